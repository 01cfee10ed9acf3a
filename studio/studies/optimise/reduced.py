"""The design search at mission scale: ``--fidelity reduced`` (issue 25 item 4).

Each design's brush becomes a reduced brush law: ``study reduce`` fits it, with its default
protocol (the detumble's regime), from short DEM runs of that design's brush, into
``OUT/laws/<design key>/`` (``law.json`` and its validation beside it). Every scenario is a
detumble of a detumble preset's target (``study detumble``'s scene: target size, spin rate,
spin-axis tilt, tumble, hold offset), run for up to ``--duration-s`` (default an hour) with
the chaser's brush replaced by that law (:func:`studio.studies.detumble.reduced_scene`).

- The scenario runs of one design share its law: the first to need it fits it, under a lock
  in the design's folder, and the others (and a resumed search) reuse it while its
  ``fit_digest`` (a hash of the fit runs) matches.
- A design changes the brush in the scene (its variables at their paths); a change of the
  tips' reach (bristle length, tip radius) moves the chaser's held offset by the same amount,
  so every design is held at the preset's tip interference, as ``study detumble``'s design
  sweep holds its designs (:func:`studio.studies.detumble.keep_interference`).
- The winner's refinement is a DEM spot check: each scenario's first ``--spot-check-s``
  seconds run with the DEM brush and compared with the reduced run
  (:func:`studio.studies.detumble.spot_check`: the whole window and the part after the
  first touch, which the law leaves out).

Metrics of a reduced run (:data:`METRICS`; a reduced brush has no bristles, so no bending
stress): see docs/design.md.
"""
from __future__ import annotations

import json
import math
import os
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Optional

from .errors import StudyInputError

DEFAULT_DURATION = 3600.0   # s: a reduced scenario's run at most (the hour the issue asks)
REST_FRACTION = 0.05        # the detumble threshold: |omega| below 5 % of its initial value
LAWS_DIR = "laws"           # OUT/laws/<design key>/: study reduce's outputs for each design
TASK = "studio.studies.optimise.reduced:reduced_metrics"
SPOT_TASK = "studio.studies.detumble:detumble_task"
#: the spot check's bounds on the winner's after-touch errors, the issue's targets for the
#: reduced law against the DEM brush: Delta-omega within 10 %, peak force within 15 %
SPOT_BOUNDS = {"delta_omega": 0.10, "peak_force": 0.15}

#: metric -> meaning, of a reduced scenario run (SI units)
METRICS = {
    "spin_left": "|omega| at the run's end over its initial |omega|",
    "abs_spin_left": "the same (|omega| is never negative)",
    "delta_omega": "change of |omega| over the run, rad/s (negative: slowed)",
    "rest_time": "time until |omega| stays below 5 % of its initial value, s (inf: never "
                 "within the run)",
    "contact_duration": "time the brush touched the target, s",
    "peak_force": "largest contact force on the target, N",
    "peak_torque": "largest contact torque on the target about its centre of mass, N m",
    "chaser_delta_v": "Delta-v of the chaser's thrusters, integral |F| dt / m (gimballed), m/s",
    "propellant_mass": "propellant for that Delta-v at --isp (default 220 s), kg",
    "wheel_momentum": "largest |angular impulse| the chaser's attitude control stores, N m s",
    "peak_chaser_torque": "largest moment of the brush's load about the chaser's centre of "
                          "mass, N m",
    "thrust_saturation": "largest per-axis fraction of frames with the thrust at its cap",
    "peak_contact_pressure": "the largest push over the brush footprint's area, Pa",
    "brush_mass": "mass of the bristles, kg",
}
RUN_KEYS = tuple(METRICS) + ("omega0", "first_contact", "end_time", "dt", "steps",
                             "law_reused", "law_cpu_s", "sim_cpu_s", "task_cpu_s")


@dataclass(frozen=True)
class DetumbleScenario:
    """One target situation of a detumble preset: the target scaled by ``size``, spinning at
    ``spin_deg`` (None: the preset's), its spin axis tilted ``tilt_deg`` towards the brush,
    a transverse ``tumble`` fraction, the hold point ``offset`` m across the surface."""

    scenario_id: str
    size: float = 1.0
    spin_deg: Optional[float] = None
    tilt_deg: float = 0.0
    tumble: float = 0.0
    offset: float = 0.0

    #: the columns of trials.csv that describe it
    COLUMNS = ("size", "spin_deg", "tilt_deg", "tumble", "offset")

    def to_dict(self) -> dict:
        return asdict(self)


def scenario_set(sizes, spins_deg, tilts, tumbles, offsets) -> list[DetumbleScenario]:
    """Every size x spin x tilt x tumble x offset (an empty spin list: the preset's)."""
    for name, values in (("sizes", sizes), ("tilts_deg", tilts), ("tumbles", tumbles),
                         ("offsets_m", offsets)):
        if not values:
            raise StudyInputError(f"{name}: give at least one value")
        if any(not math.isfinite(float(v)) for v in values):
            raise StudyInputError(f"{name}: {list(values)}: finite numbers")
    if any(float(s) <= 0 for s in sizes):
        raise StudyInputError(f"sizes: {list(sizes)}: scale factors > 0")
    if any(float(w) <= 0 for w in spins_deg):
        raise StudyInputError(f"spins_deg: {list(spins_deg)}: spin rates > 0")
    out = []
    for size in sizes:
        for spin in (spins_deg or [None]):
            for tilt in tilts:
                for tumble in tumbles:
                    for off in offsets:
                        name = f"size{size:g}_spin{'p' if spin is None else f'{spin:g}'}"
                        name += "".join(f"_{k}{v:g}" for k, v in (
                            ("tilt", tilt), ("tumble", tumble), ("off", off)) if v)
                        out.append(DetumbleScenario(
                            name.replace(".", "p").replace("-", "m"), float(size),
                            None if spin is None else float(spin), float(tilt),
                            float(tumble), float(off)))
    return out


def check_base(base: dict, where: str) -> None:
    """A reduced search needs a detumble scene (a target, a chaser carrying the brush, its
    controller): StudyInputError naming what is missing."""
    import engine

    from ..detumble import PRESETS, chaser_parts
    try:
        chaser_parts(base, where)
    except engine.SceneError as exc:
        raise StudyInputError(
            f"--fidelity reduced runs hour-long detumbles: --preset {where!r} is "
            f"{'; '.join(str(p) for p in exc.problems)} (detumble presets: "
            f"{', '.join(PRESETS)})") from None


def design_scene(base: dict, design: dict, scenario: DetumbleScenario, *,
                 stiffness_via: str, duration: float, nodes: Optional[int] = None) -> dict:
    """The DEM scene of ``design`` meeting ``scenario``: the preset with the design's values,
    held at the preset's tip interference, with the scenario's target."""
    from ..detumble import detumble_scene, keep_interference, tip_reach
    from .variables import apply_design

    scene = json.loads(json.dumps(base))
    reach = tip_reach(scene)
    apply_design(scene, design, stiffness_via=stiffness_via)
    keep_interference(scene, reach)
    return detumble_scene(scene, size=scenario.size, spin_deg=scenario.spin_deg,
                          tilt_deg=scenario.tilt_deg, tumble=scenario.tumble,
                          offset=scenario.offset, duration=duration, n_nodes=nodes)


# ----------------------------------------------------------------------------- the law
def law_for(scene: dict, folder: Path, protocol: Optional[dict] = None) -> tuple[dict, bool]:
    """The reduced law of the brush of ``scene`` (a detumble scene dict of one design):
    fitted by ``study reduce`` (its defaults, updated by ``protocol``: reduce's option
    names) into ``folder``, or the one there fitted from the same runs
    (:func:`studio.studies.reduce.fit_or_reuse`: one fit per design, under the folder's
    lock). Returns (law, reused). RuntimeError when the fit fails, naming the folder."""
    from .. import reduce

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    design_file = folder / "design_scene.json"
    # every run of the design writes the same scene: each through its own temporary file,
    # renamed into place, so a reader never sees part of one
    with tempfile.NamedTemporaryFile("w", dir=folder, suffix=".tmp", delete=False) as fh:
        json.dump(scene, fh, indent=1)
    os.replace(fh.name, design_file)
    ropts = reduce.Options(preset=str(design_file), workers=1, no_progress=True,
                           **(protocol or {}))
    try:
        return reduce.fit_or_reuse(ropts, folder)
    except reduce.LawFitError as exc:
        raise RuntimeError(f"the design's reduced law: {exc}") from None


# ----------------------------------------------------------------------------- the task
def reduced_metrics(scene, h5_path: Path, params: dict) -> dict:
    """Dask task: one design x scenario at mission scale. Fits (or reuses) the design's law
    (:func:`law_for`), runs the scenario with the brush replaced by it
    (``detumble.detumble_task``) and returns the search's metrics (:data:`METRICS`) with the
    detumble summary's other figures."""
    import engine

    from ..detumble import REDUCED_RECORD_INTERVAL, detumble_task, reduced_scene
    from .metrics import brush_mass

    c0 = time.process_time()
    dem = json.loads(scene.to_json())
    folder = Path(h5_path).resolve().parent.parent / LAWS_DIR / params["law_key"]
    law, reused = law_for(dem, folder, params.get("protocol"))
    law_cpu = time.process_time() - c0
    red = reduced_scene(dem, law)
    red["run"]["record_interval"] = REDUCED_RECORD_INTERVAL
    c1 = time.process_time()
    summary = detumble_task(engine.parse_scene(red), h5_path,
                            {"threshold": REST_FRACTION, "stress_limit": 1.0,
                             "fidelity": "reduced", "isp": params["isp"]})
    sim_cpu = time.process_time() - c1
    out = {k: v for k, v in summary.items() if k not in ("patches",)}
    out.update(metrics_of(summary), brush_mass=brush_mass(scene), law_reused=reused,
               law_cpu_s=law_cpu, sim_cpu_s=sim_cpu, task_cpu_s=time.process_time() - c0)
    return out


def metrics_of(s: dict) -> dict:
    """The search's metrics (:data:`METRICS`, less brush_mass) of a detumble summary."""
    w0, w1 = s.get("omega0"), s.get("omega_end")
    left = (w1 / w0) if w0 else None
    sat = s.get("thrust_saturation")
    td = s.get("detumble_time")
    return {"spin_left": left, "abs_spin_left": None if left is None else abs(left),
            "delta_omega": None if w0 is None or w1 is None else w1 - w0,
            "rest_time": float("inf") if td is None else float(td),
            "contact_duration": s.get("time_in_contact"),
            "peak_force": s.get("peak_target_force"),
            "peak_torque": s.get("peak_target_torque"),
            "chaser_delta_v": s.get("delta_v_gimballed", s.get("delta_v")),
            "propellant_mass": s.get("propellant_gimballed"),
            "wheel_momentum": s.get("wheel_momentum"),
            "peak_chaser_torque": s.get("peak_chaser_torque_com"),
            "thrust_saturation": max(sat) if sat else None,
            "peak_contact_pressure": s.get("peak_footprint_pressure")}


# ----------------------------------------------------------------------------- spot check
def spot_check_report(reduced_outcomes: list[dict], dem_outcomes: list[dict],
                      scenario_ids: list[str], spot_s: float) -> dict:
    """The winner's DEM spot check: per scenario, :func:`detumble.spot_check` of its DEM run
    against its reduced run; ``resolved`` when every scenario's after-touch errors are
    within :data:`SPOT_BOUNDS` (the refinement's place in the report and summary).
    ``rows``: each scenario's relative errors (reduced - DEM) / |DEM| over the whole window
    and after the first touch; ``checks``: the whole comparisons."""
    from ..detumble import spot_check
    from ..detumble_analysis import read_detumble

    rows, checks, why = [], [], []
    for sid, red, dem in zip(scenario_ids, reduced_outcomes, dem_outcomes):
        if dem.get("status") not in ("completed", "stopped"):
            why.append(f"{sid}: the DEM spot check failed ({dem.get('error')})")
            continue
        if red.get("status") not in ("completed", "stopped") or not red.get("h5"):
            why.append(f"{sid}: no reduced run to compare")
            continue
        check = spot_check(read_detumble(dem["h5"]), read_detumble(red["h5"]), spot_s)
        checks.append(dict(check, scenario=sid))
        after = check.get("after_touch")
        rows.append({"scenario": sid, "whole": check["relative_error"],
                     "after_touch": None if after is None else after["relative_error"],
                     "first_contact": check["dem"]["first_contact"]})
        if after is None:
            why.append(f"{sid}: {check['after_touch_why']}")
            continue
        for key, bound in SPOT_BOUNDS.items():
            e = after["relative_error"].get(key)
            if e is None or not math.isfinite(e) or abs(e) > bound:
                why.append(f"{sid}: after the first touch {key} off by "
                           f"{'n/a' if e is None else f'{100 * e:+.1f} %'} (bound "
                           f"{100 * bound:g} %)")
    return {"kind": "spot_check", "resolved": not why and bool(rows),
            "why": "; ".join(why) or (f"every scenario's after-touch Delta-omega within "
                                      f"{100 * SPOT_BOUNDS['delta_omega']:g} % and peak force "
                                      f"within {100 * SPOT_BOUNDS['peak_force']:g} % of the "
                                      f"DEM brush"),
            "spot_check_s": spot_s, "rows": rows, "checks": checks}
