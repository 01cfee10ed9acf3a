"""Scale warnings on a design (studio.web.design_warnings, issue 14 item 8)."""
from __future__ import annotations

import pytest

from studio import presets
from studio.web import scene as us
from studio.web import design_warnings as uw


@pytest.mark.parametrize("name", presets.preset_names())
def test_no_shipped_preset_is_warned_about(name):
    scene = us.scene_dict(presets.load_preset_or_file(name))
    assert uw.scale_warnings(scene, 0) == {}


def test_a_1000_km_bristle_is_warned_about(demo):
    scene = us.set_ui_value("bristle_length", demo, us.Selection(), 1e9)  # mm
    assert us.validate(scene).ok  # the engine accepts it: only a warning can catch it
    (absurd, body) = uw.scale_warnings(scene, 0)["bristle_length"]
    assert absurd.startswith("a 1,000 km bristle")
    # the demo's wedge: 20 mm high and long, 23.1 mm across its top (2 h tan 30 deg)
    assert "43,301,270 times the largest body (23.1 mm)" in body


def test_bristles_many_times_the_body_but_under_a_metre(demo):
    demo["bodies"][0]["shape"] = {"type": "sphere", "radius": 0.001}
    demo["brushes"][0]["bristle_length"] = 0.05  # 25 times a 2 mm sphere
    assert list(uw.scale_warnings(demo, 0)) == ["bristle_length"]
    demo["brushes"][0]["bristle_length"] = 0.039  # 19.5 times: under the 20x threshold
    assert uw.scale_warnings(demo, 0) == {}


def test_roots_thicker_than_the_pitch(demo):
    demo["brushes"][0]["pitch"] = [0.0015, 0.003]  # 2 mm roots, 1.5 mm apart along x
    w = uw.scale_warnings(demo, 0)
    assert list(w) == ["pitch_x"]
    assert w["pitch_x"] == ["roots 2 mm across at a 1.5 mm pitch: neighbouring bristles "
                            "cross each other; the pitch needs at least 2 mm"]
    demo["brushes"][0]["columns"] = 1  # one column: no neighbour along x
    assert uw.scale_warnings(demo, 0) == {}


def test_another_brushs_warning_goes_to_the_design_line():
    scene = us.scene_dict(presets.load_preset("momentum_two_brushes"))
    scene["brushes"][1]["bristle_length"] = 2.0
    assert list(uw.scale_warnings(scene, 1)) == ["bristle_length"]
    (line,) = uw.scale_warnings(scene, 0)["design"]
    assert line.startswith("brush 'brush_right': a 2 m bristle")
