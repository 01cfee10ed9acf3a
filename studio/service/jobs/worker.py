"""The worker processes of the job layer and the manager's handle on each.

A worker (``spawn``-started) sets ``NUMBA_NUM_THREADS``, imports the engine once and then
runs the jobs the manager sends through its pipe, one after another: a scene
(:func:`_worker_run`: build, run into ``result.h5``, progress on the pipe) or a study
(:func:`_worker_study`: the study's typed ``run`` with the job's cancel flag and a progress
callback). A cancel arrives through shared memory (``cancel_seq``), checked between
compiled chunks.
"""
from __future__ import annotations

import json
import os
import signal
import time
import traceback
from pathlib import Path
from typing import Optional

from studio.service.jobs.store import jsonable

STUDY_LOG = "log.txt"  # the study's printed output, in its output folder
# a run stops, failed with "No space left on device", when its result's disk has less free:
# HDF5 writing its file in SWMR mode onto a full disk crashed the worker (SIGSEGV) instead
# of raising, so the run must stop before the disk is full (1 MiB: a recorded chunk)
RUN_FREE_FLOOR_BYTES = 2**20
DISK_FULL = "No space left on device"


def free_bytes(path) -> Optional[int]:
    """Free bytes on the file system holding ``path`` (None if it cannot be told)."""
    import shutil

    try:
        return shutil.disk_usage(path).free
    except OSError:
        return None


def disk_full_reason(path) -> Optional[str]:
    """The disk-full explanation when the file system of ``path`` is (nearly) full."""
    free = free_bytes(path)
    if free is not None and free < RUN_FREE_FLOOR_BYTES:
        return (f"{DISK_FULL}: {free / 2**20:.1f} MiB free on the disk of {path} (a run "
                f"stops below {RUN_FREE_FLOOR_BYTES / 2**20:.0f} MiB)")
    return None


def cpu_count() -> int:
    """Cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def describe_exit(code: Optional[int]) -> str:
    if code is None:
        return "exit status unknown"
    if code < 0:
        try:
            return f"killed by signal {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def _study_files(folder: Path) -> list[str]:
    from studio.studies.api import study_files

    return study_files(folder)


def _os_reason(exc: OSError) -> str:
    return exc.strerror or str(exc) or type(exc).__name__


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
    import engine.assembly.system  # noqa: F401
    import engine.stepping.loop  # noqa: F401

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
                _, seq, job_id, study, options, out_dir = msg
                _worker_study(conn, cancel_seq, parent_pid, seq, job_id, study, options,
                              out_dir)
        except (BrokenPipeError, EOFError, OSError):
            return  # the manager is gone


def _worker_run(conn, cancel_seq, parent_pid, seq, job_id, scene_json, h5_path) -> None:
    import engine

    folder = Path(h5_path).parent
    disk_full: list[str] = []  # why the run was stopped for a full disk
    checked = [0.0]

    def cancelled() -> bool:
        if cancel_seq.value == seq or os.getppid() != parent_pid:
            return True
        now = time.monotonic()
        if now - checked[0] >= 0.25:  # (statvfs: microseconds; four times a second)
            checked[0] = now
            reason = disk_full_reason(folder)
            if reason:
                disk_full.append(reason)
                return True
        return False

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
    except OSError as exc:  # the result file cannot be written: a full disk, most often
        error = (f"storage error: the result file {h5_path} could not be written "
                 f"({_os_reason(exc)}); the frames written before are kept")
    except Exception as exc:  # report any bug with its traceback; the worker goes on
        error = f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"
    if disk_full:  # stopped by the disk, not by a cancel: a failure with the real reason
        status = "failed"
        error = (f"storage error: {disk_full[0]}; the run was stopped and the result file "
                 f"{h5_path} keeps the frames written before")
    conn.send(("done", job_id, {"status": status, "summary": jsonable(summary),
                                "error": error, "finished": time.time()}))


class _JobCancel:
    """The cancel flag a study job's ``run`` polls (``is_set``): the manager's cancel of this
    job through shared memory, or the manager gone."""

    def __init__(self, cancel_seq, seq: int, parent_pid: int):
        self.cancel_seq, self.seq, self.parent_pid = cancel_seq, seq, parent_pid

    def is_set(self) -> bool:
        return self.cancel_seq.value == self.seq or os.getppid() != self.parent_pid


def _worker_study(conn, cancel_seq, parent_pid, seq, job_id, study, options,
                  out_dir) -> None:
    """Run a study in this process through its typed API (``registry.get(study).run`` of
    the options model checked from the stored dict ``options``): its progress callback
    reports to the manager, its cancel is the job's; what it prints goes into
    ``out_dir/log.txt``. Bad input (:class:`StudyInputError`, :class:`StudyOptionError`)
    is the job's error, whole; the result's summary goes into the job's summary."""
    import contextlib

    from studio.exit_codes import EXIT_OK, describe
    from studio.studies import registry

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

    from studio.exit_codes import EXIT_BAD_INPUT
    from studio.studies.api import StudyInputError

    code, error, result = 1, None, None
    with open(log_path, "a", buffering=1) as log, contextlib.redirect_stdout(log), \
            contextlib.redirect_stderr(log):
        entry = registry.get(study)
        print("$ " + " ".join(w for w in ("brush-studio", entry.command, study) if w)
              + " with options " + json.dumps(options, sort_keys=True), flush=True)
        try:
            result = entry.run(entry.options_from_dict(options), out, progress=progress,
                               cancel=cancel)
            code = result.exit_code
        except (StudyInputError, registry.StudyOptionError) as exc:  # bad input: whole
            code, error = EXIT_BAD_INPUT, f"bad input: {exc}"
            print(f"error: {exc}", flush=True)
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
    if result is not None:
        summary["tables"] = sorted(result.tables)
        summary["figures"] = [p.name for p in result.figures]
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


class WorkerHandle:
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
        self.started_at: Optional[float] = None  # monotonic time the running job started
        self.over_limit: Optional[str] = None  # why the running job was stopped by a limit

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


def finalize_killed_result(path: Path, status: str, message: str) -> bool:
    """Make the result file of a job whose worker died a plain, finished HDF5 file with the
    job's status: a killed writer leaves it marked open-for-SWMR-writing (plain
    ``h5py.File(p, "r")`` refuses it) with ``status = "running"``. Its objects are copied
    into a new file with ``status`` and ``error = {"type": "WorkerDied", "message"}``, which
    then replaces it (atomically: readers see the old or the new file). Returns False (and
    leaves the file as it is; ``engine.open_result`` reads it) when it cannot."""
    import h5py

    from engine.jsonable import json_text
    from engine.io.recorder import _text

    path = Path(path)
    if not path.is_file():
        return False
    tmp = path.with_name(path.name + ".finalizing")
    try:
        with h5py.File(path, "r", swmr=True, locking=False) as src, \
                h5py.File(tmp, "w", libver="latest", locking=False) as dst:
            for key in src.attrs:
                dst.attrs.create(key, src.attrs[key], dtype=src.attrs.get_id(key).dtype)
            for name in src:
                src.copy(src[name], dst, name=name)
            dst.attrs["status"] = _text(status)
            dst.attrs["error"] = _text(json_text({"type": "WorkerDied", "message": message}))
        os.replace(tmp, path)
        return True
    except Exception:  # a file killed while it was set up, a full disk: leave it
        try:
            tmp.unlink()
        except OSError:
            pass
        return False
