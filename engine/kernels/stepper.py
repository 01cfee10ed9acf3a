"""The step loop: many velocity-Verlet (kick-drift-kick leapfrog, seed eq. 3.12-3.13) steps
per call into compiled code. Python only sees the state between calls.

Order of one step: predict whether the neighbour lists stay valid (else rebuild them), half
kick and drift of nodes and bodies, roots follow their bases, then forces (bonds, external,
contacts, roots onto mounted bodies, local damping), then the second half kick. Every
``check_every`` steps the state is checked for instability; every ``time_every`` steps the
stages are timed (so the run can report where its time goes).

The loop is one compiled function for every scene: each stage is a branch switched by a
``Flags`` field that ``build`` sets (``engine.state.STAGE_TABLE`` names the stages, their
flags and their timing slots), so a scene without, say, bodies skips those branches but is
not compiled into a loop of its own.
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit, objmode, prange

from .bodies import KINEMATIC, bodies_drift, bodies_half_kick
from .control import apply_controllers, apply_external
from .body_contacts import body_body_contacts, bristle_body_narrow, scatter_bristle_body
from .bonds import PARALLEL_MIN, bond_node_forces
from .mesh_contact import mesh_mesh_contacts
from .patch import patch_contacts
from .orbit import nodes_kick_drift_cw, orbit_body_forces
from .contacts import bristle_bristle_narrow, scatter_bristle_bristle
from .jit import item_kernel
from .neighbours import body_displacement, lists_stale, node_displacement_one, rebuild_lists
from .rotations import qexp, qmul, qnormalize, qrot
from ..state import (LIMIT_BODY_STEP, LIMIT_LOCAL_DAMPING, LIMIT_NODE_STEP, LIMIT_OVERLAP,
                     LIMIT_SKIN)
from ..state import (ACC_DISSIPATED, ACC_E_BB, ACC_E_BODY, ACC_E_BODYBODY, ACC_MAX_OVERLAP,
                     ACC_N_BB, ACC_N_BODY, ACC_N_BODYBODY, ACC_REBUILDS, ACC_STEPS, ACC_TIME,
                     ACC_TIMED_STEPS, ACC_WORK, FAIL_BODY_SPEED, FAIL_NODE_SPEED,
                     FAIL_NONFINITE_BODY, FAIL_NONFINITE_NODE, FAIL_OVERLAP_BB, FAIL_OVERLAP_BODY,
                     FAIL_OVERLAP_BODYBODY, OK, SLOT_BODY_BODY, SLOT_BONDS, SLOT_BRISTLE_BODY,
                     SLOT_BRISTLE_BRISTLE, SLOT_CHECKS, SLOT_EXTERNAL, SLOT_INTEGRATE,
                     SLOT_NEIGHBOUR_LIST)


WATCH_CHUNK = 4096   # nodes per parallel task of ``nodes_kick_watch``


@njit(cache=True)
def _clock():
    with objmode(t="float64"):
        t = time.perf_counter()
    return t


@njit(cache=True, parallel=True)
def nodes_kick_drift(x, v, q, w, f, t, inv_mass, inv_inertia, dt):
    if x.shape[0] >= PARALLEL_MIN:  # the twin loops: engine.kernels.bonds.PARALLEL_MIN
        for n in prange(x.shape[0]):
            _kick_drift(n, x, v, q, w, f, t, inv_mass, inv_inertia, dt)
    else:
        for n in range(x.shape[0]):
            _kick_drift(n, x, v, q, w, f, t, inv_mass, inv_inertia, dt)


@njit(cache=True, inline="always")
def _kick_drift(n, x, v, q, w, f, t, inv_mass, inv_inertia, dt):
    h = 0.5 * dt
    im = inv_mass[n]
    if im != 0.0:
        for a in range(3):
            v[n, a] += h * f[n, a] * im
            x[n, a] += dt * v[n, a]
        ii = inv_inertia[n]
        w0 = w[n, 0] + h * t[n, 0] * ii
        w1 = w[n, 1] + h * t[n, 1] * ii
        w2 = w[n, 2] + h * t[n, 2] * ii
        w[n, 0] = w0
        w[n, 1] = w1
        w[n, 2] = w2
        ew, ex, ey, ez = qexp(dt * w0, dt * w1, dt * w2)
        nw, nx, ny, nz = qmul(ew, ex, ey, ez, q[n, 0], q[n, 1], q[n, 2], q[n, 3])
        q[n, 0], q[n, 1], q[n, 2], q[n, 3] = qnormalize(nw, nx, ny, nz)


@njit(cache=True, parallel=True)
def nodes_kick(v, w, f, t, inv_mass, inv_inertia, dt):
    if v.shape[0] >= PARALLEL_MIN:  # the twin loops: engine.kernels.bonds.PARALLEL_MIN
        for n in prange(v.shape[0]):
            _kick(n, v, w, f, t, inv_mass, inv_inertia, dt)
    else:
        for n in range(v.shape[0]):
            _kick(n, v, w, f, t, inv_mass, inv_inertia, dt)


@njit(cache=True, parallel=True)
def nodes_kick_watch(x, x_build, v, w, f, t, inv_mass, inv_inertia, dt):
    """:func:`nodes_kick`, returning what ``neighbours.node_displacement`` would return
    right after it (the next step's check of the neighbour lists, taken in the same pass
    over the nodes, with the same numbers: the same floats, and so the same rebuilds)."""
    n = v.shape[0]
    if n >= PARALLEL_MIN:  # the twin loops: engine.kernels.bonds.PARALLEL_MIN
        nchunk = (n + WATCH_CHUNK - 1) // WATCH_CHUNK
        part = np.zeros(nchunk)
        for c in prange(nchunk):
            worst = 0.0
            for k in range(c * WATCH_CHUNK, min(n, (c + 1) * WATCH_CHUNK)):
                _kick(k, v, w, f, t, inv_mass, inv_inertia, dt)
                worst = node_displacement_one(k, x, x_build, v, f, inv_mass, dt, worst)
            part[c] = worst
        return part.max()
    worst = 0.0
    for k in range(n):
        _kick(k, v, w, f, t, inv_mass, inv_inertia, dt)
        worst = node_displacement_one(k, x, x_build, v, f, inv_mass, dt, worst)
    return worst


@njit(cache=True, inline="always")
def _kick(n, v, w, f, t, inv_mass, inv_inertia, dt):
    h = 0.5 * dt
    im = inv_mass[n]
    ii = inv_inertia[n]
    for a in range(3):
        v[n, a] += h * f[n, a] * im
        w[n, a] += h * t[n, a] * ii


@item_kernel
def roots_follow(x, v, q, w, root_node, root_body, local_pos, local_q, bpos, bq, bv, bw):
    """Roots mounted on a body move rigidly with it (fixed roots never move)."""
    for r in range(root_node.shape[0]):
        k = root_body[r]
        if k < 0:
            continue
        n = root_node[r]
        qw, qx, qy, qz = bq[k, 0], bq[k, 1], bq[k, 2], bq[k, 3]
        rx, ry, rz = qrot(qw, qx, qy, qz, local_pos[r, 0], local_pos[r, 1], local_pos[r, 2])
        x[n, 0] = bpos[k, 0] + rx
        x[n, 1] = bpos[k, 1] + ry
        x[n, 2] = bpos[k, 2] + rz
        v[n, 0] = bv[k, 0] + bw[k, 1] * rz - bw[k, 2] * ry
        v[n, 1] = bv[k, 1] + bw[k, 2] * rx - bw[k, 0] * rz
        v[n, 2] = bv[k, 2] + bw[k, 0] * ry - bw[k, 1] * rx
        q[n, 0], q[n, 1], q[n, 2], q[n, 3] = qmul(qw, qx, qy, qz, local_q[r, 0],
                                                  local_q[r, 1], local_q[r, 2], local_q[r, 3])
        w[n, 0] = bw[k, 0]
        w[n, 1] = bw[k, 1]
        w[n, 2] = bw[k, 2]


@item_kernel
def roots_to_bodies(x, f, t, root_node, root_body, bpos, bf, btq):
    """The forces on mounted roots act on the body that carries them."""
    for r in range(root_node.shape[0]):
        k = root_body[r]
        if k < 0:
            continue
        n = root_node[r]
        rx = x[n, 0] - bpos[k, 0]
        ry = x[n, 1] - bpos[k, 1]
        rz = x[n, 2] - bpos[k, 2]
        bf[k, 0] += f[n, 0]
        bf[k, 1] += f[n, 1]
        bf[k, 2] += f[n, 2]
        btq[k, 0] += ry * f[n, 2] - rz * f[n, 1] + t[n, 0]
        btq[k, 1] += rz * f[n, 0] - rx * f[n, 2] + t[n, 1]
        btq[k, 2] += rx * f[n, 1] - ry * f[n, 0] + t[n, 2]


@item_kernel
def add_gravity(f, mass, inv_mass, g):
    for n in range(f.shape[0]):
        if inv_mass[n] > 0.0:
            f[n, 0] += mass[n] * g[0]
            f[n, 1] += mass[n] * g[1]
            f[n, 2] += mass[n] * g[2]


@item_kernel
def load_amplitude(ld, k, time):
    """Piecewise-linear amplitude of load k (held outside its table), times the optional sine."""
    a = ld.start[k]
    b = ld.start[k + 1]
    if time <= ld.times[a]:
        amp = ld.values[a]
    elif time >= ld.times[b - 1]:
        amp = ld.values[b - 1]
    else:
        amp = ld.values[b - 1]
        for i in range(a, b - 1):
            if time < ld.times[i + 1]:
                t0 = ld.times[i]
                t1 = ld.times[i + 1]
                if t1 > t0:
                    amp = ld.values[i] + (ld.values[i + 1] - ld.values[i]) * (time - t0) / (t1 - t0)
                else:
                    amp = ld.values[i + 1]
                break
    if ld.frequency[k] > 0.0:
        amp *= math.sin(2.0 * math.pi * ld.frequency[k] * time + ld.phase[k])
    return amp


@item_kernel
def add_loads(ld, f, v, time, dt):
    """External loads on nodes; returns their work over this step (F . v dt)."""
    for k in range(ld.force.shape[0]):
        ld.amp[k] = load_amplitude(ld, k, time)
    work = 0.0
    for e in range(ld.node.shape[0]):
        n = ld.node[e]
        k = ld.load[e]
        a = ld.amp[k]
        fx = a * ld.force[k, 0]
        fy = a * ld.force[k, 1]
        fz = a * ld.force[k, 2]
        f[n, 0] += fx
        f[n, 1] += fy
        f[n, 2] += fz
        work += (fx * v[n, 0] + fy * v[n, 1] + fz * v[n, 2]) * dt
    return work


@item_kernel
def local_damping(f, t, v, w, inv_mass, alpha, dt, want_diss):
    """Cundall's non-viscous damping: each force component is reduced by alpha |F| against
    the velocity. Returns the energy it dissipated this step when ``want_diss`` (a run that
    books its energy), else 0.0 without summing it."""
    # branch-free (sign of the velocity as a number), so the loop vectorises: the signs
    # of a relaxing brush's velocities are random, and branches on them mispredicted. The
    # (n, 3) arrays are taken as flat rows, which the compiler vectorises where no
    # dissipation is summed (benchmarks/bond_kernel.py on the wedge's brush: 2.4 ns a node,
    # 8.1 for 531fdd8's loop over the (n, 3) arrays); the running sum cannot be vectorised
    # without reordering it, and the loop-invariant ``want_diss`` lets the compiler keep a
    # copy of the loop without it
    diss = 0.0
    F = f.reshape(f.size)
    T = t.reshape(t.size)
    V = v.reshape(v.size)
    Om = w.reshape(w.size)
    for n in range(f.shape[0]):
        free = 1.0 if inv_mass[n] != 0.0 else 0.0
        for a in range(3):
            k = 3 * n + a
            fa = F[k]
            va = V[k]
            ta = T[k]
            wa = Om[k]
            sv = free * ((va > 0.0) - (va < 0.0))
            sw = free * ((wa > 0.0) - (wa < 0.0))
            F[k] = fa - sv * alpha * abs(fa)
            T[k] = ta - sw * alpha * abs(ta)
            if want_diss:
                diss += free * alpha * (abs(fa) * abs(va) + abs(ta) * abs(wa)) * dt
    return diss


@item_kernel
def check_state(nd, bd, fl, acc, err, dt, limits, time):
    """Instability checks; returns a failure code (err gets [index, value, limit])."""
    for n in range(nd.x.shape[0]):
        ok = True
        for a in range(3):
            if not (math.isfinite(nd.x[n, a]) and math.isfinite(nd.v[n, a])
                    and math.isfinite(nd.w[n, a])):
                ok = False
        if not ok:
            err[0] = n
            err[1] = np.nan
            err[2] = 0.0
            return FAIL_NONFINITE_NODE
        if nd.inv_mass[n] > 0.0:
            sp = math.sqrt(nd.v[n, 0] ** 2 + nd.v[n, 1] ** 2 + nd.v[n, 2] ** 2)
            if sp * dt > limits[LIMIT_NODE_STEP] * nd.rad[n]:
                err[0] = n
                err[1] = sp * dt
                err[2] = limits[LIMIT_NODE_STEP] * nd.rad[n]
                return FAIL_NODE_SPEED
    for k in range(bd.pos.shape[0]):
        for a in range(3):
            if not (math.isfinite(bd.pos[k, a]) and math.isfinite(bd.v[k, a])
                    and math.isfinite(bd.w[k, a])):
                err[0] = k
                err[1] = np.nan
                err[2] = 0.0
                return FAIL_NONFINITE_BODY
        if bd.collide[k] and (fl.bristle_body or fl.body_body):
            sp = math.sqrt(bd.v[k, 0] ** 2 + bd.v[k, 1] ** 2 + bd.v[k, 2] ** 2)
            om = math.sqrt(bd.w[k, 0] ** 2 + bd.w[k, 1] ** 2 + bd.w[k, 2] ** 2)
            step = (sp + om * bd.bound_r[k]) * dt
            if step > limits[LIMIT_BODY_STEP]:
                err[0] = k
                err[1] = step
                err[2] = limits[LIMIT_BODY_STEP]
                return FAIL_BODY_SPEED
    return OK


@njit(cache=True)
def evaluate_forces(nd, bn, rt, bd, pl, bl, ld, tb, fl, acc, err, stage_time, dt, limits, ms,
                    time, want_energy, timed, c0, stats, orbit_n, pa):
    """Every force of the current state at ``time`` into ``nodes.f``/``t`` and
    ``bodies.f``/``tq`` (bonds, gravity, loads, contacts, roots onto mounted bodies, orbit,
    external loads, controllers, local damping), booking the step's work and dissipation
    over ``dt``. Returns OK or an overlap failure code. ``dt = 0`` evaluates the forces of a
    state without booking anything and without moving any contact's tangential spring (the
    start of a run, :func:`advance`); ``c0`` is the clock at entry when ``timed``."""
    if fl.bonds:
        bond_node_forces(nd, bn, fl.bond_damping, fl.track_energy and fl.bond_damping,
                         want_energy, dt)
        if fl.track_energy and fl.bond_damping:
            acc[ACC_DISSIPATED] += bn.diss.sum()
    else:
        nd.f[:] = 0.0
        nd.t[:] = 0.0
    if timed:
        c3 = _clock()
        stage_time[SLOT_BONDS] += c3 - c0
    if fl.rigid_bodies or fl.bristle_body or fl.mounted_roots:
        bd.f[:] = 0.0
        bd.tq[:] = 0.0
    if fl.gravity:
        add_gravity(nd.f, nd.mass, nd.inv_mass, tb.gravity)
    if fl.loads:
        acc[ACC_WORK] += add_loads(ld, nd.f, nd.v, time, dt)
    if timed:
        c4 = _clock()
        stage_time[SLOT_EXTERNAL] += c4 - c3
    if fl.bristle_bristle:
        bristle_bristle_narrow(nd, bn, pl, tb, fl.friction_bristle, dt)
        scatter_bristle_bristle(nd, bn, pl, stats)
        acc[ACC_N_BB] = stats[0]
        acc[ACC_E_BB] = stats[1]
        acc[ACC_DISSIPATED] += stats[2]
        if stats[3] > limits[LIMIT_OVERLAP]:
            p = int(stats[4])
            err[0] = pl.a[p]
            err[1] = stats[3]
            err[2] = pl.b[p]
            return FAIL_OVERLAP_BB
        acc[ACC_MAX_OVERLAP] = max(acc[ACC_MAX_OVERLAP], stats[3])
    if timed:
        c5 = _clock()
        stage_time[SLOT_BRISTLE_BRISTLE] += c5 - c4
    if fl.bristle_body:
        bristle_body_narrow(nd, bn, bl, bd, tb, fl.friction_body, dt)
        scatter_bristle_body(nd, bn, bl, bd, stats)
        acc[ACC_N_BODY] = stats[0]
        acc[ACC_E_BODY] = stats[1]
        acc[ACC_DISSIPATED] += stats[2]
        if stats[3] > limits[LIMIT_OVERLAP]:
            c = int(stats[4])
            err[0] = bl.s[c]
            err[1] = stats[3]
            err[2] = bl.b[c]
            return FAIL_OVERLAP_BODY
        acc[ACC_MAX_OVERLAP] = max(acc[ACC_MAX_OVERLAP], stats[3])
    if timed:
        c6 = _clock()
        stage_time[SLOT_BRISTLE_BODY] += c6 - c5
    if fl.body_body:
        body_body_contacts(bd, tb, fl.friction_body_body, stats, dt)
        if fl.mesh_mesh:
            mesh_mesh_contacts(bd, tb, fl.friction_body_body, stats, dt)
        acc[ACC_N_BODYBODY] = stats[0]
        acc[ACC_E_BODYBODY] = stats[1]
        acc[ACC_DISSIPATED] += stats[2]
        if stats[3] > limits[LIMIT_OVERLAP]:
            err[0] = -1
            err[1] = stats[3]
            err[2] = limits[LIMIT_OVERLAP]
            return FAIL_OVERLAP_BODYBODY
    if fl.patches:
        # reduced brushes (engine.kernels.patch): their stored energy and contact count
        # join the body-body ones, which the branch above set afresh this step
        n_p, sto_p, dis_p = patch_contacts(bd, pa, dt)
        if fl.body_body:
            acc[ACC_N_BODYBODY] += n_p
            acc[ACC_E_BODYBODY] += sto_p
        else:
            acc[ACC_N_BODYBODY] = n_p
            acc[ACC_E_BODYBODY] = sto_p
        acc[ACC_DISSIPATED] += dis_p
    if timed:
        c7 = _clock()
        stage_time[SLOT_BODY_BODY] += c7 - c6
    if fl.rigid_bodies or fl.bristle_body or fl.mounted_roots:
        # what the bodies' contacts alone put on them (the recorded contact force)
        bd.f_contact[:] = bd.f
        bd.tq_contact[:] = bd.tq
    if fl.mounted_roots:
        roots_to_bodies(nd.x, nd.f, nd.t, rt.node, rt.body, bd.pos, bd.f, bd.tq)
    if fl.orbit:
        orbit_body_forces(bd.motion, bd.pos, bd.q, bd.mass, bd.Ip, bd.f, bd.tq, orbit_n,
                          ms.orbit[1] != 0.0)
    if fl.external_loads:
        acc[ACC_WORK] += apply_external(ms.external, bd.motion, bd.v, bd.w, bd.f, bd.tq,
                                        dt)
    if fl.controllers:
        acc[ACC_WORK] += apply_controllers(ms.ctl_index, ms.ctl_par, ms.ctl_state, bd.pos,
                                           bd.q, bd.v, bd.w, bd.mass, bd.f, bd.tq, time,
                                           dt)
    if fl.local_damping:
        acc[ACC_DISSIPATED] += local_damping(nd.f, nd.t, nd.v, nd.w, nd.inv_mass,
                                             limits[LIMIT_LOCAL_DAMPING], dt,
                                             fl.track_energy)
    if fl.track_energy and (fl.bristle_body or fl.mounted_roots or fl.patches):
        # work done by whatever drives kinematic bodies against the contact forces
        for k in range(bd.pos.shape[0]):
            if bd.motion[k] == KINEMATIC:
                acc[ACC_WORK] -= dt * (bd.f[k, 0] * bd.v[k, 0] + bd.f[k, 1] * bd.v[k, 1]
                                       + bd.f[k, 2] * bd.v[k, 2] + bd.tq[k, 0] * bd.w[k, 0]
                                       + bd.tq[k, 1] * bd.w[k, 1]
                                       + bd.tq[k, 2] * bd.w[k, 2])
    if timed:
        c8 = _clock()
        stage_time[SLOT_EXTERNAL] += c8 - c7
    return OK


@njit(cache=True)
def advance(nd, bn, rt, bd, pl, bl, ld, tb, fl, acc, err, stage_time, dt, n_steps, limits, ms,
            pa):
    """Advance the system by up to ``n_steps`` steps. ``acc`` holds the time, the step count
    and the running energy/contact totals; ``limits`` = [max overlap / radius, max node step
    / radius, max body step (m), skin (m), local damping]; ``ms`` the mission layer (orbit,
    controllers, external loads on bodies); ``pa`` the reduced brushes (engine.kernels.patch).
    Returns (code, steps done)."""
    skin = limits[LIMIT_SKIN]
    orbit_n = ms.orbit[0] if fl.orbit else 0.0
    stats = np.zeros(5)
    watch = fl.bristle_bristle or fl.bristle_body
    # the nodes' part of the lists' check for the coming step, from the last step's second
    # half kick (nodes_kick_watch); below zero at a call's first step, which takes it afresh
    # (between calls the caller may have moved nodes or rebuilt the lists)
    node_move = -1.0
    if acc[ACC_STEPS] == 0:
        # the first half kick needs the forces of the initial state (the later ones use the
        # forces the step before left in place, across calls too): without them a load
        # present at t = 0 lost F dt / 2 of impulse and the leapfrog was first order
        code = evaluate_forces(nd, bn, rt, bd, pl, bl, ld, tb, fl, acc, err, stage_time, 0.0,
                               limits, ms, acc[ACC_TIME], fl.track_energy, False, 0.0, stats,
                               orbit_n, pa)
        if code != OK:
            return code, 0
    for it in range(n_steps):
        timed = fl.time_every > 0 and (int(acc[ACC_STEPS]) % fl.time_every == 0)
        if timed:
            c0 = _clock()
        # ---- neighbour lists valid for the coming drift?
        if watch:
            if node_move < 0.0:
                stale = lists_stale(nd, bd, dt, skin)
            else:
                stale = node_move + body_displacement(bd, dt) > 0.5 * skin
            if stale:
                code = rebuild_lists(nd, bn, bd, pl, bl, fl, skin)
                if code != OK:
                    return code, it
                acc[ACC_REBUILDS] += 1
        if timed:
            c1 = _clock()
            stage_time[SLOT_NEIGHBOUR_LIST] += c1 - c0
        # ---- half kick + drift
        if fl.orbit:
            nodes_kick_drift_cw(nd.x, nd.v, nd.q, nd.w, nd.f, nd.t, nd.inv_mass,
                                nd.inv_inertia, dt, orbit_n)
        else:
            nodes_kick_drift(nd.x, nd.v, nd.q, nd.w, nd.f, nd.t, nd.inv_mass, nd.inv_inertia,
                             dt)
        t_new = acc[ACC_TIME] + dt
        if fl.rigid_bodies:
            bodies_half_kick(bd, tb, acc, dt, orbit_n)
            bodies_drift(bd, dt, t_new, orbit_n)
        if fl.mounted_roots:
            roots_follow(nd.x, nd.v, nd.q, nd.w, rt.node, rt.body, rt.local_pos, rt.local_q,
                         bd.pos, bd.q, bd.v, bd.w)
        acc[ACC_TIME] = t_new
        if timed:
            c2 = _clock()
            stage_time[SLOT_INTEGRATE] += c2 - c1
        # ---- forces
        last = it == n_steps - 1
        want_energy = fl.track_energy and last
        code = evaluate_forces(nd, bn, rt, bd, pl, bl, ld, tb, fl, acc, err, stage_time, dt,
                               limits, ms, t_new, want_energy, timed, c2 if timed else 0.0,
                               stats, orbit_n, pa)
        if code != OK:
            return code, it + 1
        if timed:
            c8 = _clock()
        # ---- second half kick
        if watch:
            node_move = nodes_kick_watch(nd.x, nd.x_build, nd.v, nd.w, nd.f, nd.t,
                                         nd.inv_mass, nd.inv_inertia, dt)
        else:
            nodes_kick(nd.v, nd.w, nd.f, nd.t, nd.inv_mass, nd.inv_inertia, dt)
        if fl.rigid_bodies:
            bodies_half_kick(bd, tb, acc, dt, orbit_n)
        acc[ACC_STEPS] += 1
        if timed:
            c9 = _clock()
            stage_time[SLOT_INTEGRATE] += c9 - c8
        if last or (int(acc[ACC_STEPS]) % fl.check_every == 0):
            code = check_state(nd, bd, fl, acc, err, dt, limits, t_new)
            if code != OK:
                return code, it + 1
        if timed:
            stage_time[SLOT_CHECKS] += _clock() - c9
            acc[ACC_TIMED_STEPS] += 1
    return OK, n_steps
