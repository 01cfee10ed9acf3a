"""Fixtures of the study tests: reduced wedge scenes and a real Dask cluster of CLI processes.

``small_wedge_scene(angle_deg=60, rows=5, n_nodes=4)``: the wedge_60 preset (the seed's
brush and wedge, seed 4.2) reduced to a few rows and nodes, as a dict.
``dask_cluster``: a ``dask scheduler`` and two ``dask worker`` processes (the CLI executables)
on 127.0.0.1, free ports; yields the scheduler address and shuts them down afterwards.
"""
from __future__ import annotations

import copy
import json
import math
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PRESET = ROOT / "static_presets" / "wedge_60.json"
DEMO = ROOT / "studio" / "data" / "demo_scene.json"


@pytest.fixture
def small_wedge_scene():
    base = json.loads((PRESET if PRESET.exists() else DEMO).read_text())

    def make(angle_deg: float = 60.0, rows: int = 5, n_nodes: int = 4) -> dict:
        scene = copy.deepcopy(base)
        scene["brushes"][0].update(rows=rows, n_nodes=n_nodes)
        wedge = next(b for b in scene["bodies"] if b["name"] == "wedge")
        wedge["shape"]["angle"] = math.radians(angle_deg)
        return scene

    return make


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask_exe() -> list[str]:
    exe = shutil.which("dask")
    return [exe] if exe else [sys.executable, "-m", "dask"]


@pytest.fixture
def dask_cluster(tmp_path):
    """``(address, [scheduler, worker, worker])``: a real scheduler and two single-threaded
    workers started as subprocesses; all terminated at teardown."""
    from distributed import Client

    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, NUMBA_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    logs = tmp_path / "dask-logs"
    logs.mkdir()
    procs = []

    def start(name, args):
        log = open(logs / f"{name}.log", "w")
        procs.append(subprocess.Popen(_dask_exe() + args, env=env, cwd=tmp_path,
                                      stdout=log, stderr=subprocess.STDOUT))

    try:
        start("scheduler", ["scheduler", "--host", "127.0.0.1", "--port", str(port),
                            "--no-dashboard"])
        for i in range(2):
            start(f"worker{i}", ["worker", addr, "--nthreads", "1", "--host", "127.0.0.1",
                                 "--no-dashboard", "--name", f"w{i}"])
        deadline = time.monotonic() + 90
        client = None
        while client is None:
            try:
                client = Client(addr, timeout="5s")
            except OSError:
                if time.monotonic() > deadline or procs[0].poll() is not None:
                    raise
                time.sleep(0.5)
        try:
            client.wait_for_workers(2, timeout=90)
        finally:
            client.close()
        yield addr, procs
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=5)
