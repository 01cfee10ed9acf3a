"""Fixtures for the preset tests: a preset as a fresh dict, and a runner that builds a scene
dict (a preset or a modified copy of one) and runs it, returning the system and the result."""
from __future__ import annotations

import json

import pytest

from studio import presets


@pytest.fixture
def preset_dict():
    """``preset_dict(name) -> dict``: a fresh dict of the preset's JSON (safe to modify)."""

    def load(name: str) -> dict:
        return json.loads(presets.preset_path(name).read_text())

    return load


@pytest.fixture
def run_scene(tmp_path):
    """``run_scene(scene_dict, until=None) -> (system, RunResult)``: build and run."""
    import engine

    def run(scene: dict, until=None, name="run"):
        system = engine.build(engine.parse_scene(scene))
        result = engine.run(system, until=until, output=tmp_path / f"{name}.h5")
        return system, result

    return run
