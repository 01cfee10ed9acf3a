"""An optional storage quota for the data folder (issue 13, item 5: storage grew forever):
a submit that would go over it is refused with 507 naming the quota, health says so, and
purging a run makes room again."""
from __future__ import annotations

import argparse

import pytest
from fastapi.testclient import TestClient

import engine
from studio.service.jobs import JobManager, Limits, StorageError
from studio.service.jobs.quota import StorageQuota, folder_bytes
from studio.cli.serve import limits_from_args, register
from studio.service.server import create_app


def test_folder_bytes_is_the_sum_of_the_files(tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    (tmp_path / "a" / "x.bin").write_bytes(b"1" * 1000)
    (tmp_path / "a" / "b" / "y.bin").write_bytes(b"2" * 2345)
    (tmp_path / "link").symlink_to(tmp_path / "a" / "x.bin")  # not counted twice
    expected = sum(p.stat().st_size for p in tmp_path.rglob("*")
                   if p.is_file() and not p.is_symlink())
    assert folder_bytes(tmp_path) == expected == 3345
    assert folder_bytes(tmp_path / "missing") == 0


def test_what_was_admitted_counts_until_the_next_walk(tmp_path):
    quota = StorageQuota([tmp_path], max_bytes=1000, cache_s=3600)
    quota.admit(600, "one")
    # nothing is on disk yet, but the first 600 bytes are reserved: 600 + 600 > 1000
    with pytest.raises(StorageError) as exc:
        quota.admit(600, "two")
    assert "storage quota" in str(exc.value) and "two needs" in str(exc.value)
    quota.admit(400, "three")  # exactly full is allowed
    with pytest.raises(ValueError):
        StorageQuota([tmp_path], max_bytes=0)


def test_a_submit_over_the_quota_is_507_and_a_purge_makes_room(tmp_path, tiny_scene):
    scene = tiny_scene(duration=0.002)
    estimate = engine.estimate(engine.parse_scene(scene)).result_bytes
    jm = JobManager(tmp_path / "data", workers=1, limits=Limits(max_storage_bytes=1e12))
    try:
        jm.quota.cache_s = 0.0  # walk the folder at every check: the test sets the quota
        client = TestClient(create_app(jm))
        first = client.post("/api/runs", json=scene)
        assert first.status_code == 201, first.text
        assert jm.wait(first.json()["id"], timeout=600).status == "completed"
        used = jm.quota.used_bytes()
        assert used == folder_bytes(jm.runs_dir) + folder_bytes(jm.meshes_dir) > 0

        jm.quota.max_bytes = used + int(estimate) - 1  # one byte short for the next run
        r = client.post("/api/runs", json=scene)
        assert r.status_code == 507, r.text
        assert "--max-storage-gb" in r.json()["detail"]
        assert len(jm.list()) == 1  # nothing stored for the refused run
        health = client.get("/api/health").json()
        assert health["used_bytes"] == used and health["quota_bytes"] == jm.quota.max_bytes

        jm.quota.max_bytes = used + int(estimate) + 1  # room for it: accepted
        second = client.post("/api/runs", json=scene)
        assert second.status_code == 201, second.text
        jm.wait(second.json()["id"], timeout=600)

        jm.quota.max_bytes = jm.quota.used_bytes()  # full: degraded, studies refused too
        health = client.get("/api/health").json()
        assert health["status"] == "degraded"
        assert any("storage quota full" in p for p in health["problems"])
        assert client.post("/api/studies", json={"study": "rod"}).status_code == 507
        # a purge frees the run's files: a submit fits again
        purged = client.delete(f"/api/runs/{first.json()['id']}", params={"purge": "true"})
        assert purged.json()["freed_bytes"] > 0
        jm.quota.max_bytes = jm.quota.used_bytes() + int(estimate)
        assert client.post("/api/runs", json=scene).status_code == 201
    finally:
        jm.close()


def test_a_mesh_over_the_quota_is_507(tmp_path):
    jm = JobManager(tmp_path / "data", workers=1, limits=Limits(max_storage_bytes=100))
    try:
        r = TestClient(create_app(jm)).post(
            "/api/meshes", files={"file": ("m.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n" * 10
                                           + b"f 1 2 3\n")})
        assert r.status_code == 507 and "the mesh needs" in r.json()["detail"]
    finally:
        jm.close()


def test_the_serve_option_sets_the_quota_in_gib():
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    args = parser.parse_args(["serve", "--headless", "--max-storage-gb", "0.5"])
    assert limits_from_args(args).max_storage_bytes == 2**29
    args = parser.parse_args(["serve", "--headless"])
    assert limits_from_args(args).max_storage_bytes is None  # default: no quota
