"""Sensitivity (one parameter at a time) and Monte Carlo (all at once) wedge studies (seed 4.2).

    brush-studio study sensitivity -o DIR [--preset wedge_30 | --angles 30,45,60,75]
    brush-studio study montecarlo --samples 100 -o DIR [--angles ...] [--seed 1]

The uncertain parameters and their ranges (seed 4.2, DESIGN §4):

| parameter | nominal | range |
|---|---|---|
| bristle Young's modulus E | 2.7 MPa | 2.7 ± 1.1 MPa |
| bristle density | scene's (1700) | 1100 – 2300 kg/m^3 |
| Poisson's ratio nu | scene's (0.48) | 0.47 – 0.49 |
| silicone–silicone friction angle | 44° | 44 ± 2° |
| silicone–wedge friction angle | 24° | 24 ± 2° |

``sensitivity`` runs the nominal scene and each parameter at the two ends of its range
(the others nominal): 1 + 2 x 5 runs per scene. ``montecarlo`` draws every parameter
uniformly from its range at once (``--seed``, reproducible: a restart draws the same
samples) and reports the mean ± std of the force per depth and phase (like seed fig. 4.18).
Both run the wedge protocol (:mod:`studio.studies.wedge.cycle`, quasi-static by default): sensitivity
to 10 mm, montecarlo at the scene's own resolution and full depth (33 mm and back in the
presets, as the seed did); ``--depth-mm`` and ``--nodes`` change that.
"""
from __future__ import annotations

import copy
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

# name: (label, unit shown, low, high, nominal or None = the scene's value); SI inside
PARAMETERS = {
    "youngs_modulus": ("bristle Young's modulus", "MPa", 1.6e6, 3.8e6, 2.7e6),
    "density": ("bristle density", "kg/m^3", 1100.0, 2300.0, None),
    "poisson_ratio": ("bristle Poisson's ratio", "", 0.47, 0.49, None),
    "friction_bristle_bristle": ("silicone-silicone friction angle", "deg",
                                 math.radians(42), math.radians(46), math.radians(44)),
    "friction_bristle_wedge": ("silicone-wedge friction angle", "deg",
                               math.radians(22), math.radians(26), math.radians(24)),
}
_SHOW = {"MPa": 1e-6, "deg": 180 / math.pi, "kg/m^3": 1.0, "": 1.0}


def show(name: str, value: float) -> str:
    unit = PARAMETERS[name][1]
    return f"{value * _SHOW[unit]:.4g}{(' ' + unit) if unit else ''}"


def _bristle_material(scene: dict, brush: str) -> str:
    for b in scene["brushes"]:
        if b["name"] == brush:
            return b["material"]
    raise StudyInputError(f"no brush {brush!r}")


def _pair(scene: dict, a: str, b: str) -> dict:
    for cp in scene.setdefault("contact_pairs", []):
        if sorted(cp["materials"]) == sorted([a, b]):
            return cp
    cp = {"materials": [a, b]}
    scene["contact_pairs"].append(cp)
    return cp


def apply_parameters(scene: dict, values: dict, *, brush: str = "brush",
                     body: str = "wedge") -> dict:
    """A copy of ``scene`` with the uncertain parameters set (SI: Pa, kg/m^3, -, rad). The
    bristle material is given its own copy (``<material>``, changed in place: the wedge and
    other bodies have other materials in the presets)."""
    scene = copy.deepcopy(scene)
    mat = _bristle_material(scene, brush)
    wedge_mat = next((b["material"] for b in scene.get("bodies", []) if b["name"] == body),
                     None)
    if wedge_mat is None:
        raise StudyInputError(f"no body {body!r}")
    if wedge_mat == mat:
        raise StudyInputError("the wedge and the bristles share a material: the study cannot "
                              "vary them apart")
    m = scene["materials"][mat]
    for name, v in values.items():
        if name in ("youngs_modulus", "density", "poisson_ratio"):
            m[name] = float(v)
        elif name == "friction_bristle_bristle":
            _pair(scene, mat, mat)["friction_angle"] = float(v)
        elif name == "friction_bristle_wedge":
            _pair(scene, mat, wedge_mat)["friction_angle"] = float(v)
        else:
            raise StudyInputError(f"unknown parameter {name!r}")
    return scene


def nominal_values(scene: dict, brush: str = "brush") -> dict:
    """The nominal value of each parameter: the table's, or the scene's own."""
    mat = _bristle_material(scene, brush)
    out = {}
    for name, (_, _, lo, hi, nom) in PARAMETERS.items():
        if nom is None:
            nom = scene["materials"][mat][name]
        out[name] = nom
    return out


class SensitivityOptions(ProtocolOptions):
    """``brush-studio study sensitivity``: the scenes (preset names or files; default
    wedge_60) and wedge angles; default depth 10 mm."""

    preset: list[str] = Field(
        default_factory=list,
        description="scene file or preset name (repeat for several; default wedge_60)",
        json_schema_extra={"metavar": "SCENE", "scene": True,
                                           "design": True})
    angles: list[Annotated[float, Field(gt=0, lt=180)]] = Field(
        default_factory=list,
        description="wedge angles in degrees: the presets wedge_<angle> (or one --preset with "
                    "its angle changed)", json_schema_extra={"metavar": "DEG,...",
                                                             "unit": "deg"})


class MonteCarloOptions(SensitivityOptions):
    """``brush-studio study montecarlo``: ``samples`` parameter sets per scene drawn with
    ``seed``; default: the scene's resolution and full depth."""

    samples: int = Field(100, ge=2, description="samples per scene (default 100; at least 2 "
                                                "for a standard deviation)",
                         json_schema_extra={"metavar": "N"})
    seed: int = Field(1, description="random seed of the samples")


def _common(options, default_depth_mm: float, default_nodes: Optional[int]):
    """Scenes (with the protocol) for the sensitivity and Monte Carlo studies."""
    if options.depth_mm is None:
        options.depth_mm = default_depth_mm
    if options.nodes is None:
        options.nodes = default_nodes
    return resolve_scenes(options.preset, options.angles)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "sensitivity", help="one uncertain parameter at a time over its range (seed 4.2)",
        description="The wedge protocol for the nominal scene and for each uncertain "
                    "parameter (E 2.7 +- 1.1 MPa, density 1100-2300 kg/m^3, nu 0.47-0.49, "
                    "friction angles 44 +- 2 and 24 +- 2 deg) at both ends of its range. "
                    "Default depth 10 mm. Writes sensitivity.csv, sensitivity.png, "
                    "study.json and one HDF5 per run.")
    set_command(p, run_sensitivity, SensitivityOptions)

    m = sub.add_parser(
        "montecarlo", help="all uncertain parameters at once; mean +- std per depth "
                           "(seed fig. 4.18)",
        description="Draw every uncertain parameter uniformly from its range, run the wedge "
                    "protocol for each sample and report mean +- std of the force per depth. "
                    "Default: the scene's resolution and full depth (the seed's 33 mm). "
                    "Writes montecarlo.csv, samples.csv, montecarlo.png, study.json and one "
                    "HDF5 per sample.")
    set_command(m, run_montecarlo, MonteCarloOptions)


def _prepare(options, default_depth_mm, default_nodes):
    import engine

    try:
        return _common(options, default_depth_mm, default_nodes)
    except engine.SceneError as exc:
        raise StudyInputError("invalid scene: " + "; ".join(str(p) for p in exc.problems)
                              ) from None


def _run_and_write(make_specs, options, out: Path, desc: str, kept: str, write) -> int:
    """The body both commands share: build the runs (``make_specs()``; a bad input or an
    invalid scene is exit 2 before anything runs), run them (a cancel keeps the finished
    ``kept``: exit 130) and write the outputs (``write(out, specs, outcomes, wall)``)."""
    try:
        specs = make_specs()
        t0 = time.perf_counter()
        bad = validate_scenes([s.scene for s in specs])
        if bad:
            raise StudyInputError(bad)
        outcomes = run_many_from_args(specs, out, options, desc=desc)
    except KeyboardInterrupt:
        print(f"cancelled: finished {kept} are kept; run the same command again to go on",
              file=sys.stderr)
        return EXIT_CANCELLED
    wall = time.perf_counter() - t0
    return write(out, specs, outcomes, wall)


# ----------------------------------------------------------------------------- sensitivity
def _run_sensitivity(options: SensitivityOptions, out: Path) -> int:
    return _run_and_write(lambda: _sensitivity_specs(options), options, out, "sensitivity runs",
                          "runs", write_sensitivity_outputs)


run_sensitivity = api.study_run("sensitivity", _run_sensitivity)


def _sensitivity_specs(options: SensitivityOptions) -> list:
    """The nominal run and each parameter at both ends of its range, for every scene."""
    scenes = _prepare(options, 10.0, None)
    specs = []
    for rid, scene, src in scenes:
        scene = apply_resolution(scene, options.nodes)
        nom = nominal_values(scene)
        cases = [("nominal", None, None)]
        for name, (_, _, lo, hi, _) in PARAMETERS.items():
            cases += [(f"{name}_low", name, lo), (f"{name}_high", name, hi)]
        for case, name, value in cases:
            values = dict(nom)
            if name is not None:
                values[name] = value
            sc = apply_parameters(scene, values)
            specs.append(RunSpec(f"{rid}.{case}", sc, {
                "scene": rid, "case": case, "parameter": name, "value": value,
                "values": values, "angle_deg": wedge_angle_deg(sc), "source": src,
                "protocol": protocol_from_options(sc, options)}, TASK))
    print(f"sensitivity: {len(scenes)} scene(s) x {len(specs) // len(scenes)} runs, to "
          f"{options.depth_mm:g} mm")
    return specs


def write_sensitivity_outputs(out: Path, specs, outcomes, wall) -> int:
    from .plots import plot_sensitivity

    rows = []
    by_scene: dict = {}
    for spec, o in zip(specs, outcomes):
        if not o.ok:
            continue
        s, pr = numeric_summary(o.summary), spec.params
        by_scene.setdefault(pr["scene"], []).append((pr, s))
        for d, f, ph in zip(s["depth_m"], s["force_N"], s["phase"]):
            rows.append([pr["scene"], "" if pr["angle_deg"] is None else f"{pr['angle_deg']:.6g}",
                         pr["case"], pr["parameter"] or "",
                         "" if pr["value"] is None else f"{pr['value']:.6g}",
                         f"{d:.6g}", f"{f:.9g}", ph])
    with open(out / "sensitivity.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["scene", "angle_deg", "case", "parameter", "value_si", "depth_m",
                    "force_N", "phase"])
        w.writerows(rows)
    summary = {}
    for scene_id, runs in by_scene.items():
        nominal = next((s for pr, s in runs if pr["case"] == "nominal"), None)
        panels = []
        summary[scene_id] = {}
        for name, (label, unit, lo, hi, _) in PARAMETERS.items():
            curves = []
            if nominal is not None:
                curves.append(("nominal", nominal["depth_m"], nominal["force_N"],
                               nominal["phase"]))
            peaks = {}
            for pr, s in runs:
                if pr["parameter"] == name:
                    curves.append((show(name, pr["value"]), s["depth_m"], s["force_N"],
                                   s["phase"]))
                    peaks[pr["case"].rsplit("_", 1)[1]] = s["peak_force_N"]
            panels.append((label, curves))
            if nominal is not None and peaks:
                summary[scene_id][name] = {
                    "peak_nominal_N": nominal["peak_force_N"],
                    **{f"peak_{k}_N": v for k, v in peaks.items()},
                    "spread_rel": (max(peaks.values()) - min(peaks.values()))
                    / nominal["peak_force_N"] if nominal["peak_force_N"] else float("nan")}
        plot_sensitivity(panels, out / (f"sensitivity_{scene_id}.png" if len(by_scene) > 1
                                        else "sensitivity.png"),
                         f"Sensitivity of the wedge force, {scene_id} (one parameter at a time)")
    write_outcomes(out / "outcomes.json", outcomes)
    write_json_atomic(out / "study.json", {"study": "sensitivity", "wall_s": wall,
                                           "peak_force_by_parameter": summary,
                                           "failed": [o.run_id for o in outcomes if not o.ok]})
    print()
    for scene_id, table in summary.items():
        print(f"{scene_id}: peak force, change across each parameter's range")
        for name, r in sorted(table.items(), key=lambda kv: -abs(kv[1]["spread_rel"])):
            print(f"  {PARAMETERS[name][0]:<36} low {r.get('peak_low_N', float('nan')):.4g} N"
                  f"  high {r.get('peak_high_N', float('nan')):.4g} N"
                  f"  ({r['spread_rel']:+.1%} of nominal {r['peak_nominal_N']:.4g} N)")
    print(f"study wall time {wall:.1f} s; outputs in {out}/")
    return report_failures(outcomes)


# ----------------------------------------------------------------------------- Monte Carlo
def draw_samples(n: int, seed: int) -> list[dict]:
    """``n`` parameter sets, each parameter uniform over its range (reproducible)."""
    import numpy as np

    rng = np.random.default_rng(seed)
    names = list(PARAMETERS)
    lo = np.array([PARAMETERS[k][2] for k in names])
    hi = np.array([PARAMETERS[k][3] for k in names])
    u = rng.random((n, len(names)))
    return [dict(zip(names, map(float, lo + (hi - lo) * row))) for row in u]


def mean_std_table(summaries: list[dict]) -> list[dict]:
    """Mean and std (ddof 1) of the force per (phase, depth) over the runs that have it."""
    import numpy as np

    acc: dict = {}
    for s in summaries:
        s = numeric_summary(s)
        for d, f, ph in zip(s["depth_m"], s["force_N"], s["phase"]):
            acc.setdefault((ph, round(d, 9)), []).append(f)
    rows = []
    for (ph, d), fs in sorted(acc.items(), key=lambda kv: (kv[0][0] != "load",
                                                           kv[0][1] * (1 if kv[0][0] == "load"
                                                                       else -1))):
        a = np.asarray(fs)
        rows.append({"depth_m": d, "phase": ph, "mean_N": float(a.mean()),
                     "std_N": float(a.std(ddof=1)) if len(a) > 1 else 0.0, "n": len(a)})
    return rows


def _run_montecarlo(options: MonteCarloOptions, out: Path) -> int:
    return _run_and_write(lambda: _montecarlo_specs(options), options, out,
                          "Monte Carlo samples", "samples", write_montecarlo_outputs)


run_montecarlo = api.study_run("montecarlo", _run_montecarlo)


def _montecarlo_specs(options: MonteCarloOptions) -> list:
    """One run per sample of the uncertain parameters, for every scene."""
    scenes = _prepare(options, None, None)
    samples = draw_samples(options.samples, options.seed)
    specs = []
    for rid, scene, src in scenes:
        scene = apply_resolution(scene, options.nodes)
        proto = protocol_from_options(scene, options)
        for i, values in enumerate(samples):
            sc = apply_parameters(scene, values)
            specs.append(RunSpec(f"{rid}.mc{i:04d}", sc, {
                "scene": rid, "sample": i, "seed": options.seed, "values": values,
                "angle_deg": wedge_angle_deg(sc), "source": src, "protocol": proto},
                TASK))
    p0 = specs[0].params["protocol"]
    nodes = sorted({b["n_nodes"] for s in specs for b in s.scene["brushes"]})
    print(f"Monte Carlo: {len(scenes)} scene(s) x {options.samples} samples (seed "
          f"{options.seed}), to {p0['n_steps'] * p0['step'] * 1e3:g} mm"
          f"{' and back' if p0['unload'] else ''}, {'/'.join(map(str, nodes))} nodes "
          f"per bristle, {p0['method'].replace('_', '-')} method")
    return specs


def write_montecarlo_outputs(out: Path, specs, outcomes, wall) -> int:
    from .plots import plot_mean_std

    names = list(PARAMETERS)
    with open(out / "samples.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["run_id", "scene", "sample", *[f"{n}_si" for n in names], "status",
                    "peak_force_N", "wall_s"])
        for spec, o in zip(specs, outcomes):
            pr = spec.params
            w.writerow([spec.run_id, pr["scene"], pr["sample"],
                        *[f"{pr['values'][n]:.6g}" for n in names], o.status,
                        f"{o.summary['peak_force_N']:.6g}" if o.ok else "",
                        f"{o.wall_s:.2f}"])
    groups, table, stats = [], [], {}
    by_scene: dict = {}
    for spec, o in zip(specs, outcomes):
        if o.ok:
            by_scene.setdefault(spec.params["scene"], []).append((spec, o))
    for scene_id, runs in by_scene.items():
        rows = mean_std_table([o.summary for _, o in runs])
        angle = runs[0][0].params["angle_deg"]
        label = f"{angle:g} deg" if angle is not None else scene_id
        for phase in ("load", "unload"):
            sel = [r for r in rows if r["phase"] == phase]
            loads = [r for r in rows if r["phase"] == "load"]
            if phase == "unload" and sel and loads:  # unloading starts at the deepest point
                sel = [max(loads, key=lambda r: r["depth_m"])] + sel
            if sel:
                groups.append((label, [r["depth_m"] for r in sel], [r["mean_N"] for r in sel],
                               [r["std_N"] for r in sel], phase))
        for r in rows:
            table.append([scene_id, "" if angle is None else f"{angle:.6g}",
                          f"{r['depth_m']:.6g}", r["phase"],
                          f"{r['mean_N']:.9g}", f"{r['std_N']:.9g}", r["n"]])
        walls = [o.wall_s for _, o in runs]
        cpus = [o.summary.get("cpu_s") or 0.0 for _, o in runs]
        stats[scene_id] = {"samples_completed": len(runs), "mean_run_wall_s":
                           sum(walls) / len(walls), "sum_run_wall_s": sum(walls),
                           "mean_run_cpu_s": sum(cpus) / len(cpus)}
    with open(out / "montecarlo.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["scene", "angle_deg", "depth_m", "phase", "mean_N", "std_N", "n"])
        w.writerows(table)
    if groups:
        plot_mean_std(groups, out / "montecarlo.png",
                      "Monte Carlo over the uncertain parameters: mean ± std per depth "
                      "(cf. seed fig. 4.18)")
    write_outcomes(out / "outcomes.json", outcomes)
    write_json_atomic(out / "study.json", {
        "study": "montecarlo", "wall_s": wall, "samples": len(specs), "per_scene": stats,
        "parameters": {k: {"low_si": v[2], "high_si": v[3], "distribution": "uniform"}
                       for k, v in PARAMETERS.items()},
        "failed": [o.run_id for o in outcomes if not o.ok]})
    print()
    for scene_id, st in stats.items():
        print(f"{scene_id}: {st['samples_completed']} samples, mean run wall time "
              f"{st['mean_run_wall_s']:.1f} s (CPU {st['mean_run_cpu_s']:.1f} s)")
    print(f"study wall time {wall:.1f} s; outputs in {out}/ (montecarlo.csv, samples.csv, "
          f"montecarlo.png, study.json, runs/*.h5)")
    return report_failures(outcomes)
