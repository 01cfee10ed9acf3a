"""The job manager's monitor thread: it keeps the pool of worker processes full, hands
queued jobs to idle workers (oldest first), receives their progress and results through a
pipe per worker and writes them to the job database, enforces cancels and the wall-time limit
(a worker that does not stop within the grace period is terminated) and notices dead workers
through their process sentinels (their job fails with the reason, a new worker takes their
place).

:class:`WorkerMonitor` is a part of :class:`~.manager.JobManager`, not an object of its own:
the monitor and the manager's public methods share one worker table, one job database and one
lock (``JobManager.__init__`` sets them up), so the split is by purpose (this file: what the
thread does; ``manager.py``: what callers ask for), not by state.
"""
from __future__ import annotations

import json
import os
import sqlite3
import sys
import threading
import time
import traceback
from typing import Optional

from studio.service.jobs.store import FINAL_STATUSES, StorageError, storage_reason
from studio.service.jobs.worker import WorkerHandle, describe_exit, disk_full_reason, finalize_killed_result

# a killed worker's result file up to this size is finalized before its job is reported
FINALIZE_INLINE_BYTES = 64 * 1024 * 1024


class WorkerMonitor:
    """The monitor thread's steps (mixed into :class:`~.manager.JobManager`)."""

    def _wake(self) -> None:
        try:
            os.write(self._wake_w, b"x")
        except (BlockingIOError, OSError):
            pass

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
                for step in (self._writes.flush_pending, self._keep_pool, self._dispatch,
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
                    "SELECT seq, id, scene, kind, study, options, resolved FROM jobs WHERE "
                    "status = 'queued' ORDER BY seq LIMIT 1").fetchone()
                if row is None:
                    return
                seq, job_id, scene_json, kind, study, stored, resolved = row
                try:
                    cur = self._db.execute(
                        "UPDATE jobs SET status = 'running', started = ?, worker_pid = ? "
                        "WHERE id = ? AND status = 'queued'", (time.time(), w.pid, job_id))
                except sqlite3.Error as exc:  # the job stays queued; tried again next turn
                    reason = f"the job database could not be written: {storage_reason(exc)}"
                    self._writes.failed(reason)
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
                    msg = ("study", seq, job_id, study,
                           self._study_options(study, stored, resolved), str(out))
                else:
                    h5 = self.runs_dir / job_id / "result.h5"
                    h5.parent.mkdir(parents=True, exist_ok=True)
                    msg = ("run", seq, job_id, scene_json, str(h5))
            except Exception as exc:  # its folder cannot be written, its options are gone
                with self._lock:
                    w.job_id = w.seq = w.cancel_at = None
                self._writes.finish(job_id, status="failed", finished=time.time(), eta_s=None,
                             error=f"the job could not be started: {storage_reason(exc)}")
                continue
            try:
                w.conn.send(msg)
            except (OSError, ValueError):
                pass  # the worker died: its sentinel reports it and fails the job

    def _study_options(self, study: str, stored: Optional[str], resolved: Optional[str]
                       ) -> dict:
        """A study job's options (the validated model's dict it was stored with), run on
        this manager's scheduler (or one worker in the job's process). A job queued by an
        older version kept them in ``resolved``."""
        data = json.loads(resolved or stored or "{}")
        data.update(scheduler=self.scheduler, workers=None if self.scheduler else 1,
                    no_progress=True)
        data.pop("quiet", None)
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
            self._writes.update(job_id, dt=data["dt"], dt_limited_by=str(data["dt_limited_by"]),
                         until=data["until"], sim_time=data["sim_time"],
                         assembled=data["assembled"], warnings=data["warnings"])
        elif kind == "study_progress":
            self._writes.update(job_id, progress=min(max(float(data["progress"]), 0.0), 1.0),
                         message=str(data.get("message") or "")[:300])
        elif kind == "progress":
            self._writes.update(job_id, sim_time=data["sim_time"], until=data["until"],
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
            self._writes.finish(job_id, **values)

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
            full = disk_full_reason(self.runs_dir)  # a crash on a full disk: say so
            if full:
                reason += f"; {full}"
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
            self._writes.finish(job_id, status=status, finished=time.time(), error=error, eta_s=None)
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
                self._writes.finish(job_id, status="cancelled", finished=time.time(),
                             error="interrupted: the job manager was closed while this job "
                                   "ran")
        with self._lock:
            self._workers.clear()
