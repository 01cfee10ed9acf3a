"""A design search from the Studies tab (issue 24, item 4), as a user goes: pick the study
*optimise*, pick variables from the design's own fields (bounds around their values, in
the Design tab's units), refuse bounds that are no range, start the search on the current
design, watch the trials and the best so far come in, read the objective chart, pop it out
large (issue 29, item 7), and load a trial's design into the design view; a reload keeps
it. Keys typed at human speed. Screenshots under tests/e2e/artifacts/."""
from __future__ import annotations

import time

import pytest

from conftest import click, select, open_preset, wait_text

KEY_DELAY_MS = 100  # a person typing, each key its own update
DOC_VIEWPORT = {"width": 1400, "height": 900}  # the docs' screenshots (docs/studio.md)


def _doc_shot(page, shot, name: str, scroll_to=None) -> None:
    """A screenshot for the docs: a wider page, the software-WebGL notice hidden, the
    pointer off the panel (no tooltip), the panel scrolled to ``scroll_to``."""
    page.set_viewport_size(DOC_VIEWPORT)
    page.add_style_tag(content=".mantine-Notification-root { display: none !important; }")
    page.mouse.move(1390, 890)
    if scroll_to is not None:
        page.get_by_text(scroll_to, exact=True).first.evaluate(
            "e => e.scrollIntoView({block: 'start'})")
    page.wait_for_timeout(2500)
    shot(page, name)
    page.set_viewport_size({"width": 1100, "height": 800})


def _type_into(page, label: str, text: str) -> None:
    box = page.get_by_label(label, exact=True).filter(visible=True)
    box.wait_for(state="visible", timeout=30_000)
    box.focus()
    page.keyboard.press("Control+A")
    page.keyboard.type(text, delay=KEY_DELAY_MS)
    page.keyboard.press("Tab")


def _studies(studio) -> dict:
    return studio.state()["studies"]


def _to_optimise(page, studio) -> None:
    click(page, "Studies", role="tab")
    wait_text(page, "Start study")
    select(page, "study", "optimise")
    studio.wait_state(lambda s: s["studies"]["study"] == "optimise", what="optimise chosen")
    wait_text(page, "Add variable")


def _add_variable(page, studio, title: str, path: str) -> list:
    select(page, "design field", title)
    page.wait_for_timeout(300)
    for attempt in range(3):
        click(page, "Add variable")
        try:
            st = studio.wait_state(lambda s: path in s["studies"]["variables"], timeout=10,
                                   what=f"variable {path}")
            return st["studies"]["variables"][path]
        except AssertionError:
            if attempt == 2:
                raise


def test_e2e_search_variables_from_the_design(studio, page, shot):
    """Variables come from the design being edited, bounds around its values; a bound
    typed wrong is refused on the page and nothing is queued (quick: no run)."""
    click(page, "Design", role="tab")
    open_preset(studio, "spin_cube_40", page)
    _to_optimise(page, studio)
    st = _studies(studio)
    assert "root radius [mm]" in st["field_choices"] and "rows" in st["field_choices"]
    scene = studio.state()["scene"]
    r_mm = scene["brushes"][0]["root_radius"] * 1e3
    low, high, log = _add_variable(page, studio, "root radius [mm]",
                                   "brushes.0.root_radius")
    # the old Studies tab had no optimise and no rows: the bounds are half and twice the
    # design's root radius, in mm as the Design tab shows it
    assert (low, high, log) == (pytest.approx(r_mm / 2), pytest.approx(2 * r_mm), False)
    wait_text(page, f"root radius [mm]: {r_mm:g} now")
    # a bound typed below the other is refused when the search is started
    _type_into(page, "root radius to [mm]", "0.3")
    studio.wait_state(lambda s: s["studies"]["variables"]["brushes.0.root_radius"][1]
                      == pytest.approx(0.3), what="typed high bound")
    n_before = len(studio.get("/api/studies"))
    click(page, "Start study")
    st = studio.wait_state(lambda s: s["studies"]["error"] is not None, timeout=10,
                           what="a refusal")["studies"]
    assert "below the high bound" in st["error"] and st["active"] is None
    wait_text(page, "below the high bound")
    # the refusal in red on the panel (it was black text under the green Start button)
    color = page.evaluate("""() => { const el = Array.from(document.querySelectorAll('span'))
        .find(e => e.innerText.includes('below the high bound'));
        return getComputedStyle(el).color; }""")
    r, g, b = (int(c) for c in color[color.index("(") + 1:color.index(")")].split(",")[:3])
    assert r > 180 and g < 80 and b < 80, color
    assert len(studio.get("/api/studies")) == n_before
    shot(page, "search-variables-refused")
    # remove it again: the form goes back to the study's default variable
    click(page, "Remove root radius")
    studio.wait_state(lambda s: not s["studies"]["variables"], what="row removed")
    wait_text(page, "None picked")
    # a design of two brushes is refused before anything is queued (the search varies one)
    click(page, "Design", role="tab")
    open_preset(studio, "momentum_two_brushes", page)
    click(page, "Studies", role="tab")
    wait_text(page, "Start study")
    click(page, "Start study")
    st = studio.wait_state(lambda s: "one brush" in (s["studies"]["error"] or ""),
                           timeout=10, what="two brushes refused")["studies"]
    assert st["active"] is None and len(studio.get("/api/studies")) == n_before
    wait_text(page, "varies one brush")


@pytest.mark.slow  # three trials of a 2-node spin rig: ~1 min warm, minutes cold or busy
def test_e2e_search_progress_chart_popout_and_trial_design(studio, page, shot,
                                                           artifacts_dir):
    click(page, "Design", role="tab")
    open_preset(studio, "spin_cube_40", page)
    _to_optimise(page, studio)
    st = _studies(studio)
    if "brushes.0.root_radius" in st["variables"]:
        click(page, "Remove root radius")
    _add_variable(page, studio, "root radius [mm]", "brushes.0.root_radius")
    # a small search: 3 trials, 2 nodes per bristle, 20 ms of each target, no refinement
    for label, text in (("trials", "3"), ("nodes", "2"), ("duration [s]", "0.02")):
        _type_into(page, label, text)
        page.wait_for_timeout(300)
    page.get_by_label("refine", exact=True).filter(visible=True).uncheck(force=True)
    page.wait_for_timeout(800)
    t0 = time.monotonic()
    click(page, "Start study")
    st = studio.wait_state(lambda s: s["studies"]["active"] is not None, timeout=20,
                           what="a started search")
    job_id = st["studies"]["active"]
    job = studio.get(f"/api/studies/{job_id}")
    assert job["study"] == "optimise" and job["options"]["trials"] == 3
    assert job["options"]["refine"] is False and job["options"]["nodes"] == 2
    (var,) = job["options"]["variables"]
    assert var.startswith("brushes.0.root_radius=")
    assert "/designs/" in job["options"]["preset"]  # the current design, stored
    # while it runs: trials done and the best so far, on the page
    seen_running = None
    deadline = time.monotonic() + 900
    while True:
        st = studio.state()["studies"]
        s = st["search"]
        if s and s["done"] >= 1 and st["shown_status"] is None and seen_running is None:
            text = page.evaluate("() => document.body.innerText")
            if "best so far" in text:
                seen_running = s["done"]
                shot(page, "search-running")
        if st["shown_status"] is not None:
            break
        assert time.monotonic() < deadline, "the search did not finish"
        time.sleep(0.5)
    print(f"search of 3 trials: {time.monotonic() - t0:.1f} s; best so far seen while "
          f"running after {seen_running} trial(s)")
    assert st["shown_status"] == "completed", st
    s = st["search"]
    assert s["done"] == 3 and s["best"] is not None
    assert s["charts"][0][-1] == "best so far"
    wait_text(page, "trials done 3 of 3")
    wait_text(page, "per trial (minimised)")  # the chart's title
    # the objective chart is drawn in the tab, with its best-so-far line
    traces = page.evaluate("""() => Array.from(document.querySelectorAll('.js-plotly-plot'))
        .flatMap(p => (p.data || []).map(d => d.name))""")
    assert "best so far" in traces
    shot(page, "search-finished")
    _doc_shot(page, shot, "docs-search", scroll_to="Design search")
    # pop the charts out: large, legend clear of the axis titles
    click(page, "Pop out charts")
    st = studio.wait_state(lambda s: s["studies"]["popout"]["open"], what="pop-out")
    wait_text(page, "Close charts window")
    page.wait_for_timeout(1500)
    boxes = page.evaluate("""() => Array.from(document.querySelectorAll('.js-plotly-plot'))
        .map(p => { const r = p.getBoundingClientRect();
          const box = s => { const e = p.querySelector(s);
            if (!e) return null; const b = e.getBoundingClientRect();
            return [b.left, b.top, b.right, b.bottom]; };
          return {w: r.width, h: r.height, legend: box('.legend'), x: box('.xtitle'),
                  y: box('.ytitle'), title: (p.layout.title || {}).text}; })""")
    big = [b for b in boxes if b["w"] > 700]
    assert big, boxes
    for b in big:
        assert b["h"] > 400
        for axis in ("x", "y"):
            L, A = b["legend"], b[axis]
            if L and A:  # no overlap of the legend's box and an axis title's box
                assert L[2] <= A[0] or A[2] <= L[0] or L[3] <= A[1] or A[3] <= L[1], b
    shot(page, "search-popout")
    _doc_shot(page, shot, "docs-popout")
    click(page, "Close charts window")
    studio.wait_state(lambda s: not s["studies"]["popout"]["open"], what="pop-out closed")
    # load the best trial's design into the design view
    best = s["best"]
    label = next(t for t in s["trials"] if t.startswith(f"trial {best['trial']}:"))
    select(page, "trial", label)
    page.wait_for_timeout(500)
    click(page, "Load trial's design")
    r = best["params"]["brushes.0.root_radius"]
    st = studio.wait_state(lambda s: s["scene"]["brushes"][0]["root_radius"]
                           == pytest.approx(r), what="the trial's design loaded")
    assert st["mode"] == "design" and st["scene_name"].endswith(f"_trial{best['trial']}")
    wait_text(page, f"Loaded trial {best['trial']}'s design")
    shot(page, "trial-loaded")
    # a reload keeps the loaded design (the tab's draft)
    page.reload()
    page.get_by_label("rows", exact=True).wait_for(timeout=90_000)
    st = studio.wait_state(lambda s: s["scene"]["brushes"][0]["root_radius"]
                           == pytest.approx(r), timeout=30, what="the design after reload")
