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

from .bodies import FREE, HINGE
from .build import System, grow_lists
from .compile_clock import CompileClock
from .errors import InstabilityError
from .orbit import orbit_energy
from .recorder import Recorder, state_channels, state_frame
from .rotations import quat_to_matrix
from .state import (ACC_DISSIPATED, ACC_E_BB, ACC_E_BODY, ACC_E_BODYBODY, ACC_HINGE_DISS,
                    ACC_MAX_OVERLAP, ACC_N_BB, ACC_N_BODY, ACC_N_BODYBODY, ACC_REBUILDS,
                    ACC_TIMED_STEPS, ACC_WORK, FAIL_BODY_SPEED,
                    FAIL_NODE_SPEED, FAIL_NONFINITE_BODY, FAIL_NONFINITE_NODE, FAIL_OVERLAP_BB,
                    FAIL_OVERLAP_BODY, FAIL_OVERLAP_BODYBODY, OK, OVERFLOW_BODY, OVERFLOW_PAIRS,
                    STAGES, timed_slots)
from .stepper import advance

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
        """Open the result file with the reader (``engine.results.open_result``)."""
        from .results import open_result
        return open_result(self.path)


# ----------------------------------------------------------------------------- channels
#: per controller: (name, per-frame shape); forces and torques in the body's mesh axes,
#: impulses and errors in world axes (engine.control)
_CONTROLLER_CHANNELS = (("commanded_force", (3,)), ("applied_force", (3,)),
                        ("commanded_torque", (3,)), ("applied_torque", (3,)),
                        ("impulse", (3,)), ("angular_impulse", (3,)), ("delta_v", ()),
                        ("angular_impulse_total", ()), ("position_error", (3,)),
                        ("attitude_error", (3,)))


def controller_record(system: System, c: int) -> dict[str, np.ndarray]:
    """Controller c's current record (see _CONTROLLER_CHANNELS)."""
    from . import control as C
    cs = system.mission.ctl_state[c]
    slots = {"commanded_force": C.S_CMD_F, "applied_force": C.S_APP_F,
             "commanded_torque": C.S_CMD_T, "applied_torque": C.S_APP_T,
             "impulse": C.S_IMPULSE, "angular_impulse": C.S_ANG_IMPULSE,
             "position_error": C.S_ERR_POS, "attitude_error": C.S_ERR_ATT}
    out = {k: cs[i:i + 3].copy() for k, i in slots.items()}
    out["delta_v"] = np.float64(cs[C.S_DELTA_V])
    out["angular_impulse_total"] = np.float64(cs[C.S_ANG_IMPULSE_ABS])
    return out


def _channels(system: System) -> tuple[dict, dict]:
    sc = system.scene
    want = set(sc.run.channels)
    ch: dict[str, tuple] = {"time": ((), "f8")}
    static: dict[str, np.ndarray] = {}
    N = system.n_nodes
    if "nodes" in want and N:
        ch["nodes/positions"] = ((N, 3), "f8")
        static["nodes/radius"] = system.nodes.rad
        static["bristles/first_node"] = system.bristle_first_node
        static["bristles/brush"] = system.bristle_brush
        static["bonds/nodes"] = np.stack([system.bonds.i, system.bonds.j], axis=1)
    if "bodies" in want:
        for k, name in enumerate(system.body_names):
            for key, n in (("position", 3), ("orientation", 4), ("velocity", 3),
                           ("angular_velocity", 3), ("contact_force", 3),
                           ("contact_torque", 3)):
                ch[f"bodies/{name}/{key}"] = ((n,), "f8")
            sl = slice(*_tri_range(system, k))
            tris = system.bodies.tris[sl]
            v0 = tris.min() if len(tris) else 0
            v1 = tris.max() + 1 if len(tris) else 0
            static[f"bodies/{name}/vertices"] = system.bodies.verts[v0:v1]
            static[f"bodies/{name}/triangles"] = tris - v0
    if "root_force" in want:
        for b in system.brushes:
            ch[f"brushes/{b.name}/root_force"] = ((3,), "f8")
            ch[f"brushes/{b.name}/root_torque"] = ((3,), "f8")
    if "energy" in want:
        for key in ("kinetic", "bond", "contact", "gravity", "dissipated", "external_work",
                    "total"):
            ch[f"energy/{key}"] = ((), "f8")
    if "contacts" in want:
        for key in ("bristle_bristle", "bristle_body", "body_body"):
            ch[f"contacts/{key}"] = ((), "i8")
    for c in sc.controllers:  # always recorded: a controller's record is small
        for key, shape in _CONTROLLER_CHANNELS:
            ch[f"controllers/{c.name}/{key}"] = (shape, "f8")
    if "bending" in want and system.bonds.i.shape[0]:
        ch["bonds/bending_moment"] = ((system.bonds.i.shape[0],), "f4")
        static.setdefault("bonds/nodes", np.stack([system.bonds.i, system.bonds.j], axis=1))
    extra_ch, extra_static = state_channels(system)  # velocities, spins, mass properties
    ch.update(extra_ch)
    static.update(extra_static)
    return ch, static


def _tri_range(system: System, k: int) -> tuple[int, int]:
    counts = [len(g.triangles) for g in system.body_geometry]
    start = sum(counts[:k])
    return start, start + counts[k]


def energies(system: System) -> dict[str, float]:
    """Energies of the current state (J). Bond energy is that of the last force evaluation."""
    nd, bd = system.nodes, system.bodies
    free = nd.inv_mass > 0
    kin = 0.5 * float(np.sum(nd.mass[free] * np.sum(nd.v[free] ** 2, axis=1)))
    kin += 0.5 * float(np.sum(nd.inertia[free] * np.sum(nd.w[free] ** 2, axis=1)))
    g = system.tables.gravity
    grav = -float(np.sum(nd.mass[free] * ((nd.x[free] - nd.x0[free]) @ g)))
    for k in range(bd.pos.shape[0]):
        if bd.motion[k] == FREE:
            kin += 0.5 * bd.mass[k] * float(bd.v[k] @ bd.v[k]) + 0.5 * float(bd.w[k] @ bd.L[k])
            grav -= bd.mass[k] * float((bd.pos[k] - bd.pos0[k]) @ g)
        elif bd.motion[k] == HINGE:
            om = float(bd.w[k] @ bd.hinge_axis[k])
            kin += 0.5 * bd.hinge_inertia[k] * om * om
            grav -= bd.mass[k] * float((bd.pos[k] - bd.pos0[k]) @ g)
    grav += orbit_energy(system)  # tidal (Clohessy-Wiltshire) potential; 0 without an orbit
    bond = float(system.bonds.energy.sum())
    contact = float(system.acc[ACC_E_BB] + system.acc[ACC_E_BODY] + system.acc[ACC_E_BODYBODY])
    diss = float(system.acc[ACC_HINGE_DISS] + system.acc[ACC_DISSIPATED])
    work = float(system.acc[ACC_WORK])
    return {"kinetic": kin, "bond": bond, "contact": contact, "gravity": grav,
            "dissipated": diss, "external_work": work, "total": kin + bond + contact + grav}


def angular_momentum(system: System, about=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Total angular momentum of free nodes and free/hinge bodies about a point."""
    nd, bd = system.nodes, system.bodies
    o = np.asarray(about, float)
    free = nd.inv_mass > 0
    Lt = np.sum(np.cross(nd.x[free] - o, nd.mass[free, None] * nd.v[free]), axis=0)
    Lt = Lt + np.sum(nd.inertia[free, None] * nd.w[free], axis=0)
    for k in range(bd.pos.shape[0]):
        if bd.motion[k] == FREE:
            Lt = Lt + np.cross(bd.pos[k] - o, bd.mass[k] * bd.v[k]) + bd.L[k]
    return Lt


def linear_momentum(system: System) -> np.ndarray:
    nd, bd = system.nodes, system.bodies
    free = nd.inv_mass > 0
    p = np.sum(nd.mass[free, None] * nd.v[free], axis=0)
    for k in range(bd.pos.shape[0]):
        if bd.motion[k] == FREE:
            p = p + bd.mass[k] * bd.v[k]
    return p


def root_reactions(system: System) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per brush: the total force the base exerts on the roots, and its moment about the
    base origin."""
    nd, rt, bd = system.nodes, system.roots, system.bodies
    out = {}
    for b in system.brushes:
        nodes = rt.node[b.root_index]
        f = nd.f[nodes]
        if b.mount >= 0:
            origin = bd.pos[b.mount] + quat_to_matrix(bd.q[b.mount]) @ b.base_local
        else:
            origin = b.base_position
        force = -f.sum(axis=0)
        torque = -(np.cross(nd.x[nodes] - origin, f).sum(axis=0) + nd.t[nodes].sum(axis=0))
        out[b.name] = (force, torque)
    return out


def bending_moments(system: System) -> np.ndarray:
    """Bending moment magnitude per bond at its midpoint (N m), from the current state: the
    bond kernel's own value (the gradient of the bond energy in the bending rotation,
    ``|k_b phi + k_sb e_z x d|``, which includes a tapered bond's shear coupling)."""
    from .bonds import bond_forces
    nd, bn = system.nodes, system.bonds
    B = bn.i.shape[0]
    bend = np.zeros(B)
    bond_forces(nd.x, nd.v, nd.q, nd.w, bn.i, bn.j, bn.kn, bn.ks, bn.kb, bn.ksb, bn.kt, bn.L0,
                bn.cn, bn.cs, bn.cb, bn.ct, np.zeros((B, 3)), np.zeros((B, 3)),
                np.zeros((B, 3)), np.zeros(B), np.zeros(B), bend, False, True, system.dt)
    return bend


def _frame(system: System, channels: dict) -> dict:
    fr: dict = {"time": system.time}
    if "nodes/positions" in channels:
        fr["nodes/positions"] = system.nodes.x
    bd = system.bodies
    for k, name in enumerate(system.body_names):
        key = f"bodies/{name}/position"
        if key in channels:
            fr[key] = bd.pos[k]
            fr[f"bodies/{name}/orientation"] = bd.q[k]
            fr[f"bodies/{name}/velocity"] = bd.v[k]
            fr[f"bodies/{name}/angular_velocity"] = bd.w[k]
            fr[f"bodies/{name}/contact_force"] = bd.f[k]
            fr[f"bodies/{name}/contact_torque"] = bd.tq[k]
    if any(k.startswith("brushes/") for k in channels):
        for name, (f, t) in root_reactions(system).items():
            fr[f"brushes/{name}/root_force"] = f
            fr[f"brushes/{name}/root_torque"] = t
    if "energy/total" in channels:
        for key, val in energies(system).items():
            fr[f"energy/{key}"] = val
    if "contacts/bristle_bristle" in channels:
        fr["contacts/bristle_bristle"] = int(system.acc[ACC_N_BB])
        fr["contacts/bristle_body"] = int(system.acc[ACC_N_BODY])
        fr["contacts/body_body"] = int(system.acc[ACC_N_BODYBODY])
    if "bonds/bending_moment" in channels:
        fr["bonds/bending_moment"] = bending_moments(system).astype(np.float32)
    for c, ctl in enumerate(system.scene.controllers):
        for key, val in controller_record(system, c).items():
            fr[f"controllers/{ctl.name}/{key}"] = val
    fr.update(state_frame(system, channels))
    return fr


# ----------------------------------------------------------------------------- failures
def dt_cause(system: System) -> Optional[str]:
    """When the scene's own ``run.dt`` exceeds the stability limit the build found
    (``system.dt_stable``), any blow-up is the timestep's: the advice that says so (and
    nothing else, which would send the user after tip randomness or contact stiffness)."""
    given, bound = system.scene.run.dt, system.dt_stable
    if given is None or not given > bound:
        return None
    return (f"The cause is the timestep: run.dt = {given:.3g} s is {given / bound:.3g} x the "
            f"stability limit {bound:.3g} s of this scene; remove run.dt (automatic dt = "
            f"{system.scene.run.dt_safety:g} x the limit) or set it below {bound:.3g} s.")


def _instability(system: System, code: int) -> InstabilityError:
    exc = _instability_by_code(system, code)
    cause = dt_cause(system)
    if cause is None:
        return exc
    return InstabilityError(exc.quantity, exc.where, exc.time, cause, detail=exc.detail)


def _instability_by_code(system: System, code: int) -> InstabilityError:
    e = system.err
    t = system.time
    sc = system.scene
    lower_dt = (f"lower run.dt_safety (now {sc.run.dt_safety:g}) or set a smaller run.dt "
                f"(now {system.dt:.3g} s)")
    if code == FAIL_NONFINITE_NODE:
        return InstabilityError("non-finite node position or velocity",
                                system.node_label(int(e[0])), t,
                                f"The integration diverged: {lower_dt}, and check for "
                                f"extreme material values.")
    if code == FAIL_NODE_SPEED:
        return InstabilityError("node displacement per step", system.node_label(int(e[0])), t,
                                f"It moves {e[1]:.3g} m in one step, more than half its "
                                f"radius: the run is blowing up or the motion is too fast for "
                                f"the timestep; {lower_dt}.",
                                detail=f"{e[1]:.3g} m > {e[2]:.3g} m")
    at_start = system.steps <= system.flags.check_every
    start_note = ("The overlap is there from the first steps: the scene starts with these "
                  "elements overlapping (bristles that cross because of tip randomness, or "
                  "roots resting on a body: lift the brush base by the root radius). ")
    soft_note = ("If a smaller dt stops at the same time, the linear contact (k_n = 2 E1 r1 "
                 "E2 r2 / (E1 r1 + E2 r2), seed eq. 3.6) cannot hold this load within half a "
                 "radius whatever the step: ")
    if code == FAIL_OVERLAP_BB:
        if at_start:
            return InstabilityError("bristle-bristle contact overlap",
                                    f"{system.segment_label(int(e[0]))} and "
                                    f"{system.segment_label(int(e[2]))}", t,
                                    start_note + "Reduce brushes[].tip_variance or increase "
                                    "the pitch.", detail=f"overlap ratio {e[1]:.3g}")
        return InstabilityError("bristle-bristle contact overlap",
                                f"{system.segment_label(int(e[0]))} and "
                                f"{system.segment_label(int(e[2]))}", t,
                                f"The capsules overlap by {e[1]:.2f} of the smaller radius "
                                f"(limit {system.limits[0]:g}): the contact is too soft for the "
                                f"load or the step too large; {lower_dt}. {soft_note}load the "
                                f"brush more gently or use stiffer or thicker bristles.",
                                detail=f"overlap ratio {e[1]:.3g}")
    if code == FAIL_OVERLAP_BODY and at_start:
        return InstabilityError("bristle-body contact overlap",
                                f"{system.segment_label(int(e[0]))} against body "
                                f"{system.body_names[int(e[2])]!r}", t,
                                start_note + "Move the body or the brush base apart.",
                                detail=f"overlap ratio {e[1]:.3g}")
    if code == FAIL_OVERLAP_BODY:
        return InstabilityError("bristle-body contact overlap",
                                f"{system.segment_label(int(e[0]))} against body "
                                f"{system.body_names[int(e[2])]!r}", t,
                                f"The capsule penetrates the body by {e[1]:.2f} of its radius "
                                f"(limit {system.limits[0]:g}): the body pushes harder or "
                                f"faster than the contact can resist at this step; "
                                f"{lower_dt}. {soft_note}slow the body down, or use stiffer "
                                f"or thicker bristles.",
                                detail=f"overlap ratio {e[1]:.3g}")
    if code == FAIL_OVERLAP_BODYBODY:
        return InstabilityError("body-body contact overlap (overlap / sphere radius, or a "
                                "mesh vertex's depth / its vertex length)", "two bodies", t,
                                f"{lower_dt}.", detail=f"overlap ratio {e[1]:.3g}")
    if code == FAIL_BODY_SPEED:
        return InstabilityError("body displacement per step",
                                f"body {system.body_names[int(e[0])]!r}", t,
                                f"Its surface moves {e[1]:.3g} m per step, more than a quarter "
                                f"of the smallest bristle radius ({e[2]:.3g} m): it could pass "
                                f"through bristles; set a smaller run.dt.",
                                detail=f"{e[1]:.3g} m > {e[2]:.3g} m")
    if code == FAIL_NONFINITE_BODY:
        return InstabilityError("non-finite body state", f"body "
                                f"{system.body_names[int(e[0])]!r}", t, f"{lower_dt}.")
    return InstabilityError(f"unknown failure code {code}", "?", t, lower_dt)


def _is_cancelled(cancel) -> bool:
    if cancel is None:
        return False
    if hasattr(cancel, "is_set"):
        return bool(cancel.is_set())
    return bool(cancel())


# ----------------------------------------------------------------------------- run
def run(system: System, until: Optional[float] = None,
        output: Union[str, Path, None] = None,
        on_progress: Optional[Callable[[Progress], None]] = None,
        cancel=None, progress_interval: float = 0.5) -> RunResult:
    """Advance ``system`` to simulated time ``until`` (default: the scene's run.duration),
    recording to the HDF5 file ``output`` (a temporary file if None).

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
    if output is None:
        output = Path(tempfile.mkdtemp(prefix="brush-studio-")) / "result.h5"
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    channels, static = _channels(system)
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
    recorder = Recorder(output, sc.to_json(), channels, static, attrs)
    # numba compiles (a cold cache: minutes) are timed apart and left out of the speed and
    # the stage times (they made a first run's bristle_body stage 116 s against 29 s warm)
    clock = CompileClock().__enter__()
    try:
        def record():
            nonlocal frames, record_wall, e_scale, balance0
            r0, compiled0 = _time.perf_counter(), clock.seconds
            fr = _frame(system, channels)
            recorder.append(fr)
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
            _advance(system, 0)
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
                        system.limits, system.mission)
    if code in (OVERFLOW_PAIRS, OVERFLOW_BODY):
        lst = system.pairs if code == OVERFLOW_PAIRS else system.body_pairs
        grow_lists(system, code, int(lst.n[1]))
        return did
    if code != OK:
        raise _instability(system, code)
    return did


def run_steps(system: System, n_steps: int) -> None:
    """Advance ``system`` by exactly ``n_steps`` steps, recording nothing: for protocols that
    read the live state between calls (:mod:`engine.quasistatic`). A blow-up raises
    :class:`InstabilityError`, as in :func:`run`."""
    done = 0
    while done < n_steps:
        done += _advance(system, n_steps - done)


def _refresh_forces(system: System) -> None:
    """Evaluate bond energies of the initial state (no time advance)."""
    from .bonds import bond_forces
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
        "warnings": list(system.warnings),
    }
