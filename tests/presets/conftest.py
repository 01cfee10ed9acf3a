"""Fixtures for the preset tests: a preset as a fresh dict, a runner that builds a scene
dict (a preset or a modified copy of one) and runs it, returning the system and the result,
and the smoke run every preset gets."""
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


@pytest.fixture
def smoke_run(preset_dict, run_scene):
    """``smoke_run(name) -> (system, RunResult)``: run the preset for 40 of its own steps,
    recording 4 frames, and check that it completes there with every recorded channel and
    every energy finite (a smoke test: it catches a NaN, a crash, a preset the engine
    refuses, not a wrong number)."""
    import engine
    import numpy as np

    def run(name: str):
        scene = preset_dict(name)
        dt = engine.build(engine.parse_scene(scene)).dt
        until = 40 * dt
        scene["run"]["record_interval"] = until / 4
        system, result = run_scene(scene, until=until)
        assert result.status == "completed"
        assert system.time == pytest.approx(until, rel=0.05)
        with result.open() as res:
            assert res.n_frames >= 4
            for channel in res.channels():
                assert np.all(np.isfinite(res.series(channel))), channel
        assert all(np.isfinite(v) for v in engine.energies(system).values())
        return system, result

    return run
