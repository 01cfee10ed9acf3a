"""Reference for a frictional contact: a tapered elastica whose tip slides on a rigid plane.

Nothing here imports the engine. The problem (all SI, planar, in the x-z plane):

* a solid conical rod of length L, radius r(s) = r0 + (r1 - r0) s / L, Young's modulus E,
  clamped at the origin along +z (an extensible, unshearable Kirchhoff rod: bending stiffness
  E I(s) = E pi r^4 / 4, axial stiffness E A(s) = E pi r^2);
* a rigid plane whose unit normal n = (sin a, 0, -cos a) points from the plane towards the
  rod (``normal_angle`` a between n and -z), moved by ``depth`` along -z from the position
  where it just touches the rod's straight tip sphere (radius r1);
* the plane pushes the tip's sphere through a linear penalty contact of stiffness k_n (the
  overlap is F_n / k_n, so the axis end lies ``r1 - F_n / k_n`` from the plane) and Coulomb
  friction mu that acts at the middle of the overlap (a lever ``r1 - F_n / (2 k_n)`` below
  the axis end) and opposes the tip's slip: the tip force is F = F_n (n - sigma mu t) with
  the plane's tangent t = (cos a, 0, sin a) and sigma = +1 while the tip slides along +t
  relative to the plane (loading), -1 while it slides back (unloading).

With arc length s (units of L), theta the tangent's angle from +z towards +x and m the
bending moment about +y (units E I0 / L, I0 = I(r0)), the rod's equations are

    x' = (1 + eps) sin(theta),  z' = (1 + eps) cos(theta),  eps = (F . tangent) / (E A(s)),
    theta' = m / g(s)^4,        m' = -(1 + eps) (f_x cos(theta) - f_z sin(theta)),

with g(s) = r(s) / r0 and f the tip force in units E I0 / L^2, and the boundary conditions

    x(0) = z(0) = theta(0) = 0,   m(1) = -sigma mu F_n lever / L (the friction's moment),
    n . (r(1) - (0, 0, 1)) = (depth cos(a) - F_n / k_n) / L  (the tip on the shifted plane),

one boundary-value problem for (x, z, theta, m) with the unknown parameter F_n, solved by
scipy ``solve_bvp`` with continuation in the depth (each solution is the next first guess).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_bvp


@dataclass
class TipContact:
    """One equilibrium, SI: the plane's ``depth``, the tip node's position (``tip_x``,
    ``tip_z``), the force of the plane on the rod (``force_x``, ``force_z``, of which
    ``normal_force`` is the component along n) and the tip slope ``tip_angle`` (rad)."""

    depth: float
    tip_x: float
    tip_z: float
    force_x: float
    force_z: float
    normal_force: float
    tip_angle: float


def sliding_tip_on_plane(depths, *, length: float, root_radius: float, tip_radius: float,
                         youngs_modulus: float, normal_angle: float,
                         friction_coefficient: float, slip_sign: float,
                         contact_stiffness: float, tol: float = 1e-9) -> list[TipContact]:
    """Equilibria of the rod of the module docstring at each of ``depths`` (increasing from
    near zero; m), with the tip sliding in the direction ``slip_sign`` (+1: along +t, as while
    the plane is pressed in; -1: back, as while it is withdrawn)."""
    L = length
    beta = tip_radius / root_radius
    EI0 = youngs_modulus * math.pi * root_radius ** 4 / 4.0
    force_unit = EI0 / L ** 2
    axial_ratio = root_radius ** 2 / (4.0 * L ** 2)       # E I0 / (E A0 L^2)
    k_hat = contact_stiffness * L / force_unit            # k_n in units of force_unit / L
    r_hat = tip_radius / L
    sa, ca = math.sin(normal_angle), math.cos(normal_angle)
    n = np.array([sa, ca * -1.0])                         # (x, z) components
    t = np.array([ca, sa])
    mu, sigma = friction_coefficient, float(slip_sign)
    direction = n - sigma * mu * t                        # tip force per unit F_n

    def rhs(s, y, p):
        fx, fz = p[0] * direction
        g = 1.0 + (beta - 1.0) * s
        sn, cs = np.sin(y[2]), np.cos(y[2])
        stretch = 1.0 + axial_ratio * (fx * sn + fz * cs) / g ** 2
        return np.vstack([stretch * sn, stretch * cs, y[3] / g ** 4,
                          -stretch * (fx * cs - fz * sn)])

    out = []
    s = np.linspace(0.0, 1.0, 101)
    y = np.vstack([np.zeros_like(s), s, np.zeros_like(s), np.zeros_like(s)])
    p = np.array([0.0])
    for depth in depths:
        d_hat = depth / L

        def bc(ya, yb, p, d_hat=d_hat):
            fn = p[0]
            lever = r_hat - 0.5 * fn / k_hat
            return np.array([ya[0], ya[1], ya[2],
                             yb[3] + sigma * mu * fn * lever,
                             n[0] * yb[0] + n[1] * (yb[1] - 1.0) - (d_hat * ca - fn / k_hat)])

        sol = solve_bvp(rhs, bc, s, y, p, tol=tol, max_nodes=100_000)
        if not sol.success:
            raise RuntimeError(f"frictional elastica did not converge at depth {depth}: "
                               f"{sol.message}")
        s, y, p = sol.x, sol.y, sol.p
        fn = float(p[0]) * force_unit
        fx, fz = fn * direction
        out.append(TipContact(depth=float(depth), tip_x=float(y[0, -1]) * L,
                              tip_z=float(y[1, -1]) * L, force_x=float(fx), force_z=float(fz),
                              normal_force=fn, tip_angle=float(y[2, -1])))
    return out
