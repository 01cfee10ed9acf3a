"""``ResultFrames``: one result file opened for display (statics cached, frames read one at
a time, the bristles' colours and their scale), and why a run's bristles cannot be drawn as
asked (:func:`color_note`)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from studio.plots.colors import colormap


class ResultFrames:
    """One result file opened for display: statics cached, frames read one at a time."""

    def __init__(self, path: Path):
        import engine

        self.path = Path(path)
        self.res = engine.open_result(self.path)
        self._statics()

    def _statics(self) -> None:
        r = self.res
        statics = set(r.statics())
        self.has_nodes = "nodes/radius" in statics and "nodes/positions" in r.channels()
        self.radius = r.static("nodes/radius") if self.has_nodes else np.zeros(0)
        self.bonds = (np.asarray(r.static("bonds/nodes"), np.int64) if "bonds/nodes" in statics
                      else np.zeros((0, 2), np.int64))
        try:
            self.body_names = list(r.json_attr("body_names") or [])
        except Exception:
            self.body_names = []
        self.brush_names = list(r.json_attr("brush_names") or []) if "brush_names" in \
            r.attrs else []
        self.bodies = {}
        for name in self.body_names:
            v, t = f"bodies/{name}/vertices", f"bodies/{name}/triangles"
            if v in statics and t in statics:
                self.bodies[name] = (np.asarray(r.static(v)), np.asarray(r.static(t)))
        channels = set(r.channels())
        self.has_bending = "bonds/bending_moment" in channels
        self.has_body_pose = {n: f"bodies/{n}/position" in channels for n in self.body_names}
        self.rest = None
        self.bending_max = None
        self.deflection_max = None

    def refresh(self) -> None:
        """See the frames written since: close, then open again (``ResultFile.refresh``
        opens the new handle while the old one is still open, and HDF5 then hands back the
        same, stale, file)."""
        import engine

        self.res.close()
        self.res = engine.open_result(self.path)

    @property
    def n_frames(self) -> int:
        return int(self.res.n_frames)

    @property
    def time(self) -> np.ndarray:
        return self.res.time

    def nodes(self, i: int) -> Optional[np.ndarray]:
        if not self.has_nodes or self.n_frames == 0:
            return None
        return np.asarray(self.res.frame("nodes/positions", i))

    def rest_nodes(self) -> Optional[np.ndarray]:
        if self.rest is None:
            self.rest = self.nodes(0)
        return self.rest

    def body_pose(self, name: str, i: int):
        if not self.has_body_pose.get(name) or self.n_frames == 0:
            return None
        return (np.asarray(self.res.frame(f"bodies/{name}/position", i)),
                np.asarray(self.res.frame(f"bodies/{name}/orientation", i)))

    def colors(self, mode: str, i: int, x: np.ndarray) -> Optional[np.ndarray]:
        """Per-segment colours of frame ``i`` (node positions ``x``), on the scale
        :meth:`colour_scale` gives: 0 to the largest value of about 50 frames spread over
        the run (and of the first frame coloured), fixed for the run so that the legend
        holds; a larger value elsewhere takes the top colour."""
        if mode == "bending moment" and self.has_bending:
            m = np.asarray(self.res.frame("bonds/bending_moment", i), float)
            if self.bending_max is None or self.bending_max <= 0:
                sample = self._sample("bonds/bending_moment")
                self.bending_max = float(np.nanmax(sample)) if sample.size else 0.0
                self.bending_max = max(self.bending_max, float(np.nanmax(m)) if m.size else 0)
            return colormap(m, self.bending_max)
        if mode == "deflection":
            dev = self.deflection(x)
            if dev is None:
                return None
            if self.deflection_max is None:
                # one scale for the whole run (a legend that changed every frame would not
                # read): the largest deflection of a sample of frames, at least 4 radii
                floor = float(self.radius.max()) * 4 if self.radius.size else 1e-3
                n = self.n_frames  # (frame by frame: 50 frames of every node at once
                # could be gigabytes)
                peak = max((float(d.max()) for d in (self.deflection(self.nodes(k))
                                                     for k in range(0, n, max(1, n // 50)))
                            if d is not None and d.size), default=0.0)
                self.deflection_max = max(floor, peak, float(dev.max()) if dev.size else 0.0)
            return colormap(dev, self.deflection_max)
        return None

    def _sample(self, channel: str) -> np.ndarray:
        """About 50 frames of ``channel``, evenly spread over the run."""
        n = self.n_frames
        return np.asarray(self.res.series(channel, slice(0, n, max(1, n // 50))), float)

    def deflection(self, x: np.ndarray) -> Optional[np.ndarray]:
        """Per segment, how far its midpoint moved from the first frame, m."""
        rest = self.rest_nodes()
        if rest is None or x is None:
            return None
        mid = 0.5 * (x[self.bonds[:, 0]] + x[self.bonds[:, 1]])
        mid0 = 0.5 * (rest[self.bonds[:, 0]] + rest[self.bonds[:, 1]])
        return np.linalg.norm(mid - mid0, axis=1)

    def colour_scale(self, mode: str) -> Optional[tuple[str, str, float]]:
        """The colour scale the bristles are drawn on: (quantity, unit, top value in that
        unit); None when they are not coloured."""
        if mode == "bending moment" and self.has_bending and self.bending_max is not None:
            return ("bending moment", "N mm", self.bending_max * 1e3)
        if mode == "deflection" and self.deflection_max is not None:
            return ("deflection from the first frame", "mm", self.deflection_max * 1e3)
        return None

    def close(self) -> None:
        try:
            self.res.close()
        except Exception:
            pass


def color_note(res: Optional[ResultFrames], mode: str) -> str:
    """Why the bristles of a loaded run cannot be moved or coloured as ``mode`` asks ('' when
    they can): the channel the run did not record, and how to record it."""
    if res is None or mode == "none":
        return ""
    how = "tick *record {}* in Design → Run settings and run again"
    if not res.has_nodes:
        if not res.brush_names:
            return ""  # no bristles to draw
        return ("This run recorded no node positions (channel `nodes` was off): its "
                "bristles are drawn as designed, neither moving nor coloured; " +
                how.format("nodes") + ".")
    if mode == "bending moment" and not res.has_bending:
        return ("This run recorded no bending moments (channel `bending` was off): colour by "
                "*deflection* instead, or " + how.format("bending") + ".")
    return ""
