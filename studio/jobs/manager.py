"""The job manager: a bounded pool of worker processes, a FIFO queue and the job table.

One monitor thread hands queued jobs to idle workers (oldest first), receives their progress
and results through a pipe per worker and writes them to the :class:`~.store.JobStore`;
enforces cancels (a worker that does not stop within the grace period is terminated);
notices dead workers through their process sentinels (their job fails with the reason) and
starts new ones.
"""
from __future__ import annotations

import json
import os
import shutil
import sqlite3
import sys
import threading
import time
import traceback
import uuid
from pathlib import Path
from typing import Optional, Union

from engine.jsonable import finite_or_none

from ..studies.api import study_files
from ..studies.registry import make_options, options_to_dict
from .limits import LimitError, Limits, check_cost, planned_runs
from .meshes import DEFAULT_MAX_TRIANGLES, MeshStore
from .quota import StorageQuota
from .store import (FINAL_STATUSES, JobInfo, JobStore, StorageError, jsonable, storage_reason)
from .worker import WorkerHandle, cpu_count, describe_exit, finalize_killed_result

#: below this much free space in the data folder, submits are refused (507) and health says
#: ``degraded``: a run's files and the job database need room to record even a failure
DEFAULT_MIN_FREE_BYTES = 16 * 1024 * 1024
# a killed worker's result file up to this size is finalized before its job is reported
FINALIZE_INLINE_BYTES = 64 * 1024 * 1024


class _DuplicateKey(Exception):
    """A job with this idempotency key was stored meanwhile."""


class JobManager:
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

        self.min_free_bytes = int(min_free_bytes)
        self.limits = limits if limits is not None else Limits()
        # storage trouble seen last (None: the last write succeeded), and the final states of
        # jobs that could not be written yet (retried by the monitor until they are)
        self._storage_problem: Optional[str] = None
        self._pending_final: dict[str, dict] = {}
        self._monitor_problem: Optional[str] = None

        self._lock_file = self._take_folder_lock()
        self._store = JobStore(self.data_dir, self.runs_dir)
        # the database connection and the worker table share one lock
        self._lock, self._changed = self._store.lock, self._store.changed
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
        ``montecarlo``, ``rod``, ``convergence``) with ``options`` (its command-line options
        as a dict, see :func:`study_argv`); returns the job id. Raises
        :class:`StudyOptionError` for an unknown study or a bad option. The study writes its
        files into ``DATA/runs/<id>/study/`` (:meth:`study_files`); it runs on one local
        Dask worker, or on the manager's ``scheduler``."""
        typed, argv = make_options(study, options, scheduler=self.scheduler,
                                   designs_dir=self.data_dir / "designs")
        runs = planned_runs(typed)
        if self.limits.max_study_runs is not None and runs > self.limits.max_study_runs:
            raise LimitError("max_study_runs", runs, self.limits.max_study_runs,
                             f"the study plans up to {runs} runs; this server allows at most "
                             f"{self.limits.max_study_runs} per study (--max-study-runs)", 422)
        self._check_queue()
        self.quota.admit(0, "a study")
        resolved = options_to_dict(typed)
        if name is None or not str(name).strip():
            name = f"{study} study"
        name = str(name).strip()[:200]
        job_id = uuid.uuid4().hex[:12]
        spec = {"study": study, "options": jsonable(options or {}), "argv": argv,
                "resolved": resolved}
        self._create_job(job_id, {"study_job.json": json.dumps(spec, indent=1) + "\n",
                                  "study/": None},
                         "INSERT INTO jobs (id, name, status, created, scene, kind, study, "
                         "options, argv, resolved, estimate) VALUES (?, ?, 'queued', ?, '', "
                         "'study', ?, ?, ?, ?, ?)",
                         (job_id, name, time.time(), study, json.dumps(spec["options"]),
                          json.dumps(argv), json.dumps(resolved),
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
            self._storage_failed(reason)
            raise StorageError(f"the job could not be stored in {self.data_dir}: "
                               f"{reason}") from exc
        self._storage_ok()
        self._wake()

    def check_free_space(self) -> None:
        """:class:`StorageError` when the data folder has less than ``min_free_bytes``
        free."""
        free = self.free_bytes()
        if free is not None and free < self.min_free_bytes:
            reason = (f"only {free / 2**20:.1f} MiB free in {self.data_dir} (at least "
                      f"{self.min_free_bytes / 2**20:.0f} MiB are needed to run jobs)")
            self._storage_failed(reason)
            raise StorageError(reason)

    def free_bytes(self) -> Optional[int]:
        try:
            return shutil.disk_usage(self.data_dir).free
        except OSError:
            return None

    def health(self) -> dict:
        """``{"status": "ok" | "degraded", "problems": [...]}``: degraded while workers are
        missing, the monitor thread is down, storage failed last time it was written, or the
        data folder is short of space."""
        problems = []
        with self._lock:
            alive = sum(1 for w in self._workers if w.process.is_alive())
            pending = sorted(self._pending_final)
            storage = self._storage_problem
            monitor = self._monitor_problem
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

    def _storage_failed(self, reason: str) -> None:
        with self._lock:
            self._storage_problem = reason

    def _storage_ok(self) -> None:
        with self._lock:
            self._storage_problem = None

    def _update(self, job_id: str, **values) -> bool:
        """Write a job's state; on a storage error note it (health) and return False."""
        try:
            self._store.update(job_id, **values)
        except StorageError as exc:
            self._storage_failed(str(exc))
            return False
        if self._storage_problem is not None and not self._pending_final:
            self._storage_ok()
        return True

    def _finish(self, job_id: str, **values) -> None:
        """Write a job's final state; if storage fails, keep it and retry from the monitor
        until it is written (the job is reported with it meanwhile)."""
        if not self._update(job_id, **values):
            with self._lock:
                self._pending_final[job_id] = values

    def _flush_pending(self) -> None:
        with self._lock:
            pending = list(self._pending_final.items())
        for job_id, values in pending:
            if self._update(job_id, **values):
                with self._lock:
                    self._pending_final.pop(job_id, None)
        if pending and not self._pending_final:
            self._storage_ok()

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
        return self._overlay(self._store.get(job_id))

    def list(self, status: Optional[str] = None, limit: Optional[int] = None,
             kind: Optional[str] = None) -> list[JobInfo]:
        """All jobs (or those with ``status``, of ``kind`` "run" or "study"), newest
        first."""
        return [self._overlay(i) for i in self._store.list(status, limit, kind)]

    def _overlay(self, info: JobInfo) -> JobInfo:
        """A job whose final state could not be written yet is shown with it."""
        with self._lock:
            values = self._pending_final.get(info.id)
        if not values:
            return info
        import dataclasses

        known = {f.name for f in dataclasses.fields(JobInfo)}
        return dataclasses.replace(info, **{k: v for k, v in values.items() if k in known})

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
            self._storage_failed(reason)
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
                self._pending_final.pop(job_id, None)
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
        quota: :class:`StorageError`."""
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
                # each step on its own: an error in one (a full disk, a worker that cannot
                # start) is reported in health and retried, and never stops the others
                for step in (self._flush_pending, self._keep_pool, self._dispatch,
                             self._enforce_cancels, self._retain):
                    self._guarded(step)
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
                        self._guarded(self._drain, w)
                    if w.process.sentinel in ready:
                        self._guarded(self._on_death, w)
        finally:
            self._shutdown_workers()

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

    def _guarded(self, step, *args) -> None:
        """Run one step of the monitor loop; an exception is printed once per kind, shown
        by :meth:`health` and does not end the loop (a pause keeps it from spinning)."""
        try:
            step(*args)
        except Exception as exc:
            reason = f"{type(exc).__name__}: {exc}"
            if self._monitor_problem != reason:
                traceback.print_exc()
            with self._lock:
                self._monitor_problem = reason
            time.sleep(0.2)
        else:
            if self._monitor_problem is not None and step == self._dispatch:
                with self._lock:
                    self._monitor_problem = None

    def _keep_pool(self) -> None:
        with self._lock:
            missing = self.n_workers - len(self._workers)
        if missing <= 0 or time.monotonic() < self._respawn_after:
            return
        for _ in range(missing):
            try:
                w = WorkerHandle(self._ctx, self.threads_per_worker)
            except OSError as exc:  # no memory, no file descriptors: try again later
                self._respawn_after = time.monotonic() + 2.0
                raise RuntimeError(f"a worker process could not be started: "
                                   f"{storage_reason(exc)}") from exc
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
                try:
                    cur = self._db.execute(
                        "UPDATE jobs SET status = 'running', started = ?, worker_pid = ? "
                        "WHERE id = ? AND status = 'queued'", (time.time(), w.pid, job_id))
                except sqlite3.Error as exc:  # the job stays queued; tried again next turn
                    reason = f"the job database could not be written: {storage_reason(exc)}"
                    self._storage_failed(reason)
                    raise StorageError(reason) from exc
                if not cur.rowcount:
                    continue
                w.job_id, w.seq, w.cancel_at = job_id, seq, None
                w.started_at, w.over_limit = time.monotonic(), None
                w.grace = self.study_cancel_grace_s if kind == "study" else \
                    self.cancel_grace_s
                self._changed.notify_all()
            try:
                if kind == "study":
                    out = self.runs_dir / job_id / "study"
                    out.mkdir(parents=True, exist_ok=True)
                    argv = json.loads(argv or "[]") + ["--output", str(out)]
                    argv += ["--scheduler", self.scheduler] if self.scheduler else \
                        ["--workers", "1"]
                    msg = ("study", seq, job_id, study,
                           self._study_options(job_id, study, resolved), argv, str(out))
                else:
                    h5 = self.runs_dir / job_id / "result.h5"
                    h5.parent.mkdir(parents=True, exist_ok=True)
                    msg = ("run", seq, job_id, scene_json, str(h5))
            except Exception as exc:  # its folder cannot be written, its options are gone
                with self._lock:
                    w.job_id = w.seq = w.cancel_at = None
                self._finish(job_id, status="failed", finished=time.time(), eta_s=None,
                             error=f"the job could not be started: {storage_reason(exc)}")
                continue
            try:
                w.conn.send(msg)
            except (OSError, ValueError):
                pass  # the worker died: its sentinel reports it and fails the job

    def _study_options(self, job_id: str, study: str, resolved: Optional[str]) -> dict:
        """A study job's typed options as data, run on this manager's scheduler (or one
        worker in the job's process). A job queued by an older version has none stored:
        they are made again from the options it was submitted with."""

        if resolved:
            data = json.loads(resolved)
        else:
            data = options_to_dict(make_options(study, self.get(job_id).options,
                                                designs_dir=self.data_dir / "designs")[0])
        data.update(scheduler=self.scheduler, workers=None if self.scheduler else 1)
        return data

    def _drain(self, w: WorkerHandle) -> None:
        while True:
            try:
                if not w.conn.poll():
                    return
                msg = w.conn.recv()
            except (EOFError, OSError):
                return
            self._handle(w, msg)

    def _handle(self, w: WorkerHandle, msg) -> None:
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
            if w.over_limit and status == "cancelled":
                status, error = "failed", w.over_limit
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
            with self._lock:
                w.job_id = w.seq = w.cancel_at = None
            self._finish(job_id, **values)

    def _on_death(self, w: WorkerHandle) -> None:
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
            reason = describe_exit(code)
            if w.over_limit:
                status, error = "failed", w.over_limit
            elif cancel_requested:
                status, error = "cancelled", (f"cancelled: the worker process (pid {w.pid}) "
                                              f"did not stop in time and was ended ({reason})")
            else:
                status, error = "failed", (f"the worker process (pid {w.pid}) died while "
                                           f"running this job ({reason}); the result file "
                                           f"keeps the frames recorded before")
            # its result file: from "running" and open-for-writing to the job's status (a
            # copy of the file: before the job is reported finished when it is small, so
            # that a client downloading it then gets the final file; in the background
            # when it is large, not to hold the dispatcher)
            h5 = self.runs_dir / job_id / "result.h5"
            try:
                size = h5.stat().st_size
            except OSError:
                size = None
            if size is not None and size <= FINALIZE_INLINE_BYTES:
                finalize_killed_result(h5, status, error)
            elif size is not None:
                threading.Thread(target=finalize_killed_result, args=(h5, status, error),
                                 name="finalize-result", daemon=True).start()
            self._finish(job_id, status=status, finished=time.time(), error=error, eta_s=None)
        if not w.ready:  # died while starting: say so, and do not respawn in a tight loop
            self._start_failures += 1
            delay = min(2.0 * 2 ** (self._start_failures - 1), 60.0)
            self._respawn_after = time.monotonic() + delay
            if self._start_failures in (1, 3, 10):
                print(f"brush-studio jobs: a worker process failed to start ({describe_exit(code)})"
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
        limit = self.limits.max_job_seconds
        with self._lock:
            if limit is not None:
                for w in self._workers:
                    if w.job_id is not None and w.cancel_at is None and w.started_at is not \
                            None and now - w.started_at > limit and w.seq is not None:
                        w.over_limit = (f"stopped: the job ran longer than this server's "
                                        f"wall-time limit of {limit:g} s (--max-job-seconds); "
                                        f"the result file keeps the frames recorded before")
                        w.cancel_seq.value = w.seq
                        w.cancel_at = now
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
                self._finish(job_id, status="cancelled", finished=time.time(),
                             error="interrupted: the job manager was closed while this job "
                                   "ran")
        with self._lock:
            self._workers.clear()
