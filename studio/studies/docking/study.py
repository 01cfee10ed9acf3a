"""``brush-studio study docking``: brush-assisted docking (seed 5.3.2) against the same
docking hull on hull, over closing speed x lateral offset x angular misalignment.

Every combination runs twice from the presets: ``docking`` (the chaser's silicone brush
meets the target's face; hull contact off, the closest hull gap reported) and
``docking_rigid`` (hull on hull with the pair's restitution). The target is shifted
sideways by the offset (along y) and turned about z by the misalignment; its hull starts the
preset's gap clear of the brush tips (or of the chaser's face). Outputs (``-o DIR``):
``docking.csv`` (one row per run: peak force and torque on the target, separation speed and
rebound ratio, soft capture, closest hull gap, the momentum check), ``comparison.csv`` (each
brush docking beside its rigid one), ``docking.png``, ``summary.json``; ``runs/`` one result
file per run.
"""
from __future__ import annotations

import copy
import itertools
import json
import math
from pathlib import Path

from pydantic import Field

from .. import api
from ..run_files import outcome_rows, write_table
from ..options import StudyOptions

TASK = "studio.studies.docking.task:docking_task"
#: the presets' simulated times at their 30 mm/s closing speed
BRUSH_DURATION, RIGID_DURATION, PRESET_SPEED = 2.0, 0.006, 0.03


class Options(StudyOptions):
    """``brush-studio study docking``: every combination of the lists runs."""

    preset: str = Field("docking",
                        description="the brush docking: free bodies 'chaser' (carrying one "
                                    "brush) and 'target' closing along x (default docking); "
                                    "the hull-on-hull reference is the docking_rigid preset",
                        json_schema_extra={"metavar": "NAME_OR_FILE", "scene": True,
                                           "design": True})
    speeds: list[float] = Field([30.0], min_length=1, description="closing speeds",
                                json_schema_extra={"unit": "mm/s"})
    offsets: list[float] = Field([0.0], min_length=1,
                                 description="lateral offsets of the target (along y)",
                                 json_schema_extra={"unit": "mm"})
    misalignments: list[float] = Field([0.0], min_length=1,
                                       description="angular misalignments of the target "
                                                   "(about z), 0 to 30",
                                       json_schema_extra={"unit": "deg"})
    nodes: int | None = Field(None, ge=2, le=64,
                              description="nodes per bristle (default: the preset's, 6)")
    no_rigid: bool = Field(False, description="leave out the hull-on-hull reference runs")
    duration: float | None = Field(
        None, gt=0, le=600,
        description="simulated time per brush docking; default the preset's 2 s, stretched "
                    "for slower closings (x 30 mm/s / speed)",
        json_schema_extra={"unit": "s"})


def _preset(ref: str) -> dict:
    from ..fur.scenes import scene_dict

    return scene_dict(ref)


def _quat_z(angle: float) -> list[float]:
    return [math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)]


def docking_scene(speed: float, offset: float, misalignment: float, *, brush: bool,
                  nodes=None, duration=None, preset: str = "docking") -> dict:
    """The preset ``docking`` (``brush``) or ``docking_rigid`` with the chaser closing at
    ``speed`` (m/s) and the target shifted by ``offset`` (m, y) and turned by
    ``misalignment`` (rad, about z); SI."""
    scene = copy.deepcopy(_preset(preset if brush else "docking_rigid"))
    chaser = next(b for b in scene["bodies"] if b["name"] == "chaser")
    target = next(b for b in scene["bodies"] if b["name"] == "target")
    a_c = chaser["shape"]["size"][0] / 2
    a_t = target["shape"]["size"][0] / 2
    b_t = target["shape"]["size"][1] / 2
    x_face = chaser["pose"]["position"][0] + a_c
    # the preset's clearance between what touches first (tips or face) and the target
    clearance = target["pose"]["position"][0] - a_t - x_face
    # turned about z, the target's near side reaches a cos + b sin toward the chaser
    reach = a_t * math.cos(misalignment) + b_t * math.sin(abs(misalignment))
    target["pose"] = {"position": [x_face + clearance + reach, offset, 0.0],
                      "orientation": _quat_z(misalignment)}
    chaser["velocity"] = [speed, 0.0, 0.0]
    stretch = max(1.0, PRESET_SPEED / speed)
    if brush:
        if nodes:
            scene["brushes"][0]["n_nodes"] = int(nodes)
        scene["run"]["duration"] = duration or BRUSH_DURATION * stretch
    else:
        scene["run"]["duration"] = RIGID_DURATION * stretch
    scene["name"] = "docking_case" if brush else "docking_rigid_case"
    scene["description"] = (f"study docking: {speed * 1e3:g} mm/s, offset {offset * 1e3:g} mm, "
                            f"misalignment {math.degrees(misalignment):g} deg, "
                            + ("with the brush" if brush else "hull on hull"))
    return scene


def build_specs(options: Options):
    from ..runner import RunSpec

    specs = []
    for v, off, mis in itertools.product(options.speeds, options.offsets,
                                         options.misalignments):
        params = {"speed_mm_s": v, "offset_mm": off, "misalignment_deg": mis}
        tag = f"v{v:g}_y{off:g}_a{mis:g}".replace(".", "p").replace("-", "m")
        for brush in (True, False):
            if not brush and options.no_rigid:
                continue
            specs.append(RunSpec(
                run_id=("brush_" if brush else "rigid_") + tag,
                scene=docking_scene(v * 1e-3, off * 1e-3, math.radians(mis), brush=brush,
                                    nodes=options.nodes, duration=options.duration,
                                    preset=options.preset),
                params=dict(params, kind="brush" if brush else "rigid"), task=TASK))
    return specs


COLUMNS = ["run_id", "kind", "speed_mm_s", "offset_mm", "misalignment_deg", "status",
           "peak_force", "peak_torque", "separation_speed", "rebound_ratio", "in_contact_at_end",
           "soft_capture", "contact_time", "min_hull_gap", "hulls_met", "target_spin_end",
           "momentum_change"]




def compare(rows) -> list[dict]:
    key = lambda r: (r["speed_mm_s"], r["offset_mm"], r["misalignment_deg"])  # noqa: E731
    rigid = {key(r): r for r in rows if r["kind"] == "rigid" and r["status"] == "completed"}
    out = []
    for r in rows:
        if r["kind"] != "brush" or r["status"] != "completed":
            continue
        g = rigid.get(key(r))
        out.append(dict(r, rigid_peak_force=g["peak_force"] if g else "",
                        rigid_rebound_ratio=g["rebound_ratio"] if g else "",
                        peak_force_ratio=(g["peak_force"] / r["peak_force"]
                                          if g and r["peak_force"] else "")))
    return out


def _plot(out: Path, rows) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    for kind, marker in (("brush", "o"), ("rigid", "s")):
        sel = [r for r in rows if r["kind"] == kind and r["status"] == "completed"]
        if not sel:
            continue
        x = list(range(len(sel)))
        a1.semilogy(x, [max(r["peak_force"], 1e-9) for r in sel], marker, label=kind)
        a2.plot(x, [r["rebound_ratio"] for r in sel], marker, label=kind)
        labels = [f"{r['speed_mm_s']:g} mm/s\n{r['offset_mm']:g} mm, {r['misalignment_deg']:g}°"
                  for r in sel]
    for ax in (a1, a2):
        ax.set_xticks(range(len(labels)))
        ax.set_xticklabels(labels, fontsize=7)
        ax.grid(True, alpha=0.3)
        ax.legend()
    a1.set_ylabel("peak contact force on the target [N]")
    a2.set_ylabel("separation speed / closing speed")
    fig.tight_layout()
    path = out / "docking.png"
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def _run_study(options: Options, out: Path):
    from ..study_command import report_failures, run_study

    bad = [f"speeds = {v:g}: outside (0, 2000] mm/s" for v in options.speeds
           if not 0 < v <= 2000]
    bad += [f"misalignments = {a:g}: outside [-30, 30] deg" for a in options.misalignments
            if abs(a) > 30]
    bad += [f"offsets = {y:g}: outside [-100, 100] mm" for y in options.offsets
            if abs(y) > 100]
    if bad:
        raise api.StudyInputError("; ".join(bad))
    code, outcomes = run_study(lambda: build_specs(options), out, options, desc="dockings")
    if code is not None:
        return code
    rows = outcome_rows(outcomes, COLUMNS)
    write_table(out / "docking.csv", rows, COLUMNS)
    comparison = compare(rows)
    write_table(out / "comparison.csv", comparison,
               COLUMNS + ["rigid_peak_force", "rigid_rebound_ratio", "peak_force_ratio"])
    _plot(out, rows)
    summary = {"runs": len(rows), "completed": sum(r["status"] == "completed" for r in rows),
               "cases": comparison}
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    print(f"{'run':26s} {'peak F [N]':>10s} {'peak T [N m]':>12s} {'rebound':>8s} "
          f"{'capture':>7s} {'hull gap [mm]':>13s} {'dp/p':>8s}")
    for r in rows:
        if r["status"] != "completed":
            print(f"{r['run_id']:26s} {r['status']}")
            continue
        print(f"{r['run_id']:26s} {r['peak_force']:10.4g} {r['peak_torque']:12.4g} "
              f"{r['rebound_ratio']:8.3f} {str(r['soft_capture']):>7s} "
              f"{r['min_hull_gap'] * 1e3:13.2f} {r['momentum_change']:8.1e}")
    for c in comparison:
        if c["peak_force_ratio"] != "":
            print(f"{c['run_id']}: the brush lowers the peak force {c['peak_force_ratio']:.3g}x"
                  f"{' (the hulls met: it bottomed out)' if c['hulls_met'] else ''}")
    print(f"Wrote {out}/docking.csv, comparison.csv, summary.json, docking.png")
    return report_failures(outcomes), summary


def add_parser(study_subparsers) -> None:
    from ..study_command import set_command

    p = study_subparsers.add_parser(
        "docking", help="brush-assisted docking (seed 5.3.2) against hull-on-hull docking",
        description="Two small spacecraft close along x, the chaser carrying a silicone "
                    "brush on its docking face (preset docking), and the same docking hull on "
                    "hull (docking_rigid): peak force and torque on the target, rebound "
                    "(separation speed over closing speed) or soft capture, the closest "
                    "hull gap, over closing speed x lateral offset x angular misalignment.")
    set_command(p, run, Options, default_output="study-docking")


run = api.study_run("docking", _run_study)
