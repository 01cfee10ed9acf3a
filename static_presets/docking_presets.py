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

# Two small spacecraft of 12 kg (uniform inertia): the chaser a 0.2 m cube, the target a
# 0.2 x 0.3 x 0.3 m box whose docking face is larger than the chaser's (two equal faces
# meeting exactly edge on edge would touch only where a vertex lies on the other's
# boundary, which the vertex-in-body contact does not count: docs/scene.md)
CRAFT = {"size": 0.2, "mass": 12.0}
TARGET_SIZE = [0.2, 0.3, 0.3]
CLOSING_SPEED = 0.03           # m/s, a gentle docking
START_GAP = 0.005              # m: brush tips (or the bare hull) this far from the target
RIGID_GAP = 0.0001             # m
# The interface: 9 x 9 of the seed's silicone bristles (33 mm, conical 1.0 -> 0.5 mm) at an
# 8 mm pitch (64 mm square); 10 % of critical damping in the bristles, as the detumble
# presets
GRID, PITCH, N_NODES = 9, 0.008, 6
SILICONE_DAMPING = 0.1


def _body(name, x, velocity=None, collide=True, size=None):
    m = CRAFT["mass"]
    sx, sy, sz = size or [CRAFT["size"]] * 3
    ix, iy, iz = (m * (sy * sy + sz * sz) / 12, m * (sx * sx + sz * sz) / 12,
                  m * (sx * sx + sy * sy) / 12)
    body = {"name": name, "material": "aluminium",
            "shape": {"type": "box", "size": [sx, sy, sz]},
            "mass_properties": {"mass": m, "inertia": [[ix, 0, 0], [0, iy, 0], [0, 0, iz]]},
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
    target_x = a / 2 + reach + START_GAP + TARGET_SIZE[0] / 2
    desc = (
        "Seed chapter 5 (5.3.2): brush-assisted docking, as issue 27 asks. Two small "
        f"spacecraft of {CRAFT['mass']:g} kg each (uniform inertia; assumptions): the chaser "
        f"a {a:g} m aluminium cube, the target a {TARGET_SIZE[0]:g} x {TARGET_SIZE[1]:g} x "
        f"{TARGET_SIZE[2]:g} m aluminium box, in free space: the chaser (chaser) closes on the target (target, at "
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
                   _body("target", target_x, size=TARGET_SIZE)],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 2.0, "record_interval": 0.002,
                "channels": ["nodes", "bodies", "root_force", "energy", "contacts"]}}


def docking_rigid() -> dict:
    a = CRAFT["size"]
    desc = (
        "Seed chapter 5 (5.3.2): the reference of docking.json, the same docking without "
        f"the brush. The same two aluminium craft of {CRAFT['mass']:g} kg in free space; the "
        f"chaser (chaser) closes at {CLOSING_SPEED * 1000:g} mm/s along +x on the target "
        f"(target, at rest), face to face, {RIGID_GAP * 1000:g} mm apart at the start. "
        f"Hull contact on: aluminium-aluminium friction {PHI_AL_AL / DEG:g} deg, "
        f"restitution {RIGID_RESTITUTION:g} (assumptions): head on, the chaser and target "
        "separate at 0.5 times the closing speed. Duration 6 ms (the hit at 3.3 ms lasts about "
        "0.1 ms), record interval 5 us.")
    return {
        "schema_version": 1, "name": "docking_rigid", "description": desc,
        "materials": {"aluminium": ALUMINIUM},
        "contact_pairs": [{"materials": ["aluminium", "aluminium"],
                           "friction_angle": PHI_AL_AL, "restitution": RIGID_RESTITUTION}],
        "bodies": [_body("chaser", 0.0, CLOSING_SPEED),
                   _body("target", a / 2 + RIGID_GAP + TARGET_SIZE[0] / 2,
                         size=TARGET_SIZE)],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 0.006, "record_interval": 5e-6,
                "channels": ["bodies", "energy", "contacts"]}}


def presets(silicone, phi_sil_sil, seed_brush, q_z_to_plus_x) -> list[dict]:
    return [docking(silicone, phi_sil_sil, seed_brush, q_z_to_plus_x), docking_rigid()]
