"""Honest feedback on design edits, in a real browser (issue 14, item 8): a refused value
never stays in its box, a fractional count is refused rather than truncated, a bad mesh
upload gets a message a person can act on, notes about one design go with it, and loading
a preset over edits asks first. Screenshots under tests/e2e/artifacts/."""
from __future__ import annotations

import time

import pytest

from conftest import click, open_preset, set_field, wait_text


def _box(page, label: str) -> str:
    return page.get_by_label(label, exact=True).input_value()


def _wait_box(page, label: str, text: str, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while _box(page, label) != text:
        assert time.monotonic() < deadline, f"{label} shows {_box(page, label)!r}, not {text}"
        time.sleep(0.2)


def _dom_text(page) -> str:
    return page.evaluate("() => document.body.textContent")


def _wait_dom(page, text: str, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while text not in _dom_text(page):
        assert time.monotonic() < deadline, f"{text!r} not in the page"
        time.sleep(0.2)


def test_e2e_refused_values_stay_typed_and_the_design_keeps_its_own(studio, page, shot):
    # issue 29 item 1: a refused value typed in the browser stays in its box (putting the
    # design's value back mid-typing turned "0.8" into "1.8"); the message under it says
    # what the design keeps
    open_preset(studio, "demo", page)
    # 2.5 rows: refused with a message (viser would have cast it to 2 in an int box)
    st = set_field(page, studio, "rows", "2.5", lambda s: "rows" in s["errors"])
    assert st["scene"]["brushes"][0]["rows"] == 17
    assert "rows = 2.5: must be a whole number (the design keeps 17)" in st["errors"]["rows"]
    wait_text(page, "must be a whole number")
    _wait_box(page, "rows", "2.5")   # the box keeps what was typed
    shot(page, "rows-2.5-refused")
    # a value the engine refuses: the box keeps it too, the message says what was typed
    st = set_field(page, studio, "tip radius [mm]", "20", lambda s: "tip_radius" in s["errors"])
    assert st["errors"]["tip_radius"][0] == \
        "tip radius = 20 mm refused (the design keeps 0.5 mm)"
    assert st["scene"]["brushes"][0]["tip_radius"] == 0.0005
    _wait_box(page, "tip radius [mm]", "20")
    # a good value clears the messages
    st = set_field(page, studio, "rows", "3", lambda s: not s["errors"])
    assert st["scene"]["brushes"][0]["rows"] == 3 and st["edited"]


def test_e2e_bad_mesh_upload_says_why_and_notes_go_with_the_design(studio, page, shot,
                                                                   tmp_path):
    open_preset(studio, "demo", page)
    bad = tmp_path / "broken.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nf 1 2 3\n")  # a face naming a third vertex: none
    page.locator('input[type=file]:not([accept="application/json"])').set_input_files(
        str(bad))
    _wait_dom(page, "mesh 'broken.obj' refused")  # (under the Body folder, folded)
    text = _dom_text(page)
    assert "cannot be read as a OBJ triangle mesh. Export it again" in text
    assert "IndexError" not in text and "out of bounds" not in text
    shot(page, "bad-obj")
    assert studio.state()["scene"]["bodies"][0]["shape"]["type"] == "wedge"
    # another design: the note about the refused mesh goes
    open_preset(studio, "space_fur", page)
    deadline = time.monotonic() + 20
    while "broken.obj" in _dom_text(page):
        assert time.monotonic() < deadline, "the note on broken.obj stayed"
        time.sleep(0.2)


def test_e2e_loading_a_preset_over_edits_asks_first(studio, page, shot):
    open_preset(studio, "demo", page)
    set_field(page, studio, "rows", "5", lambda s: s["scene"]["brushes"][0]["rows"] == 5)
    assert studio.state()["edited"]
    # keep editing: nothing is replaced
    click(page, "Load preset")
    keep = page.get_by_role("button", name="Keep editing", exact=True)
    keep.wait_for(timeout=20_000)
    wait_text(page, "has edits since it was loaded")
    shot(page, "discard-dialog")
    keep.evaluate("b => b.click()")
    page.wait_for_timeout(1000)
    st = studio.state()
    assert st["scene"]["brushes"][0]["rows"] == 5 and st["edited"]
    # discard: the preset replaces the design
    click(page, "Load preset")
    discard = page.get_by_role("button", name="Discard edits and load demo", exact=True)
    discard.wait_for(timeout=20_000)
    discard.evaluate("b => b.click()")
    st = studio.wait_state(lambda s: s["scene"]["brushes"][0]["rows"] == 17,
                           what="the preset loaded")
    assert not st["edited"]
    # with no edits it loads at once, without a dialog
    click(page, "Load preset")
    page.wait_for_timeout(1500)
    assert page.get_by_role("button", name="Keep editing", exact=True).count() == 0


# slow: over the 1,000 km scene software WebGL draws a frame in many seconds, and under
# CI's load (two xdist workers) the page applied the reset to 33 mm after 90 s in one cold
# run of three; the scale warnings themselves are unit-tested in tests/studio_ui
@pytest.mark.slow
def test_e2e_absurd_scales_are_warned_about(studio, page, shot):
    open_preset(studio, "demo", page)
    # 1,000 km: accepted (the engine allows it) but warned about under the field
    # (90 s: on a loaded machine the page may still be applying the preset's update when
    # the first typing arrives; set_field types again after half of it)
    st = set_field(page, studio, "bristle length [mm]", "1000000000",
                   lambda s: s["scene"]["brushes"][0]["bristle_length"] == 1e6, timeout=90.0)
    st = studio.wait_state(lambda s: "bristle_length" in s["warnings"], what="a warning")
    assert st["warnings"]["bristle_length"][0].startswith("a 1,000 km bristle")
    wait_text(page, "a 1,000 km bristle: is that the length you meant?")
    wait_text(page, "times the largest body")
    shot(page, "1000-km-bristle")
    # roots wider than the pitch (back from 1,000 km: software WebGL takes many seconds a
    # frame over that scene on a loaded machine, and the page applies the edit only then)
    set_field(page, studio, "bristle length [mm]", "33",
              lambda s: s["scene"]["brushes"][0]["bristle_length"] == 0.033, timeout=90.0)
    st = set_field(page, studio, "pitch x [mm]", "1.5", lambda s: "pitch_x" in s["warnings"])
    assert "bristle_length" not in st["warnings"]
    wait_text(page, "roots 2 mm across at a 1.5 mm pitch")
    # a sound value: the warning goes
    set_field(page, studio, "pitch x [mm]", "3", lambda s: not s["warnings"])
    deadline = time.monotonic() + 20
    while "roots 2 mm across" in page.evaluate("() => document.body.innerText"):
        assert time.monotonic() < deadline, "the warning stayed"
        time.sleep(0.2)
