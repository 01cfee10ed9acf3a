"""Design variables: a bounded value put into the scene at a path, plus the derived bristle
bending stiffness E d^4.

A variable is written ``PATH=LOW:HIGH[:log][:step=S]``:

- ``PATH`` addresses a field of the scene dict with dots: ``brushes.0.root_radius``,
  ``brushes.0.bristle_length``, ``brushes.0.pitch.0``, ``brushes.0.rows`` (integer fields
  give integer variables), ``materials.silicone.youngs_modulus``,
  ``controllers.0.release_below``. ``brushes.N.material.FIELD`` follows the brush's material
  name into ``materials`` (so ``brushes.0.material.youngs_modulus`` is the bristles' E).
- ``bending_stiffness`` is E d^4 (Pa m^4) of the bristle root (d = 2 x root_radius): the knob
  that sets a bristle's bending stiffness (E I = E pi d^4 / 64). It goes into the scene
  through E, geometry kept (``stiffness_via="youngs_modulus"``), or through the diameter,
  E and the taper ratio tip/root kept (``stiffness_via="diameter"``).
- ``:log`` samples the range on a log scale, ``:step=S`` on a grid of step S.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

from .errors import StudyInputError

STIFFNESS = "bending_stiffness"


@dataclass(frozen=True)
class Variable:
    path: str
    low: float
    high: float
    log: bool = False
    step: Optional[float] = None
    integer: bool = False

    @property
    def name(self) -> str:
        return self.path

    def suggest(self, trial) -> float:
        """Optuna's value of this variable for ``trial``."""
        if self.integer:
            return trial.suggest_int(self.path, int(self.low), int(self.high),
                                     log=self.log, step=int(self.step or 1))
        return trial.suggest_float(self.path, self.low, self.high, log=self.log,
                                   step=self.step)

    def distribution(self):
        import optuna

        if self.integer:
            return optuna.distributions.IntDistribution(int(self.low), int(self.high),
                                                        log=self.log, step=int(self.step or 1))
        return optuna.distributions.FloatDistribution(self.low, self.high, log=self.log,
                                                      step=self.step)


def parse_variable(text: str, scene: dict) -> Variable:
    """``PATH=LOW:HIGH[:log][:step=S]`` -> :class:`Variable`, checked against ``scene``."""
    path, sep, rng = str(text).partition("=")
    path = path.strip()
    parts = [p.strip() for p in rng.split(":")]
    if not sep or len(parts) < 2:
        raise StudyInputError(f"variable {text!r}: expected PATH=LOW:HIGH[:log][:step=S]")
    try:
        low, high = float(parts[0]), float(parts[1])
    except ValueError:
        raise StudyInputError(f"variable {text!r}: LOW and HIGH must be numbers") from None
    log, step = False, None
    for p in parts[2:]:
        if p == "log":
            log = True
        elif p.startswith("step="):
            try:
                step = float(p[5:])
            except ValueError:
                raise StudyInputError(f"variable {text!r}: step must be a number") from None
            if not step > 0:
                raise StudyInputError(f"variable {text!r}: step must be > 0")
        else:
            raise StudyInputError(f"variable {text!r}: unknown modifier {p!r} (log, step=S)")
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise StudyInputError(f"variable {text!r}: need finite LOW < HIGH")
    if log and low <= 0:
        raise StudyInputError(f"variable {text!r}: a log scale needs LOW > 0")
    if log and step:
        raise StudyInputError(f"variable {text!r}: log and step do not go together")
    integer = False
    if path != STIFFNESS:
        current = get_path(scene, path)
        if isinstance(current, bool) or not isinstance(current, (int, float)) and current \
                is not None:
            raise StudyInputError(f"variable {text!r}: {path} is {current!r}, not a number")
        integer = isinstance(current, int) and not isinstance(current, bool)
        if integer and (low != int(low) or high != int(high)):
            raise StudyInputError(f"variable {text!r}: {path} is an integer field; give "
                                  f"integer bounds")
    return Variable(path, low, high, log, step, integer)


def _container(scene: dict, path: str, create: bool = False):
    """(container, key) of the last part of ``path`` in ``scene``."""
    parts = path.split(".")
    node: Any = scene
    for i, part in enumerate(parts[:-1]):
        node = _step(scene, node, part, path)
        # a brush's material is a name: follow it into the scene's materials
        if isinstance(node, str) and i >= 1 and parts[i] == "material":
            node = scene.get("materials", {}).get(node)
            if node is None:
                raise StudyInputError(f"variable path {path!r}: material {parts[i]!r} of "
                                      f"the brush is not among the scene's materials")
    key = parts[-1]
    if isinstance(node, list):
        try:
            key = int(key)
            node[key]
        except (ValueError, IndexError):
            raise StudyInputError(f"variable path {path!r}: {parts[-1]!r} is not an index "
                                  f"of a list of {len(node)}") from None
    elif isinstance(node, dict):
        if key not in node and not create:
            raise StudyInputError(f"variable path {path!r}: no field {key!r} (fields: "
                                  f"{sorted(node)})")
    else:
        raise StudyInputError(f"variable path {path!r}: {parts[-2]!r} holds no fields")
    return node, key


def _step(scene, node, part, path):
    if isinstance(node, list):
        try:
            return node[int(part)]
        except (ValueError, IndexError):
            raise StudyInputError(f"variable path {path!r}: {part!r} is not an index of a "
                                  f"list of {len(node)}") from None
    if isinstance(node, dict):
        if part not in node:
            raise StudyInputError(f"variable path {path!r}: no field {part!r} (fields: "
                                  f"{sorted(node)})")
        return node[part]
    raise StudyInputError(f"variable path {path!r}: {part!r} is inside a value, not a field")


def get_path(scene: dict, path: str):
    node, key = _container(scene, path)
    return node[key]


def set_path(scene: dict, path: str, value) -> None:
    node, key = _container(scene, path)
    node[key] = value


def brush_material(scene: dict, brush: int = 0) -> dict:
    return scene["materials"][scene["brushes"][brush]["material"]]


def bending_stiffness(scene: dict, brush: int = 0) -> float:
    """E d^4 of the bristle root, Pa m^4."""
    b = scene["brushes"][brush]
    return float(brush_material(scene, brush)["youngs_modulus"]) * (2 * b["root_radius"]) ** 4


def set_bending_stiffness(scene: dict, value: float, via: str = "youngs_modulus",
                          brush: int = 0) -> None:
    """Make the root's E d^4 equal ``value``: through E (the geometry kept) or through the
    diameter (E kept; root and tip radius scaled together, the taper ratio kept)."""
    b = scene["brushes"][brush]
    if via == "youngs_modulus":
        # the material may be shared with a body: give the bristles a copy of their own
        name = b["material"]
        mat = dict(scene["materials"][name])
        mat["youngs_modulus"] = float(value) / (2 * b["root_radius"]) ** 4
        users = [x for x in scene.get("bodies", []) if x.get("material") == name]
        if users:
            new = f"{name}_brush"
            scene["materials"][new] = mat
            b["material"] = new
            for pair in scene.get("contact_pairs", []):
                if name in pair["materials"]:
                    other = [m if m != name else new for m in pair["materials"]]
                    scene["contact_pairs"].append(dict(pair, materials=other))
        else:
            scene["materials"][name] = mat
    elif via == "diameter":
        E = float(brush_material(scene, brush)["youngs_modulus"])
        d = (float(value) / E) ** 0.25
        ratio = b["tip_radius"] / b["root_radius"]
        b["root_radius"] = d / 2
        b["tip_radius"] = ratio * d / 2
    else:
        raise StudyInputError(f"stiffness_via {via!r}: youngs_modulus or diameter")


def apply_design(scene: dict, design: dict, *, stiffness_via: str = "youngs_modulus") -> dict:
    """``scene`` (a dict, changed in place and returned) with the design's values: the
    variables at their paths, ``bending_stiffness`` last (it uses the geometry)."""
    for path, value in design.items():
        if path == STIFFNESS:
            continue
        current = get_path(scene, path)
        set_path(scene, path, int(round(value)) if isinstance(current, int)
                 and not isinstance(current, bool) else float(value))
    if STIFFNESS in design:
        set_bending_stiffness(scene, float(design[STIFFNESS]), stiffness_via)
    return scene
