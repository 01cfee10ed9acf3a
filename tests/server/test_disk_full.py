"""A full disk during a run is a clean job failure with the real reason (issue 28, item 8):
the worker stops the run before HDF5 meets the full disk (which crashed the worker with
SIGSEGV: the job said "killed by signal SIGSEGV"), and reports "No space left on device".
The full disk is simulated: the free space the worker reads is made zero (mounting a
small tmpfs needs privileges CI may not have)."""
from __future__ import annotations

import os

from studio.service.jobs import worker


class _Conn:
    def __init__(self):
        self.sent = []

    def send(self, msg):
        self.sent.append(msg)


class _Seq:
    value = -1


def test_a_full_disk_fails_the_run_saying_so(tmp_path, tiny_scene, monkeypatch):
    import json

    calls = []

    def no_space(path):
        calls.append(path)
        return 1024  # 1 KiB free

    monkeypatch.setattr(worker, "free_bytes", no_space)
    conn = _Conn()
    h5 = tmp_path / "run" / "result.h5"
    h5.parent.mkdir()
    worker._worker_run(conn, _Seq(), os.getppid(), 7, "job1",
                       json.dumps(tiny_scene(duration=0.05)), str(h5))
    done = [m for m in conn.sent if m[0] == "done"]
    assert done, conn.sent
    info = done[-1][2]
    assert calls and info["status"] == "failed", info
    assert "No space left on device" in info["error"], info["error"]
    assert "SIGSEGV" not in info["error"]


def test_a_dead_worker_on_a_full_disk_names_it(tmp_path, monkeypatch):
    monkeypatch.setattr(worker, "free_bytes", lambda path: 0)
    assert "No space left on device" in worker.disk_full_reason(tmp_path)
    monkeypatch.setattr(worker, "free_bytes", lambda path: 2**40)
    assert worker.disk_full_reason(tmp_path) is None
