"""Bristle-body narrow phase per candidate, split into its parts, on frozen states: the 40 x 25
box-pressed brush of ``throughput.box_scene`` (8 nodes, a 12-triangle box, 10 ms into the
tips) and ``detumble_upper_stage`` (the 17 x 5 brush rubbing a 64-facet cylinder).

Each scene is run to a state in contact, then the kernels are called again and again on that
one state from a compiled loop (the narrow phase's contact history put back before every
call, so each call sees the same state) and timed with ``time.process_time`` (CPU seconds
of this process), the median of ``--repeats``. Printed, in ns per candidate:

* ``narrow``: ``body_contacts.bristle_body_narrow`` as the step loop calls it (the whole
  per-candidate work: body frame, closest features, contact law, history, fade forces);
* ``frame``: the candidate loop with only the segment's transform into the body frame;
* ``search``: ``frame`` plus the closest-feature searches of the narrow phase (a node's
  triangle within its radius for slots 0 and 1, the segment's within the larger radius for
  slot 2) as the narrow phase makes them: from the candidate's face of the last step where
  that face's plane settles them (``supported_face``, the hint the narrow phase keeps: the
  loop above has just set it), else one walk of the body's grid (``closest_features``), or
  a walk per query (``closest_triangle``) on an engine without either; none of the law;
* ``walk``: ``search`` with the walk for every candidate (an engine with the face hint);
* ``law`` = narrow - search: the contact law (normal force, damping, friction with history,
  fade forces), and the call of the per-candidate kernel (which ``search`` makes inline);
* ``scatter``: ``scatter_bristle_body`` (the forces into nodes and bodies, serial);
* ``rebuild``: the candidate list's rebuild (``build_body_candidates``), per call (a step
  pays it only when the lists are stale).

Also the candidates whose slots touch, and the whole step (``engine.run`` from the frozen
state, ``System.save_state``/``restore_state``, median of 3 runs).

Usage (from the repository root)::

    NUMBA_NUM_THREADS=1 python benchmarks/body_kernel.py [--repeats 7] [--only box|detumble]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT))

from engine.kernels.body_contacts import (BSLOT, bristle_body_narrow,  # noqa: E402
                                          build_body_candidates, closest_triangle,
                                          scatter_bristle_body)
from engine.kernels.rotations import qrot_inv  # noqa: E402


def box_system():
    import engine
    from throughput import box_scene
    scene, warm = box_scene(25, 40)
    system = engine.build(engine.parse_scene(scene))
    out = Path(tempfile.mkdtemp(prefix="body-kernel-"))
    engine.run(system, until=warm, output=out / "warm.h5")
    return system, out


def detumble_system():
    import engine
    from engine.state import ACC_N_BODY
    system = engine.build(engine.load_scene(ROOT / "static_presets" / "detumble_upper_stage.json"))
    out = Path(tempfile.mkdtemp(prefix="body-kernel-"))
    # run on until the brush is well into the target (the chaser approaches from 10 mm out)
    for i in range(200):
        engine.run(system, until=system.time + 0.05, output=out / f"w{i}.h5")
        if int(system.acc[ACC_N_BODY]) >= 60:
            break
    return system, out


@njit(cache=True)
def _narrow_loop(nd, bn, bl, bd, tb, friction, dt, ft0, reps):
    """``reps`` calls of the narrow phase, each on the same history (put back first)."""
    m = ft0.shape[0]
    for _ in range(reps):
        bl.ft[:m] = ft0
        bristle_body_narrow(nd, bn, bl, bd, tb, friction, dt)


@njit(cache=True)
def _scatter_loop(nd, bn, bl, bd, stats, reps):
    for _ in range(reps):
        scatter_bristle_body(nd, bn, bl, bd, stats)


def _rebuild_kernel():
    """``reps`` rebuilds of the candidate list, as the step loop's rebuild makes them
    (``neighbours.build_body_list``; ``build_body_candidates`` with the arguments it had on
    an engine without it)."""
    try:
        from engine.kernels.neighbours import build_body_list
    except ImportError:
        @njit
        def loop(nd, bn, bd, bl, skin, reps):
            n = 0
            for _ in range(reps):
                n = build_body_candidates(
                    bn.mid, bn.bound, bn.mount, bd.pos, bd.bound_r, bd.collide, skin, bl.s2,
                    bl.b2, bl.deep2, nd.x, nd.rad, bn.i, bn.j, bn.rmax, bd.q, bd.sphere_r,
                    bd.watertight, bd.verts, bd.tris, bd.tnormal, bd.tedge, bd.pnormal,
                    bd.grid_origin, bd.grid_cell, bd.grid_dims, bd.grid_base, bd.grid_start,
                    bd.grid_tris, bd.grid_side, bd.scratch2)
            return n
        return loop

    @njit
    def loop(nd, bn, bd, bl, skin, reps):
        n = 0
        for _ in range(reps):
            n = build_body_list(nd, bn, bd, bl, skin)
        return n
    return loop


@njit(cache=True)
def _frame_only(nd, bn, bl, bd, reps):
    """The candidate loop with only the body-frame transform of each segment."""
    acc = 0.0
    x, bi, bj, cs, cb, local = nd.x, bn.i, bn.j, bl.s, bl.b, bl.local
    for _ in range(reps):
        for c in range(bl.n[0]):
            sg = cs[c]
            k = cb[c]
            i0 = bi[sg]
            i1 = bj[sg]
            l0 = local[c, 0]
            l1 = local[c, 1]
            qw, qx, qy, qz = bd.q[k, 0], bd.q[k, 1], bd.q[k, 2], bd.q[k, 3]
            l0[0], l0[1], l0[2] = qrot_inv(qw, qx, qy, qz, x[i0, 0] - bd.pos[k, 0],
                                           x[i0, 1] - bd.pos[k, 1], x[i0, 2] - bd.pos[k, 2])
            l1[0], l1[1], l1[2] = qrot_inv(qw, qx, qy, qz, x[i1, 0] - bd.pos[k, 0],
                                           x[i1, 1] - bd.pos[k, 1], x[i1, 2] - bd.pos[k, 2])
            acc += l0[0] + l1[2]
    return acc


@njit(cache=True)
def _search_walks(nd, bn, bl, bd, reps):
    """``_frame_only`` plus the closest-feature searches as the narrow phase made them
    before the one-walk search: a ``closest_triangle`` walk per query (slot 0's node, slot
    1's tip node, slot 2's segment). Returns the sum of the distances found within reach
    (so that nothing is optimised away)."""
    x, rad, bi, bj, has_next = nd.x, nd.rad, bn.i, bn.j, bn.has_next
    cs, cb, local = bl.s, bl.b, bl.local
    tot = 0.0
    for _ in range(reps):
        for c in range(bl.n[0]):
            sg = cs[c]
            k = cb[c]
            i0 = bi[sg]
            i1 = bj[sg]
            l0 = local[c, 0]
            l1 = local[c, 1]
            qw, qx, qy, qz = bd.q[k, 0], bd.q[k, 1], bd.q[k, 2], bd.q[k, 3]
            l0[0], l0[1], l0[2] = qrot_inv(qw, qx, qy, qz, x[i0, 0] - bd.pos[k, 0],
                                           x[i0, 1] - bd.pos[k, 1], x[i0, 2] - bd.pos[k, 2])
            l1[0], l1[1], l1[2] = qrot_inv(qw, qx, qy, qz, x[i1, 0] - bd.pos[k, 0],
                                           x[i1, 1] - bd.pos[k, 1], x[i1, 2] - bd.pos[k, 2])
            if bd.sphere_r[k] > 0.0:
                continue
            for slot_k in range(3):
                if slot_k == 1 and has_next[sg]:
                    continue
                if slot_k <= 1:
                    pe = l0 if slot_k == 0 else l1
                    re = rad[i0] if slot_k == 0 else rad[i1]
                    tri, s, u, v, w, d = closest_triangle(
                        k, pe, pe, re, bd.verts, bd.tris, bd.tnormal, bd.tedge,
                        bd.grid_origin, bd.grid_cell, bd.grid_dims, bd.grid_base,
                        bd.grid_start, bd.grid_tris)
                else:
                    tri, s, u, v, w, d = closest_triangle(
                        k, l0, l1, max(rad[i0], rad[i1]), bd.verts, bd.tris, bd.tnormal,
                        bd.tedge, bd.grid_origin, bd.grid_cell, bd.grid_dims, bd.grid_base,
                        bd.grid_start, bd.grid_tris)
                if tri >= 0:
                    tot += d
    return tot


def _search_one_walk(hinted):
    """``_search_walks`` with the one-walk search of this engine (``closest_features``),
    compiled only where the engine has it (so that this script also times an engine
    without it, through ``_search_walks``); ``hinted``: first, as the narrow phase does,
    the candidate's face of the last step where it settles the queries
    (``supported_face``, on an engine that has it)."""
    from engine.kernels.body_contacts import closest_features
    if hinted:
        from engine.kernels.body_contacts import supported_face
    else:
        supported_face = None

    @njit
    def search(nd, bn, bl, bd, reps):
        x, rad, bi, bj, has_next = nd.x, nd.rad, bn.i, bn.j, bn.has_next
        cs, cb, local = bl.s, bl.b, bl.local
        tot = 0.0
        for _ in range(reps):
            for c in range(bl.n[0]):
                sg = cs[c]
                k = cb[c]
                i0 = bi[sg]
                i1 = bj[sg]
                l0 = local[c, 0]
                l1 = local[c, 1]
                qw, qx, qy, qz = bd.q[k, 0], bd.q[k, 1], bd.q[k, 2], bd.q[k, 3]
                l0[0], l0[1], l0[2] = qrot_inv(qw, qx, qy, qz, x[i0, 0] - bd.pos[k, 0],
                                               x[i0, 1] - bd.pos[k, 1],
                                               x[i0, 2] - bd.pos[k, 2])
                l1[0], l1[1], l1[2] = qrot_inv(qw, qx, qy, qz, x[i1, 0] - bd.pos[k, 0],
                                               x[i1, 1] - bd.pos[k, 1],
                                               x[i1, 2] - bd.pos[k, 2])
                if bd.sphere_r[k] > 0.0:
                    continue
                if hinted:
                    h = supported_face(bl.face[c], k, l0, l1, rad[i0], rad[i1],
                                       max(rad[i0], rad[i1]), not has_next[sg], bd.verts,
                                       bd.tris, bd.tnormal, bd.tsupport)
                    if h[0]:
                        tot += (h[5] if h[1] >= 0 else 0.0) + (h[10] if h[6] >= 0 else 0.0)
                        continue
                r = closest_features(k, l0, l1, rad[i0], rad[i1], max(rad[i0], rad[i1]),
                                     not has_next[sg], bd.verts, bd.tris, bd.tnormal,
                                     bd.tedge, bd.grid_origin, bd.grid_cell, bd.grid_dims,
                                     bd.grid_base, bd.grid_start, bd.grid_tris)
                tot += (r[4] if r[0] >= 0 else 0.0) + (r[9] if r[5] >= 0 else 0.0) + (
                    r[15] if r[10] >= 0 else 0.0)
        return tot
    return search


def _search_kernel():
    """(the search as the narrow phase makes it, how), (the walk alone, how) or None."""
    try:
        walk = _search_one_walk(False), "one walk (closest_features)"
    except ImportError:
        return (_search_walks, "a walk per query (closest_triangle)"), None
    try:
        return (_search_one_walk(True), "last step's face where it settles them "
                "(supported_face), else one walk"), walk
    except ImportError:
        return walk, None


def _timed(fn, repeats, inner):
    """Median CPU seconds of one call (each repeat times ``inner`` calls inside compiled
    code, so that Python's dispatch is not counted)."""
    fn(1)
    runs = []
    for _ in range(repeats):
        c0 = time.process_time()
        fn(inner)
        runs.append((time.process_time() - c0) / inner)
    return float(np.median(runs))


def measure(name, system, out, repeats):
    import engine
    from engine.state import ACC_N_BODY
    nd, bn, bl, bd, tb, fl = (system.nodes, system.bonds, system.body_pairs, system.bodies,
                              system.tables, system.flags)
    dt = system.dt
    n = int(bl.n[0])
    ft0 = bl.ft[:n * BSLOT].copy()
    keep = [a.copy() for a in (nd.f, nd.t, bd.f, bd.tq)]
    stats = np.zeros(5)
    inner = max(1, int(4e5 // max(n, 1)))
    skin = float(system.limits[3])
    (search, how), walk = _search_kernel()
    t_narrow = _timed(lambda r: _narrow_loop(nd, bn, bl, bd, tb, fl.friction_body, dt, ft0, r),
                      repeats, inner)
    bl.ft[:n * BSLOT] = ft0
    _narrow_loop(nd, bn, bl, bd, tb, fl.friction_body, dt, ft0, 1)
    touching = int(bl.active[:n * BSLOT].reshape(n, BSLOT).any(axis=1).sum())
    slots = int(bl.active[:n * BSLOT].sum())
    t_scatter = _timed(lambda r: _scatter_loop(nd, bn, bl, bd, stats, r), repeats, inner)
    t_frame = _timed(lambda r: _frame_only(nd, bn, bl, bd, r), repeats, inner)
    t_search = _timed(lambda r: search(nd, bn, bl, bd, r), repeats, inner)
    t_walk = _timed(lambda r: walk[0](nd, bn, bl, bd, r), repeats, inner) if walk else None
    rebuild = _rebuild_kernel()
    t_rebuild = _timed(lambda r: rebuild(nd, bn, bd, bl, skin, r), repeats,
                       max(1, inner // 4))
    bl.ft[:n * BSLOT] = ft0
    for a, b in zip((nd.f, nd.t, bd.f, bd.tq), keep):
        a[:] = b
    # the step as a whole, from here on (each call a fresh run of the same state)
    snap = system.save_state()
    steps = max(50, int(2e6 // max(system.n_nodes, 1)) // 10)
    step_runs = []
    for i in range(3):
        system.restore_state(snap)
        c0 = time.process_time()
        engine.run(system, until=system.time + steps * system.dt, output=out / f"s{i}.h5")
        step_runs.append((time.process_time() - c0) / steps)
    t_step = float(np.median(step_runs))
    system.restore_state(snap)
    ns = 1e9 / max(n, 1)
    print(f"{name}: {n} candidates ({touching} touching, {slots} active slots), "
          f"{system.n_nodes} nodes, {int(system.acc[ACC_N_BODY])} contacts")
    print(f"  narrow  {t_narrow * ns:8.1f} ns/candidate  ({t_narrow * 1e6:.1f} us per call)")
    print(f"    frame   {t_frame * ns:8.1f}")
    print(f"    search  {(t_search - t_frame) * ns:8.1f}  (closest features, {how})")
    if walk:
        print(f"    walk    {(t_walk - t_frame) * ns:8.1f}  (the search by {walk[1]} alone)")
    print(f"    law     {(t_narrow - t_search) * ns:8.1f}  (narrow - search: law and kernel call)")
    print(f"  scatter {t_scatter * ns:8.1f} ns/candidate")
    print(f"  rebuild {t_rebuild * ns:8.1f} ns/candidate per rebuild")
    print(f"  step    {t_step * 1e6:8.1f} us ({t_step * ns:.1f} ns/candidate; "
          f"narrow + scatter {100 * (t_narrow + t_scatter) / t_step:.0f} % of it; "
          f"{system.n_nodes / t_step / 1e6:.2f} M node-steps/CPU-s)", flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--only", choices=("box", "detumble"))
    a = ap.parse_args(argv)
    import engine
    print(f"engine {engine.__file__}")
    if a.only in (None, "box"):
        measure("box 40x25x8", *box_system(), a.repeats)
    if a.only in (None, "detumble"):
        measure("detumble_upper_stage", *detumble_system(), a.repeats)


if __name__ == "__main__":
    main()
