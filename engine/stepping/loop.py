"""Run a built system: many steps per call into the compiled loop, Python between chunks for
recording, progress, cancellation and the stop condition.

``run(system, until=None, output=None, on_progress=None, cancel=None) -> RunResult``. A run can
be continued by calling ``run`` again on the same system with a later ``until`` (a new file).
"""
from __future__ import annotations

import math
import tempfile
import time as _time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional, Union

import numpy as np

from engine.assembly.neighbours import grow_on_overflow
from engine.assembly.system import System
from engine.stepping.channels import run_channels, run_frame
from engine.stepping.compile_clock import CompileClock
from engine.stepping.diagnosis import dt_cause, instability
from engine.errors import InstabilityError
from engine.stepping.observables import energies
from engine.io.output_paths import check_output_file
from engine.stepping.observe import observer_calls
from engine.io.recorder import RUN_COMMIT_SECONDS, Recorder
from engine.state import ACC_MAX_OVERLAP, ACC_REBUILDS, ACC_TIMED_STEPS, OK, STAGES, timed_slots
from engine.kernels.stepper import advance

ENERGY_BALANCE_LIMIT = 1.0  # |drift of (total + dissipated - work)| / largest energy seen
ENERGY_FLOOR = 1e-18  # J: below this every energy is round-off and the balance is not judged


@dataclass
class Progress:
    time: float          # simulated time reached, s
    until: float         # simulated time the run goes to, s
    steps: int           # steps done in this run
    total_steps: int
    wall_s: float
    steps_per_s: float
    eta_s: float

    @property
    def fraction(self) -> float:
        return self.steps / self.total_steps if self.total_steps else 1.0


@dataclass
class RunResult:
    status: str                      # completed | stopped | cancelled | failed
    summary: dict
    path: Optional[Path]
    error: Optional[dict] = None
    frames: int = 0

    def open(self):
        """Open the result file with the reader (``engine.io.results.open_result``)."""
        from engine.io.results import open_result
        return open_result(self.path)


def _is_cancelled(cancel) -> bool:
    if cancel is None:
        return False
    if hasattr(cancel, "is_set"):
        return bool(cancel.is_set())
    return bool(cancel())


# ----------------------------------------------------------------------------- run
def run(system: System, until: Optional[float] = None,
        output: Union[str, Path, None, bool] = None,
        on_progress: Optional[Callable[[Progress], None]] = None,
        cancel=None, progress_interval: float = 0.5, observer=None) -> RunResult:
    """Advance ``system`` to simulated time ``until`` (default: the scene's run.duration),
    recording to the HDF5 file ``output`` (a temporary file if None; no file if False).

    ``observer`` (:mod:`engine.stepping.observe`: a callable ``observer(frame)``, or an object with
    ``append(frame)`` and optionally ``begin(channels, static)``, e.g.
    :class:`engine.MemoryObserver`) receives every recorded frame in memory, the same
    frames the HDF5 recorder (itself one observer) writes.

    ``on_progress`` is called with a :class:`Progress` at most every ``progress_interval``
    seconds and at the end. ``cancel`` is a ``threading.Event`` (or any object with
    ``is_set()``, or a callable returning True) that stops the run within one chunk; the
    result then has status ``cancelled``. A numerical blow-up raises
    :class:`InstabilityError` (its ``result`` attribute holds the RunResult) after the frames
    recorded so far are safely closed in the file.
    """
    sc = system.scene
    until = sc.run.duration if until is None else float(until)
    dt = system.dt
    t_start = system.time
    total_steps = max(0, int(round((until - t_start) / dt)))
    rec_every = max(1, int(round(sc.run.record_interval / dt)))
    if output is False:
        output = None
    else:
        if output is None:
            output = Path(tempfile.mkdtemp(prefix="brush-studio-")) / "result.h5"
        # a regular file only (never a device or a named pipe); its folders are created
        output = check_output_file(output, "result file", parents=True)
    channels, static = run_channels(system)
    attrs = {"dt": dt, "dt_limited_by": system.dt_limited_by, "dt_stable": system.dt_stable,
             "brush_names": [b.name for b in system.brushes],
             "body_names": list(system.body_names), "stages": list(system.stages),
             "record_every_steps": rec_every}
    if system.prescribed_motions:
        attrs["prescribed_motions"] = list(system.prescribed_motions)
    import json as _json
    attrs = {k: (_json.dumps(v) if isinstance(v, (list, dict)) else v) for k, v in attrs.items()}
    stage_time0 = system.stage_time.copy()
    timed0 = system.acc[ACC_TIMED_STEPS]
    steps0 = system.steps
    wall0 = _time.perf_counter()
    record_wall = 0.0
    status = "completed"
    error: Optional[InstabilityError] = None
    frames = 0
    e_scale = 0.0
    balance0 = None
    last_progress = 0.0
    done = 0
    chunk_cap = 256
    below_since = None  # the stop condition's quantity has been below its value since
    observers = []
    recorder = None
    if output is not None:
        recorder = Recorder(output, sc.to_json(), channels, static, attrs,
                            flush_every=None, commit_seconds=RUN_COMMIT_SECONDS)
        observers.append(recorder.append)
    begin, append = observer_calls(observer)
    if begin is not None:
        begin(channels, static)
    if append is not None:
        observers.append(append)
    # numba compiles (a cold cache: minutes) are timed apart and left out of the speed and
    # the stage times (they made a first run's bristle_body stage 116 s against 29 s warm)
    clock = CompileClock().__enter__()
    try:
        def record():
            nonlocal frames, record_wall, e_scale, balance0
            r0, compiled0 = _time.perf_counter(), clock.seconds
            fr = run_frame(system, channels)
            for append_frame in observers:
                append_frame(fr)
            frames += 1
            record_wall += _time.perf_counter() - r0 - (clock.seconds - compiled0)
            if "energy/total" in fr and system.flags.track_energy:
                bal = fr["energy/total"] + fr["energy/dissipated"] - fr["energy/external_work"]
                e_scale = max(e_scale, *(abs(fr[f"energy/{k}"]) for k in (
                    "kinetic", "bond", "contact", "gravity", "dissipated", "external_work")))
                if balance0 is None:
                    balance0 = bal
                elif (e_scale > ENERGY_FLOOR
                      and abs(bal - balance0) > ENERGY_BALANCE_LIMIT * e_scale):
                    raise InstabilityError(
                        "energy balance", "the whole scene", system.time,
                        f"total + dissipated - external work drifted by {bal - balance0:.3g} J "
                        f"(largest energy {e_scale:.3g} J): " + (dt_cause(system) or
                        f"lower run.dt_safety (now {sc.run.dt_safety:g})."))
            return fr

        with clock.block():  # zero steps: compiles the step loop or loads it from the cache
            try:  # (and, at t = 0, evaluates the initial forces: the start may already fail)
                _advance(system, 0)
            except InstabilityError:
                if system.steps == 0:  # the initial state is the frame the file keeps
                    record()
                raise
        if system.steps == 0 or total_steps == 0:
            if system.flags.track_energy and system.bonds.i.shape[0]:
                _refresh_forces(system)
            record()
        while done < total_steps:
            if _is_cancelled(cancel):
                status = "cancelled"
                break
            to_record = rec_every - ((system.steps - steps0) % rec_every)
            n = min(to_record, total_steps - done, chunk_cap)
            c0 = _time.perf_counter()
            did = _advance(system, n)
            elapsed = _time.perf_counter() - c0
            done += did
            if did < n:  # a neighbour list grew: go on
                continue
            # aim for chunks of ~0.05-0.2 s of wall time
            if elapsed < 0.05 and did == n:
                chunk_cap = min(chunk_cap * 2, 1 << 20)
            elif elapsed > 0.2:
                chunk_cap = max(16, chunk_cap // 2)
            if (system.steps - steps0) % rec_every == 0 or done == total_steps:
                record()
                stop = sc.run.stop
                if stop is not None and system.time >= stop.min_time:
                    if stop.quantity == "kinetic_energy":
                        val = energies(system)["kinetic"]
                    else:
                        k = system.body_names.index(stop.body)
                        val = float(np.linalg.norm(system.bodies.w[k]))
                    if val >= stop.value:
                        below_since = None
                    else:
                        if below_since is None:
                            below_since = system.time
                        if system.time - below_since >= stop.hold * (1 - 1e-9):
                            status = "stopped"
                            break
            now = _time.perf_counter()
            if on_progress is not None and (now - last_progress >= progress_interval
                                            or done == total_steps):
                last_progress = now
                on_progress(_progress(system, until, done, total_steps,
                                      now - wall0 - clock.seconds))
    except InstabilityError as exc:
        status = "failed"
        error = exc
    except BaseException as exc:  # keep the file consistent whatever happened
        clock.__exit__()
        summary = _summary(system, status="failed", wall=_time.perf_counter() - wall0,
                           steps=system.steps - steps0, stage_time0=stage_time0,
                           timed0=timed0, record_wall=record_wall, frames=frames,
                           compile_wall=clock.seconds)
        if recorder is not None:
            recorder.close("failed", summary, {"message": f"{type(exc).__name__}: {exc}"})
        raise
    clock.__exit__()
    wall = _time.perf_counter() - wall0
    summary = _summary(system, status=status, wall=wall, steps=system.steps - steps0,
                       stage_time0=stage_time0, timed0=timed0, record_wall=record_wall,
                       frames=frames, compile_wall=clock.seconds)
    err_dict = error.as_dict() if error is not None else None
    if err_dict:
        summary["error"] = err_dict
    if recorder is not None:
        recorder.close(status, summary, err_dict)
    if on_progress is not None and status != "completed":
        on_progress(_progress(system, until, done, total_steps, wall - clock.seconds))
    result = RunResult(status=status, summary=summary, path=output, error=err_dict,
                       frames=frames)
    if error is not None:
        error.result = result
        raise error
    return result


def _advance(system: System, n: int) -> int:
    """Up to ``n`` steps of the compiled loop; returns the steps done (fewer when a neighbour
    list had to grow, which it then did). Raises :class:`InstabilityError` on a blow-up."""
    code, did = advance(system.nodes, system.bonds, system.roots, system.bodies, system.pairs,
                        system.body_pairs, system.loads, system.tables, system.flags,
                        system.acc, system.err, system.stage_time, system.dt, n,
                        system.limits, system.mission, system.patches)
    if grow_on_overflow(system, code):
        return did
    if code != OK:
        raise instability(system, code)
    return did


def run_steps(system: System, n_steps: int) -> None:
    """Advance ``system`` by exactly ``n_steps`` steps, recording nothing: for protocols that
    read the live state between calls (:mod:`engine.stepping.quasistatic`). A blow-up raises
    :class:`InstabilityError`, as in :func:`run`."""
    done = 0
    while done < n_steps:
        done += _advance(system, n_steps - done)


def _refresh_forces(system: System) -> None:
    """Evaluate bond energies of the initial state (no time advance)."""
    from engine.kernels.bonds import bond_forces
    nd, bn = system.nodes, system.bonds
    bond_forces(nd.x, nd.v, nd.q, nd.w, bn.i, bn.j, bn.kn, bn.ks, bn.kb, bn.ksb, bn.kt, bn.L0,
                bn.cn, bn.cs, bn.cb, bn.ct, bn.f, bn.ti, bn.tj, bn.energy, bn.diss, bn.bend,
                system.flags.bond_damping, True, system.dt)


def _progress(system, until, done, total, wall) -> Progress:
    sps = done / wall if wall > 0 else 0.0
    eta = (total - done) / sps if sps > 0 else math.inf
    return Progress(time=system.time, until=until, steps=done, total_steps=total,
                    wall_s=wall, steps_per_s=sps, eta_s=eta)



def _summary(system: System, status: str, wall: float, steps: int, stage_time0, timed0,
             record_wall: float, frames: int, compile_wall: float = 0.0) -> dict:
    spent = system.stage_time - stage_time0
    # the sampled stage times give the proportions; they are scaled to the measured wall
    # time of the compiled loop (the sampling clock itself would inflate tiny steps), which
    # is the run's wall time less recording and less compiling
    compute = max(wall - record_wall - compile_wall, 1e-12)
    total_sampled = float(spent.sum())
    scale = compute / total_sampled if total_sampled > 0 else 0.0
    stage_wall = {}
    for slot in timed_slots(system.stages):
        stage_wall[STAGES[slot]] = float(spent[slot] * scale)
    stage_wall["recording"] = record_wall
    # reduced brushes: their use, and where it lay outside the laws' fitted ranges
    from engine.assembly.patches import out_of_range_warnings, summary as patch_summary
    patch_rows = patch_summary(system)
    patch_warnings = out_of_range_warnings(patch_rows)
    return {
        "status": status,
        "dt": system.dt,
        "dt_limited_by": system.dt_limited_by,
        "dt_stable": system.dt_stable,
        "steps": int(steps),
        "time": system.time,
        "wall_s": wall,
        "compile_s": compile_wall,  # in wall_s, not in the speed nor the stages
        "steps_per_s": steps / compute if steps else 0.0,
        "node_steps_per_s": steps * system.n_nodes / compute if steps else 0.0,
        "n_nodes": system.n_nodes,
        "n_bristles": system.n_bristles,
        "n_bodies": len(system.body_names),
        "frames": frames,
        "stages": stage_wall,
        "assembled": list(system.stages),
        "stage_timing": (f"proportions sampled every {system.flags.time_every} steps, scaled "
                         f"to the wall time outside recording"),
        "neighbour_rebuilds": int(system.acc[ACC_REBUILDS]),
        "max_overlap_ratio": float(system.acc[ACC_MAX_OVERLAP]),
        "warnings": list(system.warnings) + patch_warnings,
        **({"patches": patch_rows} if patch_rows else {}),
    }
