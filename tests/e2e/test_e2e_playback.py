"""Playback in a real browser after design edits (issue 14, defect 2): a finished run stays
playable when the design changes, and the view says which of the two it shows."""
from __future__ import annotations

import pytest

from conftest import click, run_to_playback, set_field, wait_text


@pytest.mark.slow  # a run in the worker (its first run compiles the kernels: 1-3 min cold)
def test_e2e_playback_survives_a_design_edit(studio, page, shot, tmp_path, tiny_scene):
    # a 2 x 2 brush, a box pressed 1 mm
    st = run_to_playback(page, studio, tiny_scene(), tmp_path)
    n = st["n_frames"]
    wait_text(page, "View: run")
    # the kinematic press gets its force against depth plot (issue 14, item 9)
    assert "root force [N] against depth of box [mm]" in st["plots"]
    # the defect: any design edit used to leave the slider and play moving nothing
    click(page, "Design", role="tab")
    st = set_field(page, studio, "rows", "1", lambda s: s["scene"]["brushes"][0]["rows"] == 1)
    assert st["mode"] == "design"
    design_segments = st["n_segments"]
    wait_text(page, "is loaded: show → run")
    z_design = st["bodies"]["box"]["position_mm"][2]
    click(page, "Results", role="tab")
    page.get_by_role("slider").first.evaluate("e => e.focus()")
    page.keyboard.press("End")  # scrub: the view goes back to the run, at its last frame
    st = studio.wait_state(lambda s: s["mode"] == "playback" and s["frame"] == n - 1,
                           what="the last frame of the run shown")
    # the run's 2 x 2 bristles are drawn again, and the box where the run left it (1 mm down)
    assert st["n_segments"] == 2 * design_segments  # 2 rows in the run, 1 in the design
    assert z_design - st["bodies"]["box"]["position_mm"][2] == pytest.approx(1.0, abs=0.05)
    wait_text(page, "View: run")
    shot(page, "playback-after-edit")
    page.get_by_text("root force [N] against depth of box [mm]").first.evaluate(
        "e => e.scrollIntoView()")
    shot(page, "force-against-depth")
    # one click back to the design, which kept the edit
    click(page, "design")
    st = studio.wait_state(lambda s: s["mode"] == "design", what="design view")
    assert st["scene"]["brushes"][0]["rows"] == 1
    click(page, "run")
    studio.wait_state(lambda s: s["mode"] == "playback", what="run view")
