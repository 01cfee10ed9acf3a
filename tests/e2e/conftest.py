"""Fixtures of the browser tests: the studio as a subprocess on free ports of 127.0.0.1,
and a headless Debian chromium driven by Playwright (no browser is ever downloaded).

``studio``: a running ``brush-studio studio`` (1 worker, its own data folder), stopped with
SIGINT (then killed) at the end of the module. ``page``: a fresh browser page on the studio,
connected. Screenshots go to tests/e2e/artifacts/ (git-ignored).
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(__file__).resolve().parent / "artifacts"
CHROMIUM = os.environ.get("BRUSH_STUDIO_CHROMIUM", "/usr/bin/chromium")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class StudioProcess:
    def __init__(self, proc: subprocess.Popen, port: int, api_port: int, log: Path):
        self.proc, self.port, self.api_port, self.log = proc, port, api_port, log
        self.url = f"http://127.0.0.1:{port}/"
        self.api = f"http://127.0.0.1:{api_port}"

    def get(self, path: str) -> dict:
        with urllib.request.urlopen(self.api + path, timeout=10) as r:
            return json.loads(r.read())

    def state(self) -> dict:
        return self.get("/studio/state")

    def wait_state(self, predicate, timeout: float = 20.0, what: str = "state"):
        """Poll /studio/state until ``predicate(state)`` is true; return that state."""
        deadline = time.monotonic() + timeout
        st = None
        while time.monotonic() < deadline:
            st = self.state()
            if predicate(st):
                return st
            time.sleep(0.1)
        raise AssertionError(f"timed out waiting for {what}; last state: "
                             f"{ {k: v for k, v in (st or {}).items() if k != 'scene'} }")


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    if not Path(CHROMIUM).exists():
        pytest.skip(f"no chromium at {CHROMIUM}")
    pytest.importorskip("playwright")
    tmp = tmp_path_factory.mktemp("studio")
    port, api_port = _free_port(), _free_port()
    log = tmp / "studio.log"
    env = dict(os.environ, NUMBA_NUM_THREADS="1", PYTHONUNBUFFERED="1")
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    with open(log, "w") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "studio.cli", "studio", "--host", "127.0.0.1",
             "--port", str(port), "--api-port", str(api_port), "--data", str(tmp / "data"),
             "--workers", "1"], cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT)
    s = StudioProcess(proc, port, api_port, log)
    deadline = time.monotonic() + 60
    while True:
        try:
            s.state()
            break
        except OSError:
            if proc.poll() is not None or time.monotonic() > deadline:
                proc.kill()
                raise RuntimeError(f"the studio did not start:\n{log.read_text()}")
            time.sleep(0.2)
    yield s
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@pytest.fixture(scope="module")
def browser():
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(
            executable_path=CHROMIUM, headless=True,
            args=["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                  "--ignore-gpu-blocklist"])
        yield b
        b.close()


@pytest.fixture(scope="module")
def page(studio, browser):
    """A page on the studio, connected (the design panels are shown); one per test module
    (loading the page costs seconds with software WebGL), so tests start by opening a
    preset."""
    context = browser.new_context(viewport={"width": 1100, "height": 800},
                                  accept_downloads=True)
    pg = context.new_page()
    pg.goto(studio.url)
    pg.get_by_label("rows", exact=True).wait_for(timeout=90_000)  # (a loaded CI machine)
    yield pg
    context.close()


@pytest.fixture
def shot(request):
    """``shot(page, name)``: save a screenshot as tests/e2e/artifacts/<test>-<name>.png."""
    ARTIFACTS.mkdir(exist_ok=True)

    def take(pg, name: str) -> Path:
        path = ARTIFACTS / f"{request.node.name}-{name}.png"
        pg.wait_for_timeout(700)  # let the 3D view render the last update
        # (90 s: with software WebGL on a loaded 2-core machine a page once took over the
        # default 30 s to give a frame)
        pg.screenshot(path=str(path), timeout=90_000)
        return path

    return take


@pytest.fixture
def artifacts_dir():
    ARTIFACTS.mkdir(exist_ok=True)
    return ARTIFACTS


def clean(path: Path) -> None:
    shutil.rmtree(path, ignore_errors=True)


def _loaded(state: dict, scene_name: str, rows: str) -> bool:
    """Whether the session shows a freshly loaded scene ``scene_name`` (no edits yet)."""
    return state["scene_name"] == scene_name and not state.get("edited") and \
        str(state["scene"]["brushes"][0]["rows"]) == rows


def _close_dialogs(page) -> None:
    """Answer "Keep editing" in every discard-edits dialog still open: one an earlier
    attempt or test left (a second Load preset click on a busy page opens a second dialog)
    covers the panel, and the Presets dropdown under it never opens (seen in a cold CI
    run's screenshot)."""
    keep = page.get_by_role("button", name="Keep editing", exact=True)
    for _ in range(5):
        if not keep.count():
            return
        keep.first.evaluate("b => b.click()")
        page.wait_for_timeout(500)


def open_preset(studio: StudioProcess, name: str, page=None) -> None:
    """Open a preset in the page's own session (each tab has its own design): choose it in
    the Presets dropdown and press Load preset, as a user would, then wait until the page
    shows the preset's rows (an edit racing the page's update of the same field could be
    overwritten). Without ``page``, only check that the landing route ``/studio?preset=``
    answers with the studio page (opening a new session there)."""
    with urllib.request.urlopen(f"{studio.api}/studio?preset={name}", timeout=20) as r:
        assert r.status == 200
        assert r.url.startswith(studio.url)
    if page is None:
        return
    from studio import presets

    scene = presets.load_preset_or_file(name)
    rows = str(scene.brushes[0].rows)
    # a design with edits asks before they are discarded: its dialog's button (a late
    # attempt may find a dialog an earlier one opened, or two of them: any loads `name`)
    discard = page.get_by_role("button", name=f"Discard edits and load {name}",
                               exact=True)
    for attempt in range(3):
        loads = studio.state()["loads"]
        if not discard.count():
            _close_dialogs(page)   # (a stale dialog over the panel eats the dropdown's click)
        if discard.count():
            discard.first.evaluate("b => b.click()")
        else:
            box = page.get_by_label("preset", exact=True).first
            if box.input_value() != name:
                box.click(force=True)
                try:
                    # 30 s: in a cold CI run with two xdist workers the page once stayed
                    # busy (software WebGL) through three 10 s tries
                    page.get_by_role("option", name=name, exact=True).click(force=True,
                                                                             timeout=30_000)
                except Exception:  # (a busy page missed the click that opens the list)
                    ARTIFACTS.mkdir(exist_ok=True)
                    try:
                        page.screenshot(path=str(ARTIFACTS / f"open_preset-{name}-"
                                                 f"{attempt}.png"), timeout=30_000)
                    except Exception:
                        pass
                    if attempt == 2:
                        raise
                    page.keyboard.press("Escape")
                    continue
                page.wait_for_timeout(300)
            click(page, "Load preset")
        # wait for the load itself (``loads`` grows when it has finished): a tab that shows
        # the preset already (the studio opens on the demo) looked loaded before the click
        # was handled, and the load's refresh then overwrote a value typed after it
        deadline = time.monotonic() + 30
        st = studio.state()
        while not (st["loads"] > loads and _loaded(st, scene.name, rows)) and \
                time.monotonic() < deadline:
            if discard.count():
                discard.first.evaluate("b => b.click()")
            time.sleep(0.2)
            st = studio.state()
        if st["loads"] > loads and _loaded(st, scene.name, rows):
            break
        if attempt == 2:
            raise AssertionError(f"preset {name} not loaded; last state: "
                                 f"{ {k: v for k, v in st.items() if k != 'scene'} }")
    _close_dialogs(page)
    deadline = time.monotonic() + 30
    while page.get_by_label("rows", exact=True).input_value() != rows:
        assert time.monotonic() < deadline, f"the page never showed {rows} rows"
        time.sleep(0.2)


def wait_text(page, text: str, timeout: float = 30.0) -> None:
    """Wait until the page's visible text contains ``text`` (polling innerText: cheaper
    than Playwright's visibility checks, which wait for animation frames that software
    WebGL delivers slowly on a busy machine)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if text in page.evaluate("() => document.body.innerText"):
            return
        time.sleep(0.2)
    raise AssertionError(f"{text!r} not shown on the page within {timeout} s")


def select(page, label: str, value: str) -> None:
    """Choose ``value`` in the visible dropdown labelled ``label`` (viser's combobox)."""
    box = page.get_by_label(label, exact=True).filter(visible=True)
    for attempt in range(3):  # (a busy page can miss the click that opens the list)
        box.click(force=True)
        try:
            page.get_by_role("option", name=value, exact=True).click(force=True,
                                                                     timeout=10_000)
            return
        except Exception:
            page.keyboard.press("Escape")
            if attempt == 2:
                raise


def click(page, name: str, role: str = "button") -> None:
    """Click a button (or tab) by its accessible name with a DOM click: viser's panel
    handles pointer events itself, and synthetic mouse clicks at the element's coordinates do
    not always reach the button."""
    element = page.get_by_role(role, name=name, exact=True)
    if role == "tab":  # viser's dock tabs start a drag on pointer-down; keys activate them
        element.evaluate("e => e.focus()")
        page.keyboard.press("Enter")
    else:
        element.evaluate("b => b.click()")


def click_until(page, name: str, done, timeout: float = 40.0, what: str = ""):
    """Click the button ``name`` and poll ``done()`` until it returns something truthy, which
    is returned; clicked once more if nothing came after half the timeout. A DOM click that
    lands while viser re-renders the panel (after a server update, which on a loaded machine
    with software WebGL can take seconds) goes to a detached node and is lost, as a
    person's click would be; a person clicks again, and so does this."""
    for attempt in range(2):
        click(page, name)
        deadline = time.monotonic() + timeout / 2
        while time.monotonic() < deadline:
            result = done()
            if result:
                return result
            time.sleep(0.2)
    raise AssertionError(f"{what or name}: nothing after two clicks and {timeout:.0f} s")


def upload(page, path, accept: str = "application/json") -> None:
    """Give a file to the upload button whose input accepts ``accept``."""
    page.locator(f'input[type=file][accept="{accept}"]').set_input_files(str(path))


def run_to_playback(page, studio: StudioProcess, scene: dict, folder: Path) -> dict:
    """Upload ``scene`` (written to ``folder``), start a run of it on the Run tab and wait
    for the finished run in playback (the worker's first run compiles the engine's kernels:
    up to 400 s); returns that state."""
    path = folder / f"{scene['name']}.json"
    path.write_text(json.dumps(scene))
    upload(page, path)
    studio.wait_state(lambda s: s["scene_name"] == scene["name"],
                      what=f"{scene['name']} scene loaded")
    return start_run(page, studio)


def start_run(page, studio: StudioProcess, timeout: float = 400.0,
              what: str = "a finished run in playback") -> dict:
    """Start a run of the design on the Run tab and wait for the finished run in playback
    (more than two frames); returns that state."""
    click(page, "Run", role="tab")
    click(page, "Start run")
    return studio.wait_state(lambda s: s["mode"] == "playback" and s["n_frames"] > 2,
                             timeout=timeout, what=what)


def set_field(page, studio: StudioProcess, label: str, text: str, accepted,
              timeout: float = 20.0) -> dict:
    """Type ``text`` into the input labelled ``label`` and leave it (Tab), then wait until
    ``accepted(state)``. Typed once more if the server has not seen it after half the
    timeout: on a machine so loaded that software WebGL draws about one frame a second, an
    input typed while the page is still applying a server update can be lost."""
    field = page.get_by_label(label, exact=True)
    for attempt in range(2):
        field.fill(text, force=True)
        field.press("Tab")
        try:
            return studio.wait_state(accepted, timeout=timeout / 2, what=f"{label} = {text}")
        except AssertionError:
            if attempt == 1:
                raise
    raise AssertionError("unreachable")
