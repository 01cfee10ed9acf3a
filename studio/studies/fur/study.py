"""``brush-studio study fur``: space fur against impacts (seed 5.3.2, fig. 5.1), as a sweep.

Every combination of impact speed x angle x projectile radius x fur length x bristle root
radius x pitch is one run of a steel sphere into the fur-covered plate, and every impact
(speed x angle x radius) also one run on the bare plate of the same material, the
reference. Outputs (``-o DIR``): ``fur.csv`` (one row per run: peak transmitted force,
impulse, time to arrest, penetration, bottomed out, the momentum check), ``comparison.csv``
(one row per fur run with its bare-plate reference and the peak-force ratio),
``peak_force.png``, ``force_history.png``, ``summary.json``; ``runs/`` one result file per run.
The defaults are fig. 5.1's case, the study's first row.
"""
from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

from pydantic import Field

from .. import api
from ..run_files import outcome_rows, write_table
from ..options import StudyOptions
from .scenes import Fur, Impact, ROOT_GAP, fur_scene, fur_top, plate_scene

FIG51_SPEED = 50.0 * math.sqrt(2.0)
TASK = "studio.studies.fur.task:fur_task"
#: the presets' simulated times at fig. 5.1's impact: the fur run (the sphere has left the
#: fur by 0.9 ms) and the bare plate (3 mm of flight at 50 m/s normal, then a 2.5 us contact)
FUR_DURATION, PLATE_DURATION = 1e-3, 2e-4
FUR_RECORD, PLATE_RECORD = 2e-6, 1e-7


class Options(StudyOptions):
    """``brush-studio study fur``: the sweep's values (each a list: every combination runs)."""

    preset: str = Field("space_fur",
                        description="the fur scene: a body 'plate', a free body 'sphere' and "
                                    "one fur brush on the plate (default space_fur); the "
                                    "bare-plate reference is the same scene without its fur",
                        json_schema_extra={"metavar": "NAME_OR_FILE", "scene": True,
                                           "design": True})
    speeds: list[float] = Field([round(FIG51_SPEED, 4)], min_length=1,
                                description="impact speeds",
                                json_schema_extra={"unit": "m/s"})
    angles: list[float] = Field([45.0], min_length=1,
                                description="impact angles from the plate normal, 0 to 60",
                                json_schema_extra={"unit": "deg"})
    radii: list[float] = Field([2.0], min_length=1,
                               description="projectile (steel sphere) radii",
                               json_schema_extra={"unit": "mm"})
    lengths: list[float] = Field([20.0], min_length=1, description="fur lengths",
                                 json_schema_extra={"unit": "mm"})
    root_radii: list[float] = Field([0.3], min_length=1,
                                    description="bristle root radii (tips 2/3 of it)",
                                    json_schema_extra={"unit": "mm"})
    pitches: list[float] = Field([2.0], min_length=1,
                                 description="bristle pitch, both directions",
                                 json_schema_extra={"unit": "mm"})
    nodes: int = Field(6, ge=2, le=64, description="nodes per bristle")
    yield_strength: float | None = Field(
        None, gt=0, description="the wires' yield strength, to judge their peak bending stress "
                                "E r kappa against (default: not judged; no material data "
                                "is assumed)",
        json_schema_extra={"unit": "MPa"})
    no_bare: bool = Field(False, description="leave out the bare-plate reference runs")
    duration: float | None = Field(
        None, gt=0, le=1.0,
        description="simulated time per fur run; default the preset's 1 ms, stretched "
                    "for slower impacts (x 70.7 m/s / speed)",
        json_schema_extra={"unit": "s"})


def _check(options: Options) -> None:
    problems = []
    for name, lo, hi in (("speeds", 0.01, 2000.0), ("angles", 0.0, 60.0),
                         ("radii", 0.1, 50.0), ("lengths", 1.0, 500.0),
                         ("root_radii", 0.01, 5.0), ("pitches", 0.05, 50.0)):
        for v in getattr(options, name):
            if not lo <= v <= hi:
                problems.append(f"{name} = {v:g}: outside [{lo:g}, {hi:g}]")
    for p, r in itertools.product(options.pitches, options.root_radii):
        if p <= 2 * r:
            problems.append(f"pitch {p:g} mm <= bristle diameter {2 * r:g} mm: the roots "
                            "would overlap")
    if problems:
        raise api.StudyInputError("; ".join(problems))


def cases(options: Options):
    """(impacts, furs) in SI."""
    impacts = [Impact(v, math.radians(a), r * 1e-3) for v, a, r in
               itertools.product(options.speeds, options.angles, options.radii)]
    furs = [Fur(L * 1e-3, r * 1e-3, p * 1e-3, options.nodes) for L, r, p in
            itertools.product(options.lengths, options.root_radii, options.pitches)]
    return impacts, furs


def _impact_id(i: Impact) -> str:
    return f"v{i.speed:g}_a{math.degrees(i.angle):g}_r{i.radius * 1e3:g}"


def _fur_id(f: Fur) -> str:
    return f"L{f.length * 1e3:g}_rr{f.root_radius * 1e3:g}_p{f.pitch * 1e3:g}_n{f.n_nodes}"


def build_specs(options: Options):
    from ..runner import RunSpec

    impacts, furs = cases(options)
    specs = []
    for imp in impacts:
        stretch = max(1.0, FIG51_SPEED / imp.speed)
        params = {"speed": imp.speed, "angle_deg": math.degrees(imp.angle),
                  "radius_mm": imp.radius * 1e3}
        for fur in furs:
            dur = options.duration or FUR_DURATION * stretch
            specs.append(RunSpec(
                run_id=f"fur_{_impact_id(imp)}_{_fur_id(fur)}".replace(".", "p"),
                scene=fur_scene(imp, fur, duration=dur, record_interval=FUR_RECORD,
                                preset=options.preset),
                params=dict(params, kind="fur", length_mm=fur.length * 1e3,
                            root_radius_mm=fur.root_radius * 1e3, pitch_mm=fur.pitch * 1e3,
                            nodes=fur.n_nodes, top=fur_top(fur),
                            floor=fur.root_radius * 2 + ROOT_GAP,
                            yield_strength=(options.yield_strength * 1e6
                                            if options.yield_strength else None)),
                task=TASK))
        if not options.no_bare:
            v_n = imp.speed * math.cos(imp.angle)
            dur = PLATE_DURATION * max(1.0, 50.0 / v_n)
            specs.append(RunSpec(
                run_id=f"bare_{_impact_id(imp)}".replace(".", "p"),
                scene=plate_scene(imp, duration=dur, record_interval=PLATE_RECORD,
                                  preset=options.preset),
                params=dict(params, kind="bare", top=0.0, floor=-1.0), task=TASK))
    return specs


COLUMNS = ["run_id", "kind", "speed", "angle_deg", "radius_mm", "length_mm", "root_radius_mm",
           "pitch_mm", "nodes", "status", "peak_force", "impulse_magnitude", "time_to_arrest",
           "penetration", "bottomed_out", "rebound_speed", "peak_wire_strain", "wire_yields",
           "momentum_residual", "projectile_momentum_residual"]




def compare(rows: list[dict]) -> list[dict]:
    """Each fur run beside the bare-plate run of the same impact."""
    bare = {(r["speed"], r["angle_deg"], r["radius_mm"]): r for r in rows
            if r["kind"] == "bare" and r["status"] == "completed"}
    out = []
    for r in rows:
        if r["kind"] != "fur" or r["status"] != "completed":
            continue
        b = bare.get((r["speed"], r["angle_deg"], r["radius_mm"]))
        out.append(dict(r, bare_peak_force=b["peak_force"] if b else "",
                        peak_ratio=(b["peak_force"] / r["peak_force"]
                                    if b and r["peak_force"] else "")))
    return out


def _plots(out: Path, rows: list[dict], comparison: list[dict]) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import engine

    figures = []
    fig, ax = plt.subplots(figsize=(7, 4.5))
    keys = sorted({(r["angle_deg"], r["radius_mm"], r.get("length_mm"), r.get("root_radius_mm"),
                    r.get("pitch_mm")) for r in rows if r["kind"] == "fur"}, key=str)
    for k in keys:
        sel = sorted((r for r in rows if r["kind"] == "fur" and r["status"] == "completed"
                      and (r["angle_deg"], r["radius_mm"], r.get("length_mm"),
                           r.get("root_radius_mm"), r.get("pitch_mm")) == k),
                     key=lambda r: r["speed"])
        if sel:
            ax.plot([r["speed"] for r in sel], [r["peak_force"] for r in sel], "o-",
                    label=f"fur {k[2]:g} mm, r {k[3]:g} mm, pitch {k[4]:g} mm; "
                          f"{k[0]:g} deg, sphere r {k[1]:g} mm")
    for k in sorted({(r["angle_deg"], r["radius_mm"]) for r in rows if r["kind"] == "bare"}):
        sel = sorted((r for r in rows if r["kind"] == "bare" and r["status"] == "completed"
                      and (r["angle_deg"], r["radius_mm"]) == k), key=lambda r: r["speed"])
        if sel:
            ax.plot([r["speed"] for r in sel], [r["peak_force"] for r in sel], "s--",
                    label=f"bare plate; {k[0]:g} deg, sphere r {k[1]:g} mm")
    ax.set_xlabel("impact speed [m/s]")
    ax.set_ylabel("peak force transmitted to the plate [N]")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    figures.append(out / "peak_force.png")
    fig.savefig(figures[-1], dpi=130)
    plt.close(fig)

    if comparison:  # the first fur case and its bare plate, |F|(t)
        first = comparison[0]
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for run_id, label in ((first["run_id"], "fur"),
                              (f"bare_v{first['speed']:g}_a{first['angle_deg']:g}"
                               f"_r{first['radius_mm']:g}".replace(".", "p"), "bare plate")):
            h5 = out / "runs" / f"{run_id}.h5"
            if not h5.exists():
                continue
            with engine.open_result(h5) as res:
                f = res.series("bodies/plate/contact_force")
                names = [n for n in res.channels() if n.endswith("/root_force")]
                for n in names:
                    f = f - res.series(n)
                ax.plot(res.time * 1e3, np.linalg.norm(f, axis=1), label=label)
        ax.set_xlabel("time [ms]")
        ax.set_ylabel("|force transmitted to the plate| [N]")
        ax.set_yscale("symlog", linthresh=1.0)
        ax.set_title(f"{first['speed']:g} m/s at {first['angle_deg']:g} deg, sphere "
                     f"r {first['radius_mm']:g} mm", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend()
        fig.tight_layout()
        figures.append(out / "force_history.png")
        fig.savefig(figures[-1], dpi=130)
        plt.close(fig)
    return figures


def _run_study(options: Options, out: Path) -> int:
    from ..study_command import report_failures, run_study

    _check(options)
    code, outcomes = run_study(lambda: build_specs(options), out, options, desc="fur runs")
    if code is not None:
        return code
    rows = outcome_rows(outcomes, COLUMNS)
    write_table(out / "fur.csv", rows, COLUMNS)
    comparison = compare(rows)
    write_table(out / "comparison.csv", comparison,
               COLUMNS + ["bare_peak_force", "peak_ratio"])
    figures = _plots(out, rows, comparison)
    first = comparison[0] if comparison else None
    summary = {"runs": len(rows), "completed": sum(r["status"] == "completed" for r in rows)}
    if first:
        summary.update(first_case=first["run_id"], fur_peak_force=first["peak_force"],
                       bare_peak_force=first["bare_peak_force"],
                       peak_ratio=first["peak_ratio"], bottomed_out=first["bottomed_out"])
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    print(f"{'run':44s} {'peak F [N]':>11s} {'J [N s]':>10s} {'arrest [us]':>11s} "
          f"{'depth [mm]':>10s} bottomed  momentum check")
    for r in rows:
        if r["status"] != "completed":
            print(f"{r['run_id']:44s} {r['status']}")
            continue
        arrest = (f"{r['time_to_arrest'] * 1e6:11.1f}" if r["time_to_arrest"] not in ("", None)
                  else f"{'-':>11s}")
        print(f"{r['run_id']:44s} {r['peak_force']:11.4g} {r['impulse_magnitude']:10.4g} "
              f"{arrest} {r['penetration'] * 1e3:10.3f} {str(r['bottomed_out']):8s} "
              f"{r['momentum_residual'] * 100:.2f} %")
    for c in comparison:
        if c["peak_ratio"] != "":
            print(f"{c['run_id']}: the fur transmits {c['peak_ratio']:.3g}x less peak force "
                  "than the bare plate")
    print(f"Wrote {out}/fur.csv, comparison.csv, summary.json and "
          + ", ".join(p.name for p in figures))
    return report_failures(outcomes), summary


def add_parser(study_subparsers) -> None:
    from ..study_command import set_command

    p = study_subparsers.add_parser(
        "fur", help="space fur (seed 5.3.2, fig. 5.1): impacts into a fur-covered plate "
                    "against a bare plate",
        description="A steel sphere fired into a plate covered with steel fur and into the "
                    "bare plate: peak force transmitted to the plate, impulse, time to "
                    "arrest, penetration and whether the fur bottomed out, over impact "
                    "speed x angle x projectile radius x fur length x bristle radius x "
                    "pitch. Elastic contacts and wires: see docs/studies.md for the speeds "
                    "this holds at.")
    set_command(p, run, Options, default_output="study-fur")


run = api.study_run("fur", _run_study)
