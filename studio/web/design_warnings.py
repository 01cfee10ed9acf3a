"""Warnings on a design's scale (no viser in here; issue 14, item 8): values the engine
accepts, because they are physically possible, but that are almost certainly a slip of the
unit or of a digit: a bristle a kilometre long, bristles hundreds of times the size of every
body, roots thicker than the pitch between them. They are shown under the field in orange
and never refuse anything (the engine's validation does that).

``scale_warnings(scene, sel)`` -> ``{field key: [message, ...]}`` for the selected brush's
fields (``studio.web.scene`` keys), plus ``"design"`` for what concerns other brushes.
"""
from __future__ import annotations

import math
from typing import Optional

from studio.fmt import fmt_length

#: a bristle longer than this is out of scale for a brush end-effector (the seed's longest
#: is its 0.4 m steel rod)
MAX_PLAUSIBLE_LENGTH = 1.0          # m
#: bristles longer than this many times the largest body
MAX_LENGTH_TO_BODY = 20.0
#: roots wider than the pitch by this factor cross each other (1 = touching)
ROOT_OVERLAP_FACTOR = 1.0


def _num(x: float) -> str:
    """Three significant digits, thousands separated: 1,000 not 1e+03."""
    v = float(f"{x:.3g}")
    return f"{v:,.0f}" if abs(v) >= 100 else f"{v:g}"


def _mm(x: float) -> str:
    """A length (m) in the unit a person reads it best in, three significant digits."""
    return fmt_length(x, _num)


def body_size(body: dict) -> Optional[float]:
    """The largest extent of a primitive body, m (None for a mesh file: its size is only
    known once read)."""
    shape = body.get("shape") or {}
    t = shape.get("type")
    if t == "box":
        return float(max(shape["size"]))
    if t == "sphere":
        return 2.0 * float(shape["radius"])
    if t == "cylinder":
        return max(2.0 * float(shape["radius"]), float(shape["height"]))
    if t == "wedge":
        h = float(shape["height"])
        return max(h, float(shape["length"]), 2.0 * h * math.tan(0.5 * float(shape["angle"])))
    return None


def brush_warnings(brush: dict, bodies: list) -> dict[str, list[str]]:
    """{field key: messages} for one brush (SI scene dict) among ``bodies``."""
    out: dict[str, list[str]] = {}
    length = float(brush["bristle_length"])
    if length > MAX_PLAUSIBLE_LENGTH:
        out.setdefault("bristle_length", []).append(
            f"a {_mm(length)} bristle: is that the length you meant? (this field is in mm; "
            f"brushes for capture are millimetres to centimetres long)")
    sizes = [s for s in (body_size(b) for b in bodies) if s]
    if sizes and length > MAX_LENGTH_TO_BODY * max(sizes):
        out.setdefault("bristle_length", []).append(
            f"the bristles ({_mm(length)}) are {length / max(sizes):,.0f} times the largest "
            f"body ({_mm(max(sizes))}): check the units of both")
    pitch = brush.get("pitch") or (0.003, 0.003)
    diameter = 2.0 * float(brush["root_radius"])
    rows, columns = int(brush.get("rows", 1)), int(brush.get("columns", 1))
    for key, p, n in (("pitch_x", float(pitch[0]), columns), ("pitch_y", float(pitch[1]), rows)):
        if n > 1 and diameter > ROOT_OVERLAP_FACTOR * p:
            out.setdefault(key, []).append(
                f"roots {_mm(diameter)} across at a {_mm(p)} pitch: neighbouring bristles "
                f"cross each other; the pitch needs at least {_mm(diameter)}")
    return out


def scale_warnings(scene: dict, brush_index: int) -> dict[str, list[str]]:
    """Warnings for the fields of brush ``brush_index``, and under ``"design"`` one line per
    other brush that has any."""
    bodies = scene.get("bodies") or []
    out: dict[str, list[str]] = {}
    for i, brush in enumerate(scene.get("brushes") or []):
        found = brush_warnings(brush, bodies)
        if i == brush_index:
            for key, msgs in found.items():
                out.setdefault(key, []).extend(msgs)
        elif found:
            out.setdefault("design", []).append(
                f"brush {brush.get('name', i)!r}: " + "; ".join(m for ms in found.values()
                                                              for m in ms))
    return out
