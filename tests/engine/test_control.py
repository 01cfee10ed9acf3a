"""Sampled PD/PID pose controllers (engine.kernels.control) against linear control theory:
the steady-state error under a constant disturbance, saturation per body axis, deadband."""
import math

import numpy as np
import pytest

import engine
from engine.kernels.rotations import qlog

AL = {"youngs_modulus": 70e9, "density": 2700.0}
MASS = 2.0
INERTIA = (0.3, 0.5, 0.4)


def _scene(controller, *, force=(0, 0, 0), torque=(0, 0, 0), duration=40.0, dt=0.01,
           orientation=(1.0, 0.0, 0.0, 0.0), position=(0.0, 0.0, 0.0)):
    return engine.parse_scene({
        "materials": {"al": AL},
        "bodies": [{"name": "chaser", "material": "al",
                    "shape": {"type": "box", "size": [1.0, 0.8, 0.6]},
                    "mass_properties": {"mass": MASS,
                                        "inertia": [[INERTIA[0], 0, 0], [0, INERTIA[1], 0],
                                                    [0, 0, INERTIA[2]]]},
                    "motion": {"type": "free"},
                    "pose": {"position": list(position), "orientation": list(orientation)},
                    "external_force": list(force), "external_torque": list(torque)}],
        "controllers": [dict({"name": "hold", "body": "chaser"}, **controller)],
        "run": {"duration": duration, "dt": dt, "record_interval": 0.5}})


def _mesh_rotvec(system):
    # q_mesh = q_body q_bm; the box's mesh axes are its principal axes (diagonal inertia)
    from engine.kernels import control as C
    q = system.bodies.q[0]
    qbm = system.mission.ctl_par[0, C.P_QBM:C.P_QBM + 4]
    from engine.model.layout import quat_mul as quat_mul_np
    qm = quat_mul_np(q, qbm)
    if qm[0] < 0:
        qm = -qm
    return np.array(qlog(*qm))


def test_pd_steady_state_error_is_disturbance_over_stiffness():
    # PD theory: a constant disturbance F_d against kp e + kd e' settles at e = -F_d / kp,
    # whatever the sampling (the held command is constant at equilibrium). Critically
    # damped (kd = 2 sqrt(kp m)): after 40 s = 57 time constants the transient is below
    # 1e-20, so the tolerance only covers rounding. A factor in kp, a sign in the error, or
    # a disturbance lost in the hold would each be off by the whole error.
    kp, kpa = 2.0, 0.5
    kd = 2 * math.sqrt(kp * MASS)
    kda = 2 * math.sqrt(kpa * max(INERTIA))
    f_d = np.array([0.5, -0.2, 0.3])
    t_d = np.array([0.01, 0.02, -0.015])
    sc = _scene({"position": [1.0, 2.0, 3.0], "sample_interval": 0.05,
                 "position_gains": {"proportional": kp, "derivative": kd},
                 "attitude_gains": {"proportional": kpa, "derivative": kda}},
                force=f_d, torque=t_d, duration=60.0)
    sys = engine.build(sc)
    assert "controllers" in sys.stages and "external_body_loads" in sys.stages
    engine.run(sys)
    assert np.allclose(sys.bodies.pos[0], np.array([1.0, 2.0, 3.0]) + f_d / kp, rtol=0,
                       atol=1e-9)
    # the attitude law is kp * rotation vector, so the equilibrium is exact: rotvec = T_d/kp
    assert np.allclose(_mesh_rotvec(sys), t_d / kpa, rtol=0, atol=1e-8)
    from engine.stepping.observables import controller_record
    rec = controller_record(sys, 0)
    # the applied force balances the disturbance (world = body axes at the target attitude
    # up to the small steady rotation, so compare the world impulse rate instead)
    assert np.allclose(rec["position_error"], -f_d / kp, atol=1e-9)


def test_pid_integral_removes_the_steady_state_error():
    # with an integral term the equilibrium needs e = 0 (ki * integral(e) carries F_d);
    # s^3 + (kd/m) s^2 + (kp/m) s + ki/m, Routh-stable as kd kp > ki m. After 120 s the slowest
    # pole (~0.3/s) has decayed by e^-36: the error must be below 1e-6 of the PD error.
    kp, ki = 2.0, 0.5
    kd = 2 * math.sqrt(kp * MASS)
    f_d = np.array([0.5, -0.2, 0.3])
    sc = _scene({"position": [0.0, 0.0, 0.0], "sample_interval": 0.05,
                 "position_gains": {"proportional": kp, "derivative": kd, "integral": ki}},
                force=f_d, duration=120.0, dt=0.02)
    sys = engine.build(sc)
    engine.run(sys)
    assert np.linalg.norm(sys.bodies.pos[0]) < 1e-6 * np.linalg.norm(f_d / kp)


def test_saturation_is_per_body_axis():
    # the chaser is turned 90 deg about z (its x axis along world y). A far target along
    # world +x asks for a large force along body -y, clipped to max_force[1] = 0.2 N: the
    # body accelerates at 0.2 / m along world x. Clipping in world axes would give 0.1 / m.
    s = math.sqrt(0.5)
    sc = _scene({"position": [100.0, 0.0, 0.0], "sample_interval": 0.1,
                 "orientation": [s, 0.0, 0.0, s],
                 "position_gains": {"proportional": 50.0},
                 "attitude_gains": {"proportional": 1.0, "derivative": 1.0},
                 "max_force": [0.1, 0.2, 0.3], "max_torque": [0.01, 0.01, 0.01]},
                orientation=(s, 0.0, 0.0, s), duration=10.0)
    sys = engine.build(sc)
    res = engine.run(sys)
    with res.open() as r:
        app = r.series("controllers/hold/applied_force")
        cmd = r.series("controllers/hold/commanded_force")
    assert np.all(np.abs(app) <= np.array([0.1, 0.2, 0.3]) * (1 + 1e-12))
    assert np.all(np.abs(cmd[1:, 1]) > 0.2)            # it really was saturated
    # x(t) = a t^2 / 2 with a = 0.2 N / 2 kg, thrust from the first sample on (t = dt: the
    # 1e-3 relative tolerance covers starting one step of 10 ms late in 10 s, 2 dt / t)
    a = 0.2 / MASS
    t = sys.time
    assert sys.bodies.pos[0, 0] == pytest.approx(0.5 * a * t * t, rel=3e-3)
    assert np.linalg.norm(sys.bodies.pos[0, 1:]) < 1e-9
    # Delta-v is the integral of |F| / m: 0.2 N / 2 kg for 10 s = 1 m/s
    from engine.stepping.observables import controller_record
    assert controller_record(sys, 0)["delta_v"] == pytest.approx(a * t, rel=3e-3)


def test_deadband_commands_nothing_inside_it():
    # 1 cm from the target with a 2 cm deadband: no force, the body stays put; with a 5 mm
    # deadband it is pulled in.
    for band, moves in ((0.02, False), (0.005, True)):
        sc = _scene({"position": [0.01, 0.0, 0.0], "sample_interval": 0.1,
                     "position_deadband": band,
                     "position_gains": {"proportional": 1.0, "derivative": 2.0}},
                    duration=1.0)
        sys = engine.build(sc)
        engine.run(sys)
        assert (abs(sys.bodies.pos[0, 0]) > 1e-4) == moves


# ----------------------------------------------------------------- release rule (issue 15)
W0, ALPHA, THRESHOLD = 0.5, 0.1, 0.377   # rad/s, rad/s^2, rad/s: |omega| < 0.377 from 1.23 s


def _release_scene(release, *, duration=20.0):
    # the target spins at W0 about its principal z axis and a constant torque I*ALPHA brakes
    # it: omega_z(t) = W0 - ALPHA t (exact: torque along a principal axis), below THRESHOLD
    # from t_c = 1.23 s, through zero at 5 s, and back above THRESHOLD (negative) from 8.77 s.
    # The chaser is held 2 m along x from the target's centre (where it starts, so it holds
    # still until the release), the two boxes 1 m apart: no contact.
    box = {"shape": {"type": "box", "size": [1.0, 1.0, 1.0]}, "material": "al",
           "motion": {"type": "free"},
           "mass_properties": {"mass": MASS, "inertia": [[0.4, 0, 0], [0, 0.4, 0],
                                                         [0, 0, 0.4]]}}
    ctl = {"name": "hold", "body": "chaser", "reference": "target",
           "position": [2.0, 0.0, 0.0], "sample_interval": 0.1,
           "position_gains": {"proportional": 2.0, "derivative": 4.0}}
    ctl.update(release)
    return engine.parse_scene({
        "materials": {"al": AL},
        "bodies": [dict(box, name="target", angular_velocity=[0.0, 0.0, W0],
                        external_torque=[0.0, 0.0, -0.4 * ALPHA]),
                   dict(box, name="chaser", pose={"position": [2.0, 0.0, 0.0]})],
        "controllers": [ctl],
        "run": {"duration": duration, "dt": 0.01, "record_interval": 0.1}})


def test_release_switches_at_the_first_sample_below_the_threshold_and_stays():
    # Samples fall every 0.1 s; |omega| crosses 0.377 rad/s at 1.23 s, so the sample at
    # 1.2 s sees 0.380 and the one at 1.3 s sees 0.370: release at 1.3 s exactly (the margin,
    # 0.003 rad/s, is 3 steps of spin change, so step-timing detail cannot move it). Catches:
    # a release at the first sample whatever the spin (inverted test), one sample late or
    # early, the offset applied before the release, and a release that unlatches when the
    # spin grows back above the threshold at 8.77 s (the chaser would return to x = 2 m).
    sc = _release_scene({"release_below": THRESHOLD, "release_offset": [1.0, 0.0, 0.5]})
    sys = engine.build(sc)
    res = engine.run(sys)
    with res.open() as r:
        t = r.time
        released = r.series("controllers/hold/released")
        release_time = r.series("controllers/hold/release_time")
        chaser = r.series("bodies/chaser/position")
    assert release_time[-1] == pytest.approx(1.3, abs=1e-9)
    assert np.all(released[t < 1.3 - 1e-6] == 0.0) and np.all(release_time[t < 1.29] == -1.0)
    assert np.all(released[t > 1.3 + 1e-6] == 1.0)
    # before the release the chaser holds at its start, no command (zero error)
    assert np.all(np.abs(chaser[t < 1.29] - [2.0, 0.0, 0.0]) < 1e-12)
    # the spin came back above the threshold long before the end: still released, and the
    # chaser settled at the retreat point. PD with kd = 2 sqrt(kp m): time constant 1 s,
    # 18.7 s later the transient is ~1e-6 of the 1.1 m step; 1e-4 m covers it
    assert abs(sys.bodies.w[0, 2]) > THRESHOLD
    assert np.allclose(sys.bodies.pos[1] - sys.bodies.pos[0], [3.0, 0.0, 0.5], atol=1e-4)


def test_release_needs_a_reference():
    # the rule watches the reference's spin: without one it would never fire, silently
    with pytest.raises(engine.SceneError, match="release_below"):
        engine.parse_scene({
            "materials": {"al": AL},
            "bodies": [{"name": "chaser", "material": "al",
                        "shape": {"type": "box", "size": [1.0, 0.8, 0.6]},
                        "mass_properties": {"mass": MASS, "inertia": [[0.3, 0, 0],
                                                                      [0, 0.5, 0],
                                                                      [0, 0, 0.4]]},
                        "motion": {"type": "free"}}],
            "controllers": [{"name": "hold", "body": "chaser", "release_below": 0.1}],
            "run": {"duration": 1.0, "dt": 0.01, "record_interval": 0.5}})


def test_without_release_below_nothing_changes():
    # A threshold the target never reaches (1e-9 rad/s) exercises the new branch without
    # firing: every recorded channel must be bit-identical to the scene without the field,
    # which has no release channels at all (result files as before issue 15). Catches a
    # release offset added unconditionally, a reordered sum in the target, or a release
    # that fires on a zero threshold.
    runs = []
    for release in ({}, {"release_below": 1e-9, "release_offset": [5.0, 0.0, 0.0]}):
        sys = engine.build(_release_scene(release, duration=3.0))
        res = engine.run(sys)
        with res.open() as r:
            runs.append({k: r.series(k) for k in r.channels()})
    plain, never = runs
    assert "controllers/hold/released" not in plain
    assert np.all(never["controllers/hold/released"] == 0.0)
    for key, val in plain.items():
        assert np.array_equal(val, never[key]), key


def test_contact_channels_hold_contact_alone_and_actuators_their_own():
    """A controlled body with no contact at all: its recorded ``contact_force`` and
    ``contact_torque`` are exactly zero at every frame, while ``actuator_force`` /
    ``actuator_torque`` hold the controller's thrust (its applied force and torque turned
    from the body's mesh axes into the world: here a body turned 60 degrees about z whose
    principal axes are not its mesh axes, so a mix-up of the frames shows; the target's attitude is 30 degrees away, so there is a
    torque too) and ``total_force`` is thrust plus the external force.
    Catches the contact channels recording the body's whole accumulated force (the chaser
    of detumble_upper_stage showed -10 N of thrust as "contact force")."""
    s = math.sqrt(0.5)
    f_ext = np.array([0.05, -0.02, 0.01])
    sc = _scene({"position": [1.0, -0.5, 0.3], "orientation": [s, 0.0, 0.0, s],
                 "sample_interval": 0.1,
                 "position_gains": {"proportional": 1.0, "derivative": 2.0},
                 "attitude_gains": {"proportional": 0.5, "derivative": 1.0}},
                orientation=(math.cos(math.pi / 6), 0.0, 0.0, math.sin(math.pi / 6)),
                force=tuple(f_ext), duration=2.0)
    sc = sc.model_copy(update={"run": sc.run.model_copy(update={"channels": ["bodies"]})})
    system = engine.build(sc)
    res = engine.run(system)
    with res.open() as r:
        contact = r.series("bodies/chaser/contact_force")
        contact_t = r.series("bodies/chaser/contact_torque")
        thrust = r.series("bodies/chaser/actuator_force")
        thrust_t = r.series("bodies/chaser/actuator_torque")
        total = r.series("bodies/chaser/total_force")
        applied = r.series("controllers/hold/applied_force")
        applied_t = r.series("controllers/hold/applied_torque")
        q = r.series("bodies/chaser/orientation")
    assert np.all(contact == 0.0) and np.all(contact_t == 0.0)  # nothing touches: exactly 0
    assert np.abs(thrust[1:]).max() > 0.1 and np.abs(thrust_t[1:]).max() > 1e-3
    # same magnitudes as the controller's own record (rotation keeps lengths: rounding only)
    np.testing.assert_allclose(np.linalg.norm(thrust, axis=1),
                               np.linalg.norm(applied, axis=1), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(thrust_t, axis=1),
                               np.linalg.norm(applied_t, axis=1), rtol=1e-12, atol=1e-15)
    # in world axes: the command is in the mesh axes, q_mesh = q_body q_bm (the principal
    # frame is the engine's body frame)
    from engine.kernels import control as C
    from engine.model.layout import quat_mul, quat_to_matrix
    qbm = system.mission.ctl_par[0, C.P_QBM:C.P_QBM + 4]
    rot = np.array([quat_to_matrix(quat_mul(qk, qbm)) for qk in q])
    world = np.einsum("fij,fj->fi", rot, applied)
    np.testing.assert_allclose(thrust, world, rtol=0, atol=1e-12 * np.abs(world).max())
    # (frame 0 precedes the first force evaluation)
    np.testing.assert_allclose(total[1:], thrust[1:] + f_ext, rtol=0, atol=1e-12)


def test_automatic_dt_is_at_most_the_sample_interval_and_the_hold_follows_pd_theory():
    # A lone body held by a sampled PD loop: nothing moves elastically, so the automatic
    # step used to be the record interval (0.5 s here), five samples per step: the loop's
    # derivative gain then acts as a damper with kd h / m = 2 (the explicit limit) and the
    # hold rings or diverges. The step is now capped at the 0.1 s sample interval, and the
    # offset body returns as the continuous critically damped law x0 (1 + w t) e^(-w t)
    # (w = 2 rad/s). Tolerance 0.06 x0: the zero-order hold delays the command by about
    # half a sample (0.05 s), at most x0 w e^-1 x 0.05 s = 0.037 x0 off the closed form.
    kp = 8.0
    kd = 2 * math.sqrt(kp * MASS)
    x0 = 1.0
    sc = _scene({"position": [0.0, 0.0, 0.0], "sample_interval": 0.1,
                 "position_gains": {"proportional": kp, "derivative": kd}},
                duration=4.0, dt=None, position=(x0, 0.0, 0.0))   # (dt: automatic)
    sys = engine.build(sc)
    assert sys.dt == pytest.approx(0.1) and "controller 'hold'" in sys.dt_limited_by
    assert engine.estimate(sc).dt == sys.dt   # the estimate takes the same cap
    w = math.sqrt(kp / MASS)
    for t in (0.5, 1.0, 1.5, 2.5, 4.0):
        engine.run(sys, until=t)
        expected = x0 * (1 + w * t) * math.exp(-w * t)
        assert sys.bodies.pos[0][0] == pytest.approx(expected, abs=0.06 * x0)
