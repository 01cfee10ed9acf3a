"""The wedge study (seed 4.2): force against penetration depth, loading and unloading.

    brush-studio study wedge --preset static_presets/wedge_60.json -o DIR
    brush-studio study wedge --angles 30,45,60,75 -o DIR

One run per scene (per wedge angle), each a Dask task (:func:`wedge_cycle`). A run replaces
the wedge's scripted motion by the seed's hold-until-steady protocol (seed 4.2, fig. 4.11):

1. the brush settles under the scene's loads with the wedge at rest, until the vertical root
   force is steady: that force is the zero of the scale (the bristles' weight);
2. the wedge moves one step (1 mm) along the profile's direction with the parabolic velocity
   ``v(t) = k t (t_d - t)``, ``k = a_m / t_d``, ``t_d = sqrt(6 s / a_m)`` (seed eq. 4.3),
   through ``engine.prescribe_motion`` (times relative to now, from the current pose);
3. it holds, window after window (``window`` seconds, ``frames_per_window`` frames each),
   until the standard deviation of the total vertical root force over one window is below
   ``max(threshold, rel_threshold * |force|)``, or until ``max_hold`` (then the record is
   flagged ``converged = False`` and counted in ``hold_limit_hits``);
4. it records the window's mean force minus the zero (``force_N``) at the depth reached;
5. down to the full depth (``n_steps`` steps), then the same steps back out (phase
   ``unload``) to depth 0.

Each ``engine.run`` call writes its own HDF5: the run writes these chunks into a scratch
folder (``runs/.<run_id>.scratch/``), reads what it needs from each and deletes it, and keeps
one HDF5 per run (``runs/<run_id>.h5``, layout in docs/studies.md): the force-depth table,
the root force and wedge position and force against time for the whole cycle, and the node
positions at every recorded equilibrium. A run that fails still writes that file with the
records so far (attribute ``status = "failed"``) and keeps the chunk that failed.

No mass or density scaling is used: the equilibria are reached with the scene's own
Cundall local damping (``environment.local_damping``, 0.3 in the wedge presets), which
only acts on moving nodes and so leaves a static equilibrium's forces unchanged; the study's
output states the damping and ``a_m`` it used.
"""
from __future__ import annotations

import copy
import csv
import json
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from . import api
from .api import ExecutionOptions, StudyResult
from .runner import (RunSpec, add_common_options, check_common_options, failures_text,
                     jsonable, report_progress, run_many_from_args, write_json_atomic,
                     write_outcomes)
from ..exit_codes import EXIT_BAD_INPUT, EXIT_CANCELLED, EXIT_FAILED, EXIT_OK

TASK = "studio.studies.wedge:wedge_cycle"
PROTOCOL_DEFAULTS = {
    "method": "quasi_static",  # or "dynamic": the seed's hold-until-steady windows
    "window": 0.05,            # s, one hold window (dynamic)
    "frames_per_window": 10,   # force samples per window (dynamic)
    "threshold": 2e-5,         # N, absolute tolerance (std, or out-of-balance force)
    "rel_threshold": 0.005,    # fraction of the current force change
    "max_hold": 1.0,           # s, longest hold after one step
    # quasi-static only (docs/studies.md): numerical settings that leave equilibria unchanged
    "qs_local_damping": 0.5,
    "qs_inertia_scaling": "equalize",
    "qs_kinetic_damping": True,   # stop every node when the kinetic energy has peaked
    "qs_dt_safety": 0.95,         # run.dt_safety (fraction of the stability bound)
    "qs_checks_per_period": 100,  # balance checks per period of the slowest bristle
    "qs_max_acceleration": 4.0,  # m/s^2, a_m of each increment's parabolic move
    "qs_increments": 1,          # increments per step, each settled and its slip committed
}
METHODS = ("quasi_static", "dynamic")
METHOD_NOTES = {
    "quasi_static": "slip committed per increment (frozen Coulomb trial within it), fast "
                    "moves, local and kinetic damping, equalized inertia, dt at 0.95 of the "
                    "bound; holds end on the out-of-balance force and kinetic energy. On the "
                    "60 deg wedge (5 nodes, 0-10 mm) it matches the dynamic method at a_m "
                    "0.1 m/s^2 within 1.1 % from 2 mm on, closer than the dynamic method at "
                    "a_m 0.4 is to it (docs/studies.md; "
                    "tests/studies/test_wedge_quasistatic.py)",
    "dynamic": "the seed's protocol in physical time under the scene's damping; its curve "
               "depends on a_m (docs/studies.md)"}
DEFAULT_PRESET = "wedge_60"


class StudyInputError(ValueError):
    """A bad study input (a scene without the wedge, a bad option value)."""


# ----------------------------------------------------------------------------- scenes
def load_scene_dict(ref: str) -> tuple[dict, str]:
    """A scene as a JSON dict from a file path or a preset name, and a label for it."""
    import engine

    path = Path(ref)
    if not path.exists():
        try:
            from studio.presets import preset_path

            path = preset_path(ref)
        except (ImportError, KeyError):
            raise StudyInputError(f"{ref}: no such scene file or preset") from None
    scene = engine.load_scene(path)  # SceneError names bad fields
    return json.loads(scene.to_json()), path.stem


def default_scene_dict() -> tuple[dict, str]:
    """The wedge_60 preset, or the embedded demo scene (same brush, 60 deg wedge) if the
    presets are not there."""
    try:
        return load_scene_dict(DEFAULT_PRESET)
    except StudyInputError:
        from importlib.resources import files

        return json.loads((files("studio") / "data" / "demo_scene.json").read_text()), "demo"


def find_body(scene: dict, body: str) -> dict:
    for b in scene.get("bodies", []):
        if b.get("name") == body:
            return b
    names = [b.get("name") for b in scene.get("bodies", [])]
    raise StudyInputError(f"the scene has no body {body!r} (bodies: {names})")


def wedge_angle_deg(scene: dict, body: str = "wedge") -> Optional[float]:
    shape = find_body(scene, body).get("shape", {})
    return math.degrees(shape["angle"]) if shape.get("type") == "wedge" else None


def set_wedge_angle(scene: dict, angle_deg: float, body: str = "wedge") -> dict:
    """A copy of ``scene`` with the wedge's included angle set (degrees at this edge)."""
    scene = copy.deepcopy(scene)
    shape = find_body(scene, body)["shape"]
    if shape.get("type") != "wedge":
        raise StudyInputError(f"body {body!r} is a {shape.get('type')}, not a wedge")
    shape["angle"] = math.radians(angle_deg)
    return scene


def make_protocol(scene: dict, *, body: str = "wedge", brush: Optional[str] = None,
                  depth: Optional[float] = None, step: Optional[float] = None,
                  max_acceleration: Optional[float] = None, unload: bool = True,
                  **overrides) -> dict:
    """The hold-until-steady protocol for ``scene``: step, a_m, direction and number of steps
    from the wedge's stepped_parabolic profile (full depth = n_steps * step) unless given;
    window, thresholds and maximum hold from :data:`PROTOCOL_DEFAULTS` unless given."""
    b = find_body(scene, body)
    if b.get("motion", {}).get("type") != "kinematic":
        raise StudyInputError(f"body {body!r} must be kinematic (it is "
                              f"{b.get('motion', {}).get('type', 'fixed')})")
    prof = b["motion"].get("profile", {})
    sp = prof if prof.get("kind") == "stepped_parabolic" else {}
    step = float(step if step is not None else sp.get("step", 0.001))
    a_m = float(max_acceleration if max_acceleration is not None
                else sp.get("max_acceleration", 0.4))
    if depth is None:
        if not sp:
            raise StudyInputError("give the depth: the wedge's profile is not "
                                  "stepped_parabolic")
        depth = sp["n_steps"] * step
    n_steps = int(round(depth / step))
    if n_steps < 1 or abs(n_steps * step - depth) > 1e-9:
        raise StudyInputError(f"depth {depth:g} m is not a whole number (>= 1) of "
                              f"{step:g} m steps")
    if not (a_m > 0 and step > 0):
        raise StudyInputError("step and max_acceleration must be > 0")
    direction = [float(x) for x in sp.get("direction", [0.0, 0.0, -1.0])]
    norm = math.sqrt(sum(x * x for x in direction))
    brushes = [x["name"] for x in scene.get("brushes", [])]
    if brush is None:
        if not brushes:
            raise StudyInputError("the scene has no brush")
        brush = brushes[0]
    elif brush not in brushes:
        raise StudyInputError(f"the scene has no brush {brush!r} (brushes: {brushes})")
    proto = dict(PROTOCOL_DEFAULTS)
    unknown = set(overrides) - set(PROTOCOL_DEFAULTS)
    if unknown:
        raise StudyInputError(f"unknown protocol settings {sorted(unknown)}")
    proto.update({k: v for k, v in overrides.items() if v is not None})
    if proto["method"] not in METHODS:
        raise StudyInputError(f"method = {proto['method']!r}: one of {', '.join(METHODS)}")
    for k in ("window", "threshold", "max_hold", "qs_checks_per_period",
              "qs_max_acceleration", "qs_increments"):
        if not proto[k] > 0:
            raise StudyInputError(f"{k} = {proto[k]}: must be > 0")
    if not 0 <= proto["qs_local_damping"] < 1:
        raise StudyInputError(f"qs_local_damping = {proto['qs_local_damping']}: in [0, 1)")
    if not 0 < proto["qs_dt_safety"] <= 1:
        raise StudyInputError(f"qs_dt_safety = {proto['qs_dt_safety']}: in (0, 1]")
    if proto["qs_inertia_scaling"] not in ("none", "equalize"):
        raise StudyInputError("qs_inertia_scaling must be 'none' or 'equalize'")
    if int(proto["qs_increments"]) != proto["qs_increments"]:
        raise StudyInputError("qs_increments must be a whole number")
    if proto["frames_per_window"] < 3:
        raise StudyInputError("frames_per_window must be >= 3 (a standard deviation)")
    proto.update(body=body, brush=brush, step=step, max_acceleration=a_m,
                 n_steps=n_steps, direction=[x / norm for x in direction],
                 unload=bool(unload))
    return proto


def step_duration(step: float, max_acceleration: float) -> float:
    """t_d = sqrt(6 s / a_m), seed eq. 4.3."""
    return math.sqrt(6.0 * step / max_acceleration)


# ----------------------------------------------------------------------------- the task
def wedge_cycle(scene, h5_path: Path, params: dict) -> dict:
    """Dask task: the hold-until-steady loading/unloading cycle of one scene (see the module
    docstring). ``params["protocol"]`` is :func:`make_protocol`'s dict. Writes ``h5_path``;
    returns depths, forces, phases, convergence flags and costs."""
    import numpy as np

    import engine

    p = params["protocol"]
    body, brush = p["body"], p["brush"]
    direction = np.asarray(p["direction"], float)
    step, a_m, n_steps = p["step"], p["max_acceleration"], int(p["n_steps"])
    window, fpw = float(p["window"]), int(p["frames_per_window"])
    t_d = step_duration(step, a_m)

    quasi_static = p.get("method", "dynamic") == "quasi_static"
    d = json.loads(scene.to_json())
    d["run"].update(stop=None, duration=1e4, record_interval=window / fpw,
                    channels=["nodes", "bodies", "root_force"])
    if quasi_static:
        d["environment"].update(
            local_damping=max(p["qs_local_damping"], d["environment"].get("local_damping", 0)),
            inertia_scaling=p["qs_inertia_scaling"])
        d["run"]["dt_safety"] = p.get("qs_dt_safety", d["run"].get("dt_safety", 0.5))
    system = engine.build(engine.parse_scene(d))
    scratch = h5_path.parent / f".{h5_path.stem}.scratch"
    shutil.rmtree(scratch, ignore_errors=True)
    scratch.mkdir(parents=True)

    series = {"time": [], "root_force_z": [], "wedge_depth": [], "wedge_force_z": []}
    rec = {k: [] for k in ("depth_m", "force_N", "phase", "root_force_z_N", "std_N",
                           "out_of_balance_N", "kinetic_J", "hold_s", "converged", "time_s",
                           "wedge_force_z_N", "measured_depth_m")}
    snapshots: list = []
    costs = {"steps": 0, "engine_wall_s": 0.0, "chunks": 0}
    state = {"p0": None, "last_nodes": None, "last_chunk": None}
    n_stages = 1 + n_steps * (2 if p["unload"] else 1)
    t_wall0, t_cpu0 = time.perf_counter(), time.process_time()
    status, error = "completed", None

    def advance(duration: float):
        api.check_cancel()  # a cancel of the study running this in-process stops here
        path = scratch / f"chunk{costs['chunks']:05d}.h5"
        state["last_chunk"] = path
        res = engine.run(system, until=system.time + duration, output=path)
        costs["chunks"] += 1
        costs["steps"] += int(res.summary.get("steps", 0))
        costs["engine_wall_s"] += float(res.summary.get("wall_s", 0.0))
        with engine.open_result(path) as r:
            t = r.time
            fz = r.series(f"brushes/{brush}/root_force")[:, 2]
            pos = r.series(f"bodies/{body}/position")
            wf = r.series(f"bodies/{body}/contact_force")[:, 2]
            state["last_nodes"] = r.frame("nodes/positions", -1)
        if state["p0"] is None:
            state["p0"] = pos[0].copy()
        depth = (pos - state["p0"]) @ direction
        series["time"].append(t)
        series["root_force_z"].append(fz)
        series["wedge_depth"].append(depth)
        series["wedge_force_z"].append(wf)
        path.unlink()
        return fz, depth, wf

    def hold(stage: int, zero: Optional[float]):
        held = 0.0
        while True:
            fz, depth, wf = advance(window)
            held += window
            mean, std = float(np.mean(fz)), float(np.std(fz))
            thr = p["threshold"] if zero is None else \
                max(p["threshold"], p["rel_threshold"] * abs(mean - zero))
            converged = std <= thr
            report_progress(min((stage + held / p["max_hold"]) / n_stages, 1.0))
            if converged or held >= p["max_hold"] - 1e-9:
                return dict(mean=mean, std=std, held=held, converged=converged,
                            depth=float(depth[-1]), wedge_force=float(np.mean(wf)))

    if quasi_static:
        advance, hold = _quasi_static_steps(system, p, brush, body, direction, series, costs,
                                            state, n_stages)

    def record(target_depth: float, phase: str, h: dict, zero: float):
        rec["depth_m"].append(target_depth)
        rec["force_N"].append(h["mean"] - zero)
        rec["phase"].append(phase)
        rec["root_force_z_N"].append(h["mean"])
        rec["std_N"].append(h["std"])
        rec["out_of_balance_N"].append(h.get("out_of_balance", float("nan")))
        rec["kinetic_J"].append(h.get("kinetic", float("nan")))
        rec["hold_s"].append(h["held"])
        rec["converged"].append(h["converged"])
        rec["time_s"].append(system.time)
        rec["wedge_force_z_N"].append(h["wedge_force"])
        rec["measured_depth_m"].append(h["depth"])
        snapshots.append(state["last_nodes"])

    try:
        # the scene's own motion is replaced: at rest until the first step
        engine.prescribe_motion(system, body, {"kind": "constant",
                                               "velocity": [0.0, 0.0, 0.0],
                                               "duration": 1e-9}, after="hold")
        h = hold(0, None)
        zero = h["mean"]
        record(0.0, "load", h, zero)
        stage = 1
        moves = [(k, "load", 1.0) for k in range(1, n_steps + 1)]
        if p["unload"]:
            moves += [(k, "unload", -1.0) for k in range(n_steps - 1, -1, -1)]
        # the quasi-static method takes each step in ``qs_increments`` faster increments,
        # each settled (and its slip committed) before the next
        n_inc = int(p["qs_increments"]) if quasi_static else 1
        a_inc = p["qs_max_acceleration"] if quasi_static else a_m
        for k, phase, sign in moves:
            for j in range(n_inc):
                engine.prescribe_motion(system, body, {
                    "kind": "stepped_parabolic", "step": step / n_inc, "n_steps": 1,
                    "max_acceleration": a_inc, "direction": list(sign * direction)},
                    after="hold")
                advance(step_duration(step / n_inc, a_inc))
                if j < n_inc - 1:
                    hold(stage, zero)
            h = hold(stage, zero)
            record(k * step, phase, h, zero)
            stage += 1
    except engine.InstabilityError as exc:
        status, error = "failed", exc
        last = state["last_chunk"]
        if last is not None and last.exists():  # keep the chunk that failed, for a look
            os.replace(last, h5_path.with_name(h5_path.stem + ".failed_chunk.h5"))
    except BaseException as exc:
        status, error = "failed", exc
    finally:
        wall = time.perf_counter() - t_wall0
        _write_run_h5(h5_path, scene, params, p, rec, series, snapshots, costs, system,
                      status, str(error) if error else None, wall, t_d)
        shutil.rmtree(scratch, ignore_errors=True)
    if error is not None:
        raise error
    forces = rec["force_N"]
    return {"status": "completed", "depth_m": rec["depth_m"], "force_N": forces,
            "phase": rec["phase"], "converged": rec["converged"],
            "hold_limit_hits": int(sum(not c for c in rec["converged"])),
            "zero_force_N": zero, "peak_force_N": float(max(forces)),
            "wall_s": wall, "cpu_s": time.process_time() - t_cpu0,
            "engine_wall_s": costs["engine_wall_s"], "steps": costs["steps"],
            "sim_time_s": system.time, "dt": system.dt, "n_nodes": system.n_nodes,
            "step_duration_s": t_d,
            "local_damping": system.scene.environment.local_damping,
            "inertia_scaling": system.scene.environment.inertia_scaling,
            "method": p.get("method", "dynamic"),
            "max_out_of_balance_N": float(np.nanmax(rec["out_of_balance_N"]))
            if quasi_static else None,
            # an independent check of every record: at equilibrium the root force change
            # equals the bristles' push on the wedge (up to the zero's and the record's
            # out-of-balance, each below the tolerance)
            "max_equilibrium_gap_N": float(np.max(np.abs(np.subtract(
                rec["force_N"], rec["wedge_force_z_N"])))) if rec["force_N"] else None}


def _quasi_static_steps(system, p: dict, brush: str, body: str, direction, series: dict,
                        costs: dict, state: dict, n_stages: int):
    """``advance(duration)`` and ``hold(stage, zero)`` of the quasi-static method: the live
    state is read every ``check`` steps (about 1/``qs_checks_per_period`` of the slowest
    bristle's period) for the series, and a hold ends when the out-of-balance force and the
    kinetic energy are below the tolerance (:func:`engine.quasistatic.settle`)."""
    import numpy as np

    from engine.quasistatic import (commit_slip, freeze_slip, kinetic_tolerance_for,
                                    lowest_bristle_period, settle)
    from engine.observables import root_reactions
    from engine.run import run_steps

    dt = system.dt
    freeze_slip(system)
    k_body = system.body_names.index(body)
    check = max(1, int(lowest_bristle_period(system.scene) / p["qs_checks_per_period"] / dt))
    max_steps = max(1, int(round(p["max_hold"] / dt)))

    def sample(system, _balance=None):
        fz = float(root_reactions(system)[brush][0][2])
        pos = system.bodies.pos[k_body]
        if state["p0"] is None:
            state["p0"] = pos.copy()
        series["time"].append(np.array([system.time]))
        series["root_force_z"].append(np.array([fz]))
        series["wedge_depth"].append(np.array([(pos - state["p0"]) @ direction]))
        series["wedge_force_z"].append(np.array([system.bodies.f[k_body, 2]]))
        return fz

    def timed_steps(n: int) -> None:
        c0 = time.perf_counter()
        run_steps(system, n)
        costs["engine_wall_s"] += time.perf_counter() - c0
        costs["steps"] += n

    def advance(duration: float):
        n = int(round(duration / dt))
        while n > 0:
            timed_steps(min(check, n))
            n -= check
            sample(system)

    def hold(stage: int, zero: Optional[float]):
        if state["p0"] is None:
            sample(system)

        def force_tolerance(system):
            if zero is None:
                return p["threshold"]
            # settle calls sample (on_check) first: the root force of this very state
            fz = float(series["root_force_z"][-1][-1])
            return max(p["threshold"], p["rel_threshold"] * abs(fz - zero))

        steps0, c0 = costs["steps"], time.perf_counter()
        res = settle(system, force_tolerance=force_tolerance,
                     kinetic_tolerance=lambda f: kinetic_tolerance_for(system.scene, f),
                     max_steps=max_steps, check_every=check, on_check=sample,
                     kinetic_damping=bool(p.get("qs_kinetic_damping", False)))
        commit_slip(system)
        costs["engine_wall_s"] += time.perf_counter() - c0
        costs["steps"] = steps0 + res.steps + 1
        report_progress(min((stage + 1) / n_stages, 1.0))
        state["last_nodes"] = system.nodes.x.copy()
        return dict(mean=float(root_reactions(system)[brush][0][2]), std=float("nan"),
                    held=res.steps * dt, converged=res.converged,
                    depth=float(series["wedge_depth"][-1][-1]),
                    wedge_force=float(system.bodies.f[k_body, 2]),
                    out_of_balance=res.balance.out_of_balance, kinetic=res.balance.kinetic)

    return advance, hold


def _write_run_h5(path: Path, scene, params, p, rec, series, snapshots, costs, system,
                  status, error, wall, t_d) -> None:
    """The run's HDF5 (docs/studies.md), written to a temporary name and renamed."""
    import h5py
    import numpy as np

    tmp = path.with_name(f".{path.name}.tmp")
    with h5py.File(tmp, "w") as f:
        f.attrs["format"] = "brush-studio-study-run"
        f.attrs["study"] = "wedge"
        f.attrs["status"] = status
        if error:
            f.attrs["error"] = error
        f.attrs["scene"] = scene.to_json()
        f.attrs["params"] = json.dumps(jsonable(params))
        f.attrs["protocol"] = json.dumps(jsonable(p))
        f.attrs["wall_s"] = wall
        f.attrs["engine_wall_s"] = costs["engine_wall_s"]
        f.attrs["steps"] = costs["steps"]
        f.attrs["dt"] = system.dt
        f.attrs["dt_limited_by"] = str(system.dt_limited_by)
        f.attrs["n_nodes"] = system.n_nodes
        f.attrs["step_duration_s"] = t_d
        g = f.create_group("force_depth")
        for k, v in rec.items():
            if k == "phase":
                g.create_dataset(k, data=np.array(v, dtype="S8"))
            else:
                g.create_dataset(k, data=np.asarray(v, dtype=bool if k == "converged"
                                                    else float))
        s = f.create_group("series")
        for k, chunks in series.items():
            s.create_dataset(k, data=np.concatenate(chunks) if chunks else np.zeros(0))
        if snapshots:
            f.create_dataset("equilibria/nodes_positions", data=np.stack(snapshots),
                             compression="gzip")
    os.replace(tmp, path)


def read_run_h5(path) -> dict:
    """The force-depth table of a wedge run's HDF5 as a dict of arrays (``phase`` as str),
    plus ``status`` and ``protocol``."""
    import h5py
    import numpy as np

    with h5py.File(path, "r") as f:
        out = {k: np.asarray(v) for k, v in f["force_depth"].items()}
        out["phase"] = np.array([x.decode() for x in out["phase"]])
        out["status"] = f.attrs["status"]
        out["protocol"] = json.loads(f.attrs["protocol"])
    return out


# ----------------------------------------------------------------------------- outputs
def write_force_depth_csv(path: Path, depths, forces, phases, extra: Optional[dict] = None
                          ) -> None:
    """``depth_m,force_N,phase`` (then the ``extra`` columns, each a list)."""
    extra = extra or {}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["depth_m", "force_N", "phase", *extra])
        for i, (dd, ff, ph) in enumerate(zip(depths, forces, phases)):
            w.writerow([f"{dd:.6g}", f"{ff:.9g}", ph, *(extra[k][i] for k in extra)])
    os.replace(tmp, path)


def curve_checks(depths, forces, phases) -> dict:
    """Seed 4.2.2's observations for one loading/unloading curve: non-linear growth (the
    secant stiffness F/d at full depth exceeds that at the first step), unloading below
    loading (mean over the depths of both), peak force."""
    load = {d: f for d, f, ph in zip(depths, forces, phases) if ph == "load"}
    unload = {d: f for d, f, ph in zip(depths, forces, phases) if ph == "unload"}
    ds = sorted(d for d in load if d > 0)
    out = {"peak_force_N": max(load.values()) if load else float("nan")}
    if len(ds) >= 2:
        out["secant_first_N_per_m"] = load[ds[0]] / ds[0]
        out["secant_full_N_per_m"] = load[ds[-1]] / ds[-1]
        out["stiffening"] = out["secant_full_N_per_m"] > out["secant_first_N_per_m"]
    common = [d for d in ds if d in unload and d != ds[-1]]
    if common:
        out["mean_unload_minus_load_N"] = sum(unload[d] - load[d] for d in common) / len(common)
        out["unload_below_load"] = out["mean_unload_minus_load_N"] < 0
    return out


def _parse_angles(text: str) -> list[float]:
    try:
        angles = [float(a) for a in text.split(",") if a.strip()]
    except ValueError:
        raise StudyInputError(f"--angles {text!r}: expected degrees like 30,45,60,75") from None
    if not angles or any(not 0 < a < 180 for a in angles):
        raise StudyInputError(f"--angles {text!r}: each angle in (0, 180) degrees")
    return angles


def _safe_id(text: str) -> str:
    s = "".join(c if c.isalnum() or c in "._-" else "_" for c in text).strip("._-")
    return s or "run"


def resolve_scenes(presets: list[str], angles: Optional[str], body: str = "wedge"
                   ) -> list[tuple[str, dict, str]]:
    """``[(run_id, scene dict, where it came from)]`` for the command's options: each
    ``--preset``; or for each of ``--angles`` the preset ``wedge_<angle>`` (or, with one
    ``--preset``, that scene with the angle changed); or the default preset."""
    out = []
    if angles:
        alist = _parse_angles(angles)
        if len(presets) > 1:
            raise StudyInputError("--angles takes at most one --preset (the base scene)")
        for a in alist:
            if presets:
                base, label = load_scene_dict(presets[0])
                out.append((f"{_safe_id(label)}_at_{a:g}deg", set_wedge_angle(base, a, body),
                            f"{presets[0]} with the wedge angle set to {a:g} deg"))
            else:
                try:
                    scene, label = load_scene_dict(f"wedge_{a:g}")
                    out.append((_safe_id(label), scene, f"preset wedge_{a:g}"))
                except StudyInputError:
                    base, label = default_scene_dict()
                    out.append((f"{_safe_id(label)}_at_{a:g}deg",
                                set_wedge_angle(base, a, body),
                                f"{label} with the wedge angle set to {a:g} deg"))
    elif presets:
        for ref in presets:
            scene, label = load_scene_dict(ref)
            out.append((_safe_id(label), scene, ref))
    else:
        scene, label = default_scene_dict()
        out.append((_safe_id(label), scene, f"default ({label})"))
    seen: dict = {}
    unique = []
    for rid, scene, src in out:
        seen[rid] = seen.get(rid, 0) + 1
        unique.append((rid if seen[rid] == 1 else f"{rid}_{seen[rid]}", scene, src))
    return unique


def apply_resolution(scene: dict, n_nodes: Optional[int]) -> dict:
    if n_nodes is None:
        return scene
    scene = copy.deepcopy(scene)
    for b in scene.get("brushes", []):
        b["n_nodes"] = int(n_nodes)
    return scene


# ----------------------------------------------------------------------------- options
@dataclass
class ProtocolOptions(ExecutionOptions):
    """The hold-until-steady protocol of the wedge-based studies (``None``: the scene's
    wedge profile, or :data:`PROTOCOL_DEFAULTS`; the ``--depth-mm`` ... options)."""

    depth_mm: Optional[float] = None            # full depth, mm
    nodes: Optional[int] = None                 # nodes per bristle
    max_acceleration: Optional[float] = None    # a_m of each step, m/s^2
    window: Optional[float] = None              # hold window, s
    threshold: Optional[float] = None           # steady when the force's std is below, N
    rel_threshold: Optional[float] = None       # ... or this fraction of the force
    max_hold: Optional[float] = None            # longest hold after a step, s
    no_unload: bool = False                     # loading only
    method: Optional[str] = None                # "quasi-static" (default) | "dynamic"
    qs_max_acceleration: Optional[float] = None
    qs_increments: Optional[int] = None


@dataclass
class Options(ProtocolOptions):
    """``brush-studio study wedge``: the scenes (preset names or files; default wedge_60)
    and wedge angles (``"30,45,60"``)."""

    preset: list = field(default_factory=list)
    angles: Optional[str] = None
    check_increment: bool = False  # rerun each scene with halved increments and compare


INCREMENT_TOLERANCE = 0.02  # the increment check's pass mark: 2 % between successive halvings
INCREMENT_CHECK_SUFFIX = "_half_increment"


def add_protocol_options(p) -> None:
    """Options of the hold-until-steady protocol (shared by the wedge-based studies)."""
    g = p.add_argument_group("protocol (defaults: the scene's wedge profile; docs/studies.md)")
    g.add_argument("--depth-mm", type=float, metavar="MM",
                   help="full depth in mm (default: n_steps x step of the wedge's profile)")
    g.add_argument("--nodes", type=int, metavar="N",
                   help="nodes per bristle (default: the scene's)")
    g.add_argument("--max-acceleration", type=float, metavar="A",
                   help="a_m of each step, m/s^2 (default: the profile's)")
    g.add_argument("--window", type=float, metavar="S",
                   help=f"hold window, s (default {PROTOCOL_DEFAULTS['window']})")
    g.add_argument("--threshold", type=float, metavar="N",
                   help=f"std of the root force that counts as steady, N (default "
                        f"{PROTOCOL_DEFAULTS['threshold']:g}; or --rel-threshold times the "
                        f"force, whichever is larger)")
    g.add_argument("--rel-threshold", type=float, metavar="F",
                   help=f"(default {PROTOCOL_DEFAULTS['rel_threshold']:g})")
    g.add_argument("--max-hold", type=float, metavar="S",
                   help=f"longest hold after a step, s (default {PROTOCOL_DEFAULTS['max_hold']})")
    g.add_argument("--no-unload", action="store_true", help="loading only")
    g.add_argument("--method", choices=[m.replace("_", "-") for m in METHODS],
                   help="quasi-static (default): each hold ends when the out-of-balance force "
                        "and kinetic energy are below the tolerance, with strong local damping "
                        "and scaled rotational inertia; dynamic: the seed's protocol, windows "
                        "of the scene's own dynamics until the force's spread is small")
    g.add_argument("--qs-max-acceleration", type=float, metavar="A",
                   help=f"quasi-static: a_m of each increment's move, m/s^2 (default "
                        f"{PROTOCOL_DEFAULTS['qs_max_acceleration']:g})")
    g.add_argument("--qs-increments", type=int, metavar="N",
                   help=f"quasi-static: increments per step, each settled and its slip "
                        f"committed (default {PROTOCOL_DEFAULTS['qs_increments']})")


def protocol_from_options(scene: dict, options: "ProtocolOptions") -> dict:
    """The protocol of ``scene`` for the options of a wedge-based study."""
    o = options
    if o.nodes is not None and not 2 <= o.nodes <= 4096:
        raise StudyInputError(f"--nodes = {o.nodes}: must be in 2 .. 4096")
    return make_protocol(scene, depth=None if o.depth_mm is None else o.depth_mm * 1e-3,
                         max_acceleration=o.max_acceleration, unload=not o.no_unload,
                         window=o.window, threshold=o.threshold,
                         rel_threshold=o.rel_threshold, max_hold=o.max_hold,
                         method=None if o.method is None else o.method.replace("-", "_"),
                         qs_max_acceleration=o.qs_max_acceleration,
                         qs_increments=o.qs_increments)


def _err(msg: str) -> None:
    print(msg, file=sys.stderr)


def validate_scenes(scenes: list[dict]) -> Optional[str]:
    """Parse every scene before anything runs: a message naming the bad fields, or None."""
    import engine

    for scene in scenes:
        try:
            engine.parse_scene(scene)
        except engine.SceneError as exc:
            return "invalid scene: " + "; ".join(str(p) for p in exc.problems)
    return None


# ----------------------------------------------------------------------------- command
def add_parser(sub) -> None:
    p = sub.add_parser(
        "wedge", help="force against depth of a wedge pressed into the brush (seed 4.2)",
        description="Drive the wedge down in steps with the seed's parabolic velocity, hold "
                    "after each until the total vertical root force is steady, record it; to "
                    "full depth and back out. Writes DIR/force_depth.csv (depth_m,force_N,"
                    "phase), DIR/force_depth.png, DIR/wedge_records.csv, DIR/study.json and "
                    "one HDF5 per run in DIR/runs/.")
    p.add_argument("--preset", action="append", default=[], metavar="SCENE",
                   help="scene file or preset name (repeat for several; default wedge_60)")
    p.add_argument("--angles", metavar="DEG,...",
                   help="wedge angles in degrees, e.g. 30,45,60,75: the presets wedge_<angle> "
                        "(or one --preset with its angle changed)")
    p.add_argument("--check-increment", action="store_true",
                   help="quasi-static: run every scene again with each step in twice as many "
                        "increments and report the largest change of the recorded force "
                        f"(study.json increment_check; converged within "
                        f"{INCREMENT_TOLERANCE * 100:g} %%?); about 1.8x the CPU")
    add_protocol_options(p)
    add_common_options(p)
    p.set_defaults(func=cmd_wedge)


def run(options: Options, out_dir, *, progress: Optional[api.ProgressFn] = None,
        cancel=None) -> StudyResult:
    """The wedge study of ``options`` into ``out_dir`` (see the module docstring)."""
    return api.run_body("wedge", _run_study, options, out_dir, progress, cancel)


def cmd_wedge(args) -> int:
    return run(Options.from_args(args), args.output).exit_code


def _run_study(options: Options, out: Path) -> int:
    import engine

    msg = check_common_options(options)
    if msg:
        _err(msg)
        return EXIT_BAD_INPUT
    try:
        scenes = resolve_scenes(options.preset, options.angles)
        specs = []
        for rid, scene, src in scenes:
            scene = apply_resolution(scene, options.nodes)
            proto = protocol_from_options(scene, options)
            angle = wedge_angle_deg(scene)
            specs.append(RunSpec(rid, scene, {"angle_deg": angle, "source": src,
                                              "n_nodes": [b["n_nodes"] for b in
                                                          scene["brushes"]],
                                              "protocol": proto}, TASK))
    except engine.SceneError as exc:
        _err("invalid scene: " + "; ".join(str(p) for p in exc.problems))
        return EXIT_BAD_INPUT
    except StudyInputError as exc:
        _err(str(exc))
        return EXIT_BAD_INPUT
    bad = validate_scenes([s.scene for s in specs])
    if bad:
        _err(bad)
        return EXIT_BAD_INPUT
    checks = []
    if options.check_increment:
        for s in specs:
            pr = s.params["protocol"]
            if pr["method"] != "quasi_static":
                _err("--check-increment needs the quasi-static method: the dynamic method's "
                     "steps are not split into increments")
                return EXIT_BAD_INPUT
            finer = dict(pr, qs_increments=2 * int(pr["qs_increments"]))
            checks.append(RunSpec(s.run_id + INCREMENT_CHECK_SUFFIX, s.scene,
                                  dict(s.params, protocol=finer), TASK))
    for s in specs:
        pr = s.params["protocol"]
        print(f"{s.run_id}: {s.params['source']}; wedge {s.params['angle_deg']:g} deg, "
              f"{pr['n_steps']} x {pr['step'] * 1e3:g} mm steps (a_m {pr['max_acceleration']:g}"
              f" m/s^2, t_d {step_duration(pr['step'], pr['max_acceleration']) * 1e3:.1f} ms)"
              f"{' and back' if pr['unload'] else ''}, nodes/bristle {s.params['n_nodes']}")
    t0 = time.perf_counter()
    try:
        outcomes = run_many_from_args(specs + checks, out, options, desc="wedge runs")
    except KeyboardInterrupt:
        _err("cancelled: finished runs are kept; run the same command again to go on")
        return EXIT_CANCELLED
    wall = time.perf_counter() - t0
    return write_wedge_outputs(out, specs, outcomes[:len(specs)], wall,
                               increment_outcomes=outcomes[len(specs):])


def increment_check(coarse: dict, fine: dict, threshold: float) -> dict:
    """The recorded force of a run against the same run with halved increments: the largest
    relative change over records whose (finer) force is above ten times the absolute
    tolerance ``threshold`` (below it the tolerance itself dominates), and whether it is
    within :data:`INCREMENT_TOLERANCE`."""
    fine_at = {(round(d, 12), ph): f for d, f, ph in
               zip(fine["depth_m"], fine["force_N"], fine["phase"])}
    worst, at = 0.0, None
    for d, f, ph in zip(coarse["depth_m"], coarse["force_N"], coarse["phase"]):
        g = fine_at.get((round(d, 12), ph))
        if g is None or abs(g) <= 10.0 * threshold:
            continue
        rel = abs(f - g) / abs(g)
        if rel > worst:
            worst, at = rel, (d, ph)
    return {"max_rel_change": worst, "at_depth_m": None if at is None else at[0],
            "at_phase": None if at is None else at[1], "tolerance": INCREMENT_TOLERANCE,
            "converged": worst <= INCREMENT_TOLERANCE,
            "compared_above_N": 10.0 * threshold}


def write_wedge_outputs(out: Path, specs, outcomes, wall: float,
                        increment_outcomes=()) -> int:
    from .plots import plot_force_depth

    curves, rows, checks = [], [], {}
    single = len(specs) == 1
    for spec, o in zip(specs, outcomes):
        if not o.ok:
            continue
        s = o.summary
        angle = spec.params["angle_deg"]
        label = f"{angle:g} deg" if angle is not None else spec.run_id
        curves.append((label, s["depth_m"], s["force_N"], s["phase"]))
        checks[spec.run_id] = curve_checks(s["depth_m"], s["force_N"], s["phase"])
        checks[spec.run_id].update(hold_limit_hits=s["hold_limit_hits"], wall_s=o.wall_s,
                                   cpu_s=s.get("cpu_s"), method=s.get("method"),
                                   max_equilibrium_gap_N=s.get("max_equilibrium_gap_N"),
                                   angle_deg=angle, sim_time_s=s["sim_time_s"],
                                   steps=s["steps"], dt=s["dt"], n_nodes=s["n_nodes"],
                                   local_damping=s.get("local_damping"))
        for i in range(len(s["depth_m"])):
            rows.append((spec.run_id, angle, s["depth_m"][i], s["force_N"][i], s["phase"][i],
                         s["converged"][i]))
        if not single:
            write_force_depth_csv(out / f"force_depth_{_safe_id(spec.run_id)}.csv",
                                  s["depth_m"], s["force_N"], s["phase"])
    done = [r for r in rows]
    if single and done:
        write_force_depth_csv(out / "force_depth.csv", [r[2] for r in done],
                              [r[3] for r in done], [r[4] for r in done])
    elif done:
        write_force_depth_csv(out / "force_depth.csv", [r[2] for r in done],
                              [r[3] for r in done], [r[4] for r in done],
                              {"angle_deg": [f"{r[1]:g}" if r[1] is not None else ""
                                             for r in done],
                               "run_id": [r[0] for r in done]})
    with open(out / "wedge_records.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["run_id", "angle_deg", "depth_m", "force_N", "phase", "converged"])
        for r in rows:
            w.writerow([r[0], "" if r[1] is None else f"{r[1]:.6g}", f"{r[2]:.6g}",
                        f"{r[3]:.9g}", r[4], int(bool(r[5]))])
    if curves:
        plot_force_depth(curves, out / "force_depth.png",
                         "Wedge force against depth (hold-until-steady, seed 4.2)")
    inc = {}
    for spec, o, fine in zip(specs, outcomes, increment_outcomes):
        if o.ok and fine.ok:
            inc[spec.run_id] = increment_check(o.summary, fine.summary,
                                               spec.params["protocol"]["threshold"])
            inc[spec.run_id]["cpu_s"] = fine.summary.get("cpu_s")
    write_outcomes(out / "outcomes.json", list(outcomes) + list(increment_outcomes))
    summary = {
        "study": "wedge", "wall_s": wall, "runs": len(specs),
        "failed": [o.run_id for o in list(outcomes) + list(increment_outcomes) if not o.ok],
        "method": METHOD_NOTES,
        "checks": checks,
        "protocols": {s.run_id: s.params["protocol"] for s in specs}}
    if increment_outcomes:
        summary["increment_check"] = inc
    write_json_atomic(out / "study.json", summary)
    print()
    print(f"{'run':<22} {'angle':>6} {'peak F [N]':>11} {'unload<load':>11} "
          f"{'hold limit':>10} {'wall':>9}")
    for rid, c in checks.items():
        print(f"{rid:<22} {c['angle_deg'] or 0:>6.4g} {c['peak_force_N']:>11.4g} "
              f"{str(c.get('unload_below_load', '-')):>11} {c['hold_limit_hits']:>10} "
              f"{c['wall_s']:>8.1f}s")
    for rid, c in inc.items():
        where = ("" if c["at_depth_m"] is None
                 else f" at {c['at_depth_m'] * 1e3:g} mm ({c['at_phase']})")
        print(f"{rid}: halving the increments changes the force by at most "
              f"{c['max_rel_change']:.2%}{where}: "
              f"{'converged' if c['converged'] else 'NOT converged'} within "
              f"{c['tolerance']:.0%}")
    print(f"study wall time {wall:.1f} s; outputs in {out}/ (force_depth.csv, "
          f"force_depth.png, wedge_records.csv, study.json, runs/*.h5)")
    fails = failures_text(list(outcomes) + list(increment_outcomes))
    if fails:
        _err("failed runs:\n" + fails)
        return EXIT_FAILED
    return EXIT_OK
