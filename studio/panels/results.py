"""The Results panel: a finished (or stopped) run opened for playback: the time slider, play
and speed, colour-by, the plots with their cursor, the HDF5 download. ``ResultFrames`` reads
one result file for display. A mixin of :class:`studio.app.Studio`."""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Optional

import numpy as np

from .. import ui_view as uv
from .common import COLOR_MODES, PLOT_CURSOR_S, SPEEDS, _md_escape, _safe_name


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
        """Per-segment colours of frame ``i`` (node positions ``x``)."""
        if mode == "bending moment" and self.has_bending:
            m = np.asarray(self.res.frame("bonds/bending_moment", i), float)
            if self.bending_max is None or self.bending_max <= 0:
                n = self.n_frames
                step = max(1, n // 50)
                sample = np.asarray(self.res.series("bonds/bending_moment",
                                                    slice(0, n, step)), float)
                self.bending_max = float(np.nanmax(sample)) if sample.size else 0.0
                self.bending_max = max(self.bending_max, float(np.nanmax(m)) if m.size else 0)
            return uv.colormap(m, self.bending_max)
        if mode == "deflection":
            rest = self.rest_nodes()
            if rest is None:
                return None
            mid = 0.5 * (x[self.bonds[:, 0]] + x[self.bonds[:, 1]])
            mid0 = 0.5 * (rest[self.bonds[:, 0]] + rest[self.bonds[:, 1]])
            dev = np.linalg.norm(mid - mid0, axis=1)
            vmax = float(self.radius.max()) * 4 if self.radius.size else 1e-3
            return uv.colormap(dev, max(vmax, float(dev.max()) if dev.size else 0.0))
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


FORCE_COLORS = ("#1f77b4", "#2ca02c", "#9467bd")  # F_x, F_y, F_z (none is the cursor's)
CURSOR_COLOR = "#d62728"


def press_depth(res: "ResultFrames"):
    """For a run whose body is pressed kinematically into the brush: (body name, depth per
    frame in m), the body's displacement from its first recorded position along its overall
    direction of travel; None when no kinematic body moves."""
    try:
        scene = res.res.json_attr("scene") or {}
    except Exception:
        scene = {}
    motions = {b.get("name"): (b.get("motion") or {}).get("type")
               for b in scene.get("bodies") or []}
    channels = set(res.res.channels())
    for name in res.body_names:
        c = f"bodies/{name}/position"
        if motions.get(name) != "kinematic" or c not in channels or res.n_frames < 2:
            continue
        x = np.asarray(res.res.series(c), float)
        d = x - x[0]
        far = int(np.argmax(np.linalg.norm(d, axis=1)))
        span = float(np.linalg.norm(d[far]))
        if span <= 0:
            continue
        return name, d @ (d[far] / span)
    return None


class ResultsPanel:
    """Results tab of the studio (mixin)."""

    def _build_results_gui(self, gui) -> None:
        with self.tab_results:
            self.md_result = gui.add_markdown("No run loaded. Finished runs load here.")
            self.sl_time = gui.add_slider("frame", min=0, max=1, step=1, initial_value=0,
                                          disabled=True)
            self.sl_time.on_update(self._on_slider)
            self.cb_play = gui.add_checkbox("play", False, disabled=True)
            self.cb_play.on_update(self._on_play)
            self.dd_speed = gui.add_dropdown("speed (simulated s per s)", SPEEDS,
                                             initial_value="0.25x")
            self.dd_color = gui.add_dropdown("colour bristles by", COLOR_MODES,
                                             initial_value="bending moment")
            self.dd_color.on_update(lambda e: self._show_frame(self.frame_index))
            self.md_color = gui.add_markdown("", visible=False)
            self.bt_download_h5 = gui.add_button("Download result HDF5", disabled=True)
            self.bt_download_h5.on_click(self._on_download_h5)
            self.bt_design = gui.add_button("Back to the design view")
            self.bt_design.on_click(lambda e: self.set_mode("design"))
            self.plots: dict[str, Any] = {}
            self.figures: dict[str, Any] = {}

    # ----------------------------------------------------------------- modes and frames
    def set_mode(self, mode: str, redraw: bool = True) -> None:
        with self.lock:
            if mode == self.mode:
                return
            self.mode = mode
            if mode != "live" and self.live is not None:
                self.live.close()
                self.live = None
            if mode != "playback":
                self.cb_play.value = False
            if mode == "design" and redraw:
                self.redraw_design()
            self._place_gizmo()
            self._update_summary()

    def load_run(self, job_id: str) -> bool:
        """Open a job's result file for playback (any state but queued)."""
        import engine

        with self.lock:
            # close every handle on result files first: HDF5 shares one open file between
            # the handles of a process, so a new handle would see the live reader's old view
            for old in (self.live, self.playback):
                if old is not None:
                    old.close()
            self.live = self.playback = self.playback_job = None
            try:
                path = self.jobs.result_path(job_id)
                frames = ResultFrames(path)
            except (KeyError, engine.BrushStudioError, OSError) as exc:
                self.md_result.content = f"Cannot open run `{job_id}`: {_md_escape(str(exc))}"
                return False
            self.playback, self.playback_job = frames, job_id
            self.set_mode("playback")
            n = frames.n_frames
            self.sl_time.max = max(n - 1, 1)
            self.sl_time.disabled = n < 2
            self.cb_play.disabled = n < 2
            self.bt_download_h5.disabled = False
            info = self.jobs.get(job_id)
            t_end = float(frames.time[-1]) if n else 0.0
            self.md_result.content = (
                f"Run `{job_id}` ({_md_escape(info.name)}): **{frames.res.status}**, {n} frames,"
                f" t = 0 … {t_end:.4g} s" +
                (f". {_md_escape(info.error)}" if info.error else ""))
            self._make_plots()
            self.frame_index = -1
            self.sl_time.value = 0
            self._show_frame(0)
        return True

    def _on_slider(self, event) -> None:
        """Scrubbing shows the loaded run: after a design edit (which shows the design) the
        first touch of the slider switches the view back to the run."""
        if self.mode != "playback" and event.client is not None and self.playback is not None:
            self.set_mode("playback")
        if self.mode == "playback":
            self._show_frame(int(event.target.value))

    def _on_play(self, event) -> None:
        if event.client is not None and self.cb_play.value and self.playback is not None:
            self.set_mode("playback")
            self._show_frame(int(self.sl_time.value))

    def show_view(self, which: str) -> bool:
        """Show the design or the run (the loaded playback, else the running job live).
        Returns False when there is no run to show."""
        with self.lock:
            if which == "design":
                self.set_mode("design")
                return True
            if self.playback is not None:
                self.set_mode("playback")
                self._show_frame(max(int(self.sl_time.value), 0))
                return True
            if self.active_job is not None:
                self.set_mode("live")
                return True
            return False

    def _show_frame(self, i: int, source: Optional[ResultFrames] = None) -> None:
        """Draw frame ``i`` of the playback (or live) result."""
        with self.lock:
            res = source or self.playback
            if res is None or res.n_frames == 0:
                return
            i = int(min(max(i, 0), res.n_frames - 1))
            note = color_note(res, self.dd_color.value)
            if note != getattr(self, "_color_note", ""):
                self._color_note = note
                self.md_color.content = f"<span style='color:#b60'>⚠ {note}</span>" \
                    if note else ""
                self.md_color.visible = bool(note)
            x = res.nodes(i)
            if x is not None and len(res.bonds):
                colors = res.colors(self.dd_color.value, i, x)
                centres, wxyz, scales = uv.segment_instances(x, res.radius, res.bonds)
                self.view.set_bristles(centres, wxyz, scales, colors)
                self.n_segments_drawn = len(centres)
            meshes = []
            for name, (verts, tris) in res.bodies.items():
                pose = res.body_pose(name, i)
                if pose is not None:
                    meshes.append(uv.BodyMesh(name, verts, tris, pose[0], pose[1]))
            self.view.set_bodies(meshes)
            if source is None:
                self.frame_index = i
                now = time.monotonic()
                if not self.cb_play.value or now - self.last_cursor > PLOT_CURSOR_S:
                    self.last_cursor = now
                    self._move_cursor(float(res.time[i]))

    # ----------------------------------------------------------------- plots
    def _make_plots(self) -> None:
        import plotly.graph_objects as go

        res = self.playback
        t = res.time
        channels = set(res.res.channels())
        figs = {}
        self.cursor_x: dict[str, np.ndarray] = {}  # figure -> x of each frame (else time)
        forces = {}
        f = go.Figure()
        for brush in res.brush_names:
            c = f"brushes/{brush}/root_force"
            if c in channels:
                F = np.asarray(res.res.series(c))
                forces[brush] = F
                for k, axis in enumerate("xyz"):
                    f.add_scatter(x=t, y=F[:, k], name=f"{brush} F_{axis}", mode="lines",
                                  line=dict(color=FORCE_COLORS[k]))
        for name in res.body_names:
            c = f"bodies/{name}/contact_force"
            if c in channels:
                F = np.asarray(res.res.series(c))
                for k, axis in enumerate("xyz"):
                    f.add_scatter(x=t, y=F[:, k], name=f"{name} contact F_{axis}",
                                  mode="lines", line=dict(color=FORCE_COLORS[k], dash="dot"))
        figs["root force [N]"] = f
        press = press_depth(res)
        if press is not None and forces:
            body, depth = press
            f = go.Figure()
            for brush, F in forces.items():
                for k, axis in enumerate("xyz"):
                    f.add_scatter(x=depth * 1e3, y=F[:, k], name=f"{brush} F_{axis}",
                                  mode="lines", line=dict(color=FORCE_COLORS[k]))
            title = f"root force [N] against depth of {body} [mm]"
            f.update_layout(xaxis_title=f"depth of {body} [mm]")
            figs[title] = f
            self.cursor_x[title] = depth * 1e3
        f = go.Figure()
        for name in res.body_names:
            c = f"bodies/{name}/angular_velocity"
            if c in channels:
                w = np.asarray(res.res.series(c))
                f.add_scatter(x=t, y=np.linalg.norm(w, axis=1), name=f"{name} |ω|",
                              mode="lines")
        figs["body angular velocity [rad/s]"] = f
        f = go.Figure()
        for e in ("kinetic", "bond", "contact", "gravity", "total"):
            c = f"energy/{e}"
            if c in channels:
                f.add_scatter(x=t, y=np.asarray(res.res.series(c)), name=e, mode="lines")
        figs["energy [J]"] = f
        gui = self.server.gui
        for title, fig in figs.items():
            fig.update_layout(title=dict(text=title, font=dict(size=13)),
                              margin=dict(l=40, r=10, t=30, b=30), height=260,
                              legend=dict(font=dict(size=9)))
            if title not in self.cursor_x:
                fig.update_layout(xaxis_title="time [s]")
            x0 = self.cursor_x[title][0] if title in self.cursor_x and len(t) else \
                (float(t[0]) if len(t) else 0.0)
            fig.add_vline(x=float(x0), line_color=CURSOR_COLOR, line_width=1)
            self.figures[title] = fig
            if title in self.plots:
                self.plots[title].figure = fig
            else:
                with self.tab_results:
                    self.plots[title] = gui.add_plotly(fig, aspect=1.6)

    def _move_cursor(self, t: float) -> None:
        times = self.playback.time if self.playback is not None else None
        for title, fig in self.figures.items():
            x = t
            xs = getattr(self, "cursor_x", {}).get(title)
            if xs is not None and times is not None and len(times):
                x = float(np.interp(t, times, xs))
            fig.layout.shapes = ()
            fig.add_vline(x=x, line_color=CURSOR_COLOR, line_width=1)
            self.plots[title].figure = fig

    def _on_download_h5(self, event) -> None:
        if event.client is None or self.playback_job is None:
            return
        path = self.jobs.result_path(self.playback_job)
        event.client.send_file_download(
            f"{_safe_name(self.jobs.get(self.playback_job).name)}-{self.playback_job}.h5",
            path.read_bytes(), save_immediately=True)

    def _advance_play(self, now: float) -> None:
        if self.mode != "playback" or self.playback is None or not self.cb_play.value:
            self.play_clock = None
            return
        res = self.playback
        t = res.time
        if len(t) < 2:
            return
        speed = float(self.dd_speed.value.rstrip("x"))
        if self.play_clock is None:
            self.play_clock = (now, float(t[max(self.frame_index, 0)]))
        t0_wall, t0_sim = self.play_clock
        sim = t0_sim + (now - t0_wall) * speed
        if sim > t[-1]:
            self.play_clock = (now, float(t[0]))
            sim = float(t[0])
        i = int(np.clip(np.searchsorted(t, sim, side="right") - 1, 0, len(t) - 1))
        if i != self.frame_index:
            self.sl_time.value = i  # triggers _show_frame through the callback
