"""The job service's limits on what one job may cost and how many may wait, checked at
submit from the scene's estimate (:func:`engine.estimate`) before anything is built or
written, and the per-job wall time the monitor enforces while a job runs.

Every limit has a default that fits one workstation and is set by the server's operator
(``brush-studio serve --max-nodes ... --max-steps ... --max-job-seconds ... --max-queued
...``). A refused submit names the limit, the scene's value and the allowed maximum: HTTP
413 for what does not fit (nodes, memory, result file), 422 for what would not end in time
(steps, node-steps, frames), 429 with ``Retry-After`` for a full queue.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional

from engine.jsonable import jsonable_null


@dataclass(frozen=True)
class Limits:
    """Limits of the job service (``None``: no limit)."""

    max_nodes: Optional[int] = 2_000_000           # bristle nodes in one scene
    max_steps: Optional[float] = 100_000_000        # steps to the scene's duration (est.)
    max_node_steps: Optional[float] = 5e10          # nodes x steps: the run's work
    max_frames: Optional[float] = 1_000_000         # recorded frames
    max_memory_bytes: Optional[float] = 8 * 2**30   # the build's arrays (est.)
    max_result_bytes: Optional[float] = 16 * 2**30  # the result file (est.)
    max_job_seconds: Optional[float] = 6 * 3600.0   # wall time of one job, then it fails
    max_queued: Optional[int] = 100                 # jobs waiting: then 429
    max_study_runs: Optional[int] = 200             # runs one study may plan
    keep_days: Optional[float] = None               # finished jobs older: purged
    max_storage_bytes: Optional[float] = None       # job files + meshes: then 507

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


class LimitError(ValueError):
    """A submit over one of the service's limits: ``status`` (413, 422 or 429), ``limit``
    (its name, as the server's option without ``--``), ``value``, ``allowed``, and for 429
    ``retry_after`` (seconds)."""

    def __init__(self, limit: str, value, allowed, message: str, status: int,
                 retry_after: Optional[int] = None):
        super().__init__(message)
        self.limit, self.value, self.allowed = limit, value, allowed
        self.status, self.retry_after = status, retry_after

    def as_dict(self) -> dict:
        return {"loc": ["body"], "msg": str(self), "type": "limit_error",
                "limit": self.limit, "value": jsonable_null(self.value),
                "allowed": jsonable_null(self.allowed)}


# cost field -> (limit field, the server's option, HTTP status, what it is); in this order
_CHECKS = (("n_nodes", "max_nodes", "--max-nodes", 413, "bristle nodes"),
           ("steps", "max_steps", "--max-steps", 422, "steps to run.duration at dt (est.)"),
           ("node_steps", "max_node_steps", "--max-node-steps", 422,
            "node-steps (nodes x steps, est.)"),
           ("frames", "max_frames", "--max-frames", 422,
            "recorded frames (run.duration / run.record_interval)"),
           ("memory_bytes", "max_memory_bytes", "--max-memory-mb", 413,
            "bytes of memory for the build (est.)"),
           ("result_bytes", "max_result_bytes", "--max-result-mb", 413,
            "bytes of result file (est.)"))


def check_cost(cost, limits: Limits) -> None:
    """Raise :class:`LimitError` for the first limit ``cost`` (an ``engine.Cost``) is
    over."""
    for attr, name, option, status, what in _CHECKS:
        allowed = getattr(limits, name)
        value = getattr(cost, attr)
        if allowed is not None and value > allowed:
            raise LimitError(name, value, allowed,
                             f"the scene needs {value:.4g} {what}; this server allows at most "
                             f"{allowed:.4g} ({option}). {cost.summary()}", status)


# string options that list the study's cases, comma-separated
_LIST_TEXT = ("angles", "cubes", "configs", "levels", "ladder", "dt_factor", "cases",
              "frequencies")
_COUNTS = ("samples", "random_seeds")


def planned_runs(options) -> int:
    """An upper estimate of the runs a study's ``Options`` model plans: the product of its
    lists' lengths (presets, angles, levels, cases, ...) and its sample counts."""
    runs = 1
    for name in type(options).model_fields:
        v = getattr(options, name)
        if isinstance(v, (list, tuple)):
            runs *= max(1, len(v))
        elif name in _LIST_TEXT and isinstance(v, str):
            runs *= max(1, len([x for x in v.split(",") if x.strip()]))
        elif name in _COUNTS and isinstance(v, int) and not isinstance(v, bool):
            runs *= max(1, v)
    return runs
