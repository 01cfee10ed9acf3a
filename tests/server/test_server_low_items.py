"""The low items of issue 28, item 9, on the service: a 422 does not echo a huge value,
``/api/health`` hides its details from a request without the token, and health is ok again
once storage recovers (after a purge), not only at the next write."""
from __future__ import annotations

import json

import pytest
from fastapi.testclient import TestClient

from studio.service.jobs import JobManager
from studio.service.server import create_app


@pytest.fixture(scope="module")
def jobs(tmp_path_factory):
    jm = JobManager(tmp_path_factory.mktemp("low") / "data", workers=1)
    yield jm
    jm.close()


@pytest.mark.parametrize("path", ["/api/runs", "/api/studies"])
def test_a_422_does_not_echo_a_huge_value(jobs, tiny_scene, path):
    # bug caught: a 6 MB body holding a 3-million-element list got a 15 MB 422 that echoed
    # the value twice
    huge = [0] * 2_000_000  # 6 MB of JSON, under the 8 MiB body limit
    if path == "/api/runs":
        scene = tiny_scene()
        scene["brushes"][0]["pitch"] = huge
        body = json.dumps(scene)
    else:
        body = json.dumps({"study": "rod", "options": {"n_nodes": huge}})
    r = TestClient(create_app(jobs)).post(path, content=body,
                                          headers={"content-type": "application/json"})
    assert r.status_code == 422, r.text[:500]
    assert len(r.content) < 20_000, len(r.content)
    assert "characters)" in r.text  # the value is shown shortened, with its length


def test_health_hides_its_details_without_the_token(jobs):
    # bug caught: /api/health open and showing worker PIDs and free bytes
    client = TestClient(create_app(jobs, token="s3cret"))
    r = client.get("/api/health")
    assert r.status_code == 200
    assert set(k for k, v in r.json().items() if v is not None) == {"status", "version"}
    full = client.get("/api/health", headers={"Authorization": "Bearer s3cret"}).json()
    assert full["worker_processes"] is not None and full["free_bytes"] is not None
    open_server = TestClient(create_app(jobs)).get("/api/health").json()
    assert open_server["workers"] == jobs.n_workers  # no token: nothing to hide behind


def test_health_recovers_when_storage_does(jobs):
    # bug caught: health stayed degraded after a purge freed space, until the next write
    jobs._writes.failed("only 0.5 MiB free in the data folder")
    assert jobs._writes.problem is not None
    state = jobs.health()
    assert state["status"] == "ok", state
    assert jobs._writes.problem is None
