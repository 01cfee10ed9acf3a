"""Capture with a gripper brush on orbit (issue 27 item 2): a free chaser whose two jaws,
each carrying a brush, close on a tumbling target in the Hill frame. Loaded by
``generate.py`` (which writes the JSON file); ``studio.studies.capture`` reads the preset
back and varies it. SI units.

What the engine can and cannot represent. It has no joint between two bodies: a brush
``mount``ed on a body is rigid on it, a ``hinge`` turns about an axis fixed in the world, and
a ``kinematic`` body follows a path in the world (Hill) frame. So a jaw that slides on a free
chaser is modelled as a free body of its own (``jaw_left``, ``jaw_right``, each carrying a
brush) driven by a servo: a pose controller whose target is an offset from the chaser's
centre (``reference: chaser``), i.e. a jaw actuator with stiffness kp, damping kd and a force
limit. The servo's force acts on the jaw alone; its reaction is NOT applied to the chaser
(the engine's controllers are thrusters). The study reports that reaction, minus the sum of
the jaws' recorded actuator forces and torques, as the load the chaser's jaw mounts would
carry; the chaser itself is a free body held at its station by its own controller, and the
target's relative motion is measured against it.

Layout the study relies on: free bodies ``target`` (at the Hill origin, spinning),
``chaser`` (``collide: false``, along -y from the target), ``jaw_left`` / ``jaw_right``
(``collide: false``: only their bristles touch, on either side of the target along x);
brushes ``brush_left`` / ``brush_right`` mounted on the jaws, bristles along +x / -x;
controllers ``jaw_left_servo``, ``jaw_right_servo`` (reference chaser) and
``chaser_control`` (holds the chaser at its start in the Hill frame).
"""
from __future__ import annotations

import math

ORBIT_ALTITUDE = 400e3         # m, as the detumble presets
DEG = math.pi / 180.0
ALUMINIUM = {"youngs_modulus": 70e9, "poisson_ratio": 0.33, "density": 2700.0}
PHI_SIL_AL = 30 * DEG          # silicone-aluminium, as the detumble and docking presets
TIP_RESTITUTION = 0.5          # silicone tips on aluminium, as the detumble presets
SILICONE_DAMPING = 0.1         # of critical, in the bristles' bonds, as the detumble presets

# The target: a 1U CubeSat, a 0.1 m aluminium cube of 1.33 kg (the CubeSat standard's
# largest 1U mass; uniform inertia m a^2 / 6), tumbling at 10 deg/s about (1, 1, 1)/sqrt 3
TARGET = {"size": 0.1, "mass": 1.33, "spin": 10 * DEG, "axis": (1.0, 1.0, 1.0)}
# The chaser: a 0.2 m cube of 12 kg (the docking preset's craft), its +y face GAP_Y from the
# target's -y face; held at its start by a PD controller (assumed gains)
CHASER = {"size": 0.2, "mass": 12.0, "kp": 50.0, "kpa": 5.0, "sample_interval": 0.01,
          "max_force": 2.0, "max_torque": 0.5}
GAP_Y = 0.02
# The jaws: aluminium plates 60 x 60 x 5 mm of 0.5 kg (plate and finger mechanism, an
# assumption) either side of the target along x; the brushes are the detumble presets'
# silicone bristles (the seed's scaled up BRUSH_SCALE times: 165 mm, 10 -> 5 mm diameter),
# 3 x 3 at 20 mm pitch on each jaw
BRUSH_SCALE = 5.0
JAW = {"size": (0.005, 0.06, 0.06), "mass": 0.5}
GRID, PITCH, N_NODES = 3, 0.02, 4
# The jaws start with the undeformed tips OPEN_GAP outside the target's faces and close to
# where they would reach INTERFERENCE inside them. Their servos (assumed values, chosen by
# trial, docs/mission.md): kp / kd = 4/s sets the closing (overdamped, damping ratio 2.5;
# kd h / m = 0.2 keeps the sampled loop stable); max_force 0.2 N caps the squeeze below the
# 9 bristles' Euler buckling load as fixed-free columns (pi^2 E I / (4 L^2) with the mean
# radius: about 0.04 N each, 0.34 N); the attitude loop is a soft, damped wrist (kpa 0.01 N m/rad,
# kda 0.03 N m s/rad) that lets a jaw tilt with the target and damps its rocking. Measured
# at 10 deg/s: a stiff wrist (kpa 2, kda 0.1) or a 2 N squeeze left the target spinning
# at 15-20 deg/s after 2-3 s (the squeezed, tilted cube rocks on the bristles as on a
# spring, and buckling bristles pump it); this one took it to 0.2 deg/s at 2.75 s, after
# which the wound bristles sprang it back (4.4 deg/s at 4 s: docs/mission.md)
OPEN_GAP = 0.02
INTERFERENCE = 0.005
JAW_SERVO = {"kp": 200.0, "kd": 50.0, "max_force": 0.2, "kpa": 0.01, "kda": 0.03,
             "max_torque": 0.2, "sample_interval": 0.002}
DURATION, RECORD_INTERVAL = 4.0, 0.01


def _box_inertia(mass, size):
    sx, sy, sz = size
    return [[mass * (sy * sy + sz * sz) / 12, 0, 0], [0, mass * (sx * sx + sz * sz) / 12, 0],
            [0, 0, mass * (sx * sx + sy * sy) / 12]]


def _unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def jaw_offsets(brush_reach: float):
    """(open, closed) x of the right jaw's centre from the target's centre (the left jaw's
    are their negatives): tips OPEN_GAP outside, or INTERFERENCE inside, the face."""
    a = TARGET["size"] / 2
    base_to_centre = JAW["size"][0] / 2 + brush_reach
    return a + OPEN_GAP + base_to_centre, a - INTERFERENCE + base_to_centre


def capture_orbit(silicone: dict, phi_sil_sil: float, seed_brush, q_z_to_plus_x,
                  q_z_to_minus_x) -> dict:
    s = BRUSH_SCALE
    proto = seed_brush()
    length, r_root, r_tip = (proto["bristle_length"] * s, proto["root_radius"] * s,
                             proto["tip_radius"] * s)
    reach = length + r_tip
    x_open, x_closed = jaw_offsets(reach)
    a_t, a_c = TARGET["size"], CHASER["size"]
    y_chaser = -(a_t / 2 + GAP_Y + a_c / 2)
    m_t = TARGET["mass"]
    i_t = m_t * a_t ** 2 / 6
    omega = [TARGET["spin"] * c for c in _unit(TARGET["axis"])]
    sv = JAW_SERVO
    brushes, bodies, controllers = [], [], []
    for side, sign, q in (("left", -1.0, q_z_to_plus_x), ("right", 1.0, q_z_to_minus_x)):
        # the brush base on the jaw's face toward the target, bristles along -sign x
        brushes.append(seed_brush(
            name=f"brush_{side}", n_nodes=N_NODES, mount=f"jaw_{side}", rows=GRID,
            columns=GRID, pitch=[PITCH, PITCH], bristle_length=length, root_radius=r_root,
            tip_radius=r_tip,
            base={"position": [-sign * JAW["size"][0] / 2, 0.0, 0.0], "orientation": q}))
        bodies.append({"name": f"jaw_{side}", "material": "aluminium",
                       "shape": {"type": "box", "size": list(JAW["size"])},
                       "mass_properties": {"mass": JAW["mass"],
                                           "inertia": _box_inertia(JAW["mass"], JAW["size"])},
                       "motion": {"type": "free"},
                       "pose": {"position": [sign * x_open, 0.0, 0.0]}, "collide": False})
        controllers.append({
            "name": f"jaw_{side}_servo", "body": f"jaw_{side}", "reference": "chaser",
            "position": [sign * x_closed, -y_chaser, 0.0],
            "sample_interval": sv["sample_interval"],
            "position_gains": {"proportional": sv["kp"], "derivative": sv["kd"]},
            "attitude_gains": {"proportional": sv["kpa"], "derivative": sv["kda"]},
            "max_force": [sv["max_force"]] * 3, "max_torque": [sv["max_torque"]] * 3})
    c = CHASER
    i_c = c["mass"] * a_c ** 2 / 6
    controllers.append({
        "name": "chaser_control", "body": "chaser", "position": [0.0, y_chaser, 0.0],
        "sample_interval": c["sample_interval"],
        "position_gains": {"proportional": c["kp"],
                           "derivative": 2 * math.sqrt(c["kp"] * c["mass"])},
        "attitude_gains": {"proportional": c["kpa"],
                           "derivative": 2 * math.sqrt(c["kpa"] * i_c)},
        "max_force": [c["max_force"]] * 3, "max_torque": [c["max_torque"]] * 3})
    bodies = [{"name": "target", "material": "aluminium",
               "shape": {"type": "box", "size": [a_t, a_t, a_t]},
               "mass_properties": {"mass": m_t,
                                   "inertia": [[i_t, 0, 0], [0, i_t, 0], [0, 0, i_t]]},
               "motion": {"type": "free"}, "angular_velocity": omega},
              {"name": "chaser", "material": "aluminium",
               "shape": {"type": "box", "size": [a_c, a_c, a_c]},
               "mass_properties": {"mass": c["mass"],
                                   "inertia": [[i_c, 0, 0], [0, i_c, 0], [0, 0, i_c]]},
               "motion": {"type": "free"}, "pose": {"position": [0.0, y_chaser, 0.0]},
               "collide": False},
              *bodies]
    desc = (
        "Seed chapter 5 (5.3.2 'Gripper brush', fig. 5.2) taken to orbit, as issue 27 item 2 "
        "asks: a chaser's two brush jaws close on a tumbling target in the Hill frame of a "
        f"{ORBIT_ALTITUDE / 1e3:g} km circular orbit (Clohessy-Wiltshire; x radial, y "
        "along-track, z orbit normal; gravity-gradient torque on). Target (target): a 1U "
        f"CubeSat, a {a_t * 1e3:g} mm aluminium cube of {m_t:g} kg (uniform inertia "
        f"{i_t:.3g} kg m^2), at the origin, tumbling at {TARGET['spin'] / DEG:g} deg/s about "
        f"(1, 1, 1)/sqrt 3 (assumed). Chaser (chaser): a {a_c:g} m aluminium cube of "
        f"{c['mass']:g} kg, collide false, its +y face {GAP_Y * 1e3:g} mm behind the target "
        "along -y, held at its start by chaser_control (PD, critically damped, kp "
        f"{c['kp']:g} N/m, {1 / c['sample_interval']:g} Hz, {c['max_force']:g} N per axis; "
        "assumed). Jaws (jaw_left, jaw_right): aluminium plates "
        f"{JAW['size'][1] * 1e3:g} x {JAW['size'][2] * 1e3:g} x {JAW['size'][0] * 1e3:g} mm "
        f"of {JAW['mass']:g} kg (plate and finger, assumed), collide false, either side of "
        f"the target along x, each carrying a {GRID} x {GRID} brush (brush_left, "
        f"brush_right) at {PITCH * 1e3:g} mm pitch of the detumble presets' bristles: the "
        f"seed's silicone (E 2.7 MPa, nu 0.48, 1700 kg/m^3) scaled {BRUSH_SCALE:g} times, "
        f"{length * 1e3:g} mm, conical {2 * r_root * 1e3:g} -> {2 * r_tip * 1e3:g} mm "
        f"diameter, {N_NODES} nodes, bond damping {SILICONE_DAMPING:g} of critical; "
        f"friction silicone-aluminium {PHI_SIL_AL / DEG:g} deg, restitution "
        f"{TIP_RESTITUTION:g} (as the detumble presets). The jaws start with the tips "
        f"{OPEN_GAP * 1e3:g} mm outside the target's faces and close to where the "
        f"undeformed tips would reach {INTERFERENCE * 1e3:g} mm inside them. NOT modelled: "
        "a jaw sliding on the chaser (the engine has no joint between bodies). Each jaw is "
        "a free body driven by a servo (jaw_left_servo, jaw_right_servo: a pose controller "
        "whose target is an offset from the chaser's centre; kp "
        f"{sv['kp']:g} N/m, kd {sv['kd']:g} N s/m, {sv['max_force']:g} N per axis, attitude "
        f"kp {sv['kpa']:g} N m/rad, kd {sv['kda']:g} N m s/rad, "
        f"{1 / sv['sample_interval']:g} Hz; assumed): the servo's force acts on the jaw "
        "alone and its reaction is NOT applied to the chaser; study capture reports it "
        "(minus the jaws' actuator forces and torques) as the load on the chaser's jaw "
        f"mounts. Duration {DURATION:g} s, record interval {RECORD_INTERVAL * 1e3:g} ms. "
        "Study: brush-studio study capture (docs/mission.md).")
    return {
        "schema_version": 1, "name": "gripper_capture_orbit", "description": desc,
        "materials": {"silicone": dict(silicone, bond_damping=SILICONE_DAMPING),
                      "aluminium": ALUMINIUM},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": phi_sil_sil},
            {"materials": ["silicone", "aluminium"], "friction_angle": PHI_SIL_AL,
             "restitution": TIP_RESTITUTION}],
        "brushes": brushes, "bodies": bodies, "controllers": controllers,
        "environment": {"orbit": {"altitude": ORBIT_ALTITUDE, "gravity_gradient": True}},
        "run": {"duration": DURATION, "record_interval": RECORD_INTERVAL,
                "channels": ["nodes", "bodies", "root_force", "energy", "contacts"]}}


def presets(silicone, phi_sil_sil, seed_brush, q_z_to_plus_x, q_z_to_minus_x) -> list[dict]:
    return [capture_orbit(silicone, phi_sil_sil, seed_brush, q_z_to_plus_x, q_z_to_minus_x)]
