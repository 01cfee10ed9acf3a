"""The job manager: a bounded pool of worker processes, a FIFO queue and the job table.

This file is what callers ask for: submit a scene or a study (checked against the limits,
the queue and the storage quota), cancel, purge, wait, read a job's state and files, health.
One monitor thread hands queued jobs to idle workers, receives their progress and results and
notices dead workers (:mod:`.monitor`); job states are written through a
:class:`~.writes.StateWriter`, which keeps what a full disk refused and writes it again.
"""
from __future__ import annotations

import json
import os
import shutil
import sqlite3
import threading
import time
import uuid
from pathlib import Path
from typing import Optional, Union

from engine.jsonable import finite_or_none

from studio.studies.api import study_files
from studio.studies.registry import make_options, options_to_dict
from studio.service.jobs.limits import LimitError, Limits, check_cost, planned_runs
from studio.service.jobs.meshes import DEFAULT_MAX_TRIANGLES, MeshStore
from studio.service.jobs.monitor import WorkerMonitor
from studio.service.jobs.quota import StorageQuota
from studio.service.jobs.store import JobInfo, JobStore, StorageError, jsonable, storage_reason
from studio.service.jobs.worker import WorkerHandle, cpu_count
from studio.service.jobs.writes import StateWriter

#: below this much free space in the data folder, submits are refused (507) and health says
#: ``degraded``: a run's files and the job database need room to record even a failure
DEFAULT_MIN_FREE_BYTES = 16 * 1024 * 1024


class _DuplicateKey(Exception):
    """A job with this idempotency key was stored meanwhile."""


class JobManager(WorkerMonitor):
    """Bounded pool of worker processes, FIFO queue, state in ``data_dir/jobs.sqlite``.

    ``workers``: pool size (default one per core). ``cancel_grace_s``: how long a worker may
    take to honour a cancel before it is terminated. ``max_triangles``: the largest uploaded
    mesh accepted by :meth:`add_mesh`. ``limits``: what one job may cost, how long it may
    run and how many may wait (:class:`~.limits.Limits`; its defaults when not given).
    ``min_free_bytes``: below this much free space in the data folder, submits are refused.
    """

    def __init__(self, data_dir: Union[str, Path], workers: Optional[int] = None, *,
                 cancel_grace_s: float = 5.0, max_triangles: int = DEFAULT_MAX_TRIANGLES,
                 scheduler: Optional[str] = None, study_cancel_grace_s: float = 30.0,
                 min_free_bytes: int = DEFAULT_MIN_FREE_BYTES,
                 limits: Optional[Limits] = None):
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

        self.limits = limits if limits is not None else Limits()
        self._monitor_problem: Optional[str] = None

        self._lock_file = self._take_folder_lock()
        self._store = JobStore(self.data_dir, self.runs_dir)
        # the database connection and the worker table share one lock
        self._lock, self._changed = self._store.lock, self._store.changed
        self._writes = StateWriter(self._store, self.data_dir, min_free_bytes)
        self._meshes = MeshStore(self.meshes_dir, self._store, self.max_triangles)
        self.quota = StorageQuota([self.runs_dir, self.meshes_dir],
                                  self.limits.max_storage_bytes)

        self._ctx = mp.get_context("spawn")
        self._workers: list[WorkerHandle] = []
        self._closing = False
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_w, False)
        self._respawn_after = 0.0
        self._start_failures = 0
        self._monitor = threading.Thread(target=self._monitor_loop, name="job-monitor",
                                         daemon=True)
        self._monitor.start()

    @property
    def _db(self):
        return self._store.db

    @property
    def min_free_bytes(self) -> int:
        """Below this much free space in the data folder, submits are refused."""
        return self._writes.min_free_bytes

    # ------------------------------------------------------------------ public API
    def submit(self, scene, name: Optional[str] = None, *, allow_files: bool = True,
               check_build: bool = False, idempotency_key: Optional[str] = None) -> str:
        """Queue a scene (an ``engine.Scene``, a dict or JSON text); returns the job id.

        Raises ``engine.SceneError`` naming every bad field, :class:`~.limits.LimitError`
        when the scene's estimated cost (``engine.estimate``: nodes, steps, frames, memory)
        is over this manager's :attr:`limits` or the queue is full, and
        :class:`~.store.StorageError` when it cannot be stored. Mesh shapes may name an
        uploaded mesh as ``"mesh:<id>"``; with ``allow_files=False`` (the HTTP server) they
        must, and no other file path is accepted. Nothing is built here (a huge scene would
        hold this process); what only the build can see fails the job with the reason.
        ``check_build`` builds it here all the same (small scenes, scripts).
        ``idempotency_key``: a submit with a key already used returns that job's id and
        queues nothing (a client's retry after a lost answer).
        """
        import engine

        if idempotency_key is not None:
            known = self.job_for_key(idempotency_key)
            if known is not None:
                return known

        scene = self._meshes.resolve_scene(scene, allow_files=allow_files)
        cost = engine.estimate(scene, mesh_triangles=self._meshes.triangles_of)
        check_cost(cost, self.limits)
        self._check_queue()
        self.quota.admit(cost.result_bytes, "this run's result file (estimated)")
        if check_build:
            engine.build(scene)
        if name is None or not str(name).strip():
            name = scene.name
        name = str(name).strip()[:200]
        scene_json = scene.to_json()
        job_id = uuid.uuid4().hex[:12]
        try:
            self._create_job(job_id, {"scene.json": scene_json + "\n"},
                             "INSERT INTO jobs (id, name, status, created, until, scene, "
                             "estimate, idempotency_key) VALUES (?, ?, 'queued', ?, ?, ?, ?, ?)",
                             (job_id, name, time.time(), finite_or_none(scene.run.duration),
                              scene_json, json.dumps(jsonable(cost.as_dict())),
                              idempotency_key))
        except _DuplicateKey:
            return self.job_for_key(idempotency_key)
        return job_id

    def job_for_key(self, key: str) -> Optional[str]:
        """The job submitted with idempotency key ``key``, or None."""
        with self._lock:
            row = self._db.execute("SELECT id FROM jobs WHERE idempotency_key = ?",
                                   (key,)).fetchone()
        return row[0] if row else None

    def _check_queue(self) -> None:
        """:class:`LimitError` (429) when ``limits.max_queued`` jobs already wait."""
        allowed = self.limits.max_queued
        if allowed is None:
            return
        queued = self._store.counts()["queued"]
        if queued >= allowed:
            raise LimitError("max_queued", queued, allowed,
                             f"{queued} jobs are waiting; this server queues at most {allowed} "
                             f"(--max-queued): submit again later", 429,
                             retry_after=30)

    def submit_study(self, study: str, options: Optional[dict] = None,
                     name: Optional[str] = None) -> str:
        """Queue a study (``wedge``, ``spin``, ``refinement``, ``sensitivity``,
        ``montecarlo``, ``rod``, ``detumble``, ``convergence``) with ``options`` (its
        options model's fields as a dict, see :func:`make_options`); returns the job id.
        The validated model's dict is what the job stores and its worker runs. Raises
        :class:`StudyOptionError` for an unknown study or a bad option. The study writes its
        files into ``DATA/runs/<id>/study/`` (:meth:`study_files`); it runs on one local
        Dask worker, or on the manager's ``scheduler``."""
        typed = make_options(study, options, scheduler=self.scheduler,
                             designs_dir=self.data_dir / "designs")
        runs = planned_runs(typed)
        if self.limits.max_study_runs is not None and runs > self.limits.max_study_runs:
            raise LimitError("max_study_runs", runs, self.limits.max_study_runs,
                             f"the study plans up to {runs} runs; this server allows at most "
                             f"{self.limits.max_study_runs} per study (--max-study-runs)", 422)
        self._check_queue()
        self.quota.admit(0, "a study")
        stored = options_to_dict(typed)
        if name is None or not str(name).strip():
            name = f"{study} study"
        name = str(name).strip()[:200]
        job_id = uuid.uuid4().hex[:12]
        spec = {"study": study, "options": stored}
        self._create_job(job_id, {"study_job.json": json.dumps(spec, indent=1) + "\n",
                                  "study/": None},
                         "INSERT INTO jobs (id, name, status, created, scene, kind, study, "
                         "options, estimate) VALUES (?, ?, 'queued', ?, '', 'study', ?, ?, ?)",
                         (job_id, name, time.time(), study, json.dumps(stored),
                          json.dumps({"planned_runs": runs})))
        return job_id

    def _create_job(self, job_id: str, files: dict, sql: str, args: tuple) -> None:
        """Write a new job's folder (``files``: name -> text, a name ending in ``/`` a
        folder) and its row. Nothing is left behind when either fails: the folder is removed
        and :class:`StorageError` says why (a full disk: HTTP 507)."""
        self.check_free_space()
        run_dir = self.runs_dir / job_id
        try:
            run_dir.mkdir(parents=True, exist_ok=False)
            for fname, text in files.items():
                if fname.endswith("/"):
                    (run_dir / fname).mkdir()
                else:
                    (run_dir / fname).write_text(text)
            with self._lock:
                self._db.execute(sql, args)
                self._changed.notify_all()
        except sqlite3.IntegrityError:  # the same idempotency key, submitted concurrently
            shutil.rmtree(run_dir, ignore_errors=True)
            raise _DuplicateKey() from None
        except (OSError, sqlite3.Error) as exc:
            shutil.rmtree(run_dir, ignore_errors=True)
            reason = storage_reason(exc)
            self._writes.failed(reason)
            raise StorageError(f"the job could not be stored in {self.data_dir}: "
                               f"{reason}") from exc
        self._writes.ok()
        self._wake()

    def check_free_space(self) -> None:
        """:class:`StorageError` when the data folder has less than ``min_free_bytes``
        free."""
        self._writes.check_free_space()

    def free_bytes(self) -> Optional[int]:
        return self._writes.free_bytes()

    def _storage_recovered(self) -> bool:
        """Whether storage works again: enough free space and a small file can be written
        in the data folder."""
        free = self.free_bytes()
        if free is not None and free < self.min_free_bytes:
            return False
        probe = self.data_dir / f".health-probe-{os.getpid()}"
        try:
            probe.write_bytes(b"ok")
            probe.unlink()
            return True
        except OSError:
            try:
                probe.unlink(missing_ok=True)
            except OSError:
                pass
            return False

    def health(self) -> dict:
        """``{"status": "ok" | "degraded", "problems": [...]}``: degraded while workers are
        missing, the monitor thread is down, storage failed last time it was written, or the
        data folder is short of space."""
        problems = []
        with self._lock:
            alive = sum(1 for w in self._workers if w.process.is_alive())
            pending = sorted(self._writes.pending)
            storage = self._writes.problem
            monitor = self._monitor_problem
        if storage and not pending and self._storage_recovered():
            # (a purge or a cleanup freed space: healthy now, not at the next write)
            self._writes.ok()
            storage = None
        if not self._monitor.is_alive() and not self._closing:
            problems.append("the job monitor thread has stopped: no job will start")
        elif monitor:
            problems.append(f"the job monitor hit an error: {monitor}")
        if alive < self.n_workers:
            problems.append(f"{alive} of {self.n_workers} worker process(es) alive")
        if storage:
            problems.append(f"storage: {storage}")
        if pending:
            problems.append(f"{len(pending)} finished job(s) not yet written to the database "
                            f"({', '.join(pending[:5])})")
        free = self.free_bytes()
        if free is not None and free < self.min_free_bytes and not storage:
            problems.append(f"storage: only {free / 2**20:.1f} MiB free in {self.data_dir}")
        quota = self.quota.problem()
        if quota:
            problems.append(quota)
        return {"status": "degraded" if problems else "ok", "problems": problems,
                "free_bytes": free, "used_bytes": self.quota.used_bytes(),
                "quota_bytes": self.quota.max_bytes}

    def study_dir(self, job_id: str) -> Path:
        """A study job's output folder (KeyError if unknown or not a study)."""
        info = self.get(job_id)
        if info.kind != "study":
            raise KeyError(job_id)
        return self.runs_dir / job_id / "study"

    def study_files(self, job_id: str) -> list[str]:
        """A study job's output files so far: paths relative to its folder, sorted."""
        return study_files(self.study_dir(job_id))

    def study_file(self, job_id: str, name: str) -> Path:
        """One output file of a study job, by a name from :meth:`study_files` only (no
        other path is ever opened); KeyError otherwise."""
        if name not in self.study_files(job_id):
            raise KeyError(name)
        return self.study_dir(job_id) / name

    def get(self, job_id: str) -> JobInfo:
        """The job's state; KeyError if there is no such job."""
        return self._writes.overlay(self._store.get(job_id))

    def list(self, status: Optional[str] = None, limit: Optional[int] = None,
             kind: Optional[str] = None) -> list[JobInfo]:
        """All jobs (or those with ``status``, of ``kind`` "run" or "study"), newest
        first."""
        return [self._writes.overlay(i) for i in self._store.list(status, limit, kind)]

    def cancel(self, job_id: str, wait: float = 1.5) -> JobInfo:
        """Cancel a queued or running job (a finished one is left as it is). A running job's
        worker stops within about 0.2 s and closes the result file as ``cancelled``; this
        waits up to ``wait`` seconds for that and returns the job's state."""
        info = self.get(job_id)
        if info.done:
            return info
        now = time.time()
        try:
            return self._cancel(job_id, now, wait)
        except sqlite3.Error as exc:
            reason = f"the job database could not be written: {storage_reason(exc)}"
            self._writes.failed(reason)
            raise StorageError(reason) from exc

    def _cancel(self, job_id: str, now: float, wait: float) -> JobInfo:
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

    def purge(self, job_id: str, wait: float = 10.0) -> dict:
        """Delete a job and its files (its folder under ``runs/``: result, scene, a study's
        outputs); a queued or running job is cancelled first. Returns ``{"id", "purged":
        True, "freed_bytes"}``; KeyError if unknown, :class:`StorageError` if the folder
        cannot be removed, RuntimeError if the job does not stop within ``wait`` s."""
        info = self.get(job_id)
        if not info.done:
            self.cancel(job_id, wait=wait)
            info = self.get(job_id)
            if not info.done:
                raise RuntimeError(f"job {job_id} is still {info.status}: it did not stop "
                                   f"within {wait:g} s; purge it again later")
        folder = self.runs_dir / job_id
        freed = sum(f.stat().st_size for f in folder.rglob("*") if f.is_file()) \
            if folder.is_dir() else 0
        try:
            shutil.rmtree(folder, ignore_errors=False) if folder.exists() else None
            with self._lock:
                self._db.execute("DELETE FROM jobs WHERE id = ?", (job_id,))
                self._writes.forget(job_id)
                self._changed.notify_all()
        except (OSError, sqlite3.Error) as exc:
            raise StorageError(f"job {job_id} could not be purged: "
                               f"{storage_reason(exc)}") from exc
        return {"id": job_id, "purged": True, "freed_bytes": freed}

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
        return self._store.wait(job_id, timeout)

    def counts(self) -> dict:
        """Number of jobs per status."""
        return self._store.counts()

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
        self._store.close()
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
        """Store an uploaded STL/OBJ/PLY mesh (:meth:`MeshStore.add_mesh`); over the storage
        quota or with less free space than ``min_free_bytes`` (``--min-free-mb``), as for
        a submit: :class:`StorageError`."""
        self.check_free_space()
        self.quota.admit(len(data), "the mesh")
        return self._meshes.add_mesh(data, filename)

    def list_meshes(self) -> list[dict]:
        return self._meshes.list_meshes()

    def mesh_path(self, mesh_id: str) -> Path:
        """The stored file of an uploaded mesh; KeyError if unknown."""
        return self._meshes.mesh_path(mesh_id)

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

    # ------------------------------------------------------------------ retention
    def _retain(self) -> None:
        """Purge finished jobs older than ``limits.keep_days`` (checked once a minute)."""
        days = self.limits.keep_days
        now = time.monotonic()
        if days is None or now < getattr(self, "_next_retain", 0.0):
            return
        self._next_retain = now + 60.0
        cutoff = time.time() - days * 86400.0
        with self._lock:
            rows = self._db.execute(
                "SELECT id FROM jobs WHERE status IN ('completed', 'stopped', 'failed', "
                "'cancelled') AND finished IS NOT NULL AND finished < ?", (cutoff,)).fetchall()
        for (job_id,) in rows:
            self.purge(job_id)
