"""The one-worker path of the runner: no Dask cluster, the same outcomes and files as on one,
restart skips, failure reports, and Ctrl-C keeping the runs finished before it."""
from __future__ import annotations

import json

import numpy as np
import pytest

import engine
from studio.studies import runner
from sweeps import modulus_sweep
from studio.studies.run_files import failures_text, run_paths
from studio.studies.runner import RunSpec, run_many

MODULI = (2.0e6, 3.5e6)


def _sweep(tiny_scene) -> list[RunSpec]:
    return modulus_sweep(tiny_scene, MODULI)


def _refuse_dask(monkeypatch) -> None:
    """From here on, any attempt to start or reach a Dask cluster fails the test."""
    import distributed

    def refuse(*args, **kwargs):
        raise AssertionError("the one-worker path started a Dask cluster or client")

    monkeypatch.setattr(distributed, "LocalCluster", refuse)
    monkeypatch.setattr(distributed, "Client", refuse)


def _root_force(h5) -> np.ndarray:
    with engine.open_result(h5) as res:
        assert res.status == "completed"
        return res.series("brushes/brush/root_force")


def test_one_worker_matches_dask_without_a_cluster(dask_cluster, tiny_scene, tmp_path,
                                                   monkeypatch):
    addr, _ = dask_cluster
    specs = _sweep(tiny_scene)
    on_dask = run_many(specs, tmp_path / "dask", scheduler=addr, progress=False)

    _refuse_dask(monkeypatch)
    here = run_many(specs, tmp_path / "here", n_workers=1, progress=False)

    assert [o.run_id for o in here] == [s.run_id for s in specs]
    assert [o.status for o in here] == [o.status for o in on_dask] == \
        ["completed", "completed", "failed"]
    for a, b in zip(on_dask[:2], here[:2]):
        # the same task on one single-threaded process each: the same arithmetic, so the
        # same numbers bit for bit (a difference would mean the paths run different code)
        assert np.array_equal(_root_force(a.h5), _root_force(b.h5))
        drop = ("wall_s",)
        assert {k: v for k, v in a.summary.items() if k not in drop} == \
            {k: v for k, v in b.summary.items() if k not in drop}
    assert here[2].error == on_dask[2].error and "root_radius" in here[2].error
    assert failures_text(here) == failures_text(on_dask)
    stored = json.loads(run_paths(tmp_path / "here", "bad")[1].read_text())
    assert stored["status"] == "failed" and stored["params"] == here[2].params

    # restart: the completed runs are skipped, the failed one runs again
    again = run_many(specs, tmp_path / "here", n_workers=1, progress=False)
    assert [o.skipped for o in again] == [True, True, False]
    assert again[0].summary == here[0].summary


def test_ctrl_c_keeps_finished_runs(tiny_scene, tmp_path, monkeypatch):
    _refuse_dask(monkeypatch)
    specs = _sweep(tiny_scene)[:2] + [RunSpec("E9", tiny_scene(), {"youngs_modulus": 9})]
    plain_run = runner.plain_run

    def interrupted_at_e1(scene, h5_path, params):
        if h5_path.stem == "E1":
            raise KeyboardInterrupt
        return plain_run(scene, h5_path, params)

    monkeypatch.setattr(runner, "plain_run", interrupted_at_e1)  # resolve_task finds it
    out = tmp_path / "study"
    with pytest.raises(KeyboardInterrupt):
        run_many(specs, out, n_workers=1, progress=False)
    assert json.loads(run_paths(out, "E0")[1].read_text())["status"] == "completed"
    assert json.loads(run_paths(out, "E1")[1].read_text())["status"] == "cancelled"
    assert not run_paths(out, "E9")[1].exists()  # never started

    monkeypatch.setattr(runner, "plain_run", plain_run)
    again = run_many(specs, out, n_workers=1, progress=False)
    assert [o.skipped for o in again] == [True, False, False]
    assert [o.status for o in again] == ["completed"] * 3


def test_a_single_run_starts_no_cluster_whatever_the_workers(tiny_scene, tmp_path,
                                                            monkeypatch):
    """One run to do on a local cluster of N workers would use one of them: the runner runs
    it here instead (the default ``study wedge`` of one preset pays no cluster start-up).
    Bug caught: the cluster started for a single run (the refusal below fails the test)."""
    _refuse_dask(monkeypatch)
    spec = _sweep(tiny_scene)[0]
    (out,) = run_many([spec], tmp_path / "one", n_workers=2, progress=False)
    assert out.status == "completed"
    assert _root_force(out.h5).shape[1] == 3


def test_no_time_left_is_shown_until_a_whole_run_has_finished(tiny_scene, tmp_path,
                                                              monkeypatch, capsys):
    # issue 28: the wedge study's bar said 55 s left with 3 min 53 s to go, an estimate from
    # the cheap start of a run whose cost grows with depth. Bug caught: an estimate of the
    # time left ("<MM:SS") drawn while the first run is still under way.
    _refuse_dask(monkeypatch)
    plain_run = runner.plain_run

    def slow_start(scene, h5_path, params):
        runner.report_progress(0.5)     # half of the first run's simulated time
        return plain_run(scene, h5_path, params)

    monkeypatch.setattr(runner, "plain_run", slow_start)
    run_many(_sweep(tiny_scene)[:2], tmp_path / "study", n_workers=1, progress=True)
    bars = [ln for ln in capsys.readouterr().err.replace("\r", "\n").splitlines() if "|" in ln]
    first_done = next(i for i, ln in enumerate(bars) if "| 1/2" in ln)
    before, after = bars[:first_done], bars[first_done:]
    assert any("0.5/2" in ln for ln in before), bars     # the run's own progress is drawn
    assert all("<" not in ln for ln in before), before    # without a time left
    assert "<" in after[0], after   # whole runs done: the time left is shown
