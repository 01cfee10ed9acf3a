"""The Results panel's force against depth (issue 14, item 9): the depth of a kinematic
press is the body's travel along its own direction, from its first recorded position."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from studio.panels.results import press_depth


class _Result:
    def __init__(self, positions, motion):
        self.positions = np.asarray(positions, float)
        self.scene = {"bodies": [{"name": "wedge", "motion": {"type": motion}}]}

    def json_attr(self, name):
        return self.scene

    def channels(self):
        return ["time", "bodies/wedge/position"]

    def series(self, channel):
        return self.positions


def _frames(positions, motion="kinematic"):
    return SimpleNamespace(res=_Result(positions, motion), body_names=["wedge"],
                           n_frames=len(positions))


def test_press_depth_is_travel_along_the_press():
    # pressed 2 mm down along -z from z = 33.5 mm, with a sideways drift of 0.1 mm
    z = np.linspace(0.0335, 0.0315, 5)
    x = np.linspace(0.0, 0.0001, 5)
    body, depth = press_depth(_frames(np.stack([x, 0 * x, z], 1)))
    assert body == "wedge"
    # would catch a depth measured along z only (sign) or from the origin instead of frame 0
    total = np.hypot(0.002, 0.0001)
    assert depth == pytest.approx(np.linspace(0, total, 5), rel=1e-12)


def test_no_depth_for_free_or_still_bodies():
    still = np.zeros((4, 3))
    assert press_depth(_frames(still)) is None
    moving = np.stack([np.zeros(4), np.zeros(4), np.linspace(0, 1, 4)], 1)
    assert press_depth(_frames(moving, motion="free")) is None
