"""What start-up costs, in CPU seconds, with a warm numba cache.

Each figure is the CPU time (user + system) of a fresh child process and everything it
waited for (``resource.getrusage(RUSAGE_CHILDREN)``), the median of ``--repeat`` runs:

- ``python -c pass``: the interpreter alone, for reference;
- ``python -c "import engine"``;
- ``brush-studio --help`` (builds the whole parser, every subcommand's module imported);
- ``brush-studio validate wedge_60.json`` (loads the scene, builds the system: this one
  imports numba, the kernels and trimesh, because ``engine.build`` calls kernels);
- a tiny study, ``brush-studio study wedge --depth-mm 1 --nodes 3 --no-unload --workers 1``
  (one run, about 13,000 steps of 255 nodes), measured twice:

  * *whole*: the command in a fresh process;
  * *repeat*: the same command called a second time through ``studio.cli.main`` inside one
    process (into a new folder): the engine steps and what every study does again (build,
    hold loop, HDF5, CSV, the plot), without the one-time costs;
  * *start-up* = whole - repeat: what one invocation pays once (interpreter, imports of
    engine, numba, trimesh, scipy, matplotlib, h5py, loading the cached kernels, parsing).
    **Target: <= 2 CPU-s.**
  * *whole, on a Dask cluster*: the same command with its one run sent, as before the
    one-worker path existed, to a local Dask cluster of one worker process (the runner's
    ``_run_on_dask`` in place of ``_run_here``), for the ratio. ``--no-dask`` leaves it out.

The cold start (numba compiling every kernel) is in ``throughput.py``'s start-up figure;
this script warms the cache first and does not count that run.

Usage::

    python benchmarks/startup.py              # about 1 min of CPU on 2 cores
    python benchmarks/startup.py --repeat 1
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
STUDY = ["study", "wedge", "--depth-mm", "1", "--nodes", "3", "--no-unload", "--workers", "1",
         "--no-progress"]
CLI = [sys.executable, "-m", "studio.cli"]


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    return env


def child_cpu(cmd: list[str]) -> float:
    """CPU seconds (user + system) of ``cmd`` and its children; it must succeed."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(cmd, cwd=str(ROOT), env=_env(), capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {p.returncode}:\n{p.stderr[-3000:]}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


# the study twice in one process: the second call's CPU is the repeat cost
_REPEAT_CODE = """
import sys, time
from studio.cli.main import main
argv, a, b = sys.argv[1:-2], sys.argv[-2], sys.argv[-1]
if main(argv + ["-o", a]) != 0:
    sys.exit("first study failed")
t = time.process_time()
if main(argv + ["-o", b]) != 0:
    sys.exit("second study failed")
print("REPEAT_CPU", time.process_time() - t)
"""


def study_repeat_cpu(tmp: Path) -> float:
    p = subprocess.run([sys.executable, "-c", _REPEAT_CODE, *STUDY, str(tmp / "a"),
                        str(tmp / "b")], cwd=str(ROOT), env=_env(), capture_output=True,
                       text=True)
    if p.returncode != 0:
        raise RuntimeError(f"repeat study failed:\n{p.stderr[-3000:]}")
    shutil.rmtree(tmp / "a")
    shutil.rmtree(tmp / "b")
    line = next(x for x in p.stdout.splitlines() if x.startswith("REPEAT_CPU"))
    return float(line.split()[1])


# the study with its runs on a local Dask cluster of one worker, as before the one-worker path
_DASK_CODE = """
import sys
import studio.studies.runner as r
from studio.cli.main import main

def on_dask(todo, out_dir, bar, n_before, tally, finish):
    r._run_on_dask(todo, out_dir, bar, n_before, finish, None, 1)

r._run_here = on_dask
sys.exit(main(sys.argv[1:]))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure (median)")
    ap.add_argument("--no-dask", action="store_true",
                    help="leave out the study on a one-worker Dask cluster")
    args = ap.parse_args(argv)
    scene = ROOT / "static_presets" / "wedge_60.json"
    with tempfile.TemporaryDirectory(prefix="bench-startup-") as tmp_name:
        tmp = Path(tmp_name)
        print("warming the numba cache (not counted) ...", flush=True)
        child_cpu(CLI + STUDY + ["-o", str(tmp / "warm")])
        shutil.rmtree(tmp / "warm")

        cases = {
            "python -c pass": [sys.executable, "-c", "pass"],
            "python -c 'import engine'": [sys.executable, "-c", "import engine"],
            "brush-studio --help": CLI + ["--help"],
            "brush-studio validate wedge_60.json": CLI + ["validate", str(scene)],
        }
        figures: dict[str, list[float]] = {k: [] for k in cases}
        figures.update({"study: whole": [], "study: repeat": []})
        if not args.no_dask:
            figures["study: whole, on a Dask cluster"] = []
        for r in range(args.repeat):
            for label, cmd in cases.items():
                figures[label].append(child_cpu(cmd))
            out = tmp / f"study{r}"
            figures["study: whole"].append(child_cpu(CLI + STUDY + ["-o", str(out)]))
            shutil.rmtree(out)
            figures["study: repeat"].append(study_repeat_cpu(tmp))
            if not args.no_dask:
                cmd = [sys.executable, "-c", _DASK_CODE, *STUDY, "-o", str(out)]
                figures["study: whole, on a Dask cluster"].append(child_cpu(cmd))
                shutil.rmtree(out)

    med = {k: statistics.median(v) for k, v in figures.items()}
    med["study: start-up (whole - repeat)"] = med["study: whole"] - med["study: repeat"]
    if not args.no_dask:
        med["study: start-up on a Dask cluster"] = (med["study: whole, on a Dask cluster"]
                                                    - med["study: repeat"])
    print(f"\nStart-up, warm numba cache: CPU-s (user + system) of a fresh process, median of "
          f"{args.repeat}")
    print(f"study = brush-studio {' '.join(STUDY)}")
    width = max(len(k) for k in med)
    for k, v in med.items():
        spread = ""
        if k in figures and len(figures[k]) > 1:
            spread = f"   (min {min(figures[k]):.2f}, max {max(figures[k]):.2f})"
        print(f"  {k:<{width}}  {v:6.2f}{spread}")
    if not args.no_dask:
        ratio = (med["study: start-up on a Dask cluster"]
                 / med["study: start-up (whole - repeat)"])
        print(f"  start-up ratio, Dask cluster / in this process: {ratio:.1f}")
    ok = med["study: start-up (whole - repeat)"] <= 2.0
    print(f"target: study start-up <= 2 CPU-s: {'met' if ok else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
