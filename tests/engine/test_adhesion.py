"""Adhesive contacts (``ContactPair.adhesion_force``, ``engine.kernels.contact_law.adhesion``)
against closed forms of the law stated in docs/scene.md: a contact becomes adhered at its
first unloading step and then adds a constant attraction f_a inside the overlap, so that

* the pull-off force is f_a: a sphere pulled by a constant force F < f_a stays, at the
  overlap (f_a - F) / k_n; pulled by F > f_a it leaves;
* a sphere released at rest with an overlap d0 < f_a / k_n oscillates about f_a / k_n
  between d0 and 2 f_a / k_n - d0 (the well of k_n d^2 / 2 - f_a d), where without adhesion
  it flies off at d0 sqrt(k_n / m);
* a load-unload cycle to a peak overlap d_max loses f_a d_max: a sphere (no damping) hitting
  at v rebounds at sqrt(v (v - v_c)) and is held below v_c = 2 f_a / sqrt(k_n m);
* the books (kinetic + stored + dissipated) close, the adhesive loss included.

Nothing in the references uses the engine's kernels: they are the closed forms above.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from engine.kernels.contact_law import (HISTORY_COLUMNS, SLIP_EACH_STEP, clear_history,
                                        contact_with_history, normal_stiffness,
                                        restitution_damping_ratio)

RADIUS = 0.01
RHO = 1250.0
E = 3.5e9
KN = normal_stiffness(E, RADIUS, E, RADIUS)  # sphere on plate: E r, the engine's law
MASS = RHO * 4.0 / 3.0 * math.pi * RADIUS ** 3
PULL_OFF = 2.0  # N


def _scene(adhesion: float, z0: float, velocity=(0.0, 0.0, 0.0), force=(0.0, 0.0, 0.0),
           restitution: float = 1.0, friction_angle: float = 0.0,
           duration: float = 2e-3, channels=("bodies",)) -> engine.Scene:
    """A free PLA sphere (r 10 mm) above (z0: its centre) a fixed plate whose top is z = 0,
    no gravity."""
    return engine.parse_scene({
        "materials": {"pla": {"youngs_modulus": E, "poisson_ratio": 0.36, "density": RHO}},
        "contact_pairs": [{"materials": ["pla", "pla"], "friction_angle": friction_angle,
                           "restitution": restitution, "adhesion_force": adhesion}],
        "bodies": [
            {"name": "plate", "material": "pla",
             "shape": {"type": "box", "size": [0.1, 0.1, 0.01]},
             "pose": {"position": [0.0, 0.0, -0.005]}, "motion": {"type": "fixed"}},
            {"name": "ball", "material": "pla", "shape": {"type": "sphere", "radius": RADIUS},
             "mass_properties": {"density": RHO}, "motion": {"type": "free"},
             "pose": {"position": [0.0, 0.0, z0]}, "velocity": list(velocity),
             "external_force": list(force)}],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": duration, "record_interval": duration / 400,
                "channels": list(channels)}})


def _overlaps(scene: engine.Scene, dt_factor: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The sphere's overlap with the plate (m) per recorded frame, and its final velocity,
    at ``dt_factor`` times the automatic time step."""
    system = engine.build(scene)
    system.dt *= dt_factor
    result = engine.run(system)
    with result.open() as res:
        z = res.series("bodies/ball/position")[:, 2]
    return RADIUS - z, np.array(system.bodies.v[1])


def test_released_at_rest_it_stays_in_the_well_without_adhesion_it_leaves():
    """(a) Released at rest with the overlap d0 = f_a / (2 k_n): adhered, it oscillates
    between d0 and 2 f_a / k_n - d0 = 1.5 f_a / k_n for good (the well's closed form);
    without adhesion it leaves at d0 sqrt(k_n / m). At 1/16 of the automatic step: the
    contact turns adhered one step after the release, having moved by (omega dt)^2 / 2 of d0
    (5 % at the automatic step, 0.02 % here). Bugs caught: the pull-off force scaled twice
    (the extremes move), the attraction of the wrong sign or missing (the sphere flies off),
    an adhered state that is not kept from step to step (it would leave at once)."""
    d0 = 0.5 * PULL_OFF / KN
    ov, v = _overlaps(_scene(PULL_OFF, RADIUS - d0), 1.0 / 16.0)
    assert np.all(ov > 0.0), "the sphere must stay in contact"
    # 2 %: the overlap is sampled at 400 frames over ~25 periods of the well: the extremes
    # fall between frames (16 frames a period: up to (pi / 16)^2 / 2 = 2 % of the amplitude
    # at worst; over 25 periods some frame comes much closer)
    assert ov.max() == pytest.approx(1.5 * PULL_OFF / KN, rel=0.02)
    assert ov.min() == pytest.approx(d0, rel=0.02)
    # the well's largest speed, amplitude x omega (2 %: as the extremes)
    assert abs(v[2]) <= 1.02 * (PULL_OFF / KN - d0) * math.sqrt(KN / MASS)
    ov0, v0 = _overlaps(_scene(0.0, RADIUS - d0), 1.0 / 16.0)
    assert ov0[-1] < 0.0, "without adhesion the sphere must leave"
    # 1e-3: the release's leapfrog error, O((omega dt)^2) (1 % at the automatic step, its
    # 1/256 here)
    assert v0[2] == pytest.approx(d0 * math.sqrt(KN / MASS), rel=1e-3)


@pytest.mark.parametrize("ratio", [0.5, 0.97, 1.03])
def test_pulled_above_the_pull_off_force_it_leaves_below_it_stays(ratio):
    """(b) A constant pull F = ratio f_a away from the plate, the sphere starting at rest at
    the overlap max(f_a - F, 0.03 f_a) / k_n (its equilibrium where one exists): below f_a it
    stays and its overlap oscillates about (f_a - F) / k_n; above f_a it leaves. Bugs caught:
    a pull-off force off by more than 3 % (a factor 2 from taking the energy f_a^2 / (2 k_n)
    for a force, or from counting the attraction twice), an attraction that fades with the
    overlap (it would let go below f_a)."""
    pull = ratio * PULL_OFF
    d_eq = (PULL_OFF - pull) / KN
    d0 = max(d_eq, 0.03 * PULL_OFF / KN)
    ov, v = _overlaps(_scene(PULL_OFF, RADIUS - d0, force=(0.0, 0.0, pull)), 1.0 / 16.0)
    if ratio < 1.0:
        assert np.all(ov > 0.0), f"pulled at {ratio} x pull-off the sphere must stay"
        # 3 %: the mean of sampled extremes of a tiny oscillation (the first step's push)
        assert 0.5 * (ov.max() + ov.min()) == pytest.approx(d_eq, rel=0.03)
    else:
        assert ov[-1] < 0.0 and v[2] > 0.0, f"pulled at {ratio} x pull-off it must leave"


def _law_impact(v_in: float, fa: float, restitution: float, omega_dt: float
                ) -> tuple[float, float, bool]:
    """A point mass m hits a fixed wall at v_in (normal) + v_in/2 (tangential, mu 0.3)
    through ``contact_with_history`` with pull-off fa, kicked-drifted-kicked as the step loop
    does; returns (normal rebound speed, largest books error / E0, held)."""
    m, kn = 0.01, 1e4
    zeta = restitution_damping_ratio(restitution)
    dt = omega_dt / math.sqrt(kn / m)
    x = np.array([0.0, 1e-4])
    v = np.array([0.5 * v_in, -v_in])
    ft = np.zeros((1, HISTORY_COLUMNS))
    released = np.zeros(1)
    e0 = 0.5 * m * v @ v
    f = np.zeros(2)
    dissipated = 0.0
    worst = 0.0
    for _ in range(int(40 * math.pi * math.sqrt(m / kn) / dt)):
        v_half = v + f * dt / (2 * m)
        x = x + v_half * dt
        if x[1] >= 0.0:
            clear_history(ft, 0, SLIP_EACH_STEP, released)
            f = np.zeros(2)
            stored = 0.0
            dissipated += released[0]
        else:
            fx, fy, _, dis, stored, _ = contact_with_history(
                ft, 0, SLIP_EACH_STEP, 0.0, 1.0, 0.0, -x[1], v_half[0], v_half[1], 0.0, kn,
                0.25 * kn, 0.3, zeta, m, dt, fa)
            f = np.array([fx, fy])
            dissipated += dis
        v = v_half + f * dt / (2 * m)
        worst = max(worst, abs((0.5 * m * v @ v + stored + dissipated) / e0 - 1.0))
    return v[1], worst, bool(x[1] < 0.0)


def test_law_rebound_and_capture_speed_follow_the_adhesive_loss():
    """The law alone, frictionless and undamped: rebound at sqrt(v (v - v_c)) above
    v_c = 2 f_a / sqrt(k_n m), held below (0.9 v_c). Bugs caught: the adhesive loss booked
    or applied at the mean instead of the peak overlap (v_c off by 2), an attraction that
    acts on loading too (conservative: nothing is ever held)."""
    m, kn, fa = 0.01, 1e4, 0.5
    v_c = 2.0 * fa / math.sqrt(kn * m)
    for v_in in (1.5 * v_c, 3.0 * v_c):
        out, _, held = _law_impact(v_in, fa, 1.0, 0.02)
        assert not held
        # 1 %: O(omega dt) in where the first and last contact steps fall (omega dt 0.02;
        # measured -0.26 % and +0.10 %)
        assert out == pytest.approx(math.sqrt(v_in * (v_in - v_c)), rel=0.01)
    _, _, held = _law_impact(0.9 * v_c, fa, 1.0, 0.02)
    assert held, "below the capture speed the mass must stay on the wall"


@pytest.mark.parametrize("v_ratio", [0.7, 2.0], ids=["held", "rebounds"])
def test_law_books_close_through_a_damped_frictional_adhesive_impact(v_ratio):
    """(c, the law) The books of a damped (e = 0.6), frictional (mu 0.3), adhesive impact, held
    or rebounding, close within 0.5 % (the issue's bound; measured 0.16 % and 0.15 % at
    omega dt 0.1) and at second order: at a quarter of the step at least 8x smaller (16x
    for second order, 4x for first; measured 27x and 17x). Bugs caught: the adhesive loss
    booked as f_a d at the switch step's end overlap (first order: f_a v dt / 2 per impact),
    the let-go trapezoid forgotten, the well -f_a d left out of the stored energy (an error
    of f_a^2 / k_n)."""
    fa = 0.5
    v_c = 2.0 * fa / math.sqrt(1e4 * 0.01)
    _, coarse, held = _law_impact(v_ratio * v_c, fa, 0.6, 0.1)
    _, fine, _ = _law_impact(v_ratio * v_c, fa, 0.6, 0.025)
    assert held == (v_ratio < 1.0)
    assert coarse < 0.005, f"books off by {coarse:.3%}"
    assert fine < coarse / 8.0, (coarse, fine)


def _engine_books(dt_factor: float) -> tuple[float, float]:
    """A sphere hits the plate at twice the capture speed (oblique: 0.3 of it sideways),
    damped (e 0.8), frictional (mu 0.3), adhesive, and leaves: (largest |kinetic + stored +
    dissipated - E0| / E0 over the run, dissipated / E0 at the end)."""
    v_c = 2.0 * PULL_OFF / math.sqrt(KN * MASS)
    gap = 1e-6
    v_in = 2.0 * v_c
    duration = gap / v_in + 4 * math.pi * math.sqrt(MASS / KN)
    system = engine.build(_scene(PULL_OFF, RADIUS + gap, velocity=(0.3 * v_in, 0.0, -v_in),
                                 restitution=0.8, friction_angle=0.3, duration=duration,
                                 channels=("energy", "bodies")))
    system.dt *= dt_factor
    result = engine.run(system)
    with result.open() as res:
        total = res.series("energy/total")
        books = total + res.series("energy/dissipated") - res.series("energy/external_work")
        diss = res.series("energy/dissipated")[-1]
    assert system.bodies.v[1][2] > 0.0, "the sphere must leave"
    return float(np.abs(books / total[0] - 1.0).max()), float(diss / total[0])


def test_engine_adhesive_impact_books_close_and_capture_speed():
    """(c) A sphere on the plate through the engine (sphere-mesh contact), damped, frictional
    and adhesive: the energy channel's books close within 0.5 % of the initial energy at
    half the automatic step and converge at second order (measured max |error| / E0: 0.47 %,
    0.091 %, 0.021 % at dt, dt/2, dt/4; 0.16 % at dt once the sphere has left: the largest
    error is the leapfrog's transient dt^2 |F|^2 / (8 m) at the deepest point); undamped and
    frictionless it is held at 0.9 v_c and rebounds at sqrt(v (v - v_c)) at 2 v_c (closed
    form; measured 1.4 % fast at the automatic step). Bugs caught: the attraction missing in
    one contact type (body-body), its loss not booked (the books off by the adhesive loss,
    f_a times the peak overlap), a first-order booking of the switch (the ratio below)."""
    err, diss = _engine_books(0.5)
    err_fine, _ = _engine_books(0.25)
    assert diss > 0.1, "damping, friction and adhesion must dissipate"
    # 0.5 %: the bound (5x the measured 0.091 %)
    assert err < 0.005, f"books off by {err:.3%}"
    # second order: 1/4 per halving (measured 0.23); first order would give 1/2
    assert err_fine < 0.35 * err, (err, err_fine)
    fa = PULL_OFF
    v_c = 2.0 * fa / math.sqrt(KN * MASS)
    gap = 1e-6
    for ratio, held in ((0.9, True), (2.0, False)):
        v_in = ratio * v_c
        duration = gap / v_in + 20 * math.pi * math.sqrt(MASS / KN)
        ov, v = _overlaps(_scene(fa, RADIUS + gap, velocity=(0.0, 0.0, -v_in),
                                 duration=duration))
        if held:
            assert ov[-1] > 0.0 and abs(v[2]) < v_in, "below v_c the sphere must be held"
        else:
            assert ov[-1] < 0.0
            # 2 %: the automatic dt resolves the ~40 us contact with ~10 steps (measured 1.4 %)
            assert v[2] == pytest.approx(math.sqrt(v_in * (v_in - v_c)), rel=0.02)


def test_no_adhesion_is_the_plain_law_bit_for_bit():
    """(d) adhesion_force 0 runs the law of before: the same run with the field omitted and
    set to 0 gives bit-identical trajectories, and the elastic rebound is the closed form's
    restitution 1 (to the leapfrog's O(dt^2)). Bug caught: the adhesive branch entered (or
    its state column written) with f_a = 0, a history allocated that changes the path."""
    v_in = 0.2
    gap = 1e-6
    duration = gap / v_in + 4 * math.pi * math.sqrt(MASS / KN)
    base = _scene(0.0, RADIUS + gap, velocity=(0.05, 0.0, -v_in), friction_angle=0.3,
                  duration=duration)
    data = base.model_dump()
    for pair in data["contact_pairs"]:
        pair.pop("adhesion_force")
    omitted = engine.parse_scene(data)
    assert omitted.contact_pairs[0].adhesion_force == 0.0
    runs = []
    for scene in (base, omitted):
        system = engine.build(scene)
        assert system.dt > 0.0
        engine.run(system)
        runs.append((np.array(system.bodies.pos[1]), np.array(system.bodies.v[1]),
                     np.array(system.bodies.w[1])))
    for a, b in zip(*runs):
        assert np.array_equal(a, b)
    # restitution 1 (no damping): the normal speed comes back; 1e-3 is the leapfrog's
    # O(dt^2) over the contact's ~10 steps (a 0.1 % energy error, as measured in
    # test_verification_impact at this dt)
    assert runs[0][1][2] == pytest.approx(v_in, rel=1e-3)
