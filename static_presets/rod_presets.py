"""The rod presets (seed 4.1): the steel cantilever of table 4.1 under a tip weight (released,
and static) and a tip or root impulse. Loaded by ``generate.py``, which writes the JSON
files; SI units."""
from __future__ import annotations

import math

from seed_values import STEEL, Q_Z_TO_PLUS_X

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


def presets() -> list[dict]:
    return [rod_weight_release(), rod_weight_static(), rod_tip_impulse(), rod_root_impulse()]
