"""Run a scene through the HTTP job service with the Python client
=================================================================

Starts the headless service (``brush-studio serve --headless``) as a subprocess on
127.0.0.1 and a free port, with its job data in a folder of its own; then, with
``studio.service.client.Client``: fetches a preset the server ships (the two-plate gripper, cut to
its first 10 ms), submits it, polls the run's progress, downloads its HDF5 result and
reads it with ``engine.open_result``; finally stops the server (SIGTERM: it cancels what is
still running and exits). The HTTP API is documented in docs/api.md ("HTTP API").

Run it from the repository root, with the package installed (``pip install -e .``)::

    python examples/04_service_client.py [OUT_DIR]

It writes ``OUT_DIR/run.h5`` (the downloaded result), ``OUT_DIR/server.log`` and the
server's data folder ``OUT_DIR/server-data/`` (default OUT_DIR:
``./example_output/04_service_client``).
"""
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

import engine
from studio.service.client import ApiError, Client

out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "example_output/04_service_client")
out_dir.mkdir(parents=True, exist_ok=True)

# A free port on 127.0.0.1 (the operating system picks one; the server binds it next).
with socket.socket() as s:
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
url = f"http://127.0.0.1:{port}"

log = open(out_dir / "server.log", "w")
server = subprocess.Popen(
    [sys.executable, "-m", "studio.cli", "serve", "--headless", "--host", "127.0.0.1",
     "--port", str(port), "--workers", "1", "--data", str(out_dir / "server-data"),
     "--log-level", "warning"],
    stdout=log, stderr=subprocess.STDOUT)
try:
    with Client(url) as client:
        # Wait until the server answers and its worker process is up.
        deadline = time.monotonic() + 120
        while True:
            if server.poll() is not None:
                sys.exit(f"the server exited with code {server.returncode}; "
                         f"see {out_dir / 'server.log'}")
            try:
                if client.health()["workers_alive"] > 0:
                    break
            except (httpx.HTTPError, ApiError):   # not listening yet
                pass
            if time.monotonic() > deadline:
                sys.exit("the server did not start within 120 s")
            time.sleep(0.3)
        print(f"server up at {url}")

        # A scene the server ships (GET /api/presets lists them): the two-plate gripper
        # closing on a cylinder, cut to its first 10 ms so that the example runs in seconds
        scene = client.preset("gripper")
        scene["run"]["duration"] = 0.01
        scene["run"]["record_interval"] = 0.001
        run_id = client.submit(scene, name="example 04")
        print(f"submitted run {run_id}")

        # Poll its state (client.wait(run_id) does the same with a progress bar).
        last = None
        while True:
            info = client.get(run_id)
            state = (info["status"], round(info["progress"] or 0.0, 1))
            if state != last:
                print(f"  {info['status']:>9}: {info['progress'] or 0.0:4.0%} "
                      f"(t = {info['sim_time'] or 0.0:.4g} of {info['until']:.4g} s)")
                last = state
            if info["status"] in ("completed", "stopped", "failed", "cancelled"):
                break
            time.sleep(0.2)
        print(f"run {run_id}: {info['status']}, {info['summary']['steps']} steps, "
              f"{info['wall_s']:.2f} s wall")

        path = client.download(run_id, out_dir / "run.h5")
        with engine.open_result(path) as res:
            grip = res.series("bodies/target/contact_force")   # (n_frames, 3), N
            print(f"downloaded {path}: status {res.status}, {res.n_frames} frames, "
                  f"contact force on the target at the end {grip[-1]} N")
finally:
    server.send_signal(signal.SIGTERM)    # the server stops its workers and exits
    try:
        code = server.wait(60)
    except subprocess.TimeoutExpired:
        server.kill()
        code = server.wait()
    log.close()
    print(f"server stopped (exit code {code})")
