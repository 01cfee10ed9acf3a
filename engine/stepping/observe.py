"""Observers of a run: what :func:`engine.run` hands each recorded frame to.

An observer is a callable ``observer(frame)`` or an object with ``append(frame)``; it may
also have ``begin(channels, static)`` (told the channels' per-frame shapes and dtypes and the
static arrays before the first frame). ``frame`` maps channel names (``"time"``,
``"brushes/<name>/root_force"``, ``"nodes/positions"``...) to their values at that time; the
arrays are the system's own and are only valid during the call (copy what you keep).

The HDF5 :class:`engine.io.recorder.Recorder` is one such observer (``output=``);
:class:`MemoryObserver` keeps the requested channels in memory, with no file::

    obs = engine.MemoryObserver(["time", "brushes/brush/root_force"])
    engine.run(system, until=0.1, output=False, observer=obs)
    fz = obs.series("brushes/brush/root_force")[:, 2]
"""
from __future__ import annotations

from typing import Any, Iterable, Optional

import numpy as np


class MemoryObserver:
    """Keeps the ``channels`` it is asked for (all when None) of every frame, in memory,
    each value cast to its channel's dtype as the HDF5 recorder casts it (so
    :meth:`series` equals the file's ``series``, bit for bit)."""

    def __init__(self, channels: Optional[Iterable[str]] = None):
        self.channels = None if channels is None else list(channels)
        self._dtypes: dict[str, Any] = {}
        self._rows: dict[str, list] = {}
        self.static: dict[str, np.ndarray] = {}

    def begin(self, channels: dict, static: dict) -> None:
        names = list(channels) if self.channels is None else self.channels
        unknown = [n for n in names if n not in channels]
        if unknown:
            raise KeyError(f"no channel {unknown[0]!r} in this run; channels: "
                           f"{sorted(channels)}")
        self._dtypes = {n: np.dtype(channels[n][1]) for n in names}
        self._rows = {n: [] for n in names}
        self.static = {k: np.asarray(v) for k, v in static.items()}

    def append(self, frame: dict) -> None:
        for name, dtype in self._dtypes.items():
            self._rows[name].append(np.array(frame[name], dtype=dtype, copy=True))

    @property
    def n_frames(self) -> int:
        return len(next(iter(self._rows.values()), []))

    @property
    def time(self) -> np.ndarray:
        """Simulated time of each frame, s."""
        return self.series("time")

    def series(self, name: str) -> np.ndarray:
        """Every frame's value of channel ``name``, stacked (shape (n_frames, ...))."""
        if name not in self._rows:
            raise KeyError(f"channel {name!r} was not observed; observed: {list(self._rows)}")
        rows = self._rows[name]
        if not rows:
            return np.zeros((0,), dtype=self._dtypes[name])
        return np.stack(rows)

    def frame(self, name: str, i: int) -> np.ndarray:
        """Frame ``i``'s value of channel ``name`` (negative counts from the end)."""
        return self._rows[name][i]


def observer_calls(observer) -> tuple:
    """``(begin or None, append)`` of an observer (a callable or an object with ``append``);
    TypeError for anything else."""
    if observer is None:
        return None, None
    append = getattr(observer, "append", None)
    if append is None:
        if not callable(observer):
            raise TypeError(f"an observer is a callable or has append(frame); got "
                            f"{type(observer).__name__}")
        append = observer
    return getattr(observer, "begin", None), append
