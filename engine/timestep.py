"""The automatic timestep: a Gershgorin bound on the highest angular frequency of the
linearised system, ``dt = safety * 2 / omega_max`` (2 / omega is leapfrog's stability limit).

For every node the bound adds, over its bonds, the absolute entries of its rows of the
mass-normalised Euler-Bernoulli element stiffness matrix (axial ``EA/L``, shear ``12EI/L^3``,
coupling ``6EI/L^2``, rotation ``4EI/L``/``2EI/L``, twist ``GJ/L``), plus contacts: four
bristle-bristle contacts (``k_n = 2 E1 r1 E2 r2/(E1 r1 + E2 r2)``, seed eq. 3.6) and one body
contact (seed eq. 3.6 with both lengths equal to the node's radius, ``2 E_b E_k r / (E_b +
E_k)``, against the stiffest body that can touch it). Bodies add their contacts
with up to ``BODY_CONTACTS`` bristle segments, and sphere bodies their body-body contact.
Gershgorin's bound is an upper bound of the true highest frequency, so the rule is
conservative; the safety factor (default 0.5) leaves room for the contacts the estimate does
not foresee. The element that gives the largest bound is reported as ``dt_limited_by``.
``build`` then also caps dt so that no colliding body's surface moves more than half the step
loop's tunnelling limit (a quarter of the smallest bristle radius) per step.
"""
from __future__ import annotations

import math

import numpy as np

BRISTLE_CONTACTS_PER_NODE = 4  # a node in a square brush can touch four neighbours
BODY_CONTACTS_PER_NODE = 1
BODY_CONTACTS = 100


def node_bond_bounds(mass, inertia, bi, bj, kn, ks, kb, kt, L0):
    """Per-node Gershgorin bounds of omega^2 from the bonds (translation and rotation rows)."""
    n = mass.shape[0]
    trans = np.zeros(n)
    rot = np.zeros(n)
    for a, b in ((bi, bj), (bj, bi)):
        ma, mb = mass[a], mass[b]
        Ia, Ib = inertia[a], inertia[b]
        c = 0.5 * ks * L0  # 6EI/L^2 = ks L / 2
        row_axial = kn / ma + kn / np.sqrt(ma * mb)
        row_shear = ks / ma + ks / np.sqrt(ma * mb) + c / np.sqrt(ma * Ia) + c / np.sqrt(ma * Ib)
        # 4EI/L = ks L^2/4 + kb ; 2EI/L = ks L^2/4 - kb (the midpoint formulation)
        r_diag = 0.25 * ks * L0 ** 2 + kb
        r_off = abs(0.25 * ks * L0 ** 2 - kb)
        row_bend = (r_diag / Ia + r_off / np.sqrt(Ia * Ib) + c / np.sqrt(Ia * ma)
                    + c / np.sqrt(Ia * mb))
        row_twist = kt / Ia + kt / np.sqrt(Ia * Ib)
        np.add.at(trans, a, np.maximum(row_axial, row_shear))
        np.add.at(rot, a, np.maximum(row_bend, row_twist))
    return trans, rot


def automatic_dt(system_info: dict, safety: float) -> tuple[float, str, float]:
    """Return (dt, limited_by, omega_max) from the dict ``build`` prepares."""
    candidates: list[tuple[float, str]] = []
    mass = system_info["node_mass"]
    if mass.size:
        inertia = system_info["node_inertia"]
        rad = system_info["node_radius"]
        E = system_info["node_E"]
        trans, rot = node_bond_bounds(mass, inertia, *system_info["bond_arrays"])
        kc = 0.0 * rad
        if system_info["bristle_bristle"]:
            kc = kc + BRISTLE_CONTACTS_PER_NODE * E * rad * 2.0  # k_n = E r, two-sided row
        if system_info["bristle_body"]:
            # k_n = 2 E_b E_k r / (E_b + E_k) against the stiffest body that can be touched
            kc = kc + BODY_CONTACTS_PER_NODE * system_info["node_E_body"] * rad
        w2_t = trans + kc / mass
        w2_r = rot + kc * rad ** 2 / inertia
        free = system_info["node_free"]
        w2_t = np.where(free, w2_t, 0.0)
        w2_r = np.where(free, w2_r, 0.0)
        it = int(np.argmax(w2_t))
        ir = int(np.argmax(w2_r))
        label = system_info["node_label"]
        parts_t = "bonds" + (" + contacts" if kc.any() else "")
        candidates.append((float(w2_t[it]), f"translation of {label(it)} ({parts_t})"))
        candidates.append((float(w2_r[ir]), f"rotation of {label(ir)} ({parts_t})"))
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
    return safety * 2.0 / omega, label, omega
