"""The Run panel in a real browser (issue 14, defects 4-6): the cost of a design beside
Start with a confirmation for long runs, the warning under an unstable dt and the failure
that names it, and a spin_cube preset whose bristles now move in playback, with colour-by
saying which channel a run lacks. Screenshots under tests/e2e/artifacts/."""
from __future__ import annotations

import time

import numpy as np
import pytest

from conftest import click, open_preset, set_field, wait_text


def _choose(page, label: str, option: str) -> None:
    box = page.get_by_label(label, exact=True)
    box.click(force=True)
    page.get_by_role("option", name=option, exact=True).click(force=True, timeout=10_000)


def _open_folder(page, title: str, field: str) -> None:
    """Unfold a folder of the panel and wait until ``field`` in it can be typed into (an
    input filled while the folder still opens can be lost)."""
    if page.get_by_label(field, exact=True).is_visible():
        return  # (open already: a click would fold it)
    page.get_by_text(title, exact=True).first.click(force=True)
    page.get_by_label(field, exact=True).wait_for(state="visible", timeout=20_000)
    page.wait_for_timeout(700)


def _text(page) -> str:
    return page.evaluate("() => document.body.innerText")


def test_e2e_cost_before_start_and_confirmation(studio, page, shot):
    click(page, "Design", role="tab")
    open_preset(studio, "wedge_60", page)
    import engine
    from studio import presets

    cost = engine.estimate(presets.load_preset("wedge_60"))
    click(page, "Run", role="tab")
    wait_text(page, f"{cost.steps:,.0f} steps")  # (the line follows the design within 0.1 s)
    text = _text(page)
    # dt and what limits it, steps, nodes, wall time and file size, from engine.estimate
    for part in (f"dt ~{cost.dt * 1e6:.4g} µs (automatic, limited by the bristles of brush "
                 f"'brush'", f"{cost.n_nodes} nodes", "node-steps/s",
                 f"result file ~{cost.result_bytes / 2**20:.0f} MiB", "Start asks to confirm"):
        assert part in text, (part, text[text.find("Before Start"):][:500])
    shot(page, "run-panel-cost")
    click(page, "Start run")
    wait_text(page, "Start a long run?")
    wait_text(page, "estimated to take")
    shot(page, "confirm-long-run")
    click(page, "Don't start")
    time.sleep(1.0)
    assert studio.state()["active_job"] is None, "declined: nothing was submitted"
    # confirmed: it starts (and is cancelled at once: this test does not run the wedge)
    click(page, "Start run")
    wait_text(page, "Start a long run?")
    click(page, "Start anyway")
    st = studio.wait_state(lambda s: s["active_job"] is not None, what="the run submitted")
    cancel = page.get_by_role("button", name="Cancel run", exact=True)
    deadline = time.monotonic() + 20
    while not cancel.is_enabled():  # (a DOM click on the still-disabled button is lost)
        assert time.monotonic() < deadline, "Cancel run never enabled"
        time.sleep(0.1)
    click(page, "Cancel run")
    studio.wait_state(lambda s: s["active_job"] is None, timeout=60, what="cancelled")
    assert st["active_job"]


@pytest.mark.slow  # a run in the worker (its first run compiles the kernels: 1-3 min cold)
def test_e2e_unstable_dt_warns_and_the_failure_names_it(studio, page, shot):
    click(page, "Design", role="tab")
    open_preset(studio, "spin_cube_40", page)
    _open_folder(page, "Run settings", "dt (0 = automatic) [µs]")
    # the reproduction: dt = 1000 us, about 70 x the automatic 14 us
    set_field(page, studio, "dt (0 = automatic) [µs]", "1000",
              lambda s: s["scene"]["run"]["dt"] == pytest.approx(1e-3))
    wait_text(page, "⚠ dt = 1000 µs is 32.5 × the stability limit 30.8 µs")
    assert "Use 0 (automatic) or less than 30.8 µs" in _text(page)
    page.get_by_label("dt (0 = automatic) [µs]", exact=True).evaluate(
        "e => e.scrollIntoView({block: 'center'})")
    shot(page, "dt-warning")
    click(page, "Run", role="tab")
    wait_text(page, "dt is above the stability limit")
    click(page, "Start run")
    wait_text(page, "The cause is the timestep: run.dt = 0.001 s", timeout=300)
    text = _text(page)
    assert "failed" in text and "tip_variance" not in text
    shot(page, "dt-failure")
    # automatic dt again: the warning goes
    click(page, "Design", role="tab")
    set_field(page, studio, "dt (0 = automatic) [µs]", "0",
              lambda s: s["scene"]["run"]["dt"] is None)
    deadline = time.monotonic() + 20
    while "stability limit 30.8" in _text(page):
        assert time.monotonic() < deadline, "the dt warning stayed"
        time.sleep(0.2)


@pytest.mark.slow  # a run in the worker
def test_e2e_spin_cube_bristles_move_in_playback(studio, page, shot):
    from studio.service.client import Client

    click(page, "Design", role="tab")
    open_preset(studio, "spin_cube_20", page)
    _open_folder(page, "Run settings", "duration [s]")
    assert page.get_by_label("record nodes", exact=True).is_checked()
    assert not page.get_by_label("record bending", exact=True).is_checked()
    set_field(page, studio, "duration [s]", "0.04",
              lambda s: s["scene"]["run"]["duration"] == pytest.approx(0.04))
    click(page, "Run", role="tab")
    wait_text(page, "510 nodes")
    click(page, "Start run")
    st = studio.wait_state(lambda s: s["mode"] == "playback" and s["n_frames"] >= 20,
                           timeout=400, what="the spin_cube run in playback")
    job, n = st["playback_job"], st["n_frames"]
    # the recorded bristles moved (the cube's edge sweeps into the brush from the start)
    x = Client(studio.api).series(job, "nodes/positions")["values"]
    moved = np.linalg.norm(x[-1] - x[0], axis=-1).max()
    assert moved > 1e-4, f"the bristles moved {moved * 1e3:.3f} mm at most"
    # ... and the view draws them moving: frame 0 against the last frame
    click(page, "Results", role="tab")
    slider = page.get_by_role("slider").first
    slider.evaluate("e => e.focus()")
    page.keyboard.press("Home")
    first = studio.wait_state(lambda s: s["frame"] == 0 and s["mode"] == "playback",
                              what="frame 0")["segments_mean_mm"]
    page.keyboard.press("End")
    last = studio.wait_state(lambda s: s["frame"] == n - 1, what="the last frame")
    shift = np.abs(np.subtract(last["segments_mean_mm"], first)).max()
    assert shift > 1e-3, f"the drawn bristles moved {shift} mm on average"
    # colour-by: no bending channel in this preset, and the page says so
    wait_text(page, "recorded no bending moments")
    shot(page, "colour-by-note")
    _choose(page, "colour bristles by", "deflection")
    deadline = time.monotonic() + 20
    while "recorded no bending moments" in _text(page):
        assert time.monotonic() < deadline, "the note stayed for deflection"
        time.sleep(0.2)
    shot(page, "deflection-playback")
