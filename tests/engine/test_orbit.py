"""Relative orbital dynamics (Clohessy-Wiltshire, engine.kernels.orbit) against the closed-form
solution, the Jacobi integral, and the inertial (n = 0) engine it must leave untouched."""
import math

import numpy as np
import pytest

import engine
from engine.model.layout import quat_to_matrix

from analytic import clohessy_wiltshire  # tests/engine is on sys.path

N_LEO = 0.0011313666536110223  # rad/s: 400 km circular orbit
AL = {"youngs_modulus": 70e9, "density": 2700.0}


def _body_scene(position, velocity, angular_velocity=(0.0, 0.0, 0.0), duration=100.0,
                dt=1.0, orbit=None, record_interval=None):
    env = {} if orbit is None else {"orbit": orbit}
    return engine.parse_scene({
        "materials": {"al": AL},
        "bodies": [{"name": "b", "material": "al",
                    "shape": {"type": "box", "size": [1.0, 0.6, 0.3]},
                    "mass_properties": {"density": 100.0}, "motion": {"type": "free"},
                    "pose": {"position": list(position)}, "velocity": list(velocity),
                    "angular_velocity": list(angular_velocity)}],
        "environment": env,
        "run": {"duration": duration, "dt": dt,
                "record_interval": record_interval or duration}})


def test_closed_relative_orbit_returns_to_start_after_one_orbit():
    # CW closed-orbit initial condition: y'(0) = -2 n x(0) removes the secular drift; z
    # oscillates at n. The drift step is the exact CW flow, so the only error is rounding:
    # N = 600 steps of a few ulp of |r| ~ 20 m each is ~1e-11 m; a wrong Coriolis sign or
    # factor, or a missing tidal term, is off by metres.
    n = N_LEO
    period = 2 * math.pi / n
    r0 = (10.0, 5.0, 3.0)
    v0 = (0.004, -2 * n * r0[0], 0.002)
    sys = engine.build(_body_scene(r0, v0, duration=period, dt=period / 600,
                                   orbit={"mean_motion": n}))
    assert sys.flags.orbit and "orbit" in sys.stages
    engine.run(sys)
    assert sys.steps == 600
    assert np.allclose(sys.bodies.pos[0], r0, rtol=0, atol=1e-9)
    assert np.allclose(sys.bodies.v[0], v0, rtol=0, atol=1e-12)


def test_radial_offset_drifts_as_the_closed_form():
    # released at rest 1 m above the reference orbit: x = 4 - 3 cos nt, y = 6 (sin nt - nt),
    # i.e. it falls behind by 6 pi m per orbit. Tolerance as above (rounding only).
    n = N_LEO
    t_end = 0.37 * 2 * math.pi / n
    r0, v0 = (1.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    sys = engine.build(_body_scene(r0, v0, duration=t_end, dt=t_end / 400,
                                   orbit={"mean_motion": n}))
    engine.run(sys)
    r_ref, v_ref = clohessy_wiltshire(n, sys.time, r0, v0)
    assert abs(sys.time - t_end) < 1e-9
    assert np.allclose(sys.bodies.pos[0], r_ref, rtol=0, atol=1e-10)
    assert np.allclose(sys.bodies.v[0], v_ref, rtol=0, atol=1e-13)
    # and it did move: the along-track drift is metres, the check is not vacuous
    assert r_ref[1] < -3.0


def test_altitude_gives_the_kepler_mean_motion():
    orbit = engine.parse_scene({"materials": {"al": AL}, "environment": {
        "orbit": {"altitude": 400e3}}, "run": {"duration": 1, "record_interval": 1}}
    ).environment.orbit
    # n = sqrt(mu / a^3), mu = 3.986004418e14, a = 6378137 + 400e3 m: 92.56 min period
    assert orbit.n == pytest.approx(math.sqrt(3.986004418e14 / 6778137.0 ** 3), rel=1e-15)
    assert 2 * math.pi / orbit.n / 60 == pytest.approx(92.56, abs=0.01)


def test_inertially_fixed_body_turns_backwards_in_the_hill_frame():
    # the Hill frame turns at +n about z; a body that does not rotate in inertial space
    # (angular velocity -n z relative to the frame) is seen turned by -90 deg after a
    # quarter orbit: its x axis points along -y. A missing frame rotation leaves it at +x,
    # a wrong sign puts it at +y.
    n = N_LEO
    quarter = 0.5 * math.pi / n
    sys = engine.build(_body_scene((0, 0, 0), (0, 0, 0), angular_velocity=(0, 0, -n),
                                   duration=quarter, dt=quarter / 200,
                                   orbit={"mean_motion": n}))
    R0 = quat_to_matrix(sys.bodies.q[0])
    engine.run(sys)
    R = quat_to_matrix(sys.bodies.q[0]) @ R0.T  # rotation since the start, Hill frame
    assert np.allclose(R @ [1, 0, 0], [0, -1, 0], atol=1e-12)
    assert np.allclose(sys.bodies.w[0], [0, 0, -n], atol=1e-15)
    assert np.allclose(sys.bodies.L[0], 0.0, atol=1e-15)


def _cantilever(orbit):
    # the seed's steel rod (L = 0.4 m, d = 1.42 mm) along z, root fixed in the Hill frame at
    # x = 0 (no static tidal load across it), x-pushed tip for 5 ms, then free; n = 5 rad/s
    # puts the tidal stiffness 3 n^2 at 1/20 of the first bending mode's omega^2 (40 rad/s)
    # and the axial tidal compression at 1/20 of the buckling load: the frame's forces
    # matter, the rod stays stable
    env = {} if orbit is None else {"orbit": orbit}
    return engine.parse_scene({
        "materials": {"steel": {"youngs_modulus": 200e9, "poisson_ratio": 0.3,
                                "density": 7640.0}},
        "brushes": [{"name": "rod", "material": "steel", "bristle_length": 0.4,
                     "root_radius": 0.71e-3, "tip_radius": 0.71e-3, "n_nodes": 5,
                     "base": {"position": [0.0, 0.1, 0.0]}}],
        "loads": [{"brush": "rod", "node": -1, "force": [0.05, 0.0, 0.0],
                   "profile": {"times": [0.0, 0.005, 0.005], "values": [1.0, 1.0, 0.0]}}],
        "environment": env,
        "run": {"duration": 1.0, "record_interval": 0.01, "channels": ["energy"]}})


def test_jacobi_integral_of_a_vibrating_rod_stays_bounded():
    # Jacobi integral C = kinetic + bond + tidal potential. The splitting is symplectic, so C
    # oscillates with an O(dt^2) amplitude and does not drift: over 6 bending periods its
    # spread stays below 1e-7 of C (measured 9e-9 at the automatic dt), and the second half
    # drifts no further than the first. An explicit Euler Coriolis kick (v += dt a_c) grows
    # |v|^2 by (2 n dt)^2 per step: 6e-9 x 1.3e5 steps ~ 8e-4, far above the bound; a tidal
    # term of the wrong sign breaks the balance at once.
    sys = engine.build(_cantilever({"mean_motion": 5.0}))
    engine.run(sys, until=0.01)
    c, tip_y = [], []
    for i in range(2, 101):  # fixed ends: a run shorter than dt / 2 would make no step
        engine.run(sys, until=0.01 * i)
        e = engine.energies(sys)
        c.append(e["total"])
        tip_y.append(sys.nodes.x[-1, 1])
    c = np.array(c)
    spread = np.ptp(c) / abs(c.mean())
    assert spread < 1e-7
    half = len(c) // 2
    assert abs(c[half:].mean() - c[:half].mean()) < 0.25 * np.ptp(c) + 1e-12
    # the frame's forces did act: pushed along x only, the tip left its plane y = 0.1 m
    # (Coriolis, ~2 n v / omega^2 ~ mm); inertially it would stay there exactly
    assert np.max(np.abs(np.array(tip_y) - 0.1)) > 1e-4


def test_zero_mean_motion_leaves_the_scene_bit_for_bit_unchanged():
    # n = 0 must take the inertial code path: same bits as a scene without an orbit. A CW
    # flow evaluated at n = 0 would divide by zero; a frame correction applied at n = 0
    # would change round-off.
    a = engine.build(_cantilever(None))
    b = engine.build(_cantilever({"mean_motion": 0.0}))
    assert not b.flags.orbit
    engine.run(a, until=0.05)
    engine.run(b, until=0.05)
    for name in ("x", "v", "q", "w"):
        assert np.array_equal(getattr(a.nodes, name), getattr(b.nodes, name)), name
    sa = _body_scene((1, 2, 3), (0.1, 0, 0), angular_velocity=(0.3, 0.2, 0.1), dt=0.1,
                     duration=10.0)
    sb = _body_scene((1, 2, 3), (0.1, 0, 0), angular_velocity=(0.3, 0.2, 0.1), dt=0.1,
                     duration=10.0, orbit={"mean_motion": 0.0})
    a, b = engine.build(sa), engine.build(sb)
    engine.run(a)
    engine.run(b)
    for name in ("pos", "q", "v", "w", "L"):
        assert np.array_equal(getattr(a.bodies, name), getattr(b.bodies, name)), name
