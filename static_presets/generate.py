"""Write the preset scene files of this folder from the seed thesis's numbers.

    python static_presets/generate.py          # rewrite every static_presets/*.json
    python static_presets/generate.py --check  # exit 1 if a file differs from what this writes

The JSON files are the presets (the studio, the server and the CLI read them); this script
is how they were made: every derived number (positions, masses, profiles) is computed here
from the thesis's values, so the arithmetic can be checked and a preset regenerated after a
change. Each scene's ``description`` says which section/figure of the thesis it reproduces
and every assumption it makes. SI units throughout.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
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


# ----------------------------------------------------------------------------- 4.1 rod
ROD_LENGTH = 0.4
ROD_RADIUS = 0.5 * 1.42e-3
ROD_NODES = 36           # 35 segments of 11.43 mm: node 4 sits 45.71 mm from the root
ROOT_IMPULSE_NODE = 4    # the seed's 0.0458 m: 0.19 % (0.09 mm) away, the closest node
ROD_COMMON = (
    "Steel rod of table 4.1 (E 200 GPa, nu 0.3, density 7640 kg/m^3, L 0.4 m, d 1.42 mm) "
    "clamped at x = 0 as a horizontal cantilever along +x (a brush of one bristle, base "
    "turned so the bristle grows along +x); loads act along -z (vertical). Resolution: "
    f"{ROD_NODES} nodes ({ROD_NODES - 1} bonds of {1000 * ROD_LENGTH / (ROD_NODES - 1):.2f} mm;"
    " the first three bending frequencies fall below Euler-Bernoulli's by about 0.04, 0.13 "
    "and 0.21 %: the lumped-mass O(h^2) error, -0.2/-0.7/-1.2 % at 16 nodes in "
    "tests/engine/test_verification_beams.py, scaled by h^2). No damping, no friction (an "
    "assumption: the seed names none for this test). Gravity off: "
    "the rod's own weight (a 9.5 mm static sag) is left out, so it vibrates about the "
    "straight rod (an assumption; the seed does not say). Record: nodes, root force, "
    "energy; the tip is node -1 (nodes/positions[:, 35]) for the tip-trajectory power "
    "spectrum. ")


def rod_scene(name, description, load, duration, record_interval):
    return {
        "schema_version": 1, "name": name, "description": description,
        "materials": {"steel": STEEL},
        "brushes": [{"name": "brush", "material": "steel", "rows": 1, "columns": 1,
                     "bristle_length": ROD_LENGTH, "root_radius": ROD_RADIUS,
                     "tip_radius": ROD_RADIUS, "n_nodes": ROD_NODES,
                     "base": {"position": [0.0, 0.0, 0.0], "orientation": Q_Z_TO_PLUS_X}}],
        "loads": [load],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": duration, "record_interval": record_interval,
                "channels": ["nodes", "root_force", "energy"]},
    }


def rod_weight_release():
    weight = 0.020 * 9.81  # 20 g at the tip (seed 4.1.1), N
    ramp, release, free = 1.0, 1.1, 4.5
    # raised-cosine ramp 0 -> 1 over `ramp` s (6.3 periods of the first mode, 6.35 Hz):
    # the rod reaches the deflected state with a residual vibration of ~1 % of it
    times = [ramp * i / 20 for i in range(21)]
    values = [0.5 - 0.5 * math.cos(math.pi * t / ramp) for t in times]
    times += [release, release]
    values += [1.0, 0.0]
    desc = (
        "Seed 4.1.1 (fig. 4.2), weight release test. " + ROD_COMMON +
        f"The 20 g tip weight is its weight force, {weight:.4f} N along -z on the tip node "
        f"(a force, not a mass: an assumption), brought on with a raised-cosine ramp over "
        f"0-{ramp:g} s (slow against the 0.157 s first period, so the rod settles into the "
        f"static deflection, about 0.10 m, without ringing) and held; at t = {release:g} s "
        f"it is removed at once (released) and the rod vibrates freely for {free:g} s "
        f"as in the seed. Analyse frames with t >= {release:g} s. Duration "
        f"{release + free:g} s, record interval 1 ms (1 kHz: power spectrum up to 500 Hz, "
        f"the first four modes).")
    load = {"brush": "brush", "bristles": "all", "node": -1, "force": [0.0, 0.0, -weight],
            "profile": {"times": [round(t, 6) for t in times],
                        "values": [round(v, 9) for v in values]}}
    return rod_scene("rod_weight_release", desc, load, release + free, 0.001)


def rod_weight_static():
    weight = 0.020 * 9.81  # 20 g at the tip (seed 4.1.1), N
    ramp, duration = 0.2, 1.5
    desc = (
        "Seed 4.1.1 (fig. 4.2), the weight release test's loaded state as a static case, "
        "for convergence studies of tip_deflection. " + ROD_COMMON +
        f"Unlike the rod presets above, this one is damped and has gravity on. "
        f"The 20 g tip weight ({weight:.4f} N along -z on the tip node, a force: an "
        f"assumption) is ramped on linearly over 0-{ramp:g} s and held; gravity is on (the "
        f"rod's own weight, along the same -z), and Cundall local damping 0.7 (an "
        f"assumption: it changes how fast the rod settles, not where) lets it settle to "
        f"the static deflection, about 0.106 m (27 % of L), within {duration:g} s. "
        f"Reference: the elastica of the cantilever under its tip load and own weight. "
        f"Duration {duration:g} s, record interval 10 ms (only the last frame is the "
        f"result).")
    load = {"brush": "brush", "bristles": "all", "node": -1, "force": [0.0, 0.0, -weight],
            "profile": {"times": [0.0, ramp], "values": [0.0, 1.0]}}
    scene = rod_scene("rod_weight_static", desc, load, duration, 0.01)
    scene["environment"] = {"gravity": [0.0, 0.0, -9.81], "local_damping": 0.7}
    scene["run"]["channels"] = ["nodes", "root_force"]
    return scene


IMPULSE_PROFILE = {"times": [0.0, 0.0025, 0.005], "values": [0.0, 1.0, 0.0]}


def rod_tip_impulse():
    desc = (
        "Seed 4.1.2 (figs. 4.3, 4.4), impulse load at the free end. " + ROD_COMMON +
        "A triangular impulse (fig. 4.3: M = 1 N, d = 5 ms) acts along -z on the tip node: "
        "0 N at t = 0, rising linearly to 1 N at 2.5 ms and back to 0 at 5 ms (impulse "
        "2.5 mN s). The rod then vibrates freely. Duration 4.5 s (as the weight release "
        "test; the seed gives none for this test), record interval 0.5 ms (2 kHz: spectrum "
        "up to 1 kHz, the first six modes, for the high-frequency region of fig. 4.4b).")
    load = {"brush": "brush", "bristles": "all", "node": -1, "force": [0.0, 0.0, -1.0],
            "profile": IMPULSE_PROFILE}
    return rod_scene("rod_tip_impulse", desc, load, 4.5, 0.0005)


def rod_root_impulse():
    x = ROOT_IMPULSE_NODE * ROD_LENGTH / (ROD_NODES - 1)
    desc = (
        "Seed 4.1.3 (fig. 4.5), impulse load near the fixed end. " + ROD_COMMON +
        f"The same triangular impulse as rod_tip_impulse (0 -> 1 N at 2.5 ms -> 0 at 5 ms, "
        f"along -z) acts on node {ROOT_IMPULSE_NODE}, {x:.5f} m from the root: the node "
        f"closest to the seed's 0.0458 m ({1000 * abs(x - 0.0458):.2f} mm away; with "
        f"{ROD_NODES} nodes no node is closer). Duration 4.5 s, record interval 0.5 ms "
        f"(2 kHz), as rod_tip_impulse.")
    load = {"brush": "brush", "bristles": "all", "node": ROOT_IMPULSE_NODE,
            "force": [0.0, 0.0, -1.0], "profile": IMPULSE_PROFILE}
    return rod_scene("rod_root_impulse", desc, load, 4.5, 0.0005)


# ----------------------------------------------------------------------------- 4.2 wedge
WEDGE_DEPTH_STEPS = 33           # seed 4.2.2: 1 mm steps to 33 mm, then back out
WEDGE_A_MAX = 0.4                # m/s^2: t_d = sqrt(6 s / a_m) = 0.122 s per step
WEDGE_DWELL = 0.05               # s at rest after each step
WEDGE_NODES = 8
WEDGE_APEX_Z = BRISTLE_LENGTH + TIP_RADIUS   # apex touches the tip nodes' tops


def wedge_scene(angle_deg):
    t_d = math.sqrt(6 * 0.001 / WEDGE_A_MAX)
    cycle = 2 * WEDGE_DEPTH_STEPS * (t_d + WEDGE_DWELL)
    duration = math.ceil((cycle + 0.05) * 10) / 10
    height = 0.04
    desc = (
        f"Seed 4.2 (figs. 4.7, 4.12, 4.17-4.18), brush static test with the {angle_deg} deg "
        f"wedge. The seed's brush: 17 x 5 silicone bristles (E 2.7 MPa, nu 0.48, density "
        f"1700 kg/m^3: nominal values of the seed's ranges), 33 mm long, conical from 1.0 mm "
        f"root radius to 0.5 mm tip radius, in a square grid of 3 mm pitch both ways (an "
        f"assumption: the seed gives no pitch), roots clamped at z = 0, bristles along +z. "
        f"Grid: 17 rows of 5 along world x (a row = 5 bristles, 12 mm), rows 3 mm apart along "
        f"y (48 mm), centred on the origin; no tip randomness. Friction angles 44 deg "
        f"silicone-silicone and 24 deg silicone-wedge (seed 4.2); contacts elastic "
        f"(restitution 1). A rigid PLA wedge (included angle {angle_deg} deg, 40 mm tall, "
        f"20 mm long) lies with its apex edge along x, parallel to the 5-bristle rows, "
        f"0.5 mm to the side (y = +0.5 mm) of the axis of the middle row (row 9 of 17, "
        f"y = 0): DESIGN 4.2 explains why (an edge exactly over the bristles loads them "
        f"axially). The apex starts at z = {WEDGE_APEX_Z * 1000:.1f} mm, touching the tip "
        f"nodes' tops. Motion: the engine's stepped_parabolic profile, {WEDGE_DEPTH_STEPS} "
        f"steps of 1 mm down to the seed's full depth of 33 mm, each with v(t) = k t (t_d - "
        f"t), a_m = {WEDGE_A_MAX:g} m/s^2, t_d = sqrt(6 s / a_m) = {t_d * 1000:.1f} ms (seed "
        f"eq. 4.3), followed by a {WEDGE_DWELL * 1000:.0f} ms dwell, then the same steps "
        f"back out (unload): {cycle:.2f} s in all. The seed instead waited after each step "
        f"until the root force was steady; the hold-until-steady study replaces this "
        f"preset's motion to do that. Gravity on (-9.81 m/s^2 along z). Cundall local "
        f"damping 0.3 on the bristle nodes (quasi-static loading, so that each dwell is "
        f"close to equilibrium; an assumption of this preset, not of the seed). The "
        f"measured force is the total vertical root force, brushes/brush/root_force[:, 2] "
        f"(its change from t = 0 is the wedge's reaction, seed eq. 4.2), against the depth "
        f"z0 - bodies/wedge/position[:, 2]. Resolution: {WEDGE_NODES} nodes per bristle, "
        f"duration {duration:g} s, record interval 10 ms; channels nodes, bodies, root "
        f"force, energy, contacts.")
    return {
        "schema_version": 1, "name": f"wedge_{angle_deg}", "description": desc,
        "materials": {"silicone": SILICONE, "pla": PLA},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": PHI_SIL_SIL},
            {"materials": ["silicone", "pla"], "friction_angle": PHI_SIL_PLA}],
        "brushes": [seed_brush(n_nodes=WEDGE_NODES)],
        "bodies": [{
            "name": "wedge", "material": "pla",
            "shape": {"type": "wedge", "angle": angle_deg * DEG, "height": height,
                      "length": 0.02},
            "pose": {"position": [0.0, 0.0005, WEDGE_APEX_Z]},
            "motion": {"type": "kinematic", "after": "hold", "profile": {
                "kind": "stepped_parabolic", "direction": [0.0, 0.0, -1.0], "step": 0.001,
                "max_acceleration": WEDGE_A_MAX, "n_steps": WEDGE_DEPTH_STEPS,
                "dwell": WEDGE_DWELL, "unload": True}}}],
        "environment": {"gravity": [0.0, 0.0, -9.81], "local_damping": 0.3},
        "run": {"duration": duration, "record_interval": 0.01,
                "channels": ["nodes", "bodies", "root_force", "energy", "contacts"]},
    }


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


# ----------------------------------------------------------------------------- chapter 5
FUR = {"rows": 11, "columns": 21, "pitch": 0.002, "length": 0.02, "root_radius": 0.0003,
       "tip_radius": 0.0002, "n_nodes": 6}
FUR_BOND_DAMPING = 0.3    # fraction of critical, in the fur wires' bonds (an assumption)
FUR_DURATION = 0.001
FUR_GAP = 0.00005          # root nodes this far above the plate: they do not touch it at rest
PROJECTILE_RADIUS = 0.002
AIM_X = -0.012             # the sphere's centre crosses the fur's tip plane here
PLATE = [0.06, 0.06, 0.004]


def impact_scene(fur: bool):
    speed = 50 * math.sqrt(2)
    v = [50.0, 0.0, -50.0]           # 45 deg to the plate normal (+z), 50 sqrt2 m/s
    top = (FUR["root_radius"] + FUR_GAP + FUR["length"] + FUR["tip_radius"]) if fur else 0.0
    z0 = top + 0.003 + PROJECTILE_RADIUS    # sphere surface 3 mm above the top
    # fur: the centre crosses the tip plane at AIM_X (and would reach the plate at
    # AIM_X + top); bare plate: the sphere touches the plate at x = -R sin 45 deg
    x0 = AIM_X - (z0 - top) if fur else -z0
    ms = STEEL["density"] * 4 / 3 * math.pi * PROJECTILE_RADIUS ** 3
    common = (
        f"Projectile: a rigid steel sphere (sphere), radius {PROJECTILE_RADIUS * 1000:g} mm, "
        f"{ms * 1000:.3f} g, striking at 50 sqrt2 = {speed:.2f} m/s at 45 deg to the plate "
        f"normal (velocity [50, 0, -50] m/s; the seed's fig. 5.1 gives speed and angle, not "
        f"the projectile: its size and material are assumptions). Plate: a fixed steel "
        f"plate (plate) {PLATE[0] * 1000:g} x {PLATE[1] * 1000:g} x {PLATE[2] * 1000:g} mm, "
        f"top face at z = 0. Steel: E 200 GPa, nu 0.3, 7640 kg/m^3. No gravity; contacts "
        f"elastic (restitution 1), steel-steel friction 20 deg (an assumption). ")
    if fur:
        desc = (
            "Seed chapter 5 (5.3.2 'Space fur', fig. 5.1), the fur-covered plate. " + common +
            f"Fur (brush): {FUR['rows']} rows (along y) x {FUR['columns']} columns (along x) "
            f"of steel wires (a tough material, as the seed proposes), "
            f"{FUR['length'] * 1000:g} mm long, conical {FUR['root_radius'] * 1000:g} -> "
            f"{FUR['tip_radius'] * 1000:g} mm radius, {FUR['pitch'] * 1000:g} mm pitch, "
            f"roots clamped on the plate (base fixed at z = "
            f"{(FUR['root_radius'] + FUR_GAP) * 1000:g} mm, so the root nodes sit "
            f"{FUR_GAP * 1000:g} mm above the plate without touching it at rest), bristles "
            f"along +z; they can also touch the plate (bristle-body contacts). The wires' "
            f"bonds carry {FUR_BOND_DAMPING:g} of critical damping (material bond_damping, "
            f"an assumption standing for a lossy wire or coating; without it the undamped "
            f"wires keep ringing axially after the hit, the ringing dominates the root "
            f"force, and wires flung against each other end the run with a contact-overlap "
            f"instability at about 2.4 ms). The sphere starts 3 mm above the fur tips, aimed "
            f"so its centre crosses the tip plane at x = {AIM_X * 1000:g} mm. Transmitted "
            f"force (what reaches the plate, the quantity of fig. 5.1): "
            f"bodies/plate/contact_force - brushes/brush/root_force (the fur's roots push "
            f"the plate with minus the force the base exerts on them; plus sphere and wires "
            f"touching the plate); the tests compare its peak magnitude with solid_plate's. "
            f"Resolution: {FUR['n_nodes']} nodes per bristle, duration {FUR_DURATION * 1e3:g}"
            f" ms (the sphere has bounced out of the fur by about 0.9 ms), record interval "
            f"2 us; channels nodes (for playback: the wires move), bodies, root force, "
            f"energy, contacts.")
    else:
        desc = (
            "Seed chapter 5 (5.3.2 'Space fur', fig. 5.1), the bare (solid) plate: the "
            "reference for space_fur.json, the same projectile and plate without fur. " +
            common + "The sphere starts 3 mm above the plate. Transmitted force: "
            "bodies/plate/contact_force (the sphere on the plate). The contact lasts about "
            "2.5 us, so run.dt_safety is 0.1 (about 50 steps per contact) and the record "
            "interval 0.1 us, to catch its peak. Duration 0.2 ms; channels bodies, energy, "
            "contacts.")
    scene = {
        "schema_version": 1, "name": "space_fur" if fur else "solid_plate",
        "description": desc,
        "materials": {"steel": dict(STEEL, bond_damping=FUR_BOND_DAMPING) if fur else STEEL},
        "contact_pairs": [
            {"materials": ["steel", "steel"], "friction_angle": 20 * DEG}],
        "bodies": [
            {"name": "plate", "material": "steel", "shape": {"type": "box", "size": PLATE},
             "pose": {"position": [0.0, 0.0, -PLATE[2] / 2]}, "motion": {"type": "fixed"}},
            {"name": "sphere", "material": "steel",
             "shape": {"type": "sphere", "radius": PROJECTILE_RADIUS, "subdivisions": 3},
             "mass_properties": {"mass": ms, "inertia": [
                 [0.4 * ms * PROJECTILE_RADIUS ** 2, 0, 0],
                 [0, 0.4 * ms * PROJECTILE_RADIUS ** 2, 0],
                 [0, 0, 0.4 * ms * PROJECTILE_RADIUS ** 2]]},
             "pose": {"position": [x0, 0.0, z0]}, "motion": {"type": "free"},
             "velocity": v}],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": FUR_DURATION if fur else 0.0002,
                "record_interval": 2e-6 if fur else 1e-7,
                "channels": (["nodes", "bodies", "root_force", "energy", "contacts"] if fur
                             else ["bodies", "energy", "contacts"])},
    }
    if not fur:
        scene["run"]["dt_safety"] = 0.1
    if fur:
        scene["brushes"] = [{
            "name": "brush", "material": "steel", "rows": FUR["rows"],
            "columns": FUR["columns"], "pitch": [FUR["pitch"], FUR["pitch"]],
            "bristle_length": FUR["length"], "root_radius": FUR["root_radius"],
            "tip_radius": FUR["tip_radius"], "n_nodes": FUR["n_nodes"],
            "base": {"position": [0.0, 0.0, FUR["root_radius"] + FUR_GAP]}}]
    return scene


def gripper():
    a = 0.04
    n_nodes = 6
    plate = [0.016, 0.052, 0.004]
    gap = 0.012                                   # tips start 12 mm outside the faces
    x_tips = a / 2 + gap
    close_speed, close_time = 0.04, 0.4           # each base moves 16 mm in
    x_plate = x_tips + BRISTLE_LENGTH + TIP_RADIUS + plate[2] / 2
    m = cube_mass(a, FOAM["density"])
    desc = (
        "Seed chapter 5 (5.3.2 'Gripper brush', fig. 5.2): two brushes on kinematic bases "
        "close on a tumbling free body. Target (target): a free NECURON foam cube "
        f"(700 kg/m^3, E 1 GPa), 40 mm edge, {m * 1000:.1f} g, at the origin, tumbling at "
        "[1, 4, 0.5] rad/s (an assumption). Brushes brush_left and brush_right: the "
        "seed's 17 x 5 silicone brush (33 mm, conical 1.0 -> 0.5 mm, 3 mm pitch, E 2.7 MPa, "
        "nu 0.48, 1700 kg/m^3), 17-bristle rows along y, each mounted on a kinematic PLA "
        "base plate (plate_left, plate_right: 16 x 52 x 4 mm, collide false) on either "
        f"side along x, bristles pointing at the target, tips starting {gap * 1000:g} mm "
        f"outside its faces (x = -+{x_tips * 1000:g} mm). Both bases close at "
        f"{close_speed * 1000:g} mm/s for {close_time:g} s ({close_speed * close_time * 1000:g}"
        f" mm each: the tips end 4 mm inside the face planes) and then hold. Friction "
        "silicone-foam 36 deg, silicone-silicone 44 deg; no gravity; contacts elastic. "
        "Watch the target's angular_velocity fall and its position stay between the "
        "brushes. Resolution: 6 nodes per bristle, duration 1.0 s, record interval 2 ms; "
        "all channels but bending.")

    def side(sign, name):
        q = Q_Z_TO_PLUS_X if sign < 0 else Q_Z_TO_MINUS_X
        return ({"name": f"plate_{name}", "material": "pla",
                 "shape": {"type": "box", "size": plate},
                 "pose": {"position": [sign * x_plate, 0.0, 0.0], "orientation": q},
                 "motion": {"type": "kinematic", "after": "hold", "profile": {
                     "kind": "constant", "velocity": [-sign * close_speed, 0.0, 0.0],
                     "duration": close_time}},
                 "collide": False},
                seed_brush(name=f"brush_{name}", n_nodes=n_nodes, mount=f"plate_{name}",
                           base={"position": [0.0, 0.0, plate[2] / 2]}))

    pl, bl = side(-1, "left")
    pr, br = side(+1, "right")
    return {
        "schema_version": 1, "name": "gripper", "description": desc,
        "materials": {"silicone": SILICONE, "foam": FOAM, "pla": PLA},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": PHI_SIL_SIL},
            {"materials": ["silicone", "foam"], "friction_angle": PHI_SIL_FOAM}],
        "brushes": [bl, br],
        "bodies": [{"name": "target", "material": "foam",
                    "shape": {"type": "box", "size": [a, a, a]},
                    "mass_properties": {"density": FOAM["density"]},
                    "motion": {"type": "free"}, "angular_velocity": [1.0, 4.0, 0.5]},
                   pl, pr],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 1.0, "record_interval": 0.002,
                "channels": ["nodes", "bodies", "root_force", "energy", "contacts"]},
    }


def _detumble_presets() -> list[dict]:
    """The mission presets of issue 15 (``detumble_presets.py``, beside this file)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("detumble_presets",
                                                  HERE / "detumble_presets.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.all_detumble(SILICONE, PHI_SIL_SIL, seed_brush(), quat_axis_angle)


def all_presets() -> dict[str, dict]:
    scenes = [rod_weight_release(), rod_weight_static(), rod_tip_impulse(),
              rod_root_impulse(),
              *(wedge_scene(a) for a in (30, 45, 60, 75)),
              *(spin_cube(s) for s in (20, 40, 60)),
              momentum_two_brushes(), momentum_spheres_cube(),
              impact_scene(fur=True), impact_scene(fur=False), gripper(),
              *_detumble_presets()]
    return {s["name"]: s for s in scenes}


def render(scene: dict) -> str:
    return json.dumps(scene, indent=2) + "\n"


def main(argv: list[str]) -> int:
    check = "--check" in argv
    stale = []
    for name, scene in all_presets().items():
        path = HERE / f"{name}.json"
        text = render(scene)
        if check:
            if not path.exists() or path.read_text() != text:
                stale.append(path.name)
        else:
            path.write_text(text)
            print(f"wrote {path}")
    if stale:
        print("out of date (run python static_presets/generate.py): " + ", ".join(stale))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
