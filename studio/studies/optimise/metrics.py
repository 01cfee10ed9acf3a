"""What a run of one design x scenario says (the task each Dask worker runs), the list of
metrics a search may minimise or bound, and their aggregation over the scenario set.

Metrics per run (all SI; the target is the spinning body, its initial spin axis n):

==================  ======  =================================================================
metric              unit    meaning
==================  ======  =================================================================
spin_left           --      omega.n just after the first contact over |omega0| (seed 4.3.4:
                            falls as the brush stiffens, below 0 once the brush throws the
                            target back); a contact ends once the target has felt no force
                            for 10 ms; a target caught for the whole run: omega.n at its end
abs_spin_left       --      abs(spin_left): the thesis's metric to minimise
delta_omega         rad/s   change of omega.n over the first contact
contact_duration    s       duration of the first contact
peak_force          N       largest contact force on the target (the whole run)
peak_torque         N m     largest contact torque on the target about its centre
peak_stress_ratio   --      largest bristle bending stress 4 M / (pi r^3) (M: the bond's
                            bending moment at its midpoint, r: the radius there) over the
                            limit --stress-limit-mpa
brush_mass          kg      mass of the bristles (truncated cones)
rest_time           s       time until |omega.n| stays below 5 % of omega0 (the run then
                            goes on to --duration-s; ``inf`` when it never does)
==================  ======  =================================================================

Aggregation over scenarios: ``mean``, ``worst`` (the largest: every metric is minimised)
or ``pNN`` (the NN-th percentile).
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Optional

import numpy as np

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
}
AGGREGATES = ("mean", "worst")
REST_FRACTION = 0.05
QUIET_AFTER_CONTACT = 0.01  # s without contact force that ends the first contact's run


def parse_objective(text: str) -> tuple[str, str]:
    """``METRIC[:AGG]`` -> (metric, aggregate)."""
    metric, _, agg = str(text).strip().partition(":")
    agg = agg or "worst"
    if metric not in METRICS:
        raise StudyInputError(f"objective {text!r}: unknown metric {metric!r}; metrics: "
                              f"{sorted(METRICS)}")
    _check_aggregate(text, agg)
    return metric, agg


def parse_constraint(text: str) -> tuple[str, str, float]:
    """``METRIC[:AGG]<=LIMIT`` -> (metric, aggregate, limit)."""
    left, sep, limit = str(text).partition("<=")
    if not sep:
        raise StudyInputError(f"constraint {text!r}: expected METRIC[:AGG]<=LIMIT")
    metric, agg = parse_objective(left)
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
    from engine.observables import bending_moments  # noqa: F401 (the recorded channel)

    from .. import api

    target = params.get("target", "cube")
    full = bool(params.get("full_run", False))
    c0 = time.process_time()
    system = engine.build(scene)
    k = list(system.body_names).index(target)
    monitor = FirstContactMonitor(system, k)
    cancel = (lambda: api.cancel_requested()) if full else \
        (lambda: monitor() or api.cancel_requested())
    result = engine.run(system, output=h5_path, cancel=cancel)
    sim_cpu = time.process_time() - c0
    api.check_cancel()
    out = analyse_run(h5_path, target, float(params.get("stress_limit", 5e6)))
    status = result.status
    if status == "cancelled" and monitor.fired:
        status = "stopped"
    out.update(status=status, dt=system.dt, steps=result.summary.get("steps"),
               sim_cpu_s=sim_cpu, task_cpu_s=time.process_time() - c0,
               brush_mass=brush_mass(scene))
    return out


def analyse_run(h5_path: Path, target: str, stress_limit: float) -> dict:
    """The metrics of a recorded run (see the module's table)."""
    import engine

    from ..spin import contact_intervals

    with engine.open_result(h5_path) as res:
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
    return out


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
