"""Several brushes in one design, in a real browser (issue 14, item 7): the Brush layout
folder edits the brush chosen in "edit brush"; Add brush and Remove brush change the list.
Screenshots under tests/e2e/artifacts/."""
from __future__ import annotations

import copy
import json
import time

from conftest import click, open_preset, set_field


def _select(page, label: str, value: str) -> None:
    """Choose ``value`` in viser's dropdown labelled ``label`` (a combobox input)."""
    box = page.get_by_label(label, exact=True)
    box.click(force=True)
    page.get_by_role("option", name=value, exact=True).click(force=True)


def test_e2e_second_brush_is_edited_added_and_removed(studio, page, shot):
    open_preset(studio, "momentum_two_brushes", page)
    before = studio.wait_state(lambda s: s["scene_name"] is not None and
                               len(s["scene"]["brushes"]) == 2, what="two brushes")["scene"]
    left, right = before["brushes"]
    assert left["bristle_length"] == right["bristle_length"] == 0.033
    _select(page, "edit brush", "brush_right")
    studio.wait_state(lambda s: s["brush"] == 1, what="brush 2 selected")
    st = set_field(page, studio, "bristle length [mm]", "40",
                   lambda s: s["scene"]["brushes"][1]["bristle_length"] == 0.04)
    after = st["scene"]
    # brush 2 changed in that one field; brush 1 and everything else as loaded
    assert after["brushes"][0] == left
    expected = copy.deepcopy(before)
    expected["brushes"][1]["bristle_length"] = 0.04
    assert after == expected
    shot(page, "brush-2-edited")
    # the downloaded design says the same (the JSON a user would share)
    with page.expect_download(timeout=30_000) as dl:
        click(page, "Download design as JSON")
    saved = json.loads(open(dl.value.path()).read())
    assert [b["bristle_length"] for b in saved["brushes"]] == [0.033, 0.04]
    # back on brush 1 the field shows brush 1's length
    _select(page, "edit brush", "brush_left")
    studio.wait_state(lambda s: s["brush"] == 0, what="brush 1 selected")
    field = page.get_by_label("bristle length [mm]", exact=True)
    deadline = time.monotonic() + 20
    while field.input_value() != "33":
        assert time.monotonic() < deadline, f"the field shows {field.input_value()}"
        time.sleep(0.2)
    # add a brush: a copy of brush 1 beside it, selected
    click(page, "Add brush")
    st = studio.wait_state(lambda s: len(s["scene"]["brushes"]) == 3, what="a third brush")
    assert st["brush"] == 2 and st["scene"]["brushes"][2]["name"] == "brush_left_2"
    assert st["n_bristles"] == 3 * 17 * 5
    page.get_by_text("added brush 'brush_left_2'").wait_for(timeout=20_000)
    shot(page, "brush-added")
    # remove it: the two brushes as edited remain
    click(page, "Remove brush")
    st = studio.wait_state(lambda s: len(s["scene"]["brushes"]) == 2, what="brush removed")
    assert st["scene"]["brushes"] == after["brushes"]
    page.get_by_text("removed brush 'brush_left_2'").wait_for(timeout=20_000)
