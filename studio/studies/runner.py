"""Many independent simulations on Dask distributed: one task per run, one HDF5 per run.

    from studio.studies.runner import RunSpec, run_many

    specs = [RunSpec(run_id=f"E{i}", scene=scene_dict_i, params={"youngs_modulus": E_i})
             for i, (scene_dict_i, E_i) in enumerate(cases)]
    outcomes = run_many(specs, "study-out")          # local cluster, one worker per core
    outcomes = run_many(specs, "study-out", scheduler="tcp://10.0.0.5:8786")  # existing one

Every run writes ``out_dir/runs/<run_id>.h5`` (the task decides what goes into it) and, last
and atomically, ``out_dir/runs/<run_id>.json`` (its :class:`RunOutcome`, plus a hash of the
run's scene, parameters and task). A study that is stopped and started again skips every run
whose ``.json`` says ``completed`` or ``stopped`` for the same hash; a run that failed, was
cancelled or never finished runs again (those files: :mod:`studio.studies.run_files`). A
failing run is reported with its parameters (:func:`studio.studies.run_files.failures_text`);
the other runs go on. The options and body every study command shares are in
:mod:`studio.studies.study_command`.

A task is ``"module:function"``, called on the worker as
``fn(scene: engine.Scene, h5_path: pathlib.Path, params: dict) -> dict`` (a small JSON-able
summary; it may hold ``"status"``: ``"completed"`` (the default) or ``"stopped"``). An
exception in the task (an instability, a scene the engine refuses) makes the run ``failed``,
with the error's type and message; nothing else is affected.

One worker (``n_workers=1``, or a one-core machine, and no scheduler) starts no cluster: the
runs go one after another through the same task function in this process, so that a short
study does not pay for a scheduler and a worker process that imports the engine again (with
the same outputs, restart skips, failure reports, and Ctrl-C keeping finished runs).

Workers: the local cluster starts one single-threaded worker *process* per core
(``NUMBA_NUM_THREADS=1`` in each), so that the runs, not numba's thread pools, share the
cores. Each task also caps numba's threads for its own thread at
``BRUSH_STUDIO_NUMBA_THREADS`` (default 1), so that workers started by hand with ``dask worker``
do not oversubscribe either. With ``--scheduler`` the workers must import this project
(``pip install -e .``) and see ``out_dir`` at the same path (a shared file system).
"""
from __future__ import annotations

import hashlib
import importlib
import json
import os
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional, Sequence

from engine.jsonable import jsonable
from . import api
from .run_files import (DONE_STATUSES, STATUSES, RunOutcome, load_outcome, outcome_from_dict,
                        run_paths, write_json_atomic)

DEFAULT_TASK = "studio.studies.runner:plain_run"
#: the progress bar before any run has finished: elapsed time, no estimate of the time left
NO_ETA_FORMAT = "{l_bar}{bar}| {n:.3g}/{total_fmt} [{elapsed}{postfix}]"


# ----------------------------------------------------------------------------- data
@dataclass
class RunSpec:
    """One simulation of a study.

    ``run_id``: filesystem-safe (letters, digits, ``._-``) and stable across restarts (it
    names the run's files); ``scene``: the scene as a JSON dict; ``params``: the study
    parameters of this run (JSON-able; reported with failures and stored in the outcome);
    ``task``: ``"module:function"`` run on the worker (see the module docstring)."""

    run_id: str
    scene: dict
    params: dict = field(default_factory=dict)
    task: str = DEFAULT_TASK

    def digest(self) -> str:
        """Hash of what the run computes (scene, params, task): a restart skips a finished
        run only when this is unchanged."""
        text = json.dumps({"scene": self.scene, "params": self.params, "task": self.task},
                          sort_keys=True, default=str, allow_nan=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _check_run_id(run_id: str) -> None:
    ok = run_id and all(c.isalnum() or c in "._-" for c in run_id) and run_id[0] not in ".-"
    if not ok:
        raise ValueError(f"run_id {run_id!r}: use letters, digits, '.', '_' and '-' only "
                         f"(it names the run's files), not starting with '.' or '-'")



# ----------------------------------------------------------------------------- worker side
def resolve_task(task: str) -> Callable:
    """The function named by ``"module:function"``."""
    module, sep, name = task.partition(":")
    if not sep or not module or not name:
        raise ValueError(f"task {task!r}: expected 'module:function'")
    fn = importlib.import_module(module)
    for part in name.split("."):
        fn = getattr(fn, part)
    if not callable(fn):
        raise TypeError(f"task {task!r} is not callable")
    return fn


def _limit_numba_threads() -> None:
    try:
        import numba

        n = int(os.environ.get("BRUSH_STUDIO_NUMBA_THREADS", "1"))
        numba.set_num_threads(max(1, min(n, numba.config.NUMBA_NUM_THREADS)))
    except Exception:  # no numba threading layer: nothing to limit
        pass


def execute_spec(spec: dict, out_dir: str, *, on_progress: Optional[Callable] = None,
                 reraise_interrupt: bool = False) -> dict:
    """Run one spec (as a dict) on this process: the function each Dask task calls, and
    the one-worker path of :func:`run_many` calls in its own process.

    Writes ``runs/<run_id>.h5`` (through the task) and then, atomically,
    ``runs/<run_id>.json``; returns the outcome as a dict. Never raises for a failing run:
    the failure is the outcome. A KeyboardInterrupt makes the run ``cancelled``; with
    ``reraise_interrupt`` it is raised again once that outcome is written (a study in this
    process stops there). ``on_progress(fraction)``: also told what the task reports."""
    import engine

    global _PROGRESS
    _limit_numba_threads()
    run_id = spec["run_id"]
    h5, js = run_paths(Path(out_dir), run_id)
    h5.parent.mkdir(parents=True, exist_ok=True)
    outer = _PROGRESS   # a task that runs specs of its own (a search run fitting its law)
    _PROGRESS = _ProgressFile(progress_path(Path(out_dir), run_id), on_progress)
    status, summary, error = "failed", {}, None
    interrupted = False
    t0 = time.perf_counter()
    try:
        fn = resolve_task(spec["task"])
        scene = engine.parse_scene(spec["scene"])
        result = fn(scene, h5, dict(spec["params"]))
        summary = dict(result or {})
        status = summary.get("status", "completed")
        if status not in STATUSES:
            raise ValueError(f"task returned status {status!r}; expected one of {STATUSES}")
        if status == "failed" and summary.get("error"):
            error = str(summary["error"])
    except engine.SceneError as exc:
        error = "SceneError: " + "; ".join(str(p) for p in exc.problems)
    except KeyboardInterrupt:
        status, error, interrupted = "cancelled", "KeyboardInterrupt", True
    except Exception as exc:
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" (at {tb[-1].filename}:{tb[-1].lineno})" if tb else ""
        error = f"{type(exc).__name__}: {exc}{where}"
        status = "failed"
    wall = time.perf_counter() - t0
    if error is not None:
        error = " ".join(error.split())  # one line: it is printed beside the parameters
    _PROGRESS.remove()
    _PROGRESS = outer
    outcome = {"run_id": run_id, "params": spec["params"], "status": status,
               "summary": summary, "error": error, "h5": str(h5), "wall_s": wall,
               "skipped": False}
    write_json_atomic(js, dict(outcome, digest=spec["digest"], task=spec["task"],
                               finished=time.time()))
    if interrupted and reraise_interrupt:
        raise KeyboardInterrupt
    return jsonable(outcome)


def progress_path(out_dir: Path, run_id: str) -> Path:
    """Where a running task reports how far it is (read by :func:`run_many`'s bar)."""
    return Path(out_dir) / "runs" / f".{run_id}.progress"


class _ProgressFile:
    def __init__(self, path: Path, on_progress: Optional[Callable] = None):
        self.path = path
        self.on_progress = on_progress
        self.last = 0.0

    def write(self, fraction: float) -> None:
        now = time.monotonic()
        if now - self.last < 0.5:
            return
        self.last = now
        if self.on_progress is not None:
            self.on_progress(min(max(float(fraction), 0.0), 1.0))
        tmp = self.path.with_name(self.path.name + ".tmp")
        try:
            tmp.write_text(f"{min(max(float(fraction), 0.0), 1.0):.6f}")
            os.replace(tmp, self.path)
        except OSError:  # progress is a nicety: never fail a run for it
            pass

    def remove(self) -> None:
        try:
            self.path.unlink()
        except OSError:
            pass


_PROGRESS: Optional[_ProgressFile] = None


def report_progress(fraction: float) -> None:
    """Called by a task (on its worker) to say how far its run is, 0..1; shown in the
    study's progress bar. Does nothing outside a study run; at most two writes a second.
    Also a cancel check point: raises :class:`api.StudyCancelled` once the study running
    in this process is cancelled."""
    if _PROGRESS is not None:
        _PROGRESS.write(fraction)
    api.check_cancel()


def _read_progress(out_dir: Path, run_id: str) -> float:
    try:
        return min(max(float(progress_path(out_dir, run_id).read_text()), 0.0), 1.0)
    except (OSError, ValueError):
        return 0.0


def plain_run(scene, h5_path: Path, params: dict) -> dict:
    """The default task: build the scene and run it to ``run.duration`` into ``h5_path``.
    Returns the run's status, simulated time, wall time, dt, steps and sizes, and the last
    recorded vertical root force of each brush (N)."""
    import engine

    system = engine.build(scene)
    result = engine.run(system, output=h5_path)  # InstabilityError -> the run failed
    s = result.summary
    out = {"status": result.status if result.status in STATUSES else "failed",
           "time": s.get("time"), "wall_s": s.get("wall_s"), "dt": s.get("dt"),
           "steps": s.get("steps"), "n_nodes": s.get("n_nodes"), "frames": result.frames}
    if result.status == "cancelled":
        out["status"] = "cancelled"
    try:
        with engine.open_result(result.path) as res:
            for b in scene.brushes:
                f = res.series(f"brushes/{b.name}/root_force")
                if len(f):
                    out[f"root_force_z.{b.name}"] = float(f[-1, 2])
    except (engine.BrushStudioError, KeyError):
        pass
    return out


# ----------------------------------------------------------------------------- client side
def run_counting_momentum(scene, h5_path: Path):
    """Build and run ``scene`` into ``h5_path`` for a study's task, under the study's cancel;
    returns ``(system, result, p_start, p_end)``: the total linear momentum of the moving
    parts before and after (a study checks what its recorded forces transmitted against it)."""
    import engine
    import numpy as np

    system = engine.build(scene)
    p_start = np.asarray(engine.linear_momentum(system), float)
    result = engine.run(system, output=h5_path, cancel=api.cancel_requested)
    api.check_cancel()
    return system, result, p_start, np.asarray(engine.linear_momentum(system), float)


def default_workers() -> int:
    """Cores this process may use (one worker process per core)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def _connect(scheduler: Optional[str], n_workers: Optional[int]):
    """(client, cluster or None). A local cluster of single-threaded worker processes with
    NUMBA_NUM_THREADS=1, or a client of an existing scheduler."""
    import logging

    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler, timeout="30s"), None
    n = n_workers or default_workers()
    env = {"NUMBA_NUM_THREADS": "1", "BRUSH_STUDIO_NUMBA_THREADS": "1",
           "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    try:
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None,
                               silence_logs=logging.ERROR, env=env,
                               worker_dashboard_address=None,
                               # no dashboard; its bare HTTP server on any free port, not 8787
                               scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
    except RuntimeError as exc:
        raise RuntimeError(
            f"Dask could not start its {n} local worker processes ({exc}). They are "
            f"spawned: each imports the calling script again, so a script that runs a study "
            f"must do it under `if __name__ == \"__main__\":` (examples/03_study_on_dask.py); "
            f"or pass workers=1 to run in this process.") from exc
    return Client(cluster), cluster


def run_many(specs: Sequence[RunSpec], out_dir, *, scheduler: Optional[str] = None,
             n_workers: Optional[int] = None, progress: bool = True,
             desc: str = "runs") -> list[RunOutcome]:
    """Run ``specs``, one task per run; outcomes in the order of ``specs``.

    ``scheduler``: ``None`` starts a local Dask cluster with ``n_workers`` single-threaded
    worker processes (default: one per core) and stops it at the end, or, for one worker or
    a single run to do, runs the tasks one after another in this process (no cluster); ``"tcp://host:port"``
    uses an existing scheduler and its workers. Runs already complete in ``out_dir`` (same
    hash) are skipped (``skipped=True``). ``progress`` shows a tqdm bar over runs.

    Ctrl-C (KeyboardInterrupt), or the cancel of the study running this (``api.session``),
    cancels the queued runs and raises; runs finished before it keep their files, so the next
    call picks up from there. That study's progress callback follows the bar."""
    from tqdm import tqdm

    out_dir = Path(out_dir)
    ids = [s.run_id for s in specs]
    for rid in ids:
        _check_run_id(rid)
    if len(set(ids)) != len(ids):
        dup = sorted({r for r in ids if ids.count(r) > 1})
        raise ValueError(f"run_id must be unique within a study; repeated: {dup}")
    (out_dir / "runs").mkdir(parents=True, exist_ok=True)

    outcomes: list[Optional[RunOutcome]] = [None] * len(specs)
    todo: list[tuple[int, dict]] = []
    for i, spec in enumerate(specs):
        digest = spec.digest()
        old = load_outcome(out_dir, spec.run_id)
        if old and old.get("status") in DONE_STATUSES and old.get("digest") == digest \
                and Path(old.get("h5", "")).exists():
            outcomes[i] = outcome_from_dict(old, skipped=True)
            continue
        try:  # a progress note left by a run killed earlier
            progress_path(out_dir, spec.run_id).unlink()
        except OSError:
            pass
        todo.append((i, {"run_id": spec.run_id, "scene": spec.scene,
                         "params": jsonable(spec.params), "task": spec.task,
                         "digest": digest}))

    n_before = len(specs) - len(todo)
    # No time left is shown until a whole run has finished: a run's own progress is in
    # simulated time, and its cost per simulated second is not uniform (a wedge costs more
    # the deeper it is), so an estimate from the first part of a run fell short by 4x. After
    # that, the average over the whole study so far (smoothing 0), not the last seconds'.
    bar = tqdm(total=len(specs), initial=n_before, desc=desc, unit="run",
               disable=not progress, dynamic_ncols=True, file=sys.stderr, smoothing=0,
               bar_format=NO_ETA_FORMAT)
    bar.study_desc = desc  # a disabled bar keeps no desc: the progress callback's words
    _refresh(bar, force=True)
    tally = {"failed": 0, "finished": 0}

    def finish(i: int, d: dict, result) -> None:
        """Record the outcome of ``todo`` entry (i, d): ``result`` is what
        :func:`execute_spec` returned, or the exception that came instead of it."""
        if isinstance(result, BaseException):  # the worker died (KilledWorker), ...
            h5, js = run_paths(out_dir, d["run_id"])
            outcome = RunOutcome(d["run_id"], d["params"], "failed", {},
                                 f"{type(result).__name__}: {result}", h5, 0.0)
            write_json_atomic(js, dict(outcome.to_dict(), digest=d["digest"], task=d["task"]))
        else:
            outcome = outcome_from_dict(result, skipped=False)
        outcomes[i] = outcome
        if not outcome.ok:
            tally["failed"] += 1
            bar.write(f"run {outcome.run_id} {outcome.status}: "
                      f"{outcome.error}  params {json.dumps(outcome.params)}")
        tally["finished"] += 1
        bar.bar_format = None     # whole runs done: tqdm's own format, with the time left
        bar.set_postfix_str(f"{tally['failed']} failed", refresh=False)
        bar.n = n_before + tally["finished"]
        _refresh(bar, force=True)

    try:
        # one worker, or a single run to do (a cluster would give it one worker anyway):
        # no cluster, the run in this process
        if todo and scheduler is None and (len(todo) == 1
                                           or (n_workers or default_workers()) == 1):
            _run_here(todo, out_dir, bar, n_before, tally, finish)
        elif todo:
            _run_on_dask(todo, out_dir, bar, n_before, finish, scheduler, n_workers)
    finally:
        bar.close()
    return list(outcomes)  # type: ignore[arg-type]  # every run has its outcome here


def _refresh(bar, force: bool = False) -> None:
    """Redraw the terminal bar (when shown) and tell the study's progress callback."""
    bar.refresh()
    total = bar.total or 0
    desc = getattr(bar, "study_desc", None) or "runs"
    api.current().report(bar.n / total if total else 0.0,
                         f"{desc}: {bar.n:.4g}/{total:g} run", force=force)


def _run_here(todo: list, out_dir: Path, bar, n_before: int, tally: dict, finish) -> None:
    """The one-worker path: each run through :func:`execute_spec` in this process, in order.
    Ctrl-C cancels the run under way (its outcome says so) and the ones after it."""
    import numba

    def moved(fraction: float) -> None:
        n = round(n_before + tally["finished"] + fraction, 2)
        if n != bar.n:
            bar.n = n
            _refresh(bar)

    threads = numba.get_num_threads()  # execute_spec caps this thread's; give it back
    try:
        for i, d in todo:
            api.check_cancel()
            try:
                result = execute_spec(d, str(out_dir.resolve()), on_progress=moved,
                                      reraise_interrupt=True)
            except Exception as exc:  # an outcome that could not be written, ...
                result = exc
            finish(i, d, result)
    finally:
        numba.set_num_threads(threads)


def _run_on_dask(todo: list, out_dir: Path, bar, n_before: int, finish,
                 scheduler: Optional[str], n_workers: Optional[int]) -> None:
    """Every run as a task of a Dask cluster (a local one, or ``scheduler``'s)."""
    client, cluster = _connect(scheduler, n_workers)
    try:
        futures = {}
        for i, d in todo:
            fut = client.submit(execute_spec, d, str(out_dir.resolve()),
                                key=f"brush-run-{d['run_id']}-{d['digest']}",
                                pure=False, retries=0)
            futures[fut] = (i, d)
        try:
            for fut in _completed(futures, bar, out_dir, n_before):
                i, d = futures[fut]
                try:
                    result = fut.result()
                except Exception as exc:  # the worker died (KilledWorker), ...
                    result = exc
                finish(i, d, result)
        except BaseException:
            client.cancel(list(futures))
            raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _completed(futures: dict, bar, out_dir: Path, n_before: int):
    """Yield futures as they finish; meanwhile move the bar by the runs' own progress."""
    from distributed import wait

    pending = set(futures)
    n_done = 0
    while pending:
        try:
            done, pending = wait(pending, timeout=0.5, return_when="FIRST_COMPLETED")
        except TimeoutError:  # (distributed's TimeoutError is the builtin one)
            done = set()
        for fut in done:
            n_done += 1
            yield fut
        partial = sum(_read_progress(out_dir, futures[f][1]["run_id"]) for f in pending
                      if f.status == "pending")
        n = round(n_before + n_done + partial, 2)
        if n != bar.n:
            bar.n = n
            _refresh(bar)
        api.check_cancel()  # the caller cancels the queued tasks
