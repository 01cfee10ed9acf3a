"""Small scenes that between them exercise every kind of state a run writes (shared by
``test_state_fields.py`` and ``test_state_snapshot.py``): a wedge pressing a frictional,
damped brush hard enough that its bristles touch each other; a chaser in orbit under a
controller with a hinged wheel and a loaded rod; a reduced-brush patch pressed by a
kinematic carrier that is released when its profile ends; free bodies striking each other
(sphere-mesh and mesh-mesh contacts with friction)."""
from __future__ import annotations

import copy
import math

import engine
import stability_cases as cases
from test_patch import LAW, PLATE_TOP, _carrier, _plate, _scene as _patch_scene


def wedge_press() -> dict:
    """A 3 x 3 silicone brush of 1 mm thick cylindrical bristles 50 um apart, with damped
    bonds, pressed 1.5 mm by the PLA wedge, with friction in every contact."""
    brush = cases._brush("silicone", 3, 3, 4, pitch=0.00205, tip_radius=0.001)
    scene = cases._silicone_pressed("wedge_press", "state test", brush, speed=0.5,
                                    depth=0.0015, hold=0.0005)
    scene["materials"]["silicone"] = dict(scene["materials"]["silicone"], bond_damping=0.05)
    # at 1 ms the wedge touches three bristles and two pairs of bristles touch, with
    # tangential history in both kinds of contact (the wedge bounces off later)
    scene["run"].update(duration=0.001, record_interval=0.0005,
                        channels=["nodes", "bodies", "contacts", "energy"])
    return scene


def chaser() -> dict:
    """A free box in orbit (gravity gradient on) held by a PID pose controller against a
    constant external force, a hinged wheel with dissipation, a rod loaded at its tip."""
    q = [math.cos(0.4), math.sin(0.4) * 0.6, 0.0, math.sin(0.4) * 0.8]
    al = {"youngs_modulus": 70e9, "density": 2700.0}
    steel = {"youngs_modulus": 200e9, "poisson_ratio": 0.3, "density": 7640.0}
    return {
        "materials": {"al": al, "steel": steel},
        "brushes": [{"name": "rod", "material": "steel", "bristle_length": 0.2,
                     "root_radius": 1e-3, "tip_radius": 1e-3, "n_nodes": 4,
                     "base": {"position": [0.3, 0.2, 0.1]}}],
        "loads": [{"brush": "rod", "force": [0.0, 0.01, 0.0],
                   "profile": {"times": [0.0, 0.02], "values": [0.0, 1.0]}}],
        "bodies": [
            {"name": "box", "material": "al", "shape": {"type": "box", "size": [0.4, 0.3, 0.2]},
             "mass_properties": {"density": 500.0}, "motion": {"type": "free"},
             "pose": {"position": [1.0, -0.5, 0.4], "orientation": q},
             "velocity": [0.01, 0.02, -0.01], "angular_velocity": [0.2, -0.1, 0.3],
             "external_force": [0.1, 0.0, 0.0]},
            {"name": "wheel", "material": "al",
             "shape": {"type": "box", "size": [0.2, 0.1, 0.3]},
             "mass_properties": {"density": 500.0},
             "motion": {"type": "hinge", "axis": [0.0, 0.6, 0.8], "k1": 0.5},
             "pose": {"position": [-1.0, 0.5, -0.3], "orientation": q},
             "angular_velocity": [0.0, 0.3, 0.4]}],
        "controllers": [{"name": "hold", "body": "box", "position": [1.0, -0.5, 0.4],
                         "sample_interval": 0.002,
                         "position_gains": {"proportional": 2.0, "derivative": 1.0,
                                            "integral": 0.1},
                         "attitude_gains": {"proportional": 0.5, "derivative": 0.3}}],
        "environment": {"orbit": {"mean_motion": 0.05, "gravity_gradient": True}},
        "run": {"duration": 0.005, "record_interval": 0.0025,
                "channels": ["nodes", "bodies", "energy"]}}


def patch_press():
    """A kinematic carrier presses its reduced brush 1 mm into a fixed plate (after a 1 mm
    gap) along two waypoint intervals in 50 ms, then is released as free (scene, not
    dict)."""
    z = PLATE_TOP + 0.001 + 0.2
    carrier = _carrier(PLATE_TOP + 0.001, LAW, motion={
        "type": "kinematic", "after": "free",
        "profile": {"kind": "waypoints", "times": [0.0, 0.025, 0.05],
                    "positions": [[0.0, 0.0, z], [0.0, 0.0, z - 0.001],
                                  [0.0, 0.0, z - 0.002]]}})
    return _patch_scene([_plate(), carrier], 0.06, dt=1e-3, channels=("bodies",))


def impacts() -> dict:
    """A free steel sphere slides on a fixed box (sphere-mesh) while a free cube strikes
    another free cube face on (mesh-mesh), all with friction."""
    m = {"youngs_modulus": 1e8, "poisson_ratio": 0.3, "density": 7800.0}

    def box(name, size, position, motion, **extra):
        return dict({"name": name, "material": "m",
                     "shape": {"type": "box", "size": [size] * 3},
                     "mass_properties": {"density": 7800.0}, "motion": {"type": motion},
                     "pose": {"position": list(position)}}, **extra)

    return {"materials": {"m": m},
            "contact_pairs": [{"materials": ["m", "m"], "friction_angle": 0.5,
                               "restitution": 0.5}],
            "bodies": [
                box("floor", 0.1, (0.0, 0.0, -0.05), "fixed"),
                {"name": "ball", "material": "m", "shape": {"type": "sphere", "radius": 0.01},
                 "mass_properties": {"density": 7800.0}, "motion": {"type": "free"},
                 "pose": {"position": [0.0, 0.0, 0.01]}, "velocity": [0.1, 0.0, 0.0]},
                box("bullet", 0.04, (0.3, 0.0, 0.0), "free", velocity=[0.5, 0.02, 0.0],
                    angular_velocity=[0.0, 0.0, 0.5]),
                box("target", 0.04, (0.3405, 0.005, 0.0), "free")],
            "environment": {"gravity": [0.0, 0.0, -9.81]},
            "run": {"duration": 0.004, "record_interval": 0.002,
                    "channels": ["bodies", "energy"]}}


def scene(make) -> "engine.Scene":
    """The scene of one of the makers above, parsed (a fresh copy each time)."""
    made = make()
    return made if isinstance(made, engine.Scene) else engine.parse_scene(copy.deepcopy(made))


MAKERS = (wedge_press, chaser, patch_press, impacts)
