"""The tapered bristle element, one home for its formulas: the node masses and twist
inertias of a bristle cut into frustum segments (:func:`node_masses`) and the exact frustum
bond stiffnesses (:func:`frustum_bond_stiffness`). The build (:mod:`engine.assembly.bristles`)
and the time-step estimate (:mod:`engine.assembly.estimate`) both use them; numpy only, so the
estimate stays numba-free.
"""
from __future__ import annotations

import math

import numpy as np


def node_masses(density: float, r_node: np.ndarray, seg_len: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(mass, inertia)`` of the nodes of one bristle of node radii ``r_node`` and segment
    length ``seg_len``: each frustum segment's mass ``rho pi L (r0^2 + r0 r1 + r1^2) / 3``
    split half to each end node; the twist inertia ``m r^2 / 2`` of each node (isotropic: the
    node's own)."""
    r_node = np.asarray(r_node, float)
    r0, r1 = r_node[:-1], r_node[1:]
    seg_mass = density * math.pi * seg_len * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0  # frustum
    mass = np.zeros(len(r_node))
    mass[:-1] += 0.5 * seg_mass
    mass[1:] += 0.5 * seg_mass
    return mass, 0.5 * mass * r_node ** 2


def frustum_bond_stiffness(E, G, r0, r1, length):
    """Stiffnesses of the bond between nodes of radii ``r0`` (node i) and ``r1`` (node j), a
    linearly tapered solid circular Euler-Bernoulli frustum of ``length`` (arrays or floats):
    ``(kn, ks, kb, ksb, kt)`` for the energy of ``bonds._law``.

    Axial and twist are the exact frustum compliances, ``1/kn = int dx / (E A(x))`` and
    ``1/kt = int dx / (G J(x))``: ``kn = E pi r0 r1 / L``, ``kt = G pi/2 * 3 r0^3 r1^3 /
    (L (r0^2 + r0 r1 + r1^2))`` (seed eq. 3.1 for a uniform bond).

    Bending: the bond's energy in one plane is ``1/2 ks d^2 + ksb d phi + 1/2 kb phi^2`` with
    ``d`` the midpoint shear displacement and ``phi`` the relative rotation, whose conjugate
    forces are the shear force V and the bending moment at the midpoint. For a beam whose
    node i is clamped these are ``[d, phi] = C [V, M_mid]`` with the exact flexibility

        C = int_0^L [xi^2, xi; xi, 1] / (E I(x)) dx,   xi = L/2 - x,

    and the stiffness is ``C^-1``. With ``I = pi r^4 / 4`` and r linear in x the integrals are
    rational in r0, r1 (E0 = E pi r0^4 / 4, beta = r1 / r0):
    ``C = [L^3 (b^2 - b + 1) / 12, L^2 (b^2 - 1) / 6; ., L (b^2 + b + 1) / 3] / (E0 b^3)``,
    determinant ``L^4 / (12 E0^2 b^4)``, so

        ks  = E pi r0 r1 (r0^2 + r0 r1 + r1^2) / L^3
        kb  = E pi r0 r1 (r0^2 - r0 r1 + r1^2) / (4 L)
        ksb = E pi r0 r1 (r0^2 - r1^2) / (2 L^2)

    (uniform: ``12 E I / L^3``, ``E I / L``, 0, seed eq. 3.1). The element is then the exact
    Euler-Bernoulli stiffness of the frustum for any end loads, so a tapered cantilever under
    tip loads is exact at any resolution, as the uniform one already was; ``ks kb - ksb^2 =
    3 (E pi r0^2 r1^2)^2 / (4 L^4) > 0``.
    """
    s2 = r0 * r0 + r1 * r1
    p = r0 * r1
    e = E * math.pi * p
    kn = e / length
    ks = e * (s2 + p) / length ** 3
    kb = e * (s2 - p) / (4.0 * length)
    ksb = e * (r0 * r0 - r1 * r1) / (2.0 * length ** 2)
    kt = G * math.pi / 2.0 * 3.0 * p ** 3 / (length * (s2 + p))
    return kn, ks, kb, ksb, kt
