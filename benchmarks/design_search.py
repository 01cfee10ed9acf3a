"""Design search (``study optimise``) benchmark: per-trial overhead and the seed's example.

Measures, from a fresh output folder each time:

1. per-trial overhead: a search of ``--trials`` designs on a tiny spin-cube scene (the
   ``spin_cube_20`` preset with a 2 x 5 brush, 3 nodes per bristle, 0.25 s per run), in this
   process (one worker, as ``--workers 1``). The overhead is the search's CPU seconds (this
   process and its children) minus the CPU the runs spent in ``engine.build`` + ``engine.run``
   (measured inside each run's task), per trial: Optuna's ask/tell and journal, the run
   files, reading each run's result back and scoring it. Target: <= 0.5 CPU-s per trial.
2. with ``--example``: ``examples/06_optimum_stiffness.py`` run as a user would (a
   subprocess), its wall time and CPU seconds (the subprocess and its descendants). Target:
   <= 20 min wall on 2 cores.

Usage::

    python benchmarks/design_search.py                # overhead only (a few minutes cold)
    python benchmarks/design_search.py --example      # and the example
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))


def cpu_s() -> float:
    """CPU seconds of this process and its waited-for children."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + ch.ru_utime + ch.ru_stime


def overhead(trials: int) -> dict:
    from studio.studies.optimise import Options
    from studio.studies.optimise.search import Problem, search

    options = Options(preset="spin_cube_20", variables=["bending_stiffness=1e-5:1e-4:log"],
                      cubes_mm=[20.0], duration_s=0.25, nodes=3, workers=1,
                      no_progress=True, refine=False, trials=trials)
    problem = Problem.from_options(options)
    problem.base["brushes"][0]["rows"] = 2
    with tempfile.TemporaryDirectory(prefix="design-search-bench-") as tmp:
        # a warm-up search elsewhere: the kernels compiled (or loaded) before the timing
        search(problem, Path(tmp) / "warm", trials=1, cpu_budget_s=None, workers=1)
        c0, w0 = cpu_s(), time.perf_counter()
        _, log = search(problem, Path(tmp) / "timed", trials=trials, cpu_budget_s=None,
                        workers=1)
        cpu, wall = cpu_s() - c0, time.perf_counter() - w0
    return {"trials": log.trials_run, "runs": log.runs_run, "cpu_s": cpu, "wall_s": wall,
            "sim_cpu_s": log.sim_cpu_s,
            "overhead_cpu_s_per_trial": (cpu - log.sim_cpu_s) / max(log.trials_run, 1)}


def example() -> dict:
    with tempfile.TemporaryDirectory(prefix="design-search-example-") as tmp:
        env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
        c0, w0 = cpu_s(), time.perf_counter()
        proc = subprocess.run([sys.executable, str(ROOT / "examples" /
                                                   "06_optimum_stiffness.py"), tmp],
                              cwd=ROOT, env=env, capture_output=True, text=True)
        cpu, wall = cpu_s() - c0, time.perf_counter() - w0
        if proc.returncode:
            print(proc.stdout + proc.stderr, file=sys.stderr)
            raise SystemExit(f"example exited {proc.returncode}")
        runs = next((ln for ln in proc.stdout.splitlines() if ln.startswith("runs:")), "")
    return {"cpu_s": cpu, "wall_s": wall, "runs_line": runs, "stdout": proc.stdout}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=6)
    ap.add_argument("--example", action="store_true", help="also time examples/06")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, python {sys.version.split()[0]}")
    r = overhead(args.trials)
    print(f"search of {r['trials']} trials ({r['runs']} runs), in process: "
          f"{r['cpu_s']:.2f} CPU-s, {r['wall_s']:.2f} s wall; runs (build + run) "
          f"{r['sim_cpu_s']:.2f} CPU-s")
    print(f"per-trial overhead beyond the simulations: "
          f"{r['overhead_cpu_s_per_trial']:.3f} CPU-s (target <= 0.5)")
    if args.example:
        e = example()
        print(e["stdout"].rstrip())
        print(f"examples/06_optimum_stiffness.py: {e['wall_s']:.1f} s wall, "
              f"{e['cpu_s']:.1f} CPU-s (with its descendants); {e['runs_line']}")


if __name__ == "__main__":
    main()
