"""A job's state written to the job database even when storage fails.

A write that fails (a full disk, a read-only database) is noted as the storage problem
:meth:`JobManager.health` reports; a job's *final* state that could not be written is kept
here, shown in place of the stored one (:meth:`StateWriter.overlay`) and written again by the
monitor thread (:meth:`StateWriter.flush_pending`) until it is. The free-space check that
refuses submits on a nearly full data folder lives here too: it is the same storage problem.
"""
from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path
from typing import Optional

from studio.service.jobs.store import JobInfo, JobStore, StorageError


class StateWriter:
    """Writes job states to ``store`` under its lock; ``data_dir`` and ``min_free_bytes``:
    the folder whose free space :meth:`check_free_space` checks, and the least it needs."""

    def __init__(self, store: JobStore, data_dir: Path, min_free_bytes: int):
        self._store = store
        self._lock = store.lock
        self.data_dir = data_dir
        self.min_free_bytes = int(min_free_bytes)
        # storage trouble seen last (None: the last write succeeded), and the final states of
        # jobs that could not be written yet (retried by the monitor until they are)
        self.problem: Optional[str] = None
        self.pending: dict[str, dict] = {}

    def failed(self, reason: str) -> None:
        with self._lock:
            self.problem = reason

    def ok(self) -> None:
        with self._lock:
            self.problem = None

    def update(self, job_id: str, **values) -> bool:
        """Write a job's state; on a storage error note it (health) and return False."""
        try:
            self._store.update(job_id, **values)
        except StorageError as exc:
            self.failed(str(exc))
            return False
        if self.problem is not None and not self.pending:
            self.ok()
        return True

    def finish(self, job_id: str, **values) -> None:
        """Write a job's final state; if storage fails, keep it and retry from the monitor
        until it is written (the job is reported with it meanwhile)."""
        if not self.update(job_id, **values):
            with self._lock:
                self.pending[job_id] = values

    def flush_pending(self) -> None:
        with self._lock:
            pending = list(self.pending.items())
        for job_id, values in pending:
            if self.update(job_id, **values):
                with self._lock:
                    self.pending.pop(job_id, None)
        if pending and not self.pending:
            self.ok()

    def forget(self, job_id: str) -> None:
        """Drop a purged job's unwritten final state (call with the store's lock held)."""
        self.pending.pop(job_id, None)

    def overlay(self, info: JobInfo) -> JobInfo:
        """A job whose final state could not be written yet is shown with it."""
        with self._lock:
            values = self.pending.get(info.id)
        if not values:
            return info
        known = {f.name for f in dataclasses.fields(JobInfo)}
        return dataclasses.replace(info, **{k: v for k, v in values.items() if k in known})

    def free_bytes(self) -> Optional[int]:
        try:
            return shutil.disk_usage(self.data_dir).free
        except OSError:
            return None

    def check_free_space(self) -> None:
        """:class:`StorageError` when the data folder has less than ``min_free_bytes``
        free."""
        free = self.free_bytes()
        if free is not None and free < self.min_free_bytes:
            reason = (f"only {free / 2**20:.1f} MiB free in {self.data_dir} (at least "
                      f"{self.min_free_bytes / 2**20:.0f} MiB are needed to run jobs)")
            self.failed(reason)
            raise StorageError(reason)
