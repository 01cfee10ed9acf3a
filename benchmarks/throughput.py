"""Brush Studio engine throughput benchmark.

Measures, in one run:

1. start-up: a fresh ``python -c "import engine; engine.run(engine.build(...))"`` with
   ``NUMBA_CACHE_DIR`` pointing at an empty temporary folder (cold: every kernel compiled),
   then the same command again with that folder now filled (cached start);
2. throughput of three scenes in contact, on 1 and 2 threads (``numba.set_num_threads``):
   node-steps per CPU second (``time.process_time``, all threads; the figure that does not
   depend on what else the machine runs) and per wall second, for the seed's 17 x 5 brush
   (8 nodes per bristle) pressed about 5 mm by the 60 degree wedge, and 40 x 25 and
   100 x 100 brushes (8 nodes) pressed by a box;
3. time per step divided by the number of bristles, to show the cost grows linearly.

Usage::

    python benchmarks/throughput.py            # everything (about 3-6 min on 2 cores)
    python benchmarks/throughput.py --quick    # without the 10,000-bristle brush
    python benchmarks/throughput.py --json     # also write benchmarks/results.json
    python benchmarks/throughput.py --only 10000   # one throughput case (and no start-up)
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

SILICONE = {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1700.0}
PLA = {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1240.0}
LENGTH, ROOT_R, TIP_R = 0.033, 0.001, 0.0005
TIP_TOP = LENGTH + TIP_R  # highest point of an unbent bristle's tip sphere, m


def _base(name, rows, cols, n_nodes, body, duration=10.0):
    return {
        "schema_version": 1,
        "name": name,
        "materials": {"silicone": SILICONE, "pla": PLA},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": 0.767944870877505},
            {"materials": ["silicone", "pla"], "friction_angle": 0.418879020478639},
        ],
        "brushes": [{"name": "brush", "material": "silicone", "rows": rows, "columns": cols,
                     "pitch": [0.003, 0.003], "bristle_length": LENGTH,
                     "root_radius": ROOT_R, "tip_radius": TIP_R, "n_nodes": n_nodes}],
        "bodies": [body],
        "environment": {"gravity": [0.0, 0.0, -9.81]},
        # one frame per second of simulated time: recording never runs inside a timed run
        "run": {"duration": duration, "record_interval": 1.0, "channels": ["contacts"]},
    }


def wedge_scene():
    """The seed's 17 x 5 brush with 8 nodes per bristle (the wedge_60 preset's resolution);
    the 60 degree PLA wedge's edge starts at the tip tops and keeps moving down at 20 mm/s
    (5 mm by the end of the warm-up, 5.4 mm at the end of the benchmark), so that it keeps
    pressing bristles rather than letting them spring off and lose contact."""
    wedge = {"name": "wedge", "material": "pla",
             "shape": {"type": "wedge", "angle": 1.0471975511965976, "height": 0.02,
                       "length": 0.02},
             "pose": {"position": [0.0, 0.0005, TIP_TOP]},
             "motion": {"type": "kinematic",
                        "profile": {"kind": "constant", "velocity": [0.0, 0.0, -0.02]}}}
    return _base("bench_wedge_17x5", 17, 5, 8, wedge), 0.25


def box_scene(rows, cols, n_nodes=8):
    """rows x cols brush pressed by a PLA box whose bottom starts touching the tips and keeps
    moving down slowly (10 mm/s; the warm-up runs 10 ms = 0.1 mm in, the whole benchmark
    stays under 1 mm), so that the tips stay in contact without violent buckling."""
    sx, sy = cols * 0.003 + 0.01, rows * 0.003 + 0.01
    h = 0.01
    box = {"name": "box", "material": "pla", "shape": {"type": "box", "size": [sx, sy, h]},
           "pose": {"position": [0.0, 0.0, TIP_TOP + h / 2]},
           "motion": {"type": "kinematic", "after": "hold",
                      "profile": {"kind": "constant", "velocity": [0.0, 0.0, -0.01]}}}
    return _base(f"bench_box_{rows}x{cols}", rows, cols, n_nodes, box), 0.01


# label, scene factory -> (scene, warm-up end time), warm-up steps if no time, steps/run
CASES = {
    "85": ("17x5 brush, 8 nodes, wedge 5mm", wedge_scene, 0, 2000),
    "1000": ("40x25 brush, 8 nodes, box", lambda: box_scene(25, 40), 0, 600),
    "10000": ("100x100 brush, 8 nodes, box", lambda: box_scene(100, 100), 0, 150),
}


# --------------------------------------------------------------------------- start-up
def _startup_code(scene: dict) -> str:
    return ("import json, engine; "
            f"s = engine.parse_scene(json.loads({json.dumps(json.dumps(scene))})); "
            "sys_ = engine.build(s); engine.run(sys_, until=200 * sys_.dt)")


def measure_startup() -> dict:
    small = json.loads((ROOT / "studio" / "data" / "demo_scene.json").read_text())
    small["run"]["channels"] = ["contacts"]
    code = _startup_code(small)
    out = {}
    with tempfile.TemporaryDirectory(prefix="bench-numba-cache-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold", "cached"):
            t0 = time.perf_counter()
            p = subprocess.run([sys.executable, "-c", code], env=env, cwd=str(ROOT),
                               capture_output=True, text=True)
            wall = time.perf_counter() - t0
            if p.returncode != 0:
                raise RuntimeError(f"{label} start-up run failed:\n{p.stderr[-3000:]}")
            n_files = sum(1 for f in Path(cache).rglob("*") if f.suffix in (".nbi", ".nbc"))
            out[f"{label}_s"] = wall
            out[f"{label}_cache_files"] = n_files
    # NUMBA_CACHE_DIR is honoured iff the cold run filled the empty folder
    out["numba_cache_dir_honoured"] = out["cold_cache_files"] > 0
    return out


# --------------------------------------------------------------------------- throughput
def measure_case(key: str, threads=(1, 2), repeats: int = 3) -> dict:
    import numba

    import engine
    from engine.state import ACC_N_BODY

    label, factory, warm_steps, steps = CASES[key]
    scene_dict, warm_until = factory()
    t0 = time.perf_counter()
    system = engine.build(engine.parse_scene(scene_dict))
    build_s = time.perf_counter() - t0
    tmp = Path(tempfile.mkdtemp(prefix="bench-run-"))
    n_out = [0]

    def go(n_steps=None, until=None):
        n_out[0] += 1
        if until is None:
            until = system.time + n_steps * system.dt
        c0 = time.process_time()
        res = engine.run(system, until=until, output=tmp / f"r{n_out[0]}.h5")
        res.summary["cpu_s"] = time.process_time() - c0
        if res.status != "completed":
            raise RuntimeError(f"{label}: run {res.status}: {res.error}")
        (tmp / f"r{n_out[0]}.h5").unlink(missing_ok=True)
        return res.summary

    # warm-up: compiles (or loads) every kernel and drives the body into contact
    numba.set_num_threads(min(threads))
    t0 = time.perf_counter()
    go(n_steps=warm_steps, until=warm_until)
    warm_s = time.perf_counter() - t0
    per_threads = {}
    for n in threads:
        numba.set_num_threads(n)
        go(n_steps=max(10, steps // 10))  # settle the thread pool at this count
        runs, seen = [], []
        for _ in range(repeats):
            runs.append(go(n_steps=steps))
            seen.append(int(system.acc[ACC_N_BODY]))
        contacts = min(seen)
        if contacts <= 0:
            raise RuntimeError(f"{label}: no bristle-body contact during the timed runs")
        med = sorted(runs, key=lambda s: s["steps_per_s"])[len(runs) // 2]
        per_threads[n] = {
            "steps_per_s": med["steps_per_s"],
            "node_steps_per_s": med["node_steps_per_s"],
            "node_steps_per_cpu_s": med["steps"] * system.n_nodes / med["cpu_s"],
            "s_per_step": 1.0 / med["steps_per_s"],
            "steps": med["steps"],
            "wall_s_all": [r["wall_s"] for r in runs],
            "stages": med["stages"],
            "bristle_body_contacts": contacts,
        }
    return {"label": label, "n_bristles": system.n_bristles, "n_nodes": system.n_nodes,
            "dt": system.dt, "build_s": build_s, "warmup_s": warm_s,
            "threads": per_threads}


def run_case_subprocess(key: str) -> dict:
    """Each case in its own interpreter, so that one case's memory and thread pool do not
    affect the next."""
    p = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--_case", key],
                       cwd=str(ROOT), capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"case {key} failed:\n{p.stderr[-4000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


# --------------------------------------------------------------------------- report
def table(results: dict) -> str:
    lines = []
    st = results.get("startup")
    if st:
        lines.append("Start-up (subprocess wall time: import, parse, build, run 200 steps of "
                     "the demo scene)")
        lines.append(f"  cold   (empty NUMBA_CACHE_DIR, compiles everything): "
                     f"{st['cold_s']:8.2f} s")
        ok = "OK" if st["cached_s"] < 2.0 else "MISSED"
        lines.append(f"  cached (same NUMBA_CACHE_DIR again)              : "
                     f"{st['cached_s']:8.2f} s   target < 2 s: {ok}")
        lines.append(f"  NUMBA_CACHE_DIR honoured: {st['numba_cache_dir_honoured']} "
                     f"({st['cold_cache_files']} cache files written)")
        lines.append("")
    cases = results.get("cases", {})
    if cases:
        lines.append("Throughput in contact (median of 3 timed runs after a warm-up; "
                     "M node-steps per wall second and per CPU second of all threads)")
        hdr = (f"  {'case':<30}{'nodes':>8}{'thr':>4}{'steps':>7}{'steps/s':>11}"
               f"{'Mn-s/wall-s':>13}{'Mn-s/CPU-s':>12}{'contacts':>10}"
               f"{'us/step/bristle':>17}")
        lines.append(hdr)
        lines.append("  " + "-" * (len(hdr) - 2))
        for key, c in cases.items():
            for n, t in c["threads"].items():
                per_b = t["s_per_step"] / c["n_bristles"] * 1e6
                lines.append(f"  {c['label']:<30}{c['n_nodes']:>8}{n:>4}{t['steps']:>7}"
                             f"{t['steps_per_s']:>11.1f}{t['node_steps_per_s'] / 1e6:>13.2f}"
                             f"{t['node_steps_per_cpu_s'] / 1e6:>12.2f}"
                             f"{t['bristle_body_contacts']:>10}{per_b:>17.3f}")
        lines.append("")
        if "85" in cases:
            best = max(t["node_steps_per_s"] for t in cases["85"]["threads"].values())
            two = cases["85"]["threads"].get(2) or cases["85"]["threads"].get("2")
            v = two["node_steps_per_s"] if two else best
            ok = "OK" if v >= 5e6 else "MISSED"
            lines.append(f"  17x5 brush in contact, 2 threads: {v / 1e6:.2f} M node-steps/s "
                         f"(target >= 5): {ok}")
        lines.append("")
        lines.append("Time per step vs bristle count (per bristle and per node; flat = "
                     "linear)")
        lines.append(f"  {'bristles':>9}{'thr':>4}{'ms/step':>10}{'us/step/bristle':>17}"
                     f"{'ns/step/node':>14}{'ratio to 85':>13}")
        ref = {}
        for key, c in cases.items():
            for n, t in c["threads"].items():
                per_b = t["s_per_step"] / c["n_bristles"]
                ref.setdefault(str(n), per_b if key == "85" else None)
                r = ref.get(str(n))
                ratio = f"{per_b / r:13.2f}" if r else f"{'-':>13}"
                lines.append(f"  {c['n_bristles']:>9}{n:>4}{t['s_per_step'] * 1e3:>10.3f}"
                             f"{per_b * 1e6:>17.3f}"
                             f"{t['s_per_step'] / c['n_nodes'] * 1e9:>14.1f}{ratio}")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="skip the 10,000-bristle case")
    ap.add_argument("--json", action="store_true", help="write benchmarks/results.json")
    ap.add_argument("--only", choices=sorted(CASES), help="run one throughput case only")
    ap.add_argument("--_case", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)

    if a._case:  # worker: one case, JSON on the last line of stdout
        print(json.dumps(measure_case(a._case)))
        return 0

    t_all = time.perf_counter()
    results: dict = {"python": sys.version.split()[0], "machine": platform.machine(),
                     "cpus": os.cpu_count()}
    try:
        import numba
        results["numba"] = numba.__version__
    except ImportError:
        pass
    if a.only:
        keys = [a.only]
    else:
        keys = [k for k in CASES if not (a.quick and k == "10000")]
        print("measuring start-up (cold compile, then cached) ...", flush=True)
        results["startup"] = measure_startup()
    results["cases"] = {}
    for k in keys:
        print(f"measuring {CASES[k][0]} ...", flush=True)
        results["cases"][k] = run_case_subprocess(k)
    # JSON keys of thread counts come back as strings
    for c in results["cases"].values():
        c["threads"] = {int(n): t for n, t in c["threads"].items()}
    results["total_s"] = time.perf_counter() - t_all
    print()
    print(table(results))
    print(f"\n(total benchmark time {results['total_s']:.0f} s)")
    if a.json:
        path = HERE / "results.json"
        path.write_text(json.dumps(results, indent=2) + "\n")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
