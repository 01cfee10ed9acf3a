"""Two tabs, two designs (issue 14, defect 3): each browser tab has its own session (design,
playback, selection); opening a preset by URL or editing in one tab leaves the other alone;
a design is shared by a link that opens a copy in a new session."""
from __future__ import annotations

import re
import time

from conftest import click_until, set_field

PRESET = "space_fur"  # 11 rows: the demo has 17


def _open(browser, url: str):
    context = browser.new_context(viewport={"width": 1100, "height": 800})
    page = context.new_page()
    page.goto(url)
    page.get_by_label("rows", exact=True).wait_for(timeout=60_000)
    return page


def _rows(studio, client) -> int:
    return studio.get(f"/studio/state?client={client}")["scene"]["brushes"][0]["rows"]


def test_e2e_two_tabs_have_separate_designs(studio, browser, shot):
    from studio import presets

    a = _open(browser, studio.url)
    st = studio.wait_state(lambda s: s["client"] is not None and len(s["sessions"]) == 1,
                           what="tab A's session")
    client_a = st["client"]
    assert st["scene_name"] == presets.demo_scene().name
    # tab B opens the studio on a preset through its URL: a new session on that preset
    b = _open(browser, f"{studio.api}/studio?preset={PRESET}")
    # the page's URL names its design (reload, share): the preset it opened, until the tab's
    # own draft takes its place (issue 29 item 2: a reload keeps the edits)
    assert f"preset/{PRESET}" in b.url or "%2Fdraft%2F" in b.url or "/draft/" in b.url
    st = studio.wait_state(lambda s: len(s["sessions"]) == 2, what="tab B's session")
    client_b = st["client"]
    assert client_b != client_a
    wedge = presets.load_preset(PRESET)
    assert st["scene_name"] == wedge.name
    # ... and tab A still has the demo (the defect: opening a preset replaced every tab's)
    st_a = studio.get(f"/studio/state?client={client_a}")
    assert st_a["scene_name"] == presets.demo_scene().name
    assert _rows(studio, client_a) == 17 != wedge.brushes[0].rows
    # an edit in tab A stays in tab A
    set_field(a, studio, "rows", "3", lambda s: _rows(studio, client_a) == 3)
    assert _rows(studio, client_b) == wedge.brushes[0].rows
    assert b.get_by_label("rows", exact=True).input_value() == str(wedge.brushes[0].rows)
    shot(a, "tab-a-edited")
    shot(b, "tab-b-untouched")
    # tab A shares its design by link; B opens it: a copy, in B's new session
    def shown_link():
        m = re.search(r"http://\S+/design/[0-9a-f]+", a.evaluate("() => document.body.innerText"))
        return m.group(0) if m else None

    link = click_until(a, "Share this design (link)", shown_link, what="the share link")
    b.goto(link)
    b.get_by_label("rows", exact=True).wait_for(timeout=60_000)
    deadline = time.monotonic() + 30
    while b.get_by_label("rows", exact=True).input_value() != "3":
        assert time.monotonic() < deadline, "the shared design never showed in tab B"
        time.sleep(0.2)
    st = studio.state()  # the newest session: B's after its reload
    assert st["client"] not in (client_a, client_b) and st["scene"]["brushes"][0]["rows"] == 3
    shot(b, "tab-b-shared-link")
    a.context.close()
    b.context.close()
