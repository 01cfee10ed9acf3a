"""What a brush's load asks of what carries it (a chaser body, or a fixed mount): the mission
figures a chaser designer reads, each declared once here and used by the detumble study
(``detumble_analysis``) and the design search (``optimise.metrics``).

* the load on the carrier: the brushes mounted on it push it with ``-root_force`` (summed) and
  turn it with ``mount_torque`` (their roots' moment about its centre of mass, summed:
  ``engine.stepping.observables.mount_torques``);
* Delta-v of a load: integral of |F| / m over the frames (the trapezoid rule): the velocity
  change thrusters must supply to cancel it (for a push of fixed direction, also the velocity
  a free carrier picks up);
* wheel momentum: the largest |angular impulse| over the run, max_t |integral_0^t tau dt|
  (N m s): what reaction wheels store if they provide (or absorb) that torque.
"""
from __future__ import annotations

import numpy as np


def running_integral(time, series) -> np.ndarray:
    """integral_0^t of ``series`` (frames x ...) at every frame, by the trapezoid rule over the
    recorded frames (0 at the first frame)."""
    t = np.asarray(time, float)
    y = np.asarray(series, float)
    out = np.zeros_like(y)
    if len(t) > 1:
        steps = 0.5 * (y[1:] + y[:-1]) * np.diff(t).reshape((-1,) + (1,) * (y.ndim - 1))
        out[1:] = np.cumsum(steps, axis=0)
    return out


def peak_magnitude(series) -> float:
    """The largest |v| over the frames of a (frames, 3) series (0 for none)."""
    a = np.asarray(series, float)
    return float(np.linalg.norm(a, axis=1).max()) if len(a) else 0.0


def load_delta_v(time, force, mass: float) -> float:
    """integral of |F| dt / m over the run (m/s): the Delta-v thrusters supply to cancel the
    load ``force`` (frames, 3; N) on a body of ``mass`` (kg)."""
    magnitude = np.linalg.norm(np.asarray(force, float), axis=1)
    if len(magnitude) < 2:
        return 0.0
    return float(running_integral(time, magnitude)[-1] / mass)


def wheel_momentum(angular_impulse) -> float:
    """max_t |H(t)| of the running angular impulse H (frames, 3; N m s): the momentum
    reaction wheels store if they provide the torque (0 for none)."""
    return peak_magnitude(angular_impulse)


def brush_load_on_body(res, body: str):
    """(force, torque about the body's centre of mass), each (frames, 3), world axes: the
    load of the brushes mounted on ``body`` (an open result with the ``root_force`` channel
    group); the torque is None without the ``mount_torque`` channel (older results)."""
    mounted = [b for b in res.scene.brushes if b.mount == body]
    force = -sum(np.asarray(res.series(f"brushes/{b.name}/root_force")) for b in mounted)
    torque = None
    if all(f"brushes/{b.name}/mount_torque" in res.channels() for b in mounted):
        torque = sum(np.asarray(res.series(f"brushes/{b.name}/mount_torque"))
                     for b in mounted)
    return force, torque
