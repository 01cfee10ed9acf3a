"""What every seed-thesis preset family shares (``generate.py`` loads the families): the
materials and friction angles of the thesis, the seed's brush, and the quaternions that turn a
brush base. SI units."""
from __future__ import annotations

import math

DEG = math.pi / 180.0

# ----------------------------------------------------------------------------- materials
# Table 4.1 (seed 4.1): the steel rod.
STEEL = {"youngs_modulus": 200e9, "poisson_ratio": 0.3, "density": 7640.0}
# Seed 4.2: silicone E = 2.7 +- 1.1 MPa (the text's "GPa" is a typo: appendix B measured
# MPa, as DESIGN 4.2 says), nu 0.47-0.49, density 1100-2300 kg/m^3; nominal values.
SILICONE = {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1700.0}
# FDM-printed PLA wedges (seed 4.2.3): textbook PLA values.
PLA = {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1240.0}
# NECURON rigid foam (seed 4.3.3); the thesis gives no properties: a board of about
# 700 kg/m^3 and 1 GPa, rigid next to the silicone (an assumption).
FOAM = {"youngs_modulus": 1.0e9, "poisson_ratio": 0.3, "density": 700.0}

PHI_SIL_SIL = 44 * DEG    # seed 4.2: silicone-silicone friction angle 44 +- 2 deg
PHI_SIL_PLA = 24 * DEG    # seed 4.2: silicone-PLA (wedge) 24 +- 2 deg
PHI_SIL_FOAM = 36 * DEG   # seed 4.3: silicone-foam 36 +- 2 deg

# The seed's brush (4.2.1): 17 x 5 bristles, 33 mm, conical 1.0 -> 0.5 mm radius.
BRISTLE_LENGTH = 0.033
ROOT_RADIUS = 0.001
TIP_RADIUS = 0.0005
PITCH = 0.003  # not in the seed: an assumption (DESIGN 4.2)


def quat_axis_angle(axis, angle):
    n = math.sqrt(sum(a * a for a in axis))
    s = math.sin(angle / 2) / n
    return [math.cos(angle / 2), axis[0] * s, axis[1] * s, axis[2] * s]


# bristles grow along the base's local +z; these turn local z into a world direction
Q_Z_TO_PLUS_X = quat_axis_angle([0, 1, 0], math.pi / 2)     # local x -> world -z
Q_Z_TO_MINUS_X = quat_axis_angle([0, 1, 0], -math.pi / 2)   # local x -> world +z


def seed_brush(name="brush", n_nodes=8, **extra):
    brush = {"name": name, "material": "silicone", "rows": 17, "columns": 5,
             "pitch": [PITCH, PITCH], "bristle_length": BRISTLE_LENGTH,
             "root_radius": ROOT_RADIUS, "tip_radius": TIP_RADIUS, "n_nodes": n_nodes}
    brush.update(extra)
    return brush


def cube_mass(a, density):
    return density * a ** 3
