"""The capture criterion of ``study capture``, computed from recorded time series alone (no
engine): pure numpy, so it is unit-tested on synthetic series.

A frame is *held* when, at once, the target's speed relative to the chaser is at most
``max_speed`` (m/s), its angular speed relative to the chaser at most ``max_rate`` (rad/s),
the target is between the jaws (:func:`between_jaws`), and the brushes have touched it
(frames before the first contact are not held: a still target is not captured before the
jaws reach it). The target is *captured* at
``t_c`` when the frames from ``t_c`` to the end of the record are all held and span at least
``hold`` seconds: a target held for a while and then lost (it slipped out, or spun up
again) is not captured; ``first_hold`` still says when it was first held that long.
"""
from __future__ import annotations

from typing import Optional

import numpy as np


def between_jaws(target_pos, left_pos, right_pos, radius: float) -> np.ndarray:
    """Per frame, whether the target's centre lies between the jaws: its projection on the
    segment from the left jaw's centre to the right jaw's falls strictly inside it, and its
    distance from that line is at most ``radius`` (m). Arrays (F, 3)."""
    target_pos, left_pos, right_pos = (np.asarray(a, float) for a in
                                       (target_pos, left_pos, right_pos))
    axis = right_pos - left_pos
    length2 = np.einsum("fi,fi->f", axis, axis)
    rel = target_pos - left_pos
    s = np.einsum("fi,fi->f", rel, axis) / np.maximum(length2, 1e-300)
    off = rel - s[:, None] * axis
    return (s > 0.0) & (s < 1.0) & (np.linalg.norm(off, axis=1) <= radius)


def _runs(ok: np.ndarray):
    """(start, stop) index pairs of the runs of consecutive True in ``ok`` (stop exclusive)."""
    edges = np.diff(np.concatenate(([0], ok.astype(np.int8), [0])))
    return list(zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]))


def capture(t, rel_speed, rel_rate, between, *, max_speed: float, max_rate: float,
            hold: float, first_contact: Optional[float] = 0.0) -> dict:
    """The criterion over the frames ``t`` (s) of a run: ``rel_speed`` (m/s) and ``rel_rate``
    (rad/s) the target's relative speed and angular speed, ``between`` per-frame booleans,
    ``first_contact`` the time (s) the brushes first touched the target (None: never).
    Returns ``captured`` (bool), ``time_to_capture`` (s, the start of the final held
    stretch; None if not captured), ``first_hold`` (s, the start of the first stretch held
    for ``hold``; None if none) and ``lost`` (held for ``hold`` at some point, and not
    captured at the end)."""
    t = np.asarray(t, float)
    ok = ((np.asarray(rel_speed, float) <= max_speed) & (np.asarray(rel_rate, float) <= max_rate)
          & np.asarray(between, bool))
    ok &= t >= (np.inf if first_contact is None else first_contact)
    # half a frame of slack: a stretch of k frames spans (k - 1) intervals of sampling
    slack = 0.5 * (t[1] - t[0]) if len(t) > 1 else 0.0
    long_enough = [(a, b) for a, b in _runs(ok) if t[b - 1] - t[a] + slack >= hold]
    first: Optional[float] = float(t[long_enough[0][0]]) if long_enough else None
    final = long_enough[-1] if long_enough and long_enough[-1][1] == len(t) else None
    return {"captured": final is not None,
            "time_to_capture": float(t[final[0]]) if final is not None else None,
            "first_hold": first,
            "lost": first is not None and final is None}
