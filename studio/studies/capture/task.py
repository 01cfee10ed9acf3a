"""One capture of ``study capture`` on a worker: run the scene, then its figures.

Figures (world = Hill axes): the target's velocity and angular velocity relative to the
chaser's, frame by frame; whether the target's centre is between the jaws
(:func:`.criterion.between_jaws`, within ``between_radius`` of the line joining the jaws'
centres); the capture criterion (:func:`.criterion.capture`); the residual relative speed and
rate (their means over the last ``hold`` seconds); the peak contact force and torque (about
its centre of mass) on the target; and the peak load on the chaser's jaw mounts. That load is
the reaction of the jaw servos: the engine applies each servo's force to its jaw alone (no
joint between bodies), so the chaser's load is computed here, minus the sum of the jaws'
recorded actuator forces, and minus the sum of their actuator torques plus the moments of
their forces about the chaser's centre of mass.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .criterion import between_jaws, capture

JAWS = ("jaw_left", "jaw_right")


def chaser_load(chaser_pos, jaw_pos, jaw_force, jaw_torque):
    """(force, torque) on the chaser, (F, 3) each, from the jaws' actuator forces and torques
    (lists of (F, 3), world axes) at the jaws' centres ``jaw_pos``: the servos' reaction."""
    force = -sum(jaw_force)
    torque = -sum(tq + np.cross(p - chaser_pos, f)
                  for p, f, tq in zip(jaw_pos, jaw_force, jaw_torque))
    return force, torque


def analyse(t, series: dict, *, max_speed, max_rate, hold, between_radius) -> dict:
    """The run's figures from its recorded ``series`` (name -> array, names as
    ``bodies/<body>/<channel>``)."""
    s = series
    v_rel = s["bodies/target/velocity"] - s["bodies/chaser/velocity"]
    w_rel = s["bodies/target/angular_velocity"] - s["bodies/chaser/angular_velocity"]
    speed = np.linalg.norm(v_rel, axis=1)
    rate = np.linalg.norm(w_rel, axis=1)
    between = between_jaws(s["bodies/target/position"], s["bodies/jaw_left/position"],
                           s["bodies/jaw_right/position"], between_radius)
    force_t = np.linalg.norm(s["bodies/target/contact_force"], axis=1)
    first = np.nonzero(force_t > 0.0)[0]
    first_contact = float(t[first[0]]) if len(first) else None
    out = capture(t, speed, rate, between, max_speed=max_speed, max_rate=max_rate, hold=hold,
                  first_contact=first_contact)
    tail = t >= t[-1] - hold
    f_c, tq_c = chaser_load(s["bodies/chaser/position"],
                            [s[f"bodies/{j}/position"] for j in JAWS],
                            [s[f"bodies/{j}/actuator_force"] for j in JAWS],
                            [s[f"bodies/{j}/actuator_torque"] for j in JAWS])
    out.update(
        residual_speed=float(speed[tail].mean()), residual_rate=float(rate[tail].mean()),
        initial_rate=float(rate[0]),
        between_at_end=bool(between[-1]),
        first_contact=first_contact,
        peak_target_force=float(force_t.max()),
        peak_target_torque=float(np.linalg.norm(s["bodies/target/contact_torque"],
                                                axis=1).max()),
        peak_chaser_force=float(np.linalg.norm(f_c, axis=1).max()),
        peak_chaser_torque=float(np.linalg.norm(tq_c, axis=1).max()))
    return out


def capture_task(scene, h5_path: Path, params: dict) -> dict:
    """Dask task (``studio.studies.runner``): one capture."""
    import engine

    from ..runner import run_counting_momentum

    system, result, _, _ = run_counting_momentum(scene, h5_path)
    names = [f"bodies/{b}/{c}" for b in ("target", "chaser")
             for c in ("position", "velocity", "angular_velocity")]
    names += [f"bodies/target/{c}" for c in ("contact_force", "contact_torque")]
    names += [f"bodies/{j}/{c}" for j in JAWS
              for c in ("position", "actuator_force", "actuator_torque")]
    with engine.open_result(h5_path) as res:
        t = res.time
        series = {n: res.series(n) for n in names}
    out = analyse(t, series, max_speed=params["max_speed"], max_rate=params["max_rate"],
                  hold=params["hold"], between_radius=params["between_radius"])
    out.update(status=result.status, dt=system.dt, steps=result.summary.get("steps"),
               wall_s=result.summary.get("wall_s"), n_nodes=system.n_nodes)
    return out
