"""Run a scene through the HTTP job service with the Python client
=================================================================

Starts the headless service (``brush-studio serve --headless``) as a subprocess on
127.0.0.1 and a free port, with its job data in a folder of its own; then, with
``studio.client.Client``: submits a small scene (a 3 x 3 brush pressed by a box for 10 ms,
as in ``01_build_and_run.py``), polls the run's progress, downloads its HDF5 result and
reads it with ``engine.open_result``; finally stops the server (SIGTERM: it cancels what is
still running and exits). The HTTP API is documented in docs/api.md ("HTTP API").

Run it from the repository root, with the package installed (``pip install -e .``)::

    python examples/04_service_client.py [OUT_DIR]

It writes ``OUT_DIR/run.h5`` (the downloaded result), ``OUT_DIR/server.log`` and the
server's data folder ``OUT_DIR/server-data/`` (default OUT_DIR:
``./example_output/04_service_client``).
"""
import math
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

import engine
from studio.client import ApiError, Client

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

        scene = {
            "schema_version": 1,
            "name": "example_service_press",
            "description": "3 x 3 silicone brush pressed 1 mm by a PLA box (examples/04)",
            "materials": {
                "silicone": {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48,
                             "density": 1700.0},
                "pla": {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1240.0},
            },
            "contact_pairs": [
                {"materials": ["silicone", "silicone"], "friction_angle": math.radians(44)},
                {"materials": ["silicone", "pla"], "friction_angle": math.radians(24)},
            ],
            "brushes": [
                {"name": "brush", "material": "silicone", "rows": 3, "columns": 3,
                 "pitch": [0.003, 0.003], "bristle_length": 0.02, "root_radius": 0.001,
                 "tip_radius": 0.0005, "n_nodes": 5},
            ],
            "bodies": [
                {"name": "box", "material": "pla",
                 "shape": {"type": "box", "size": [0.015, 0.015, 0.002]},
                 "pose": {"position": [0.0, 0.0, 0.022]},
                 "motion": {"type": "kinematic",
                            "profile": {"kind": "constant", "velocity": [0.0, 0.0, -0.15],
                                        "duration": 0.01}}},
            ],
            "environment": {"gravity": [0.0, 0.0, -9.81]},
            "run": {"duration": 0.01, "record_interval": 0.0005},
        }
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
            force = res.series("brushes/brush/root_force")   # (n_frames, 3), N
            print(f"downloaded {path}: status {res.status}, {res.n_frames} frames, "
                  f"last vertical root force {force[-1, 2]:.6g} N")
finally:
    server.send_signal(signal.SIGTERM)    # the server stops its workers and exits
    try:
        code = server.wait(60)
    except subprocess.TimeoutExpired:
        server.kill()
        code = server.wait()
    log.close()
    print(f"server stopped (exit code {code})")
