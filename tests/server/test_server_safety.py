"""Safety settings of the app (in-process): bearer token, CORS off by default, the warning
for a non-loopback bind without a token."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from studio.cli.main import main
from studio.service.jobs import JobManager
from studio.service.hosts import is_loopback
from studio.service.server import create_app


@pytest.fixture(scope="module")
def jobs(tmp_path_factory):
    jm = JobManager(tmp_path_factory.mktemp("safety") / "data", workers=1)
    yield jm
    jm.close()


def test_token_required_except_for_health(jobs):
    client = TestClient(create_app(jobs, token="s3cret"))
    r = client.get("/api/runs")
    assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
    assert client.get("/api/runs", headers={"Authorization": "Bearer wrong"}).status_code == 401
    assert client.post("/api/runs", json={}).status_code == 401
    assert client.get("/api/runs", headers={"Authorization": "Bearer s3cret"}).status_code == 200
    assert client.get("/api/health").status_code == 200


def test_no_token_means_open(jobs):
    assert TestClient(create_app(jobs)).get("/api/runs").status_code == 200


def test_cors_off_by_default_and_on_for_given_origins(jobs):
    headers = {"Origin": "https://evil.example", "Access-Control-Request-Method": "POST"}
    closed = TestClient(create_app(jobs))
    assert "access-control-allow-origin" not in closed.get("/api/health", headers=headers).headers
    assert closed.options("/api/runs", headers=headers).status_code in (405, 404)
    opened = TestClient(create_app(jobs, cors_origins=["https://lab.example"]))
    ok = {"Origin": "https://lab.example", "Access-Control-Request-Method": "POST"}
    r = opened.options("/api/runs", headers=ok)
    assert r.status_code == 200
    assert r.headers["access-control-allow-origin"] == "https://lab.example"
    assert opened.options("/api/runs", headers=headers).status_code == 400


def test_upload_limit(jobs):
    client = TestClient(create_app(jobs, max_upload_bytes=1000))
    r = client.post("/api/meshes", files={"file": ("big.stl", b"x" * 200_000)})
    assert r.status_code == 413


def test_loopback_detection():
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5")


def test_public_bind_without_token_warns(jobs, capsys):
    # the data folder is held by `jobs`, so the command stops before it binds anything
    code = main(["serve", "--headless", "--host", "0.0.0.0", "--data", str(jobs.data_dir)])
    err = capsys.readouterr().err
    assert "WARNING: binding 0.0.0.0 without --token" in err
    assert "another running job manager" in err and code == 1
    code = main(["serve", "--headless", "--host", "0.0.0.0", "--token", "t",
                 "--data", str(jobs.data_dir)])
    assert "WARNING" not in capsys.readouterr().err and code == 1


def test_serve_needs_headless(capsys):
    assert main(["serve"]) == 2
    assert "--headless" in capsys.readouterr().err


def test_port_in_use_is_a_clear_error(tmp_path, capsys):
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        code = main(["serve", "--headless", "--port", str(port), "--workers", "1",
                     "--data", str(tmp_path / "data"), "--log-level", "critical"])
    assert code == 1
    assert f"could not serve on 127.0.0.1:{port}" in capsys.readouterr().err


def test_after_a_stop_signal_a_hanging_thread_cannot_hold_the_server():
    # issue 13, item 2: SIGTERM could not stop a server whose request thread was stuck in
    # a build. After the signal, serve arms a deadline that ends the process even while
    # a non-daemon thread (here: a 100 s sleep) would keep the interpreter from exiting.
    import subprocess
    import sys
    import time

    code = ("import threading, time; from studio.cli.serve import _exit_after; "
            "threading.Thread(target=time.sleep, args=(100,)).start(); _exit_after(0.5, 143)")
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == 143 and time.monotonic() - t0 < 30
    assert "exiting now" in p.stderr
