"""The wedge presets (seed 4.2): the seed's brush pressed by a PLA wedge of 30, 45, 60 and 75
deg in 1 mm steps and back out. Loaded by ``generate.py``, which writes the JSON files; SI
units."""
from __future__ import annotations

import math

from seed_values import (DEG, SILICONE, PLA, PHI_SIL_SIL, PHI_SIL_PLA, BRISTLE_LENGTH,
                         TIP_RADIUS, seed_brush)

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


def presets() -> list[dict]:
    return [wedge_scene(a) for a in (30, 45, 60, 75)]
