"""The job layer shared by the HTTP server (``studio.server``) and the 3D studio.

A :class:`JobManager` owns a bounded pool of worker processes (default: one per core), a
FIFO queue of submitted scenes and a SQLite database (``DATA/jobs.sqlite``) that keeps every
job's state across restarts. Each run writes its files under ``DATA/runs/<job_id>/``
(``result.h5``, the engine's result file, and ``scene.json``)::

    from studio.jobs import JobManager

    jobs = JobManager(Path("data"), workers=2)
    job_id = jobs.submit(scene_dict, name="first try")   # engine.SceneError if invalid
    info = jobs.wait(job_id)                             # JobInfo: status, summary, error...
    with engine.open_result(jobs.result_path(job_id)) as res:
        ...
    jobs.close()

How it works. Worker processes are started with the ``spawn`` method, set
``NUMBA_NUM_THREADS`` so that workers x threads <= cores, import the engine once and then
run one job after another. One monitor thread in the manager hands queued jobs to idle
workers (oldest first), receives their progress (the engine's ``on_progress``: simulated
time, steps/s, ETA) through a pipe per worker and writes it to the database. A cancel reaches
the running worker through shared memory and is checked by the engine between compiled
chunks (about 0.2 s); a worker that does not stop within ``cancel_grace_s`` is terminated. A
worker that dies (killed, out of memory, a crash in compiled code) is noticed through its
process sentinel: its job is marked ``failed`` with the reason, the partial result file is
kept (engine result files stay readable after a crash) and a new worker takes its place.
When a manager starts on a folder whose database lists ``running`` jobs (the previous server
was killed), those are marked ``failed`` as interrupted; ``queued`` jobs are run.

Studies run as jobs too (``submit_study``): the options come as a dict, are checked and made
the study's typed ``Options`` by :mod:`studio.studies.registry` (no output/scheduler options
and no file paths from clients: scenes are preset names), and the worker calls the study's
``run(options, DATA/runs/<job_id>/study/, progress=..., cancel=...)`` in-process: its progress
callback becomes the job's progress, the job's cancel is its cancel flag (finished runs are
kept, as with Ctrl-C) and what it prints goes into ``log.txt``::

    job_id = jobs.submit_study("wedge", {"preset": "wedge_60", "depth_mm": 2, "nodes": 3})
    jobs.wait(job_id).files          # ["force_depth.csv", "force_depth.png", ...]

Uploaded meshes (``add_mesh``) are stored under ``DATA/meshes/`` by content hash; a scene
names one as ``"file": "mesh:<id>"`` in a mesh shape, resolved here before validation.

Workers are started with ``multiprocessing``'s ``spawn`` method, which re-imports the main
script in each worker: a script that creates a JobManager must do so under
``if __name__ == "__main__":`` (the ``brush-studio`` command does).
"""
from __future__ import annotations

import hashlib
import io
import json
import math
import os
import re
import signal
import sqlite3
import sys
import threading
import time
import traceback
import uuid
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Optional, Union

from .jsonable import jsonable as _to_json

STATUSES = ("queued", "running", "completed", "stopped", "failed", "cancelled")
FINAL_STATUSES = frozenset({"completed", "stopped", "failed", "cancelled"})
MESH_FORMATS = ("stl", "obj", "ply")
MESH_PREFIX = "mesh:"
DEFAULT_MAX_TRIANGLES = 200_000  # the engine's own limit (docs/scene.md)

_JOB_ID = re.compile(r"^[0-9a-f]{12}$")
_MESH_ID = re.compile(r"^[0-9a-f]{16}$")


def cpu_count() -> int:
    """Cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def jsonable(value: Any) -> Any:
    """Strict JSON for API answers: non-finite floats become null."""
    return _to_json(value, nonfinite="null")


# ----------------------------------------------------------------------------- job info
@dataclass
class JobInfo:
    """One job's state, as the database holds it (times are unix seconds)."""

    id: str
    name: str
    status: str
    created: float
    started: Optional[float] = None
    finished: Optional[float] = None
    progress: float = 0.0            # 0..1 (steps done / steps to do)
    sim_time: Optional[float] = None  # simulated time reached, s
    until: Optional[float] = None     # simulated time to run to, s
    steps_per_s: Optional[float] = None
    eta_s: Optional[float] = None     # wall seconds left
    dt: Optional[float] = None
    dt_limited_by: Optional[str] = None
    stages: dict = field(default_factory=dict)   # stage name -> wall s (when finished)
    summary: dict = field(default_factory=dict)  # the engine's run summary (when finished)
    error: Optional[str] = None
    worker_pid: Optional[int] = None  # the worker process running (or that ran) the job
    assembled: list = field(default_factory=list)  # the stages the build assembled
    warnings: list = field(default_factory=list)   # the build's and the run's warnings
    wall_s: Optional[float] = None    # started -> finished (or -> now while running)
    kind: str = "run"                 # "run" (one scene) or "study" (submit_study)
    study: Optional[str] = None       # a study job's study name (wedge, spin, ...)
    options: dict = field(default_factory=dict)  # a study job's options, as submitted
    message: Optional[str] = None     # a study job's progress text (its current bar)
    files: list = field(default_factory=list)    # a study job's output files (relative)

    @property
    def done(self) -> bool:
        return self.status in FINAL_STATUSES

    def to_dict(self) -> dict:
        return jsonable(asdict(self))


_COLUMNS = ("id", "name", "status", "created", "started", "finished", "progress", "sim_time",
            "until", "steps_per_s", "eta_s", "dt", "dt_limited_by", "stages", "summary",
            "error", "worker_pid", "assembled", "warnings", "kind", "study", "options",
            "message")
_JSON_COLUMNS = {"stages": dict, "summary": dict, "assembled": list, "warnings": list,
                 "options": dict}
# columns added after the first release: added to an older database when it is opened
_ADDED_COLUMNS = (("kind", "TEXT NOT NULL DEFAULT 'run'"), ("study", "TEXT"),
                  ("options", "TEXT NOT NULL DEFAULT '{}'"), ("argv", "TEXT"),
                  ("message", "TEXT"), ("resolved", "TEXT"))

_SCHEMA = """
CREATE TABLE IF NOT EXISTS jobs (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    id TEXT UNIQUE NOT NULL,
    name TEXT NOT NULL,
    status TEXT NOT NULL,
    created REAL NOT NULL,
    started REAL, finished REAL,
    progress REAL NOT NULL DEFAULT 0,
    sim_time REAL, until REAL, steps_per_s REAL, eta_s REAL,
    dt REAL, dt_limited_by TEXT,
    stages TEXT NOT NULL DEFAULT '{}',
    summary TEXT NOT NULL DEFAULT '{}',
    error TEXT,
    worker_pid INTEGER,
    assembled TEXT NOT NULL DEFAULT '[]',
    warnings TEXT NOT NULL DEFAULT '[]',
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    scene TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS jobs_status ON jobs (status, seq);
CREATE TABLE IF NOT EXISTS meshes (
    id TEXT PRIMARY KEY,
    filename TEXT NOT NULL,
    format TEXT NOT NULL,
    created REAL NOT NULL,
    info TEXT NOT NULL
);
"""


def _finite(x) -> Optional[float]:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _describe_exit(code: Optional[int]) -> str:
    if code is None:
        return "exit status unknown"
    if code < 0:
        try:
            return f"killed by signal {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


class MeshError(ValueError):
    """An uploaded mesh that cannot be used: ``status`` is the HTTP status that fits
    (413 too large, 422 unreadable or invalid)."""

    def __init__(self, message: str, status: int = 422):
        super().__init__(message)
        self.status = status


# ----------------------------------------------------------------------------- studies
# study names, option checking and errors live with the studies (studio.studies.registry)
from .studies.registry import (SCENE_OPTIONS, SERVER_OPTIONS, STUDIES,  # noqa: E402,F401
                               StudyOptionError, study_argv, study_options)

STUDY_LOG = "log.txt"  # the study's printed output, in its output folder


def _study_files(folder: Path) -> list[str]:
    from .studies.api import study_files

    return study_files(folder)


def _tail(path: Path, n: int = 12) -> str:
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError:
        return ""
    lines = [ln.rstrip() for ln in lines if ln.strip() and "\r" not in ln]
    return "\n".join(lines[-n:])


# ----------------------------------------------------------------------------- worker process
def _worker_main(conn, cancel_seq, threads: int, parent_pid: int) -> None:
    """A worker process: import the engine once, then run the jobs the manager sends."""
    os.environ["NUMBA_NUM_THREADS"] = str(threads)
    # Ctrl-C in a terminal reaches the whole process group: the manager decides for us.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # a study job starts a local Dask cluster (worker processes) from this process: allowed
    # although the manager started this one as a daemon (which it ends when it exits)
    import multiprocessing

    multiprocessing.current_process()._config["daemon"] = False
    import numba

    # the kernel modules, numba and trimesh: once per worker (``import engine`` alone is
    # light and would leave them to the first job)
    import engine.build  # noqa: F401
    import engine.run  # noqa: F401

    conn.send(("ready", os.getpid(), int(numba.config.NUMBA_NUM_THREADS)))
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if not msg or msg[0] not in ("run", "study"):
            return
        try:
            if msg[0] == "run":
                _, seq, job_id, scene_json, h5_path = msg
                _worker_run(conn, cancel_seq, parent_pid, seq, job_id, scene_json, h5_path)
            else:
                _, seq, job_id, study, options, argv, out_dir = msg
                _worker_study(conn, cancel_seq, parent_pid, seq, job_id, study, options, argv,
                              out_dir)
        except (BrokenPipeError, EOFError, OSError):
            return  # the manager is gone


def _worker_run(conn, cancel_seq, parent_pid, seq, job_id, scene_json, h5_path) -> None:
    import engine

    def cancelled() -> bool:
        return cancel_seq.value == seq or os.getppid() != parent_pid

    status, summary, error = "failed", {}, None
    last = [0.0]

    def on_progress(p) -> None:
        now = time.monotonic()
        if now - last[0] < 0.2 and p.steps < p.total_steps:
            return
        last[0] = now
        conn.send(("progress", job_id, {
            "sim_time": p.time, "until": p.until,
            "progress": p.fraction if p.total_steps else 1.0,
            "steps_per_s": p.steps_per_s, "eta_s": p.eta_s}))

    try:
        scene = engine.parse_scene(scene_json)
        system = engine.build(scene)
        conn.send(("built", job_id, {
            "dt": system.dt, "dt_limited_by": system.dt_limited_by,
            "until": scene.run.duration, "sim_time": system.time,
            "assembled": list(system.stages), "warnings": list(system.warnings)}))
        if cancelled():
            status = "cancelled"
        else:
            result = engine.run(system, output=h5_path, on_progress=on_progress,
                                cancel=cancelled, progress_interval=0.25)
            status, summary = result.status, dict(result.summary)
    except engine.InstabilityError as exc:
        res = getattr(exc, "result", None)
        summary = dict(res.summary) if res is not None else {}
        error = str(exc)
    except engine.SceneError as exc:
        error = str(exc)
    except engine.BrushStudioError as exc:
        error = f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # report any bug with its traceback; the worker goes on
        error = f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"
    conn.send(("done", job_id, {"status": status, "summary": jsonable(summary),
                                "error": error, "finished": time.time()}))


class _JobCancel:
    """The cancel flag a study job's ``run`` polls (``is_set``): the manager's cancel of this
    job through shared memory, or the manager gone."""

    def __init__(self, cancel_seq, seq: int, parent_pid: int):
        self.cancel_seq, self.seq, self.parent_pid = cancel_seq, seq, parent_pid

    def is_set(self) -> bool:
        return self.cancel_seq.value == self.seq or os.getppid() != self.parent_pid


def _worker_study(conn, cancel_seq, parent_pid, seq, job_id, study, options, argv,
                  out_dir) -> None:
    """Run a study in this process through its typed API (``registry.get(study).run``):
    its progress callback reports to the manager, its cancel is the job's; what it prints
    goes into ``out_dir/log.txt``."""
    import contextlib

    from .exit_codes import EXIT_OK, describe
    from .studies import registry

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    log_path = out / STUDY_LOG
    t0 = time.time()
    cancel = _JobCancel(cancel_seq, seq, parent_pid)

    def progress(fraction: float, message: str) -> None:
        try:
            conn.send(("study_progress", job_id, {"progress": fraction, "message": message}))
        except (OSError, ValueError):
            pass

    code, error = 1, None
    with open(log_path, "a", buffering=1) as log, contextlib.redirect_stdout(log), \
            contextlib.redirect_stderr(log):
        entry = registry.get(study)
        print("$ " + " ".join(w for w in ("brush-studio", entry.command, study) if w) + " "
              + " ".join(argv), flush=True)
        try:
            result = entry.run(entry.options_from_dict(options), out, progress=progress,
                               cancel=cancel)
            code = result.exit_code
        except Exception as exc:  # a bug in a study: its traceback in the log
            error = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
        print(f"exit code {code}", flush=True)
    if cancel.is_set() and code != EXIT_OK:
        status, error = "cancelled", "cancelled"
    elif code == EXIT_OK:
        status = "completed"
    else:
        status = "failed"
        detail = error or _tail(log_path)
        error = f"the study ended with exit code {code} ({describe(code)})" + \
            (f":\n{detail}" if detail else "")
    summary = {"exit_code": code, "wall_s": time.time() - t0, "study": study,
               "files": len(_study_files(out))}
    study_json = out / "study.json"
    if study_json.is_file():
        try:
            data = json.loads(study_json.read_text())
            summary["runs"] = data.get("runs")
            summary["failed_runs"] = data.get("failed")
        except (OSError, ValueError, AttributeError):
            pass
    conn.send(("done", job_id, {"status": status, "summary": jsonable(summary),
                                "error": error, "finished": time.time()}))


class _Worker:
    """The manager's handle on one worker process (used by the monitor thread only, except
    ``cancel_seq`` which ``cancel`` may set under the manager's lock)."""

    def __init__(self, ctx, threads: int):
        import multiprocessing.connection  # noqa: F401

        self.conn, child = ctx.Pipe(duplex=True)
        self.cancel_seq = ctx.Value("q", -1, lock=False)
        self.process = ctx.Process(target=_worker_main, name="brush-studio-worker",
                                   args=(child, self.cancel_seq, threads, os.getpid()),
                                   daemon=True)
        self.process.start()
        child.close()
        self.ready = False
        self.numba_threads: Optional[int] = None  # what numba reports in the worker
        self.job_id: Optional[str] = None
        self.seq: Optional[int] = None
        self.cancel_at: Optional[float] = None  # monotonic time a cancel was requested
        self.grace: float = 5.0  # how long the running job may take to honour a cancel

    @property
    def pid(self) -> Optional[int]:
        return self.process.pid

    def stop(self, timeout: float = 2.0) -> None:
        try:
            self.conn.send(("stop",))
        except (OSError, ValueError):
            pass
        self.process.join(timeout)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(2.0)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(2.0)
        self.conn.close()


# ----------------------------------------------------------------------------- manager
class JobManager:
    """Bounded pool of worker processes, FIFO queue, state in ``data_dir/jobs.sqlite``.

    ``workers``: pool size (default one per core). ``cancel_grace_s``: how long a worker may
    take to honour a cancel before it is terminated. ``max_triangles``: the largest uploaded
    mesh accepted by :meth:`add_mesh`.
    """

    def __init__(self, data_dir: Union[str, Path], workers: Optional[int] = None, *,
                 cancel_grace_s: float = 5.0, max_triangles: int = DEFAULT_MAX_TRIANGLES,
                 scheduler: Optional[str] = None, study_cancel_grace_s: float = 30.0):
        import multiprocessing as mp

        self.data_dir = Path(data_dir).resolve()
        self.runs_dir = self.data_dir / "runs"
        self.meshes_dir = self.data_dir / "meshes"
        for d in (self.data_dir, self.runs_dir, self.meshes_dir):
            d.mkdir(parents=True, exist_ok=True)
        cores = cpu_count()
        if workers is None:
            workers = cores
        if not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers = {workers!r}: must be an integer >= 1")
        self.n_workers = workers
        self.threads_per_worker = max(1, cores // workers)
        self.cancel_grace_s = float(cancel_grace_s)
        self.max_triangles = int(max_triangles)
        if scheduler is not None and "://" not in str(scheduler):
            raise ValueError(f"scheduler = {scheduler!r}: expected an address like "
                             f"tcp://HOST:PORT")
        self.scheduler = scheduler  # study jobs' Dask scheduler (None: one local worker)
        self.study_cancel_grace_s = float(study_cancel_grace_s)

        self._lock_file = self._take_folder_lock()
        self._lock = threading.RLock()          # the database connection and worker table
        self._changed = threading.Condition(self._lock)
        self._db = sqlite3.connect(str(self.data_dir / "jobs.sqlite"), timeout=30,
                                   check_same_thread=False, isolation_level=None)
        self._db.row_factory = sqlite3.Row
        with self._lock:
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=NORMAL")
            self._db.executescript(_SCHEMA)
            have = {r[1] for r in self._db.execute("PRAGMA table_info(jobs)").fetchall()}
            for col, decl in _ADDED_COLUMNS:
                if col not in have:
                    self._db.execute(f"ALTER TABLE jobs ADD COLUMN {col} {decl}")
            self._recover()

        self._ctx = mp.get_context("spawn")
        self._workers: list[_Worker] = []
        self._closing = False
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_w, False)
        self._respawn_after = 0.0
        self._start_failures = 0
        self._monitor = threading.Thread(target=self._monitor_loop, name="job-monitor",
                                         daemon=True)
        self._monitor.start()

    # ------------------------------------------------------------------ public API
    def submit(self, scene, name: Optional[str] = None, *, allow_files: bool = True,
               check_build: bool = True) -> str:
        """Queue a scene (an ``engine.Scene``, a dict or JSON text); returns the job id.

        Raises ``engine.SceneError`` naming every bad field. Mesh shapes may name an uploaded
        mesh as ``"mesh:<id>"``; with ``allow_files=False`` (the HTTP server) they must, and
        no other file path is accepted. ``check_build`` also builds the scene here, so that
        what only the build can see (an unreadable mesh, missing mass properties) is reported
        now rather than as a failed job.
        """
        import engine

        scene = self._resolve_scene(scene, allow_files=allow_files)
        if check_build:
            engine.build(scene)
        if name is None or not str(name).strip():
            name = scene.name
        name = str(name).strip()[:200]
        scene_json = scene.to_json()
        job_id = uuid.uuid4().hex[:12]
        run_dir = self.runs_dir / job_id
        run_dir.mkdir(parents=True, exist_ok=False)
        (run_dir / "scene.json").write_text(scene_json + "\n")
        with self._lock:
            self._db.execute(
                "INSERT INTO jobs (id, name, status, created, until, scene) "
                "VALUES (?, ?, 'queued', ?, ?, ?)",
                (job_id, name, time.time(), _finite(scene.run.duration), scene_json))
            self._changed.notify_all()
        self._wake()
        return job_id

    def submit_study(self, study: str, options: Optional[dict] = None,
                     name: Optional[str] = None) -> str:
        """Queue a study (``wedge``, ``spin``, ``refinement``, ``sensitivity``,
        ``montecarlo``, ``rod``, ``convergence``) with ``options`` (its command-line options
        as a dict, see :func:`study_argv`); returns the job id. Raises
        :class:`StudyOptionError` for an unknown study or a bad option. The study writes its
        files into ``DATA/runs/<id>/study/`` (:meth:`study_files`); it runs on one local
        Dask worker, or on the manager's ``scheduler``."""
        from .studies.registry import make_options, options_to_dict

        typed, argv = make_options(study, options, scheduler=self.scheduler)
        resolved = options_to_dict(typed)
        if name is None or not str(name).strip():
            name = f"{study} study"
        name = str(name).strip()[:200]
        job_id = uuid.uuid4().hex[:12]
        run_dir = self.runs_dir / job_id
        (run_dir / "study").mkdir(parents=True, exist_ok=False)
        spec = {"study": study, "options": jsonable(options or {}), "argv": argv,
                "resolved": resolved}
        (run_dir / "study_job.json").write_text(json.dumps(spec, indent=1) + "\n")
        with self._lock:
            self._db.execute(
                "INSERT INTO jobs (id, name, status, created, scene, kind, study, options, "
                "argv, resolved) VALUES (?, ?, 'queued', ?, '', 'study', ?, ?, ?, ?)",
                (job_id, name, time.time(), study, json.dumps(spec["options"]),
                 json.dumps(argv), json.dumps(resolved)))
            self._changed.notify_all()
        self._wake()
        return job_id

    def study_dir(self, job_id: str) -> Path:
        """A study job's output folder (KeyError if unknown or not a study)."""
        info = self.get(job_id)
        if info.kind != "study":
            raise KeyError(job_id)
        return self.runs_dir / job_id / "study"

    def study_files(self, job_id: str) -> list[str]:
        """A study job's output files so far: paths relative to its folder, sorted."""
        return _study_files(self.study_dir(job_id))

    def study_file(self, job_id: str, name: str) -> Path:
        """One output file of a study job, by a name from :meth:`study_files` only (no
        other path is ever opened); KeyError otherwise."""
        if name not in self.study_files(job_id):
            raise KeyError(name)
        return self.study_dir(job_id) / name

    def get(self, job_id: str) -> JobInfo:
        """The job's state; KeyError if there is no such job."""
        if not isinstance(job_id, str) or not _JOB_ID.match(job_id):
            raise KeyError(job_id)
        with self._lock:
            row = self._db.execute(f"SELECT {', '.join(_COLUMNS)} FROM jobs WHERE id = ?",
                                   (job_id,)).fetchone()
        if row is None:
            raise KeyError(job_id)
        return self._info(row)

    def list(self, status: Optional[str] = None, limit: Optional[int] = None,
             kind: Optional[str] = None) -> list[JobInfo]:
        """All jobs (or those with ``status``, of ``kind`` "run" or "study"), newest
        first."""
        sql = f"SELECT {', '.join(_COLUMNS)} FROM jobs"
        args: list = []
        where = []
        if status is not None:
            where.append("status = ?")
            args.append(status)
        if kind is not None:
            where.append("kind = ?")
            args.append(kind)
        if where:
            sql += " WHERE " + " AND ".join(where)
        sql += " ORDER BY seq DESC"
        if limit is not None:
            sql += " LIMIT ?"
            args.append(int(limit))
        with self._lock:
            rows = self._db.execute(sql, args).fetchall()
        return [self._info(r) for r in rows]

    def cancel(self, job_id: str, wait: float = 1.5) -> JobInfo:
        """Cancel a queued or running job (a finished one is left as it is). A running job's
        worker stops within about 0.2 s and closes the result file as ``cancelled``; this
        waits up to ``wait`` seconds for that and returns the job's state."""
        info = self.get(job_id)
        if info.done:
            return info
        now = time.time()
        with self._lock:
            cur = self._db.execute(
                "UPDATE jobs SET status = 'cancelled', finished = ?, error = ? "
                "WHERE id = ? AND status = 'queued'",
                (now, "cancelled before it started", job_id))
            if cur.rowcount:
                self._changed.notify_all()
                return self.get(job_id)
            self._db.execute("UPDATE jobs SET cancel_requested = 1 WHERE id = ?", (job_id,))
            for w in self._workers:
                if w.job_id == job_id and w.seq is not None:
                    w.cancel_seq.value = w.seq
                    if w.cancel_at is None:
                        w.cancel_at = time.monotonic()
        self._wake()
        try:
            return self.wait(job_id, timeout=wait)
        except TimeoutError:
            return self.get(job_id)

    def result_path(self, job_id: str) -> Path:
        """The job's HDF5 result file (it may not exist yet, or be partial while the job
        runs; ``engine.open_result`` reads it in every state)."""
        self.get(job_id)  # KeyError if unknown
        return self.runs_dir / job_id / "result.h5"

    def scene_path(self, job_id: str) -> Path:
        """The scene the job runs, as JSON (mesh references resolved)."""
        self.get(job_id)
        return self.runs_dir / job_id / "scene.json"

    def wait(self, job_id: str, timeout: Optional[float] = None) -> JobInfo:
        """Block until the job is finished; TimeoutError after ``timeout`` seconds."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._changed:
            while True:
                info = self.get(job_id)
                if info.done:
                    return info
                left = 0.5 if deadline is None else min(0.5, deadline - time.monotonic())
                if left <= 0:
                    raise TimeoutError(f"job {job_id} is still {info.status} after "
                                       f"{timeout} s")
                self._changed.wait(left)

    def counts(self) -> dict:
        """Number of jobs per status."""
        with self._lock:
            rows = self._db.execute("SELECT status, COUNT(*) FROM jobs GROUP BY status")
            found = {s: n for s, n in rows.fetchall()}
        return {s: found.get(s, 0) for s in STATUSES}

    def worker_pids(self) -> list[int]:
        with self._lock:
            return [w.pid for w in self._workers if w.process.is_alive()]

    def workers_info(self) -> list[dict]:
        """The live worker processes: pid, ready, numba's thread count, the job running."""
        with self._lock:
            return [{"pid": w.pid, "ready": w.ready, "numba_threads": w.numba_threads,
                     "job": w.job_id} for w in self._workers if w.process.is_alive()]

    def close(self, timeout: float = 5.0) -> None:
        """Stop the pool: running jobs are cancelled (their files closed as ``cancelled``),
        queued jobs stay queued for the next manager on this folder."""
        with self._lock:
            if self._closing:
                return
            self._closing = True
            for w in self._workers:
                if w.job_id is not None and w.seq is not None:
                    w.cancel_seq.value = w.seq
        self._wake()
        self._monitor.join(timeout + 5.0)
        with self._lock:
            try:
                self._db.close()
            except sqlite3.Error:
                pass
        for fd in (self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass
        try:
            self._lock_file.close()
        except OSError:
            pass

    def __enter__(self) -> "JobManager":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ meshes
    def add_mesh(self, data: bytes, filename: str) -> dict:
        """Store an uploaded STL/OBJ/PLY mesh; returns its description with ``id`` and
        ``ref`` (``"mesh:<id>"``, what a scene's mesh shape names as ``file``). Raises
        :class:`MeshError` for an unknown format, an unreadable or empty mesh, non-finite
        coordinates, or more than ``max_triangles`` triangles."""
        import numpy as np
        import trimesh

        fmt = Path(str(filename or "")).suffix.lower().lstrip(".")
        if fmt not in MESH_FORMATS:
            raise MeshError(f"file name {filename!r}: the format is taken from the extension, "
                            f"one of {', '.join('.' + f for f in MESH_FORMATS)}")
        if not data:
            raise MeshError("the uploaded file is empty")
        try:
            loaded = trimesh.load(io.BytesIO(data), file_type=fmt, force="mesh",
                                  process=False)
        except Exception as exc:  # trimesh raises many kinds on garbage
            raise MeshError(f"cannot be read as a {fmt.upper()} triangle mesh: "
                            f"{type(exc).__name__}: {exc}") from None
        if not isinstance(loaded, trimesh.Trimesh):
            raise MeshError(f"holds no triangle mesh (read as {type(loaded).__name__})")
        vertices = np.asarray(loaded.vertices, dtype=np.float64)
        faces = np.asarray(loaded.faces)
        if faces.ndim != 2 or len(faces) == 0 or len(vertices) == 0:
            raise MeshError("holds no triangles")
        if len(faces) > self.max_triangles:
            raise MeshError(f"has {len(faces)} triangles; at most {self.max_triangles} are "
                            f"allowed (decimate the mesh)", status=413)
        if not np.isfinite(vertices).all():
            raise MeshError("has vertices with NaN or infinite coordinates")
        if faces.min() < 0 or faces.max() >= len(vertices):
            raise MeshError("has triangles referring to missing vertices")
        mesh_id = hashlib.sha256(fmt.encode() + b"\0" + data).hexdigest()[:16]
        info = {"id": mesh_id, "ref": MESH_PREFIX + mesh_id, "filename": str(filename)[:200],
                "format": fmt, "triangles": int(len(faces)), "vertices": int(len(vertices)),
                "bounds": jsonable(np.array([vertices.min(axis=0), vertices.max(axis=0)])),
                "watertight": bool(trimesh.Trimesh(vertices, faces).is_watertight),
                "bytes": len(data)}
        path = self.meshes_dir / f"{mesh_id}.{fmt}"
        if not path.exists():
            tmp = path.with_suffix(f".tmp{os.getpid()}.{threading.get_ident()}")
            tmp.write_bytes(data)
            os.replace(tmp, path)
        with self._lock:
            self._db.execute("INSERT OR IGNORE INTO meshes (id, filename, format, created, "
                             "info) VALUES (?, ?, ?, ?, ?)",
                             (mesh_id, info["filename"], fmt, time.time(), json.dumps(info)))
        return info

    def list_meshes(self) -> list[dict]:
        with self._lock:
            rows = self._db.execute("SELECT info FROM meshes ORDER BY created DESC").fetchall()
        return [json.loads(r[0]) for r in rows]

    def mesh_path(self, mesh_id: str) -> Path:
        """The stored file of an uploaded mesh; KeyError if unknown."""
        if not isinstance(mesh_id, str) or not _MESH_ID.match(mesh_id):
            raise KeyError(mesh_id)
        with self._lock:
            row = self._db.execute("SELECT format FROM meshes WHERE id = ?",
                                   (mesh_id,)).fetchone()
        if row is None:
            raise KeyError(mesh_id)
        path = self.meshes_dir / f"{mesh_id}.{row[0]}"
        if not path.is_file():
            raise KeyError(mesh_id)
        return path

    # ------------------------------------------------------------------ internals
    def _resolve_scene(self, scene, *, allow_files: bool):
        import engine

        if isinstance(scene, engine.Scene):
            scene = scene.model_copy(deep=True)
        else:
            scene = engine.parse_scene(scene)
        problems = []
        for i, body in enumerate(scene.bodies):
            if body.shape.type != "mesh":
                continue
            ref = body.shape.file
            fieldname = f"bodies.{i}.shape.file"
            if ref.startswith(MESH_PREFIX):
                try:
                    path = self.mesh_path(ref[len(MESH_PREFIX):])
                except KeyError:
                    problems.append((fieldname, ref, "names no uploaded mesh (upload it "
                                     "first: POST /api/meshes gives its 'mesh:<id>')"))
                    continue
                body.shape = body.shape.model_copy(update={"file": str(path)})
            elif not allow_files:
                problems.append((fieldname, ref, "must name an uploaded mesh as "
                                 "'mesh:<id>' (POST /api/meshes); file paths are not "
                                 "accepted here"))
        if problems:
            from engine.errors import FieldProblem

            raise engine.SceneError([FieldProblem(*p) for p in problems])
        return scene

    def _take_folder_lock(self):
        import fcntl

        f = open(self.data_dir / "jobs.lock", "a+")
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            raise RuntimeError(f"{self.data_dir} is used by another running job manager "
                               f"(another server or studio); give each its own data "
                               f"folder") from None
        f.seek(0)
        f.truncate()
        f.write(f"{os.getpid()}\n")
        f.flush()
        return f

    def _recover(self) -> None:
        """Jobs left ``running`` by a manager that died are failed (interrupted)."""
        now = time.time()
        self._db.execute(
            "UPDATE jobs SET status = 'failed', finished = ?, error = ?, eta_s = NULL "
            "WHERE status = 'running'",
            (now, "interrupted: the server stopped while this job was running; the result "
                  "file keeps the frames recorded before"))
        self._db.execute(
            "UPDATE jobs SET status = 'cancelled', finished = ?, error = 'cancelled' "
            "WHERE status = 'queued' AND cancel_requested = 1", (now,))

    def _info(self, row) -> JobInfo:
        d = {k: row[k] for k in _COLUMNS}
        for k, typ in _JSON_COLUMNS.items():
            try:
                d[k] = json.loads(d[k]) if d[k] else typ()
            except ValueError:
                d[k] = typ()
        if d["started"] is not None:
            end = d["finished"] if d["finished"] is not None else time.time()
            d["wall_s"] = max(0.0, end - d["started"])
        d["kind"] = d["kind"] or "run"
        if d["kind"] == "study":
            d["files"] = _study_files(self.runs_dir / d["id"] / "study")
        return JobInfo(**d)

    def _update(self, job_id: str, **values) -> None:
        cols = []
        args = []
        for k, v in values.items():
            if k in _JSON_COLUMNS:
                v = json.dumps(jsonable(v))
            elif isinstance(v, float):
                v = _finite(v)
            cols.append(f"{k} = ?")
            args.append(v)
        with self._lock:
            self._db.execute(f"UPDATE jobs SET {', '.join(cols)} WHERE id = ?",
                             (*args, job_id))
            self._changed.notify_all()

    def _wake(self) -> None:
        try:
            os.write(self._wake_w, b"x")
        except (BlockingIOError, OSError):
            pass

    # ------------------------------------------------------------------ monitor thread
    def _monitor_loop(self) -> None:
        from multiprocessing.connection import wait as mp_wait

        try:
            while True:
                with self._lock:
                    closing = self._closing
                if closing:
                    break
                self._keep_pool()
                self._dispatch()
                self._enforce_cancels()
                with self._lock:
                    workers = list(self._workers)
                waitables = [self._wake_r]
                for w in workers:
                    waitables += [w.conn, w.process.sentinel]
                ready = mp_wait(waitables, timeout=0.5)
                if self._wake_r in ready:
                    try:
                        os.read(self._wake_r, 4096)
                    except OSError:
                        pass
                for w in workers:
                    if w.conn in ready:
                        self._drain(w)
                    if w.process.sentinel in ready:
                        self._on_death(w)
        except Exception:  # keep the manager usable and say why, rather than die silently
            traceback.print_exc()
        finally:
            self._shutdown_workers()

    def _keep_pool(self) -> None:
        with self._lock:
            missing = self.n_workers - len(self._workers)
        if missing <= 0 or time.monotonic() < self._respawn_after:
            return
        for _ in range(missing):
            w = _Worker(self._ctx, self.threads_per_worker)
            with self._lock:
                self._workers.append(w)

    def _dispatch(self) -> None:
        with self._lock:
            idle = [w for w in self._workers if w.ready and w.job_id is None]
        for w in idle:
            with self._lock:
                row = self._db.execute(
                    "SELECT seq, id, scene, kind, study, argv, resolved FROM jobs WHERE "
                    "status = 'queued' ORDER BY seq LIMIT 1").fetchone()
                if row is None:
                    return
                seq, job_id, scene_json, kind, study, argv, resolved = row
                cur = self._db.execute(
                    "UPDATE jobs SET status = 'running', started = ?, worker_pid = ? "
                    "WHERE id = ? AND status = 'queued'", (time.time(), w.pid, job_id))
                if not cur.rowcount:
                    continue
                w.job_id, w.seq, w.cancel_at = job_id, seq, None
                w.grace = self.study_cancel_grace_s if kind == "study" else \
                    self.cancel_grace_s
                self._changed.notify_all()
            if kind == "study":
                out = self.runs_dir / job_id / "study"
                out.mkdir(parents=True, exist_ok=True)
                argv = json.loads(argv or "[]") + ["--output", str(out)]
                argv += ["--scheduler", self.scheduler] if self.scheduler else \
                    ["--workers", "1"]
                msg = ("study", seq, job_id, study, self._study_options(job_id, study, resolved),
                       argv, str(out))
            else:
                h5 = self.runs_dir / job_id / "result.h5"
                h5.parent.mkdir(parents=True, exist_ok=True)
                msg = ("run", seq, job_id, scene_json, str(h5))
            try:
                w.conn.send(msg)
            except (OSError, ValueError):
                pass  # the worker died: its sentinel reports it and fails the job

    def _study_options(self, job_id: str, study: str, resolved: Optional[str]) -> dict:
        """A study job's typed options as data, run on this manager's scheduler (or one
        worker in the job's process). A job queued by an older version has none stored:
        they are made again from the options it was submitted with."""
        from .studies.registry import make_options, options_to_dict

        if resolved:
            data = json.loads(resolved)
        else:
            data = options_to_dict(make_options(study, self.get(job_id).options)[0])
        data.update(scheduler=self.scheduler, workers=None if self.scheduler else 1)
        return data

    def _drain(self, w: _Worker) -> None:
        while True:
            try:
                if not w.conn.poll():
                    return
                msg = w.conn.recv()
            except (EOFError, OSError):
                return
            self._handle(w, msg)

    def _handle(self, w: _Worker, msg) -> None:
        kind = msg[0]
        if kind == "ready":
            w.ready = True
            w.numba_threads = msg[2]
            self._start_failures = 0
            return
        job_id, data = msg[1], msg[2]
        if job_id != w.job_id:
            return
        if kind == "built":
            self._update(job_id, dt=data["dt"], dt_limited_by=str(data["dt_limited_by"]),
                         until=data["until"], sim_time=data["sim_time"],
                         assembled=data["assembled"], warnings=data["warnings"])
        elif kind == "study_progress":
            self._update(job_id, progress=min(max(float(data["progress"]), 0.0), 1.0),
                         message=str(data.get("message") or "")[:300])
        elif kind == "progress":
            self._update(job_id, sim_time=data["sim_time"], until=data["until"],
                         progress=min(max(float(data["progress"]), 0.0), 1.0),
                         steps_per_s=data["steps_per_s"], eta_s=data["eta_s"])
        elif kind == "done":
            summary = data["summary"] or {}
            status = data["status"] if data["status"] in FINAL_STATUSES else "failed"
            error = data["error"]
            if status == "cancelled" and error is None:
                error = ("interrupted: the job manager was closed" if self._closing
                         else "cancelled")
            values = dict(status=status, finished=data["finished"], summary=summary,
                          stages=summary.get("stages") or {}, error=error, eta_s=0.0
                          if status in ("completed", "stopped") else None)
            if status in ("completed", "stopped"):
                values["progress"] = 1.0
            if isinstance(summary.get("time"), (int, float)):
                values["sim_time"] = float(summary["time"])
            if summary.get("warnings"):
                values["warnings"] = list(self.get(job_id).warnings) + [
                    x for x in summary["warnings"] if x not in self.get(job_id).warnings]
            self._update(job_id, **values)
            with self._lock:
                w.job_id = w.seq = w.cancel_at = None

    def _on_death(self, w: _Worker) -> None:
        self._drain(w)  # what it sent before dying
        w.process.join(1.0)
        code = w.process.exitcode
        with self._lock:
            if w in self._workers:
                self._workers.remove(w)
            job_id = w.job_id
            w.job_id = w.seq = None
        if job_id is not None:
            cancel_requested = w.cancel_at is not None
            reason = _describe_exit(code)
            if cancel_requested:
                status, error = "cancelled", (f"cancelled: the worker process (pid {w.pid}) "
                                              f"did not stop in time and was ended ({reason})")
            else:
                status, error = "failed", (f"the worker process (pid {w.pid}) died while "
                                           f"running this job ({reason}); the result file "
                                           f"keeps the frames recorded before")
            self._update(job_id, status=status, finished=time.time(), error=error,
                         eta_s=None)
        if not w.ready:  # died while starting: say so, and do not respawn in a tight loop
            self._start_failures += 1
            delay = min(2.0 * 2 ** (self._start_failures - 1), 60.0)
            self._respawn_after = time.monotonic() + delay
            if self._start_failures in (1, 3, 10):
                print(f"brush-studio jobs: a worker process failed to start ({_describe_exit(code)})"
                      f"; retrying in {delay:.0f} s (a script creating a JobManager must do so "
                      f"under `if __name__ == '__main__':`)", file=sys.stderr)
        else:
            self._start_failures = 0
        try:
            w.conn.close()
        except OSError:
            pass

    def _enforce_cancels(self) -> None:
        now = time.monotonic()
        with self._lock:
            late = [w for w in self._workers if w.job_id is not None
                    and w.cancel_at is not None and now - w.cancel_at > w.grace]
        for w in late:
            w.process.terminate()  # its sentinel fires; _on_death marks the job cancelled

    def _shutdown_workers(self) -> None:
        with self._lock:
            workers = list(self._workers)
        # a study closes its Dask cluster when cancelled: give it longer than a run
        studies = any(w.job_id is not None and w.grace > self.cancel_grace_s for w in workers)
        deadline = time.monotonic() + (20.0 if studies else 5.0)
        # running jobs were asked to cancel: let them close their files
        for w in workers:
            while w.job_id is not None and w.process.is_alive() and \
                    time.monotonic() < deadline:
                if w.conn.poll(0.1):
                    self._drain(w)
        for w in workers:
            job_id = w.job_id
            w.stop()
            if job_id is not None:
                self._update(job_id, status="cancelled", finished=time.time(),
                             error="interrupted: the job manager was closed while this job "
                                   "ran")
        with self._lock:
            self._workers.clear()
