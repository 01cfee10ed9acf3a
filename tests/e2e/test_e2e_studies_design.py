"""Studies on the design being edited, from the Studies tab (issue 14, item 10): the study
runs on the session's design as it is at Start (not a shipped preset), shows its progress
and time left while it runs, and its force-depth curve as an interactive chart. Screenshots
under tests/e2e/artifacts/."""
from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from conftest import click, open_preset, set_field, wait_text


def _select_visible(page, label: str, value: str) -> None:
    """Choose ``value`` in the visible dropdown labelled ``label`` (the Design tab has a
    "preset" dropdown too, hidden while the Studies tab is shown)."""
    box = page.get_by_label(label, exact=True).filter(visible=True)
    box.click(force=True)
    page.get_by_role("option", name=value, exact=True).click(force=True)


@pytest.mark.slow  # a wedge study of 15 bristles: a minute idle, several on a busy machine
def test_e2e_wedge_study_on_the_edited_design(studio, page, shot):
    open_preset(studio, "wedge_60", page)
    # an edit the shipped presets do not have: 3 rows of 5 bristles
    set_field(page, studio, "rows", "3", lambda s: s["scene"]["brushes"][0]["rows"] == 3)
    click(page, "Studies", role="tab")
    wait_text(page, "Start study")
    # issue 29 item 6: the form starts on the design being edited, not on wedge_60
    assert page.get_by_label("preset", exact=True).filter(visible=True).input_value() == \
        "(current design)"
    for attempt in range(3):
        _select_visible(page, "preset", "(current design)")
        page.wait_for_timeout(500)
        if page.get_by_label("preset", exact=True).filter(visible=True).input_value() == \
                "(current design)":
            break
    # (a text field: empty is the scene's own depth; viser's text inputs have no label id)
    depth = page.locator('xpath=//label[normalize-space()="depth [mm]"]/following::input[1]')
    depth.fill("1", force=True)
    depth.press("Tab")
    page.wait_for_timeout(500)
    t0 = time.monotonic()
    click(page, "Start study")
    st = studio.wait_state(lambda s: s["studies"]["active"] is not None, timeout=20,
                           what="a started study")
    job_id = st["studies"]["active"]
    job = studio.get(f"/api/studies/{job_id}")
    # the job stores its validated options: the design's file, its own resolution kept
    (preset,) = job["options"]["preset"]
    assert "/designs/" in preset and job["options"]["nodes"] is None
    assert job["options"]["depth_mm"] == 1
    assert job["name"] == "wedge study of design 'wedge_60'"
    # the stored design is the edited one
    stored = json.loads(Path(preset).read_text())
    assert stored["brushes"][0]["rows"] == 3
    # while it runs: percent and time left on the status line
    seen_left = False
    deadline = time.monotonic() + 900
    while True:
        st = studio.state()["studies"]
        text = page.evaluate("() => document.body.innerText")
        seen_left = seen_left or " left" in text and "running:" in text
        if st["shown_status"] is not None:
            break
        assert time.monotonic() < deadline, "the study did not finish"
        time.sleep(0.3)
    wall = time.monotonic() - t0
    assert st["shown_status"] == "completed", st
    assert st["charts"] == 1  # force against depth, interactive
    assert "force_depth.png" in st["files"]  # (still there to download)
    wait_text(page, "wedge force against depth")
    chart = page.locator(".js-plotly-plot").first
    chart.wait_for(timeout=30_000)
    chart.scroll_into_view_if_needed()
    print(f"wedge study of a 3-row design: {wall:.1f} s to its chart; time left seen: "
          f"{seen_left}")
    shot(page, "study-on-design-chart")
