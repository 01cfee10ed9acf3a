"""``brush-studio study capture``: capture of a tumbling target by a gripper brush on orbit
(issue 27 item 2), over target spin x approach error.

Every combination of spin rate and offset runs the preset (``gripper_capture_orbit``: a
free chaser whose two servo-driven jaws, each carrying a brush, close on a tumbling target in
the Hill frame; its description says what is and is not modelled) with the target spinning
at the rate about ``--spin-axis`` and shifted by the offset along ``--offset-axis`` (z:
across the jaws' closing axis; x: along it, toward the right jaw; y: toward/away from the
chaser). The capture criterion (:mod:`.criterion`): the target's speed and angular speed
relative to the chaser below ``--max-speed`` and ``--max-rate``, its centre between the jaws,
from some time to the end of the run and for at least ``--hold``. Outputs (``-o DIR``):
``capture.csv`` (one row per run: captured, time to capture, residual relative speed and
rate, peak contact force and torque on the target, peak load on the chaser's jaw mounts),
``capture.png`` (success map and time to capture over spin x offset), ``summary.json``;
``runs/`` one result file per run.
"""
from __future__ import annotations

import copy
import itertools
import json
import math
from pathlib import Path
from typing import Literal

from pydantic import Field

from .. import api
from ..run_files import outcome_rows, write_table
from ..options import StudyOptions

TASK = "studio.studies.capture.task:capture_task"
AXES = {"x": 0, "y": 1, "z": 2}


class Options(StudyOptions):
    """``brush-studio study capture``: every spin x offset combination runs."""

    preset: str = Field("gripper_capture_orbit",
                        description="the capture scene: free bodies 'target', 'chaser', "
                                    "'jaw_left', 'jaw_right' (jaws closing along x), as the "
                                    "gripper_capture_orbit preset",
                        json_schema_extra={"metavar": "NAME_OR_FILE", "scene": True})
    spins: list[float] = Field([10.0], min_length=1,
                               description="target spin rates, 0 to 90",
                               json_schema_extra={"unit": "deg/s"})
    spin_axis: list[float] = Field([1.0, 1.0, 1.0], min_length=3, max_length=3,
                                   description="target spin axis (world/Hill axes; normalised)")
    offsets: list[float] = Field([0.0], min_length=1,
                                 description="approach errors: the target's offset from the "
                                             "jaws' centre line along --offset-axis",
                                 json_schema_extra={"unit": "mm"})
    offset_axis: Literal["x", "y", "z"] = Field(
        "z", description="axis of the offsets: z across the closing axis, x along it")
    max_speed: float = Field(2.0, gt=0, le=1000,
                             description="capture: relative speed below this",
                             json_schema_extra={"unit": "mm/s"})
    max_rate: float = Field(1.0, gt=0, le=360,
                            description="capture: relative angular speed below this",
                            json_schema_extra={"unit": "deg/s"})
    hold: float = Field(0.5, gt=0, le=600,
                        description="capture: held (and kept to the end of the run) this long",
                        json_schema_extra={"unit": "s"})
    nodes: int | None = Field(None, ge=2, le=64,
                              description="nodes per bristle (default: the preset's)")
    duration: float | None = Field(None, gt=0, le=600,
                                   description="simulated time per run (default: the "
                                               "preset's)", json_schema_extra={"unit": "s"})


def _preset(ref: str) -> dict:
    from ..fur.scenes import scene_dict

    return scene_dict(ref)


def _body(scene: dict, name: str) -> dict:
    try:
        return next(b for b in scene["bodies"] if b["name"] == name)
    except StopIteration:
        raise api.StudyInputError(f"preset {scene.get('name')!r}: no body {name!r} (study "
                                  f"capture needs target, chaser, jaw_left, jaw_right)"
                                  ) from None


def geometry(scene: dict) -> dict:
    """What the study reads from the scene (SI): ``between_radius`` (the target's half size:
    the jaws' centre line crosses its faces), ``clearance`` (the gap between the open brush
    tips and the target's faces along x)."""
    target = _body(scene, "target")
    jaw = _body(scene, "jaw_right")
    half = target["shape"]["size"][0] / 2
    brush = next(b for b in scene["brushes"] if b.get("mount") == "jaw_right")
    reach = brush["bristle_length"] + brush["tip_radius"]
    tips = jaw["pose"]["position"][0] - jaw["shape"]["size"][0] / 2 - reach
    x_target = target.get("pose", {}).get("position", [0.0, 0.0, 0.0])[0]
    return {"between_radius": half, "clearance": tips - x_target - half}


def capture_scene(spin: float, axis, offset: float, offset_axis: str, *, preset: str,
                  nodes=None, duration=None) -> dict:
    """The preset with the target spinning at ``spin`` (rad/s) about ``axis`` and shifted
    by ``offset`` (m) along ``offset_axis``; SI."""
    scene = copy.deepcopy(_preset(preset))
    target = _body(scene, "target")
    n = math.sqrt(sum(c * c for c in axis))
    target["angular_velocity"] = [spin * c / n for c in axis]
    pose = target.setdefault("pose", {})
    pos = list(pose.get("position", [0.0, 0.0, 0.0]))
    pos[AXES[offset_axis]] += offset
    pose["position"] = pos
    if nodes:
        for b in scene["brushes"]:
            b["n_nodes"] = int(nodes)
    if duration:
        scene["run"]["duration"] = duration
    scene["name"] = "capture_case"
    scene["description"] = (f"study capture: target spin {math.degrees(spin):g} deg/s about "
                            f"{list(axis)}, offset {offset * 1e3:g} mm along {offset_axis}; "
                            + scene.get("description", ""))
    return scene


def _tag(spin, offset):
    return f"w{spin:g}_d{offset:g}".replace(".", "p").replace("-", "m")


def build_specs(options: Options):
    from ..runner import RunSpec

    radius = geometry(_preset(options.preset))["between_radius"]
    params = {"max_speed": options.max_speed * 1e-3, "max_rate": math.radians(options.max_rate),
              "hold": options.hold, "between_radius": radius}
    return [RunSpec(run_id=_tag(w, d),
                    scene=capture_scene(math.radians(w), options.spin_axis, d * 1e-3,
                                        options.offset_axis, preset=options.preset,
                                        nodes=options.nodes, duration=options.duration),
                    params=dict(params, spin_deg_s=w, offset_mm=d), task=TASK)
            for w, d in itertools.product(options.spins, options.offsets)]


COLUMNS = ["run_id", "spin_deg_s", "offset_mm", "status", "captured", "time_to_capture",
           "first_hold", "lost", "residual_speed", "residual_rate", "initial_rate",
           "between_at_end", "first_contact", "peak_target_force", "peak_target_torque",
           "peak_chaser_force", "peak_chaser_torque"]


def _plot(out: Path, rows, options: Options) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spins, offsets = sorted(set(options.spins)), sorted(set(options.offsets))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    for r in rows:
        if r["status"] != "completed":
            continue
        x, y = offsets.index(r["offset_mm"]), spins.index(r["spin_deg_s"])
        a1.scatter(x, y, s=300, marker="o" if r["captured"] else "x",
                   c="tab:green" if r["captured"] else "tab:red")
        if r["captured"]:
            a2.scatter(x, y, s=300, c=[[0.2, 0.4, 0.8]])
            a2.annotate(f"{r['time_to_capture']:.2f} s", (x, y), ha="center",
                        va="bottom", xytext=(0, 10), textcoords="offset points")
        else:
            a2.annotate(f"{math.degrees(r['residual_rate']):.1f} °/s\nleft", (x, y),
                        ha="center", va="center", color="tab:red", fontsize=8)
    for ax in (a1, a2):
        ax.set_xticks(range(len(offsets)), [f"{d:g}" for d in offsets])
        ax.set_yticks(range(len(spins)), [f"{w:g}" for w in spins])
        ax.set_xlim(-0.5, len(offsets) - 0.5)
        ax.set_ylim(-0.5, len(spins) - 0.5)
        ax.set_xlabel(f"target offset along {options.offset_axis} [mm]")
        ax.set_ylabel("target spin [deg/s]")
        ax.grid(True, alpha=0.3)
    a1.set_title("captured (o) / not (x)")
    a2.set_title("time to capture (or relative rate left)")
    fig.tight_layout()
    path = out / "capture.png"
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def _run_study(options: Options, out: Path):
    from ..study_command import report_failures, run_study

    geo = geometry(_preset(options.preset))
    bad = [f"spins = {w:g}: outside [0, 90] deg/s" for w in options.spins if not 0 <= w <= 90]
    bad += [f"offsets = {d:g}: outside [-300, 300] mm" for d in options.offsets
            if abs(d) > 300]
    if options.offset_axis == "x":
        # along the closing axis the target must start clear of both jaws' open tips
        lim = geo["clearance"] * 1e3
        bad += [f"offsets = {d:g}: along x the target must start clear of the open brush "
                f"tips, |offset| < {lim:g} mm" for d in options.offsets if abs(d) >= lim]
    if not any(options.spin_axis):
        bad.append("spin_axis = [0, 0, 0]: give a non-zero axis")
    if bad:
        raise api.StudyInputError("; ".join(bad))
    code, outcomes = run_study(lambda: build_specs(options), out, options, desc="captures")
    if code is not None:
        return code
    rows = outcome_rows(outcomes, COLUMNS)
    write_table(out / "capture.csv", rows, COLUMNS)
    _plot(out, rows, options)
    done = [r for r in rows if r["status"] == "completed"]
    summary = {"runs": len(rows), "completed": len(done),
               "captured": sum(bool(r["captured"]) for r in done),
               "criterion": {"max_speed_mm_s": options.max_speed,
                             "max_rate_deg_s": options.max_rate, "hold_s": options.hold,
                             "between_radius_mm": geo["between_radius"] * 1e3},
               "cases": rows}
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    print(f"{'run':14s} {'captured':>8s} {'t_cap [s]':>9s} {'v_rel [mm/s]':>12s} "
          f"{'w_rel [deg/s]':>13s} {'F_tgt [N]':>9s} {'T_tgt [N m]':>11s} "
          f"{'F_chaser [N]':>12s} {'T_chaser [N m]':>14s}")
    for r in rows:
        if r["status"] != "completed":
            print(f"{r['run_id']:14s} {r['status']}")
            continue
        tc = f"{r['time_to_capture']:.2f}" if r["captured"] else "-"
        print(f"{r['run_id']:14s} {str(r['captured']):>8s} {tc:>9s} "
              f"{r['residual_speed'] * 1e3:12.3f} {math.degrees(r['residual_rate']):13.3f} "
              f"{r['peak_target_force']:9.3f} {r['peak_target_torque']:11.4f} "
              f"{r['peak_chaser_force']:12.3f} {r['peak_chaser_torque']:14.4f}")
    print(f"Wrote {out}/capture.csv, summary.json, capture.png")
    return report_failures(outcomes), summary


def add_parser(study_subparsers) -> None:
    from ..study_command import set_command

    p = study_subparsers.add_parser(
        "capture", help="capture of a tumbling target by a gripper brush on orbit",
        description="A free chaser's two servo-driven jaws, each carrying a brush, close on "
                    "a tumbling target in the Hill frame (preset gripper_capture_orbit): "
                    "captured or not, time to capture, residual relative speed and rate, "
                    "peak loads on the target and on the chaser's jaw mounts, over target "
                    "spin x approach error.")
    set_command(p, run, Options, default_output="study-capture")


run = api.study_run("capture", _run_study)
