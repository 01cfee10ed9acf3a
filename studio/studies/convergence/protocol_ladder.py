"""The loading ladder: the wedge study's quasi-static protocol at refined increments or rates.

    brush-studio convergence --preset wedge_60 --quantity wedge_force@2mm \\
        --ladder qs_increments=1,2,4 -o DIR

A wedge curve is a numerical result of its loading protocol as much as of its resolution: the
recorded equilibrium may depend on how the wedge is stepped (issue 11). Each level of this
ladder runs the scene through the wedge study's hold-until-steady cycle
(:func:`studio.studies.wedge.wedge_cycle`, quasi-static method, loading only, down to the
quantity's depth) with one protocol setting changed, named as the study's own option is:

* ``qs_increments=N1,N2,...`` (increasing): increments per wedge step, each settled and its
  slip committed; h = 1 / N, the increment as a fraction of the step;
* ``qs_max_acceleration=A1,A2,...`` (decreasing): a_m of each increment's parabolic move,
  m/s^2 (the loading rate); h = a_m.

The quantity (``wedge_force@DEPTH``) is the force the level recorded at DEPTH on the way in,
read from the run's own HDF5 (:func:`studio.studies.wedge.read_run_h5`); beside the usual
table, every level's whole recorded curve is compared with the previous level's
(:func:`studio.studies.wedge.increment_check`: the largest relative change of the force over
the depths, against the study's 2 % mark).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Optional, Sequence

from .ladder import Level
from .quantities import ConvergenceError, Quantity, _parse_int

# name -> (value type, must increase?, what h is)
PROTOCOL_LADDERS = {
    "qs_increments": (int, True, "1 / increments per step"),
    "qs_max_acceleration": (float, False, "a_m of each increment's move, m/s^2"),
}


def parse_protocol_ladder(text: str) -> Optional[tuple[str, list]]:
    """``"qs_increments=1,2,4"`` -> ("qs_increments", [1, 2, 4]); None when the key is not a
    protocol setting (then it is the resolution ladder's)."""
    key, sep, values = text.partition("=")
    key = key.strip()
    if key not in PROTOCOL_LADDERS or not sep:
        return None
    kind, increasing, _ = PROTOCOL_LADDERS[key]
    out = []
    for v in (v.strip() for v in values.split(",")):
        if not v:
            continue
        if kind is int:
            out.append(_parse_int(v, key, 1))
            continue
        try:
            f = float(v)
        except ValueError:
            raise ConvergenceError(f"--ladder {text!r}: {v!r} is not a number") from None
        if not (math.isfinite(f) and f > 0):
            raise ConvergenceError(f"--ladder {text!r}: {key} must be > 0")
        out.append(f)
    if not out:
        raise ConvergenceError(f"--ladder {text!r}: no values")
    pairs = list(zip(out, out[1:]))
    if increasing and any(b <= a for a, b in pairs):
        raise ConvergenceError(f"--ladder {text!r}: {key} must increase from level to level "
                               "(finer increments)")
    if not increasing and any(b >= a for a, b in pairs):
        raise ConvergenceError(f"--ladder {text!r}: {key} must decrease from level to level "
                               "(slower loading)")
    return key, out


def protocol_levels(scene: dict, quantity: Quantity, key: str, values: Sequence
                    ) -> list[Level]:
    """One level per value: the wedge study's quasi-static protocol for ``scene``, loading
    only, down to the quantity's depth, with ``key`` set to the value (``Level.protocol``)."""
    from studio.studies.wedge.protocol import make_protocol
    from studio.studies.wedge.scenes import StudyInputError

    if quantity.kind != "wedge_force":
        raise ConvergenceError(
            f"a {key} ladder runs the wedge study's protocol, which records the wedge force "
            f"at each depth: use --quantity wedge_force@DEPTH (not {quantity.text})")
    body = _wedge_body(scene, quantity.body)
    levels = []
    for i, value in enumerate(values):
        try:
            proto = make_protocol(scene, body=body, depth=quantity.depth, unload=False,
                                  method="quasi_static", **{key: value})
        except StudyInputError as exc:
            raise ConvergenceError(f"wedge protocol: {exc}") from None
        tag = f"L{i:02d}_{key}{value:g}".replace(".", "p")
        levels.append(Level(i, None, None, None, tag, json.loads(json.dumps(scene)),
                            protocol=proto, setting=(key, value)))
    return levels


def _wedge_body(scene: dict, name: Optional[str]) -> str:
    for b in scene.get("bodies", []):
        prof = b.get("motion", {}).get("profile") or {}
        if (name is None or b.get("name") == name) and prof.get("kind") == "stepped_parabolic":
            return b["name"]
    raise ConvergenceError(
        "the wedge protocol needs a kinematic body with a stepped_parabolic profile"
        + (f" named {name!r}" if name else "") + " (the wedge presets have one)")


def run_protocol_ladder(levels: Sequence[Level], out_dir: Path, *, serial: bool,
                        scheduler: Optional[str], workers: Optional[int],
                        progress: bool) -> list[dict]:
    """Run the levels through the studies' runner (``serial``: one worker, in this process);
    one record per level like :func:`running.run_ladder`'s."""
    from studio.studies.runner import RunSpec, run_many
    from studio.studies.wedge.cycle import TASK

    specs = [RunSpec(lv.run_id, lv.scene, {"level": lv.level, "protocol": lv.protocol,
                                           "setting": list(lv.setting)}, TASK)
             for lv in levels]
    outcomes = run_many(specs, out_dir, scheduler=scheduler,
                        n_workers=1 if serial else workers, progress=progress,
                        desc="levels")
    # wall_s: the engine's own stepping time in the cycle (engine_wall_s), as a resolution
    # ladder's wall_s is the engine's run time; the task's whole wall time where it is absent
    return [{"run_id": o.run_id, "params": o.params, "status": o.status,
             "summary": {"wall_s": (o.summary or {}).get("engine_wall_s", o.wall_s),
                         **{k: v for k, v in (o.summary or {}).items()
                            if k in ("dt", "cpu_s", "status", "error")}},
             "error": o.error, "h5": str(o.h5), "wall_s": o.wall_s, "skipped": o.skipped}
            for o in outcomes]


def measure_protocol_level(h5, quantity: Quantity) -> float:
    """The force the level recorded at the quantity's depth on the way in, N."""
    from studio.studies.wedge.cycle import read_run_h5

    curve = read_run_h5(h5)
    for d, f, phase in zip(curve["depth_m"], curve["force_N"], curve["phase"]):
        if phase == "load" and abs(d - quantity.depth) <= 1e-9:
            return float(f)
    raise ConvergenceError(f"{h5}: no record at {quantity.depth:g} m on the way in")


def curve_changes(levels: Sequence[Level], records: Sequence[dict]) -> list[Optional[dict]]:
    """For each level after the first, its whole recorded curve against the previous level's
    (:func:`studio.studies.wedge.increment_check`); None where either run did not finish."""
    from studio.studies.wedge.cycle import increment_check, read_run_h5

    out: list[Optional[dict]] = []
    for lv, prev, rec, prev_rec in zip(levels[1:], levels, records[1:], records):
        if not all(r["status"] in ("completed", "stopped") for r in (rec, prev_rec)):
            out.append(None)
            continue
        change = increment_check(read_run_h5(prev_rec["h5"]), read_run_h5(rec["h5"]),
                                 lv.protocol["threshold"])
        change.update(level=lv.level, against_level=prev.level)
        out.append(change)
    return out
