"""Guides in the 3D view, in a real browser (issue 14, item 8): axes at the origin and a
scale bar sized to the design, which can be hidden; Fit view brings the camera back to
frame the design. Screenshots under tests/e2e/artifacts/."""
from __future__ import annotations

import numpy as np

from conftest import click, open_preset, set_field


def test_e2e_axes_scale_bar_and_fit_view(studio, page, shot):
    from studio.web import guides as ug

    open_preset(studio, "demo", page)
    st = studio.wait_state(lambda s: s["guides"]["scale_bar_mm"] > 0, what="guides")
    # the demo: 17 x 5 bristles 33 mm long under a 20 mm wedge: about 50 mm across
    assert st["guides"]["visible"] and st["guides"]["scale_bar_mm"] == 10.0
    shot(page, "demo-guides")
    # a design 120 mm tall: the bar follows (a third of it, rounded down to 1, 2, 5 x 10^k)
    set_field(page, studio, "bristle length [mm]", "120",
              lambda s: s["scene"]["brushes"][0]["bristle_length"] == 0.12)
    st = studio.wait_state(lambda s: s["guides"]["scale_bar_mm"] == 20.0, what="a 20 mm bar")
    shot(page, "tall-design-guides")  # (the labels are drawn in WebGL: looked at, not read)
    # Fit view: the camera goes to frame the design's extent
    lo, hi = (np.array(e) for e in st["guides"]["extent_mm"])
    position, look_at = ug.camera_for(lo, hi)
    click(page, "Fit view")
    st = studio.wait_state(
        lambda s: s["camera"] is not None and
        np.allclose(s["camera"]["look_at"], look_at, atol=0.5), what="the camera aimed")
    # (0.5 mm: the browser reports the camera in float32, rounded)
    assert np.allclose(st["camera"]["position"], position, atol=0.5)
    shot(page, "fit-view")
    # hidden on request
    page.get_by_label("axes and scale bar", exact=True).evaluate("e => e.click()")
    studio.wait_state(lambda s: not s["guides"]["visible"], what="guides hidden")
