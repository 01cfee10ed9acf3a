"""The job table: one SQLite database (``DATA/jobs.sqlite``) that keeps every job's state
across restarts, and :class:`JobInfo`, one job as the API shows it.

A :class:`JobStore` owns the connection, the lock that guards it (shared with the manager's
worker table) and a condition notified on every change (what :meth:`JobStore.wait` waits
on). The schema grows by columns: an older database gets the new ones when it is opened.
"""
from __future__ import annotations

import json
import re
import sqlite3
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional

from engine.jsonable import finite_or_none
from engine.jsonable import jsonable_null as jsonable  # strict JSON, non-finite as null

STATUSES = ("queued", "running", "completed", "stopped", "failed", "cancelled")
FINAL_STATUSES = frozenset({"completed", "stopped", "failed", "cancelled"})
_JOB_ID = re.compile(r"^[0-9a-f]{12}$")


class StorageError(RuntimeError):
    """The job database or a job's folder could not be written (a full disk, a read-only or
    vanished data folder): the message says what was being written and why it failed."""


def storage_reason(exc: BaseException) -> str:
    """One line for a storage failure: the OS's or SQLite's own words."""
    if isinstance(exc, OSError) and exc.strerror:
        where = f" ({exc.filename})" if exc.filename else ""
        return f"{exc.strerror}{where}"
    return f"{type(exc).__name__}: {exc}"


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
    estimate: dict = field(default_factory=dict)  # its cost estimated at submit

    @property
    def done(self) -> bool:
        return self.status in FINAL_STATUSES

    def to_dict(self) -> dict:
        return jsonable(asdict(self))


_COLUMNS = ("id", "name", "status", "created", "started", "finished", "progress", "sim_time",
            "until", "steps_per_s", "eta_s", "dt", "dt_limited_by", "stages", "summary",
            "error", "worker_pid", "assembled", "warnings", "kind", "study", "options",
            "message", "estimate")
_JSON_COLUMNS = {"stages": dict, "summary": dict, "assembled": list, "warnings": list,
                 "options": dict, "estimate": dict}
# columns added after the first release: added to an older database when it is opened
# (``argv`` and ``resolved`` are no longer written: a study job stores its validated options
# model's dict in ``options``; ``resolved`` is still read for jobs queued by older versions)
_ADDED_COLUMNS = (("kind", "TEXT NOT NULL DEFAULT 'run'"), ("study", "TEXT"),
                  ("options", "TEXT NOT NULL DEFAULT '{}'"), ("argv", "TEXT"),
                  ("message", "TEXT"), ("resolved", "TEXT"), ("estimate", "TEXT"),
                  ("idempotency_key", "TEXT"))

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


class JobStore:
    """The jobs table of ``data_dir/jobs.sqlite`` (``runs_dir``: where study jobs' files
    are, for :attr:`JobInfo.files`). ``lock`` guards the connection; ``changed`` is notified
    after every update."""

    def __init__(self, data_dir: Path, runs_dir: Path):
        self.runs_dir = Path(runs_dir)
        self.lock = threading.RLock()
        self.changed = threading.Condition(self.lock)
        self.db = sqlite3.connect(str(Path(data_dir) / "jobs.sqlite"), timeout=30,
                                  check_same_thread=False, isolation_level=None)
        self.db.row_factory = sqlite3.Row
        with self.lock:
            self.db.execute("PRAGMA journal_mode=WAL")
            self.db.execute("PRAGMA synchronous=NORMAL")
            self.db.executescript(_SCHEMA)
            have = {r[1] for r in self.db.execute("PRAGMA table_info(jobs)").fetchall()}
            for col, decl in _ADDED_COLUMNS:
                if col not in have:
                    self.db.execute(f"ALTER TABLE jobs ADD COLUMN {col} {decl}")
            self.db.execute("CREATE UNIQUE INDEX IF NOT EXISTS jobs_idempotency_key ON jobs "
                            "(idempotency_key) WHERE idempotency_key IS NOT NULL")
            self.recover()

    def close(self) -> None:
        with self.lock:
            try:
                self.db.close()
            except sqlite3.Error:
                pass

    def get(self, job_id: str) -> JobInfo:
        """The job's state; KeyError if there is no such job."""
        if not isinstance(job_id, str) or not _JOB_ID.match(job_id):
            raise KeyError(job_id)
        with self.lock:
            row = self.db.execute(f"SELECT {', '.join(_COLUMNS)} FROM jobs WHERE id = ?",
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
        with self.lock:
            rows = self.db.execute(sql, args).fetchall()
        return [self._info(r) for r in rows]

    def wait(self, job_id: str, timeout: Optional[float] = None) -> JobInfo:
        """Block until the job is finished; TimeoutError after ``timeout`` seconds."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self.changed:
            while True:
                info = self.get(job_id)
                if info.done:
                    return info
                left = 0.5 if deadline is None else min(0.5, deadline - time.monotonic())
                if left <= 0:
                    raise TimeoutError(f"job {job_id} is still {info.status} after "
                                       f"{timeout} s")
                self.changed.wait(left)

    def counts(self) -> dict:
        """Number of jobs per status."""
        with self.lock:
            rows = self.db.execute("SELECT status, COUNT(*) FROM jobs GROUP BY status")
            found = {s: n for s, n in rows.fetchall()}
        return {s: found.get(s, 0) for s in STATUSES}

    def recover(self) -> None:
        """Jobs left ``running`` by a manager that died are failed (interrupted)."""
        now = time.time()
        self.db.execute(
            "UPDATE jobs SET status = 'failed', finished = ?, error = ?, eta_s = NULL "
            "WHERE status = 'running'",
            (now, "interrupted: the server stopped while this job was running; the result "
                  "file keeps the frames recorded before"))
        self.db.execute(
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
            from studio.studies.api import study_files

            d["files"] = study_files(self.runs_dir / d["id"] / "study")
        return JobInfo(**d)

    def update(self, job_id: str, **values) -> None:
        """Write ``values`` into the job's row; :class:`StorageError` if the database cannot
        be written (a full disk), with the database's reason."""
        cols = []
        args = []
        for k, v in values.items():
            if k in _JSON_COLUMNS:
                v = json.dumps(jsonable(v))
            elif isinstance(v, float):
                v = finite_or_none(v)
            cols.append(f"{k} = ?")
            args.append(v)
        with self.lock:
            try:
                self.db.execute(f"UPDATE jobs SET {', '.join(cols)} WHERE id = ?",
                                (*args, job_id))
            except sqlite3.Error as exc:
                raise StorageError(f"the job database could not be written: "
                                   f"{storage_reason(exc)}") from exc
            self.changed.notify_all()
