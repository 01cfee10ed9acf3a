"""One thread against two on the box-pressed brushes of ``throughput.box_scene`` (8 nodes per
bristle, a box moving 10 mm/s into the tips): wall and CPU seconds per step of the compiled
step loop, at several brush sizes, each (size, threads) pair in a fresh child process
(``NUMBA_NUM_THREADS`` set before numba starts), the pairs interleaved 1, 2, 1, 2, ... so that
a drift of the machine's load falls on both. CPU is ``time.process_time`` of the child (every
thread); wall is ``time.perf_counter``; both around ``engine.run`` of the timed steps only,
after a warm-up into contact. The machine's load average is printed before and after: on a
shared machine the second core may be busy, which the ratio then shows.

A kernel switches to its ``prange`` loop from its threshold in ``engine.kernels.bonds``
(``PARALLEL_MIN`` nodes for the kicks and drifts, ``PARALLEL_MIN_BONDS`` nodes for the bonds,
``PARALLEL_MIN_CANDIDATES`` bristle-body candidates), so the table says which of the step's
kernels ran in parallel on two threads.

Usage (from the repository root)::

    python benchmarks/threads.py [--sizes 25 50 100] [--repeats 3]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

_CHILD = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
from throughput import box_scene
import engine
side, steps, out = int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
scene, warm = box_scene(side, side)
system = engine.build(engine.parse_scene(scene))
engine.run(system, until=warm, output=out + "/warm.h5")
c0, w0 = time.process_time(), time.perf_counter()
engine.run(system, until=system.time + steps * system.dt, output=out + "/timed.h5")
cpu, wall = time.process_time() - c0, time.perf_counter() - w0
print(json.dumps({"nodes": system.n_nodes, "candidates": int(system.body_pairs.n[0]),
                  "cpu": cpu / steps, "wall": wall / steps}))
"""


def run_child(side: int, steps: int, threads: int) -> dict:
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    out = tempfile.mkdtemp(prefix="threads-")
    p = subprocess.run([sys.executable, "-c", _CHILD, str(HERE), str(side), str(steps), out],
                       env=env, cwd=ROOT, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"child failed ({side}, {threads} threads):\n{p.stderr[-3000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[25, 36, 50, 100],
                    help="brush side (side x side bristles)")
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args(argv)
    from engine.kernels import bonds
    limits = {"nodes": getattr(bonds, "PARALLEL_MIN"),
              "bonds": getattr(bonds, "PARALLEL_MIN_BONDS", bonds.PARALLEL_MIN),
              "candidates": getattr(bonds, "PARALLEL_MIN_CANDIDATES", bonds.PARALLEL_MIN)}
    print(f"load average before: {os.getloadavg()}; cores {os.cpu_count()}; "
          f"thresholds {limits}", flush=True)
    run_child(10, 10, 1)  # fill the numba cache (not counted)
    print(f"{'bristles':>8} {'nodes':>7} {'cand.':>6} | {'1 thread us/step':>16} "
          f"{'2 threads wall':>14} {'2 thr. CPU':>10} | {'wall 2/1':>8} {'CPU 2/1':>7}  "
          f"parallel kernels")
    for side in a.sizes:
        steps = max(50, int(1.2e7 / (side * side * 8)))
        runs = {1: [], 2: []}
        for _ in range(a.repeats):
            for t in (1, 2):
                runs[t].append(run_child(side, steps, t))
        r1 = runs[1][0]
        w1 = float(np.median([r["wall"] for r in runs[1]]))
        c1 = float(np.median([r["cpu"] for r in runs[1]]))
        w2 = float(np.median([r["wall"] for r in runs[2]]))
        c2 = float(np.median([r["cpu"] for r in runs[2]]))
        ratio_w = float(np.median([b["wall"] / a_["wall"] for a_, b in zip(runs[1], runs[2])]))
        ratio_c = float(np.median([b["cpu"] / a_["cpu"] for a_, b in zip(runs[1], runs[2])]))
        par = [k for k, n in (("nodes", r1["nodes"]), ("bonds", r1["nodes"]),
                              ("candidates", r1["candidates"])) if n >= limits[k]]
        print(f"{side * side:>8} {r1['nodes']:>7} {r1['candidates']:>6} | "
              f"{w1 * 1e6:>9.0f} wall {c1 * 1e6:>6.0f} CPU  {w2 * 1e6:>9.0f} wall "
              f"{c2 * 1e6:>6.0f} CPU | {ratio_w:>8.2f} {ratio_c:>7.2f}  "
              f"{', '.join(par) or 'none'}", flush=True)
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
