"""Storage failures (issue 13, item 1): a full disk fails the affected job with a clear
reason, keeps the dispatcher and the pool running, leaves no orphan run folders, and the
health check says ``degraded`` with the reason until storage works again.

Two reproductions: a database wrapper that answers "database or disk is full" to every
write while a flag is set (deterministic, runs everywhere), and a real 4 MiB tmpfs filled
to the last byte (needs root to mount; skipped otherwise)."""
from __future__ import annotations

import os
import signal
import sqlite3

import pytest
from fastapi.testclient import TestClient

from studio.service.jobs import JobManager, StorageError
from studio.service.server import create_app


class FullDisk:
    """The job database's connection, answering SQLite's own disk-full error to every write
    while ``full`` is set (reads go through: SQLite reads from a full disk)."""

    def __init__(self, db: sqlite3.Connection):
        self.db, self.full = db, False

    def execute(self, sql, *args):
        if self.full and sql.lstrip().split()[0].upper() in ("INSERT", "UPDATE", "DELETE"):
            raise sqlite3.OperationalError("database or disk is full")
        return self.db.execute(sql, *args)

    def __getattr__(self, name):
        return getattr(self.db, name)


def test_a_full_database_fails_the_job_and_the_service_recovers(tmp_path, long_scene,
                                                                tiny_scene, wait_until):
    jm = JobManager(tmp_path / "data", workers=1)
    disk = FullDisk(jm._store.db)
    jm._store.db = disk
    client = TestClient(create_app(jm))
    try:
        running = jm.submit(long_scene, name="running when the disk fills")
        wait_until(lambda: jm.get(running).status == "running" and jm.get(running).sim_time,
                   what="the job to run")
        pid = jm.get(running).worker_pid
        disk.full = True
        os.kill(pid, signal.SIGKILL)  # its death must be written to a full database
        info = wait_until(lambda: jm.get(running).done and jm.get(running), timeout=30,
                          what="the killed job to be reported finished")
        assert info.status == "failed" and "died while running" in info.error
        health = client.get("/api/health").json()
        assert health["status"] == "degraded"
        assert any("database or disk is full" in p for p in health["problems"]), health
        # a submit while the disk is full: 507 naming the reason, and no folder left behind
        before = sorted(p.name for p in jm.runs_dir.iterdir())
        r = client.post("/api/runs", json=tiny_scene())
        assert r.status_code == 507 and "database or disk is full" in r.json()["detail"]
        with pytest.raises(StorageError):
            jm.submit_study("rod", {})
        assert sorted(p.name for p in jm.runs_dir.iterdir()) == before
        # space returns: the failure is written, the pool is whole, new jobs run
        disk.full = False
        wait_until(lambda: jm._store.get(running).status == "failed", timeout=10,
                   what="the pending failure to be written")
        wait_until(lambda: client.get("/api/health").json()["status"] == "ok", timeout=120,
                   what="health to recover")
        after = client.post("/api/runs", json=tiny_scene(duration=0.002))
        assert after.status_code == 201
        assert jm.wait(after.json()["id"], timeout=600).status == "completed"
    finally:
        jm.close()


def test_a_full_tmpfs_fails_the_job_and_the_service_recovers(tiny_tmpfs, long_scene,
                                                             tiny_scene, wait_until,
                                                             fill_disk):
    jm = JobManager(tiny_tmpfs / "data", workers=1, min_free_bytes=0)
    client = TestClient(create_app(jm))
    filler = tiny_tmpfs / "filler"
    try:
        first = jm.submit(long_scene, name="running when the disk fills")
        wait_until(lambda: jm.get(first).status == "running" and jm.get(first).sim_time,
                   what="the job to run")
        fill_disk(filler)
        info = wait_until(lambda: jm.get(first).done and jm.get(first), timeout=300,
                          what="the job running on a full disk to finish")
        # it either fitted (its file was already allocated) or failed saying why
        assert info.status == "completed" or "No space left on device" in (info.error or "") \
            or "full" in (info.error or ""), info
        before = sorted(p.name for p in jm.runs_dir.iterdir())
        r = client.post("/api/runs", json=tiny_scene())
        assert r.status_code == 507, r.text
        assert sorted(p.name for p in jm.runs_dir.iterdir()) == before  # no orphan folder
        assert client.get("/api/health").json()["status"] == "degraded"
        # space returns: the filler goes, and the first run is purged with its files
        filler.unlink(missing_ok=True)
        purged = client.delete(f"/api/runs/{first}", params={"purge": "true"})
        assert purged.status_code == 200 and purged.json()["purged"], purged.text
        assert not (jm.runs_dir / first).exists()
        assert client.get(f"/api/runs/{first}").status_code == 404
        r = client.post("/api/runs", json=tiny_scene(duration=0.002))
        assert r.status_code == 201, r.text
        assert jm.wait(r.json()["id"], timeout=600).status == "completed"
        assert client.get("/api/health").json()["status"] == "ok"
    finally:
        jm.close()
