"""Adding and removing brushes of a design (no viser in here): the edits behind the Brush
layout folder's "edit brush" selector, "Add brush" and "Remove brush" (issue 14, item 7).

Both return a changed deep copy of a scene dict (SI, as ``studio.web.scene`` keeps it) and
leave validation to the caller (``studio.web.scene.validate``), like ``studio.web.scene.add_body``.
"""
from __future__ import annotations

import copy
from typing import Optional

import numpy as np


def brush_names(scene: dict) -> tuple[str, ...]:
    """The design's brush names, in order."""
    return tuple(str(b.get("name", "brush")) for b in scene.get("brushes") or [])


def _new_name(taken: set[str], base: str) -> str:
    stem = base.rstrip("0123456789_") or "brush"
    for i in range(2, 100_000):
        name = f"{stem}_{i}"
        if name not in taken:
            return name
    raise ValueError("too many brushes")


def _rotate(q, v) -> np.ndarray:
    """Vector ``v`` rotated by the unit quaternion ``q`` = [w, x, y, z]."""
    w, x, y, z = (float(c) for c in q)
    u = np.array([x, y, z])
    v = np.asarray(v, float)
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def brush_width(brush: dict) -> float:
    """The extent of a brush's grid of roots along its base's x, m (columns - 1 pitches,
    plus half a pitch when staggered)."""
    pitch_x = float((brush.get("pitch") or (0.003, 0.003))[0])
    width = (int(brush.get("columns", 1)) - 1) * pitch_x
    if brush.get("pattern") == "staggered" and int(brush.get("rows", 1)) > 1:
        width += 0.5 * pitch_x
    return width


def add_brush(scene: dict, source: int = 0) -> dict:
    """A copy of ``scene`` with a copy of brush ``source`` appended, under a new name, its
    base moved along the source base's x by the grid's width plus two pitches, so the two
    brushes stand side by side without touching. A scene with no brush gets a small
    silicone brush at the origin (the demo's bristle)."""
    new = copy.deepcopy(scene)
    brushes = new.setdefault("brushes", [])
    taken = set(brush_names(new))
    if not brushes:
        mats = new.setdefault("materials", {})
        if "silicone" not in mats:
            mats["silicone"] = {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48,
                                "density": 1700.0}
        name = "brush" if "brush" not in taken else _new_name(taken, "brush")
        brushes.append({"name": name, "material": "silicone", "rows": 5, "columns": 5,
                        "pitch": [0.003, 0.003], "bristle_length": 0.033,
                        "root_radius": 0.001, "tip_radius": 0.0005, "n_nodes": 6})
        return new
    if not 0 <= source < len(brushes):
        raise ValueError(f"brush {source}: the design has brushes 0 to {len(brushes) - 1}")
    brush = copy.deepcopy(brushes[source])
    brush["name"] = _new_name(taken, str(brush.get("name", "brush")))
    base = brush.setdefault("base", {}) or {}
    brush["base"] = base
    q = base.get("orientation") or [1.0, 0.0, 0.0, 0.0]
    pitch_x = float((brush.get("pitch") or (0.003, 0.003))[0])
    shift = _rotate(q, [brush_width(brush) + 2.0 * pitch_x, 0.0, 0.0])
    position = np.asarray(base.get("position") or [0.0, 0.0, 0.0], float) + shift
    base["position"] = [float(c) for c in position]
    brushes.append(brush)
    return new


def remove_brush(scene: dict, index: int) -> tuple[dict, list[str]]:
    """A copy of ``scene`` without brush ``index``, and notes on what went with it (the
    loads that named it). Raises ``ValueError`` for an index the design does not have."""
    new = copy.deepcopy(scene)
    brushes = new.get("brushes") or []
    if not 0 <= index < len(brushes):
        raise ValueError(f"brush {index}: the design has {len(brushes)} brushes")
    name = brushes.pop(index).get("name", "brush")
    notes = []
    loads = new.get("loads") or []
    kept = [ld for ld in loads if ld.get("brush") != name]
    if len(kept) != len(loads):
        n = len(loads) - len(kept)
        notes.append(f"{n} load{'s' if n != 1 else ''} on brush {name!r} removed with it")
        new["loads"] = kept
    return new, notes


#: the brushes not being edited, in a design with several: greyed, so the selected one
#: (in the view's usual colour) stands out
OTHER_BRUSH_COLOR = (175, 185, 198)


def selected_brush_colors(scene: dict, bonds: np.ndarray, bristle_first: np.ndarray,
                          selected: int, colors: Optional[np.ndarray], base_color
                          ) -> Optional[np.ndarray]:
    """Per-segment colours that grey every brush but ``selected`` (None for a design with
    one brush: nothing to tell apart). ``bonds``: the drawn segments' node pairs;
    ``bristle_first``: per bristle its first node (``studio.web.view.design_bristle_first``);
    ``colors``: colours already chosen (overlaps in red), kept where they differ from
    ``base_color``."""
    brushes = scene.get("brushes") or []
    if len(brushes) < 2 or len(bonds) == 0:
        return colors
    per_brush = np.array([int(b.get("rows", 1)) * int(b.get("columns", 1)) for b in brushes])
    bristle_brush = np.repeat(np.arange(len(brushes)), per_brush)
    seg_bristle = np.searchsorted(bristle_first, bonds[:, 0], side="right") - 1
    seg_brush = bristle_brush[seg_bristle]
    base = np.asarray(base_color, np.uint8)
    out = np.tile(base, (len(bonds), 1)) if colors is None else np.array(colors, np.uint8)
    plain = np.all(out == base, axis=1)
    out[plain & (seg_brush != selected)] = OTHER_BRUSH_COLOR
    return out
