"""The micro-object trap (issue 27 item 4): a mm-sized glass bead fired into a sticky brush of
the seed's silicone bristles, the bristle-bead contact adhesive (``adhesion_force``: the pull-off
force per contact, docs/scene.md). Loaded by ``generate.py``; ``studio.studies.trap`` reads the
preset back and varies the speed, the adhesion and the pitch. SI units.

Layout the study relies on: a brush ``brush`` of ``GRID`` x ``GRID`` bristles growing along +z
from a base fixed in the world at z = ``ROOT_Z``, its tip plane (the tips' top) at
``tip_plane(brush)``; a free sphere ``bead`` whose surface starts ``START_GAP`` above the tip
plane, moving at ``ANGLE`` from -z in the x-z plane so that its centre crosses the tip plane at
(``AIM[0]`` pitch, ``AIM[1]`` pitch) from the brush's centre.
"""
from __future__ import annotations

import math

DEG = math.pi / 180.0
# a soda-lime glass bead (handbook values)
GLASS = {"youngs_modulus": 70e9, "poisson_ratio": 0.22, "density": 2500.0}
BEAD_RADIUS = 0.001            # m: a 2 mm bead, the size of coarse regolith or debris flakes
SPEED = 0.5                    # m/s: the preset's impact speed
ANGLE = 20 * DEG               # from the brush's axis: an oblique shot crosses bristles
AIM = (0.5, 0.25)              # where the centre crosses the tip plane, in pitches
START_GAP = 0.002              # m: the bead's surface above the tip plane at the start
# The sticky brush: 7 x 7 of the seed's silicone bristles (33 mm, conical 1.0 -> 0.5 mm
# radius) at a 3 mm pitch (the seed brush's), 10 % of critical damping in the bonds (as the
# detumble presets)
GRID, PITCH, N_NODES = 7, 0.003, 6
SILICONE_DAMPING = 0.1
ROOT_Z = 0.0                   # m: the base plane
# Silicone on glass: friction 30 deg and restitution 0.5 (assumptions, as the detumble
# presets' silicone on aluminium); pull-off force 1 mN per contact: a tacky silicone. The
# JKR pull-off 1.5 pi W R* of clean PDMS on glass (W ~ 0.05 J/m^2) at the contact's
# R* ~ 0.4 mm is about 0.1 mN; tacky silicone gels (W ~ 1 J/m^2) reach a few mN.
PHI_SIL_GLASS = 30 * DEG
RESTITUTION = 0.5
ADHESION = 0.001               # N per contact


def tip_plane(brush: dict) -> float:
    """z of the bristle tips' top (the base's z, the length and the tip's radius)."""
    return brush["base"]["position"][2] + brush["bristle_length"] + brush["tip_radius"]


def bead_start(tip_z: float, pitch: float, speed: float, angle: float = ANGLE,
               radius: float = BEAD_RADIUS) -> tuple[list, list]:
    """The bead's start position and velocity: its surface ``START_GAP`` above the tip plane,
    its centre crossing the tip plane at ``AIM`` (in pitches) along a line at ``angle`` from
    -z in the x-z plane."""
    z0 = tip_z + radius + START_GAP
    rise = z0 - tip_z
    x0 = AIM[0] * pitch - rise * math.tan(angle)
    return ([x0, AIM[1] * pitch, z0],
            [speed * math.sin(angle), 0.0, -speed * math.cos(angle)])


def duration(speed: float, length: float) -> float:
    """Simulated time: the bead crosses the brush's length 2.5 times at its impact speed (in,
    and out again if it rebounds), at least 40 ms, at most 3 s."""
    return min(3.0, max(0.04, 2.5 * (length + START_GAP) / speed))


def micro_trap(silicone: dict, phi_sil_sil: float, seed_brush) -> dict:
    brush = seed_brush(name="brush", n_nodes=N_NODES, rows=GRID, columns=GRID,
                       pitch=[PITCH, PITCH], base={"position": [0.0, 0.0, ROOT_Z]})
    tip_z = tip_plane(brush)
    pos, vel = bead_start(tip_z, PITCH, SPEED)
    t_end = duration(SPEED, brush["bristle_length"])
    mass_mg = GLASS["density"] * 4 / 3 * math.pi * BEAD_RADIUS ** 3 * 1e6
    desc = (
        "Issue 27 (item 4): the micro-object trap. A glass bead (radius "
        f"{BEAD_RADIUS * 1000:g} mm, E 70 GPa, 2500 kg/m^3, {mass_mg:.1f} mg) "
        f"fired at {SPEED:g} m/s, {ANGLE / DEG:g} deg from the brush's axis, into a sticky "
        f"brush of {GRID} x {GRID} of the seed's silicone bristles (33 mm, conical 1.0 -> 0.5 "
        f"mm radius, E 2.7 MPa, nu 0.48, 1700 kg/m^3, {SILICONE_DAMPING:g} of critical damping "
        f"in the bonds) at a {PITCH * 1000:g} mm pitch, the base fixed, in free space (no "
        "gravity; no backing plate: a bead that reaches the roots' plane has crossed the "
        "brush). The bead's surface starts "
        f"{START_GAP * 1000:g} mm above the tips; its centre crosses the tip plane between "
        "bristles near the brush's centre. Silicone-glass contact: friction "
        f"{PHI_SIL_GLASS / DEG:g} deg, restitution {RESTITUTION:g} (assumptions) and adhesion: "
        f"a pull-off force of {ADHESION * 1000:g} mN per contact (a tacky silicone; clean PDMS "
        "on glass is about 0.1 mN at this size, JKR), which acts once a contact unloads "
        "(docs/scene.md). Speeds of cm/s to a few m/s are what this elastic model covers; "
        "hypervelocity impacts (km/s) are outside it (material failure, shock, no "
        f"plasticity). Duration {t_end * 1000:g} ms, record interval 0.5 ms. study trap "
        "varies the speed, the adhesion and the pitch.")
    return {
        "schema_version": 1, "name": "micro_trap", "description": desc,
        "materials": {"silicone": dict(silicone, bond_damping=SILICONE_DAMPING),
                      "glass": GLASS},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": phi_sil_sil},
            {"materials": ["silicone", "glass"], "friction_angle": PHI_SIL_GLASS,
             "restitution": RESTITUTION, "adhesion_force": ADHESION}],
        "brushes": [brush],
        "bodies": [
            {"name": "bead", "material": "glass",
             "shape": {"type": "sphere", "radius": BEAD_RADIUS},
             "mass_properties": {"density": GLASS["density"]}, "motion": {"type": "free"},
             "pose": {"position": pos}, "velocity": vel}],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": t_end, "record_interval": 0.0005,
                "channels": ["nodes", "bodies", "energy", "contacts"]}}


def presets(silicone, phi_sil_sil, seed_brush) -> list[dict]:
    return [micro_trap(silicone, phi_sil_sil, seed_brush)]
