"""The studio's Studies tab in a real browser: a bad option is refused on the page, a tiny
wedge study started from the tab finishes and its force-depth chart appears; a convergence study shows
its table and log-log plot (slow). Screenshots under tests/e2e/artifacts/."""
from __future__ import annotations

import time

import pytest

from conftest import click, select, wait_text


def _set_text(page, label: str, text: str) -> None:
    # viser's text inputs are not tied to their <label> (no id): the input after the label
    field = page.locator(f'xpath=//label[normalize-space()="{label}"]/following::input[1]')
    field.fill(text, force=True)
    field.press("Tab")


def _wait_studies(studio, predicate, timeout: float, what: str) -> dict:
    return studio.wait_state(lambda s: s["studies"] is not None and predicate(s["studies"]),
                             timeout=timeout, what=what)["studies"]


def _typed(studio, page, label: str, text: str, accepted, what: str) -> None:
    """Type into a field until the server has the value (retyped once on a busy page)."""
    for attempt in range(3):
        _set_text(page, label, text)
        try:
            studio.wait_state(accepted, timeout=10, what=what)
            return
        except AssertionError:
            if attempt == 2:
                raise


def test_e2e_studies_tab_refuses_a_bad_option(studio, page, shot):
    click(page, "Studies", role="tab")
    wait_text(page, "Start study")
    assert studio.state()["studies"]["study"] == "wedge"
    # an option the wedge study does not have, through the "other options" JSON field
    for attempt in range(3):
        _set_text(page, "other options (JSON)", '{"depth": 3}')
        page.wait_for_timeout(500)
        click(page, "Start study")
        try:
            st = _wait_studies(studio, lambda s: s["error"] is not None, 10, "a refusal")
            break
        except AssertionError:
            if attempt == 2:
                raise
    assert "unknown option" in st["error"] and st["active"] is None
    wait_text(page, "Refused")
    wait_text(page, "unknown option")
    shot(page, "refused-option")
    # a client file path where a preset name belongs is refused the same way
    _set_text(page, "other options (JSON)", '{"preset": "/etc/passwd"}')
    page.wait_for_timeout(500)
    click(page, "Start study")
    wait_text(page, "not a preset name")
    assert studio.get("/api/studies") == []  # nothing was queued
    _set_text(page, "other options (JSON)", "")


def test_e2e_wedge_study_from_the_tab_shows_its_plot(studio, page, shot, artifacts_dir):
    click(page, "Studies", role="tab")
    wait_text(page, "Start study")
    # the form starts on the current design at its own depth and resolution; a small study
    _typed(studio, page, "other options (JSON)",
           '{"preset": "wedge_60", "depth_mm": 2, "nodes": 3}', lambda s: True, "typed")
    page.wait_for_timeout(500)
    t0 = time.monotonic()
    click(page, "Start study")  # wedge_60, 2 mm, 3 nodes per bristle
    st = _wait_studies(studio, lambda s: s["active"] is not None or s["shown"] is not None,
                       20, "a started study")
    st = _wait_studies(studio, lambda s: s["shown_status"] is not None and s["charts"] > 0,
                       400, "the study's chart shown")
    wall = time.monotonic() - t0
    assert st["shown_status"] == "completed", st
    assert "force_depth.png" in st["files"] and "force_depth.csv" in st["files"]
    # the force-depth curve is an interactive plotly chart in the page (its PNG stays in
    # the file list, not shown twice)
    page.locator(".js-plotly-plot").first.wait_for(timeout=30_000)
    wait_text(page, "wedge force against depth")
    assert st["images"] == 0
    wait_text(page, "completed")
    job = studio.get(f"/api/studies/{st['shown']}")
    assert job["kind"] == "study" and job["options"]["preset"][0].endswith("wedge_60.json")
    shot(page, "wedge-study-plot")
    print(f"wedge study from the Studies tab: {wall:.1f} s to its plot")
    # its files download from the tab
    with page.expect_download(timeout=60_000) as dl:
        click(page, "Download file")
    saved = artifacts_dir / "study_download"
    dl.value.save_as(str(saved))
    assert saved.stat().st_size > 0


#: each plotly chart of the page: its size, and the boxes of its legend, axis titles and
#: plot area (page pixels: left, top, right, bottom)
_PLOT_BOXES = """() => Array.from(document.querySelectorAll('.js-plotly-plot'))
    .filter(p => p.getBoundingClientRect().width > 0)
    .map(p => { const r = p.getBoundingClientRect();
      const box = s => { const e = p.querySelector(s);
        if (!e) return null; const b = e.getBoundingClientRect();
        return [b.left, b.top, b.right, b.bottom]; };
      return {w: r.width, h: r.height, legend: box('.legend'), x: box('.xtitle'),
              y: box('.ytitle'), area: box('.nsewdrag')}; })"""


def _readable(b: dict, min_w: float, min_h: float) -> None:
    area = b["area"]
    assert area[2] - area[0] > min_w and area[3] - area[1] > min_h, b
    for axis in ("x", "y"):
        L, A = b["legend"], b[axis]
        if L and A:  # the legend's box and an axis title's box do not overlap
            assert L[2] <= A[0] or A[2] <= L[0] or L[3] <= A[1] or A[3] <= L[1], (axis, b)


def test_e2e_study_chart_pops_out_readable(studio, page, shot):
    """Issue 29 item 7: a study chart in the 350 px side panel had a plot area of about
    165 x 60 px and its legend over the axis title; *Pop out charts* shows it large, the
    legend clear of both axis titles, and *Close charts window* puts it away."""
    click(page, "Studies", role="tab")
    wait_text(page, "Start study")
    st = studio.state()["studies"]
    if not st["charts"]:  # (run alone: a tiny wedge study first, ~15 s warm)
        _typed(studio, page, "other options (JSON)",
               '{"preset": "wedge_60", "depth_mm": 2, "nodes": 3}', lambda s: True, "typed")
        page.wait_for_timeout(500)
        click(page, "Start study")
        st = _wait_studies(studio, lambda s: s["shown_status"] is not None and s["charts"] > 0,
                           400, "the study's chart shown")
    assert not st["popout"]["open"]
    page.locator(".js-plotly-plot").first.wait_for(timeout=30_000)
    small = page.evaluate(_PLOT_BOXES)
    # in the side panel too, a plot area taller than the old 60 px, legend off the titles
    _readable(small[0], min_w=200, min_h=150)
    click(page, "Pop out charts")
    st = _wait_studies(studio, lambda s: s["popout"]["open"] and s["popout"]["charts"] > 0,
                       20, "the charts window")
    assert "force_depth.csv" in st["popout"]["titles"]
    wait_text(page, "Close charts window")
    deadline = time.monotonic() + 20
    while True:
        plots = page.evaluate(_PLOT_BOXES)
        big = [p for p in plots if p["w"] > 700]
        if big or time.monotonic() > deadline:
            break
        time.sleep(0.5)
    assert big, (small, plots)
    # a plot area a reader can read (the side panel's was ~165 x 60 px)
    _readable(big[0], min_w=500, min_h=300)
    shot(page, "study-chart-popped-out")
    click(page, "Close charts window")
    _wait_studies(studio, lambda s: not s["popout"]["open"], 20, "the window closed")


@pytest.mark.slow  # three rod runs: ~35 s on an idle 2-core machine, minutes when busy
def test_e2e_convergence_study_shows_table_and_plot(studio, page, shot):
    click(page, "Studies", role="tab")
    wait_text(page, "Start study")
    select(page, "study", "convergence")
    studio.wait_state(lambda s: s["studies"]["study"] == "convergence", what="convergence")
    page.wait_for_timeout(500)
    # the form starts on the current design with no quantity (the options model has no
    # default for it): a user picks the rod preset and types what to measure and the ladder
    select(page, "scene", "rod_weight_static")
    # (an earlier test of this studio may have left options in the JSON field)
    _typed(studio, page, "other options (JSON)", "",
           lambda s: s["studies"]["other_options"] == "", "the JSON options cleared")
    for label, text in (("quantity", "tip_deflection"), ("ladder", "n_nodes=5,9,17")):
        _typed(studio, page, label, text,
               lambda s, label=label, text=text: s["studies"]["form"].get(label) == text,
               f"the {label} typed")
    assert studio.state()["studies"]["form"]["scene"] == "rod_weight_static"
    click(page, "Start study")
    # (a refusal ends the wait at once, with its reason)
    st = _wait_studies(studio, lambda s: s["error"] is not None or (
        s["shown_status"] is not None and s["plot"] and s["table"]), 600,
        "the convergence table and plot")
    assert st["error"] is None, st["error"]
    assert st["shown_status"] == "completed"
    wait_text(page, "error against wall time")  # the plot's title
    wait_text(page, "tip_deflection")
    # the table: one short line per level (nodes, dt in µs, error in %) readable in the panel
    header = page.get_by_text("error [%]", exact=True).first
    header.scroll_into_view_if_needed()
    table = page.locator("table", has=page.get_by_text("error [%]", exact=True)).first
    row = table.locator("tbody tr").first
    line = float(row.evaluate("e => parseFloat(getComputedStyle(e).lineHeight)"))
    assert row.bounding_box()["height"] <= 1.6 * line  # a level's row is one line tall
    shot(page, "convergence-table-plot")
