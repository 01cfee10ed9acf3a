"""Guides of the 3D view (studio.web.guides, issue 14 item 8): round scale-bar lengths and a
camera that frames the design."""
from __future__ import annotations

import numpy as np
import pytest

from studio.web import guides as ug


@pytest.mark.parametrize("x, expected", [(11.0, 10.0), (10.0, 10.0), (9.99, 5.0), (4.0, 2.0),
                                         (1.5, 1.0), (0.33, 0.2), (3.3e8, 2e8)])
def test_round_length_is_1_2_or_5_times_a_power_of_ten(x, expected):
    assert ug.round_length(x) == pytest.approx(expected, rel=1e-12)  # exact decimal steps


def test_round_length_refuses_nonsense():
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="positive finite"):
            ug.round_length(bad)


def test_length_text_units():
    assert [ug.length_text(x) for x in (0.5, 10, 2000, 5e6)] == ["0.5 mm", "10 mm", "2 m",
                                                                  "5 km"]


def test_camera_sees_the_whole_box():
    lo, hi = np.array([-10.0, -5.0, 0.0]), np.array([10.0, 5.0, 40.0])
    position, look_at = ug.camera_for(lo, hi)
    assert look_at == pytest.approx([0.0, 0.0, 20.0])
    # far enough that the box's bounding sphere (radius 23 mm) fits a 75 deg view cone
    distance = np.linalg.norm(position - look_at)
    radius = 0.5 * np.linalg.norm(hi - lo)
    assert distance * np.tan(np.radians(37.5)) > radius


class _Handle:
    def __init__(self):
        self.visible, self.removed = True, False

    def remove(self):
        self.removed = True


class _Scene:
    """Records what the guides draw (a stand-in for viser's scene API)."""

    def __init__(self):
        self.items = {}

    def add_line_segments(self, name, points, colors, **kw):
        self.items[name] = ("lines", np.asarray(points), kw)
        return _Handle()

    def add_label(self, name, text, **kw):
        self.items[name] = ("label", text, kw)
        return _Handle()


def test_guides_size_the_scale_bar_to_the_design():
    scene = _Scene()
    g = ug.Guides(scene)
    g.update([-6.0, -24.0, 0.0], [6.0, 24.0, 35.0])  # the demo brush: 48 mm deep
    assert g.bar_mm == 10.0 and g.axes_mm == 10.0
    _, bar, _ = scene.items["/studio/guides/scale_bar"]
    assert np.linalg.norm(bar[0][1] - bar[0][0]) == pytest.approx(10.0)  # drawn as labelled
    assert scene.items["/studio/guides/scale_label"][1] == "10 mm"
    g.update([0, 0, 0], [0, 0, 1e9])  # a 1,000 km bristle
    assert scene.items["/studio/guides/scale_label"][1] == "200 km"
    g.set_visible(False)
    assert not g.visible
