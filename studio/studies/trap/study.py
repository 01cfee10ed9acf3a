"""``brush-studio study trap``: the micro-object trap (issue 27 item 4). A mm-sized glass bead
is fired into a sticky brush (preset ``micro_trap``: the seed's silicone bristles, the
bristle-bead contact adhesive, docs/scene.md) over impact speed x adhesion (the pull-off
force per contact) x brush pitch; every combination is one run.

The bead keeps the preset's size, direction (its angle from the brush's axis) and aim (its
centre crosses the tip plane half a pitch and a quarter pitch off the brush's centre, scaled
with the pitch); its surface starts 2 mm above the tips. Outputs (``-o DIR``): ``trap.csv``
(one row per run: trapped, how the shot ended, depth reached below the tip plane, arrested
and the time to arrest, rebound speed), ``trap.png`` (fraction trapped and depth against
speed, one line per adhesion), ``summary.json``; ``runs/`` one result file per run.

Speeds of cm/s to a few m/s are what this elastic model covers; hypervelocity impacts (km/s)
are outside it (material failure, shock waves, no plasticity: docs/studies.md).
"""
from __future__ import annotations

import copy
import itertools
import json
import math
from pathlib import Path

from pydantic import Field

from .. import api
from ..options import StudyOptions
from ..run_files import outcome_rows, write_table

TASK = "studio.studies.trap.task:trap_task"
#: where the bead's centre crosses the tip plane, in pitches from the brush's centre, and
#: its surface's start above the tips, m (as static_presets/trap_presets.py)
AIM = (0.5, 0.25)
START_GAP = 0.002
#: the shots of one case cross the tip plane at AIM + k (R2_X, R2_Y) modulo one pitch, k = 0,
#: 1, ...: the R2 low-discrepancy sequence, spread evenly over the brush's unit cell
R2_X, R2_Y = 0.7548776662466927, 0.5698402909980532


def aim(shot: int) -> tuple[float, float]:
    """Where shot ``shot`` crosses the tip plane, in pitches from the brush's centre."""
    return ((AIM[0] + shot * R2_X) % 1.0, (AIM[1] + shot * R2_Y) % 1.0)


class Options(StudyOptions):
    """``brush-studio study trap``: the sweep's values (each a list: every combination
    runs)."""

    preset: str = Field("micro_trap",
                        description="the trap scene: one brush 'brush' growing along +z from "
                                    "a fixed base, a free sphere 'bead' and an adhesive "
                                    "contact pair between their materials (default "
                                    "micro_trap)",
                        json_schema_extra={"metavar": "NAME_OR_FILE", "scene": True,
                                           "design": True})
    speeds: list[float] = Field([0.2, 0.5, 1.0, 2.0], min_length=1,
                                description="impact speeds, 0.01 to 5 (the elastic model's "
                                            "range; km/s impacts are outside it)",
                                json_schema_extra={"unit": "m/s"})
    adhesions: list[float] = Field([0.0, 1.0, 5.0], min_length=1,
                                   description="pull-off force per bristle-bead contact, 0 to "
                                               "100",
                                   json_schema_extra={"unit": "mN"})
    pitches: list[float] = Field([3.0], min_length=1,
                                 description="bristle pitch, both directions, 2.5 to 20 (the "
                                             "seed bristle's root is 2 mm thick)",
                                 json_schema_extra={"unit": "mm"})
    shots: int = Field(3, ge=1, le=64,
                       description="shots per case, each aimed at another point of the "
                                   "brush's unit cell (the fraction trapped is over them)")
    nodes: int | None = Field(None, ge=2, le=64,
                              description="nodes per bristle (default: the preset's, 6)")
    duration: float | None = Field(
        None, gt=0, le=10,
        description="simulated time per shot; default 2.5 x the brush's length over the "
                    "speed (40 ms to 3 s)",
        json_schema_extra={"unit": "s"})


def _preset(ref: str) -> dict:
    from ..fur.scenes import scene_dict

    return scene_dict(ref)


def tip_plane(brush: dict) -> float:
    """z of the tips' top: the base's z, the bristle length and the tip radius (SI)."""
    return (brush.get("base", {}).get("position", [0.0, 0.0, 0.0])[2]
            + brush["bristle_length"] + brush["tip_radius"])


def shot_duration(speed: float, length: float) -> float:
    """2.5 crossings of the brush's length at the impact speed, 40 ms to 3 s."""
    return min(3.0, max(0.04, 2.5 * (length + START_GAP) / speed))


def trap_scene(speed: float, adhesion: float, pitch: float, *, shot: int = 0, nodes=None,
               duration=None, preset: str = "micro_trap") -> tuple[dict, dict]:
    """The preset with the bead fired at ``speed`` (m/s), aimed at :func:`aim` (``shot``),
    the bristle-bead contact's pull-off force ``adhesion`` (N) and the brush's ``pitch`` (m);
    SI. Returns (scene, geometry: tip and roots' planes and the footprint's half width)."""
    scene = copy.deepcopy(_preset(preset))
    brush = scene["brushes"][0]
    bead = next(b for b in scene["bodies"] if b["name"] == "bead")
    brush["pitch"] = [pitch, pitch]
    if nodes:
        brush["n_nodes"] = int(nodes)
    pair = next(p for p in scene["contact_pairs"]
                if sorted(p["materials"]) == sorted([brush["material"], bead["material"]]))
    pair["adhesion_force"] = adhesion
    vx, _, vz = bead["velocity"]
    angle = math.atan2(vx, -vz)
    radius = bead["shape"]["radius"]
    tip_z = tip_plane(brush)
    z0 = tip_z + radius + START_GAP
    ax, ay = aim(shot)
    bead["pose"] = {"position": [ax * pitch - (z0 - tip_z) * math.tan(angle), ay * pitch, z0]}
    bead["velocity"] = [speed * math.sin(angle), 0.0, -speed * math.cos(angle)]
    scene["run"]["duration"] = duration or shot_duration(speed, brush["bristle_length"])
    scene["name"] = "trap_case"
    scene["description"] = (f"study trap: {speed:g} m/s, pull-off {adhesion * 1e3:g} mN per "
                            f"contact, pitch {pitch * 1e3:g} mm, shot {shot}")
    root_z = tip_z - brush["bristle_length"] - brush["tip_radius"]
    n = max(brush.get("rows", 1), brush.get("columns", 1))
    return scene, {"tip_z": tip_z, "root_z": root_z,
                   "half_width": (n - 1) * pitch / 2 + brush["root_radius"]}


def build_specs(options: Options):
    from ..runner import RunSpec

    specs = []
    for v, a, p, k in itertools.product(options.speeds, options.adhesions, options.pitches,
                                        range(options.shots)):
        scene, geometry = trap_scene(v, a * 1e-3, p * 1e-3, shot=k, nodes=options.nodes,
                                     duration=options.duration, preset=options.preset)
        tag = f"v{v:g}_a{a:g}_p{p:g}_s{k}".replace(".", "p")
        specs.append(RunSpec(run_id=tag, scene=scene, task=TASK,
                             params=dict({"speed_m_s": v, "adhesion_mN": a, "pitch_mm": p,
                                          "shot": k}, **geometry)))
    return specs


COLUMNS = ["run_id", "speed_m_s", "adhesion_mN", "pitch_mm", "shot", "status", "trapped",
           "outcome", "depth_mm", "arrested", "time_to_arrest", "rebound_speed", "end_speed",
           "touching_at_end", "first_contact"]


def _rows(outcomes) -> list[dict]:
    """The table's rows; the depth in mm, at most the brush's depth (tips to roots' plane: a
    bead that passed the roots flies on, which is no depth of the brush)."""
    rows = outcome_rows(outcomes, COLUMNS + ["depth"])
    for o, r in zip(outcomes, rows):
        if r.get("depth") not in (None, ""):
            full = o.params["tip_z"] - o.params["root_z"]
            r["depth_mm"] = min(r["depth"], full) * 1e3
    return rows


def fractions(rows) -> list[dict]:
    """Per (adhesion, pitch, speed): runs, trapped fraction, mean depth (mm)."""
    groups: dict = {}
    for r in rows:
        if r["status"] != "completed":
            continue
        groups.setdefault((r["adhesion_mN"], r["pitch_mm"], r["speed_m_s"]), []).append(r)
    out = []
    for (a, p, v), rs in sorted(groups.items()):
        out.append({"adhesion_mN": a, "pitch_mm": p, "speed_m_s": v, "runs": len(rs),
                    "fraction_trapped": sum(bool(r["trapped"]) for r in rs) / len(rs),
                    "depth_mm": sum(r["depth_mm"] for r in rs) / len(rs)})
    return out


def _plot(out: Path, table) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from matplotlib.ticker import NullFormatter, ScalarFormatter

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    adhesions = sorted({g["adhesion_mN"] for g in table})
    pitches = sorted({g["pitch_mm"] for g in table})
    speeds = sorted({g["speed_m_s"] for g in table})
    styles = ["-", "--", ":", "-."]
    for i, a in enumerate(adhesions):
        for j, p in enumerate(pitches):
            sel = [g for g in table if g["adhesion_mN"] == a and g["pitch_mm"] == p]
            if not sel:
                continue
            v = [g["speed_m_s"] for g in sel]
            label = f"{a:g} mN" + (f", pitch {p:g} mm" if len(pitches) > 1 else "")
            kw = dict(color=f"C{i}", linestyle=styles[j % 4], marker="os^v"[j % 4],
                      label=label, alpha=0.85)
            # the fractions of equal cases coincide: each line shifted by 1 % to stay visible
            a1.semilogx(v, [g["fraction_trapped"] + 0.01 * (i - j) for g in sel], **kw)
            a2.semilogx(v, [g["depth_mm"] for g in sel], **kw)
    a1.set_ylabel("fraction trapped")
    a1.set_ylim(-0.05, 1.05)
    a2.set_ylabel("depth reached below the tips [mm]\n(at most the brush's depth)")
    for ax in (a1, a2):
        ax.set_xlabel("impact speed [m/s]")
        ax.set_xticks(speeds)
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, alpha=0.3)
        ax.legend(title="pull-off per contact", fontsize=8)
    fig.tight_layout()
    path = out / "trap.png"
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def _run_study(options: Options, out: Path):
    from ..study_command import report_failures, run_study

    bad = [f"speeds = {v:g}: outside [0.01, 5] m/s (km/s impacts are outside this elastic "
           f"model)" for v in options.speeds if not 0.01 <= v <= 5.0]
    bad += [f"adhesions = {a:g}: outside [0, 100] mN" for a in options.adhesions
            if not 0.0 <= a <= 100.0]
    bad += [f"pitches = {p:g}: outside [2.5, 20] mm" for p in options.pitches
            if not 2.5 <= p <= 20.0]
    if bad:
        raise api.StudyInputError("; ".join(bad))
    code, outcomes = run_study(lambda: build_specs(options), out, options, desc="shots")
    if code is not None:
        return code
    rows = _rows(outcomes)
    write_table(out / "trap.csv", rows, COLUMNS)
    table = fractions(rows)
    _plot(out, table)
    summary = {"runs": len(rows), "completed": sum(r["status"] == "completed" for r in rows),
               "trapped": sum(bool(r.get("trapped")) for r in rows), "by_case": table}
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    print(f"{'run':22s} {'outcome':>9s} {'depth [mm]':>10s} {'arrest [ms]':>11s} "
          f"{'rebound [m/s]':>13s}")
    for r in rows:
        if r["status"] != "completed":
            print(f"{r['run_id']:22s} {r['status']}")
            continue
        arrest = (f"{r['time_to_arrest'] * 1e3:11.1f}" if r["time_to_arrest"] not in (None, "")
                  else f"{'-':>11s}")
        print(f"{r['run_id']:22s} {r['outcome']:>9s} {r['depth_mm']:10.2f} {arrest} "
              f"{r['rebound_speed']:13.3f}")
    print(f"Wrote {out}/trap.csv, summary.json, trap.png")
    return report_failures(outcomes), summary


def add_parser(study_subparsers) -> None:
    from ..study_command import set_command

    p = study_subparsers.add_parser(
        "trap", help="the micro-object trap: beads fired into a sticky brush (issue 27)",
        description="A mm-sized glass bead fired into a sticky brush of silicone bristles "
                    "(preset micro_trap; the bristle-bead contact adhesive): whether it is "
                    "trapped, the depth it reaches below the tips, the time to arrest and the "
                    "rebound speed, over impact speed x adhesion (pull-off force per contact) "
                    "x brush pitch. Speeds of cm/s to m/s: hypervelocity (km/s) impacts are "
                    "outside this elastic model.")
    set_command(p, run, Options, default_output="study-trap")


run = api.study_run("trap", _run_study)
