"""The designer's figures of study detumble (issue 25 item 6): the debris's CW drift, the
propellant, per-axis against gimballed thrust, and the brush's moment about the chaser's
centre of mass."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from studio.studies.detumble_analysis import (G0, cw_drift, cw_min_separation,
                                              designer_figures, propellant_mass)

N = 0.0011  # rad/s: a low orbit's mean motion


def test_cw_drift_matches_a_scipy_integration_of_the_hill_equations():
    # x'' = 3n^2 x + 2n y', y'' = -2n x', z'' = -n^2 z integrated by scipy (rtol 1e-11) over
    # 1.5 orbits against the closed form: agreement to 1e-6 m on km-scale drifts. Catches a
    # sign in the Coriolis terms or a swapped coefficient (metres off within an orbit).
    pos, vel = np.array([0.5, -2.0, 0.3]), np.array([0.01, -0.02, 0.005])
    times = np.linspace(0, 1.5 * 2 * math.pi / N, 7)

    def rhs(t, s):
        x, y, z, vx, vy, vz = s
        return [vx, vy, vz, 3 * N * N * x + 2 * N * vy, -2 * N * vx, -N * N * z]

    ref = solve_ivp(rhs, (0, times[-1]), np.concatenate([pos, vel]), t_eval=times,
                    rtol=1e-11, atol=1e-12).y[:3].T
    assert cw_drift(N, pos, vel, times) == pytest.approx(ref, abs=1e-6)
    # without an orbit: a straight line
    assert cw_drift(0.0, pos, vel, [10.0])[0] == pytest.approx(pos + 10 * vel)


def test_min_separation_of_a_debris_leaving_along_the_line():
    # n = 0: the debris leaves the held chaser at 0.1 m/s from 2 m: the minimum is at t = 0
    d, t = cw_min_separation(0.0, [2.0, 0, 0], [0.1, 0, 0], [0.0, 0, 0], 100.0)
    assert (d, t) == (pytest.approx(2.0), 0.0)
    # passing by: from (-5, 1, 0) at +0.5 m/s along x, closest (1 m) at t = 10 s
    d, t = cw_min_separation(0.0, [-5.0, 1.0, 0], [0.5, 0, 0], [0.0, 0, 0], 40.0)
    assert d == pytest.approx(1.0, abs=1e-9) and t == pytest.approx(10.0, abs=0.02)


def test_propellant_is_the_rocket_equation():
    # dv = Isp g0 burns 1 - 1/e of the wet mass
    assert propellant_mass(300.0, 220.0 * G0, 220.0) == pytest.approx(300 * (1 - math.exp(-1)))


def test_per_axis_thrust_needs_sqrt2_more_for_a_diagonal_push():
    # a constant 2 N along (1, 1, 0)/sqrt(2) in body axes for 10 s on 300 kg: gimballed
    # 2*10/300, per-axis thrusters fire both x and y: sqrt(2) times that. A per-axis figure
    # computed as |F| (the old Delta-v) would equal the gimballed one.
    t = np.linspace(0, 10, 101)
    f = np.tile([math.sqrt(2), math.sqrt(2), 0.0], (t.size, 1))
    d = {"time": t, "n_contacts": np.ones(t.size), "chaser_mass": 300.0,
         "delta_v": 2.0 * t / 300.0, "applied_force": f,
         "angular_impulse": np.outer(t, [0.0, 0.0, 0.3]),
         "chaser_torque_com": np.tile([0.0, 1.5, 0.0], (t.size, 1)),
         "target_position": np.tile([2.0, 0, 0], (t.size, 1)),
         "target_velocity": np.tile([0.1, 0, 0], (t.size, 1)),
         "chaser_position": np.zeros((t.size, 3)), "chaser_velocity": np.zeros((t.size, 3)),
         "mean_motion": 0.0}
    out = designer_figures(d, isp=300.0, drift_time=100.0)
    assert out["delta_v_gimballed"] == pytest.approx(20 / 300)
    assert out["delta_v_per_axis"] == pytest.approx(math.sqrt(2) * 20 / 300)
    assert out["propellant_per_axis"] > out["propellant_gimballed"]
    assert out["wheel_momentum"] == pytest.approx(3.0)
    assert out["peak_chaser_torque_com"] == pytest.approx(1.5)
    assert out["debris_dv"] == pytest.approx(0.1) and out["debris_speed"] == pytest.approx(0.1)
    assert out["min_separation"] == pytest.approx(2.0)


def test_mount_torque_is_the_roots_moment_about_the_chasers_centre_of_mass():
    # random forces and torques on the root nodes of the detumble brush: the recorded moment
    # about the chaser's centre of mass (engine.stepping.observables.mount_torques, via the root
    # reactions about the brush base) against the step loop's own transfer of the roots'
    # loads onto the body (roots_to_bodies, about the body's centre). A moment left about the
    # base (the old peak_chaser_torque) misses the 0.5 m lever x force term.
    import engine
    from engine.kernels.stepper import roots_to_bodies
    from engine.stepping.observables import mount_torques
    from studio import presets

    sys = engine.build(presets.load_preset_or_file("detumble_upper_stage"))
    nd, rt, bd = sys.nodes, sys.roots, sys.bodies
    rng = np.random.default_rng(1)
    nd.f[:] = 0.0
    nd.t[:] = 0.0
    nd.f[rt.node] = rng.normal(size=(rt.node.size, 3))
    nd.t[rt.node] = 0.01 * rng.normal(size=(rt.node.size, 3))
    bf, btq = np.zeros_like(bd.f), np.zeros_like(bd.tq)
    roots_to_bodies(nd.x, nd.f, nd.t, rt.node, rt.body, bd.pos, bf, btq)
    k = [b.name for b in sys.scene.bodies].index("chaser")
    # rounding only (sums of ~85 terms of order 1 N x 0.5 m)
    assert mount_torques(sys)["brush"] == pytest.approx(btq[k], abs=1e-9)
