"""The studio's editable scene fields: what each is (label, unit, where it lives in a scene
dict), how UI units convert to SI, how a field's path resolves in a scene, and what value a
field has when a scene leaves it out (read from the engine's scene model, ``engine.Scene``,
where every default is written once). No viser, and no editing here: ``studio.web.scene``
reads and writes scenes through these fields.
"""
from __future__ import annotations

import functools
import math
import types
from dataclasses import dataclass
from typing import Annotated, Any, Optional, Union, get_args, get_origin

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


SHAPE_TYPES = ("box", "sphere", "cylinder", "wedge", "mesh")
MOTION_TYPES = ("fixed", "free", "hinge", "kinematic")
PROFILE_KINDS = ("constant", "stepped_parabolic", "waypoints")
MASS_MODES = ("none", "density", "mass")

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


def placeholder_names(scene: dict, sel: Selection) -> dict[str, str]:
    """What a field path's placeholders stand for in ``scene``: ``B``/``K`` the selected
    brush/body index, ``BM``/``KM`` their material names (absent when there is no such
    brush/body)."""
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
    names = placeholder_names(scene, sel)
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


def get_path(obj: Any, path: list) -> Any:
    """The value at a resolved path (KeyError/IndexError when it is not there)."""
    for p in path:
        if isinstance(obj, dict):
            if p not in obj:
                raise KeyError(p)
            obj = obj[p]
        else:
            obj = obj[p]
    return obj


def set_path(obj: Any, path: list, value: Any) -> None:
    """Set the value at a resolved path, making the dicts on the way that are missing."""
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


# --------------------------------------------------------------------------- spec defaults
_MISSING = object()


def _models(annotation) -> list:
    """The scene-model classes a field's annotation can hold (through Optional, unions and
    ``Annotated``)."""
    from pydantic import BaseModel

    origin = get_origin(annotation)
    if origin is Annotated:
        return _models(get_args(annotation)[0])
    if origin in (Union, types.UnionType):
        return [m for a in get_args(annotation) for m in _models(a)]
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return []


def _placeholder(part: str) -> bool:
    return part.startswith("{") or part == "*"


def _as_data(value: Any) -> Any:
    from pydantic import BaseModel

    if isinstance(value, BaseModel):
        return value.model_dump(mode="json")
    if isinstance(value, (tuple, list)):
        return [_as_data(v) for v in value]
    return value


def _inside(value: Any, parts: list) -> Any:
    """``value`` (a default: a model instance, a tuple...) followed along ``parts``."""
    from pydantic import BaseModel

    for part in parts:
        if isinstance(value, BaseModel) and part in type(value).model_fields:
            value = getattr(value, part)
        elif isinstance(value, (tuple, list)) and part.isdigit() and int(part) < len(value):
            value = value[int(part)]
        else:
            return _MISSING
    return value


def _default_below(model, parts: list, tags: set) -> Any:
    """The default of the field ``parts`` leads to, from the model class ``model``: the
    default of the first field on the way that has one and holds the rest; else down its
    annotation (list/dict items, the union member that has the next field, picked by the
    field's ``when`` tags where several have it). None where the spec gives no default."""
    from pydantic_core import PydanticUndefined

    name, rest = parts[0], parts[1:]
    info = model.model_fields.get(name)
    if info is None:
        return None
    default = info.get_default(call_default_factory=True)
    if default is not PydanticUndefined:
        value = _inside(default, rest)
        if value is not _MISSING:
            return value
    if not rest:
        return None
    annotation = info.annotation
    if _placeholder(rest[0]):  # an item of a list (brushes.{B}) or a dict (materials.{BM})
        annotation, rest = get_args(annotation)[-1], rest[1:]
    if not rest:
        return None
    candidates = [m for m in _models(annotation) if rest[0] in m.model_fields]
    if len(candidates) > 1:  # a union: the member the field's ``when`` condition names
        candidates = [m for m in candidates if any(
            m.model_fields[tag].default in tags for tag in ("type", "kind")
            if tag in m.model_fields)]
    if len(candidates) != 1:
        return None
    return _default_below(candidates[0], rest, tags)


@functools.lru_cache(maxsize=None)
def spec_default(field_: UiField) -> Any:
    """The value the engine uses for this field when a scene leaves it out (or does not list
    its contact pair), as JSON data; None where the scene model has no default. Read from
    ``engine.Scene`` (engine/model/spec.py), the one place scene defaults are written."""
    import engine

    text = field_.path
    if text.startswith("pair("):
        parts = ["contact_pairs", "*"] + text.split(")", 1)[1].lstrip(".").split(".")
    else:
        parts = text.split(".")
    tags = {v for _, values in field_.when for v in values}
    return _as_data(_default_below(engine.Scene, parts, tags))
