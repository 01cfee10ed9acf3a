"""The ladder: the levels of a study (nodes per bristle and time-step factors) as scenes."""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from typing import Optional, Sequence

from .quantities import ConvergenceError, _parse_int


@dataclass
class Level:
    level: int
    n_nodes: Optional[int]
    dt_factor: Optional[float]
    dt: Optional[float]
    run_id: str
    scene: dict
    protocol: Optional[dict] = None   # a loading ladder's wedge protocol (protocol_ladder.py)
    setting: Optional[tuple] = None   # its (name, value), e.g. ("qs_increments", 2)


def parse_ladder(text: str) -> list[int]:
    """``"n_nodes=3,5,9"`` -> [3, 5, 9]."""
    key, sep, values = text.partition("=")
    if key.strip() != "n_nodes" or not sep:
        raise ConvergenceError(f"--ladder {text!r}: expected n_nodes=N1,N2,... (resolution), "
                               "qs_increments=N1,N2,... or qs_max_acceleration=A1,A2,... "
                               "(the wedge's loading)")
    out = [_parse_int(v.strip(), "n_nodes", 2) for v in values.split(",") if v.strip()]
    if not out:
        raise ConvergenceError(f"--ladder {text!r}: no values")
    if any(b <= a for a, b in zip(out, out[1:])):
        raise ConvergenceError(f"--ladder {text!r}: n_nodes must increase from level to level")
    if max(out) > 4096:
        raise ConvergenceError(f"--ladder {text!r}: n_nodes at most 4096")
    return out


def parse_factors(text: str) -> list[float]:
    """``"1,0.5,0.25"`` -> [1.0, 0.5, 0.25] (each in (0, 1], decreasing)."""
    out = []
    for v in text.split(","):
        try:
            f = float(v)
        except ValueError:
            raise ConvergenceError(f"--dt-factor {text!r}: numbers in (0, 1]") from None
        if not (math.isfinite(f) and 0 < f <= 1):
            raise ConvergenceError(f"--dt-factor {v!r}: must be in (0, 1] (a fraction of the "
                                   "automatic time step)")
        out.append(f)
    if any(b >= a for a, b in zip(out, out[1:])):
        raise ConvergenceError(f"--dt-factor {text!r}: factors must decrease from level to "
                               "level")
    return out


def make_levels(scene: dict, n_nodes: Optional[Sequence[int]],
                dt_factors: Optional[Sequence[float]]) -> list[Level]:
    """The ladder's scenes. A list of one value applies to every level; two lists of several
    values are paired level by level (equal lengths). Every brush gets the level's n_nodes;
    with a dt factor, run.dt = factor x the automatic dt of that level's scene."""
    import engine

    n_list = list(n_nodes) if n_nodes else [None]
    f_list = list(dt_factors) if dt_factors else [None]
    if len(n_list) > 1 and len(f_list) > 1 and len(n_list) != len(f_list):
        raise ConvergenceError(f"--ladder has {len(n_list)} levels and --dt-factor "
                               f"{len(f_list)}: give equal numbers (they pair up level by "
                               "level) or a single value for one of them")
    count = max(len(n_list), len(f_list))
    if len(n_list) == 1:
        n_list *= count
    if len(f_list) == 1:
        f_list *= count
    if n_list[0] is not None and not scene.get("brushes"):
        raise ConvergenceError("the scene has no brush: an n_nodes ladder needs one")
    levels = []
    for i, (n, f) in enumerate(zip(n_list, f_list)):
        s = json.loads(json.dumps(scene))
        for brush in s.get("brushes", []):
            if n is not None:
                brush["n_nodes"] = n
        dt = None
        if f is not None:
            s["run"]["dt"] = None
            auto = engine.build(engine.parse_scene(s)).dt
            dt = f * auto
            s["run"]["dt"] = dt
        # the run id changes with everything the run computes (not with the description)
        physics = {k: v for k, v in s.items() if k != "description"}
        digest = hashlib.sha256(json.dumps(physics, sort_keys=True).encode()).hexdigest()[:10]
        tag = f"L{i:02d}" + (f"_n{n}" if n is not None else "") + \
            (f"_dt{f:g}" if f is not None else "")
        levels.append(Level(i, n, f, dt, f"{tag}_{digest}".replace(".", "p"), s))
    return levels


def level_resolution(levels: Sequence[Level]) -> tuple[list[float], str]:
    """The h of each level for the observed order: 1 / (n_nodes - 1) (relative segment
    length) when n_nodes varies, else the dt factor; for a loading ladder, 1 / increments
    per step or the move's a_m."""
    if levels and levels[0].setting is not None:
        key = levels[0].setting[0]
        values = [float(lv.setting[1]) for lv in levels]
        if key == "qs_increments":
            return [1.0 / v for v in values], "increment / wedge step"
        return values, f"{key} (m/s^2)"
    ns = [lv.n_nodes for lv in levels]
    if ns[0] is not None and len(set(ns)) > 1:
        return [1.0 / (n - 1) for n in ns], "segment length / bristle length"
    fs = [lv.dt_factor for lv in levels]
    if fs[0] is not None and len(set(fs)) > 1:
        return list(fs), "dt factor"
    return [1.0] * len(levels), "none (a single resolution)"
