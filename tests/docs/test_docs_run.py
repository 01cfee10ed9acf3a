"""Documentation that runs: every fenced code block of README.md, docs/*.md and
static_presets/README.md is executed. (The scene example of docs/scene.md, a ``json`` block,
is validated by tests/engine/test_spec.py.)

Each ``bash``/``sh``/``shell`` block runs in ``bash -e`` and each ``python`` block in a fresh
``python`` subprocess, in a new empty temporary folder, and must exit 0. The folder holds one
thing besides: ``static_presets`` (a link to the repository's), because the docs say their
commands run from the repository root, where the presets are. ``brush-studio`` resolves to
*this* checkout's ``studio.cli.main`` (a shim first on ``PATH``, ``PYTHONPATH`` = the checkout),
never to whatever an editable install elsewhere points at.

Every fence must have an info string: ``bash``/``python`` blocks run, anything else
(``text`` for a synopsis or an output, ``json``) is not code. An HTML comment on the lines
right before a fence says more about it:

``<!-- docs: not-run REASON -->``
    an illustration only (a server that stays up, a docker build, a benchmark of minutes);
    the reason is required.
``<!-- docs: session NAME -->``
    blocks of one file with the same session run one after another in the same folder
    (the first makes the file the next reads).
``<!-- docs: replace "OLD" -> "NEW" REASON -->``
    run the block with OLD replaced by NEW (e.g. drop the ``pip install`` of the README's
    first command: the test runs inside the installed checkout); the reason is required.
``<!-- docs: fast "OLD" -> "NEW" -->``
    the same, only with reduced sizes (``BRUSH_DOCS_FAST=1``, the default here; set
    ``BRUSH_DOCS_FAST=0`` to run the documented sizes).
``<!-- docs: in-checkout -->``
    run in the repository root instead of a temporary folder (the README's test command).
``<!-- docs: server -->``
    the block talks to a headless server at ``127.0.0.1:8000`` (curl, the Python client):
    the test starts ``brush-studio serve --headless`` on a free port (one for the module,
    started when a block first needs it, stopped at the end) and runs the block with that
    address in place of ``127.0.0.1:8000``, which the block must contain.
``<!-- docs: output -->`` (before a ``text`` block)
    the output of the block before it: each non-empty line must appear, in order, in that
    block's stdout, ``...`` standing for any text (a shape, not the numbers).

A documented command that breaks makes its block's test fail, with the command and its
output in the message.
"""
from __future__ import annotations

import importlib.util
import os
import re
import shlex
import signal
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC_FILES = ([ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
             + [ROOT / "static_presets" / "README.md"])
RUN_LANGS = {"bash": "bash", "sh": "bash", "shell": "bash", "python": "python", "py": "python"}
FAST = os.environ.get("BRUSH_DOCS_FAST", "1") != "0"
# one block may run a small study or a short simulation; minutes mean a size was not reduced
BLOCK_TIMEOUT_S = float(os.environ.get("BRUSH_DOCS_TIMEOUT", "300"))
# the engine's first compile (a cold numba cache) is done once, before any block, with its
# own limit: about 100 CPU-s, 5 min of wall time on a loaded 2-core machine; 30 min is a hang
WARM_TIMEOUT_S = float(os.environ.get("BRUSH_DOCS_WARM_TIMEOUT", "1800"))

# the README's test command, run by this test with BRUSH_DOCS_FAST=0, would run this test
# again, and so on: inside a documented command this module does nothing
pytestmark = pytest.mark.skipif(bool(os.environ.get("BRUSH_DOCS_NESTED")),
                                reason="run by a documented command inside the docs test")

_FENCE = re.compile(r"^(\s*)(```+)(.*)$")
_MARKER = re.compile(r"<!--\s*docs:\s*(.*?)\s*-->")
_REPLACE = re.compile(r'^"((?:[^"\\]|\\.)*)"\s*->\s*"((?:[^"\\]|\\.)*)"\s*(.*)$', re.S)


@dataclass
class Block:
    path: Path
    line: int                  # 1-based line of the opening fence
    lang: str                  # the info string's first word
    code: str
    markers: list[str] = field(default_factory=list)
    output: "Block | None" = None   # the `<!-- docs: output -->` block after it

    @property
    def id(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"

    def marker(self, key: str) -> list[str]:
        return [m[len(key):].strip() for m in self.markers
                if m == key or m.startswith(key + " ")]


def _unescape(text: str) -> str:
    return text.replace('\\"', '"').replace("\\\\", "\\")


def parse_blocks(path: Path) -> list[Block]:
    """Every fenced block of a markdown file, with the docs markers right before it."""
    lines = path.read_text().splitlines()
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, info = m.groups()
        start = i
        body = []
        i += 1
        while i < len(lines) and not lines[i].strip().startswith(fence):
            line = lines[i]
            body.append(line[len(indent):] if line.startswith(indent) else line)
            i += 1
        i += 1  # the closing fence
        markers: list[str] = []
        j = start - 1
        while j >= 0 and (not lines[j].strip() or _MARKER.search(lines[j])):
            if not lines[j].strip():
                if markers:  # a blank line ends the markers that belong to this fence
                    break
            else:
                markers[:0] = _MARKER.findall(lines[j])
            j -= 1
        blocks.append(Block(path, start + 1, info.strip().split(" ")[0] if info.strip()
                            else "", "\n".join(body) + "\n", markers))
    # attach output blocks to the block before them
    kept: list[Block] = []
    for b in blocks:
        if "output" in b.markers:
            assert kept, f"{b.id}: an output block with no block before it"
            kept[-1].output = b
        else:
            kept.append(b)
    return kept


ALL_BLOCKS = [b for p in DOC_FILES for b in parse_blocks(p)]


def _runnable(b: Block) -> bool:
    return b.lang in RUN_LANGS


def _sessions() -> list[tuple[str, list[Block]]]:
    """Test units: one block, or the blocks of one session in document order."""
    units: dict[str, list[Block]] = {}
    for b in ALL_BLOCKS:
        if not _runnable(b) or b.marker("not-run"):
            continue
        names = b.marker("session")
        key = f"{b.path.relative_to(ROOT)}[{names[0]}]" if names else b.id
        units.setdefault(key, []).append(b)
    return list(units.items())


def _apply_replacements(b: Block) -> str:
    code = b.code
    for key in ("replace", "fast"):
        if key == "fast" and not FAST:
            continue
        for arg in b.marker(key):
            m = _REPLACE.match(arg)
            assert m, f"{b.id}: {key} marker must be \"OLD\" -> \"NEW\" [reason]: {arg!r}"
            old, new, reason = _unescape(m.group(1)), _unescape(m.group(2)), m.group(3)
            if key == "replace":
                assert reason, f"{b.id}: a replace marker states its reason"
            assert old in code, f"{b.id}: {key} marker's text {old!r} is not in the block"
            code = code.replace(old, new)
    return code


def make_shim(d: Path, executable: str = sys.executable) -> Path:
    """``d`` with a ``brush-studio`` that runs this checkout's CLI and a ``python``, both
    running ``executable`` itself. Scripts, not links: Python finds its virtual environment
    from the ``pyvenv.cfg`` beside the path it was started by, so a link to a venv's
    interpreter from elsewhere starts the base interpreter without the venv's packages."""
    d.mkdir(parents=True, exist_ok=True)
    for name, args in (("brush-studio", " -m studio.cli"), ("python", "")):
        exe = d / name
        exe.write_text(f"#!/bin/sh\nexec {shlex.quote(executable)}{args} \"$@\"\n")
        exe.chmod(0o755)
    return d


@pytest.fixture(scope="module")
def shim_dir(tmp_path_factory) -> Path:
    """A folder with a ``brush-studio`` that runs this checkout's CLI, and ``python``."""
    return make_shim(tmp_path_factory.mktemp("shim"))


@pytest.fixture(scope="module")
def warm_engine(tmp_path_factory, shim_dir) -> None:
    """Compile the engine once, before the first block that runs it, with its own generous
    limit (``WARM_TIMEOUT_S``): a short run of the demo scene fills numba's cache, so that
    on a cold cache the first documented command does not spend its per-block limit
    compiling. Warm, this takes seconds."""
    d = tmp_path_factory.mktemp("warm")
    env = _env(shim_dir)
    steps = [[sys.executable, "-m", "studio.cli", "demo", "--scene-only", "-o", str(d)],
             [sys.executable, "-m", "studio.cli", "run", str(d / "scene.json"), "-o",
              str(d / "warm.h5"), "--until", "0.002", "-q"]]
    for argv in steps:
        try:
            proc = subprocess.run(argv, cwd=d, env=env, capture_output=True, text=True,
                                  timeout=WARM_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pytest.fail(f"compiling the engine ran past {WARM_TIMEOUT_S:.0f} s: {argv}")
        assert proc.returncode == 0, f"warm-up {argv} failed:\n{proc.stdout}\n{proc.stderr}"


def _env(shim: Path) -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{shim}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = str(ROOT) + (os.pathsep + env["PYTHONPATH"]
                                     if env.get("PYTHONPATH") else "")
    env["MPLBACKEND"] = "Agg"
    env.setdefault("NUMBA_NUM_THREADS", "2")
    env["BRUSH_DOCS_FAST"] = "1" if FAST else "0"
    env["BRUSH_DOCS_NESTED"] = "1"
    return env


def check_output_shape(expected: str, actual: str) -> list[str]:
    """Lines of ``expected`` (``...`` = any text) not found, in order, in ``actual``."""
    out_lines = actual.splitlines()
    missing = []
    k = 0
    for want in (ln.strip() for ln in expected.splitlines()):
        if not want:
            continue
        pattern = re.compile(".*?".join(re.escape(part.strip()) if part.strip() else ""
                                        for part in want.split("...")))
        for idx in range(k, len(out_lines)):
            if pattern.search(out_lines[idx]):
                k = idx + 1
                break
        else:
            missing.append(want)
    return missing


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


SERVER_ADDRESS = "127.0.0.1:8000"  # the address the docs show for a local headless server


@pytest.fixture(scope="module")
def docs_server(tmp_path_factory):
    """A headless server on a free port for the ``server`` blocks: the server tests'
    ``ServerProcess`` (tests/server/conftest.py), so both start it the same way."""
    spec = importlib.util.spec_from_file_location(
        "_docs_server_fixtures", ROOT / "tests" / "server" / "conftest.py")
    fixtures = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fixtures)
    server = fixtures.ServerProcess(tmp_path_factory.mktemp("docs-server") / "data", workers=2)
    yield server
    server.stop()


def _run_block(b: Block, cwd: Path, env: dict, server_url: "str | None" = None) -> None:
    code = _apply_replacements(b)
    if b.marker("server"):
        assert SERVER_ADDRESS in code, f"{b.id}: a server block names {SERVER_ADDRESS}"
        code = code.replace(f"http://{SERVER_ADDRESS}", server_url)
    if RUN_LANGS[b.lang] == "bash":
        argv = ["bash", "-e", "-o", "pipefail", "-c", code]
    else:
        script = cwd / f"_docs_snippet_{b.line}.py"
        script.write_text(code)
        argv = [sys.executable, str(script)]
    # its own process group, so that whatever it leaves behind (a server started with `&`)
    # is ended with it
    proc = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=BLOCK_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        _kill_group(proc)
        stdout, _ = proc.communicate()
        pytest.fail(f"{b.id}: ran past {BLOCK_TIMEOUT_S:.0f} s (reduce its size with a "
                    f"'docs: fast' marker)\n--- code\n{code}\n--- stdout\n{stdout}")
    finally:
        _kill_group(proc)
    report = (f"\n--- code ({b.id})\n{code}--- exit {proc.returncode}\n--- stdout\n"
              f"{stdout[-4000:]}\n--- stderr\n{stderr[-4000:]}")
    assert proc.returncode == 0, f"{b.id}: documented block failed" + report
    if b.output is not None:
        missing = check_output_shape(b.output.code, stdout)
        assert not missing, f"{b.id}: output lacks the documented lines {missing}" + report


SESSIONS = _sessions()


@pytest.mark.parametrize("blocks", [s for _, s in SESSIONS], ids=[k for k, _ in SESSIONS])
def test_documented_block_runs(blocks, tmp_path, shim_dir, warm_engine, request):
    env = _env(shim_dir)
    (tmp_path / "static_presets").symlink_to(ROOT / "static_presets")
    url = (request.getfixturevalue("docs_server").url
           if any(b.marker("server") for b in blocks) else None)
    for b in blocks:
        cwd = ROOT if b.marker("in-checkout") else tmp_path
        _run_block(b, cwd, env, url)


# ----------------------------------------------------------------------------- markup
def test_every_fence_says_what_it_is():
    """An untyped fence could hide a command nobody runs: each one names its language."""
    untyped = [b.id for b in ALL_BLOCKS if not b.lang]
    assert not untyped, f"fences without an info string (bash/python to run, text or json " \
                        f"otherwise): {untyped}"


def test_not_run_blocks_give_their_reason():
    bad = [b.id for b in ALL_BLOCKS for r in b.marker("not-run") if not r]
    assert not bad, f"not-run markers without a reason: {bad}"


def test_output_shape_matching_catches_a_changed_output():
    """The shape check is not vacuous: a documented line missing from stdout is reported,
    and ``...`` stands for varying numbers."""
    assert check_output_shape("OK: 'x': ... nodes\nWrote:", "OK: 'x': 510 nodes\nWrote:") == []
    assert check_output_shape("Wrote:\nOK: ...", "OK: 1\nWrote:") == ["OK: ..."]


def test_server_blocks_name_the_documented_address():
    """A ``server`` block that no longer names 127.0.0.1:8000 would talk to nothing the test
    controls: each one names it (and so is run against the test's server)."""
    bad = [b.id for b in ALL_BLOCKS if b.marker("server") and SERVER_ADDRESS not in b.code]
    assert not bad, f"server blocks without {SERVER_ADDRESS}: {bad}"


def test_markers_are_parsed(tmp_path):
    md = tmp_path / "x.md"
    md.write_text('text\n\n<!-- docs: not-run a server -->\n<!-- docs: session s -->\n'
                  '```bash\necho hi\n```\n\n<!-- docs: output -->\n```text\nhi\n```\n')
    (b,) = parse_blocks(md)
    assert b.marker("not-run") == ["a server"] and b.marker("session") == ["s"]
    assert b.output is not None and b.output.code == "hi\n"


# ----------------------------------------------------------------- the interpreter used
def test_blocks_run_with_the_interpreter_of_a_virtual_environment(tmp_path):
    """The shim's ``python`` sees a venv's own packages (issue 28, item 5). Bug caught: the
    shim linked ``python`` to the venv's interpreter; started through the link, Python found
    no ``pyvenv.cfg`` and ran as the base interpreter (``No module named 'h5py'``)."""
    import venv

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(system_site_packages=True, with_pip=False, symlinks=True).create(env_dir)
    venv_python = env_dir / "bin" / "python"
    site = subprocess.run([str(venv_python), "-c", "import site; print(site.getsitepackages()[0])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    (Path(site) / "only_in_this_venv.py").write_text("WHERE = 'venv'\n")
    shim = make_shim(tmp_path / "shim", str(venv_python))
    proc = subprocess.run(["python", "-c", "import only_in_this_venv, sys; print(sys.prefix)"],
                          env={**os.environ, "PATH": f"{shim}{os.pathsep}{os.environ['PATH']}"},
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert Path(proc.stdout.strip()) == env_dir


@pytest.mark.slow
def test_the_readme_commands_pass_in_a_fresh_venv(tmp_path):
    """The README's first screen (the demo and the test command's collection) in a fresh
    virtual environment (``--system-site-packages``: the dependencies come from this
    machine, nothing is downloaded; the checkout on its path as an editable install puts
    it), run by that venv's own interpreter: the docs test of README.md inside it must pass
    (issue 28, item 5: it failed with "No module named 'h5py'" through the linked python)."""
    import venv

    env_dir = tmp_path / "venv"
    # (no pip of its own: nothing is installed into it)
    venv.EnvBuilder(system_site_packages=True, with_pip=False, symlinks=True).create(env_dir)
    py = str(env_dir / "bin" / "python")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "BRUSH_DOCS_NESTED")}
    env["PATH"] = f"{env_dir / 'bin'}{os.pathsep}{env['PATH']}"
    env["VIRTUAL_ENV"] = str(env_dir)
    # the checkout on the venv's path, as `pip install -e .` puts it (building the editable
    # wheel needs setuptools >= 68 from the package index: this test downloads nothing)
    site = subprocess.run([py, "-c", "import site; print(site.getsitepackages()[0])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    (Path(site) / "brush_studio_checkout.pth").write_text(str(ROOT) + "\n")
    # the README's blocks only (not this test again: -k is case-blind, "readme" is in its name)
    proc = subprocess.run([py, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "not slow",
                           str(Path(__file__)), "-k", "README and not venv"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=3600)
    assert proc.returncode == 0, proc.stdout[-6000:] + proc.stderr[-3000:]
    assert " passed" in proc.stdout and "failed" not in proc.stdout
