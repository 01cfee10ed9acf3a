"""Bristle-bristle narrow phase per listed pair on the wedge's deep states (issue 26 item 4).

The wedge_60 preset's brush is pressed 20 and 33 mm by the wedge (``bond_kernel.wedge_system``,
8 nodes per bristle, frictional contacts with history), and ``contacts.bristle_bristle_narrow``
is called again and again on that one state from a compiled loop (the pairs' tangential
history put back before each repeat) and timed with ``time.process_time`` (CPU seconds of
this process), the median of ``--repeats``. The pair list is then cut into three classes
and each is timed alone, in ns per pair:

* ``apart``: capsules apart (axis distance at least both segments' largest radii): no
  slot can touch, the pair's slots are cleared;
* ``near``: capsules within reach but no slot touching (node and crossing tests only);
* ``touching``: at least one slot in contact (the contact law too);
* ``all``: the list as the step loop has it.

Also the pair list's rebuild (``contacts.segment_bounds`` and ``build_pair_list`` from the
state, us per rebuild; ``--detumble`` adds it for ``detumble_upper_stage`` 3,000 steps in,
whose 17 x 5 brush of long segments has no pair touching) and the whole step
(``run_steps`` from the state, median of 3). Usage (repository root)::

    NUMBA_NUM_THREADS=1 python benchmarks/pair_kernel.py [--repeats 5] [--depths 20 33] [--detumble]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from bond_kernel import detumble_system, wedge_system  # noqa: E402
from engine.kernels.contacts import (NSLOT, bristle_bristle_narrow,  # noqa: E402
                                     build_pair_list, segment_bounds)
from engine.state import LIMIT_SKIN  # noqa: E402
from engine.kernels.geometry import segment_segment_closest  # noqa: E402
from engine.stepping.loop import run_steps  # noqa: E402


@njit
def _calls(nd, bn, pl, tb, friction, dt, n):
    for _ in range(n):
        bristle_bristle_narrow(nd, bn, pl, tb, friction, dt)


@njit
def _rebuilds(nd, bn, pl, skin, n):
    found = 0
    for _ in range(n):
        segment_bounds(nd.x, nd.rad, bn.i, bn.j, bn.mid, bn.bound)
        found = build_pair_list(bn.mid, bn.bound, bn.bristle, skin, pl.a2, pl.b2, nd.x, bn.i,
                                bn.j, bn.rmax)
    return found


def rebuild_us(system, repeats: int, calls: int = 200) -> tuple[float, int]:
    """(CPU us per rebuild of the pair list from the system's state, pairs it finds); the
    list's second rows only, which the step loop copies from after a rebuild."""
    nd, bn, pl = system.nodes, system.bonds, system.pairs
    skin = float(system.limits[LIMIT_SKIN])
    found = _rebuilds(nd, bn, pl, skin, 1)
    out = []
    for _ in range(repeats):
        t0 = time.process_time()
        _rebuilds(nd, bn, pl, skin, calls)
        out.append((time.process_time() - t0) / calls * 1e6)
    return statistics.median(out), int(found)


def _apart(system, a, b) -> np.ndarray:
    """Per pair, whether the capsules are apart (the narrow phase's own first test)."""
    x, rad, bi, bj = system.nodes.x, system.nodes.rad, system.bonds.i, system.bonds.j
    out = np.zeros(len(a), bool)
    for p in range(len(a)):
        i0, i1, j0, j1 = bi[a[p]], bj[a[p]], bi[b[p]], bj[b[p]]
        s, t = segment_segment_closest(tuple(x[i0]), tuple(x[i1]), tuple(x[j0]), tuple(x[j1]))
        g = x[i0] + s * (x[i1] - x[i0]) - x[j0] - t * (x[j1] - x[j0])
        reach = max(rad[i0], rad[i1]) + max(rad[j0], rad[j1])
        out[p] = g @ g >= reach * reach
    return out


def measure(depth_mm: float, repeats: int, calls: int) -> None:
    system = wedge_system(depth_mm / 1e3)
    nd, bn, pl, tb = system.nodes, system.bonds, system.pairs, system.tables
    friction, dt = system.flags.friction_bristle, system.dt
    snap = system.save_state()
    n = int(pl.n[0])
    a0, b0 = pl.a[:n].copy(), pl.b[:n].copy()
    _calls(nd, bn, pl, tb, friction, dt, 1)
    touching = pl.active[:n * NSLOT].reshape(n, NSLOT).any(axis=1)
    apart = _apart(system, a0, b0)
    print(f"wedge {depth_mm:g} mm ({system.n_nodes} nodes): {n} pairs listed, "
          f"{int(apart.sum())} apart, {int((~apart & ~touching).sum())} near, "
          f"{int(touching.sum())} touching")
    for name, keep in (("apart", apart), ("near", ~apart & ~touching),
                       ("touching", touching), ("all", np.ones(n, bool))):
        k = int(keep.sum())
        if k == 0:
            continue
        system.restore_state(snap)
        pl.a[:k], pl.b[:k], pl.n[0] = a0[keep], b0[keep], k
        ft = pl.ft.copy()
        out = []
        for _ in range(repeats):
            pl.ft[:] = ft
            t0 = time.process_time()
            _calls(nd, bn, pl, tb, friction, dt, calls)
            out.append((time.process_time() - t0) / calls / k * 1e9)
        print(f"  {name:<9} {k:5d} pairs  {statistics.median(out):7.1f} ns per pair")
    system.restore_state(snap)
    us, found = rebuild_us(system, repeats)
    print(f"  list rebuild {us:7.1f} us ({bn.i.shape[0]} segments, {found} pairs)")
    out = []
    for _ in range(3):
        system.restore_state(snap)
        t0 = time.process_time()
        run_steps(system, 2000)
        out.append((time.process_time() - t0) / 2000 * 1e6)
    print(f"  whole step {statistics.median(out):7.1f} us")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--depths", type=float, nargs="+", default=[20.0, 33.0])
    ap.add_argument("--detumble", action="store_true",
                    help="also the pair list's rebuild on detumble_upper_stage")
    args = ap.parse_args(argv)
    for d in args.depths:
        measure(d, args.repeats, args.calls)
    if args.detumble:
        system = detumble_system()
        us, found = rebuild_us(system, args.repeats)
        print(f"detumble_upper_stage ({system.n_nodes} nodes): list rebuild {us:7.1f} us "
              f"({system.bonds.i.shape[0]} segments, {found} pairs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
