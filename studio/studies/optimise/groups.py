"""Non-dimensional groups of a design x scenario, so that a result transfers to another
target (reported beside the dimensional values):

- ``stiffness_group`` = N k_tip (a/2)^2 / (I omega0^2): the brush's torsional stiffness about
  the target's axis, as if every bristle (tip stiffness k_tip) pushed at the half edge a/2,
  over the target's rotational energy scale I omega0^2 (I about the spin axis);
- ``length_ratio`` = L / a: bristle length over the target's edge;
- ``mass_ratio`` = brush mass / target mass.

k_tip is the exact tip stiffness of the tapered bristle as an Euler-Bernoulli cantilever:
1 / k_tip = integral_0^L (L - x)^2 / (E I(x)) dx, I(x) = pi r(x)^4 / 4, r linear from root to
tip.
"""
from __future__ import annotations

import math

import numpy as np


def tip_stiffness(E: float, root_radius: float, tip_radius: float, length: float) -> float:
    """Tip stiffness (N/m) of a linearly tapered circular cantilever."""
    x = np.linspace(0.0, length, 401)
    r = root_radius + (tip_radius - root_radius) * x / length
    integrand = (length - x) ** 2 / (E * math.pi * r ** 4 / 4)
    return float(1.0 / np.trapezoid(integrand, x))


def groups(scene: dict, target: str = "cube") -> dict:
    """The groups (and the dimensional values they come from) of a scene dict."""
    b = scene["brushes"][0]
    E = float(scene["materials"][b["material"]]["youngs_modulus"])
    k_tip = tip_stiffness(E, b["root_radius"], b["tip_radius"], b["bristle_length"])
    body = next((x for x in scene["bodies"] if x["name"] == target), scene["bodies"][0])
    size = np.asarray(body["shape"]["size"], float)
    rho = float(body["mass_properties"]["density"])
    mass = rho * float(np.prod(size))
    w = np.asarray(body["angular_velocity"], float)
    omega0 = float(np.linalg.norm(w))
    n = w / omega0
    # box inertia about its centre, principal axes along the world axes (unturned box)
    inertia = mass / 12 * np.diag([size[1] ** 2 + size[2] ** 2, size[0] ** 2 + size[2] ** 2,
                                   size[0] ** 2 + size[1] ** 2])
    I_axis = float(n @ inertia @ n)
    a = float(size.min())
    n_bristles = b["rows"] * b["columns"]
    rho_b = float(scene["materials"][b["material"]]["density"])
    r1, r2, L = b["root_radius"], b["tip_radius"], b["bristle_length"]
    brush_mass = n_bristles * rho_b * math.pi * L * (r1 * r1 + r1 * r2 + r2 * r2) / 3
    return {"bending_stiffness_Pa_m4": E * (2 * r1) ** 4, "tip_stiffness_N_per_m": k_tip,
            "target_inertia_kg_m2": I_axis, "omega0_rad_s": omega0,
            "stiffness_group": n_bristles * k_tip * (a / 2) ** 2 / (I_axis * omega0 ** 2),
            "length_ratio": L / a, "mass_ratio": brush_mass / mass}
