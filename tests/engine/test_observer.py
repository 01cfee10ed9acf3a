"""``engine.run(observer=...)``: a run observed in memory receives the very values the HDF5
recorder writes, at the same times, and a run with ``output=False`` writes no file."""
from __future__ import annotations

import numpy as np
import pytest

import engine

CHANNELS = ["nodes", "bodies", "root_force", "energy", "contacts", "bending"]


def _system(tiny_scene):
    return engine.build(engine.parse_scene(tiny_scene(duration=0.002, record_interval=0.0002,
                                                      channels=CHANNELS)))


def test_the_observer_gets_what_the_recorder_writes(tiny_scene, tmp_path):
    # Bugs caught: a frame handed over before the recorder's cast (float64 bending moments
    # against the file's float32), arrays kept by reference (every row the last state), a
    # frame left out of the observer (the first one, before the step loop) or the file.
    calls = []
    obs = engine.MemoryObserver()  # every channel

    class Counting:  # an observer object: told the channels, then every frame
        def begin(self, channels, static):
            obs.begin(channels, static)

        def append(self, frame):
            obs.append(frame)
            calls.append(frame["time"])

    path = tmp_path / "run.h5"
    result = engine.run(_system(tiny_scene), output=path, observer=Counting())
    assert result.status == "completed" and result.frames == len(calls) > 5
    with engine.open_result(path) as r:
        assert sorted(r.channels()) == sorted(obs._rows)
        for name in r.channels():
            # the same numbers exactly: one frame dict feeds both, cast to the same dtype
            assert np.array_equal(obs.series(name), r.series(name)), name
            assert obs.series(name).dtype == r.series(name).dtype, name
        assert np.array_equal(np.asarray(calls), r.time)


def test_an_observed_run_needs_no_file(tiny_scene, tmp_path, monkeypatch):
    monkeypatch.setenv("TMPDIR", str(tmp_path))  # where a temporary result would go
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    obs = engine.MemoryObserver(["time", "brushes/brush/root_force", "nodes/positions"])
    system = _system(tiny_scene)
    result = engine.run(system, output=False, observer=obs)
    assert result.path is None and not list(tmp_path.iterdir())
    assert obs.n_frames == result.frames and obs.time[-1] == pytest.approx(system.time)
    # a kept row is a copy: the last frame's node positions are the state now, the first
    # frame's are not (the box pressed the tips down meanwhile)
    assert np.array_equal(obs.frame("nodes/positions", -1), system.nodes.x)
    assert not np.array_equal(obs.frame("nodes/positions", 0), system.nodes.x)
    assert obs.series("brushes/brush/root_force").shape == (obs.n_frames, 3)
    times = []  # a plain callable is an observer too
    engine.run(_system(tiny_scene), output=False, observer=lambda fr: times.append(fr["time"]))
    assert np.array_equal(times, obs.time)
    with pytest.raises(KeyError, match="no channel"):
        engine.run(_system(tiny_scene), output=False,
                   observer=engine.MemoryObserver(["bodies/nope/position"]))
    with pytest.raises(TypeError, match="observer"):
        engine.run(_system(tiny_scene), output=False, observer=42)
