"""The spinning-body presets (seed 4.3 and appendix H): a foam cube on a hinge spun into the
brush (20, 40 and 60 mm), and the two angular momentum checks. Loaded by ``generate.py``,
which writes the JSON files; SI units."""
from __future__ import annotations

import math

from seed_values import (DEG, SILICONE, PLA, FOAM, PHI_SIL_SIL, PHI_SIL_FOAM, BRISTLE_LENGTH,
                         TIP_RADIUS, Q_Z_TO_PLUS_X, Q_Z_TO_MINUS_X, seed_brush, cube_mass)

# ----------------------------------------------------------------------------- 4.3 spin
SPIN_OMEGA0 = 10.0     # rad/s (assumption)
SPIN_K1 = 0.1          # 1/s   (assumption)
SPIN_K2 = 0.5          # rad/s^2 (assumption)
SPIN_NODES = 6


def spin_cube(size_mm):
    a = size_mm / 1000
    x_tips = a / 2                       # configuration 1: tips on the face plane
    x_base = x_tips + BRISTLE_LENGTH + TIP_RADIUS
    halfway = a * (1 + math.sqrt(2)) / 4
    m = cube_mass(a, FOAM["density"])
    desc = (
        f"Seed 4.3 (figs. 4.22-4.26, 4.40), brush dynamic test with the {size_mm} mm cube, "
        f"brush in configuration 1. Cube: rigid NECURON foam, {size_mm} mm edge, density "
        f"700 kg/m^3 (mass {m * 1000:.2f} g; E 1 GPa: assumptions, the seed gives neither), "
        f"centred on the origin, faces along the world axes, on a hinge about the world y "
        f"axis through its centre (seed 4.3.1: one horizontal axis, translation fixed). "
        f"External dissipation seed eq. 4.6, dw/dt = -k1 w - k2 sign(w), with k1 = "
        f"{SPIN_K1:g} 1/s and k2 = {SPIN_K2:g} rad/s^2: the seed fitted k1, k2 per cube "
        f"(appendix F, figs. F.1-F.3) but its text keeps no numbers, so these are "
        f"assumptions (a free spin-down from {SPIN_OMEGA0:g} rad/s in about 11 s); replace "
        f"them with the fitted values. Initial spin {SPIN_OMEGA0:g} rad/s about +y (the seed "
        f"set it by hand and gives no number: an assumption). Friction silicone-foam "
        f"36 deg, silicone-silicone 44 deg; contacts elastic. Brush: the seed's 17 x 5 "
        f"silicone brush (33 mm, conical 1.0 -> 0.5 mm, 3 mm pitch, E 2.7 MPa, nu 0.48, "
        f"1700 kg/m^3), bristles horizontal along world -x, pointing at the cube. Geometry "
        f"of the six configurations (seed figs. 4.24-4.25; coordinates of this preset, a = "
        f"cube edge, tips = x of the bristle tips' ends, i.e. tip node centre + 0.5 mm; the "
        f"brush base is at x = tips + 33.5 mm, turned by the quaternion "
        f"[cos(-45 deg), 0, sin(-45 deg), 0] about y): two horizontal positions, P1 "
        f"'touching one face' tips = a/2 (the corners sweep a(sqrt2 - 1)/2 into the brush) "
        f"and P2 halfway to 'touching one edge' (tips = a sqrt2/2), tips = a(1 + sqrt2)/4 "
        f"(= {halfway * 1000:.2f} mm here); two vertical levels, the brush centre at the "
        f"axis (z = 0) or at the top face (z = a/2); 'horizontal' brush = its 17-bristle "
        f"rows horizontal, along y (parallel to the axis; scene rows 17, columns 5, base "
        f"local x = world z), 'vertical' = 17-bristle rows along z. Configurations: 1 = "
        f"horizontal, axis level, P1 (this preset: base at x = {x_base * 1000:.2f} mm, "
        f"y = z = 0); 2 = horizontal, axis level, P2; 3 = horizontal, top-face level, P1; "
        f"4 = horizontal, top-face level, P2; 5 = vertical, axis level, P1; 6 = vertical, "
        f"axis level, P2. (The seed's figure 4.25 with its numbering is an image; this "
        f"numbering follows its text: config. 1 has the largest overlap and stops the "
        f"cube fastest, config. 4 less.) Gravity off: the hinge takes the cube's weight and "
        f"the bristles' sag is left out (an assumption). Resolution: {SPIN_NODES} nodes per "
        f"bristle, duration 3 s (no stop condition: caught in the brush the cube rocks "
        f"through w = 0 many times before it settles), record interval 2 ms; channels "
        f"nodes (for playback: the bristles move), bodies (the cube's "
        f"angular_velocity[:, 1] is w(t)), root force, energy, contacts.")
    return {
        "schema_version": 1, "name": f"spin_cube_{size_mm}", "description": desc,
        "materials": {"silicone": SILICONE, "foam": FOAM},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": PHI_SIL_SIL},
            {"materials": ["silicone", "foam"], "friction_angle": PHI_SIL_FOAM}],
        "brushes": [seed_brush(n_nodes=SPIN_NODES, base={
            "position": [x_base, 0.0, 0.0], "orientation": Q_Z_TO_MINUS_X})],
        "bodies": [{
            "name": "cube", "material": "foam",
            "shape": {"type": "box", "size": [a, a, a]},
            "mass_properties": {"density": FOAM["density"]},
            "motion": {"type": "hinge", "axis": [0.0, 1.0, 0.0], "point": [0.0, 0.0, 0.0],
                       "k1": SPIN_K1, "k2": SPIN_K2},
            "angular_velocity": [0.0, SPIN_OMEGA0, 0.0]}],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 3.0, "record_interval": 0.002,
                "channels": ["nodes", "bodies", "root_force", "energy", "contacts"]},
    }


# ----------------------------------------------------------------------------- appendix H
def momentum_two_brushes():
    a = 0.02
    n_nodes = 6
    plate = [0.016, 0.052, 0.004]     # local x (5 bristles), y (17 bristles), z (thickness)
    x_base = a / 2 + BRISTLE_LENGTH + TIP_RADIUS
    x_plate = x_base + plate[2] / 2
    desc = (
        "Seed appendix H (fig. H.3, H.4; seed 4.3.5), angular momentum check with a brush: "
        "two brushes face each other with a cube spinning between them, and the system's "
        "angular momentum must not change. Cube: NECURON foam (700 kg/m^3, E 1 GPa, "
        "assumptions), 20 mm edge (the size with the largest YADE error in fig. H.4), a "
        "free body at the origin spinning at 10 rad/s about +y. Brushes brush_left and "
        "brush_right: the seed's 17 x 5 silicone brush (33 mm, conical 1.0 -> 0.5 mm, "
        "3 mm pitch, E 2.7 MPa, nu 0.48, 1700 kg/m^3), 17-bristle rows along y, one on "
        "each side along x with bristles pointing at the cube and tips on the cube's face "
        "planes (x = -+10 mm), so the spinning corners sweep 4.1 mm into both. As in the "
        "seed, the roots of each brush are one rigid fixture: each brush is mounted on a "
        "free PLA plate (plate_left, plate_right: 16 x 52 x 4 mm, 4.1 g, collide false) "
        "that carries it, so the system (cube + plates + bristles) is closed and its "
        "angular momentum is conserved exactly. Friction silicone-foam 36 deg, "
        "silicone-silicone 44 deg (dissipative: energy falls, angular momentum stays); no "
        "gravity, no damping. Check: engine.angular_momentum(system) before and after; "
        "the tests require |dL|/|L| < 1e-6. Resolution: 6 nodes per bristle, duration "
        "0.3 s, record interval 1 ms; all channels but bending.")

    def side(sign, name):
        # brush_left (sign -1) grows along +x, brush_right (sign +1) along -x
        q = Q_Z_TO_PLUS_X if sign < 0 else Q_Z_TO_MINUS_X
        return ({"name": f"plate_{name}", "material": "pla",
                 "shape": {"type": "box", "size": plate},
                 "mass_properties": {"density": PLA["density"]},
                 "pose": {"position": [sign * x_plate, 0.0, 0.0], "orientation": q},
                 "motion": {"type": "free"}, "collide": False},
                seed_brush(name=f"brush_{name}", n_nodes=n_nodes, mount=f"plate_{name}",
                           base={"position": [0.0, 0.0, plate[2] / 2]}))

    pl, bl = side(-1, "left")
    pr, br = side(+1, "right")
    return {
        "schema_version": 1, "name": "momentum_two_brushes", "description": desc,
        "materials": {"silicone": SILICONE, "foam": FOAM, "pla": PLA},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": PHI_SIL_SIL},
            {"materials": ["silicone", "foam"], "friction_angle": PHI_SIL_FOAM}],
        "brushes": [bl, br],
        "bodies": [{"name": "cube", "material": "foam",
                    "shape": {"type": "box", "size": [a, a, a]},
                    "mass_properties": {"density": FOAM["density"]},
                    "motion": {"type": "free"}, "angular_velocity": [0.0, 10.0, 0.0]},
                   pl, pr],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 0.3, "record_interval": 0.001,
                "channels": ["nodes", "bodies", "root_force", "energy", "contacts"]},
    }


def momentum_spheres_cube():
    a = 0.02
    m = cube_mass(a, FOAM["density"])
    r = a * (3 / (4 * math.pi)) ** (1 / 3)     # sphere of the cube's volume: equal masses
    inertia = 0.4 * m * r * r
    offset, speed, x0 = 0.006, 1.0, 0.04
    desc = (
        "Seed appendix H (fig. H.1, H.2), angular momentum check without a brush: two "
        "spheres move antiparallel on offset paths and hit a stationary cube off-centre; "
        "with no external torque the system's angular momentum must not change. Cube: "
        f"NECURON foam (700 kg/m^3, E 1 GPa, assumptions), 20 mm edge, {m * 1000:.2f} g, a "
        "free body at rest at the origin, faces along the axes. Spheres sphere_left and "
        f"sphere_right: foam, radius {r * 1000:.3f} mm (the cube's volume), so each has the "
        f"cube's mass {m * 1000:.2f} g (equal masses: the largest YADE error in fig. H.2); "
        f"mass and inertia 2/5 m r^2 given exactly. sphere_left starts at x = -{x0} m, "
        f"z = +{offset} m moving +x at {speed:g} m/s; sphere_right at x = +{x0} m, "
        f"z = -{offset} m moving -x at {speed:g} m/s; both strike the cube's faces "
        f"{offset * 1000:g} mm off-centre at t = 17.6 ms and set it spinning about y. "
        f"Foam-foam friction angle 30 deg (an assumption: the seed gives none), elastic. "
        f"No gravity. Check: engine.angular_momentum(system) before and after the impact; "
        f"the tests require |dL|/|L| < 1e-6. Duration 0.05 s, record interval 0.1 ms; "
        f"channels bodies, energy, contacts. run.dt_safety 0.05 (dt 0.5 us, about 90 steps "
        f"per 47 us impact): at the default 0.5 the impact gets only ~9 steps and the "
        f"energy balance (total + dissipated) is off by 12 % with friction (angular "
        f"momentum is conserved either way); at 0.05 it is within about 2 %.")

    def sphere(name, x, z, vx):
        return {"name": name, "material": "foam",
                "shape": {"type": "sphere", "radius": r, "subdivisions": 3},
                "mass_properties": {"mass": m, "inertia": [[inertia, 0, 0], [0, inertia, 0],
                                                           [0, 0, inertia]]},
                "pose": {"position": [x, 0.0, z]}, "motion": {"type": "free"},
                "velocity": [vx, 0.0, 0.0]}

    return {
        "schema_version": 1, "name": "momentum_spheres_cube", "description": desc,
        "materials": {"foam": FOAM},
        "contact_pairs": [{"materials": ["foam", "foam"], "friction_angle": 30 * DEG}],
        "bodies": [{"name": "cube", "material": "foam",
                    "shape": {"type": "box", "size": [a, a, a]},
                    "mass_properties": {"density": FOAM["density"]},
                    "motion": {"type": "free"}},
                   sphere("sphere_left", -x0, offset, speed),
                   sphere("sphere_right", x0, -offset, -speed)],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 0.05, "record_interval": 0.0001, "dt_safety": 0.05,
                "channels": ["bodies", "energy", "contacts"]},
    }


def presets() -> list[dict]:
    return [*(spin_cube(s) for s in (20, 40, 60)), momentum_two_brushes(),
            momentum_spheres_cube()]
