"""The automatic timestep: a Gershgorin bound on the highest angular frequency of the
linearised system, ``dt = 2 / omega_max`` (2 / omega is leapfrog's stability limit);
:func:`choose_dt` multiplies it by ``run.dt_safety`` and applies the other limits.

For every node the bound adds, over its bonds, the absolute entries of its rows of the
mass-normalised Euler-Bernoulli element stiffness matrix (axial ``EA/L``, shear ``12EI/L^3``,
coupling ``6EI/L^2``, rotation ``4EI/L``/``2EI/L``, twist ``GJ/L``; a tapered bond's exact
frustum matrix, see :func:`node_bond_bounds`), plus the contacts the node
can actually have (``build`` works them out from where the node can reach):

* bristle-bristle: one contact per other bristle that can reach the node's segments, at most
  ``BRISTLE_CONTACTS_PER_NODE`` (``k_n = 2 E1 r1 E2 r2/(E1 r1 + E2 r2)``, seed eq. 3.6, taken
  as ``E r`` of the node: the partner is assumed no softer, smaller nor lighter, as before);
  a two-sided row (the node's own entry and its partner's);
* bristle-body: one contact per body that can reach it (seed eq. 3.6 with both lengths equal
  to the node's radius, ``2 E_b E_k r / (E_b + E_k)``); one-sided against fixed and
  kinematic bodies, two-sided against bodies that move under forces.

Every contact force acts at a point on the normal through the axis point it is attached to
(``contacts.add_segment_force``), so the normal force has no moment about the node: only the
tangential spring ``k_t = tangential_ratio k_n`` (zero without friction) acts on the node's
rotation, with a lever of at most the radius ``r``. Per contact that adds ``k_t r^2/I`` to the
rotation row and ``k_t r / sqrt(m I)`` coupling terms to both rows.

Bodies add their contacts with up to ``BODY_CONTACTS`` bristle segments, and sphere bodies
their body-body contact. Gershgorin's bound is an upper bound of the true highest frequency
of the linearised system, so the rule is conservative. The element that gives the largest
bound is reported as ``dt_limited_by``. :func:`choose_dt` then also caps dt so that no
colliding body's surface moves more than half the step loop's tunnelling limit (a quarter of
the smallest bristle radius) per step.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

# at most this many other bristles touch one node at once: the four neighbours of a square
# brush (six parallel bristles of equal radius fit around one, but not with overlaps kept
# below the instability limit in a pressed square brush: an assumption checked by
# benchmarks/dt_margins.py, not a packing theorem)
BRISTLE_CONTACTS_PER_NODE = 4
BODY_CONTACTS = 100
# Cundall local damping (``environment.local_damping`` alpha) turns a node's force F into
# F - alpha |F| sign(v): while a node moves away from equilibrium its restoring force is
# raised up to (1 + alpha) times, a stiffness (1 + alpha) k, so leapfrog's limit 2 / omega
# becomes 2 / (omega sqrt(1 + alpha)). The automatic dt stays below this fraction of that
# damped limit whatever run.dt_safety asks (issue 22: one bristle pressed by a wedge face
# never settled at dt_safety 0.95 with alpha 0.5, the tip chattering on its contact; it
# settled at 0.90, and at 0.95 without local damping).
LOCAL_DAMPING_MARGIN = 0.95


def node_bond_bounds(mass, inertia, bi, bj, kn, ks, kb, ksb, kt, L0):
    """Per-node Gershgorin bounds of omega^2 from the bonds (translation and rotation rows).

    In each bending plane the element matrix of the energy ``1/2 ks d^2 + ksb d phi +
    1/2 kb phi^2`` (``d = v_j - v_i - L/2 (theta_i + theta_j)``, ``phi = theta_j - theta_i``)
    has the shear-rotation coupling ``ks L/2 + ksb`` at node i's rotation and
    ``ks L/2 - ksb`` at node j's, the rotation diagonals ``ks L^2/4 + kb +- ksb L`` and the
    off-diagonal ``ks L^2/4 - kb`` (uniform, ksb = 0: 6EI/L^2, 4EI/L, 2EI/L)."""
    n = mass.shape[0]
    trans = np.zeros(n)
    rot = np.zeros(n)
    for a, b, sign in ((bi, bj, 1.0), (bj, bi, -1.0)):
        ma, mb = mass[a], mass[b]
        Ia, Ib = inertia[a], inertia[b]
        c_own = np.abs(0.5 * ks * L0 + sign * ksb)    # shear of either node <-> a's rotation
        c_other = np.abs(0.5 * ks * L0 - sign * ksb)  # ... <-> b's rotation
        row_axial = kn / ma + kn / np.sqrt(ma * mb)
        row_shear = (ks / ma + ks / np.sqrt(ma * mb) + c_own / np.sqrt(ma * Ia)
                     + c_other / np.sqrt(ma * Ib))
        r_diag = 0.25 * ks * L0 ** 2 + kb + sign * ksb * L0
        r_off = np.abs(0.25 * ks * L0 ** 2 - kb)
        row_bend = (r_diag / Ia + r_off / np.sqrt(Ia * Ib) + c_own / np.sqrt(Ia * ma)
                    + c_own / np.sqrt(Ia * mb))
        row_twist = kt / Ia + kt / np.sqrt(Ia * Ib)
        np.add.at(trans, a, np.maximum(row_axial, row_shear))
        np.add.at(rot, a, np.maximum(row_bend, row_twist))
    return trans, rot


def node_bounds(system_info: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per node, the Gershgorin bounds of omega^2 of its translation and its rotation (zero
    for nodes that do not move), and the normal contact stiffness charged to it (N/m)."""
    mass = system_info["node_mass"]
    inertia = system_info["node_inertia"]
    rad = system_info["node_radius"]
    E = system_info["node_E"]
    trans, rot = node_bond_bounds(mass, inertia, *system_info["bond_arrays"])
    # two-sided rows: the node's own entry and its partner's (k_n = E r, seed eq. 3.6)
    k_bb = 2.0 * system_info["node_bristle_contacts"] * E * rad
    k_body = system_info["node_k_body"]
    kt = system_info["kt_ratio_bristle"] * k_bb + system_info["kt_ratio_body"] * k_body
    lever = kt * rad / np.sqrt(mass * inertia)  # tangential spring at lever r
    w2_t = trans + (k_bb + k_body) / mass + lever
    w2_r = rot + kt * rad ** 2 / inertia + lever
    free = system_info["node_free"]
    return np.where(free, w2_t, 0.0), np.where(free, w2_r, 0.0), k_bb + k_body


def equalizing_scales(system_info: dict) -> tuple[np.ndarray, np.ndarray]:
    """Factors (>= 1) on each node's mass and rotational inertia that bring every bound of
    :func:`node_bounds` down to the median translational bound of the moving nodes: the
    light, stiffly contacted tip nodes then no longer set dt alone (a Jacobi-like
    preconditioning of dynamic relaxation). For quasi-static runs only."""
    w2_t, w2_r, _ = node_bounds(system_info)
    free = system_info["node_free"]
    if not free.any():
        return np.ones_like(w2_t), np.ones_like(w2_r)
    target = float(np.median(w2_t[free]))
    return (np.where(free, np.maximum(1.0, w2_t / target), 1.0),
            np.where(free, np.maximum(1.0, w2_r / target), 1.0))


def automatic_dt(system_info: dict) -> tuple[float, str, float]:
    """Return (dt, limited_by, omega_max) from the dict ``build`` prepares. Per node it needs
    ``node_bristle_contacts`` (how many other bristles can touch it, already capped),
    ``node_k_body`` (the summed one-sided normal stiffness of the bodies that can touch it,
    N/m, two-sided ones counted twice) and the tangential ratios ``kt_ratio_bristle`` and
    ``kt_ratio_body`` (0 without friction)."""
    candidates: list[tuple[float, str]] = []
    mass = system_info["node_mass"]
    if mass.size:
        w2_t, w2_r, k_contact = node_bounds(system_info)
        it = int(np.argmax(w2_t))
        ir = int(np.argmax(w2_r))
        label = system_info["node_label"]

        def parts(n):
            return "bonds" + (" + contacts" if k_contact[n] > 0 else "")
        candidates.append((float(w2_t[it]), f"translation of {label(it)} ({parts(it)})"))
        candidates.append((float(w2_r[ir]), f"rotation of {label(ir)} ({parts(ir)})"))
    for name, m, imin, k_body, bound_r in system_info["bodies"]:
        if m > 0:
            candidates.append((k_body / m, f"contacts of body {name!r} (translation)"))
            if imin > 0:
                candidates.append((k_body * bound_r ** 2 / imin,
                                   f"contacts of body {name!r} (rotation)"))
    candidates = [c for c in candidates if c[0] > 0 and math.isfinite(c[0])]
    if not candidates:
        return math.inf, "nothing moves elastically", 0.0
    w2, label = max(candidates)
    omega = math.sqrt(w2)
    return 2.0 / omega, label, omega


MAX_BODY_STEP_RATIO = 0.25   # body surface displacement per step / smallest bristle radius


def controller_cap(controllers) -> Optional[tuple[float, str]]:
    """The automatic timestep's cap from the scene's controllers: the shortest sample interval
    and what to call it, or None without controllers. A controller holds its command between
    samples (zero-order hold): a step longer than a sample would skip samples, and the loop's
    derivative gain acts as a damper that no stability limit here sees (a reduced-law
    detumble with a soft, lightly damped law took 1 s steps against a 10 Hz loop and went
    unstable). The build (:func:`choose_dt`) and the estimate both apply it."""
    if not controllers:
        return None
    ctl = min(controllers, key=lambda c: c.sample_interval)
    return (float(ctl.sample_interval),
            f"sample interval of controller {ctl.name!r} (zero-order hold)")


def choose_dt(system_info: dict, run, r_min: float, body_speed=None,
              warnings: list = None, local_damping: float = 0.0,
              controllers=()) -> tuple[float, float, str]:
    """The run's timestep: ``(dt, dt_stable, limited_by)``.

    ``dt_stable`` is :func:`automatic_dt`'s stability limit. Without ``run.dt`` the step is
    ``run.dt_safety`` of it (``record_interval`` when nothing moves elastically), and
    ``limited_by`` names the element that sets it; a ``run.dt`` given in the scene is kept,
    with a warning when it exceeds the limit. ``body_speed`` ``(speed, body name)``, given
    when bodies can touch bristles or each other, is the fastest colliding body's surface
    speed: the automatic dt keeps its surface within half of ``MAX_BODY_STEP_RATIO`` x the
    smallest bristle radius ``r_min`` per step (the step loop's tunnelling check stops at the
    whole of it), and a given dt that breaks the check is warned about. dt is at most the
    record interval and the duration. With Cundall ``local_damping`` alpha > 0 the automatic
    dt is at most ``LOCAL_DAMPING_MARGIN / sqrt(1 + alpha)`` of ``dt_stable`` (the damped
    limit, see :data:`LOCAL_DAMPING_MARGIN`): 0.78 at alpha 0.5, 0.83 at 0.3, so only a
    ``dt_safety`` above that is lowered. The automatic dt is at most the shortest sample
    interval of ``controllers`` (:func:`controller_cap`)."""
    warnings = [] if warnings is None else warnings
    dt_stable, limited_by, _ = automatic_dt(system_info)
    if run.dt is None:
        dt = run.dt_safety * dt_stable
        cap = LOCAL_DAMPING_MARGIN / math.sqrt(1.0 + local_damping)
        if local_damping > 0 and run.dt_safety > cap and math.isfinite(dt):
            dt = cap * dt_stable
            limited_by += (f"; dt_safety {run.dt_safety:g} lowered to {cap:.3g}: local "
                           f"damping {local_damping:g} raises restoring forces up to "
                           f"{1 + local_damping:g} x")
        if not math.isfinite(dt):
            dt = run.record_interval
            limited_by = "nothing moves elastically: dt = record_interval"
        cap = controller_cap(controllers)
        if cap is not None and cap[0] < dt:
            dt, limited_by = cap
    else:
        dt = run.dt
        if dt > dt_stable:
            warnings.append(f"run.dt = {dt:.3g} s exceeds the estimated stability limit "
                            f"{dt_stable:.3g} s (set by {limited_by}); the run may "
                            f"become unstable")
        limited_by = "given in the scene (run.dt)"
    # tunnelling: a body's surface must not move more than a fraction of the smallest
    # bristle radius per step (the step loop's check); the automatic dt keeps half of that
    if body_speed is not None:
        speed, fastest = body_speed
        step_max = MAX_BODY_STEP_RATIO * r_min
        if speed > 0:
            dt_speed = 0.5 * step_max / speed
            if run.dt is None and dt_speed < dt:
                dt = dt_speed
                limited_by = (f"speed of body {fastest!r} (up to {speed:.3g} m/s; "
                              f"half of {MAX_BODY_STEP_RATIO:g} x the smallest bristle radius "
                              f"per step, against tunnelling)")
            elif run.dt is not None and run.dt > 2 * dt_speed:
                warnings.append(f"run.dt = {run.dt:.3g} s lets body "
                                f"{fastest!r} ({speed:.3g} m/s) move more than "
                                f"{MAX_BODY_STEP_RATIO:g} x the smallest bristle radius per "
                                f"step: the run will stop on the tunnelling check")
    dt = min(dt, run.record_interval, run.duration)
    return float(dt), float(dt_stable), limited_by
