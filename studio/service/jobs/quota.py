"""An optional storage quota for the job service's data folder (``brush-studio serve
--max-storage-gb``): the bytes of its job files (results, scenes, study outputs) and uploaded
meshes. A submit that would go over it is refused with :class:`~.store.StorageError` (HTTP
507, like a full disk) naming the quota, what is used and what the job would add; health
reports it. Purging runs (``DELETE /api/runs/{id}?purge=true``) or the retention policy
(``--keep-days``) frees room.

The folder is walked at most once per ``cache_s`` seconds (50 submits at once walk it once);
the jobs added meanwhile are counted by their estimate until the next walk.
"""
from __future__ import annotations

import os
import threading
import time
from pathlib import Path
from typing import Optional

from studio.service.jobs.store import StorageError


def folder_bytes(folder: Path) -> int:
    """Bytes of the regular files under ``folder`` (0 if it does not exist); files that
    vanish while it is walked (a purge) are skipped."""
    total = 0
    stack = [str(folder)]
    while stack:
        try:
            entries = os.scandir(stack.pop())
        except OSError:
            continue
        with entries:
            for e in entries:
                try:
                    if e.is_dir(follow_symlinks=False):
                        stack.append(e.path)
                    elif e.is_file(follow_symlinks=False):
                        total += e.stat(follow_symlinks=False).st_size
                except OSError:
                    continue
    return total


class StorageQuota:
    """At most ``max_bytes`` of files under ``folders`` (``None``: no quota, nothing is
    walked)."""

    def __init__(self, folders: list[Path], max_bytes: Optional[float], cache_s: float = 2.0):
        if max_bytes is not None and not max_bytes > 0:
            raise ValueError(f"storage quota = {max_bytes!r}: must be > 0 bytes (or None)")
        self.folders = [Path(f) for f in folders]
        self.max_bytes = None if max_bytes is None else int(max_bytes)
        self.cache_s = float(cache_s)
        self._lock = threading.Lock()
        self._walked_at = -float("inf")
        self._used = 0
        self._added = 0  # estimated bytes of what was admitted since the last walk

    def used_bytes(self) -> Optional[int]:
        """Bytes used now (the last walk, at most ``cache_s`` old, plus what was admitted
        since); None without a quota."""
        if self.max_bytes is None:
            return None
        with self._lock:
            now = time.monotonic()
            if now - self._walked_at >= self.cache_s:
                self._used = sum(folder_bytes(f) for f in self.folders)
                self._walked_at, self._added = now, 0
            return self._used + self._added

    def admit(self, adding: float, what: str) -> None:
        """Reserve ``adding`` bytes for ``what`` (a run's estimated result file, a mesh);
        :class:`StorageError` when they do not fit."""
        if self.max_bytes is None:
            return
        used = self.used_bytes()
        adding = max(int(adding), 0)
        if used + adding > self.max_bytes or used >= self.max_bytes:
            raise StorageError(
                f"storage quota: the data folder holds {used / 2**20:.1f} MiB of its "
                f"{self.max_bytes / 2**20:.1f} MiB (--max-storage-gb) and {what} needs "
                f"{adding / 2**20:.1f} MiB more: purge finished runs (DELETE "
                f"/api/runs/{{id}}?purge=true) or ask for a larger quota")
        with self._lock:
            self._added += adding

    def problem(self) -> Optional[str]:
        """A line for health when the quota is full, else None."""
        used = self.used_bytes()
        if used is None or used < self.max_bytes:
            return None
        return (f"storage quota full: {used / 2**20:.1f} MiB of "
                f"{self.max_bytes / 2**20:.1f} MiB used (--max-storage-gb)")
