"""The job service tried as a hostile client would (issue 13's measurements, re-runnable):
each case starts ``brush-studio serve --headless`` on 127.0.0.1 and a free port with a fresh
data folder, measures, prints one line of figures and stops the server.

    python benchmarks/service_robustness.py                     # every case
    python benchmarks/service_robustness.py --only kill-worker kill-server
    python benchmarks/service_robustness.py --schemathesis /tmp/st/bin/schemathesis \
        --max-examples 20

Cases:

* ``schemathesis``: schemathesis (its own virtual environment: ``--schemathesis PATH``; it
  is not a dependency of the project) against ``/openapi.json``, every check, phases
  examples, coverage and fuzzing; the cases it ran, its failures per check, and the 5xx
  answers counted from the server's own access log.
* ``concurrent``: 50 tiny scenes submitted at once by 50 threads; all must complete.
* ``kill-worker``: two long runs on two workers; SIGKILL one worker: its run fails (seconds
  from the kill to the failed state), the other completes.
* ``kill-server``: 4 threads submit tiny scenes for 3 s; SIGKILL the server; a new server on
  the same folder must list every submit that had been answered 201.
* ``disk-full``: the data folder on a 4 MiB tmpfs (needs root) filled while a run runs: the
  run fails saying why, a submit is 507, health says degraded; when space returns, a run
  completes and health is ok again.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from conftest import TINY_SCENE, fill_disk, mount_tmpfs  # noqa: E402  (one source)

FINAL = ("completed", "stopped", "failed", "cancelled")


def tiny(**run) -> dict:
    scene = json.loads(json.dumps(TINY_SCENE))
    scene["run"].update(run)
    return scene


class Server:
    """``brush-studio serve --headless`` on a free port (access log in ``log``)."""

    def __init__(self, data: Path, workers: int = 2, args: tuple = ()):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.port = s.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}"
        self.log = Path(data).parent / f"server-{self.port}.log"
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        env.pop("BRUSH_STUDIO_TOKEN", None)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "studio.cli", "serve", "--headless", "--port",
             str(self.port), "--workers", str(workers), "--data", str(data),
             "--log-level", "info", *args], cwd=ROOT, env=env,
            stdout=open(self.log, "w"), stderr=subprocess.STDOUT)
        self.client = httpx.Client(base_url=self.url, timeout=120)
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited:\n{self.log.read_text()}")
            try:
                h = self.client.get("/api/health", timeout=2).json()
                if sum(w["ready"] for w in h["worker_processes"]) == workers:
                    return  # every worker has imported the engine
            except (httpx.HTTPError, ValueError, KeyError):
                pass
            time.sleep(0.3)
        raise RuntimeError("server did not start")

    def wait(self, run_id: str, timeout: float = 600, until=FINAL) -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            info = self.client.get(f"/api/runs/{run_id}").json()
            if info["status"] in until:
                return info
            time.sleep(0.05)
        raise TimeoutError(f"run {run_id}: {info['status']} after {timeout} s")

    def stop(self) -> None:
        self.client.close()
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(60)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def case_schemathesis(tmp: Path, args) -> str:
    if not args.schemathesis:
        return "skipped: no --schemathesis PATH (pip install schemathesis in a venv)"
    token = ("--token", "schemathesis-token") if args.token else ()
    server = Server(tmp / "data", workers=1, args=token)
    try:
        t0 = time.monotonic()
        out = subprocess.run(
            [args.schemathesis, "run", f"{server.url}/openapi.json", "--checks", "all",
             "--phases", "examples,coverage,fuzzing", "--max-examples",
             str(args.max_examples), "-w", "2", "--request-timeout", "30", "--no-color",
             *(["-H", f"Authorization: Bearer {token[1]}"] if token else [])],
            capture_output=True, text=True, timeout=900, cwd=tmp).stdout  # (its cache dir)
        wall = time.monotonic() - t0
    finally:
        server.stop()
    (tmp / "schemathesis.txt").write_text(out)
    cases = re.search(r"(\d+) generated", out)
    failures = dict(re.findall(r"❌ (ST\d+ [^:\n]+): (\d+)", out.split("SUMMARY")[-1]))
    access = server.log.read_text()
    server_errors = len(re.findall(r'HTTP/1\.[01]" 5\d\d', access))
    requests = len(re.findall(r'HTTP/1\.[01]" \d\d\d', access))
    unauthorized = len(re.findall(r'HTTP/1\.[01]" 401', access))
    return (f"{'with a token: ' if token else ''}{cases.group(1) if cases else '?'} cases, "
            f"{requests} requests in {wall:.0f} s; 5xx answers: {server_errors}; 401 "
            f"answers: {unauthorized}; failures by check: "
            f"{failures or 'none'} (full output: {tmp / 'schemathesis.txt'})")


def case_concurrent(tmp: Path, args) -> str:
    server = Server(tmp / "data", workers=2)
    try:
        t0 = time.monotonic()
        with ThreadPoolExecutor(50) as pool:
            answers = list(pool.map(lambda i: server.client.post(
                "/api/runs", json=tiny(duration=0.002), params={"name": f"c{i}"}), range(50)))
        submitted = time.monotonic() - t0
        codes = sorted({r.status_code for r in answers})
        ids = [r.json()["id"] for r in answers if r.status_code == 201]
        infos = [server.wait(i) for i in ids]
        done = time.monotonic() - t0
    finally:
        server.stop()
    completed = sum(i["status"] == "completed" for i in infos)
    return (f"50 submits answered {codes} in {submitted:.2f} s; {len(set(ids))} distinct ids; "
            f"{completed}/50 completed in {done:.1f} s")


def case_kill_worker(tmp: Path, args) -> str:
    server = Server(tmp / "data", workers=2)
    try:
        long = tiny(duration=0.5, record_interval=0.005)
        a = server.client.post("/api/runs", json=long).json()["id"]
        b = server.client.post("/api/runs", json=long).json()["id"]
        info = server.wait(a, until=("running",))
        server.wait(b, until=("running",))
        while not (info := server.client.get(f"/api/runs/{a}").json())["sim_time"]:
            time.sleep(0.05)
        pid = info["worker_pid"]
        t0 = time.monotonic()
        os.kill(pid, signal.SIGKILL)
        a_info = server.wait(a, timeout=60)
        noticed = time.monotonic() - t0
        b_info = server.wait(b)
        health = server.client.get("/api/health").json()
    finally:
        server.stop()
    return (f"killed worker {pid}: its run {a_info['status']} after {noticed:.2f} s "
            f"({(a_info['error'] or '').split(';')[0]}); the other run {b_info['status']}; "
            f"workers alive after: {health['workers_alive']}/2")


def case_kill_server(tmp: Path, args) -> str:
    data = tmp / "data"
    server = Server(data, workers=2, args=("--max-queued", "0"))
    acknowledged: list[str] = []
    refused: list[int] = []
    stop = threading.Event()

    def submit_loop():
        with httpx.Client(base_url=server.url, timeout=30) as c:
            while not stop.is_set():
                try:
                    r = c.post("/api/runs", json=tiny(duration=0.002))
                except httpx.HTTPError:
                    return  # the server is gone
                if r.status_code == 201:
                    acknowledged.append(r.json()["id"])
                else:
                    refused.append(r.status_code)

    threads = [threading.Thread(target=submit_loop) for _ in range(4)]
    for t in threads:
        t.start()
    time.sleep(3.0)
    server.proc.kill()  # SIGKILL, with submits in flight
    server.proc.wait()
    stop.set()
    for t in threads:
        t.join()
    again = Server(data, workers=2)
    try:
        listed = {i["id"]: i["status"] for i in
                  again.client.get("/api/runs", params={"limit": 100000}).json()}
        lost = [i for i in acknowledged if i not in listed]
        at_restart = _count(listed.get(i) for i in acknowledged)
        t0 = time.monotonic()
        final = _count(again.wait(i)["status"] for i in acknowledged if i in listed)
        ran = time.monotonic() - t0
    finally:
        again.stop()
    return (f"{len(acknowledged)} submits acknowledged (201) before SIGKILL, {len(refused)} "
            f"refused; after restart {len(lost)} lost; their states at restart: "
            f"{at_restart}, {ran:.0f} s later: {final}")


def _count(values) -> dict:
    out: dict = {}
    for v in values:
        out[v] = out.get(v, 0) + 1
    return out


def case_disk_full(tmp: Path, args) -> str:
    mnt = tmp / "tmpfs"
    mnt.mkdir()
    problem = mount_tmpfs(mnt)
    if problem:
        return f"skipped: {problem} (tests/server/test_server_storage.py covers a full disk " \
               f"with a patched writer too)"
    server = None
    try:
        server = Server(mnt / "data", workers=1, args=("--min-free-mb", "0"))
        run = server.client.post("/api/runs", json=tiny(duration=0.5, record_interval=0.0005)
                                 ).json()["id"]
        server.wait(run, until=("running",))
        filler = mnt / "filler"
        fill_disk(filler)
        info = server.wait(run, timeout=300)
        full = server.client.post("/api/runs", json=tiny(duration=0.002))
        degraded = server.client.get("/api/health").json()
        filler.unlink()
        server.client.delete(f"/api/runs/{run}", params={"purge": "true"})
        after = server.client.post("/api/runs", json=tiny(duration=0.002)).json()["id"]
        after_info = server.wait(after)
        ok = server.client.get("/api/health").json()["status"]
    finally:
        if server is not None:
            server.stop()
        subprocess.run(["umount", "-l", str(mnt)], check=False)
    return (f"run on the full disk: {info['status']} ({(info['error'] or '')[:90]}); submit "
            f"while full: {full.status_code}; health: {degraded['status']} "
            f"({'; '.join(degraded['problems'])[:90]}); after freeing space a run "
            f"{after_info['status']}, health {ok}")


CASES = {"schemathesis": case_schemathesis, "concurrent": case_concurrent,
         "kill-worker": case_kill_worker, "kill-server": case_kill_server,
         "disk-full": case_disk_full}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", nargs="*", choices=list(CASES), default=list(CASES))
    p.add_argument("--schemathesis", default=shutil.which("schemathesis"),
                   help="the schemathesis command (default: on PATH)")
    p.add_argument("--max-examples", type=int, default=20)
    p.add_argument("--token", action="store_true",
                   help="schemathesis against a server with a bearer token (it sends it, "
                        "and checks that requests without it are refused)")
    args = p.parse_args()
    for name in args.only:
        tmp = Path(tempfile.mkdtemp(prefix=f"brush-svc-{name}-"))
        t0 = time.monotonic()
        try:
            line = CASES[name](tmp, args)
        except Exception as exc:  # report and go on with the other cases
            line = f"ERROR {type(exc).__name__}: {exc}"
        print(f"{name:13s} {line}  [{time.monotonic() - t0:.0f} s]", flush=True)
        if name != "schemathesis":
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
