"""Fixtures shared by every test package.

``demo_scene_dict``: the embedded default scene (``studio/data/demo_scene.json``) as a dict.
``tiny_scene``: a factory of small, fast scenes (a 2 x 2 brush pressed by a box) as dicts;
tests change what they need and write them under pytest's ``tmp_path``.
``tiny_tmpfs``, ``fill_disk``: a 4 MiB tmpfs and a way to fill it (a full disk, for real).
"""
from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
from importlib.resources import files
from pathlib import Path
from typing import Optional

# CI machines have 2 cores; numba's thread pool must not oversubscribe them. Set before any
# test imports numba (this file is imported first).
os.environ.setdefault("NUMBA_NUM_THREADS", "2")

# pytest puts tests/ on sys.path to import this file, and tests/engine and tests/studio
# (folders without __init__.py) would then be found as namespace packages named `engine`
# and `studio`, shadowing the real ones when the project is installed in editable mode and
# the repository root is not on sys.path (plain `pytest` rather than `python -m pytest`).
# A regular package anywhere on sys.path wins over a namespace package, so this suffices.
_ROOT = str(Path(__file__).resolve().parents[1])
if _ROOT not in sys.path:
    sys.path.append(_ROOT)

import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="session")
def _engine_scratch_in_pytest_tmp(tmp_path_factory):
    """``engine.run(system)`` without an output writes ``brush-studio-*/result.h5`` under the
    temporary folder and leaves it for the caller (its result points there). Tests that do so
    write under pytest's base temp (pytest keeps the last three), not /tmp forever."""
    import tempfile

    before = tempfile.tempdir
    tempfile.tempdir = str(tmp_path_factory.mktemp("scratch"))
    yield
    tempfile.tempdir = before


TINY_SCENE = {
    "schema_version": 1,
    "name": "tiny",
    "description": "2 x 2 silicone brush (10 mm bristles, 4 nodes each) pressed 0.8 mm by a "
                   "small rigid box for 4 ms: a scene for fast tests",
    "materials": {
        "silicone": {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1100.0},
        "pla": {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1250.0},
    },
    "contact_pairs": [
        {"materials": ["silicone", "silicone"], "friction_angle": 0.767945},
        {"materials": ["silicone", "pla"], "friction_angle": 0.418879},
    ],
    "brushes": [
        {"name": "brush", "material": "silicone", "rows": 2, "columns": 2,
         "pitch": [0.003, 0.003], "bristle_length": 0.01, "root_radius": 0.0008,
         "tip_radius": 0.0005, "n_nodes": 4},
    ],
    "bodies": [
        # box bottom face at z = 0.0107 m: 0.2 mm above the tip nodes' surfaces (tip node
        # centre 0.010 m + tip radius 0.5 mm). It moves 1 mm down in 4 ms, compressing the
        # bristles 0.8 mm, then holds (so longer runs stay safe). Pressing much faster or
        # deeper overloads the contacts (overlap > half a radius: an instability).
        {"name": "box", "material": "pla",
         "shape": {"type": "box", "size": [0.01, 0.01, 0.002]},
         "pose": {"position": [0.0, 0.0, 0.0117]},
         "motion": {"type": "kinematic",
                    "profile": {"kind": "constant", "velocity": [0.0, 0.0, -0.25],
                                "duration": 0.004}}},
    ],
    # gravity on: with no load at all before the box arrives, every energy is round-off
    # (1e-32 J) and the engine's relative energy-balance check fires on it (reported)
    "environment": {"gravity": [0.0, 0.0, -9.81]},
    "run": {"duration": 0.004, "record_interval": 0.0005},
}


@pytest.fixture
def demo_scene_dict() -> dict:
    """The embedded demo scene as a fresh dict (safe to modify)."""
    return json.loads((files("studio") / "data" / "demo_scene.json").read_text())


@pytest.fixture
def tiny_scene():
    """Factory: ``tiny_scene()`` returns a fresh dict of the tiny scene; keyword arguments
    update its ``run`` settings, e.g. ``tiny_scene(duration=0.002)``."""

    def make(**run_settings) -> dict:
        scene = copy.deepcopy(TINY_SCENE)
        scene["run"].update(run_settings)
        return scene

    return make


@pytest.fixture
def write_scene(tmp_path):
    """``write_scene(scene_dict, name="scene.json") -> Path``: the scene as a JSON file in
    the test's tmp_path."""

    def write(scene: dict, name: str = "scene.json"):
        path = tmp_path / name
        path.write_text(json.dumps(scene, indent=1))
        return path

    return write



def mount_tmpfs(mnt: Path, size: str = "4m") -> Optional[str]:
    """Mount a tmpfs of ``size`` on the folder ``mnt``: None, or why it could not be (not
    root, no mount). Unmount with ``umount -l``. The storage tests and
    benchmarks/service_robustness.py fill one to reproduce a full disk."""
    if os.geteuid() != 0:
        return "mounting a tmpfs needs root"
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)],
                       capture_output=True, text=True)
    return None if r.returncode == 0 else f"cannot mount a tmpfs here: {r.stderr.strip()}"


def fill_disk(path: Path) -> None:
    """Write ``path`` until its disk is full (it may be full already): 64 KiB blocks, then
    the last partial blocks 512 bytes at a time."""
    for block in (65536, 512):
        try:
            with open(path, "ab") as f:
                while True:
                    f.write(b"\0" * block)
                    f.flush()
        except OSError:
            pass


@pytest.fixture
def tiny_tmpfs(tmp_path):
    """A 4 MiB tmpfs (issue 13's full-disk reproduction); skipped where it cannot be
    mounted."""
    mnt = tmp_path / "tmpfs"
    mnt.mkdir()
    problem = mount_tmpfs(mnt)
    if problem:
        pytest.skip(problem)
    yield mnt
    subprocess.run(["umount", "-l", str(mnt)], check=False)


@pytest.fixture(name="fill_disk")
def _fill_disk_fixture():
    """:func:`fill_disk` for tests (a test file cannot import this conftest by name)."""
    return fill_disk


def pytest_terminal_summary(terminalreporter):
    """Say so when the browser suite (tests/e2e) was skipped, e.g. without chromium: a
    skipped suite must not pass for a passed one."""
    skipped = [r for r in terminalreporter.stats.get("skipped", [])
               if "tests/e2e/" in str(getattr(r, "nodeid", "")).replace("\\", "/")
               or "e2e" in str(getattr(r, "location", ("",))[0])]
    if skipped:
        reason = skipped[0].longrepr[2] if isinstance(skipped[0].longrepr, tuple) else ""
        terminalreporter.write_line(
            f"browser tests: {len(skipped)} skipped ({reason.removeprefix('Skipped: ')}); "
            f"they need Debian's chromium (apt-get install chromium) and playwright",
            yellow=True, bold=True)
