"""The leapfrog is second order from t = 0: the forces of the initial state are evaluated
before the first half kick (engine.kernels.stepper.advance), also for loads that depend on
the state, and a run continued in chunks neither repeats nor loses a half kick."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import engine
from engine.model.layout import quat_to_matrix

AL = {"youngs_modulus": 70e9, "density": 2700.0}
MASS = 2.0
FORCE = 2.0  # N: F / m = 1 m/s^2


def _pushed_body(dt, duration=1.0):
    return engine.parse_scene({
        "materials": {"al": AL},
        "bodies": [{"name": "b", "material": "al", "shape": {"type": "box", "size": [1, 1, 1]},
                    "mass_properties": {"mass": MASS, "inertia": [[1, 0, 0], [0, 1, 0],
                                                                  [0, 0, 1]]},
                    "motion": {"type": "free"}, "external_force": [FORCE, 0.0, 0.0]}],
        "run": {"duration": duration, "dt": dt, "record_interval": duration,
                "channels": ["bodies"]}})


@pytest.mark.parametrize("dt", [0.1, 0.05])
def test_constant_force_from_t0_is_integrated_exactly(dt):
    # F/m = 1 from t = 0 for 1 s: v = 1, x = 1/2 exactly, and velocity Verlet is exact for a
    # constant force, so both hold to rounding (1e-12). Catches a first half kick with zero
    # force (the old start): v = 0.95 at dt 0.1, 0.975 at dt 0.05 (error F dt / 2m).
    sys = engine.build(_pushed_body(dt))
    engine.run(sys)
    assert sys.steps == round(1.0 / dt)
    assert sys.bodies.v[0, 0] == pytest.approx(1.0, abs=1e-12)
    assert sys.bodies.pos[0, 0] == pytest.approx(0.5, abs=1e-12)


def test_a_run_in_chunks_matches_one_run():
    # engine.run called ten times (0.1 s each) against one call: the same steps, so the same
    # state to rounding (1e-12). Catches a start that re-evaluates (doubles) the half kick at
    # every call, or one that loses the forces between calls.
    one = engine.build(_pushed_body(0.01))
    engine.run(one)
    chunks = engine.build(_pushed_body(0.01))
    for k in range(1, 11):
        engine.run(chunks, until=0.1 * k)
    assert chunks.steps == one.steps == 100
    assert np.allclose(chunks.bodies.v[0], one.bodies.v[0], rtol=0, atol=1e-12)
    assert np.allclose(chunks.bodies.pos[0], one.bodies.pos[0], rtol=0, atol=1e-12)
    assert chunks.bodies.v[0, 0] == pytest.approx(1.0, abs=1e-12)


# ------------------------------------------------------------------ state-dependent: pitch
INERTIA = (2.0, 5.0, 6.0)
N_ORBIT = 0.1
THETA0 = 0.5  # rad: large, the libration is nonlinear


def _pitch_scene(dt, duration):
    I1, I2, I3 = INERTIA
    q = [math.cos(THETA0 / 2), 0.0, 0.0, math.sin(THETA0 / 2)]
    return engine.parse_scene({
        "materials": {"al": AL},
        "bodies": [{"name": "b", "material": "al",
                    "shape": {"type": "box", "size": [1.0, 0.6, 0.3]},
                    "mass_properties": {"mass": 10.0, "inertia": [[I1, 0, 0], [0, I2, 0],
                                                                  [0, 0, I3]]},
                    "motion": {"type": "free"}, "pose": {"orientation": q}}],
        "environment": {"orbit": {"mean_motion": N_ORBIT, "gravity_gradient": True}},
        "run": {"duration": duration, "dt": dt, "record_interval": duration,
                "channels": ["bodies"]}})


def _pitch(sys):
    R = quat_to_matrix(sys.bodies.q[0])
    e = R[:, 0]  # the body's x axis (minimum inertia)
    return math.atan2(e[1], e[0])


def test_gravity_gradient_pitch_is_second_order_from_t0():
    # pitch libration at 0.5 rad, I3 theta'' = -3 n^2 (I2 - I1) sin(theta) cos(theta),
    # integrated by scipy (rtol 1e-12) to T = 20 s, against the engine at dt and dt / 2: a
    # second-order start makes the error shrink ~4x per halving (3 to 5 allows the
    # higher-order terms); the old start (zero torque in the first half kick) made it
    # first order, ~2x.
    I1, I2, I3 = INERTIA
    T = 20.0
    c = 3.0 * N_ORBIT ** 2 * (I2 - I1) / I3
    ref = solve_ivp(lambda t, y: [y[1], -c * math.sin(y[0]) * math.cos(y[0])], (0.0, T),
                    [THETA0, 0.0], rtol=1e-12, atol=1e-14).y[0, -1]
    errors = []
    for dt in (0.2, 0.1):
        sys = engine.build(_pitch_scene(dt, T))
        engine.run(sys)
        errors.append(abs(_pitch(sys) - ref))
    ratio = errors[0] / errors[1]
    assert errors[1] > 0.0
    assert 3.0 < ratio < 5.0, (errors, ratio)
