"""Jobs through the real server: a killed worker fails its run and the service goes on, a
restarted server lists earlier runs with their results, 50 concurrent submissions."""
from __future__ import annotations

import os
import signal
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

import engine
import h5py


def _wait_running(server, run_id, timeout=600) -> dict:
    """Until the run is running and has recorded frames (sim_time > 0)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        info = server.client.get(f"/api/runs/{run_id}").json()
        if info["status"] == "running" and (info["sim_time"] or 0) > 0.005:
            return info
        assert info["status"] in ("queued", "running"), info
        time.sleep(0.05)
    raise TimeoutError(info)


def _wait_committed(server, run_id, n, timeout=60) -> None:
    """Until the live result file has ``n`` committed frames (the engine commits at least
    every quarter second of wall time)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        r = server.client.get(f"/api/runs/{run_id}/series")  # reads the live file
        if r.status_code == 200 and r.json()["n_frames"] >= n:
            return
        time.sleep(0.05)
    raise TimeoutError(f"run {run_id}: fewer than {n} committed frames after {timeout} s")


def test_killed_worker_fails_its_run_and_the_next_run_completes(server, long_scene,
                                                                tiny_scene, tmp_path):
    run_id = server.client.post("/api/runs", json=long_scene).json()["id"]
    info = _wait_running(server, run_id)
    pid = info["worker_pid"]
    assert pid and pid != server.proc.pid
    _wait_committed(server, run_id, 2)
    os.kill(pid, signal.SIGKILL)

    info = server.wait_run(run_id, timeout=30)
    assert info["status"] == "failed", info
    assert f"pid {pid}" in info["error"] and "SIGKILL" in info["error"], info["error"]
    # the partial result file is kept and readable (every committed frame survives the kill),
    # by plain h5py too, and says what the job says (issue 13, item 7: it said "running")
    r = server.client.get(f"/api/runs/{run_id}/result")
    assert r.status_code == 200
    (tmp_path / "partial.h5").write_bytes(r.content)
    with h5py.File(tmp_path / "partial.h5", "r") as f:
        status = f.attrs["status"]
        assert (status.decode() if isinstance(status, bytes) else str(status)) == "failed"
    with engine.open_result(tmp_path / "partial.h5") as res:
        assert res.status == "failed" and res.n_frames >= 2
        assert "SIGKILL" in res.error["message"]
        assert res.time[-1] < 0.5

    nxt = server.client.post("/api/runs", json=tiny_scene()).json()["id"]
    info = server.wait_run(nxt)
    assert info["status"] == "completed", info
    assert info["worker_pid"] != pid  # a fresh worker took the dead one's place
    health = server.client.get("/api/health").json()
    assert health["workers_alive"] == 2 and pid not in [
        w["pid"] for w in health["worker_processes"]]


def test_restarted_server_lists_earlier_runs_and_marks_the_interrupted_one(
        start_server, long_scene, tiny_scene, tmp_path):
    data = tmp_path / "data"
    first = start_server(data, workers=1)
    done = first.client.post("/api/runs", json=tiny_scene(), params={"name": "done"}).json()
    assert first.wait_run(done["id"])["status"] == "completed"
    running = first.client.post("/api/runs", json=long_scene,
                                params={"name": "running"}).json()
    _wait_running(first, running["id"])
    queued = first.client.post("/api/runs", json=tiny_scene(),
                               params={"name": "queued"}).json()
    assert first.client.get(f"/api/runs/{queued['id']}").json()["status"] == "queued"
    first.kill()  # SIGKILL: no chance to clean up

    second = start_server(data, workers=1)
    listed = {i["id"]: i for i in second.client.get("/api/runs").json()}
    assert [i["name"] for i in second.client.get("/api/runs").json()] == \
        ["queued", "running", "done"]  # newest first
    assert listed[done["id"]]["status"] == "completed"
    interrupted = listed[running["id"]]
    assert interrupted["status"] == "failed" and "interrupted" in interrupted["error"]
    # nothing lost: the queued run runs on the new server
    assert second.wait_run(queued["id"])["status"] == "completed"
    for run_id, status in ((done["id"], "completed"), (running["id"], None)):
        r = second.client.get(f"/api/runs/{run_id}/result")
        assert r.status_code == 200
        path = tmp_path / f"{run_id}.h5"
        path.write_bytes(r.content)
        with engine.open_result(path) as res:
            assert res.n_frames > 0
            if status:
                assert res.status == status

    # a graceful stop (SIGTERM) ends the server and its workers
    pid = second.client.get(f"/api/runs/{queued['id']}").json()["worker_pid"]
    assert second.stop() == 0
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)


@pytest.mark.slow  # about 40 s: 50 runs on a 2-core machine
def test_fifty_concurrent_submissions_all_complete_once(start_server, tiny_scene):
    server = start_server(workers=2)
    scenes = [tiny_scene() for _ in range(50)]
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=50) as pool:
        answers = list(pool.map(
            lambda i: server.client.post("/api/runs", json=scenes[i],
                                         params={"name": f"n{i}"}), range(50)))
    submitted = time.perf_counter() - t0
    assert all(a.status_code == 201 for a in answers), [a.text for a in answers
                                                        if a.status_code != 201]
    ids = [a.json()["id"] for a in answers]
    assert len(set(ids)) == 50
    infos = [server.wait_run(i, timeout=600) for i in ids]
    wall = time.perf_counter() - t0
    assert [i["status"] for i in infos] == ["completed"] * 50
    listed = server.client.get("/api/runs").json()
    assert sorted(i["id"] for i in listed) == sorted(ids)  # none lost, none duplicated
    assert sorted(i["name"] for i in listed) == sorted(f"n{i}" for i in range(50))
    assert len({i["worker_pid"] for i in infos}) == 2  # both workers took runs
    health = server.client.get("/api/health").json()
    threads = [w["numba_threads"] for w in health["worker_processes"]]
    assert len(threads) == 2 and sum(threads) <= max(2, os.cpu_count())  # no oversubscription
    print(f"\n50 tiny runs, 2 workers: submitted in {submitted:.2f} s, all completed in "
          f"{wall:.1f} s")
