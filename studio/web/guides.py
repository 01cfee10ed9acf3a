"""Guides in the 3D view (issue 14, item 8): the world axes at the origin, labelled, and a
scale bar of a round length under the design, sized to it; and where the camera goes to fit
the design in view. View units are millimetres (``studio.web.view.VIEW_SCALE``).

``Guides(scene_api).update(lo, hi)`` draws them for a design spanning ``lo``..``hi`` (mm);
``camera_for(lo, hi)`` is the camera position and look-at point that frame that box.
"""
from __future__ import annotations

import math

import numpy as np

from studio.fmt import fmt_length

AXIS_COLORS = ((220, 40, 40), (40, 170, 40), (40, 90, 230))   # x red, y green, z blue
BAR_COLOR = (30, 30, 30)


def round_length(x: float) -> float:
    """The largest 1, 2 or 5 times a power of ten not above ``x`` (> 0)."""
    if not x > 0 or not math.isfinite(x):
        raise ValueError(f"length {x!r}: must be a positive finite number")
    power = 10.0 ** math.floor(math.log10(x))
    for step in (5.0, 2.0, 1.0):
        if step * power <= x * (1 + 1e-12):
            return step * power
    return power  # (unreachable: 1 * power <= x)


def length_text(mm: float) -> str:
    """A scale bar's label: 10 mm, 0.5 mm, 2 m, 5 km."""
    return fmt_length(mm / 1e3)


def camera_for(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """(position, look_at) of a camera that sees the box ``lo``..``hi`` whole, from the
    front right and above (the studio's usual view), z up."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centre = 0.5 * (lo + hi)
    size = max(float(np.max(hi - lo)), 1e-9)
    return centre + np.array([1.2, -1.6, 0.9]) * size * 0.9, centre


class Guides:
    """Axes at the origin and a scale bar under the design (one set per session)."""

    def __init__(self, scene, root: str = "/studio/guides"):
        self.scene = scene
        self.root = root
        self.visible = True
        self.bar_mm: float = 0.0
        self.axes_mm: float = 0.0
        self._handles: list = []

    def update(self, lo, hi) -> None:
        """Redraw for a design spanning ``lo``..``hi`` (mm, view units)."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        size = max(float(np.max(hi - lo)), 1e-6)
        for h in self._handles:
            h.remove()
        self._handles = []
        # axes: a quarter of the design, from the origin, named
        self.axes_mm = round_length(size / 4)
        a = self.axes_mm
        thick = a / 40
        points = np.array([[[0, 0, 0], [a, 0, 0]], [[0, 0, 0], [0, a, 0]],
                           [[0, 0, 0], [0, 0, a]]], float)
        self._handles.append(self.scene.add_line_segments(
            f"{self.root}/axes", points, np.array([[c, c] for c in AXIS_COLORS], np.uint8),
            thickness=3.0, thickness_units="screen", visible=self.visible))
        for name, tip in zip("xyz", points[:, 1]):
            self._handles.append(self.scene.add_label(
                f"{self.root}/axis_{name}", name, position=tuple(tip * 1.08),
                visible=self.visible, anchor="center-center"))
        # the scale bar: a round length about a third of the design, under its front edge
        self.bar_mm = round_length(size / 3)
        y = lo[1] - 0.15 * size
        start = np.array([lo[0], y, lo[2]])
        end = start + np.array([self.bar_mm, 0.0, 0.0])
        ticks = [[start, end],
                 [start - [0, 0, 0], start + [0, thick * 8, 0]],
                 [end, end + [0, thick * 8, 0]]]
        self._handles.append(self.scene.add_line_segments(
            f"{self.root}/scale_bar", np.array(ticks, float),
            np.array([[BAR_COLOR, BAR_COLOR]] * 3, np.uint8), thickness=3.0,
            thickness_units="screen", visible=self.visible))
        self._handles.append(self.scene.add_label(
            f"{self.root}/scale_label", length_text(self.bar_mm),
            position=tuple(0.5 * (start + end) - [0, 0.06 * size, 0]),
            visible=self.visible, anchor="top-center"))

    def set_visible(self, visible: bool) -> None:
        self.visible = bool(visible)
        for h in self._handles:
            h.visible = self.visible
