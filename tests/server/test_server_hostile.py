"""Hostile request bodies (issue 13, items 6 and 7): deep JSON, true for a number, the
bearer token before any body is read, a mesh's triangles counted before it is parsed."""
from __future__ import annotations

import asyncio
import time

import pytest
from fastapi.testclient import TestClient

from studio.service.jobs import JobManager, MeshError
from studio.service.server import create_app
from studio.service.server.common import RequestGuard


@pytest.fixture(scope="module")
def jobs(tmp_path_factory):
    jm = JobManager(tmp_path_factory.mktemp("hostile") / "data", workers=1)
    yield jm
    jm.close()


@pytest.mark.parametrize("path", ["/api/runs", "/api/studies"])
def test_deeply_nested_json_is_422_not_500(jobs, path):
    client = TestClient(create_app(jobs))
    for depth in (100, 100_000):  # past MAX_JSON_DEPTH; past Python's recursion limit
        body = "[" * depth + "]" * depth
        r = client.post(path, content=body, headers={"content-type": "application/json"})
        assert r.status_code == 422, (depth, r.text[:300])
        assert "nested" in r.text


def test_true_is_not_a_number(jobs, tiny_scene):
    client = TestClient(create_app(jobs))
    scene = tiny_scene()
    scene["brushes"][0]["bristle_length"] = True  # was read as 1.0 m
    r = client.post("/api/runs", json=scene)
    assert r.status_code == 422
    assert [d["field"] for d in r.json()["detail"]] == ["brushes.0.bristle_length"]


def test_the_token_is_checked_before_the_body_is_read():
    async def app(scope, receive, send):  # pragma: no cover - must not be reached
        raise AssertionError("the app ran")

    async def receive():
        raise AssertionError("the body was read")

    sent = []

    async def send(message):
        sent.append(message)

    guard = RequestGuard(app, None, (), ("/api/runs",), token="s3cret",
                         open_paths=("/api/health",))
    scope = {"type": "http", "method": "POST", "path": "/api/meshes",
             "headers": [(b"host", b"127.0.0.1:8000"),
                         (b"content-length", b"58720256")]}  # a 56 MB upload announced
    asyncio.run(guard(scope, receive, send))
    assert sent[0]["status"] == 401


def test_an_obj_with_millions_of_faces_is_refused_before_parsing(jobs):
    data = b"v 0 0 0\nv 1 0 0\nv 0 1 0\n" + b"f 1 2 3\n" * 5_000_000  # the 40 MB
    t0 = time.perf_counter()
    with pytest.raises(MeshError) as err:
        jobs.add_mesh(data, "many.obj")
    assert err.value.status == 413 and "5000000 triangles" in str(err.value)
    assert time.perf_counter() - t0 < 2.0  # it was 20.5 s and +860 MB of parsing


def test_a_repeated_idempotency_key_queues_one_job(jobs, tiny_scene):
    client = TestClient(create_app(jobs))
    headers = {"Idempotency-Key": "retry-after-a-lost-answer-1"}
    first = client.post("/api/runs", json=tiny_scene(duration=0.002), headers=headers)
    again = client.post("/api/runs", json=tiny_scene(duration=0.002), headers=headers)
    assert first.status_code == 201 and again.status_code == 200
    assert again.json()["id"] == first.json()["id"]
    other = client.post("/api/runs", json=tiny_scene(duration=0.002),
                        headers={"Idempotency-Key": "another"})
    assert other.status_code == 201 and other.json()["id"] != first.json()["id"]


def test_purge_deletes_a_run_and_its_files(jobs, tiny_scene):
    client = TestClient(create_app(jobs))
    run_id = client.post("/api/runs", json=tiny_scene(duration=0.002)).json()["id"]
    jobs.wait(run_id, timeout=600)
    assert (jobs.runs_dir / run_id / "result.h5").is_file()
    r = client.delete(f"/api/runs/{run_id}", params={"purge": "true"})
    assert r.status_code == 200 and r.json()["freed_bytes"] > 0
    assert not (jobs.runs_dir / run_id).exists()
    assert client.get(f"/api/runs/{run_id}").status_code == 404
