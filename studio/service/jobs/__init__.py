"""The job layer shared by the HTTP server (``studio.service.server``) and the 3D studio.

A :class:`JobManager` owns a bounded pool of worker processes (default: one per core), a
FIFO queue of submitted scenes and a SQLite database (``DATA/jobs.sqlite``) that keeps every
job's state across restarts. Each run writes its files under ``DATA/runs/<job_id>/``
(``result.h5``, the engine's result file, and ``scene.json``)::

    from studio.service.jobs import JobManager

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

from studio.studies.registry import (SCENE_OPTIONS, SERVER_OPTIONS, STUDIES, StudyOptionError,
                                make_options, study_options, study_schema)
from studio.service.jobs.limits import LimitError, Limits, planned_runs
from studio.service.jobs.manager import JobManager
from studio.service.jobs.meshes import DEFAULT_MAX_TRIANGLES, MESH_FORMATS, MESH_PREFIX, MeshError, MeshStore
from studio.service.jobs.store import FINAL_STATUSES, STATUSES, JobInfo, JobStore, StorageError, jsonable
from studio.service.jobs.worker import STUDY_LOG, cpu_count

__all__ = ["JobManager", "JobInfo", "JobStore", "StorageError", "Limits", "LimitError",
           "planned_runs", "MeshStore", "MeshError", "STATUSES",
           "FINAL_STATUSES", "MESH_FORMATS", "MESH_PREFIX", "DEFAULT_MAX_TRIANGLES",
           "STUDIES", "SCENE_OPTIONS", "SERVER_OPTIONS", "STUDY_LOG", "StudyOptionError",
           "make_options", "study_options", "study_schema", "jsonable", "cpu_count"]
