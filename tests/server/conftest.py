"""Fixtures of the server tests: a real ``brush-studio serve --headless`` subprocess on
127.0.0.1 and a free port, stopped at the end of the test (or module) that started it."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[2]
START_TIMEOUT_S = 120  # a cold start imports numba and the engine on a loaded 2-core machine


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ServerProcess:
    """``brush-studio serve --headless`` as a subprocess; ``url``, ``client`` (httpx),
    ``stop()`` (SIGTERM: graceful), ``kill()`` (SIGKILL)."""

    def __init__(self, data_dir: Path, workers: int = 2, args: tuple = (), log: Path = None):
        self.data_dir = Path(data_dir)
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        env = dict(os.environ)
        # the repository first: the tests run against this checkout
        env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get(
            "PYTHONPATH", "").split(os.pathsep) if p])
        env.pop("BRUSH_STUDIO_TOKEN", None)
        self.log = log or (self.data_dir.parent / f"server-{self.port}.log")
        self._log_file = open(self.log, "w")
        cmd = [sys.executable, "-m", "studio.cli", "serve", "--headless",
               "--host", "127.0.0.1", "--port", str(self.port), "--workers", str(workers),
               "--data", str(self.data_dir), "--log-level", "warning", *args]
        self.proc = subprocess.Popen(cmd, cwd=str(ROOT), env=env, stdout=self._log_file,
                                     stderr=subprocess.STDOUT)
        self.client = httpx.Client(base_url=self.url, timeout=300)
        # a server with a token tells its workers only to a request that carries it
        args = list(args)
        self._health_headers = ({"Authorization": f"Bearer {args[args.index('--token') + 1]}"}
                                if "--token" in args else {})
        self._wait_up()

    def _wait_up(self) -> None:
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited with {self.proc.returncode}:\n"
                                   f"{self.log.read_text()}")
            try:
                r = self.client.get("/api/health", timeout=2, headers=self._health_headers)
                if r.status_code == 200 and r.json()["workers_alive"] > 0:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.3)
        self.kill()
        raise RuntimeError(f"server did not start in {START_TIMEOUT_S} s:\n"
                           f"{self.log.read_text()}")

    def wait_run(self, run_id: str, timeout: float = 600) -> dict:  # a cold numba cache: minutes
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            info = self.client.get(f"/api/runs/{run_id}").json()
            if info["status"] in ("completed", "stopped", "failed", "cancelled"):
                return info
            time.sleep(0.1)
        raise TimeoutError(f"run {run_id} not finished after {timeout} s: {info}")

    def stop(self, timeout: float = 30) -> int:
        self.client.close()
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
        self._log_file.close()
        return self.proc.returncode

    def kill(self) -> None:
        self.client.close()
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)
        self._log_file.close()


@pytest.fixture
def start_server(tmp_path):
    """``start_server(data_dir=None, workers=2, args=()) -> ServerProcess``; every server
    started is stopped after the test."""
    started: list[ServerProcess] = []

    def start(data_dir=None, workers: int = 2, args: tuple = ()) -> ServerProcess:
        server = ServerProcess(data_dir or tmp_path / "data", workers, args)
        started.append(server)
        return server

    yield start
    for s in started:
        if s.proc.poll() is None:
            s.stop()


@pytest.fixture(scope="session")
def server(tmp_path_factory):
    """One server (2 workers, meshes of at most 1000 triangles) shared by the tests that
    do not depend on a fresh data folder."""
    tmp = tmp_path_factory.mktemp("server")
    s = ServerProcess(tmp / "data", workers=2, args=("--max-triangles", "1000"))
    yield s
    s.stop()


@pytest.fixture
def long_scene(tiny_scene):
    """The tiny scene run long enough (2 s simulated: several wall seconds) to act on while
    it runs; the box holds still after its 4 ms of travel."""
    return tiny_scene(duration=2.0, record_interval=0.005)


@pytest.fixture
def wait_until():
    """``wait_until(cond, timeout=600, what="")``: call ``cond()`` every 20 ms until it
    returns something true, and return that; TimeoutError naming ``what`` after ``timeout``
    seconds (the default leaves room for a cold numba cache compiling first)."""

    def wait(cond, timeout: float = 600.0, what: str = ""):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = cond()
            if value:
                return value
            time.sleep(0.02)
        raise TimeoutError(what)

    return wait
