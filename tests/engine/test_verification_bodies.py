"""Verification of rigid bodies and contacts against conservation laws and Coulomb's law.

References are independent of the engine: conservation of angular momentum and energy (exact
physical laws for the isolated scenes below), Euler's equations' intermediate-axis instability,
and the closed-form acceleration of a block sliding on an incline, a = g (sin θ − μ cos θ).
"""
import math

import numpy as np
import pytest

import engine
from engine.model.layout import quat_to_matrix

STEEL = {"youngs_modulus": 200e9, "poisson_ratio": 0.3, "density": 7800.0}
FIGURES: dict[str, float] = {}  # measured values, printed by benchmarks/verification_figures.py
SILICONE = {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1700.0}


def _relative_drift(series: np.ndarray) -> float:
    ref = np.linalg.norm(series[0])
    return float(np.max(np.linalg.norm(series - series[0], axis=-1)) / ref)


def _run_collecting(system, until, every, quantity):
    """Run in pieces and evaluate ``quantity(system)`` at each piece's end."""
    values = [quantity(system)]
    t = system.time
    while t < until - 1e-12:
        t = min(until, t + every)
        engine.run(system, until=t)
        values.append(quantity(system))
    return np.array(values)


def test_intermediate_axis_flip_conserves_momentum_and_energy():
    # a box spun about its intermediate principal axis with a tiny perturbation must flip
    # (Dzhanibekov effect) while L and E of the torque-free body stay constant
    scene = engine.parse_scene({
        "materials": {"al": {"youngs_modulus": 70e9, "density": 2700}},
        "bodies": [{"name": "box", "material": "al", "shape": {"type": "box",
                                                                "size": [0.1, 0.2, 0.3]},
                    "mass_properties": {"density": 2700}, "motion": {"type": "free"},
                    "angular_velocity": [1e-3, 5.0, 1e-3]}],
        "run": {"duration": 12.0, "dt": 1e-3, "record_interval": 0.02,
                "channels": ["bodies", "energy"]}})
    system = engine.build(scene)
    L0 = engine.angular_momentum(system)
    result = engine.run(system)
    with result.open() as res:
        q = res.series("bodies/box/orientation")
        w = res.series("bodies/box/angular_velocity")
        kinetic = res.series("energy/kinetic")
    w_body_y = np.array([quat_to_matrix(qq).T @ ww for qq, ww in zip(q, w)])[:, 1]
    assert w_body_y[0] > 4.9
    assert w_body_y.min() < -4.9, "the body must flip about its intermediate axis"
    L1 = engine.angular_momentum(system)
    FIGURES["flip: |dL|/|L|"] = float(np.linalg.norm(L1 - L0) / np.linalg.norm(L0))
    FIGURES["flip: max |dE|/E"] = float(np.max(np.abs(kinetic - kinetic[0])) / kinetic[0])
    # the splitting integrator only rotates L's body-frame image: round-off level
    assert np.linalg.norm(L1 - L0) / np.linalg.norm(L0) < 1e-6
    # symplectic splitting: bounded O(dt^2) energy error, far below the 1e-4
    assert np.max(np.abs(kinetic - kinetic[0])) / kinetic[0] < 1e-4


def test_two_spheres_striking_a_free_cube_conserve_angular_momentum():
    # seed appendix H: YADE lost several percent here; with equal and opposite forces applied
    # at one contact point the discrete angular momentum is conserved to round-off
    scene = engine.parse_scene({
        "materials": {"steel": STEEL},
        "contact_pairs": [{"materials": ["steel", "steel"], "friction_angle": 0.5,
                           "restitution": 0.6}],
        "bodies": [
            {"name": "cube", "material": "steel", "shape": {"type": "box", "size": [0.1] * 3},
             "mass_properties": {"density": 7800}, "motion": {"type": "free"},
             "angular_velocity": [0.0, 0.0, 1.0]},
            {"name": "s1", "material": "steel", "shape": {"type": "sphere", "radius": 0.02},
             "mass_properties": {"density": 7800}, "motion": {"type": "free"},
             "pose": {"position": [-0.09, 0.03, 0.01]}, "velocity": [2.0, 0.0, 0.0]},
            {"name": "s2", "material": "steel", "shape": {"type": "sphere", "radius": 0.02},
             "mass_properties": {"density": 7800}, "motion": {"type": "free"},
             "pose": {"position": [0.02, -0.1, -0.03]}, "velocity": [0.0, 3.0, 0.5]}],
        "run": {"duration": 0.03, "record_interval": 0.001,
                "channels": ["bodies", "contacts"]}})
    system = engine.build(scene)
    assert "body_body_contacts" in system.stages
    about = np.array([0.3, -0.2, 0.1])  # any fixed point: the law holds about every point
    L = _run_collecting(system, 0.03, 0.003, lambda s: engine.angular_momentum(s, about))
    FIGURES["two spheres hit a free cube: max |dL|/|L|"] = _relative_drift(L)
    cube_w = system.bodies.w[0]
    assert not np.allclose(cube_w, [0.0, 0.0, 1.0], atol=1e-3), "the spheres must hit the cube"
    # relative change allowed: 1e-6 (the bound); round-off is ~1e-13 per step
    assert _relative_drift(L) < 1e-6


def test_cube_spinning_between_two_free_brushes_conserves_angular_momentum():
    # two brushes on free bases face each other with a spinning cube between them; bristle
    # contacts with friction exchange momentum between the cube, bristles and bases, but the
    # isolated system keeps its total angular momentum
    brush = {"material": "silicone", "rows": 3, "columns": 3, "pitch": [0.004, 0.004],
             "bristle_length": 0.02, "root_radius": 0.0008, "tip_radius": 0.0005,
             "n_nodes": 4}
    base_mass = {"mass": 0.05, "inertia": [[2e-5, 0, 0], [0, 2e-5, 0], [0, 0, 2e-5]]}
    c = math.cos(math.pi / 4)
    scene = engine.parse_scene({
        "materials": {"silicone": SILICONE, "foam": {"youngs_modulus": 5e7, "density": 50}},
        "contact_pairs": [{"materials": ["silicone", "foam"], "friction_angle": 0.6},
                          {"materials": ["silicone", "silicone"], "friction_angle": 0.7}],
        "brushes": [
            dict(brush, name="left", mount="base_left",
                 base={"orientation": [c, 0, c, 0]}),     # bristles along +x
            dict(brush, name="right", mount="base_right",
                 base={"orientation": [c, 0, -c, 0]})],   # bristles along -x
        "bodies": [
            {"name": "base_left", "material": "foam", "shape": {"type": "box",
                                                                  "size": [0.004, 0.02, 0.02]},
             "mass_properties": base_mass, "motion": {"type": "free"}, "collide": False,
             "pose": {"position": [-0.0404, 0.0, 0.0]}},
            {"name": "base_right", "material": "foam", "shape": {"type": "box",
                                                                   "size": [0.004, 0.02, 0.02]},
             "mass_properties": base_mass, "motion": {"type": "free"}, "collide": False,
             "pose": {"position": [0.0404, 0.0, 0.0]}},
            {"name": "cube", "material": "foam", "shape": {"type": "box", "size": [0.04] * 3},
             "mass_properties": {"density": 50}, "motion": {"type": "free"},
             "angular_velocity": [0.0, 0.0, 20.0]}],
        "run": {"duration": 0.05, "record_interval": 0.001, "channels": ["contacts"]}})
    system = engine.build(scene)
    assert {"mounted_roots", "bristle_body_contacts", "tangential_history"} <= set(
        system.stages)
    L = _run_collecting(system, 0.05, 0.005, lambda s: engine.angular_momentum(s))
    FIGURES["cube between two free brushes: max |dL|/|L|"] = _relative_drift(L)
    # the cube must actually have been slowed by the bristles
    assert system.bodies.w[2, 2] < 19.0
    # 1e-6: the bound; all contact and bond actions are equal and opposite about one
    # point, so only round-off accumulates
    assert _relative_drift(L) < 1e-6


@pytest.mark.parametrize("tilt_deg, expect_slide", [(20.0, False), (40.0, True)])
def test_bristle_on_incline_sticks_or_slides(tilt_deg, expect_slide):
    # a steel bristle lying flat on a plate, its root mounted on a small free sled; gravity is
    # tilted by the incline angle instead of the plate; friction angle 30 degrees. A flat
    # bristle touches along its length, so the slider cannot rock or hop the way a block on
    # point feet does, and Coulomb's law alone sets its motion. The plate is soft (10 MPa)
    # so that contact overlaps are micrometres, not nanometres.
    phi = math.radians(30.0)
    th = math.radians(tilt_deg)
    g = 9.81
    r = 0.0005
    c = math.cos(math.pi / 4)
    scene = engine.parse_scene({
        "materials": {"steel": STEEL, "pad": {"youngs_modulus": 1e7, "density": 1000}},
        "contact_pairs": [{"materials": ["steel", "pad"], "friction_angle": phi,
                           "restitution": 0.1}],
        "brushes": [{"name": "rod", "material": "steel", "mount": "sled",
                     "bristle_length": 0.02, "root_radius": r, "tip_radius": r, "n_nodes": 6,
                     "base": {"orientation": [c, 0, c, 0]}}],   # lying along +x
        "bodies": [
            {"name": "sled", "material": "steel",
             "shape": {"type": "box", "size": [0.002, 0.002, 0.0005]},
             "mass_properties": {"mass": 2e-4, "inertia": [[1e-10, 0, 0], [0, 1e-10, 0],
                                                           [0, 0, 1e-10]]},
             "motion": {"type": "free"}, "collide": False, "pose": {"position": [0, 0, r]}},
            {"name": "plate", "material": "pad",
             "shape": {"type": "box", "size": [0.3, 0.05, 0.002]},
             "pose": {"position": [0.1, 0, -0.001]}}],
        "environment": {"gravity": [g * math.sin(th), 0.0, -g * math.cos(th)]},
        "run": {"duration": 0.025, "record_interval": 0.0005, "channels": ["bodies"]}})
    system = engine.build(scene)
    result = engine.run(system)
    with result.open() as res:
        t = res.time
        x = res.series("bodies/sled/position")[:, 0]
    settled = t > 0.008  # the bristle settles onto the pad within a few ms
    if expect_slide:
        a_fit = 2.0 * np.polyfit(t[settled], x[settled], 2)[0]
        a_ref = g * (math.sin(th) - math.tan(phi) * math.cos(th))
        FIGURES["incline 40 deg: a / g(sin - mu cos) - 1"] = float(a_fit / a_ref - 1)
        # 1 %: the bound (measured agreement is ~1e-6)
        assert a_fit == pytest.approx(a_ref, rel=0.01)
        assert x[-1] > 1e-4  # it really moved
    else:
        FIGURES["incline 20 deg: creep (m)"] = float(np.ptp(x[settled]))
        # sticking: only the tangential contact springs deflect (F_t / k_t ~ 1e-8 m)
        assert np.ptp(x[settled]) < 1e-6


def test_energy_is_conserved_in_a_vibrating_brush_with_elastic_contacts():
    # bristles pushed in opposite directions by a short pulse collide and vibrate; no friction,
    # no damping of any kind: total (kinetic + bond + contact) energy must stay constant
    scene = engine.parse_scene({
        "materials": {"silicone": SILICONE},
        "brushes": [{"name": "b", "material": "silicone", "rows": 2, "columns": 3,
                     "pitch": [0.0024, 0.0024], "bristle_length": 0.02,
                     "root_radius": 0.001, "tip_radius": 0.0008, "n_nodes": 5}],
        "loads": [
            {"brush": "b", "bristles": [0, 2, 4], "node": -1, "force": [0.01, 0.004, 0.0],
             "profile": {"times": [0.0, 0.002, 0.004], "values": [0.0, 1.0, 0.0]}},
            {"brush": "b", "bristles": [1, 3, 5], "node": -1, "force": [-0.01, -0.004, 0.0],
             "profile": {"times": [0.0, 0.002, 0.004], "values": [0.0, 1.0, 0.0]}}],
        # dt = 9.2e-6 s, 0.21 of the stability bound (default 0.5): the drift of these undamped
        # linear contacts falls as dt^2 (0.97 % over 1e5 steps at 2.3x this dt). The bound no
        # longer charges frictionless contacts a torque on the node's rotation, so it is 1.42x
        # what it was when this test used 0.3 for the same dt.
        "run": {"duration": 1.0, "record_interval": 0.001, "dt_safety": 0.21,
                "channels": ["energy", "contacts"]}})
    system = engine.build(scene)
    n_steps = 100_000
    end = 0.004 + n_steps * system.dt
    result = engine.run(system, until=end)
    with result.open() as res:
        t = res.time
        total = res.series("energy/total")
        contacts = res.series("contacts/bristle_bristle")
    after = t > 0.0045  # the pulse is over: from here the scene is isolated
    assert contacts[after].max() > 0, "the bristles must collide"
    e = total[after]
    tenth = max(1, len(e) // 10)
    drift = abs(e[-tenth:].mean() - e[:tenth].mean()) / e.mean()
    band = (e.max() - e.min()) / e.mean()
    FIGURES["vibrating brush, 1e5 steps: energy drift"] = float(drift)
    FIGURES["vibrating brush, 1e5 steps: energy band"] = float(band)
    # 0.5 %: the bound on the secular drift over 1e5 steps; leapfrog's energy also
    # oscillates within a bounded O(dt^2) band, 2 % at the default dt here (0.1 % at dt / 4)
    assert drift < 0.005, f"energy drift {drift:.3%}"
    assert band < 0.02, f"energy band {band:.3%}"


def _body_on_tapered_brush(body: dict, dt_factor: float, until):
    """Issue 11's brush: an undamped, frictionless 5 x 5 brush of tapered bristles (8 nodes,
    1.0 -> 0.5 mm, 20 mm long, 2.5 mm pitch) hit by the free PLA ``body`` (a scene body
    without its material), run until ``until`` (s, or a function of the automatic dt) at
    ``dt_factor`` x the automatic dt. Returns
    (relative total energy series, dt, the body's final velocity, per frame whether the body
    touches a bristle)."""
    scene = engine.parse_scene({
        "materials": {"silicone": SILICONE,
                      "pla": {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36,
                              "density": 1250.0}},
        "brushes": [{"name": "b", "material": "silicone", "rows": 5, "columns": 5,
                     "pitch": [0.0025, 0.0025], "bristle_length": 0.02,
                     "root_radius": 0.001, "tip_radius": 0.0005, "n_nodes": 8}],
        "bodies": [dict(body, material="pla")],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 10.0, "record_interval": 0.0005,
                "channels": ["energy", "contacts", "bodies"]}})
    system = engine.build(scene)
    auto_dt = system.dt
    system.dt = auto_dt * dt_factor
    result = engine.run(system, until=until(auto_dt) if callable(until) else until)
    with result.open() as res:
        total = res.series("energy/total")
        touching = res.series("contacts/bristle_body") > 0
    assert touching.any(), f"the {body['name']} must hit the brush"
    return total / total[0] - 1.0, system.dt, system.bodies.v[0].copy(), touching


def _sphere_on_tapered_brush(dt_factor: float):
    """Issue 11's scene: the brush hit off-centre by a free PLA sphere (r 6 mm, 0.5 m/s), for
    1e5 automatic steps' worth of time at ``dt_factor`` x the automatic dt. Returns (relative
    total energy series, dt, the sphere's final velocity, per frame whether it touches)."""
    return _body_on_tapered_brush(
        {"name": "ball", "shape": {"type": "sphere", "radius": 0.006},
         "mass_properties": {"density": 1250.0},
         "pose": {"position": [0.0017, 0.0009, 0.0275]},
         "motion": {"type": "free"}, "velocity": [0.0, 0.0, -0.5]},
        dt_factor, lambda auto_dt: 100_000 * auto_dt)


# slow (about 60 s: 1.1 s of ringing at dt and dt/4); the quick pass keeps the box edge-first
# impact on the same brush and tests/engine/test_energy_books.py's damped impact
@pytest.mark.slow
def test_free_sphere_on_tapered_brush_conserves_energy():
    """The sphere's contact with a segment's interior fades out towards the nodes and sees the
    taper's radius; its force must be the whole gradient of that energy (including dU/ds of the
    fade, the radius and k_n proportional to r). Bug caught: applying only w k ov n gained
    +3.9 % (up to +7.0 %) over 1e5 steps, not less at dt/2. Tolerances: 0.5 % is the issue's
    bound over 1e5 steps; a conservative leapfrog's energy error is O(dt^2), so a quarter of
    the dt must shrink the excursion while the sphere touches to at most a quarter (first
    order's ratio; a non-conservative force would not shrink it at all).

    Why the convergence is checked while the sphere touches, not over the whole run: after
    the sphere leaves (75 ms), the brush rings for the rest of the 1.1 s with bristle-bristle
    collisions, and the whole run's excursion is the leapfrog's O(dt^2) band plus a random
    walk of the small O(dt^2) energy steps of those collisions, whose sum depends on which
    collisions a chaotic run happens to have. Measured (10 kHz frames): the band within 20 ms
    windows 5.39e-4, 1.70e-4, 3.45e-5 at dt, dt/2, dt/4 and the rms step of its 20 ms mean
    1.08e-4, 2.02e-5, 6.53e-6 (both second order), but that mean wandered within +-2.5e-4
    at dt, drifted to -2.26e-4 at dt/2 and stayed within +-4.4e-5 at dt/4, so the whole
    run's excursion (the test's 2 kHz frames) went 5.38e-4, 2.89e-4, 5.79e-5 (ratio 0.54 at
    dt/2, 0.20 from dt/2 to dt/4); until the sphere has let go: 5.38e-4, 1.63e-4, 3.79e-5
    (0.30, 0.23). So the drop from 0.25 (9.28e-4 -> 2.34e-4 before issue 22's merge) to
    0.54 is this walk, not a lost order: the forces from t = 0 and the cap on the total
    normal force cannot change this scene (nothing touches at t = 0 and the bristles are
    straight, no friction, no damping), while the same merge gave the sphere its exact mass
    (3c1da2e, +0.9 %), another run with other collisions (the old engine not re-run).

    One halving is that noisy while the sphere touches too: at commit a8ca7f9 the excursion
    until it lets go measured 4.50e-4, 2.44e-4, 4.37e-5 at dt, dt/2, dt/4 (ratio 0.54 for
    the first halving, which failed the 0.5 this test once held it to, and 0.097 over two),
    so the convergence is taken at dt/4."""
    rel, dt, v_ball, touching = _sphere_on_tapered_brush(1.0)
    rel_fine, _, _, touching_fine = _sphere_on_tapered_brush(0.25)
    excursion = float(np.abs(rel).max())
    during = float(np.abs(rel[:np.nonzero(touching)[0][-1] + 2]).max())
    during_fine = float(np.abs(rel_fine[:np.nonzero(touching_fine)[0][-1] + 2]).max())
    FIGURES["sphere on tapered brush, 1e5 steps: max |dE|/E"] = excursion
    FIGURES["sphere on tapered brush, while touching: max |dE|/E"] = during
    FIGURES["sphere on tapered brush, while touching, dt/4: max |dE|/E"] = during_fine
    assert v_ball[2] > 0.0, "the sphere must bounce back"
    assert excursion < 0.005, f"energy excursion {excursion:.3%} at dt {dt:.3g} s"
    # 0.25: first order's ratio at dt/4; second order gives 0.0625 (measured 0.097 and 0.07,
    # docstring); a non-conservative force does not shrink the excursion at all (ratio ~1)
    assert during_fine < 0.25 * during, (during, during_fine)


def _box_edge_on_tapered_brush(dt_factor: float) -> tuple[np.ndarray, np.ndarray]:
    """The same brush hit by a free PLA box (20 x 12 x 12 mm, turned 45 deg about its long
    axis so that it falls edge-first, the edge along x and 0.9 mm off the middle row, 0.5
    m/s) until 0.1 s (the contact lasts from 2.5 to 82 ms). Most of the contact is with the
    edge: the bristles' segments cross it between their nodes. Returns (relative total
    energy series, the box's final velocity)."""
    half = math.radians(45.0) / 2
    rel, _dt, v, _touching = _body_on_tapered_brush(
        {"name": "box", "shape": {"type": "box", "size": [0.02, 0.012, 0.012]},
         "mass_properties": {"density": 1250.0},
         "pose": {"position": [0.0, 0.0009, 0.0295],
                  "orientation": [math.cos(half), math.sin(half), 0.0, 0.0]},
         "motion": {"type": "free"}, "velocity": [0.0, 0.0, -0.5]},
        dt_factor, 0.1)
    return rel, v


def test_free_box_edge_first_on_tapered_brush_conserves_energy():
    """A mesh edge touching a tapered segment between its nodes stores U = 1/2 w(s) chi k_n(r(s))
    ov^2 (the fade towards the nodes, the fade towards either face's plane, the taper); its
    force must be the whole gradient, including -dU/ds grad s (s the segment's point closest to
    the edge) and -dU/dchi grad chi. Bug caught: without the edge's dU/ds term (before issue
    11's fix) this scene's energy rose by 1.02 %, 1.24 %, 1.02 % at dt, dt/2, dt/4 (not
    converging); with it, 0.030 %, 0.0087 %, 0.0037 %. Tolerances: 0.1 % is 3x the measured
    excursion and 10x below the missing term's; a conservative leapfrog's error is O(dt^2),
    so halving dt must at least halve the excursion (a non-conservative force would not)."""
    rel, v_box = _box_edge_on_tapered_brush(1.0)
    rel_half, _ = _box_edge_on_tapered_brush(0.5)
    excursion = float(np.abs(rel).max())
    excursion_half = float(np.abs(rel_half).max())
    FIGURES["box edge-first on tapered brush, 0.1 s: max |dE|/E"] = excursion
    FIGURES["box edge-first on tapered brush, dt/2: max |dE|/E"] = excursion_half
    assert v_box[2] > 0.0, "the box must bounce back"
    assert excursion < 0.001, f"energy excursion {excursion:.3%}"
    assert excursion_half < 0.5 * excursion, (excursion, excursion_half)
