"""The energy books close with friction and damping: the contact law's own books through one
damped frictional impact integrated by the engine's leapfrog, and a free PLA sphere into a
frictional 5 x 5 silicone brush mounted on a free PLA plate (issue 22's scene). Reference: the
conservation law itself, ``total + dissipated - external_work`` = the initial energy (no
external work here: no gravity, no loads, no driven body), up to the leapfrog's O(dt^2) error.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import engine
from engine.kernels.contact_law import (HISTORY_COLUMNS, SLIP_EACH_STEP, clear_history,
                                        contact_with_history, restitution_damping_ratio)

SILICONE = {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1700.0}
PLA = {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1250.0}
FIGURES: dict[str, float] = {}
DURATION = 0.03  # s: the sphere hits at 1 ms, bounces off by about 10 ms; the brush rings on


def _scene(restitution: float) -> engine.Scene:
    return engine.parse_scene({
        "materials": {"silicone": SILICONE, "pla": PLA},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": 0.768,
             "restitution": restitution},
            {"materials": ["silicone", "pla"], "friction_angle": 0.419,
             "restitution": restitution}],
        "brushes": [{"name": "b", "material": "silicone", "rows": 5, "columns": 5,
                     "pitch": [0.0025, 0.0025], "bristle_length": 0.02, "root_radius": 0.001,
                     "tip_radius": 0.0005, "n_nodes": 8, "mount": "plate",
                     "base": {"position": [0.0, 0.0, 0.001]}}],
        "bodies": [
            {"name": "plate", "material": "pla",
             "shape": {"type": "box", "size": [0.02, 0.02, 0.002]},
             "mass_properties": {"density": 1250.0}, "motion": {"type": "free"}},
            {"name": "ball", "material": "pla", "shape": {"type": "sphere", "radius": 0.006},
             "mass_properties": {"density": 1250.0},
             "pose": {"position": [0.0017, 0.0009, 0.0285]}, "motion": {"type": "free"},
             "velocity": [0.1, 0.0, -0.5]}],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": DURATION, "record_interval": 0.0005,
                "channels": ["energy", "contacts"]}})


@functools.lru_cache(maxsize=None)
def balance(restitution: float, dt_factor: float) -> tuple[float, float, int, int]:
    """(largest |total + dissipated - external work - E0| / E0 over the run, dissipated / E0
    at the end, most bristle-bristle and bristle-body contacts at once)."""
    system = engine.build(_scene(restitution))
    system.dt *= dt_factor
    result = engine.run(system)
    with result.open() as res:
        total = res.series("energy/total")
        books = total + res.series("energy/dissipated") - res.series("energy/external_work")
        diss = res.series("energy/dissipated")[-1]
        n_bb = int(res.series("contacts/bristle_bristle").max())
        n_body = int(res.series("contacts/bristle_body").max())
    return (float(np.abs(books / total[0] - 1.0).max()), float(diss / total[0]), n_bb,
            n_body)


# (bound at the automatic dt, the finer dt's fraction, bound on err(fine) / err(dt)) per
# restitution, from ``python benchmarks/contact_law_figures.py --books`` (max |error| / E0 at
# dt, dt/2, dt/4, dt/8):
# * elastic contacts with friction: 0.2 % is the bound (measured 0.0049 %, 0.0009 %,
#   0.0006 %, 0.0005 %: the leapfrog's O(dt^2) down to a floor of the sampled frames); 0.5
#   at dt/4 with room;
# * damped contacts (e = 0.5) with friction: before, the dashpot's work was booked with the
#   force at the step's end and the half-step velocity, a first-order error (0.259 %,
#   0.135 %, 0.062 %: it halves with dt, so about 0.125 of it at dt/8); booked as the
#   trapezoid of the step's first and last force (``contact_law.contact_force``), 0.0078 %,
#   0.0033 %, 0.0013 %, 0.0005 % (ratio 0.058 at dt/8). 0.05 %: 6x the measured figure,
#   and the old booking fails it by 5x (the 0.2 % would nearly pass 0.259 %). The
#   ratio is taken at dt/8: the contacts differ from one dt to the next in this chaotic
#   scene, so one halving is no clean factor (0.17 at dt/4 here, where 0.093 was once
#   measured and held to 0.15, a bound this machine's run never met); 0.085 is the
#   geometric mean of the measured 0.058 and first order's 0.125, 1.5x from either.
BOUNDS = {1.0: (0.002, 0.25, 0.5), 0.5: (0.0005, 0.125, 0.085)}


@pytest.mark.slow
@pytest.mark.parametrize("restitution", [1.0, 0.5], ids=["elastic", "damped"])
def test_frictional_multi_contact_impact_books_close(restitution):
    """The books at the automatic dt within the bound above, and converging (at dt/4 for
    elastic contacts, dt/8 for damped ones). Bugs
    caught (the issue measured -2.98 % on such a scene): the tangential spring's energy of
    the crossing contacts left out of the stored energy, a spring forgotten when a contact
    hands over to the next segment without booking what it held, slip work taken at the
    capped force alone instead of the force's mean over the step (measured before that fix
    with ``benchmarks/contact_law_figures.py --books``: elastic 0.40 % at dt, 0.15 % at dt/4;
    damped 0.088 % at dt, 0.028 % at dt/2 and dt/4, an error that no longer shrinks with
    dt), and the dashpot's work booked with the step's end force alone (first order: the
    damped bounds above)."""
    bound, fine, shrink = BOUNDS[restitution]
    err, diss, n_bb, n_body = balance(restitution, 1.0)
    err_fine, _, _, _ = balance(restitution, fine)
    FIGURES[f"books, e={restitution}: max |error| / E0 at dt"] = err
    FIGURES[f"books, e={restitution}: max |error| / E0 at dt/{round(1 / fine)}"] = err_fine
    assert n_bb > 0 and n_body > 0, "bristles must touch each other and the sphere"
    assert diss > 0.01, "friction must dissipate a real share of the energy"
    assert err < bound, f"books off by {err:.3%} of the initial energy"
    # converging with dt (no absolute slack: 1e-5 of E0 is more than the damped err_fine
    # itself, 4.5e-6, and would let a first-order error pass)
    assert err_fine < shrink * err, (err, err_fine)


def _law_books(omega_dt: float) -> float:
    """A 10 g mass hits a fixed wall at 45 deg (0.3 m/s each way) through the law of
    ``contact_with_history`` (k_n 1e4 N/m, k_t = k_n / 4, mu 0.3, restitution 0.5), the
    history kept and let go as the kernels do (``clear_history``), integrated by the step
    loop's kick-drift-kick with the contact seeing the half-step velocity; returns the
    largest |kinetic + stored + dissipated - E0| / E0 until well after it has let go."""
    m, kn = 0.01, 1e4
    zeta = restitution_damping_ratio(0.5)
    dt = omega_dt / math.sqrt(kn / m)
    x = np.array([0.0, 0.001])
    v = np.array([0.3, -0.3])
    ft = np.zeros((1, HISTORY_COLUMNS))
    released = np.zeros(1)
    e0 = 0.5 * m * v @ v
    f = np.zeros(2)
    dissipated = 0.0
    worst = 0.0
    for _ in range(int(0.02 / dt)):
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
                0.25 * kn, 0.3, zeta, m, dt, 0.0)
            f = np.array([fx, fy])
            dissipated += dis
        v = v_half + f * dt / (2 * m)
        worst = max(worst, abs((0.5 * m * v @ v + stored + dissipated) / e0 - 1.0))
    assert v[1] > 0.1, "the mass must have bounced off"
    return worst


def test_law_books_close_at_second_order_through_a_damped_frictional_impact():
    """The dashpot's and the slip's work as the law books them, against what the leapfrog's
    kicks do: equal up to O(dt^2). Bug caught: the dashpot booked as ``-f_d v_n dt`` (the
    step's end force times the half-step velocity) with nothing booked on letting go,
    measured by booking these same runs that way: 4.8 %, 2.5 %, 1.3 % at omega dt = 0.2,
    0.1, 0.05 (first order); the trapezoid
    measures 0.44 %, 0.11 %, 0.028 % (x 1/4 per halving: the kicks' telescoping
    dt^2 |F|^2 / (8 m), largest at the deepest point). Bounds: 1 % (2.3x the measured, 5x
    below the bug), and a ratio below 0.1 over two halvings (second order 1/16, first 1/4)."""
    coarse = _law_books(0.2)
    fine = _law_books(0.05)
    assert coarse < 0.01, f"books off by {coarse:.3%}"
    assert fine < 0.1 * coarse, (coarse, fine)
