"""Adding and removing brushes of a design (studio.web.brushes, issue 14 item 7)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from studio import presets
from studio.web import brushes as ub
from studio.web import scene as us


def _two_brushes() -> dict:
    return us.scene_dict(presets.load_preset("momentum_two_brushes"))


def test_add_brush_copies_the_selected_brush_beside_it(demo):
    new = ub.add_brush(demo, 0)
    assert us.validate(new).ok
    a, b = new["brushes"]
    assert b["name"] != a["name"] and b["name"] == "brush_2"
    assert {k: v for k, v in b.items() if k not in ("name", "base")} == \
        {k: v for k, v in a.items() if k not in ("name", "base")}
    # beside it: the roots of the new grid start two pitches past the old grid's last
    # column (a shift of 0 would overlap every bristle: the plausible bug)
    shift = np.subtract(b["base"]["position"], a["base"]["position"])
    expected = ub.brush_width(a) + 2 * a["pitch"][0]
    assert shift == pytest.approx([expected, 0.0, 0.0], abs=1e-12)  # exact arithmetic
    assert demo["brushes"][0] is not a and len(demo["brushes"]) == 1  # input untouched


def test_add_brush_shifts_along_a_rotated_base(demo):
    demo["brushes"][0].setdefault("base", {})["orientation"] = us.rpy_to_quat((0, 0, 90))
    new = ub.add_brush(demo, 0)
    shift = np.subtract(new["brushes"][1]["base"]["position"],
                        demo["brushes"][0]["base"]["position"])
    # yawed 90 deg: the base's x is the world's y
    width = ub.brush_width(demo["brushes"][0]) + 2 * demo["brushes"][0]["pitch"][0]
    assert shift == pytest.approx([0.0, width, 0.0], abs=1e-12)  # rounding of the quat


def test_add_brush_names_stay_unique():
    scene = _two_brushes()
    names = set(ub.brush_names(scene))
    for _ in range(3):
        scene = ub.add_brush(scene, 1)
        assert us.validate(scene).ok
    assert len(set(ub.brush_names(scene))) == 5 and names <= set(ub.brush_names(scene))


def test_remove_brush_takes_its_loads_with_it():
    scene = _two_brushes()
    scene["loads"] = [{"brush": "brush_right", "force": [0.0, 0.0, -0.01]},
                      {"brush": "brush_left", "force": [0.0, 0.0, -0.01]}]
    assert us.validate(scene).ok
    new, notes = ub.remove_brush(scene, 1)
    assert ub.brush_names(new) == ("brush_left",)
    assert [ld["brush"] for ld in new["loads"]] == ["brush_left"]
    assert notes == ["1 load on brush 'brush_right' removed with it"]
    assert us.validate(new).ok


def test_remove_brush_refuses_an_index_it_does_not_have(demo):
    with pytest.raises(ValueError, match="has 1 brushes"):
        ub.remove_brush(demo, 3)


def test_add_brush_to_a_design_without_brushes(demo):
    new, _ = ub.remove_brush(demo, 0)
    again = ub.add_brush(new, 0)
    assert us.validate(again).ok and len(again["brushes"]) == 1


def test_fields_edit_the_selected_brush_only():
    scene = _two_brushes()
    sel = us.Selection(brush=1)
    new = us.set_ui_value("bristle_length", scene, sel, 40.0)
    assert math.isclose(new["brushes"][1]["bristle_length"], 0.040)
    assert new["brushes"][0] == scene["brushes"][0]


def test_the_brushes_not_edited_are_greyed_in_the_view():
    from studio.web import view as uv

    scene = _two_brushes()
    bristles = uv.design_bristles(scene)
    first = uv.design_bristle_first(scene)
    colors = ub.selected_brush_colors(scene, bristles.bonds, first, 1, None,
                                      uv.BRISTLE_COLOR)
    n = len(bristles.bonds) // 2  # two equal brushes, brush 0's segments first
    assert (colors[:n] == ub.OTHER_BRUSH_COLOR).all()
    assert (colors[n:] == uv.BRISTLE_COLOR).all()
    # an overlap's red is kept on a greyed brush
    red = np.tile(np.asarray(uv.BRISTLE_COLOR, np.uint8), (len(bristles.bonds), 1))
    red[0] = (230, 30, 30)
    colors = ub.selected_brush_colors(scene, bristles.bonds, first, 1, red, uv.BRISTLE_COLOR)
    assert tuple(colors[0]) == (230, 30, 30) and tuple(colors[1]) == ub.OTHER_BRUSH_COLOR
    # one brush: nothing to grey
    one, _ = ub.remove_brush(scene, 1)
    b1 = uv.design_bristles(one)
    assert ub.selected_brush_colors(one, b1.bonds, uv.design_bristle_first(one), 0, None,
                                    uv.BRISTLE_COLOR) is None
