"""The seed's headline experiment as users run it: the 60 degree wedge study, timed.

Each case is one ``brush-studio study wedge`` command in a fresh process (start-up included),
with a warm numba cache (a warm-up command runs first and is not counted). CPU seconds are
the child's user + system time (``resource.getrusage(RUSAGE_CHILDREN)``); the study's own
``study.json`` gives the steps, dt and forces.

- ``load20``: ``static_presets/wedge_60.json`` at its 8 nodes, loading 0 -> 20 mm, one
  worker, ``NUMBA_NUM_THREADS=1``: CPU-s, wall, steps, dt, node-steps per CPU-second, the
  force at 5/10/20 mm, and the ratio against YADE 2023.02a's 130 CPU-s for the same loading
  curve (measured on this kind of machine, single-threaded, grid/pfacet, each within 5 % of
  its own converged curve). **Target: <= 6.5 CPU-s (20x YADE).**
- ``cycle``: the full cycle, 33 mm down and back, with ``NUMBA_NUM_THREADS=2`` (both cores of
  this machine for the one run). **Target: <= 60 s wall on 2 cores.**
- ``dynamic10`` (``--dynamic``): the seed's plain dynamic protocol (``--method dynamic``),
  0 -> 10 mm at 5 nodes, beside the quasi-static method on the same case: the force at every
  depth from both, and their costs.
- ``montecarlo`` (``--montecarlo``, about half an hour): ``study montecarlo --samples 100``
  of the 60 degree wedge at the preset's resolution and full depth, on 2 workers.
  **Target: <= 30 min on 2 cores.**

Usage::

    python benchmarks/wedge_study.py                 # load20 and cycle, a few minutes
    python benchmarks/wedge_study.py --dynamic       # + the dynamic protocol comparison
    python benchmarks/wedge_study.py --montecarlo    # + the 100-sample Monte Carlo
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PRESET = str(ROOT / "static_presets" / "wedge_60.json")
YADE_LOAD20_CPU_S = 130.0
CLI = [sys.executable, "-m", "studio.cli"]


def run_cli(args: list[str], threads: int) -> tuple[float, float]:
    """(CPU s, wall s) of one CLI command and its children; it must succeed."""
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(CLI + args, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        sys.exit(f"failed ({proc.returncode}): {' '.join(args)}\n{proc.stdout}\n{proc.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall


def forces(out: Path) -> dict[tuple[float, str], float]:
    with open(out / "force_depth.csv") as fh:
        return {(round(float(r["depth_m"]) * 1e3, 6), r["phase"]): float(r["force_N"])
                for r in csv.DictReader(fh)}


def study(out: Path, extra: list[str], threads: int) -> dict:
    cpu, wall = run_cli(["study", "wedge", "--preset", PRESET, "--workers", "1",
                         "--no-progress", "-o", str(out)] + extra, threads)
    info = json.loads((out / "study.json").read_text())
    check = next(iter(info["checks"].values()))
    n_nodes = check["n_nodes"]
    return {"cpu_s": cpu, "wall_s": wall, "steps": check["steps"], "dt": check["dt"],
            "n_nodes": n_nodes, "node_steps_per_cpu_s": check["steps"] * n_nodes / cpu,
            "forces": forces(out), "method": info["protocols"]
            [next(iter(info["protocols"]))].get("method", "dynamic")}


def show(name: str, r: dict, depths=(5, 10, 20)) -> None:
    f = r["forces"]
    fs = "  ".join(f"F({d} mm) {f[(float(d), 'load')] * 1e3:.4g} mN" for d in depths
                   if (float(d), "load") in f)
    print(f"{name:<10} {r['method']:<12} {r['cpu_s']:8.2f} CPU-s {r['wall_s']:8.2f} s wall "
          f"{r['steps']:>9} steps  dt {r['dt']:.3g} s  {r['n_nodes']} nodes  "
          f"{r['node_steps_per_cpu_s'] / 1e6:.2f} M node-steps/CPU-s")
    print(f"{'':<10} {fs}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dynamic", action="store_true",
                    help="also the plain dynamic protocol, 0 -> 10 mm at 5 nodes")
    ap.add_argument("--montecarlo", action="store_true",
                    help="also the 100-sample Monte Carlo (about 30 min)")
    ap.add_argument("--skip-cycle", action="store_true", help="leave the full cycle out")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="wedge-bench-"))
    print(f"warming the numba cache ({work})", flush=True)
    run_cli(["study", "wedge", "--preset", PRESET, "--depth-mm", "1", "--nodes", "3",
             "--no-unload", "--workers", "1", "--no-progress", "-o", str(work / "warm")], 1)

    r = study(work / "load20", ["--depth-mm", "20", "--no-unload"], threads=1)
    show("load20", r)
    print(f"{'':<10} YADE 2023.02a: {YADE_LOAD20_CPU_S:g} CPU-s -> "
          f"{YADE_LOAD20_CPU_S / r['cpu_s']:.1f}x faster (target 20x: <= 6.5 CPU-s)",
          flush=True)
    if not args.skip_cycle:
        r = study(work / "cycle", [], threads=2)
        show("cycle", r, depths=(5, 10, 20, 33))
        print(f"{'':<10} target: <= 60 s wall on 2 cores", flush=True)
    if args.dynamic:
        q = study(work / "qs10", ["--depth-mm", "10", "--nodes", "5", "--no-unload"], 1)
        d = study(work / "dyn10", ["--depth-mm", "10", "--nodes", "5", "--no-unload",
                                   "--method", "dynamic"], 1)
        show("qs10", q, depths=(5, 10))
        show("dyn10", d, depths=(5, 10))
        print(f"{'':<10} depth mm   quasi-static mN   dynamic mN   difference")
        for k in sorted(d["forces"]):
            if k in q["forces"] and k[0] > 0:
                a, b = q["forces"][k], d["forces"][k]
                print(f"{'':<10} {k[0]:>8g}   {a * 1e3:>15.4g}   {b * 1e3:>10.4g}   "
                      f"{(a - b) * 1e3:+.3g} mN ({(a - b) / b:+.1%})")
        print(f"{'':<10} cost ratio dynamic/quasi-static: {d['cpu_s'] / q['cpu_s']:.1f}x CPU",
              flush=True)
    if args.montecarlo:
        out = work / "mc"
        cpu, wall = run_cli(["study", "montecarlo", "--samples", "100", "--preset", PRESET,
                             "--workers", "2", "--no-progress", "-o", str(out)], 1)
        print(f"montecarlo 100 samples, preset resolution: {cpu:.0f} CPU-s, {wall:.0f} s wall "
              f"= {wall / 60:.1f} min on 2 cores (target <= 30 min)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
