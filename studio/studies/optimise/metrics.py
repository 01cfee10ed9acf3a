"""What a run of one design x scenario says (the task each Dask worker runs), the list of
metrics a search may minimise or bound, and their aggregation over the scenario set.

Metrics per run (all SI; the target is the spinning body, its initial spin axis n):

=====================  ======  =================================================================
metric                 unit    meaning
=====================  ======  =================================================================
spin_left              --      omega.n just after the first contact over |omega0| (seed 4.3.4:
                               falls as the brush stiffens, below 0 once the brush throws the
                               target back); a contact ends once the target has felt no force
                               for 10 ms; a target caught for the whole run: omega.n at its end
abs_spin_left          --      abs(spin_left): the thesis's metric to minimise
delta_omega            rad/s   change of omega.n over the first contact
contact_duration       s       duration of the first contact
peak_force             N       largest contact force on the target (the whole run)
peak_torque            N m     largest contact torque on the target about its centre
peak_stress_ratio      --      largest bristle bending stress 4 M / (pi r^3) (M: the bond's
                               bending moment at its midpoint, r: the radius there) over the
                               limit --stress-limit-mpa
brush_mass             kg      mass of the bristles (truncated cones)
rest_time              s       time until |omega.n| stays below 5 % of omega0 (the run then
                               goes on to --duration-s; ``inf`` when it never does)
chaser_delta_v         m/s     Delta-v the chaser's thrusters supply over the run: a chaser with
                               a controller: integral |F_actuator| dt / m (the controller's own
                               ``delta_v`` record); a free chaser without one: integral |F_load|
                               dt / m, F_load the brush's load (-root_force) plus the chaser's
                               own contact force; a fixed brush: integral |root_force| dt over
                               --chaser-mass-kg (the chaser it would be on)
wheel_momentum         N m s   max over t of |integral_0^t tau dt|: a controlled chaser's tau
                               is its controller's torque; otherwise the load's moment about
                               the chaser's centre of mass (mount_torque + its contact torque),
                               for a fixed brush about the brush base (-root_torque)
peak_chaser_torque     N m     largest |moment of the load about the chaser's centre of mass|
                               (fixed brush: about the brush base)
peak_contact_pressure  Pa      largest single bristle-target contact force (every contact of
                               every recorded frame, from the engine's contact list) over the
                               bristle tip's cross-section pi r_tip^2: a nominal pressure (the
                               true Hertzian patch is smaller, its pressure higher)
=====================  ======  =================================================================

"The chaser" is the body the brush is mounted on (``brushes.0.mount``); the spin rig's brush
is fixed in the world, and then the chaser is the mount itself: its centre of mass is taken
at the brush base and chaser_delta_v needs its mass (--chaser-mass-kg, refused without).
All figures are over the recorded run (it ends 10 ms after the first contact unless
rest_time is asked for), integrals by the trapezoid rule over the frames
(``studio.studies.chaser_loads``, shared with the detumble study).

Aggregation over scenarios: ``mean``, ``worst`` (the largest: every metric is minimised)
or ``pNN`` (the NN-th percentile).
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Optional

import numpy as np

from ..contact_peak import ContactForcePeak, nominal_pressure
from .errors import StudyInputError

METRICS = {
    "spin_left": "fraction of the initial spin left after the first contact (signed)",
    "abs_spin_left": "|spin_left|",
    "delta_omega": "change of the spin over the first contact, rad/s",
    "contact_duration": "duration of the first contact, s",
    "peak_force": "largest contact force on the target, N",
    "peak_torque": "largest contact torque on the target about its centre, N m",
    "peak_stress_ratio": "largest bristle bending stress over the material's limit",
    "brush_mass": "mass of the bristles, kg",
    "rest_time": "time until the spin stays below 5 % of its initial value, s",
    "chaser_delta_v": "Delta-v the chaser's thrusters supply, integral |F| dt / m (the "
                      "controller's force, else the brush's load), m/s",
    "wheel_momentum": "largest |angular impulse| on the chaser's attitude over the run "
                      "(the controller's torque, else the load about the chaser's centre of "
                      "mass), N m s",
    "peak_chaser_torque": "largest moment of the brush's load about the chaser's centre of "
                          "mass (fixed brush: about its base), N m",
    "peak_contact_pressure": "largest single bristle-target contact force over the tip's "
                             "cross-section pi r_tip^2 (a nominal pressure), Pa",
}
#: what a trial keeps of each scenario run (and trials.csv shows): every metric, then the
#: run's facts
RUN_KEYS = tuple(METRICS) + ("n_contacts", "first_contact_at", "end_time", "dt", "steps",
                             "sim_cpu_s", "task_cpu_s")
#: metrics that need a chaser mass: a fixed brush needs --chaser-mass-kg for them
NEEDS_CHASER_MASS = ("chaser_delta_v",)
AGGREGATES = ("mean", "worst")
REST_FRACTION = 0.05
QUIET_AFTER_CONTACT = 0.01  # s without contact force that ends the first contact's run


def parse_objective(text: str, metrics: Optional[dict] = None,
                    where: str = "") -> tuple[str, str]:
    """``METRIC[:AGG]`` -> (metric, aggregate); ``metrics``: the known ones (default
    :data:`METRICS`, the DEM runs'), ``where`` says whose in the error."""
    metrics = METRICS if metrics is None else metrics
    metric, _, agg = str(text).strip().partition(":")
    agg = agg or "worst"
    if metric not in metrics:
        raise StudyInputError(f"objective {text!r}: unknown metric {metric!r}"
                              f"{' with ' + where if where else ''}; metrics: "
                              f"{sorted(metrics)}")
    _check_aggregate(text, agg)
    return metric, agg


def parse_constraint(text: str, metrics: Optional[dict] = None,
                     where: str = "") -> tuple[str, str, float]:
    """``METRIC[:AGG]<=LIMIT`` -> (metric, aggregate, limit)."""
    left, sep, limit = str(text).partition("<=")
    if not sep:
        raise StudyInputError(f"constraint {text!r}: expected METRIC[:AGG]<=LIMIT")
    metric, agg = parse_objective(left, metrics, where)
    try:
        value = float(limit)
    except ValueError:
        raise StudyInputError(f"constraint {text!r}: LIMIT must be a number") from None
    if not math.isfinite(value):
        raise StudyInputError(f"constraint {text!r}: LIMIT must be finite")
    return metric, agg, value


def _check_aggregate(text: str, agg: str) -> None:
    if agg in AGGREGATES:
        return
    if agg.startswith("p"):
        try:
            q = float(agg[1:])
        except ValueError:
            q = -1
        if 0 <= q <= 100:
            return
    raise StudyInputError(f"{text!r}: aggregate {agg!r}: mean, worst or pNN (0 <= NN <= 100)")


def aggregate(values, agg: str) -> float:
    """``values`` over the scenarios by ``agg`` (a NaN makes the result NaN)."""
    v = np.asarray(list(values), float)
    if not len(v) or np.isnan(v).any():
        return float("nan")
    if agg == "mean":
        return float(v.mean())
    if agg == "worst":
        return float(v.max())
    return float(np.percentile(v, float(agg[1:])))


def brush_mass(scene) -> float:
    """Mass of the bristles of every brush, kg (truncated cones, the base not counted)."""
    total = 0.0
    for b in scene.brushes:
        rho = scene.materials[b.material].density
        r1, r2, L = b.root_radius, b.tip_radius, b.bristle_length
        total += b.rows * b.columns * rho * math.pi * L * (r1 * r1 + r1 * r2 + r2 * r2) / 3
    return float(total)


class FirstContactMonitor:
    """``cancel`` for ``engine.run``: True once the target has been touched and then felt no
    contact force for ``QUIET_AFTER_CONTACT`` simulated seconds (the first contact is over)."""

    def __init__(self, system, body_index: int):
        self.system, self.k = system, body_index
        self.touched = False
        self.quiet_since: Optional[float] = None
        self.fired = False

    def __call__(self) -> bool:
        f = float(np.linalg.norm(self.system.bodies.f[self.k]))
        t = float(self.system.time)
        if f > 0:
            self.touched, self.quiet_since = True, None
        elif self.touched and self.quiet_since is None:
            self.quiet_since = t
        self.fired = bool(self.touched and self.quiet_since is not None
                          and t - self.quiet_since >= QUIET_AFTER_CONTACT)
        return self.fired


def run_metrics(scene, h5_path: Path, params: dict) -> dict:
    """Dask task (``"module:function"`` of :mod:`studio.studies.runner`): run one design x
    scenario, return its metrics (JSON-able; ``sim_cpu_s``: CPU of build + run, the rest of
    the task is analysis)."""
    import engine
    from engine.stepping.observables import bending_moments  # noqa: F401 (the recorded channel)

    from .. import api

    target = params.get("target", "cube")
    full = bool(params.get("full_run", False))
    c0 = time.process_time()
    system = engine.build(scene)
    k = list(system.body_names).index(target)
    monitor = FirstContactMonitor(system, k)
    contact_peak = ContactForcePeak(system, k)
    cancel = (lambda: api.cancel_requested()) if full else \
        (lambda: monitor() or api.cancel_requested())
    result = engine.run(system, output=h5_path, cancel=cancel, observer=contact_peak)
    sim_cpu = time.process_time() - c0
    api.check_cancel()
    out = analyse_run(h5_path, target, float(params.get("stress_limit", 5e6)),
                      chaser_mass=params.get("chaser_mass"),
                      peak_contact_force=contact_peak.peak)
    status = result.status
    if status == "cancelled" and monitor.fired:
        status = "stopped"
    out.update(status=status, dt=system.dt, steps=result.summary.get("steps"),
               sim_cpu_s=sim_cpu, task_cpu_s=time.process_time() - c0,
               brush_mass=brush_mass(scene))
    return out


def analyse_run(h5_path: Path, target: str, stress_limit: float, *,
                chaser_mass: Optional[float] = None,
                peak_contact_force: Optional[float] = None) -> dict:
    """The metrics of a recorded run (see the module's table). ``chaser_mass``: the mass of
    the chaser a fixed brush would be on (kg; a mounted brush's chaser has its own);
    ``peak_contact_force``: :class:`ContactForcePeak`'s figure (no channel records it;
    without it peak_contact_pressure is None)."""
    import engine

    from ..spin.runs import contact_intervals

    with engine.open_result(h5_path) as res:
        load = read_chaser_load(res, chaser_mass)
        t = np.asarray(res.time)
        w = np.asarray(res.series(f"bodies/{target}/angular_velocity"))
        f = np.asarray(res.series(f"bodies/{target}/contact_force"))
        tq = np.asarray(res.series(f"bodies/{target}/contact_torque"))
        scene = res.scene
        moment = (np.asarray(res.series("bonds/bending_moment"))
                  if "bonds/bending_moment" in res.channels() else np.zeros((len(t), 0)))
    body = next(b for b in scene.bodies if b.name == target)
    w0 = np.asarray(body.angular_velocity, float)
    n = w0 / np.linalg.norm(w0)
    om = w @ n
    omega0 = float(np.linalg.norm(w0))
    # one contact until the target has felt no force for QUIET_AFTER_CONTACT (the bristles
    # touch and leave one by one as a corner sweeps through: that is one collision)
    frame_dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    contacts = contact_intervals(t, f, om, fraction=1e-6, floor=1e-12,
                                 max_gap=max(1, int(round(QUIET_AFTER_CONTACT / frame_dt))))
    out = {"omega0": omega0, "n_contacts": len(contacts),
           "peak_force": float(np.linalg.norm(f, axis=1).max()) if len(f) else 0.0,
           "peak_torque": float(np.linalg.norm(tq, axis=1).max()) if len(tq) else 0.0,
           "end_time": float(t[-1]) if len(t) else 0.0}
    if contacts:
        c = contacts[0]
        out.update(spin_left=c["omega_after"] / omega0, delta_omega=c["delta_omega"],
                   contact_duration=c["duration"], first_contact_at=c["t_start"])
    else:  # never touched: all of the spin is left
        out.update(spin_left=float(om[-1]) / omega0 if len(om) else 1.0, delta_omega=0.0,
                   contact_duration=0.0, first_contact_at=None)
    out["abs_spin_left"] = abs(out["spin_left"])
    slow = np.abs(om) < REST_FRACTION * omega0
    fast = np.flatnonzero(~slow)
    out["rest_time"] = (float(t[fast[-1] + 1]) if fast.size and fast[-1] + 1 < len(t)
                        else (0.0 if not fast.size else float("inf")))
    out["peak_stress_ratio"] = _peak_stress(scene, moment) / stress_limit
    out.update(chaser_figures(**load))
    r_tip = scene.brushes[0].tip_radius
    out["peak_contact_pressure"] = (None if peak_contact_force is None
                                    else nominal_pressure(peak_contact_force, r_tip))
    return out


def read_chaser_load(res, chaser_mass: Optional[float] = None) -> dict:
    """The load the brush puts on its chaser (see the module's table), from an open result
    with the ``bodies`` and ``root_force`` channel groups: :func:`chaser_figures`'s
    arguments."""
    from ..chaser_loads import brush_load_on_body

    scene = res.scene
    brush = scene.brushes[0]
    t = np.asarray(res.time)
    if brush.mount is None:  # fixed: the mount is the chaser, its centre at the base
        force = -np.asarray(res.series(f"brushes/{brush.name}/root_force"))
        torque = -np.asarray(res.series(f"brushes/{brush.name}/root_torque"))
        return {"time": t, "force": force, "torque": torque, "mass": chaser_mass}
    if chaser_mass is not None:
        raise StudyInputError(f"chaser mass {chaser_mass} kg given, but the brush is mounted "
                              f"on body {brush.mount!r}, whose own mass counts")
    chaser = brush.mount
    force, torque = brush_load_on_body(res, chaser)
    force = force + np.asarray(res.series(f"bodies/{chaser}/contact_force"))
    torque = torque + np.asarray(res.series(f"bodies/{chaser}/contact_torque"))
    out = {"time": t, "force": force, "torque": torque,
           "mass": float(res.static(f"bodies/{chaser}/mass"))}
    controllers = [c.name for c in scene.controllers if c.body == chaser]
    if controllers:
        out["delta_v"] = sum(np.asarray(res.series(f"controllers/{c}/delta_v"))
                             for c in controllers)
        out["angular_impulse"] = sum(np.asarray(res.series(f"controllers/{c}/angular_impulse"))
                                     for c in controllers)
    return out


def chaser_figures(time, force, torque, mass: Optional[float], *, delta_v=None,
                   angular_impulse=None) -> dict:
    """chaser_delta_v, wheel_momentum and peak_chaser_torque of a run from the load on the
    chaser (``force``, N, and ``torque`` about its centre of mass, N m: frames x 3) and, for a
    controlled chaser, its controller's running records ``delta_v`` (m/s, frames) and
    ``angular_impulse`` (N m s, frames x 3), which then say what the thrusters and wheels
    did. ``mass`` None (a fixed brush without --chaser-mass-kg): chaser_delta_v is None."""
    from ..chaser_loads import (load_delta_v, peak_magnitude, running_integral,
                                wheel_momentum)

    if delta_v is not None:
        dv = float(np.asarray(delta_v)[-1]) if len(delta_v) else 0.0
    else:
        dv = None if mass is None else load_delta_v(time, force, mass)
    if angular_impulse is None:
        angular_impulse = running_integral(time, torque)
    return {"chaser_delta_v": dv, "wheel_momentum": wheel_momentum(angular_impulse),
            "peak_chaser_torque": peak_magnitude(torque)}


def _peak_stress(scene, moment: np.ndarray) -> float:
    """Largest 4 M / (pi r^3) over bonds and frames, r the radius at the bond's midpoint
    (the bonds of a brush run root to tip, n_nodes - 1 per bristle, in bristle order)."""
    if moment.size == 0:
        return 0.0
    radii = []
    for b in scene.brushes:
        n = b.n_nodes
        r = np.linspace(b.root_radius, b.tip_radius, n)
        per = 0.5 * (r[:-1] + r[1:])
        radii.append(np.tile(per, b.rows * b.columns))
    radii = np.concatenate(radii) if radii else np.zeros(0)
    if len(radii) != moment.shape[1]:  # another bond layout: use the thinnest radius
        radii = np.full(moment.shape[1], min(b.tip_radius for b in scene.brushes))
    sigma = 4.0 * np.abs(moment) / (math.pi * radii[None, :] ** 3)
    return float(sigma.max())
