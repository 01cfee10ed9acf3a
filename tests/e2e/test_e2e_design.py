"""Design feedback in a real browser (issue 14): a body that starts inside the brush is
flagged in the design before Start (defect 1). Screenshots under tests/e2e/artifacts/."""
from __future__ import annotations

import json
import time

from conftest import click, open_preset, upload, wait_text


def _page_text(page) -> str:
    """All the panel's text, folded folders included (their content stays in the DOM)."""
    return page.evaluate("() => document.body.textContent")


def _wait_dom_text(page, text: str, timeout: float = 60.0, present: bool = True) -> None:
    deadline = time.monotonic() + timeout
    while (text in _page_text(page)) != present:
        assert time.monotonic() < deadline, f"{text!r} {'never' if present else 'still'} " \
                                            f"in the page"
        time.sleep(0.2)


def test_e2e_body_inside_the_brush_is_flagged_before_start(studio, page, shot, tmp_path,
                                                          demo_scene_dict):
    open_preset(studio, "demo", page)
    st = studio.wait_state(lambda s: s["scene_name"] is not None, what="demo")
    assert st["overlaps"] == []
    # the reproduction: the demo's body as a 20 mm box at z = 33.5 mm reaches
    # 23.5 mm, inside the 33 mm bristles (uploaded as a design file, as a user would share it)
    scene = demo_scene_dict
    scene["bodies"][0]["shape"] = {"type": "box", "size": [0.02, 0.02, 0.02]}
    path = tmp_path / "box_in_brush.json"
    path.write_text(json.dumps(scene))
    upload(page, path)
    st = studio.wait_state(lambda s: s["overlaps"], what="overlap found")
    (o,) = st["overlaps"]
    assert o["kind"] == "body-bristle" and o["body"] == "wedge"
    assert o["depth_m"] > 0.009  # 9.5 mm below the tips plus the tip radius
    # the message under the Body folder, the pointer to it in the summary on top
    _wait_dom_text(page, "starts inside 35 bristles of brush 'brush', up to 10 mm deep")
    wait_text(page, "the design starts overlapping")
    shot(page, "overlap-flagged")
    # Start is refused with the same message instead of running meaningless physics
    click(page, "Run", role="tab")
    click(page, "Start run")
    wait_text(page, "Refused: initial overlap")
    assert studio.state()["active_job"] is None
    click(page, "Design", role="tab")
    # another design: the message goes
    open_preset(studio, "demo", page)
    studio.wait_state(lambda s: not s["overlaps"], what="overlap cleared")
    _wait_dom_text(page, "Start would be refused", present=False)  # (the Run tab keeps its note)
    _wait_dom_text(page, "the design starts overlapping", present=False)
