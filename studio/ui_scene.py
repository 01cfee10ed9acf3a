"""The studio's mapping between UI fields and the scene (no viser in here).

The UI shows millimetres, degrees, MPa, grams...; a scene is SI (docs/scene.md). Every
editable value of the design panels is a :class:`UiField`: a label, a unit, and a dotted path
into the scene dict with placeholders for the selected brush and body. The functions here
read a field's UI value from a scene, write a UI value into a copy of a scene, validate the
result with the engine's own validation (``engine.parse_scene``) and route the engine's
problems (``SceneError.problems``) back to the fields they name, so that the UI can show a
refused value's message next to the field.

Only the engine's public API is used (``engine.parse_scene``, ``engine.SceneError``).
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

# --------------------------------------------------------------------------- units
# UI value = SI value * factor (angles: degrees from radians).
UNIT_FACTORS: dict[str, float] = {
    "": 1.0,
    "mm": 1e3,
    "mm²": 1e6,
    "mm/s": 1e3,
    "ms": 1e3,
    "µs": 1e6,
    "MPa": 1e-6,
    "g": 1e3,
    "deg": 180.0 / math.pi,
    "deg/s": 180.0 / math.pi,
    "s": 1.0,
    "kg/m³": 1.0,
    "m/s²": 1.0,
    "1/s": 1.0,
    "rad/s²": 1.0,
}


def to_ui(si: float, unit: str) -> float:
    """An SI value in the UI's unit (rounded to 12 significant digits, so that 2.7e6 Pa
    shows as 2.7 MPa rather than 2.6999999999999997)."""
    return float(f"{float(si) * UNIT_FACTORS[unit]:.12g}")


def to_si(ui: float, unit: str) -> float:
    """A UI value in SI."""
    return float(ui) / UNIT_FACTORS[unit]


# --------------------------------------------------------------------------- materials
# Material presets for the "material" dropdown (SI). Silicone: the seed's brush (section 4.2:
# E = 2.7 MPa, nu 0.47-0.49, density 1100-2300 kg/m^3; the demo's 1700). Nylon 6,6:
# typical datasheet values. Steel: the seed's rod (section 4.1: E = 200 GPa, nu = 0.3,
# 7640 kg/m^3).
MATERIAL_PRESETS: dict[str, dict[str, float]] = {
    "silicone": {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1700.0,
                 "bond_damping": 0.0},
    "nylon": {"youngs_modulus": 2.7e9, "poisson_ratio": 0.39, "density": 1140.0,
              "bond_damping": 0.0},
    "steel": {"youngs_modulus": 2.0e11, "poisson_ratio": 0.3, "density": 7640.0,
              "bond_damping": 0.0},
}

SHAPE_TYPES = ("box", "sphere", "cylinder", "wedge", "mesh")
MOTION_TYPES = ("fixed", "free", "hinge", "kinematic")
PROFILE_KINDS = ("constant", "stepped_parabolic", "waypoints")
MASS_MODES = ("none", "density", "mass")

# discriminator tags pydantic puts into error locations of tagged unions
_UNION_TAGS = set(SHAPE_TYPES) | set(MOTION_TYPES) | set(PROFILE_KINDS)


# --------------------------------------------------------------------------- fields
@dataclass(frozen=True)
class UiField:
    """One editable value. ``path`` is dotted, with ``{B}`` = selected brush index, ``{K}`` =
    selected body index, ``{BM}``/``{KM}`` = the brush's / body's material name, and
    ``pair({X},{Y})`` = the contact pair between two materials. ``kind``: ``number``, ``int``,
    ``vector3``, ``dropdown``, ``checkbox``, ``rpy`` (a quaternion shown as roll/pitch/yaw in
    degrees) or ``optional`` (a number where 0 means ``null``)."""

    key: str
    label: str
    path: str
    unit: str = ""
    kind: str = "number"
    folder: str = ""
    options: tuple[str, ...] = ()
    step: Optional[float] = None
    hint: str = ""
    # only shown when the scene at these paths holds these values, e.g. (("{K}shape.type",
    # ("box",)),)
    when: tuple[tuple[str, tuple[str, ...]], ...] = ()


BRUSH = "brushes.{B}."
BODY = "bodies.{K}."

FIELDS: tuple[UiField, ...] = (
    # ---------------------------------------------------------------- brush layout
    UiField("rows", "rows", BRUSH + "rows", kind="int", folder="brush", step=1,
            hint="rows stacked along the base's y"),
    UiField("columns", "columns", BRUSH + "columns", kind="int", folder="brush", step=1,
            hint="bristles per row, along the base's x"),
    UiField("pitch_x", "pitch x", BRUSH + "pitch.0", "mm", folder="brush", step=0.1),
    UiField("pitch_y", "pitch y", BRUSH + "pitch.1", "mm", folder="brush", step=0.1),
    UiField("pattern", "pattern", BRUSH + "pattern", kind="dropdown", folder="brush",
            options=("grid", "staggered")),
    UiField("bristle_length", "bristle length", BRUSH + "bristle_length", "mm",
            folder="brush", step=0.5),
    UiField("root_radius", "root radius", BRUSH + "root_radius", "mm", folder="brush",
            step=0.05),
    UiField("tip_radius", "tip radius", BRUSH + "tip_radius", "mm", folder="brush",
            step=0.05),
    UiField("n_nodes", "nodes per bristle", BRUSH + "n_nodes", kind="int", folder="brush",
            step=1),
    UiField("tip_variance", "tip variance", BRUSH + "tip_variance", "mm²", folder="brush",
            step=0.0001, hint="variance of the Gaussian tip perturbation (seed: 4e-4 mm²)"),
    UiField("seed", "random seed", BRUSH + "seed", kind="int", folder="brush", step=1),
    UiField("base_position", "base position", BRUSH + "base.position", "mm", kind="vector3",
            folder="brush", step=0.5),
    UiField("base_orientation", "base roll/pitch/yaw", BRUSH + "base.orientation", "deg",
            kind="rpy", folder="brush", step=1.0),
    # ---------------------------------------------------------------- brush material
    UiField("youngs_modulus", "Young's modulus", "materials.{BM}.youngs_modulus", "MPa",
            folder="material", step=0.1),
    UiField("poisson_ratio", "Poisson ratio", "materials.{BM}.poisson_ratio",
            folder="material", step=0.01),
    UiField("density", "density", "materials.{BM}.density", "kg/m³", folder="material",
            step=10.0),
    UiField("bond_damping", "bond damping", "materials.{BM}.bond_damping", folder="material",
            step=0.01, hint="fraction of critical damping of each bond"),
    UiField("friction_bristles", "friction angle bristle-bristle",
            "pair({BM},{BM}).friction_angle", "deg", folder="material", step=1.0),
    UiField("restitution_bristles", "restitution bristle-bristle",
            "pair({BM},{BM}).restitution", folder="material", step=0.05),
    # ---------------------------------------------------------------- body
    UiField("shape_type", "shape", BODY + "shape.type", kind="dropdown", folder="body",
            options=SHAPE_TYPES),
    UiField("box_size", "box size", BODY + "shape.size", "mm", kind="vector3", folder="body",
            step=1.0, when=((BODY + "shape.type", ("box",)),)),
    UiField("sphere_radius", "radius", BODY + "shape.radius", "mm", folder="body", step=1.0,
            when=((BODY + "shape.type", ("sphere", "cylinder")),)),
    UiField("cylinder_height", "height", BODY + "shape.height", "mm", folder="body",
            step=1.0, when=((BODY + "shape.type", ("cylinder", "wedge")),)),
    UiField("wedge_angle", "wedge angle", BODY + "shape.angle", "deg", folder="body",
            step=1.0, when=((BODY + "shape.type", ("wedge",)),)),
    UiField("wedge_length", "wedge length", BODY + "shape.length", "mm", folder="body",
            step=1.0, when=((BODY + "shape.type", ("wedge",)),)),
    UiField("mesh_scale", "mesh scale", BODY + "shape.scale", folder="body", step=0.001,
            when=((BODY + "shape.type", ("mesh",)),),
            hint="file coordinates x scale = metres"),
    UiField("mass_mode", "mass from", BODY + "mass_properties", kind="dropdown",
            folder="body", options=MASS_MODES,
            hint="none: driven or fixed body; density: from the closed mesh; mass: inertia "
                 "of the uniform body scaled to this mass"),
    UiField("body_density", "body density", BODY + "mass_properties.density", "kg/m³",
            folder="body", step=10.0),
    UiField("body_mass", "body mass", BODY + "mass_properties.mass", "g", folder="body",
            step=1.0),
    UiField("body_position", "position", BODY + "pose.position", "mm", kind="vector3",
            folder="body", step=0.5),
    UiField("body_orientation", "roll/pitch/yaw", BODY + "pose.orientation", "deg",
            kind="rpy", folder="body", step=1.0),
    UiField("body_youngs_modulus", "body Young's modulus", "materials.{KM}.youngs_modulus",
            "MPa", folder="body", step=1.0),
    UiField("body_poisson_ratio", "body Poisson ratio", "materials.{KM}.poisson_ratio",
            folder="body", step=0.01),
    UiField("friction_body", "friction angle bristle-body", "pair({BM},{KM}).friction_angle",
            "deg", folder="body", step=1.0),
    UiField("restitution_body", "restitution bristle-body", "pair({BM},{KM}).restitution",
            folder="body", step=0.05),
    # ---------------------------------------------------------------- motion
    UiField("motion_type", "motion", BODY + "motion.type", kind="dropdown", folder="motion",
            options=MOTION_TYPES),
    UiField("velocity", "initial velocity", BODY + "velocity", "mm/s", kind="vector3",
            folder="motion", step=1.0),
    UiField("angular_velocity", "initial angular velocity", BODY + "angular_velocity",
            "deg/s", kind="vector3", folder="motion", step=1.0),
    UiField("hinge_axis", "hinge axis", BODY + "motion.axis", kind="vector3", folder="motion",
            step=0.1, when=((BODY + "motion.type", ("hinge",)),)),
    UiField("hinge_k1", "hinge k1", BODY + "motion.k1", "1/s", folder="motion", step=0.01,
            when=((BODY + "motion.type", ("hinge",)),),
            hint="seed eq. 4.6: dω/dt = -k1 ω - k2 sign(ω)"),
    UiField("hinge_k2", "hinge k2", BODY + "motion.k2", "rad/s²", folder="motion", step=0.01,
            when=((BODY + "motion.type", ("hinge",)),)),
    UiField("profile_kind", "profile", BODY + "motion.profile.kind", kind="dropdown",
            folder="motion", options=PROFILE_KINDS,
            when=((BODY + "motion.type", ("kinematic",)),)),
    UiField("after", "after the profile", BODY + "motion.after", kind="dropdown",
            folder="motion", options=("hold", "free"),
            when=((BODY + "motion.type", ("kinematic",)),)),
    UiField("profile_velocity", "profile velocity", BODY + "motion.profile.velocity", "mm/s",
            kind="vector3", folder="motion", step=1.0,
            when=((BODY + "motion.profile.kind", ("constant",)),)),
    UiField("profile_angular_velocity", "profile angular velocity",
            BODY + "motion.profile.angular_velocity", "deg/s", kind="vector3",
            folder="motion", step=1.0,
            when=((BODY + "motion.profile.kind", ("constant",)),)),
    UiField("profile_duration", "profile duration (0 = whole run)",
            BODY + "motion.profile.duration", "s", kind="optional", folder="motion",
            step=0.001, when=((BODY + "motion.profile.kind", ("constant",)),)),
    UiField("profile_direction", "step direction", BODY + "motion.profile.direction",
            kind="vector3", folder="motion", step=0.1,
            when=((BODY + "motion.profile.kind", ("stepped_parabolic",)),)),
    UiField("profile_step", "step length", BODY + "motion.profile.step", "mm",
            folder="motion", step=0.1,
            when=((BODY + "motion.profile.kind", ("stepped_parabolic",)),)),
    UiField("profile_max_acceleration", "max acceleration",
            BODY + "motion.profile.max_acceleration", "m/s²", folder="motion", step=0.1,
            when=((BODY + "motion.profile.kind", ("stepped_parabolic",)),)),
    UiField("profile_n_steps", "steps", BODY + "motion.profile.n_steps", kind="int",
            folder="motion", step=1,
            when=((BODY + "motion.profile.kind", ("stepped_parabolic",)),)),
    UiField("profile_dwell", "dwell", BODY + "motion.profile.dwell", "ms", folder="motion",
            step=1.0, when=((BODY + "motion.profile.kind", ("stepped_parabolic",)),)),
    UiField("profile_unload", "unload", BODY + "motion.profile.unload", kind="checkbox",
            folder="motion", when=((BODY + "motion.profile.kind", ("stepped_parabolic",)),)),
    # ---------------------------------------------------------------- environment
    UiField("gravity", "gravity", "environment.gravity", "m/s²", kind="vector3",
            folder="environment", step=0.01),
    UiField("local_damping", "local damping", "environment.local_damping",
            folder="environment", step=0.05,
            hint="Cundall's non-viscous damping, for quasi-static loading only"),
    # ---------------------------------------------------------------- run
    UiField("duration", "duration", "run.duration", "s", folder="run", step=0.01),
    UiField("record_interval", "record interval", "run.record_interval", "ms", folder="run",
            step=0.5),
    UiField("dt_safety", "dt safety", "run.dt_safety", folder="run", step=0.05),
    UiField("dt", "dt (0 = automatic)", "run.dt", "µs", kind="optional", folder="run",
            step=0.01),
)

FIELDS_BY_KEY: dict[str, UiField] = {f.key: f for f in FIELDS}
FOLDERS: tuple[str, ...] = ("brush", "material", "body", "motion", "environment", "run")


@dataclass
class Selection:
    """Which brush and which body the design panels edit."""

    brush: int = 0
    body: int = 0


# --------------------------------------------------------------------------- paths
class NotApplicable(LookupError):
    """The field has nothing to show for this scene (no body, not a wedge...)."""


def _names(scene: dict, sel: Selection) -> dict[str, str]:
    out = {"B": str(sel.brush), "K": str(sel.body)}
    brushes, bodies = scene.get("brushes") or [], scene.get("bodies") or []
    if 0 <= sel.brush < len(brushes):
        out["BM"] = brushes[sel.brush]["material"]
    if 0 <= sel.body < len(bodies):
        out["KM"] = bodies[sel.body]["material"]
    return out


def _pair_index(scene: dict, a: str, b: str) -> Optional[int]:
    for i, p in enumerate(scene.get("contact_pairs") or []):
        if sorted(p["materials"]) == sorted([a, b]):
            return i
    return None


def resolve(field_: UiField | str, scene: dict, sel: Selection,
            create: bool = False, path: Optional[str] = None) -> list:
    """The concrete path (list of keys/indices) of a field in ``scene``. Raises
    :class:`NotApplicable` when the scene has no such thing (no body; a pair that does not
    exist and ``create`` is False). With ``create``, a missing contact pair is appended."""
    f = FIELDS_BY_KEY[field_] if isinstance(field_, str) else field_
    text = f.path if path is None else path
    names = _names(scene, sel)
    if ("{B" in text and "BM" not in names) or ("{K" in text and "KM" not in names):
        raise NotApplicable(f.key)
    if text.startswith("pair("):
        inside, rest = text[5:].split(")", 1)
        a, b = (s.format(**names) for s in inside.split(","))
        idx = _pair_index(scene, a, b)
        if idx is None:
            if not create:
                raise NotApplicable(f.key)
            scene.setdefault("contact_pairs", []).append({"materials": [a, b]})
            idx = len(scene["contact_pairs"]) - 1
        text = f"contact_pairs.{idx}{rest}"
    else:
        text = text.format(**names)
    return [int(p) if p.lstrip("-").isdigit() else p for p in text.split(".")]


def _get(obj: Any, path: list) -> Any:
    for p in path:
        if isinstance(obj, dict):
            if p not in obj:
                raise KeyError(p)
            obj = obj[p]
        else:
            obj = obj[p]
    return obj


def _set(obj: Any, path: list, value: Any) -> None:
    for p in path[:-1]:
        if isinstance(obj, dict) and (p not in obj or obj[p] is None):
            obj[p] = {}
        obj = obj[p]
    obj[path[-1]] = value


def dotted(path: list) -> str:
    return ".".join(str(p) for p in path)


# --------------------------------------------------------------------------- rotations
def quat_to_rpy(q) -> tuple[float, float, float]:
    """[w, x, y, z] -> (roll, pitch, yaw) in degrees, extrinsic x-y-z (R = Rz Ry Rx)."""
    from scipy.spatial.transform import Rotation

    w, x, y, z = (float(c) for c in q)
    return tuple(float(a) for a in Rotation.from_quat([x, y, z, w]).as_euler("xyz",
                                                                               degrees=True))


def rpy_to_quat(rpy) -> list[float]:
    """(roll, pitch, yaw) in degrees -> unit quaternion [w, x, y, z] (w >= 0)."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_euler("xyz", [float(a) for a in rpy], degrees=True).as_quat()
    q = np.array([w, x, y, z])
    if q[0] < 0:
        q = -q
    return [float(c) for c in q]


# --------------------------------------------------------------------------- read / write
def applicable(field_: UiField | str, scene: dict, sel: Selection) -> bool:
    """Whether the field is shown for this scene: the selected brush/body exists and the
    field's ``when`` conditions hold."""
    f = FIELDS_BY_KEY[field_] if isinstance(field_, str) else field_
    names = _names(scene, sel)
    if "{B" in f.path and "BM" not in names:
        return False
    if "{K" in f.path and "KM" not in names:
        return False
    try:
        for cond_path, values in f.when:
            if _get(scene, resolve(f, scene, sel, path=cond_path)) not in values:
                return False
        if f.key in ("body_density", "body_mass"):
            mp = _get(scene, resolve(f, scene, sel, path=BODY + "mass_properties"))
            key = "density" if f.key == "body_density" else "mass"
            return bool(mp) and mp.get(key) is not None
    except (NotApplicable, KeyError, IndexError, TypeError):
        return False
    return True


def _scene_default(f: UiField) -> Any:
    """Defaults of optional scene fields (docs/scene.md) for display."""
    return {"pattern": "grid", "n_nodes": 8, "tip_variance": 0.0, "seed": 0,
            "base_position": [0.0, 0.0, 0.0], "base_orientation": [1.0, 0.0, 0.0, 0.0],
            "pitch_x": 0.003, "pitch_y": 0.003, "rows": 1, "columns": 1,
            "poisson_ratio": 0.3, "bond_damping": 0.0, "friction_bristles": 0.0,
            "restitution_bristles": 1.0, "friction_body": 0.0, "restitution_body": 1.0,
            "body_poisson_ratio": 0.3, "body_position": [0.0, 0.0, 0.0],
            "body_orientation": [1.0, 0.0, 0.0, 0.0], "motion_type": "fixed",
            "velocity": [0.0, 0.0, 0.0], "angular_velocity": [0.0, 0.0, 0.0],
            "hinge_k1": 0.0, "hinge_k2": 0.0, "after": "hold",
            "profile_velocity": [0.0, 0.0, 0.0], "profile_angular_velocity": [0.0, 0.0, 0.0],
            "profile_duration": None, "profile_direction": [0.0, 0.0, -1.0],
            "profile_step": 0.001, "profile_dwell": 0.0, "profile_unload": False,
            "gravity": [0.0, 0.0, 0.0], "local_damping": 0.0, "dt_safety": 0.5, "dt": None,
            "mesh_scale": 1.0}.get(f.key)


def get_ui_value(field_: UiField | str, scene: dict, sel: Selection) -> Any:
    """The field's value in UI units (raises NotApplicable when it has none)."""
    f = FIELDS_BY_KEY[field_] if isinstance(field_, str) else field_
    if not applicable(f, scene, sel):
        raise NotApplicable(f.key)
    try:
        si = _get(scene, resolve(f, scene, sel, create=False))
    except (NotApplicable, KeyError, IndexError, TypeError):
        si = _scene_default(f)  # an optional field left out, or a pair not listed
    if f.key == "mass_mode":
        if not si:
            return "none"
        return "density" if si.get("density") is not None else "mass"
    if f.kind == "rpy":
        return quat_to_rpy(si if si is not None else (1.0, 0.0, 0.0, 0.0))
    if f.kind == "vector3":
        v = si if si is not None else (0.0, 0.0, 0.0)
        return tuple(to_ui(c, f.unit) for c in v)
    if f.kind == "optional":
        return 0.0 if si is None else to_ui(si, f.unit)
    if f.kind in ("dropdown", "checkbox"):
        return si
    if f.kind == "int":
        return int(si)
    if si is None:
        raise NotApplicable(f.key)
    return to_ui(si, f.unit)


def _shape_default(kind: str, size: float) -> dict:
    if kind == "box":
        return {"type": "box", "size": [size, size, size]}
    if kind == "sphere":
        return {"type": "sphere", "radius": size / 2}
    if kind == "cylinder":
        return {"type": "cylinder", "radius": size / 2, "height": size}
    if kind == "wedge":
        return {"type": "wedge", "angle": math.radians(60.0), "height": size, "length": size}
    raise ValueError(f"shape {kind!r}: upload a mesh file (STL, OBJ or PLY) instead")


def _shape_size(shape: dict) -> float:
    """A characteristic size of a shape, m (to keep a new primitive about as big)."""
    t = shape.get("type")
    if t == "box":
        return float(max(shape["size"]))
    if t in ("sphere", "cylinder"):
        return 2.0 * float(shape["radius"])
    if t == "wedge":
        return float(max(shape["height"], shape["length"]))
    return 0.02


def inertia_for_mass(shape: dict, mass: float) -> tuple[list, list]:
    """(inertia about the centre of mass, centre of mass) of the uniform body of this shape
    with the given mass, SI, in the shape's frame."""
    from .ui_view import shape_mesh

    mesh = shape_mesh(shape)
    if not mesh.is_watertight or not mesh.volume > 0:
        raise ValueError("this mesh is not closed: give a density-free mass in the scene JSON")
    mesh.density = 1.0
    scale = mass / float(mesh.mass)
    inertia = (np.asarray(mesh.moment_inertia) * scale).tolist()
    inertia = [[0.5 * (inertia[a][b] + inertia[b][a]) for b in range(3)] for a in range(3)]
    return inertia, [float(c) for c in mesh.center_mass]


def set_ui_value(field_: UiField | str, scene: dict, sel: Selection, value: Any) -> dict:
    """A deep copy of ``scene`` with the field set to the UI ``value`` (converted to SI).
    The result is not validated; see :func:`validate`. Raises ``ValueError`` for a value
    the UI cannot even express in the scene (a non-number), with a message for the user."""
    f = FIELDS_BY_KEY[field_] if isinstance(field_, str) else field_
    new = copy.deepcopy(scene)
    path = resolve(f, new, sel, create=True)
    if f.key == "shape_type":
        body = _get(new, path[:-2])
        if body["shape"]["type"] != value:
            body["shape"] = _shape_default(value, _shape_size(body["shape"]))
            mp = body.get("mass_properties")
            if mp and mp.get("mass") is not None:
                body["mass_properties"] = _mass_props_for(body, "mass", mp["mass"])
        return new
    if f.key == "mass_mode":
        body = _get(new, path[:-1])
        body["mass_properties"] = _mass_props_for(body, value, None, new)
        return new
    if f.key == "body_mass":
        body = _get(new, path[:-2])
        body["mass_properties"] = _mass_props_for(body, "mass", _number(value, f) / 1e3)
        return new
    if f.key == "motion_type":
        body = _get(new, path[:-2])
        body["motion"] = _motion_default(value, body)
        if value in ("free", "hinge") and not body.get("mass_properties"):
            body["mass_properties"] = _mass_props_for(body, "density", None, new)
        return new
    if f.key == "profile_kind":
        motion = _get(new, path[:-2])
        if motion["profile"]["kind"] != value:
            motion["profile"] = _profile_default(value)
        return new
    if f.kind == "rpy":
        _set(new, path, rpy_to_quat(_vector(value, f, scale=False)))
    elif f.kind == "vector3":
        _set(new, path, [to_si(c, f.unit) for c in _vector(value, f)])
    elif f.kind == "optional":
        x = _number(value, f)
        _set(new, path, None if x == 0 else to_si(x, f.unit))
    elif f.kind == "int":
        x = _number(value, f)
        if x != int(x):
            raise ValueError(f"{f.label} = {value}: must be a whole number")
        _set(new, path, int(x))
    elif f.kind == "checkbox":
        _set(new, path, bool(value))
    elif f.kind == "dropdown":
        if f.options and value not in f.options:
            raise ValueError(f"{f.label} = {value!r}: must be one of {list(f.options)}")
        _set(new, path, value)
    else:
        _set(new, path, to_si(_number(value, f), f.unit))
    return new


def _number(value: Any, f: UiField) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{f.label} = {value!r}: must be a number") from None
    if not math.isfinite(x):
        raise ValueError(f"{f.label} = {value!r}: must be a finite number")
    return x


def _vector(value: Any, f: UiField, scale: bool = True) -> list[float]:
    try:
        v = [float(c) for c in value]
    except (TypeError, ValueError):
        raise ValueError(f"{f.label} = {value!r}: must be three numbers") from None
    if len(v) != 3 or not all(math.isfinite(c) for c in v):
        raise ValueError(f"{f.label} = {value!r}: must be three finite numbers")
    return v


def _mass_props_for(body: dict, mode: str, mass: Optional[float],
                    scene: Optional[dict] = None) -> Optional[dict]:
    if mode == "none":
        return None
    old = body.get("mass_properties") or {}
    if mode == "density":
        density = old.get("density")
        if density is None and scene is not None:
            density = scene["materials"][body["material"]]["density"]
        return {"density": float(density or 1000.0)}
    if mode == "mass":
        if mass is None:
            mass = old.get("mass")
        if mass is None:
            from .ui_view import shape_mesh

            density = old.get("density") or (scene["materials"][body["material"]]["density"]
                                             if scene is not None else 1000.0)
            try:
                mass = float(abs(shape_mesh(body["shape"]).volume)) * float(density)
            except Exception:
                mass = 0.01
        if not mass > 0:  # let the engine name the bad mass
            return {"mass": mass, "inertia": [[1e-6, 0, 0], [0, 1e-6, 0], [0, 0, 1e-6]]}
        inertia, com = inertia_for_mass(body["shape"], mass)
        return {"mass": mass, "inertia": inertia, "center_of_mass": com}
    raise ValueError(f"mass from = {mode!r}: must be one of {list(MASS_MODES)}")


def _motion_default(kind: str, body: dict) -> dict:
    if kind == "fixed":
        return {"type": "fixed"}
    if kind == "free":
        return {"type": "free"}
    if kind == "hinge":
        return {"type": "hinge", "axis": [1.0, 0.0, 0.0]}
    if kind == "kinematic":
        return {"type": "kinematic", "profile": _profile_default("constant")}
    raise ValueError(f"motion = {kind!r}: must be one of {list(MOTION_TYPES)}")


def _profile_default(kind: str) -> dict:
    if kind == "constant":
        return {"kind": "constant", "velocity": [0.0, 0.0, -0.01]}
    if kind == "stepped_parabolic":
        return {"kind": "stepped_parabolic", "direction": [0.0, 0.0, -1.0], "step": 0.001,
                "max_acceleration": 1.0, "n_steps": 3, "dwell": 0.05}
    if kind == "waypoints":
        return {"kind": "waypoints", "times": [0.0, 0.1],
                "positions": [[0.0, 0.0, 0.0], [0.0, 0.0, -0.001]]}
    raise ValueError(f"profile = {kind!r}: must be one of {list(PROFILE_KINDS)}")


def set_material_preset(scene: dict, sel: Selection, preset: str) -> dict:
    """A copy of ``scene`` whose brush material takes the preset's values; the material is
    renamed to the preset's name (and every reference to it follows) unless another material
    already has that name."""
    if preset not in MATERIAL_PRESETS:
        raise ValueError(f"material preset {preset!r}: must be one of "
                         f"{list(MATERIAL_PRESETS)}")
    new = copy.deepcopy(scene)
    old = new["brushes"][sel.brush]["material"]
    name = old
    if preset != old and preset not in new["materials"]:
        name = preset
        new["materials"][name] = new["materials"].pop(old)
        for br in new.get("brushes") or []:
            if br["material"] == old:
                br["material"] = name
        for bd in new.get("bodies") or []:
            if bd["material"] == old:
                bd["material"] = name
        for p in new.get("contact_pairs") or []:
            p["materials"] = [name if m == old else m for m in p["materials"]]
    new["materials"][name] = dict(new["materials"][name], **MATERIAL_PRESETS[preset])
    return new


def add_body(scene: dict, kind: str = "box", size: float = 0.02) -> dict:
    """A copy of ``scene`` with a new fixed primitive body above the first brush's tips."""
    new = copy.deepcopy(scene)
    mats = new.setdefault("materials", {})
    if "pla" not in mats:
        mats["pla"] = {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1250.0}
    z = size
    if new.get("brushes"):
        br = new["brushes"][0]
        z = float(br.get("base", {}).get("position", [0, 0, 0])[2]) + br["bristle_length"]
    names = {b["name"] for b in new.get("bodies") or []}
    name = next(n for n in ("cube", "sphere", "plate", "target", "wedge") +
                tuple(f"body{i}" for i in range(2, 1000)) if n not in names)
    shape = _shape_default(kind, size)
    offset = size / 2 if kind != "wedge" else 0.0
    new.setdefault("bodies", []).append(
        {"name": name, "material": "pla", "shape": shape,
         "pose": {"position": [0.0, 0.0, z + offset + 0.001]}})
    return new


# --------------------------------------------------------------------------- validation
@dataclass
class Problem:
    """One validation problem as the UI shows it."""

    field: str     # the engine's dotted field path
    message: str   # "field = value: allowed"


@dataclass
class Validation:
    scene: Optional[Any]  # engine.Scene
    problems: list[Problem] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.scene is not None and not self.problems


def validate(scene: dict) -> Validation:
    """Validate a scene dict with the engine."""
    import engine

    try:
        return Validation(engine.parse_scene(scene))
    except engine.SceneError as exc:
        return Validation(None, [Problem(p.field, str(p)) for p in exc.problems])


def _normalise(loc: str) -> list[str]:
    return [p for p in loc.split(".") if p not in _UNION_TAGS]


def problems_for(field_: UiField | str, problems: list[Problem], scene: dict,
                 sel: Selection) -> list[Problem]:
    """The problems that name this field (or something inside it)."""
    f = FIELDS_BY_KEY[field_] if isinstance(field_, str) else field_
    try:
        path = [str(p) for p in resolve(f, copy.deepcopy(scene), sel, create=True)]
    except NotApplicable:
        return []
    if f.key in ("shape_type", "motion_type", "profile_kind"):  # the whole shape/motion
        path = path[:-1]
    out = []
    for p in problems:
        loc = _normalise(p.field)
        if loc[:len(path)] == path:
            out.append(p)
    return out


def fields_for_problems(problems: list[Problem], scene: dict, sel: Selection) -> dict:
    """{field key: [problems]} for every field a problem names (most specific field)."""
    out: dict[str, list[Problem]] = {}
    for p in problems:
        best, best_len = None, -1
        for f in FIELDS:
            try:
                path = [str(x) for x in resolve(f, copy.deepcopy(scene), sel, create=True)]
            except NotApplicable:
                continue
            loc = _normalise(p.field)
            if loc[:len(path)] == path and len(path) > best_len:
                best, best_len = f.key, len(path)
        if best is not None:
            out.setdefault(best, []).append(p)
    return out


def scene_dict(scene) -> dict:
    """A validated scene as a plain JSON-able dict (the studio's working copy)."""
    return scene.model_dump(mode="json")
