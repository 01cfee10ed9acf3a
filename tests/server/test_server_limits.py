"""Limits on job cost and queue size (issue 13, items 2 and 3): each of the issue's scenes
is refused at submit from its estimate, at once, with the limit named; a full queue answers
429 with Retry-After; a job over the wall-time limit fails saying so; the estimate is in the
job's record."""
from __future__ import annotations

import time

import pytest
from fastapi.testclient import TestClient

from studio.cli.main import main
from studio.service.jobs import JobManager, Limits
from studio.service.server import create_app


@pytest.fixture(scope="module")
def jobs(tmp_path_factory):
    jm = JobManager(tmp_path_factory.mktemp("limits") / "data", workers=1)
    yield jm
    jm.close()


@pytest.fixture(scope="module")
def client(jobs):
    return TestClient(create_app(jobs))


def _refused(client, scene, status, limit):
    t0 = time.perf_counter()
    r = client.post("/api/runs", json=scene)
    elapsed = time.perf_counter() - t0
    assert r.status_code == status, r.text
    body = r.json()
    limits = (limit,) if isinstance(limit, str) else limit
    assert body["limit"] in limits and body["detail"][0]["limit"] == body["limit"]
    option = "--" + body["limit"].replace("_", "-").replace("-bytes", "-mb")
    assert option in body["message"]  # says which option to change
    assert elapsed < 5.0, elapsed  # the estimate, not a build (the issue: no answer in 300 s)
    return body


@pytest.mark.parametrize("rows", [1000, 100_000])
def test_a_huge_grid_is_refused_by_its_node_count(client, tiny_scene, rows):
    scene = tiny_scene()
    scene["brushes"][0].update(rows=rows, columns=rows)
    body = _refused(client, scene, 413, "max_nodes")
    assert body["detail"][0]["value"] == rows * rows * scene["brushes"][0]["n_nodes"]


def test_the_issues_expensive_scenes_are_refused_by_their_steps(client, tiny_scene):
    many_nodes = tiny_scene()
    many_nodes["brushes"][0]["n_nodes"] = 4096  # the documented maximum: a 24 h ETA
    _refused(client, many_nodes, 422, ("max_steps", "max_node_steps"))
    _refused(client, tiny_scene(duration=1e9), 422, "max_steps")
    _refused(client, tiny_scene(duration=1e308), 422, "max_steps")
    _refused(client, tiny_scene(record_interval=1e-12), 422, "max_frames")


def test_a_run_records_its_estimate(client, jobs, tiny_scene):
    r = client.post("/api/runs", json=tiny_scene(duration=0.002))
    assert r.status_code == 201
    est = r.json()["estimate"]
    assert est["n_nodes"] == 16 and est["n_bristles"] == 4 and est["steps"] > 0
    jobs.wait(r.json()["id"], timeout=600)


def test_a_study_planning_too_many_runs_is_refused(client):
    r = client.post("/api/studies", json={"study": "wedge",
                                          "options": {"preset": ["wedge_60"] * 1000}})
    assert r.status_code == 422 and r.json()["limit"] == "max_study_runs"
    assert r.json()["detail"][0]["value"] == 1000


def test_a_full_queue_answers_429_with_retry_after(tmp_path, long_scene):
    jm = JobManager(tmp_path / "data", workers=1, limits=Limits(max_queued=2))
    client = TestClient(create_app(jm))
    try:
        answers = [client.post("/api/runs", json=long_scene) for _ in range(4)]
        codes = [a.status_code for a in answers]
        assert codes[:2] == [201, 201] and 429 in codes, codes  # at most 1 runs, 2 wait
        full = answers[codes.index(429)]
        assert int(full.headers["retry-after"]) > 0 and full.json()["limit"] == "max_queued"
        assert jm.counts()["queued"] <= 2
    finally:
        jm.close()


def test_a_job_over_the_wall_time_limit_fails_saying_so(tmp_path, long_scene):
    jm = JobManager(tmp_path / "data", workers=1, limits=Limits(max_job_seconds=1.0))
    try:
        info = jm.wait(jm.submit(long_scene), timeout=600)
        assert info.status == "failed" and "wall-time limit of 1 s" in info.error, info
        assert "--max-job-seconds" in info.error
    finally:
        jm.close()


def test_serve_limits_options(tmp_path, capsys):
    assert main(["serve", "--headless", "--max-nodes", "-1", "--data",
                 str(tmp_path)]) == 2
    assert "--max-nodes = -1" in capsys.readouterr().err


def test_validate_refuses_a_huge_scene_from_its_estimate(write_scene, tiny_scene, capsys):
    scene = tiny_scene()
    scene["brushes"][0].update(rows=10_000, columns=10_000)
    t0 = time.perf_counter()
    assert main(["validate", str(write_scene(scene))]) == 2
    assert time.perf_counter() - t0 < 5.0  # the issue: nothing for 300 s, 4.3 GB
    out = capsys.readouterr()
    assert "400000000 nodes" in out.out and "--max-nodes" in out.err
    assert main(["validate", "--estimate-only", str(write_scene(tiny_scene()))]) == 0
    assert "16 nodes" in capsys.readouterr().out


def test_finished_jobs_past_the_retention_are_purged(tmp_path, tiny_scene):
    jm = JobManager(tmp_path / "data", workers=1, limits=Limits(keep_days=1.0))
    try:
        old = jm.submit(tiny_scene(duration=0.002))
        jm.wait(old, timeout=600)
        new = jm.submit(tiny_scene(duration=0.002))
        jm.wait(new, timeout=600)
        jm._store.update(old, finished=time.time() - 2 * 86400.0)  # finished 2 days ago
        jm._next_retain = 0.0
        jm._wake()
        def purged() -> bool:  # the folder and the job's row (removed one after the other)
            if (jm.runs_dir / old).exists():
                return False
            try:
                jm.get(old)
            except KeyError:
                return True
            return False

        deadline = time.monotonic() + 10
        while not purged() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not (jm.runs_dir / old).exists()
        with pytest.raises(KeyError):
            jm.get(old)
        assert jm.get(new).status == "completed"  # finished today: kept
    finally:
        jm.close()
