"""The gravity-gradient torque (engine.kernels.orbit, ``orbit.gravity_gradient``) against the
textbook component form and against the closed-form pitch libration it causes."""
import math

import numpy as np
import pytest

import engine
from engine.model.layout import quat_to_matrix

AL = {"youngs_modulus": 70e9, "density": 2700.0}
INERTIA = (2.0, 5.0, 6.0)   # kg m^2, principal (x, y, z): three different moments


def _scene(orientation, n, duration, dt, gravity_gradient=True, record_interval=None):
    I1, I2, I3 = INERTIA
    return engine.parse_scene({
        "materials": {"al": AL},
        "bodies": [{"name": "b", "material": "al",
                    "shape": {"type": "box", "size": [1.0, 0.6, 0.3]},
                    "mass_properties": {"mass": 10.0, "inertia": [[I1, 0, 0], [0, I2, 0],
                                                                  [0, 0, I3]]},
                    "motion": {"type": "free"}, "pose": {"orientation": list(orientation)}}],
        "environment": {"orbit": {"mean_motion": n, "gravity_gradient": gravity_gradient}},
        "run": {"duration": duration, "dt": dt, "record_interval": record_interval or dt,
                "channels": ["bodies"]}})


def _textbook_torque(R, Ip, n):
    """Gravity-gradient torque in principal axes (e.g. Wie, Space Vehicle Dynamics and
    Control, eq. 6.57): with c = the radial unit vector in body axes,
    T = 3 n^2 (c2 c3 (I3 - I2), c3 c1 (I1 - I3), c1 c2 (I2 - I1)); returned in world axes."""
    c = R.T @ np.array([1.0, 0.0, 0.0])
    I1, I2, I3 = Ip
    body = 3 * n * n * np.array([c[1] * c[2] * (I3 - I2), c[2] * c[0] * (I1 - I3),
                                 c[0] * c[1] * (I2 - I1)])
    return R @ body


def test_torque_is_the_textbook_component_form_at_every_frame(tmp_path):
    # a body turned off all orbital axes; the recorded total torque on a body with no
    # contacts is the gravity-gradient torque alone (its contact torque is zero). Same state, two formulas: they agree to rounding
    # (1e-12 of the torque); a swapped inertia difference, a missing factor 3 or a wrong
    # sign is off by the whole torque.
    n = 0.05
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    q = [math.cos(0.6), *(math.sin(0.6) * axis)]
    sys = engine.build(_scene(q, n, duration=2.0, dt=0.01, record_interval=0.1))
    result = engine.run(sys, output=tmp_path / "gg.h5")
    with result.open() as res:
        Ip = res.static("bodies/b/principal_inertia")
        qs = res.series("bodies/b/orientation")
        torques = res.series("bodies/b/total_torque")
        assert np.all(res.series("bodies/b/contact_torque") == 0.0)
    assert len(qs) >= 20
    for qk, tk in zip(qs[1:], torques[1:]):
        ref = _textbook_torque(quat_to_matrix(qk), Ip, n)
        assert np.linalg.norm(ref) > 1e-3  # off the axes: a real torque
        assert np.allclose(tk, ref, rtol=0, atol=1e-12 * np.linalg.norm(ref))


def test_torque_is_off_when_not_asked_for():
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    q = [math.cos(0.6), *(math.sin(0.6) * axis)]
    sys = engine.build(_scene(q, 0.05, duration=0.05, dt=0.01, gravity_gradient=False))
    engine.run(sys)
    assert np.all(sys.bodies.tq[0] == 0.0)


def test_pitch_libration_has_the_closed_form_frequency():
    # turned by theta0 about the orbit normal z, the body librates in pitch: I3 theta'' =
    # -3 n^2 (I2 - I1) sin(theta) cos(theta), so for small theta0, theta = theta0 cos(w t)
    # with w = n sqrt(3 (I2 - I1) / I3). After half a period theta = -theta0. Errors:
    # the nonlinearity, relative (2/3) theta0^2 ~ 7e-7 in frequency, and leapfrog's phase
    # error (w dt)^2 / 24 ~ 4e-7 at 1000 steps per half period: the phase is off by
    # < 1e-5 rad, theta by < 1e-5 theta0; 1e-4 theta0 leaves margin. A factor 3 missing
    # moves the half period by sqrt(3), a sign error makes it diverge.
    n = 0.1
    I1, I2, I3 = INERTIA
    w_lib = n * math.sqrt(3 * (I2 - I1) / I3)
    theta0 = 1e-3
    half = math.pi / w_lib
    q = [math.cos(theta0 / 2), 0.0, 0.0, math.sin(theta0 / 2)]
    sys = engine.build(_scene(q, n, duration=half, dt=half / 1000, record_interval=half))
    engine.run(sys)
    R = quat_to_matrix(sys.bodies.q[0])
    e = R[:, int(np.argmin(sys.bodies.Ip[0]))]   # the body's minimum-inertia axis (x)
    theta = math.atan2(e[1], e[0])
    if abs(theta) > math.pi / 2:                  # an axis has two ends
        theta = math.atan2(-e[1], -e[0])
    assert sys.steps == 1000
    assert theta == pytest.approx(-theta0, abs=1e-4 * theta0)
