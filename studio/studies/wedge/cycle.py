"""One run of the wedge study (seed 4.2): force against penetration depth, loading and
unloading. The study (:mod:`studio.studies.wedge.study`) makes one run per scene (per wedge
angle), each a Dask task (:func:`wedge_cycle`, named by :data:`TASK`). A run replaces
the wedge's scripted motion by the seed's hold-until-steady protocol (seed 4.2, fig. 4.11):

1. the brush settles under the scene's loads with the wedge at rest, until the vertical root
   force is steady: that force is the zero of the scale (the bristles' weight);
2. the wedge moves one step (1 mm) along the profile's direction with the parabolic velocity
   ``v(t) = k t (t_d - t)``, ``k = a_m / t_d``, ``t_d = sqrt(6 s / a_m)`` (seed eq. 4.3),
   through ``engine.prescribe_motion`` (times relative to now, from the current pose);
3. it holds, window after window (``window`` seconds, ``frames_per_window`` frames each),
   until the standard deviation of the total vertical root force over one window is below
   ``max(threshold, rel_threshold * |force|)``, or until ``max_hold`` (then the record is
   flagged ``converged = False``, counted in ``hold_limit_hits``, and its ``force_N`` is
   NaN: the study warns, marks it on the plot and exits with status 1);
4. it records the window's mean force minus the zero (``force_N``) at the depth reached;
5. down to the full depth (``n_steps`` steps), then the same steps back out (phase
   ``unload``) to depth 0.

Each ``engine.run`` call (one hold window of the dynamic method) hands its frames to an
in-memory observer (``engine.MemoryObserver``: the root force, the wedge's position and
force, the node positions), with no file; the run keeps one HDF5 (``runs/<run_id>.h5``,
layout in docs/studies.md): the force-depth table, the root force and wedge position and
force against time for the whole cycle, and the node positions at every recorded
equilibrium. A run that fails still writes that file with the records so far (attribute
``status = "failed"``).

No mass or density scaling is used: the equilibria are reached with the scene's own
Cundall local damping (``environment.local_damping``, 0.3 in the wedge presets), which
only acts on moving nodes and so leaves a static equilibrium's forces unchanged; the study's
output states the damping and ``a_m`` it used.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Optional

from engine.jsonable import jsonable
from studio.studies import api
from studio.studies.runner import report_progress
from studio.studies.wedge.protocol import step_duration

TASK = "studio.studies.wedge.cycle:wedge_cycle"
INCREMENT_TOLERANCE = 0.02  # the increment check's pass mark: 2 % between successive halvings


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
    # a brush with perfectly straight bristles gets a seeded tip scatter far below the
    # resolution's error (p["tip_scatter"], default 1 um): it breaks the exact symmetry
    # that a real brush never has and that the methods would otherwise keep or break
    # differently (issue 22: 14.02 against 11.50 mN at 20 mm, 10.66 mN from both with it)
    scatter = float(p.get("tip_scatter", 0.0))
    for b in d.get("brushes", []):
        if scatter > 0 and not b.get("tip_variance"):
            b["tip_variance"] = scatter * scatter
    if quasi_static:
        d["environment"].update(
            local_damping=max(p["qs_local_damping"], d["environment"].get("local_damping", 0)),
            inertia_scaling=p["qs_inertia_scaling"])
        d["run"]["dt_safety"] = p.get("qs_dt_safety", d["run"].get("dt_safety", 0.5))
    system = engine.build(engine.parse_scene(d))

    series = {"time": [], "root_force_z": [], "wedge_depth": [], "wedge_force_z": []}
    rec = {k: [] for k in ("depth_m", "force_N", "phase", "root_force_z_N", "std_N",
                           "out_of_balance_N", "kinetic_J", "hold_s", "converged", "time_s",
                           "wedge_force_z_N", "measured_depth_m")}
    snapshots: list = []
    costs = {"steps": 0, "engine_wall_s": 0.0, "chunks": 0}
    state = {"p0": None, "last_nodes": None}
    n_stages = 1 + n_steps * (2 if p["unload"] else 1)
    t_wall0, t_cpu0 = time.perf_counter(), time.process_time()
    status, error = "completed", None

    observed = ("time", f"brushes/{brush}/root_force", f"bodies/{body}/position",
                f"bodies/{body}/contact_force", "nodes/positions")

    def advance(duration: float):
        api.check_cancel()  # a cancel of the study running this in-process stops here
        obs = engine.MemoryObserver(observed)  # the window's frames in memory, no file
        res = engine.run(system, until=system.time + duration, output=False, observer=obs)
        costs["chunks"] += 1
        costs["steps"] += int(res.summary.get("steps", 0))
        costs["engine_wall_s"] += float(res.summary.get("wall_s", 0.0))
        t = obs.time
        fz = obs.series(f"brushes/{brush}/root_force")[:, 2]
        pos = obs.series(f"bodies/{body}/position")
        wf = obs.series(f"bodies/{body}/contact_force")[:, 2]
        state["last_nodes"] = obs.frame("nodes/positions", -1)
        if state["p0"] is None:
            state["p0"] = pos[0].copy()
        depth = (pos - state["p0"]) @ direction
        series["time"].append(t)
        series["root_force_z"].append(fz)
        series["wedge_depth"].append(depth)
        series["wedge_force_z"].append(wf)
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
        # a hold that hit its limit is no equilibrium: its force is NaN (the raw root force
        # stays in root_force_z_N, flagged by converged = False), never a silent value
        rec["force_N"].append(h["mean"] - zero if h["converged"] else float("nan"))
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
    except BaseException as exc:  # an InstabilityError included: the records so far are kept
        status, error = "failed", exc
    finally:
        wall = time.perf_counter() - t_wall0
        _write_run_h5(h5_path, scene, params, p, rec, series, snapshots, costs, system,
                      status, str(error) if error else None, wall, t_d)
    if error is not None:
        raise error
    forces = rec["force_N"]
    finite = [f for f in forces if f == f]
    return {"status": "completed", "depth_m": rec["depth_m"], "force_N": forces,
            "phase": rec["phase"], "converged": rec["converged"],
            "hold_limit_hits": int(sum(not c for c in rec["converged"])),
            "zero_force_N": zero,
            "peak_force_N": float(max(finite)) if finite else float("nan"),
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
            "max_equilibrium_gap_N": float(np.nanmax(np.abs(np.subtract(
                rec["force_N"], rec["wedge_force_z_N"])))) if finite else None}


def _quasi_static_steps(system, p: dict, brush: str, body: str, direction, series: dict,
                        costs: dict, state: dict, n_stages: int):
    """``advance(duration)`` and ``hold(stage, zero)`` of the quasi-static method: the live
    state is read every ``check`` steps (about 1/``qs_checks_per_period`` of the slowest
    bristle's period) for the series, and a hold ends when the out-of-balance force and the
    kinetic energy are below the tolerance (:func:`engine.stepping.quasistatic.settle`)."""
    import numpy as np

    from engine.stepping.quasistatic import (commit_slip, freeze_slip, kinetic_tolerance_for,
                                    lowest_bristle_period, settle)
    from engine.stepping.observables import root_reactions
    from engine.stepping.loop import run_steps

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


# ----------------------------------------------------------------------------- curves
def numeric_summary(summary: dict) -> dict:
    """A wedge run's summary with its forces as floats: a hold that hit its limit has a NaN
    force, which comes back from the outcome's JSON as the string "nan"."""
    out = dict(summary, force_N=[float(f) for f in summary["force_N"]])
    if "peak_force_N" in out:
        out["peak_force_N"] = float(out["peak_force_N"])
    return out


def curve_checks(depths, forces, phases) -> dict:
    """Seed 4.2.2's observations for one loading/unloading curve: non-linear growth (the
    secant stiffness F/d at full depth exceeds that at the first step), unloading below
    loading (mean over the depths of both), peak force."""
    # records whose hold hit its limit (NaN force; "nan" once through JSON) are left out
    forces = [float(f) for f in forces]
    load = {d: f for d, f, ph in zip(depths, forces, phases) if ph == "load" and f == f}
    unload = {d: f for d, f, ph in zip(depths, forces, phases) if ph == "unload" and f == f}
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


def increment_check(coarse: dict, fine: dict, threshold: float) -> dict:
    """The recorded force of a run against the same run with halved increments: the largest
    relative change over records whose (finer) force is above ten times the absolute
    tolerance ``threshold`` (below it the tolerance itself dominates), and whether it is
    within :data:`INCREMENT_TOLERANCE`."""
    fine_at = {(round(d, 12), ph): float(f) for d, f, ph in
               zip(fine["depth_m"], fine["force_N"], fine["phase"])}
    worst, at = 0.0, None
    for d, f, ph in zip(coarse["depth_m"], coarse["force_N"], coarse["phase"]):
        f = float(f)
        g = fine_at.get((round(d, 12), ph))
        if g is None:
            continue
        if not (f == f and g == g):  # a hold hit its limit: nothing converged to compare
            worst, at = float("inf"), (d, ph)
            break
        if abs(g) <= 10.0 * threshold:
            continue
        rel = abs(f - g) / abs(g)
        if rel > worst:
            worst, at = rel, (d, ph)
    return {"max_rel_change": worst, "at_depth_m": None if at is None else at[0],
            "at_phase": None if at is None else at[1], "tolerance": INCREMENT_TOLERANCE,
            "converged": worst <= INCREMENT_TOLERANCE,
            "compared_above_N": 10.0 * threshold}
