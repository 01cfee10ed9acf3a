"""Brush-assisted docking (seed 5.3.2, issue 27): two small spacecraft close along x, the
chaser carrying a silicone brush on its docking face; and the same docking without the
brush, hull on hull (the reference). Loaded by ``generate.py``; ``studio.studies.docking``
reads the presets back and varies them. SI units.

Layout the study relies on: free bodies ``chaser`` (at the origin side, moving +x) and
``target`` (at rest); in ``docking`` the brush ``brush`` is mounted on the chaser's +x face
(``mount: chaser``) with its tips ``START_GAP`` from the target's face, and hull contact is
off (``collide: false`` on the chaser: aluminium on aluminium would cut the time step about
tenfold; the study reports the closest hull gap instead, and a brush that lets the hulls
meet has bottomed out). In ``docking_rigid`` the hulls touch after ``RIGID_GAP``, with the
pair's coefficient of restitution ``RIGID_RESTITUTION``.
"""
from __future__ import annotations

import math

ALUMINIUM = {"youngs_modulus": 70e9, "poisson_ratio": 0.33, "density": 2700.0}
DEG = math.pi / 180.0
PHI_SIL_AL = 30 * DEG          # as the detumble presets (an assumption)
PHI_AL_AL = 40 * DEG           # dry aluminium on aluminium (an assumption)
RIGID_RESTITUTION = 0.5        # hull on hull (an assumption)
TIP_RESTITUTION = 0.5          # silicone tips on aluminium, as the detumble presets

# Two 12U-class spacecraft: 0.2 m aluminium cubes of 12 kg (uniform: I = m a^2 / 6)
CRAFT = {"size": 0.2, "mass": 12.0}
CLOSING_SPEED = 0.03           # m/s, a gentle docking
START_GAP = 0.005              # m: brush tips (or the bare hull) this far from the target
RIGID_GAP = 0.001              # m
# The interface: 9 x 9 of the seed's silicone bristles (33 mm, conical 1.0 -> 0.5 mm) at an
# 8 mm pitch (64 mm square); 10 % of critical damping in the bristles, as the detumble
# presets
GRID, PITCH, N_NODES = 9, 0.008, 6
SILICONE_DAMPING = 0.1


def _body(name, x, velocity=None, collide=True):
    a, m = CRAFT["size"], CRAFT["mass"]
    i = m * a * a / 6.0
    body = {"name": name, "material": "aluminium", "shape": {"type": "box", "size": [a, a, a]},
            "mass_properties": {"mass": m, "inertia": [[i, 0, 0], [0, i, 0], [0, 0, i]]},
            "motion": {"type": "free"}, "pose": {"position": [x, 0.0, 0.0]},
            "collide": collide}
    if velocity is not None:
        body["velocity"] = [velocity, 0.0, 0.0]
    return body


def docking(silicone: dict, phi_sil_sil: float, seed_brush, q_z_to_plus_x) -> dict:
    a = CRAFT["size"]
    brush = seed_brush(name="brush", n_nodes=N_NODES, mount="chaser", rows=GRID, columns=GRID,
                       pitch=[PITCH, PITCH],
                       base={"position": [a / 2, 0.0, 0.0], "orientation": q_z_to_plus_x})
    reach = brush["bristle_length"] + brush["tip_radius"]   # base plane to the tip's surface
    target_x = a / 2 + reach + START_GAP + a / 2
    desc = (
        "Seed chapter 5 (5.3.2): brush-assisted docking, as issue 27 asks. Two 12U-class "
        f"spacecraft, {a:g} m aluminium cubes of {CRAFT['mass']:g} kg each (uniform inertia; "
        "assumptions), in free space: the chaser (chaser) closes on the target (target, at "
        f"rest) at {CLOSING_SPEED * 1000:g} mm/s along +x. On the chaser's +x face a "
        f"{GRID} x {GRID} brush (brush) of the seed's silicone bristles (33 mm, conical 1.0 -> "
        f"0.5 mm radius, E 2.7 MPa, nu 0.48, 1700 kg/m^3, {SILICONE_DAMPING:g} of critical "
        f"damping in the bonds) at {PITCH * 1000:g} mm pitch; its tips start "
        f"{START_GAP * 1000:g} mm from the target's face. Silicone-aluminium friction "
        f"{PHI_SIL_AL / DEG:g} deg and restitution {TIP_RESTITUTION:g} (as the detumble "
        "presets). Hull contact is off (chaser collide false): aluminium on aluminium would "
        "cut the time step about tenfold; study docking reports the closest hull gap and "
        "says when the brush bottomed out. docking_rigid is the same docking without the "
        "brush. Duration 2 s, record interval 2 ms.")
    return {
        "schema_version": 1, "name": "docking", "description": desc,
        "materials": {"silicone": dict(silicone, bond_damping=SILICONE_DAMPING),
                      "aluminium": ALUMINIUM},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": phi_sil_sil},
            {"materials": ["silicone", "aluminium"], "friction_angle": PHI_SIL_AL,
             "restitution": TIP_RESTITUTION}],
        "brushes": [brush],
        "bodies": [_body("chaser", 0.0, CLOSING_SPEED, collide=False),
                   _body("target", target_x)],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 2.0, "record_interval": 0.002,
                "channels": ["nodes", "bodies", "root_force", "energy", "contacts"]}}


def docking_rigid() -> dict:
    a = CRAFT["size"]
    desc = (
        "Seed chapter 5 (5.3.2): the reference of docking.json, the same docking without "
        f"the brush. Two {a:g} m aluminium cubes of {CRAFT['mass']:g} kg in free space; the "
        f"chaser (chaser) closes at {CLOSING_SPEED * 1000:g} mm/s along +x on the target "
        f"(target, at rest), face to face, {RIGID_GAP * 1000:g} mm apart at the start. "
        f"Hull contact on: aluminium-aluminium friction {PHI_AL_AL / DEG:g} deg, "
        f"restitution {RIGID_RESTITUTION:g} (assumptions): head on, the chaser and target "
        "separate at 0.5 times the closing speed. Duration 0.1 s, record interval 0.2 ms.")
    return {
        "schema_version": 1, "name": "docking_rigid", "description": desc,
        "materials": {"aluminium": ALUMINIUM},
        "contact_pairs": [{"materials": ["aluminium", "aluminium"],
                           "friction_angle": PHI_AL_AL, "restitution": RIGID_RESTITUTION}],
        "bodies": [_body("chaser", 0.0, CLOSING_SPEED),
                   _body("target", a + RIGID_GAP)],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 0.1, "record_interval": 0.0002,
                "channels": ["bodies", "energy", "contacts"]}}


def presets(silicone, phi_sil_sil, seed_brush, q_z_to_plus_x) -> list[dict]:
    return [docking(silicone, phi_sil_sil, seed_brush, q_z_to_plus_x), docking_rigid()]
