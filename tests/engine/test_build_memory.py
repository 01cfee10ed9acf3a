"""Memory of the build and the run bounded by the estimate, and the size guard that holds
before anything is built (issue 26 item 1, issue 28 item 4).

The build's checks (initial overlap, which bristles can meet) once held per-node neighbour
lists: 4.2 GB for a 100 x 100 x 8 brush whose built arrays are ~100 MB, 21 GB for
300 x 300 x 20 estimated at 3.5 GiB. The guard compares ``engine.estimate`` with the limit,
so the estimate must bound what a build and a run really take."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import engine
from studio.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


def box_brush(rows: int, cols: int, n_nodes: int = 8) -> dict:
    """A rows x cols silicone brush with a PLA box resting on its tips, moving down (the
    throughput benchmark's box scene), recording every per-node channel."""
    length, tip_r = 0.033, 0.0005
    sx, sy, h = cols * 0.003 + 0.01, rows * 0.003 + 0.01, 0.01
    return {
        "schema_version": 1, "name": f"box_{rows}x{cols}x{n_nodes}",
        "materials": {"silicone": {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48,
                                   "density": 1700.0},
                      "pla": {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36,
                              "density": 1240.0}},
        "contact_pairs": [
            {"materials": ["silicone", "silicone"], "friction_angle": 0.767944870877505},
            {"materials": ["silicone", "pla"], "friction_angle": 0.418879020478639}],
        "brushes": [{"name": "brush", "material": "silicone", "rows": rows, "columns": cols,
                     "pitch": [0.003, 0.003], "bristle_length": length,
                     "root_radius": 0.001, "tip_radius": tip_r, "n_nodes": n_nodes}],
        "bodies": [{"name": "box", "material": "pla",
                    "shape": {"type": "box", "size": [sx, sy, h]},
                    "pose": {"position": [0.0, 0.0, length + tip_r + h / 2]},
                    "motion": {"type": "kinematic", "after": "hold",
                               "profile": {"kind": "constant",
                                           "velocity": [0.0, 0.0, -0.01]}}}],
        "environment": {"gravity": [0.0, 0.0, -9.81]},
        "run": {"duration": 0.01, "record_interval": 1e-4,
                "channels": ["nodes", "node_velocities", "bodies", "root_force", "energy",
                             "contacts", "bending"]},
    }


_PEAK = """
import json, resource, sys, time
import engine
scene = engine.parse_scene(json.loads(sys.argv[1]))
t = time.process_time()
system = engine.build(scene)
build_cpu = time.process_time() - t
build_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
engine.run(system, until=float(sys.argv[3]) * system.dt, output=sys.argv[2])
print(json.dumps({"build_peak": build_peak, "build_cpu": build_cpu,
                  "peak": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}))
"""


@pytest.mark.slow
def test_a_large_brush_builds_and_runs_under_its_estimate(tmp_path):
    """Catches a build-time check that holds pairs or per-node lists (the old 40 KB per
    node), or an estimate that leaves out what the run allocates (recorder buffers, contact
    lists grown in contact): a 100 x 100 x 8 brush (80,000 nodes) built and run 200 steps
    in a fresh process (kernels from the cache) peaks below ``estimate().memory_bytes``,
    and below 1 GB (issue 26's target for 10,000 bristles x 8 nodes)."""
    data = box_brush(100, 100)
    cost = engine.estimate(engine.parse_scene(data))
    # the kernels compiled and cached in this worktree first, so that the measured process
    # loads them as a user's does after the first run (a cold compile is a one-off)
    engine.run(engine.build(engine.parse_scene(box_brush(3, 3))), until=1e-5,
               output=tmp_path / "warm.h5")
    out = subprocess.run([sys.executable, "-c", _PEAK, json.dumps(data),
                          str(tmp_path / "big.h5"), "200"], cwd=ROOT, capture_output=True,
                         text=True, timeout=1200)
    assert out.returncode == 0, out.stderr[-3000:]
    measured = json.loads(out.stdout.strip().splitlines()[-1])
    assert measured["peak"] <= cost.memory_bytes, (measured, cost.memory_bytes)
    assert measured["peak"] <= 2**30, measured



@pytest.mark.slow
def test_a_first_run_that_compiles_the_kernels_stays_under_its_estimate(tmp_path):
    """Catches an estimate whose fixed part leaves out the compiler: a fresh installation's
    first run compiles every kernel with the built arrays alive (LLVM's memory on top of
    them: 1.11 GB peak for this brush against 0.41 GB from a warm cache, and 0.97 GB
    estimated when the fixed part was 768 MiB). The same 100 x 100 x 8 brush, 20 steps,
    in a fresh process whose numba cache folder is empty."""
    data = box_brush(100, 100)
    cost = engine.estimate(engine.parse_scene(data))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "empty_cache"))
    out = subprocess.run([sys.executable, "-c", _PEAK, json.dumps(data),
                          str(tmp_path / "big.h5"), "20"], cwd=ROOT, capture_output=True,
                         text=True, timeout=1800, env=env)
    assert out.returncode == 0, out.stderr[-3000:]
    measured = json.loads(out.stdout.strip().splitlines()[-1])
    assert measured["build_cpu"] > 5.0, ("the kernels were not compiled", measured)
    assert measured["peak"] <= cost.memory_bytes, (measured, cost.memory_bytes)

def test_a_scene_over_the_memory_limit_is_refused_before_the_build(tmp_path, monkeypatch,
                                                                   capsys, write_scene):
    """Catches ``run`` building (and so allocating) a scene before checking its size, or
    a refusal that does not say by how much: over ``--max-memory-mb`` the command exits 2
    naming the estimate and the limit, without calling the build or creating the result."""
    path = write_scene(box_brush(300, 300, 20))   # 1.8 M nodes: the OOM scene
    cost = engine.estimate(engine.parse_scene(box_brush(300, 300, 20)))

    def no_build(*a, **k):
        raise AssertionError("the build ran")

    monkeypatch.setattr(engine, "build", no_build)
    for argv in (["run", str(path), "-o", str(tmp_path / "r.h5")], ["validate", str(path)]):
        code = main(argv + ["--max-memory-mb", "1000"])
        err = capsys.readouterr().err
        assert code == 2, err
        assert f"{cost.memory_bytes / 2**20:.4g} MiB" in err and "--max-memory-mb 1000" in err
    assert not (tmp_path / "r.h5").exists()
