"""Refinement study (seed appendix E): force at maximum penetration against nodes per bristle.

    brush-studio study refinement -o DIR [--preset wedge_75] [--levels 4,6,8,12,17,24,32]

One wedge loading run (:func:`studio.studies.wedge.wedge_cycle`, loading only, to
``--depth-mm``, default 5 mm) per resolution, all on Dask. The seed's YADE model could not
go past the number of nodes at which neighbouring nodes of a bristle overlap (appendix E,
fig. E.1), because overlapping nodes of one bristle collided; this engine never lets bonded
neighbours collide, so the ladder goes past that ceiling (marked in the table and the plot).

Writes ``DIR/refinement.csv`` (nodes_per_bristle, force_N, change_N, rel_change, wall_s, cpu_s,
steps, dt_s, n_nodes, past_overlap_ceiling, hold_limit_hits), ``DIR/refinement.png``,
``DIR/study.json`` and one HDF5 per level in ``DIR/runs/``.
"""
from __future__ import annotations

import csv
import math
import sys
import time
from pathlib import Path
from typing import Annotated, Optional

from pydantic import Field

from . import api
from .run_files import write_json_atomic, write_outcomes
from .runner import RunSpec
from .study_command import report_failures, run_many_from_args, set_command
from ..exit_codes import EXIT_CANCELLED
from .wedge.cycle import TASK, numeric_summary
from .wedge.protocol import ProtocolOptions, protocol_from_options
from .wedge.scenes import (StudyInputError, apply_resolution, resolve_scenes, validate_scenes,
                           wedge_angle_deg)

DEFAULT_LEVELS = "4,6,8,12,17,24,32"
DEFAULT_DEPTH_MM = 5.0


def overlap_ceiling(brush: dict) -> int:
    """The largest number of nodes per bristle at which no two neighbouring nodes of a
    bristle overlap (radii r_i + r_(i+1) <= segment length): the seed's YADE ceiling
    (appendix E, fig. E.1)."""
    length, r0, r1 = brush["bristle_length"], brush["root_radius"], brush["tip_radius"]
    best = 2
    for n in range(2, 4097):
        seg = length / (n - 1)
        radii = [r0 + (r1 - r0) * i / (n - 1) for i in range(n)]
        if any(radii[i] + radii[i + 1] > seg + 1e-15 for i in range(n - 1)):
            break
        best = n
    return best


def parse_levels(text) -> list[int]:
    """The levels of ``text`` (``"4,8,16"``, or a list of integers), sorted, each once."""
    if isinstance(text, (list, tuple)):
        text = ",".join(str(x) for x in text)
    try:
        levels = sorted({int(x) for x in text.split(",") if x.strip()})
    except ValueError:
        raise StudyInputError(f"--levels {text!r}: expected integers like 4,8,16") from None
    if len(levels) < 2 or levels[0] < 2 or levels[-1] > 4096:
        raise StudyInputError(f"--levels {text!r}: at least two levels in 2 .. 4096")
    return levels


class Options(ProtocolOptions):
    """``brush-studio study refinement``: one scene (preset name or file; default wedge_60)
    at the numbers of nodes per bristle in ``levels``. Default depth 5 mm, loading only;
    ``nodes`` does not apply."""

    preset: list[str] = Field(default_factory=list, max_length=1,
                              description="scene file or preset name (default wedge_60); "
                                          "one only",
                              json_schema_extra={"metavar": "SCENE", "scene": True,
                                           "design": True})
    levels: list[Annotated[int, Field(ge=2, le=4096)]] = Field(
        [int(x) for x in DEFAULT_LEVELS.split(",")], min_length=2,
        description=f"nodes per bristle (default {DEFAULT_LEVELS})",
        json_schema_extra={"metavar": "N,..."})


def add_parser(sub) -> None:
    p = sub.add_parser(
        "refinement", help="force at maximum penetration against nodes per bristle "
                           "(seed appendix E), with wall time per level",
        description="Run the wedge loading protocol at several numbers of nodes per bristle, "
                    "including past the seed's node-overlap ceiling, and report the force at "
                    "maximum penetration, its change between successive levels and the wall "
                    "time of each. Default depth 5 mm (--depth-mm).")
    set_command(p, run, Options)


def _run_study(options: Options, out: Path) -> int:
    import engine

    if options.nodes is not None:
        raise StudyInputError("--nodes does not apply: use --levels")
    try:
        levels = parse_levels(options.levels)
        if len(options.preset) > 1:
            raise StudyInputError("refinement takes one --preset")
        (rid, scene, src), = resolve_scenes(options.preset, None)
        if options.depth_mm is None:
            options.depth_mm = DEFAULT_DEPTH_MM
        options.no_unload = True
        ceiling = overlap_ceiling(scene["brushes"][0])
        specs = []
        for n in levels:
            sc = apply_resolution(scene, n)
            specs.append(RunSpec(f"{rid}_n{n:04d}", sc, {
                "n_nodes_per_bristle": n, "source": src, "angle_deg": wedge_angle_deg(sc),
                "protocol": protocol_from_options(sc, options)}, TASK))
    except engine.SceneError as exc:
        raise StudyInputError("invalid scene: " + "; ".join(str(p) for p in exc.problems)
                              ) from None
    bad = validate_scenes([s.scene for s in specs])
    if bad:
        raise StudyInputError(bad)
    print(f"refinement of {src}: nodes per bristle {levels}, loading to "
          f"{options.depth_mm:g} mm; the seed's node-overlap ceiling is {ceiling} nodes")
    t0 = time.perf_counter()
    try:
        outcomes = run_many_from_args(specs, out, options, desc="refinement levels")
    except KeyboardInterrupt:
        print("cancelled: finished levels are kept; run the same command again to go on",
              file=sys.stderr)
        return EXIT_CANCELLED
    wall = time.perf_counter() - t0
    rows = refinement_table(levels, outcomes, ceiling)
    write_refinement_outputs(out, rows, outcomes, ceiling, src, wall)
    return report_failures(outcomes)


run = api.study_run("refinement", _run_study)


def refinement_table(levels, outcomes, ceiling) -> list[dict]:
    """One row per completed level: force at maximum penetration (the last loading record)
    and its change from the previous completed level."""
    rows, prev = [], None
    for n, o in zip(levels, outcomes):
        if not o.ok:
            continue
        s = numeric_summary(o.summary)
        force = [f for f, ph in zip(s["force_N"], s["phase"]) if ph == "load"][-1]
        change = float("nan") if prev is None else force - prev
        rows.append({"nodes_per_bristle": n, "force_N": force, "change_N": change,
                     "rel_change": change / force if force and prev is not None
                     else float("nan"),
                     "wall_s": o.wall_s, "cpu_s": s.get("cpu_s", float("nan")),
                     "steps": s["steps"], "dt_s": s["dt"],
                     "n_nodes": s["n_nodes"], "past_overlap_ceiling": n > ceiling,
                     "hold_limit_hits": s["hold_limit_hits"]})
        prev = force
    return rows


def write_refinement_outputs(out: Path, rows, outcomes, ceiling, src, wall) -> None:
    from .plots import plot_refinement

    cols = ["nodes_per_bristle", "force_N", "change_N", "rel_change", "wall_s", "cpu_s",
            "steps",
            "dt_s", "n_nodes", "past_overlap_ceiling", "hold_limit_hits"]
    with open(out / "refinement.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow([f"{r[c]:.6g}" if isinstance(r[c], float) else int(r[c])
                        if isinstance(r[c], bool) else r[c] for c in cols])
    if rows:
        plot_refinement([r["nodes_per_bristle"] for r in rows], [r["force_N"] for r in rows],
                        [r["wall_s"] for r in rows], out / "refinement.png",
                        f"Refinement (seed appendix E): {Path(src).name}", ceiling=ceiling)
    write_outcomes(out / "outcomes.json", outcomes)
    write_json_atomic(out / "study.json", {"study": "refinement", "source": src,
                                           "overlap_ceiling": ceiling, "wall_s": wall,
                                           "levels": rows,
                                           "failed": [o.run_id for o in outcomes if not o.ok]})
    print()
    print(f"{'nodes':>5} {'force [N]':>11} {'change [N]':>11} {'rel':>8} {'wall':>8}")
    for r in rows:
        mark = "  (past the seed's ceiling)" if r["past_overlap_ceiling"] else ""
        ch = "" if math.isnan(r["change_N"]) else f"{r['change_N']:.3g}"
        rel = "" if math.isnan(r["rel_change"]) else f"{r['rel_change']:.1%}"
        print(f"{r['nodes_per_bristle']:>5} {r['force_N']:>11.4g} {ch:>11} {rel:>8} "
              f"{r['wall_s']:>7.1f}s{mark}")
    print(f"study wall time {wall:.1f} s; outputs in {out}/ (refinement.csv, refinement.png, "
          f"study.json, runs/*.h5)")
