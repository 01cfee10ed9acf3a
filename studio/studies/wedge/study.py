"""The wedge study (seed 4.2): force against penetration depth, loading and unloading.

    brush-studio study wedge --preset static_presets/wedge_60.json -o DIR
    brush-studio study wedge --angles 30,45,60,75 -o DIR

One run per scene (per wedge angle), each a Dask task (:func:`studio.studies.wedge.wedge_cycle`,
whose docstring gives the protocol); this module maps the command to :class:`Options`, runs
them and writes the outputs: DIR/force_depth.csv, force_depth.png, wedge_records.csv,
study.json, and with ``--check-increment`` the same runs with halved increments compared.
"""
from __future__ import annotations

import csv
import os
import sys
import time
from pathlib import Path
from typing import Annotated, Optional

from pydantic import Field

from studio.studies import api
from studio.studies.run_files import write_json_atomic, write_outcomes
from studio.studies.runner import RunSpec
from studio.studies.study_command import report_failures, run_many_from_args, set_command
from studio.studies.wedge.cycle import (INCREMENT_TOLERANCE, TASK, curve_checks, increment_check,
                    numeric_summary)
from studio.studies.wedge.protocol import (METHOD_NOTES, ProtocolOptions, protocol_from_options,
                             step_duration)
from studio.studies.wedge.scenes import (StudyInputError, apply_resolution, resolve_scenes, safe_id,
                           validate_scenes, wedge_angle_deg)
from studio.exit_codes import EXIT_CANCELLED, EXIT_FAILED


class Options(ProtocolOptions):
    """``brush-studio study wedge``: the scenes (preset names or files; default wedge_60),
    the wedge angles and the protocol."""

    preset: list[str] = Field(
        default_factory=list,
        description="scene file or preset name (repeat for several; default wedge_60)",
        json_schema_extra={"metavar": "SCENE", "scene": True,
                                           "design": True})
    angles: list[Annotated[float, Field(gt=0, lt=180)]] = Field(
        default_factory=list,
        description="wedge angles in degrees, e.g. 30,45,60,75: the presets wedge_<angle> "
                    "(or one --preset with its angle changed)",
        json_schema_extra={"metavar": "DEG,...", "unit": "deg"})
    check_increment: bool = Field(
        False, description="quasi-static: run every scene again with each step in twice as "
                           "many increments and report the largest change of the recorded "
                           f"force (study.json increment_check; converged within "
                           f"{INCREMENT_TOLERANCE * 100:g} %?); about 1.8x the CPU")


INCREMENT_CHECK_SUFFIX = "_half_increment"


def _err(msg: str) -> None:
    print(msg, file=sys.stderr)


# ----------------------------------------------------------------------------- command
def add_parser(sub) -> None:
    p = sub.add_parser(
        "wedge", help="force against depth of a wedge pressed into the brush (seed 4.2)",
        description="Drive the wedge down in steps with the seed's parabolic velocity, hold "
                    "after each until the total vertical root force is steady, record it; to "
                    "full depth and back out. Writes DIR/force_depth.csv (depth_m,force_N,"
                    "phase), DIR/force_depth.png, DIR/wedge_records.csv, DIR/study.json and "
                    "one HDF5 per run in DIR/runs/.")
    set_command(p, run, Options)


def _run_study(options: Options, out: Path) -> int:
    import engine

    try:
        scenes = resolve_scenes(options.preset, options.angles)
        specs = []
        for rid, scene, src in scenes:
            scene = apply_resolution(scene, options.nodes)
            proto = protocol_from_options(scene, options)
            angle = wedge_angle_deg(scene)
            specs.append(RunSpec(rid, scene, {"angle_deg": angle, "source": src,
                                              "n_nodes": [b["n_nodes"] for b in
                                                          scene["brushes"]],
                                              "protocol": proto}, TASK))
    except engine.SceneError as exc:
        raise StudyInputError("invalid scene: " + "; ".join(str(p) for p in exc.problems)
                              ) from None
    bad = validate_scenes([s.scene for s in specs])
    if bad:
        raise StudyInputError(bad)
    checks = []
    if options.check_increment:
        for s in specs:
            pr = s.params["protocol"]
            if pr["method"] != "quasi_static":
                raise StudyInputError("--check-increment needs the quasi-static method: the "
                                      "dynamic method's steps are not split into increments")
            finer = dict(pr, qs_increments=2 * int(pr["qs_increments"]))
            checks.append(RunSpec(s.run_id + INCREMENT_CHECK_SUFFIX, s.scene,
                                  dict(s.params, protocol=finer), TASK))
    for s in specs:
        pr = s.params["protocol"]
        print(f"{s.run_id}: {s.params['source']}; wedge {s.params['angle_deg']:g} deg, "
              f"{pr['n_steps']} x {pr['step'] * 1e3:g} mm steps (a_m {pr['max_acceleration']:g}"
              f" m/s^2, t_d {step_duration(pr['step'], pr['max_acceleration']) * 1e3:.1f} ms)"
              f"{' and back' if pr['unload'] else ''}, nodes/bristle {s.params['n_nodes']}")
    t0 = time.perf_counter()
    try:
        outcomes = run_many_from_args(specs + checks, out, options, desc="wedge runs")
    except KeyboardInterrupt:
        _err("cancelled: finished runs are kept; run the same command again to go on")
        return EXIT_CANCELLED
    wall = time.perf_counter() - t0
    return write_wedge_outputs(out, specs, outcomes[:len(specs)], wall,
                               increment_outcomes=outcomes[len(specs):])


run = api.study_run("wedge", _run_study)


# ----------------------------------------------------------------------------- outputs
def write_wedge_outputs(out: Path, specs, outcomes, wall: float,
                        increment_outcomes=()) -> int:
    from studio.studies.plots import plot_force_depth

    curves, rows, checks = [], [], {}
    single = len(specs) == 1
    for spec, o in zip(specs, outcomes):
        if not o.ok:
            continue
        s = numeric_summary(o.summary)
        angle = spec.params["angle_deg"]
        label = f"{angle:g} deg" if angle is not None else spec.run_id
        curves.append((label, s["depth_m"], s["force_N"], s["phase"]))
        checks[spec.run_id] = curve_checks(s["depth_m"], s["force_N"], s["phase"])
        checks[spec.run_id].update(hold_limit_hits=s["hold_limit_hits"], wall_s=o.wall_s,
                                   cpu_s=s.get("cpu_s"), method=s.get("method"),
                                   max_equilibrium_gap_N=s.get("max_equilibrium_gap_N"),
                                   angle_deg=angle, sim_time_s=s["sim_time_s"],
                                   steps=s["steps"], dt=s["dt"], n_nodes=s["n_nodes"],
                                   local_damping=s.get("local_damping"))
        for i in range(len(s["depth_m"])):
            rows.append((spec.run_id, angle, s["depth_m"][i], s["force_N"][i], s["phase"][i],
                         s["converged"][i]))
        if not single:
            write_force_depth_csv(out / f"force_depth_{safe_id(spec.run_id)}.csv",
                                  s["depth_m"], s["force_N"], s["phase"])
    done = [r for r in rows]
    conv = {"converged": [int(bool(r[5])) for r in done]}
    if single and done:
        write_force_depth_csv(out / "force_depth.csv", [r[2] for r in done],
                              [r[3] for r in done], [r[4] for r in done], conv)
    elif done:
        write_force_depth_csv(out / "force_depth.csv", [r[2] for r in done],
                              [r[3] for r in done], [r[4] for r in done],
                              {"angle_deg": [f"{r[1]:g}" if r[1] is not None else ""
                                             for r in done],
                               "run_id": [r[0] for r in done], **conv})
    unconverged = {rid: c["hold_limit_hits"] for rid, c in checks.items()
                   if c["hold_limit_hits"]}
    warning = None
    if unconverged:
        warning = ("NOT RECORDED: " + ", ".join(f"{rid} {n} hold(s)" for rid, n in
                                                unconverged.items())
                   + " hit the hold limit (force NaN in force_depth.csv, converged = 0)")
    with open(out / "wedge_records.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["run_id", "angle_deg", "depth_m", "force_N", "phase", "converged"])
        for r in rows:
            w.writerow([r[0], "" if r[1] is None else f"{r[1]:.6g}", f"{r[2]:.6g}",
                        f"{r[3]:.9g}", r[4], int(bool(r[5]))])
    if curves:
        plot_force_depth(curves, out / "force_depth.png",
                         "Wedge force against depth (hold-until-steady, seed 4.2)",
                         warning=warning)
    inc = {}
    for spec, o, fine in zip(specs, outcomes, increment_outcomes):
        if o.ok and fine.ok:
            inc[spec.run_id] = increment_check(o.summary, fine.summary,
                                               spec.params["protocol"]["threshold"])
            inc[spec.run_id]["cpu_s"] = fine.summary.get("cpu_s")
    write_outcomes(out / "outcomes.json", list(outcomes) + list(increment_outcomes))
    summary = {
        "study": "wedge", "wall_s": wall, "runs": len(specs),
        "failed": [o.run_id for o in list(outcomes) + list(increment_outcomes) if not o.ok],
        "method": METHOD_NOTES,
        "checks": checks,
        "protocols": {s.run_id: s.params["protocol"] for s in specs}}
    if warning:
        summary["warning"] = warning
    if increment_outcomes:
        summary["increment_check"] = inc
    write_json_atomic(out / "study.json", summary)
    print()
    print(f"{'run':<22} {'angle':>6} {'peak F [N]':>11} {'unload<load':>11} "
          f"{'hold limit':>10} {'wall':>9}")
    for rid, c in checks.items():
        print(f"{rid:<22} {c['angle_deg'] or 0:>6.4g} {c['peak_force_N']:>11.4g} "
              f"{str(c.get('unload_below_load', '-')):>11} {c['hold_limit_hits']:>10} "
              f"{c['wall_s']:>8.1f}s")
    for rid, c in inc.items():
        where = ("" if c["at_depth_m"] is None
                 else f" at {c['at_depth_m'] * 1e3:g} mm ({c['at_phase']})")
        print(f"{rid}: halving the increments changes the force by at most "
              f"{c['max_rel_change']:.2%}{where}: "
              f"{'converged' if c['converged'] else 'NOT converged'} within "
              f"{c['tolerance']:.0%}")
    print(f"study wall time {wall:.1f} s; outputs in {out}/ (force_depth.csv, "
          f"force_depth.png, wedge_records.csv, study.json, runs/*.h5)")
    code = report_failures(list(outcomes) + list(increment_outcomes))
    if warning:
        _err("WARNING: " + warning + ": those records are no equilibria (docs/studies.md; "
             "a longer --max-hold or --method dynamic may settle them)")
        return code or EXIT_FAILED
    return code


def write_force_depth_csv(path: Path, depths, forces, phases, extra: Optional[dict] = None
                          ) -> None:
    """``depth_m,force_N,phase`` (then the ``extra`` columns, each a list; the study adds
    ``converged``: 0 where the hold hit its limit, whose force is written as ``nan``)."""
    extra = extra or {}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["depth_m", "force_N", "phase", *extra])
        for i, (dd, ff, ph) in enumerate(zip(depths, forces, phases)):
            w.writerow([f"{dd:.6g}", f"{ff:.9g}", ph, *(extra[k][i] for k in extra)])
    os.replace(tmp, path)
