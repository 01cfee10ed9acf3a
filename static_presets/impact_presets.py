"""The chapter 5 presets: a steel sphere fired at a plate with and without steel fur, and the
two-brush gripper. Loaded by ``generate.py``, which writes the JSON files; SI units."""
from __future__ import annotations

import math

from seed_values import (DEG, STEEL, SILICONE, PLA, FOAM, PHI_SIL_SIL, PHI_SIL_FOAM,
                         BRISTLE_LENGTH, TIP_RADIUS, Q_Z_TO_PLUS_X, Q_Z_TO_MINUS_X, seed_brush,
                         cube_mass)

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


def presets() -> list[dict]:
    return [impact_scene(fur=True), impact_scene(fur=False), gripper()]
