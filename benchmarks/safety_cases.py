"""Issue 28's hostile inputs, measured (re-runnable): mesh parse bombs (seconds and peak
memory before the 413), output paths that are not regular files (the CLI's exit code and
time), and the studio's Host/Origin checks (status codes). Each case runs in its own
process, so that its peak memory is its own.

    python benchmarks/safety_cases.py

Prints one line per case: what was sent, the answer, wall seconds, peak RSS growth in MiB.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

MESH_CASE = r"""
import json, resource, sys, time
sys.path.insert(0, sys.argv[1])
from studio.service.jobs import JobManager, MeshError
import trimesh, numpy  # (imported before the baseline)
path, fmt = sys.argv[2], sys.argv[2].rsplit(".", 1)[1]
jm = JobManager(sys.argv[3], workers=1)
data = open(path, "rb").read()
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key + ":"):
            return int(line.split()[1])  # kB
open("/proc/self/clear_refs", "w").write("5")  # reset the peak (VmHWM) to the current RSS
rss0 = status("VmRSS")
t0 = time.perf_counter()
try:
    jm.add_mesh(data, "bomb." + fmt)
    answer = "stored"
except MeshError as exc:
    answer = f"{exc.status} {str(exc)[:70]}"
dt = time.perf_counter() - t0
grown = (status("VmHWM") - rss0) / 1024
jm.close()
print(json.dumps({"answer": answer, "s": dt, "mib": grown, "bytes": len(data)}))
"""


def mesh_cases() -> None:
    sys.path.insert(0, str(ROOT / "tests" / "server"))
    from test_mesh_bombs import BOMBS

    for name, (data, fmt, _) in BOMBS.items():
        with tempfile.TemporaryDirectory() as d:
            bomb = Path(d) / f"bomb.{fmt}"
            bomb.write_bytes(data)  # the child reads it before its baseline: only the
            # parser's memory is counted
            out = subprocess.run([sys.executable, "-c", MESH_CASE, str(ROOT), str(bomb),
                                  d + "/data"],
                                 capture_output=True, text=True, cwd=ROOT)
            if out.returncode:
                print(f"mesh {name}: error {out.stderr[-300:]}")
                continue
            r = json.loads(out.stdout.strip().splitlines()[-1])
            print(f"mesh {name:26s} {r['bytes'] / 2**20:6.1f} MB -> {r['answer']:<60s} "
                  f"{r['s']:6.2f} s  +{r['mib']:.0f} MiB peak")


def output_cases() -> None:
    import socket

    with tempfile.TemporaryDirectory(dir="/tmp") as d:
        d = Path(d)
        fifo = d / "fifo"
        os.mkfifo(fifo)
        sock = socket.socket(socket.AF_UNIX)
        sock.bind(str(d / "sock"))
        subprocess.run([sys.executable, "-m", "studio.cli", "demo", "--scene-only", "-o",
                        str(d / "s")], cwd=ROOT, capture_output=True, check=True)
        scene = str(d / "s" / "scene.json")
        cases = {"run -o FIFO": ["run", scene, "-o", str(fifo), "-q"],
                 "run -o SOCKET": ["run", scene, "-o", str(d / "sock"), "-q"],
                 "run -o DIR": ["run", scene, "-o", str(d), "-q"],
                 "run --summary FIFO": ["run", scene, "-o", str(d / "r.h5"), "--summary",
                                        str(fifo), "-q"],
                 "run -o missing/dir/x.h5": ["run", scene, "-o", str(d / "no" / "dir" / "x.h5"),
                                             "-q"],
                 "demo -o FIFO": ["demo", "-o", str(fifo)],
                 "study rod -o FIFO": ["study", "rod", "-o", str(fifo), "--workers", "1"]}
        for name, argv in cases.items():
            t0 = time.perf_counter()
            p = subprocess.run([sys.executable, "-m", "studio.cli", *argv], cwd=ROOT,
                               capture_output=True, text=True, timeout=300)
            dt = time.perf_counter() - t0
            line = (p.stderr.strip().splitlines() or [""])[-1]
            print(f"cli  {name:26s} exit {p.returncode} in {dt:5.1f} s: {line[:90]}")
        assert fifo.is_fifo() and not (d / "no").exists()
        sock.close()


def studio_cases() -> None:
    from fastapi.testclient import TestClient

    from studio.service.jobs import JobManager
    from studio.service.hosts import allowed_hosts
    from studio.service.server.studio_routes import make_api_app
    from studio.service.server.ws_guard import guarded_viser_server

    sys.path.insert(0, str(ROOT / "tests" / "server"))
    from test_studio_origin import _Studio, _upgrade

    with tempfile.TemporaryDirectory() as d:
        jm = JobManager(Path(d) / "data", workers=1)
        c = TestClient(make_api_app(jm, _Studio(), viser_port=8080),
                       base_url="http://127.0.0.1:8081")
        r = c.post("/api/runs", content="{}", headers={
            "Host": "evil.example:8081", "Origin": "http://evil.example:8081",
            "Content-Type": "application/json"})
        print(f"studio POST /api/runs, rebound Host+Origin      -> {r.status_code}")
        r = c.get("/api/runs", headers={"Host": "evil.example:8081"})
        print(f"studio GET /api/runs, rebound Host               -> {r.status_code}")
        r = c.get("/studio?preset=demo", follow_redirects=False)
        print(f"studio GET /studio?preset=demo (shared design)   -> {r.status_code}")
        r = c.post("/studio?preset=demo", headers={"Origin": "http://evil.example"},
                   follow_redirects=False)
        print(f"studio POST /studio?preset=demo, foreign Origin  -> {r.status_code}")
        r = c.post("/api/runs", content="{}", headers={"Origin": "http://localhost:8081",
                                                      "Content-Type": "application/json"})
        print(f"studio POST Origin localhost, Host 127.0.0.1     -> {r.status_code} (not 403)")
        jm.close()
    server = guarded_viser_server("127.0.0.1", 0, allowed_hosts("127.0.0.1"), verbose=False)
    port = server.get_port()
    for host, origin in ((f"127.0.0.1:{port}", "http://evil.example"),
                         (f"evil.example:{port}", f"http://evil.example:{port}"),
                         (f"127.0.0.1:{port}", f"http://localhost:{port}")):
        print(f"studio WebSocket upgrade Host {host.split(':')[0]:13s} Origin "
              f"{origin:28s} -> {_upgrade(port, host, origin)}")
    server.stop()


if __name__ == "__main__":
    os.chdir(ROOT)
    sys.path.insert(0, str(ROOT))
    output_cases()
    mesh_cases()
    studio_cases()
