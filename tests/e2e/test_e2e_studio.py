"""Brush Studio in a real browser (headless chromium through Playwright).

Software WebGL (swiftshader) renders a frame or two per second on a busy machine, and
Playwright's actionability checks wait for animation frames, so inputs are filled with
``force=True`` (no waiting for the element to be "stable") and buttons clicked through the
DOM (conftest ``click``).

Each test opens the page on the studio subprocess (``studio`` fixture), drives the panels as
a user would and checks what the server shows (``GET /studio/state``: the number of
instanced bristle segments pushed to viser, bodies' drawn poses, field errors), and saves a
screenshot under tests/e2e/artifacts/.
"""
from __future__ import annotations

import re
from urllib.parse import unquote

import pytest

from conftest import click, open_preset, run_to_playback, set_field, upload, wait_text

DEMO_SEGMENTS = 17 * 5 * (6 - 1)  # the demo scene: 17 x 5 bristles, 6 nodes each


def test_e2e_page_connects(studio, page, shot):
    open_preset(studio, "demo", page)
    wait_text(page, "Connected")
    st = studio.wait_state(lambda s: s["n_segments"] == DEMO_SEGMENTS, what="demo drawn")
    assert st["mode"] == "design"
    assert set(st["bodies"]) == {"wedge"}
    assert page.get_by_label("rows", exact=True).input_value() == "17"
    shot(page, "connected")


@pytest.mark.slow  # reloads the page: half a minute with software WebGL on a busy machine
def test_e2e_url_opens_a_preset(studio, page, shot):
    from studio import presets

    names = studio.get("/studio/presets")["presets"]
    name = "wedge_45" if "wedge_45" in names else names[-1]
    expected = presets.load_preset(name) if name != "demo" else None
    page.goto(f"{studio.api}/studio?preset={name}")  # the landing route redirects
    page.get_by_label("rows", exact=True).wait_for(timeout=30_000)
    # the page's URL names the design its own session opened on (a link to it): the preset,
    # or, once the session keeps its design in a draft (issue 29 item 7), that draft, which
    # a reload reopens
    assert page.url.startswith(studio.url)
    assert re.search(rf"(preset/{name}|draft/[0-9a-f]{{16}})($|[&#])", unquote(page.url)), \
        page.url
    st = studio.wait_state(lambda s: s["scene_name"] == (expected.name if expected else
                                                         s["scene_name"]),
                           what="the new session on the preset")
    if expected is not None:
        assert st["scene_name"] == expected.name
        assert st["scene"]["brushes"][0]["rows"] == expected.brushes[0].rows
    wait_text(page, st["scene_name"])
    shot(page, name)


def test_e2e_rows_change_instanced_segments(studio, page, shot):
    open_preset(studio, "demo", page)
    studio.wait_state(lambda s: s["n_segments"] == DEMO_SEGMENTS, what="demo drawn")
    st = set_field(page, studio, "rows", "3", lambda s: s["n_segments"] == 3 * 5 * 5)
    assert st["scene"]["brushes"][0]["rows"] == 3
    wait_text(page, "15 bristles, 75 segments")
    shot(page, "three-rows")
    set_field(page, studio, "rows", "9", lambda s: s["n_segments"] == 9 * 5 * 5)


def test_e2e_bad_value_shows_message(studio, page, shot):
    open_preset(studio, "demo", page)
    studio.wait_state(lambda s: s["n_segments"] == DEMO_SEGMENTS, what="demo drawn")
    # a 40 mm thick tip on a 33 mm bristle: refused by the engine
    st = set_field(page, studio, "tip radius [mm]", "20", lambda s: "tip_radius" in s["errors"])
    assert any("bristle_length" in m or "tip_radius" in m for m in st["errors"]["tip_radius"])
    wait_text(page, "tip radius = 20 mm refused")
    # refused: the design and the view are unchanged
    assert st["scene"]["brushes"][0]["tip_radius"] == 0.0005
    assert st["n_segments"] == DEMO_SEGMENTS
    shot(page, "refused-tip-radius")
    set_field(page, studio, "rows", "0", lambda s: "rows" in s["errors"])
    wait_text(page, "brushes.0.rows = 0")
    shot(page, "refused-rows")
    # a good value clears the messages
    st = set_field(page, studio, "tip radius [mm]", "0.4", lambda s: not s["errors"])
    assert st["scene"]["brushes"][0]["tip_radius"] == pytest.approx(0.0004)


def test_e2e_preset_download_upload_identical(studio, page, shot, artifacts_dir):
    import engine

    open_preset(studio, "wedge_45" if "wedge_45" in studio.get("/studio/presets")["presets"]
                else "demo", page)
    before = set_field(page, studio, "rows", "4",
                       lambda s: s["scene"]["brushes"][0]["rows"] == 4)["scene"]
    with page.expect_download(timeout=60_000) as dl:
        click(page, "Download design as JSON")
    path = artifacts_dir / "downloaded_design.json"
    dl.value.save_as(str(path))
    assert engine.parse_scene(path.read_text()).model_dump() == \
        engine.parse_scene(before).model_dump()
    open_preset(studio, "demo", page)  # something else in between
    studio.wait_state(lambda s: s["scene"]["brushes"][0]["rows"] == 17, what="demo again")
    upload(page, path)
    after = studio.wait_state(lambda s: s["scene"]["brushes"][0]["rows"] == 4,
                              what="uploaded design")["scene"]
    assert after == before
    shot(page, "uploaded")


@pytest.mark.slow  # the worker's first run compiles the engine's kernels (1-3 min when cold)
def test_e2e_run_finishes_and_scrubs(studio, page, shot, artifacts_dir, tmp_path,
                                     tiny_scene):
    import engine

    st = run_to_playback(page, studio, tiny_scene(), tmp_path)  # a 2 x 2 brush, a box
    wait_text(page, "completed")
    shot(page, "run-list")
    click(page, "Results", role="tab")
    z0 = st["bodies"]["box"]["position_mm"][2]
    page.get_by_role("slider").first.evaluate("e => e.focus()")
    page.keyboard.press("End")  # the timeline to its last frame
    st2 = studio.wait_state(lambda s: s["frame"] == s["n_frames"] - 1, what="last frame")
    z1 = st2["bodies"]["box"]["position_mm"][2]
    # the box is driven 1 mm down in the run (0.25 m/s for 4 ms)
    assert z0 - z1 == pytest.approx(1.0, abs=0.05)
    shot(page, "scrubbed-to-end")
    with page.expect_download(timeout=60_000) as dl:
        click(page, "Download result HDF5")
    h5 = artifacts_dir / "downloaded_result.h5"
    dl.value.save_as(str(h5))
    with engine.open_result(h5) as res:
        assert res.status == "completed"
        assert res.n_frames == st2["n_frames"]
    click(page, "Design", role="tab")
