"""The studio's edits of a scene through its UI fields (no viser in here).

The UI shows millimetres, degrees, MPa, grams...; a scene is SI (docs/scene.md). Every
editable value of the design panels is a :class:`~studio.web.fields.UiField` (the field table,
units and paths are in ``studio.web.fields``). The functions here read a field's UI value from
a scene, write a UI value into a copy of a scene, validate the result with the engine's own
validation (``engine.parse_scene``) and route the engine's problems (``SceneError.problems``)
back to the fields they name, so that the UI can show a refused value's message next to the
field.

Only the engine's public API is used (``engine.parse_scene``, ``engine.SceneError``,
``engine.Scene`` for the defaults of fields a scene leaves out).
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

# the field table and its helpers, imported from here by the panels and the tests
from studio.web.fields import (BODY, BRUSH, FIELDS, FIELDS_BY_KEY, FOLDERS, MASS_MODES,  # noqa: F401
                        MOTION_TYPES, PROFILE_KINDS, SHAPE_TYPES, UNIT_FACTORS, NotApplicable,
                        Selection, UiField, dotted, get_path, placeholder_names, quat_to_rpy,
                        resolve, rpy_to_quat, set_path, spec_default, to_si, to_ui)

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

# discriminator tags pydantic puts into error locations of tagged unions
_UNION_TAGS = set(SHAPE_TYPES) | set(MOTION_TYPES) | set(PROFILE_KINDS)


# --------------------------------------------------------------------------- read / write
def applicable(field_: UiField | str, scene: dict, sel: Selection) -> bool:
    """Whether the field is shown for this scene: the selected brush/body exists and the
    field's ``when`` conditions hold."""
    f = FIELDS_BY_KEY[field_] if isinstance(field_, str) else field_
    names = placeholder_names(scene, sel)
    if "{B" in f.path and "BM" not in names:
        return False
    if "{K" in f.path and "KM" not in names:
        return False
    try:
        for cond_path, values in f.when:
            if get_path(scene, resolve(f, scene, sel, path=cond_path)) not in values:
                return False
        if f.key in ("body_density", "body_mass"):
            mp = get_path(scene, resolve(f, scene, sel, path=BODY + "mass_properties"))
            key = "density" if f.key == "body_density" else "mass"
            return bool(mp) and mp.get(key) is not None
    except (NotApplicable, KeyError, IndexError, TypeError):
        return False
    return True


def get_ui_value(field_: UiField | str, scene: dict, sel: Selection) -> Any:
    """The field's value in UI units (raises NotApplicable when it has none)."""
    f = FIELDS_BY_KEY[field_] if isinstance(field_, str) else field_
    if not applicable(f, scene, sel):
        raise NotApplicable(f.key)
    try:
        si = get_path(scene, resolve(f, scene, sel, create=False))
    except (NotApplicable, KeyError, IndexError, TypeError):
        si = spec_default(f)  # an optional field left out, or a pair not listed
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
    from studio.web.view import shape_mesh

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
        body = get_path(new, path[:-2])
        if body["shape"]["type"] != value:
            body["shape"] = _shape_default(value, _shape_size(body["shape"]))
            mp = body.get("mass_properties")
            if mp and mp.get("mass") is not None:
                body["mass_properties"] = _mass_props_for(body, "mass", mp["mass"])
        return new
    if f.key == "mass_mode":
        body = get_path(new, path[:-1])
        body["mass_properties"] = _mass_props_for(body, value, None, new)
        return new
    if f.key == "body_mass":
        body = get_path(new, path[:-2])
        body["mass_properties"] = _mass_props_for(body, "mass", _number(value, f) / 1e3)
        return new
    if f.key == "motion_type":
        body = get_path(new, path[:-2])
        body["motion"] = _motion_default(value, body)
        if value in ("free", "hinge") and not body.get("mass_properties"):
            body["mass_properties"] = _mass_props_for(body, "density", None, new)
        return new
    if f.key == "profile_kind":
        motion = get_path(new, path[:-2])
        if motion["profile"]["kind"] != value:
            motion["profile"] = _profile_default(value)
        return new
    if f.kind == "rpy":
        set_path(new, path, rpy_to_quat(_vector(value, f, scale=False)))
    elif f.kind == "vector3":
        set_path(new, path, [to_si(c, f.unit) for c in _vector(value, f)])
    elif f.kind == "optional":
        x = _number(value, f)
        set_path(new, path, None if x == 0 else to_si(x, f.unit))
    elif f.kind == "int":
        x = _number(value, f)
        if x != int(x):
            raise ValueError(f"{f.label} = {value}: must be a whole number")
        set_path(new, path, int(x))
    elif f.kind == "checkbox":
        set_path(new, path, bool(value))
    elif f.kind == "dropdown":
        if f.options and value not in f.options:
            raise ValueError(f"{f.label} = {value!r}: must be one of {list(f.options)}")
        set_path(new, path, value)
    else:
        set_path(new, path, to_si(_number(value, f), f.unit))
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
            from studio.web.view import shape_mesh

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
    if kind == "stepped_parabolic":  # direction and step as the scene model has them
        return {"kind": "stepped_parabolic",
                "direction": spec_default(FIELDS_BY_KEY["profile_direction"]),
                "step": spec_default(FIELDS_BY_KEY["profile_step"]),
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
    """A copy of ``scene`` with a new fixed primitive body above the first brush's tips and
    above every body already there (it used to land inside a wedge pressed on the tips,
    issue 29 item 8), 1 mm clear."""
    new = copy.deepcopy(scene)
    mats = new.setdefault("materials", {})
    if "pla" not in mats:
        mats["pla"] = {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1250.0}
    z = size
    if new.get("brushes"):
        br = new["brushes"][0]
        z = float(br.get("base", {}).get("position", [0, 0, 0])[2]) + br["bristle_length"]
    if new.get("bodies"):
        from engine.model import layout

        from studio.web.view import design_bodies

        for b in design_bodies(new):
            if len(b.vertices):
                world = b.vertices @ layout.quat_to_matrix(b.wxyz).T + b.position
                z = max(z, float(world[:, 2].max()))
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
