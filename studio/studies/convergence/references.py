"""Analytic references: Euler-Bernoulli frequencies of a cantilever, the elastica of a tapered
self-weighted cantilever, and which one applies to a scene and quantity."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from engine.analysis.beam_theory import circle_second_moment, rod_frequency
from engine.model.layout import quat_to_matrix

from .quantities import Quantity


def tapered_elastica_tip(length: float, youngs_modulus: float, root_radius: float,
                         tip_radius: float, tip_force: float, weight_density: float = 0.0,
                         tol: float = 1e-10) -> tuple[float, float]:
    """Large deflection of an inextensible, unshearable cantilever of circular section whose
    radius tapers linearly from ``root_radius`` to ``tip_radius``, clamped with its axis
    horizontal, under a dead vertical tip force ``tip_force`` (N) and its own weight
    (``weight_density`` = rho g, N/m^3, along the same direction).

    With u = s / L in [0, 1], theta the slope (measured towards the load) and m = M L / (E I0)
    the bending moment in units of E I0 / L (I0 the root's second moment), the shear force
    V(u) = P + rho g L int_u^1 A du' carried by the section gives

        theta' = m I0 / I(u),   m' = -(L^2 / E I0) V(u) cos(theta),
        x' = cos(theta),  y' = sin(theta);  theta(0) = x(0) = y(0) = 0,  m(1) = 0,

    solved with scipy ``solve_bvp`` from the linear solution, with continuation in the load.
    Returns ``(x_tip / L, y_tip / L)``: the tip's position along the clamp axis and its
    deflection along the load, relative to L."""
    from scipy.integrate import solve_bvp

    r0, r1 = root_radius, tip_radius
    i0 = circle_second_moment(r0)
    scale = length ** 2 / (youngs_modulus * i0)

    def radius(u):
        return r0 + (r1 - r0) * u

    def shear(u, load):
        ru = radius(u)
        # int_u^1 pi r^2 du' for a linear taper, exactly: pi (1 - u)(r1^2 + r1 ru + ru^2) / 3
        weight = weight_density * length * math.pi * (1.0 - u) * (r1 ** 2 + r1 * ru + ru ** 2) / 3
        return load * (tip_force + weight)

    def stiffness_ratio(u):
        return (r0 / radius(u)) ** 4  # I0 / I(u)

    u = np.linspace(0.0, 1.0, 401)
    total = scale * (abs(tip_force) + abs(weight_density) * length * math.pi * r0 ** 2)
    steps = max(1, int(math.ceil(total / 1.5)))
    guess = None
    sol = None
    for load in np.linspace(1.0 / steps, 1.0, steps):
        if guess is None:
            # linear beam: m(u) = scale int_u^1 V(u') (u' - u) du' ~ scale V(0) (1 - u)^2/2 ...
            # a rough, consistent start (continuation makes it exact)
            m = scale * shear(0.0, load) * (1.0 - u) ** 2 / 2.0
            th = np.cumsum(m * stiffness_ratio(u)) * (u[1] - u[0])
            guess = np.vstack([th, m, u.copy(), np.cumsum(np.sin(th)) * (u[1] - u[0])])

        def rhs(s, y, load=load):
            return np.vstack([y[1] * stiffness_ratio(s), -scale * shear(s, load) * np.cos(y[0]),
                              np.cos(y[0]), np.sin(y[0])])

        def bc(ya, yb):
            return np.array([ya[0], yb[1], ya[2], ya[3]])

        sol = solve_bvp(rhs, bc, u, guess, tol=tol, max_nodes=200_000)
        if not sol.success:
            raise RuntimeError(f"elastica BVP did not converge at load {load:g}: {sol.message}")
        u, guess = sol.x, sol.y
    return float(sol.y[2, -1]), float(sol.y[3, -1])


@dataclass
class Reference:
    value: float
    kind: str          # "analytic" | "richardson" | "finest" | "given"
    note: str


def _amplitude(profile, t: float) -> float:
    return float(np.interp(t, profile.times, profile.values))


def analytic_reference(scene, quantity: Quantity) -> Optional[Reference]:
    """The analytic reference of ``quantity`` for ``scene``, or None where there is none.

    Rod cases only: one brush of one straight bristle (no tip variance, fixed base), no
    bodies. tip_deflection: loads on the tip only, constant in the end (no oscillation), and
    those loads plus gravity all along one direction perpendicular to the bristle
    (the elastica of :func:`tapered_elastica_tip`). spectral_peak: a uniform rod (equal root and
    tip radius; Euler-Bernoulli modes, which ignore the rod's static sag under gravity and
    any damping)."""
    if quantity.kind not in ("tip_deflection", "spectral_peak") or quantity.index != 0:
        return None
    if len(scene.brushes) != 1 or scene.bodies:
        return None
    brush = scene.brushes[0]
    if brush.rows * brush.columns != 1 or brush.tip_variance != 0 or brush.mount is not None:
        return None
    material = scene.materials[brush.material]
    E, rho = material.youngs_modulus, material.density
    L = brush.bristle_length
    if quantity.kind == "spectral_peak":
        if abs(brush.root_radius - brush.tip_radius) > 1e-12 * brush.root_radius:
            return None
        f = rod_frequency(quantity.peak, L, E, brush.root_radius, rho)
        return Reference(f, "analytic", f"Euler-Bernoulli cantilever mode {quantity.peak}: "
                         f"(beta_n L)^2 / (2 pi) sqrt(E I / (rho A L^4)) = {f:.6g} Hz")
    q = np.asarray(brush.base.orientation, float)
    axis = quat_to_matrix(q / np.linalg.norm(q)) @ np.array([0.0, 0.0, 1.0])
    total = np.zeros(3)
    for load in scene.loads:
        if load.node not in (-1, brush.n_nodes - 1) or load.profile.frequency > 0:
            return None
        total += np.asarray(load.force, float) * _amplitude(load.profile, scene.run.duration)
    gravity = np.asarray(scene.environment.gravity, float)
    vectors = [v for v in (total, gravity) if np.linalg.norm(v) > 0]
    if not vectors:
        return None
    direction = vectors[0] / np.linalg.norm(vectors[0])
    for v in vectors:
        n = np.linalg.norm(v)
        if np.linalg.norm(np.cross(v / n, direction)) > 1e-9 or abs(v @ axis) > 1e-9 * n:
            return None
    _, y = tapered_elastica_tip(L, E, brush.root_radius, brush.tip_radius,
                                float(total @ direction), rho * float(gravity @ direction))
    what = "tip load" + (" and own weight" if np.linalg.norm(gravity) > 0 else "")
    shape = "uniform" if brush.root_radius == brush.tip_radius else "tapered"
    return Reference(y * L, "analytic", f"elastica of the {shape} cantilever under its "
                     f"{what} (scipy solve_bvp): {y * L:.6g} m")
