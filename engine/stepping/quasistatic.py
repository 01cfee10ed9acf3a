"""Quasi-static protocols: reach a static equilibrium by dynamic relaxation and say when it is
reached, from the live state, without recording frames.

A study that records equilibria (the wedge test and its sweeps) moves a body a little, then
:func:`settle`\\ s: it advances the system in short chunks and stops when both

- the **out-of-balance force** ``sum |f_i|`` over the free nodes (every component of the
  undamped resultant force on each node) is below ``force_tolerance``. By global equilibrium
  the root reaction differs from the load on the bristles (body contacts, gravity, loads) by
  at most this sum, so it bounds the error of a recorded root force; and
- the **kinetic energy** is below ``kinetic_tolerance``: a bristle passing through its
  equilibrium position at speed has no out-of-balance force for a moment, but it has kinetic
  energy. Oscillating in a mode of stiffness ``k`` with kinetic energy ``K``, it carries a
  force amplitude ``sqrt(2 k K)``; :func:`kinetic_tolerance_for` turns a force tolerance into
  an energy with the softest bristle's cantilever stiffness.

Neither inertia nor the way the equilibrium is approached changes a static equilibrium (within
the friction path), so a quasi-static run may use strong Cundall local damping and scaled
inertia (``environment.local_damping``, ``environment.inertia_scaling``);
the wedge study shows that its recorded forces match the plain dynamic protocol.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from engine.analysis.beam_theory import circle_second_moment, rod_frequency
from engine.state import SLIP_EACH_STEP, SLIP_FROZEN
from engine.stepping.loop import run_steps


@dataclass
class Balance:
    out_of_balance: float   # N, sum over free nodes of |f| (all components), undamped bound
    kinetic: float          # J, nodes (translation and rotation)


@dataclass
class Settled:
    converged: bool
    steps: int
    balance: Balance


def balance(system) -> Balance:
    """The out-of-balance force and the nodes' kinetic energy of the current state.

    The forces the step loop leaves in ``nodes.f`` are those of the last step after Cundall
    damping, which changes each component by at most ``alpha |f|``; dividing by ``1 - alpha``
    makes the sum an upper bound of the undamped one."""
    nd = system.nodes
    free = nd.inv_mass > 0
    alpha = system.scene.environment.local_damping
    oob = float(np.abs(nd.f[free]).sum()) / (1.0 - alpha)
    # the masses the integrator uses (inertia scaling may raise them above the weight's)
    kin = 0.5 * float(np.sum(np.einsum("ij,ij->i", nd.v[free], nd.v[free]) / nd.inv_mass[free]))
    kin += 0.5 * float(np.sum(nd.inertia[free] * np.einsum("ij,ij->i", nd.w[free],
                                                           nd.w[free])))
    return Balance(oob, kin)


def softest_bristle_stiffness(scene) -> float:
    """The smallest tip stiffness of a cantilevered bristle in the scene, ``3 E I / L^3``
    with ``I`` of the tip radius (a lower bound for a conical bristle), N/m; inf if none."""
    k = math.inf
    for br in scene.brushes:
        E = scene.materials[br.material].youngs_modulus
        k = min(k, 3.0 * E * circle_second_moment(br.tip_radius) / br.bristle_length ** 3)
    return k


def kinetic_tolerance_for(scene, force_tolerance: float) -> float:
    """Kinetic energy below which no bristle can oscillate with a force amplitude above
    ``force_tolerance``: ``K = F^2 / (2 k)`` with the softest bristle's stiffness."""
    k = softest_bristle_stiffness(scene)
    return force_tolerance ** 2 / (2.0 * k) if math.isfinite(k) else math.inf


def lowest_bristle_period(scene) -> float:
    """Period of the first cantilever mode of the slowest bristle, s (Euler-Bernoulli with
    the mean radius, :func:`engine.analysis.beam_theory.rod_frequency`); used to space the checks."""
    period = 0.0
    for br in scene.brushes:
        mat = scene.materials[br.material]
        r = 0.5 * (br.root_radius + br.tip_radius)
        f = rod_frequency(1, br.bristle_length, mat.youngs_modulus, r, mat.density)
        period = max(period, 1.0 / f)
    return period


def settle(system, *, force_tolerance: float | Callable[[object], float],
           kinetic_tolerance: float | Callable[[float], float], max_steps: int,
           check_every: int, on_check: Optional[Callable[[object, Balance], None]] = None,
           cancel=None, kinetic_damping: bool = False) -> Settled:
    """Advance ``system`` in chunks of ``check_every`` steps until the out-of-balance force
    and the kinetic energy are both below their tolerances (see the module docstring), or
    ``max_steps`` have been done. A tolerance may be a callable: ``force_tolerance(system)``
    (for a tolerance relative to the force being measured), ``kinetic_tolerance(f_tol)``.
    ``on_check(system, balance)`` runs after every chunk (to record a series). A blow-up
    raises :class:`engine.InstabilityError`; a set ``cancel`` event raises
    :class:`KeyboardInterrupt`."""
    if check_every < 1 or max_steps < 0:
        raise ValueError("check_every must be >= 1 and max_steps >= 0")
    steps = 0
    bal = balance(system)
    last_kinetic = bal.kinetic
    rising = False
    while steps < max_steps:
        if cancel is not None and cancel.is_set():
            raise KeyboardInterrupt("cancelled")
        n = min(check_every, max_steps - steps)
        run_steps(system, n)
        steps += n
        bal = balance(system)
        if kinetic_damping and rising and bal.kinetic < last_kinetic:
            # the kinetic energy rose, then fell: it peaked since the last check, where the
            # dominant mode passed its equilibrium; stopping every node there leaves the
            # least energy behind (kinetic damping)
            _stop_nodes(system)
            bal = Balance(bal.out_of_balance, 0.0)
        rising = bal.kinetic > last_kinetic
        last_kinetic = bal.kinetic
        if on_check is not None:
            on_check(system, bal)
        f_tol = force_tolerance(system) if callable(force_tolerance) else force_tolerance
        k_tol = kinetic_tolerance(f_tol) if callable(kinetic_tolerance) else kinetic_tolerance
        if bal.out_of_balance <= f_tol and bal.kinetic <= k_tol:
            return Settled(True, steps, bal)
    return Settled(False, steps, bal)


def freeze_slip(system, frozen: bool = True) -> None:
    """Within a quasi-static increment, keep the bristle contacts' tangential springs as
    uncapped trials (``engine.state.Friction.SLIP_FROZEN``): the friction force then depends on the net
    tangential displacement since the last :func:`commit_slip`, not on how the relaxation
    moved back and forth, so the equilibrium reached does not depend on the loading rate,
    the damping or the inertia, only on the size of the increment (a return mapping per
    increment, as implicit quasi-static solvers do). ``frozen=False`` restores the dynamics'
    slip at every step. Body-body contacts are not affected."""
    fl = system.flags
    mode = SLIP_FROZEN if frozen else SLIP_EACH_STEP
    system.flags = fl._replace(
        friction_bristle=mode if fl.friction_bristle else fl.friction_bristle,
        friction_body=mode if fl.friction_body else fl.friction_body)


def commit_slip(system) -> None:
    """End an increment: one step with the dynamics' slip caps every kept tangential spring
    at Coulomb's cone (the slip of the increment becomes history), then the springs are
    frozen again."""
    freeze_slip(system, False)
    try:
        run_steps(system, 1)
    finally:
        freeze_slip(system, True)


def _stop_nodes(system) -> None:
    nd = system.nodes
    free = nd.inv_mass > 0
    nd.v[free] = 0.0
    nd.w[free] = 0.0
