"""The detumble presets (issue 15): a chaser holds a brush against a spinning target in low
Earth orbit. Loaded by ``generate.py`` (which writes the JSON files); ``studio.studies.
detumble`` reads the presets back and varies them.

Both scenes share one layout, which the study relies on: a free body ``target`` spinning
about a principal axis, a free body ``chaser`` (``collide: false``: hull contact is left
off, see ``HULL_CONTACT``) carrying the brush ``brush`` (``mount: chaser``), and the controller
``chaser_control`` holding the chaser at a fixed offset from the target's centre (world
axes) and at a fixed attitude. The brush's bristles point from the chaser at the target
along the offset's direction; at the held offset the undeformed bristle tips would reach
``INTERFERENCE`` inside the target's surface, and the chaser starts ``START_GAP`` + that
farther out (the approach). SI units.
"""
from __future__ import annotations

import math

ORBIT_ALTITUDE = 400e3        # m: a 400 km circular orbit (n = 1.131e-3 rad/s)
INTERFERENCE = 0.03           # m: held bristle-tip interference with the surface
START_GAP = 0.01              # m: tips outside the surface at the start
DEG = math.pi / 180.0

# The brush: the seed's 17 x 5 silicone brush scaled up five times (bristles 165 mm,
# conical 10 -> 5 mm diameter, 15 mm pitch): geometric scaling keeps the bristles' strains
# and bending stresses at the seed's for the same relative deflection.
BRUSH_SCALE = 5.0
ALUMINIUM = {"youngs_modulus": 70e9, "poisson_ratio": 0.33, "density": 2700.0}
PHI_SIL_AL = 30 * DEG         # silicone-aluminium: between the seed's silicone-PLA 24 deg
#                               and silicone-foam 36 deg (an assumption)

# The chaser: a 1 m cube of 300 kg (uniform: I = m a^2 / 6 = 50 kg m^2), 10 Hz control,
# 10 N per axis of thrust and 2 N m per axis of torque (assumptions)
CHASER = {"size": 1.0, "mass": 300.0, "sample_interval": 0.1, "max_force": 10.0,
          "max_torque": 2.0, "kp": 600.0, "ki": 100.0, "kpa": 50.0}
# silicone is lossy: 10 % of critical damping in the bristles and a coefficient of
# restitution 0.5 against the target (assumptions; elastic, the tips bounce off the face)
SILICONE_DAMPING = 0.1
RESTITUTION = 0.5
# Hull contact (issue 15 item 2) is off: the held offset keeps the chaser's face
# reach - INTERFERENCE = 137.5 mm from the target's surface, and turning it on (chaser
# collide true, the target sampled at 0.1 m) cuts the automatic time step from 8.8e-5 s to
# 8.1e-6 s (upper stage) and 5.3e-6 s (box satellite): the aluminium-aluminium contact
# stiffness against the target's rotational inertia (measured: docs/mission.md)
HULL_CONTACT = False
# Letting go (issue 15 item 1): the controller's release rule backs the chaser off by RETREAT
# along the approach axis once the target is slow; 0.1 m is three times the held
# interference, so the undeformed tips end 70 mm clear of the surface
RETREAT = 0.1                 # m


def _chaser_gains():
    c = CHASER
    inertia = c["mass"] * c["size"] ** 2 / 6.0
    # critically damped loops (kd = 2 sqrt(kp m)); the integral term is Routh-stable as
    # kd kp > ki m (509 000 > 30 000); w_n h = 0.14 rad at 10 Hz sampling
    return ({"proportional": c["kp"], "derivative": 2 * math.sqrt(c["kp"] * c["mass"]),
             "integral": c["ki"]},
            {"proportional": c["kpa"], "derivative": 2 * math.sqrt(c["kpa"] * inertia)},
            inertia)


def _brush(silicone_brush: dict, base: dict, n_nodes: int) -> dict:
    b = dict(silicone_brush)
    s = BRUSH_SCALE
    b.update(pitch=[b["pitch"][0] * s, b["pitch"][1] * s],
             bristle_length=b["bristle_length"] * s, root_radius=b["root_radius"] * s,
             tip_radius=b["tip_radius"] * s, n_nodes=n_nodes, mount="chaser", base=base)
    return b


def _scene(name, what, target, brushes, axis, surface, controller_extra, silicone,
           phi_sil_sil, n_nodes, duration, stop_fraction, omega0, tilt=0.0):
    """The shared layout: ``axis`` the unit approach direction (target -> chaser),
    ``surface`` the target's surface distance from its centre along it; ``what`` the
    description's part about this target (the rest is the same for every preset)."""
    desc = ("Seed chapter 5 ('Test brush in mission simulations', no figure: the thesis "
            "recommends this simulation) and issue 15: a chaser detumbles " + what +
            _common_text(brushes[0], n_nodes, duration, stop_fraction))
    materials, pairs = _materials(silicone, phi_sil_sil)
    pos_gains, att_gains, inertia = _chaser_gains()
    a = CHASER["size"]
    brush = brushes[0]                                        # all of one design
    # base -> tip end along the approach axis (bristles leaning by `tilt` from it)
    reach = brush["bristle_length"] * math.cos(tilt) + brush["tip_radius"]
    hold = surface - INTERFERENCE + reach + a / 2
    start = surface + START_GAP + reach + a / 2
    ctl = {"name": "chaser_control", "body": "chaser", "reference": "target",
           "position": [hold * x for x in axis], "sample_interval": CHASER["sample_interval"],
           "position_gains": pos_gains, "attitude_gains": att_gains,
           "max_force": [CHASER["max_force"]] * 3, "max_torque": [CHASER["max_torque"]] * 3}
    ctl.update(controller_extra)
    chaser = {"name": "chaser", "material": "aluminium",
              "shape": {"type": "box", "size": [a, a, a]},
              "mass_properties": {"mass": CHASER["mass"],
                                  "inertia": [[inertia, 0, 0], [0, inertia, 0],
                                              [0, 0, inertia]]},
              "motion": {"type": "free"}, "pose": {"position": [start * x for x in axis]},
              "collide": HULL_CONTACT}
    return {
        "schema_version": 1, "name": name, "description": desc,
        "materials": materials, "contact_pairs": pairs, "brushes": brushes,
        "bodies": [target, chaser], "controllers": [ctl],
        "environment": {"orbit": {"altitude": ORBIT_ALTITUDE, "gravity_gradient": True}},
        "run": {"duration": duration, "record_interval": 0.02,
                "channels": ["nodes", "bodies", "root_force", "energy", "contacts",
                             "bending"],
                "stop": {"quantity": "body_angular_speed", "body": "target",
                         "value": stop_fraction * omega0, "hold": 1.0, "min_time": 1.0}}}


def _materials(silicone: dict, phi_sil_sil: float):
    materials = {"silicone": dict(silicone, bond_damping=SILICONE_DAMPING),
                 "aluminium": ALUMINIUM}
    pairs = [{"materials": ["silicone", "silicone"], "friction_angle": phi_sil_sil},
             {"materials": ["silicone", "aluminium"], "friction_angle": PHI_SIL_AL,
              "restitution": RESTITUTION}]
    return materials, pairs


def _common_text(brush, n_nodes, duration, stop_fraction):
    a = CHASER["size"]
    pos_gains, att_gains, inertia = _chaser_gains()
    return (
        f"Brushes: the seed's 17 x 5 silicone brush (seed 4.2: E 2.7 MPa, nu 0.48, "
        f"1700 kg/m^3) scaled up {BRUSH_SCALE:g} times, an assumption (geometric scaling "
        f"keeps the seed's strains for the same relative deflection): bristles "
        f"{brush['bristle_length'] * 1e3:g} mm, conical {2 * brush['root_radius'] * 1e3:g} "
        f"-> {2 * brush['tip_radius'] * 1e3:g} mm diameter, {brush['pitch'][0] * 1e3:g} mm "
        f"pitch, bond damping {SILICONE_DAMPING:g} of critical (assumed: silicone is "
        f"lossy). Friction silicone-aluminium {PHI_SIL_AL / DEG:g} deg (assumed, between "
        f"the seed's silicone-PLA 24 deg and silicone-foam 36 deg), silicone-silicone 44 deg "
        f"(seed 4.2); coefficient of restitution silicone-aluminium {RESTITUTION:g} "
        f"(assumed), silicone-silicone 1. Chaser (chaser): a "
        f"{a:g} m aluminium box of {CHASER['mass']:g} kg (uniform inertia {inertia:g} kg "
        f"m^2), collide false (hull contact off: the held offset keeps its face "
        f"{(brush['bristle_length'] + brush['tip_radius'] - INTERFERENCE) * 1e3:g} mm "
        f"clear of the target, and the aluminium hulls' contact stiffness would cut the "
        f"time step 11 to 17 times), carrying the brush on its face toward "
        f"the target. Controller chaser_control (assumed values): holds the chaser at a "
        f"fixed offset from the target's centre (world axes) where the undeformed bristle "
        f"tips would reach {INTERFERENCE * 1e3:g} mm inside the target's surface, and at "
        f"its initial attitude; PID kp {pos_gains['proportional']:g} N/m, kd "
        f"{pos_gains['derivative']:.1f} N s/m (critical), ki {pos_gains['integral']:g} "
        f"N/(m s); attitude kp {att_gains['proportional']:g} N m/rad, kd "
        f"{att_gains['derivative']:g} N m s/rad; sampled at "
        f"{1 / CHASER['sample_interval']:g} Hz; thrust saturated at "
        f"{CHASER['max_force']:g} N and torque at {CHASER['max_torque']:g} N m per body "
        f"axis. The chaser starts with the tips {START_GAP * 1e3:g} mm outside the surface "
        f"and approaches. Orbit: circular, {ORBIT_ALTITUDE / 1e3:g} km (Clohessy-Wiltshire "
        f"Hill frame: x radial, y along-track, z orbit normal), gravity-gradient torque on. "
        f"Resolution: {n_nodes} nodes per bristle, duration {duration:g} s, record interval "
        f"20 ms; the run stops once the target's |omega| stays below "
        f"{stop_fraction:g} of its initial value for 1 s. Study: brush-studio study "
        f"detumble (docs/mission.md).")


def upper_stage(silicone: dict, phi_sil_sil: float, seed_brush: dict, quat_axis_angle):
    """A spent cylindrical kick stage spinning about its axis; the brush rubs its side."""
    radius, length, mass = 0.62, 1.4, 130.0
    omega0 = 10 * DEG
    i_axis = mass * radius ** 2                              # thin-walled shell
    i_trans = mass * (radius ** 2 / 2 + length ** 2 / 12)
    n_nodes, duration, stop_fraction = 5, 20.0, 0.05
    # chaser radially above (+x), bristles along -x; the 17-bristle rows along the stage's
    # axis (z, base local x), 5 of them around it (y): the side is straight along z, so
    # every bristle reaches it (across it, 5 rows span 60 mm: 0.7 mm of curvature)
    base = {"position": [-CHASER["size"] / 2, 0.0, 0.0],
            "orientation": quat_axis_angle([0, 1, 0], -math.pi / 2)}
    brush = _brush(seed_brush, base, n_nodes)
    brush.update(rows=5, columns=17)
    target = {"name": "target", "material": "aluminium",
              "shape": {"type": "cylinder", "radius": radius, "height": length,
                        "sections": 64},
              "mass_properties": {"mass": mass, "inertia": [[i_trans, 0, 0], [0, i_trans, 0],
                                                            [0, 0, i_axis]]},
              "motion": {"type": "free"}, "angular_velocity": [0.0, 0.0, omega0]}
    what = (
        "a spent cylindrical "
        f"upper stage with its brush. Target (target): an assumed kick-stage case of the "
        f"size of a Star-48-class motor, a thin-walled aluminium cylinder {2 * radius:g} m "
        f"in diameter and {length:g} m long (nozzle left out), {mass:g} kg, inertia "
        f"{i_axis:.1f} kg m^2 about its axis (m r^2) and {i_trans:.1f} kg m^2 across it "
        f"(m (r^2/2 + l^2/12): the axis is the major axis, so the spin is stable), axis "
        f"along the orbit normal z, spinning at {omega0 / DEG:g} deg/s about it (all "
        f"assumptions); the brush rubs its side, the chaser radially above it (+x), the "
        f"brush's 17-bristle rows along the stage's axis (scene rows 5, columns 17). ")
    # Release at 0.85 deg/s (measured, docs/mission.md): while the chaser backs off, the wound
    # bristles still turn the target on; that unloading took 0.84 deg/s more off the spin
    # (released at 0.5 deg/s it ended at -0.34 deg/s; at 1.0 deg/s, +0.16; at 0.85, -0.04)
    release = 0.85 * DEG
    what += (f"Release: once the target's |omega| is below {release / DEG:g} deg/s the "
             f"controller backs the chaser off {RETREAT * 1e3:g} mm along +x (release_below, "
             f"release_offset): the bristles unwinding as they let go take about 0.84 deg/s "
             f"more off the spin, so the stage is left nearly still instead of being spun "
             f"back. ")
    return _scene("detumble_upper_stage", what, target, [brush], (1.0, 0.0, 0.0), radius,
                  {"release_below": release, "release_offset": [RETREAT, 0.0, 0.0]},
                  silicone, phi_sil_sil, n_nodes, duration, stop_fraction, omega0)


def box_satellite(silicone: dict, phi_sil_sil: float, seed_brush: dict, quat_axis_angle):
    """A box satellite with one solar panel, spinning about its major axis; the brush
    rubs the face perpendicular to the spin axis, off the axis (a disc brake)."""
    bus, bus_mass = 1.0, 200.0
    panel = (1.0, 2.0, 0.03)                 # x, y, z: 2 m out along +y from the bus
    panel_mass = 20.0
    mass = bus_mass + panel_mass
    panel_y = bus / 2 + panel[1] / 2           # panel centre in the bus frame
    com_y = panel_mass * panel_y / mass
    i_bus = bus_mass * bus ** 2 / 6
    dy_bus, dy_panel = com_y, panel_y - com_y
    ixx = (i_bus + bus_mass * dy_bus ** 2 + panel_mass * (panel[1] ** 2 + panel[2] ** 2) / 12
           + panel_mass * dy_panel ** 2)
    iyy = i_bus + panel_mass * (panel[0] ** 2 + panel[2] ** 2) / 12
    izz = (i_bus + bus_mass * dy_bus ** 2 + panel_mass * (panel[0] ** 2 + panel[1] ** 2) / 12
           + panel_mass * dy_panel ** 2)
    omega0 = 2 * DEG
    lever = 0.25                                # each brush's centre from the spin axis
    tip_sd = 1e-3                               # m: scatter of the tips (assumed)
    n_nodes, duration, stop_fraction = 5, 30.0, 0.05
    # Held on, it does not detumble (issue 15 item 1, docs/mission.md): the brushes' tips
    # stick to the slow face (friction limit tan 30 deg x 4.3 N x 0.25 m = 0.62 N m, never
    # reached: at most 0.42 N m while winding), so against the rigidly held chaser they are
    # a torsional spring (1.5 N m/rad loading, 47 s period with izz) that stores the spin
    # (0.20 J of bond energy at omega_z = 0, 21.8 s) and gives it back (-1.38 deg/s at 30 s);
    # the bristles' bond dampers (c/k ~ 2.5e-4 s: loss factor ~3e-5 at that period) cannot
    # take it (bond damping 0.5 tried: -1.45 deg/s at 30 s), nor could soft, damped attitude
    # loops for the chaser (kp 0 / kd 10 and 15, 0.5 / 12, 1 / 20: the wound brush collapsed
    # or the target drifted back up). So the chaser lets go (release_below, below).
    # chaser above the +z face on the spin axis (through the centre of mass), two brushes on
    # its -z face at x = -+lever, bristles along -z (turned 180 deg about x), 9 rows of 5
    # each: their pushes' moments across the spin axis cancel (one brush off the axis
    # tilted the target: seen, |w| grew), their friction torques about it add (one brush
    # on the axis had almost no lever: seen, |w| stayed). Within 0.29 m of the axis they
    # stay on the face (its inscribed circle about the centre of mass: 0.36 m)
    # The tips scatter by tip_sd (Gaussian, in the base plane): pressed end-on on a flat
    # face that hardly moves, perfectly straight bristles stay straight columns (stiff:
    # the chaser chattered on them, seen) instead of buckling, bending and sliding
    brushes = []
    for side, sign in (("left", -1.0), ("right", 1.0)):
        base = {"position": [sign * lever, 0.0, -CHASER["size"] / 2],
                "orientation": quat_axis_angle([1, 0, 0], math.pi)}
        b = _brush(seed_brush, base, n_nodes)
        b.update(name=f"brush_{side}", rows=9, columns=5, tip_variance=tip_sd ** 2,
                 seed=1 if sign < 0 else 2)
        brushes.append(b)
    target = {"name": "target", "material": "aluminium",
              "shape": {"type": "box", "size": [bus, bus, bus]},
              "mass_properties": {"mass": mass, "center_of_mass": [0.0, com_y, 0.0],
                                  "inertia": [[ixx, 0, 0], [0, iyy, 0], [0, 0, izz]]},
              "motion": {"type": "free"}, "angular_velocity": [0.0, 0.0, omega0],
              # the bus centre placed so that the centre of mass is at the origin
              "pose": {"position": [0.0, -com_y, 0.0]}}
    what = (
        "a box-shaped "
        f"satellite with a solar panel. Target (target): an assumed {bus:g} m aluminium "
        f"bus of {bus_mass:g} kg (uniform) with one {panel[1]:g} x {panel[0]:g} m panel of "
        f"{panel_mass:g} kg ({panel[2] * 1e3:g} mm thick) out along +y from the bus's +y "
        f"face; {mass:g} kg, centre of mass {com_y * 1e3:.1f} mm from the bus centre toward "
        f"the panel (placed at the origin), principal inertia {ixx:.1f}, {iyy:.1f}, "
        f"{izz:.1f} kg m^2 (x, y, z; "
        f"z, the orbit normal, is the major axis, so the spin is stable). The contact shape "
        f"is the bus alone: the panel's mass and inertia are in, its geometry is not (the "
        f"brush works on the bus's +z face and never reaches the panel; an assumption of "
        f"this preset). Spinning at {omega0 / DEG:g} deg/s about z (assumed). The chaser "
        f"holds above the +z face on the spin axis through the centre of mass; two brushes "
        f"(brush_left, brush_right: 9 rows of 5 bristles each, the rows along y), centred "
        f"{lever * 1e3:g} mm either side of the axis along x (so their pushes do not tilt "
        f"the target), tips scattered by {tip_sd * 1e3:g} mm (standard deviation in the "
        f"base plane, seeds 1 and 2: assumed manufacturing scatter; perfectly straight "
        f"bristles pressed end-on stay stiff columns), rub the face like a disc brake. "
        f"Measured (docs/mission.md): held on, the brushes take the spin about z through zero "
        f"(21.8 s) and then spin the target back (-1.38 deg/s at 30 s): their tips stick "
        f"to the slow face "
        f"(the friction limit, tan 30 deg x the 4.3 N push x 0.25 m = 0.62 N m, exceeds "
        f"the 0.42 N m they reach), so they store the spin as a torsional spring (about "
        f"1.5 N m/rad with the target's {izz:.1f} kg m^2) and give it back. ")
    # Release at 0.4 deg/s (measured, docs/mission.md: released at 0.2/0.3/0.4/0.45 deg/s the
    # target kept 0.236/0.156/0.125/0.144 deg/s at 30 s; held on, it is spun back to 1.38)
    release = 0.4 * DEG
    what += (f"Release: once the target's |omega| is below {release / DEG:g} deg/s the "
             f"controller backs the chaser off {RETREAT * 1e3:g} mm along +z (release_below, "
             f"release_offset), so the wound brushes let go instead of spinning the target "
             f"back; what stays is the rocking about x and y that the two brushes build up "
             f"(about 0.12 deg/s), above the study's 5 % threshold. ")
    # the chaser's centre: above the target's centre of mass (the body origin) on +z
    return _scene("detumble_box_satellite", what, target, brushes, (0.0, 0.0, 1.0), bus / 2,
                  {"release_below": release, "release_offset": [0.0, 0.0, RETREAT]},
                  silicone, phi_sil_sil, n_nodes, duration, stop_fraction, omega0)


def all_detumble(silicone, phi_sil_sil, seed_brush, quat_axis_angle) -> list[dict]:
    return [upper_stage(silicone, phi_sil_sil, seed_brush, quat_axis_angle),
            box_satellite(silicone, phi_sil_sil, seed_brush, quat_axis_angle)]
