"""The reduced brush as a contact element (engine/kernels/patch.py, issue 25 item 2) against
independent references: the law's closed form for a flat press (engine.model.reduced_law's numpy
functions), the torsional moment mu_eff F_n r_t with the footprint's mean radius
(reduced_law.torsion_radius, a 400 x 400 midpoint sum), the energy balance of a free plate's
impact (kinetic energy before = after + what the element booked as dissipated), elastic
restitution with a lossless law, conservation of linear and angular momentum, and the
out-of-range report."""
import copy
import math

import numpy as np
import pytest

import engine
from engine.stepping.observables import angular_momentum, energies, linear_momentum
from engine.model.reduced_law import normal_force, torsion_radius

A, B = 0.06, 0.24               # m: the law's footprint
LAW = {"law_version": 1,
       "parameters": {"k": 2000.0, "p": 1.5, "c": 0.5, "eta": 0.6, "mu": 0.4, "q": 0.1,
                      "v_s": 0.01},
       "ranges": {"interference": [0.0, 0.03], "rate": [-0.5, 0.5],
                  "slip_speed": [0.0, 0.5]},
       "patch": {"size": [A, B]}}
MATERIALS = {"m": {"youngs_modulus": 1e9, "poisson_ratio": 0.3, "density": 2700.0}}
DOWN = [0.0, 1.0, 0.0, 0.0]     # half a turn about x: the patch's +z faces world -z
PLATE_TOP = 0.02                # m: the plate's upper face (z)


def _law(**par):
    law = copy.deepcopy(LAW)
    law["parameters"].update(par)
    return law


def _plate(motion="fixed", **extra):
    """A 0.5 x 0.5 x 0.1 m plate, upper face at z = PLATE_TOP."""
    body = {"name": "plate", "material": "m",
            "shape": {"type": "box", "size": [0.5, 0.5, 0.1]},
            "pose": {"position": [0.0, 0.0, PLATE_TOP - 0.05]}, "motion": {"type": motion}}
    if motion != "fixed":
        body["mass_properties"] = {"mass": 20.0, "inertia": [[0.42, 0, 0], [0, 0.42, 0],
                                                            [0, 0, 0.83]]}
    body.update(extra)
    return body


def _carrier(z_tip, law, motion=None, grid=None, **extra):
    """A body carrying one patch whose tip plane (facing down) is at height ``z_tip``, 0.2 m
    below the body's centre."""
    patch = {"name": "p", "law": law, "pose": {"position": [0.0, 0.0, -0.2],
                                               "orientation": DOWN}}
    if grid is not None:
        patch["grid"] = list(grid)
    body = {"name": "carrier", "material": "m",
            "shape": {"type": "box", "size": [0.3, 0.3, 0.1]},
            "mass_properties": {"mass": 10.0, "inertia": [[0.2, 0, 0], [0, 0.2, 0],
                                                         [0, 0, 0.3]]},
            "motion": motion or {"type": "free"}, "collide": False,
            "pose": {"position": [0.0, 0.0, z_tip + 0.2]}, "patches": [patch]}
    body.update(extra)
    return body


def _scene(bodies, duration, dt=None, channels=("bodies", "energy")):
    run = {"duration": duration, "record_interval": duration, "channels": list(channels)}
    if dt is not None:
        run["dt"] = dt
    return engine.parse_scene({"materials": MATERIALS, "bodies": bodies, "run": run})


def test_flat_press_gives_the_fitted_law():
    # a kinematic carrier presses its patch into a fixed plate at a constant 5 mm/s: at
    # every step every point has the same depth d = v t - gap and rate v, so the element's
    # force is the closed form k d^p (u(v) + c v) up to round-off in summing 64 equal shares
    v, gap = 0.005, 0.001
    carrier = _carrier(PLATE_TOP + gap, LAW, motion={
        "type": "kinematic", "profile": {"kind": "constant", "velocity": [0.0, 0.0, -v]}})
    system = engine.build(_scene([_plate(), carrier], 4.0, dt=0.01))
    assert "patch_contacts" in system.stages
    par = LAW["parameters"]
    checked = 0
    for t in (0.5, 1.0, 2.0, 3.0, 4.0):
        engine.run(system, until=t, output=False)
        d = v * system.time - gap
        expected = float(normal_force(d, v, par["k"], par["p"], par["c"], par["eta"]))
        got = system.bodies.f_contact[1]
        assert got[2] == pytest.approx(expected, rel=1e-9)  # round-off only
        assert abs(got[0]) + abs(got[1]) < 1e-9 * expected  # no slip: no friction
        checked += 1
    assert checked == 5


def test_torsion_of_a_spinning_flat_contact_matches_the_torsional_radius():
    # held at 10 mm, spinning at 10 rad/s about the patch normal: every point slips at
    # w r >= 53 mm/s >> v_s = 1 mm/s (tanh = 1), so M = mu (F_n / 1 N)^q F_n x (the grid's
    # mean point radius); the grid's midpoint rule on 8 x 32 points differs from the
    # footprint's mean radius by 0.09 % (O(h^2): 0.35 % on 4 x 16), hence 0.3 %
    law = _law(v_s=0.001)
    omega = 10.0
    carrier = _carrier(PLATE_TOP - 0.01, law, grid=(8, 32), motion={
        "type": "kinematic", "profile": {"kind": "constant",
                                         "angular_velocity": [0.0, 0.0, omega]}})
    system = engine.build(_scene([_plate(), carrier], 0.05, dt=0.01))
    engine.run(system, output=False)
    f = system.bodies.f_contact[1]
    tq = system.bodies.tq_contact[1]
    par = law["parameters"]
    fn = f[2]
    mu_eff = par["mu"] * fn ** par["q"]
    expected = -mu_eff * fn * torsion_radius(A, B, 400)   # opposing the spin
    assert tq[2] == pytest.approx(expected, rel=3e-3)
    # the normal force is the law's at zero rate, u(0) = (1 + eta) / 2
    assert fn == pytest.approx(par["k"] * 0.01 ** par["p"] * (1 + par["eta"]) / 2, rel=1e-9)


def _impact(law, vz, vx=0.0, dt=None, duration=1.5):
    """A free plate falling at vz (and sliding at vx) onto a patch facing up on a fixed
    carrier; returns the built system."""
    patch = {"name": "p", "law": law, "pose": {"position": [0.0, 0.0, 0.2]}}
    carrier = {"name": "carrier", "material": "m", "shape": {"type": "box",
                                                            "size": [0.3, 0.3, 0.1]},
               "collide": False, "patches": [patch]}
    plate = _plate("free", velocity=[vx, 0.0, -vz])
    plate["pose"] = {"position": [0.0, 0.0, 0.2 + 0.001 + 0.05]}
    return engine.build(_scene([carrier, plate], duration, dt=dt))


def test_energy_books_of_an_impact_close():
    # a lossy law (eta, rate damping, friction): the plate's kinetic energy before equals
    # its kinetic energy after plus the element's booked dissipation. The dissipation is
    # booked from the mid-step rate each step, an O(dt) quadrature of the loss over the
    # ~5000 steps in contact (measured 6e-5 of the energy at dt = 2e-4): 1e-3, and the
    # error must halve with dt (first order: a booking that missed a term would not)
    errors = []
    for dt in (2e-4, 1e-4):
        system = _impact(_law(q=0.0), 0.1, vx=0.05, dt=dt)
        e0 = energies(system)["kinetic"]
        engine.run(system, output=False)
        e = energies(system)
        assert e["contact"] == 0.0   # the plate has left: nothing stored
        assert system.bodies.v[1, 2] > 0.0
        assert e["dissipated"] > 0.2 * e0   # the law is lossy: the check is not vacuous
        errors.append(abs(e0 - e["kinetic"] - e["dissipated"]) / e0)
    assert errors[0] < 1e-3
    assert errors[1] < 0.7 * errors[0]   # first order in dt


def test_lossless_law_gives_an_elastic_impact():
    # eta = 1, c = 0, mu = 0: the element's force is conservative (k d^p per point), so
    # leapfrog returns the plate at its speed up to O((omega dt)^2) ~ 1e-6 (omega ~ 5 rad/s
    # at the deepest point, dt = 2e-4); 1e-5
    system = _impact(_law(eta=1.0, c=0.0, mu=0.0), 0.1, dt=2e-4)
    engine.run(system, output=False)
    assert system.bodies.v[1, 2] == pytest.approx(0.1, rel=1e-5)
    assert energies(system)["dissipated"] == pytest.approx(0.0, abs=1e-12)


def test_momentum_is_conserved_between_two_free_bodies():
    # the free carrier's patch meets a free plate obliquely, both spinning: every point's
    # force is applied to both bodies at one point, so the totals keep to round-off
    carrier = _carrier(PLATE_TOP + 0.001, _law(), velocity=[0.02, -0.01, -0.1],
                       angular_velocity=[0.3, 0.2, 1.0])
    plate = _plate("free", angular_velocity=[0.0, 0.1, -0.2])
    system = engine.build(_scene([plate, carrier], 0.3, dt=2e-4))
    p0 = linear_momentum(system)
    L0 = angular_momentum(system)
    engine.run(system, output=False)
    assert system.patches.state[0, 0] > 100     # it touched for many steps
    scale_p = 10.0 * 0.1
    scale_L = float(np.linalg.norm(L0)) + scale_p * 0.5
    assert np.allclose(linear_momentum(system), p0, rtol=0, atol=1e-12 * scale_p)
    assert np.allclose(angular_momentum(system), L0, rtol=0, atol=1e-12 * scale_L)


def test_use_outside_the_fitted_range_is_reported():
    # pressed to 10 mm with a law fitted up to 5 mm: counted, reported, warned about
    law = copy.deepcopy(LAW)
    law["ranges"]["interference"] = [0.0, 0.005]
    v, gap = 0.005, 0.0
    carrier = _carrier(PLATE_TOP + gap, law, motion={
        "type": "kinematic", "profile": {"kind": "constant", "velocity": [0.0, 0.0, -v]}})
    system = engine.build(_scene([_plate(), carrier], 2.0, dt=0.01))
    result = engine.run(system, output=False)
    row = result.summary["patches"][0]
    assert row["steps_in_contact"] == 200
    # beyond 5 mm from t = 1 s: 100 of the 200 steps (the one at exactly 5 mm is not beyond)
    assert row["steps_out_of_range"]["interference"] == pytest.approx(100, abs=1)
    assert row["steps_out_of_range"]["rate"] == 0
    assert row["largest"]["interference"] == pytest.approx(0.01, rel=1e-9)
    assert any("outside its law's fitted ranges" in w and "interference" in w
               for w in result.summary["warnings"])


def test_a_bad_law_is_refused_with_its_field():
    bad = _law(eta=1.5)
    carrier = _carrier(0.1, bad)
    with pytest.raises(engine.SceneError) as err:
        _scene([_plate(), carrier], 0.1)
    assert "patches" in str(err.value)
    missing = _carrier(0.1, "no/such/law.json")
    with pytest.raises(engine.SceneError) as err:
        engine.build(_scene([_plate(), missing], 0.1))
    assert "bodies.1.patches.0.law" in str(err.value)


def test_patch_stiffness_sets_the_rigid_body_step():
    # no bristles: the automatic dt comes from the patch's stiffness at the fitted range's
    # largest interference, dF/dd = k p d^(p-1), against the carrier's mass (2 / omega)
    # (its inertia is made large so that its rotation, charged with the patch's lever,
    # does not set the step)
    carrier = _carrier(0.1, _law(mu=0.0, c=0.0),
                       mass_properties={"mass": 10.0, "inertia": [[100.0, 0, 0],
                                                                  [0, 100.0, 0],
                                                                  [0, 0, 100.0]]})
    system = engine.build(_scene([_plate(), carrier], 10.0))
    par = LAW["parameters"]
    kn = par["k"] * par["p"] * 0.03 ** (par["p"] - 1)
    dt_expected = 2.0 / math.sqrt(kn / 10.0)
    assert "patch" in system.dt_limited_by
    assert system.dt_stable == pytest.approx(dt_expected, rel=1e-9)
