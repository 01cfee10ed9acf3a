"""Every example in ``examples/`` runs as a user would run it, and what it printed or wrote is
checked, so that the examples cannot rot.

Each example runs as a subprocess (``sys.executable examples/NN_name.py OUT_DIR``, cwd the
repository root, ``PYTHONPATH`` the repository root) with its output folder in ``tmp_path``.
"""
from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
# a cold numba cache compiles the engine's kernels first: minutes on a loaded 2-core machine
TIMEOUT_S = 900


def run_example(name: str, out_dir: Path) -> str:
    """Run ``examples/<name>`` into ``out_dir``; its stdout (a failure shows both streams)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get(
        "PYTHONPATH", "").split(os.pathsep) if p])
    env["MPLBACKEND"] = "Agg"
    # a session of its own: on a timeout the whole group goes, with the server or the Dask
    # workers the example started (a killed example cannot stop them itself)
    proc = subprocess.Popen([sys.executable, str(EXAMPLES / name), str(out_dir)], cwd=ROOT,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        stdout, stderr = proc.communicate()
        pytest.fail(f"{name} ran over {TIMEOUT_S} s\n--- stdout\n{stdout}\n--- stderr\n"
                    f"{stderr}")
    assert proc.returncode == 0, (f"{name} exited {proc.returncode}\n--- stdout\n"
                                  f"{stdout}\n--- stderr\n{stderr}")
    return stdout


def number(pattern: str, text: str) -> float:
    m = re.search(pattern, text, re.MULTILINE)
    assert m, f"{pattern!r} not in the output:\n{text}"
    return float(m.group(1))


def test_every_example_is_tested_and_listed():
    """A new example must get a test here and a line in examples/README.md."""
    names = sorted(p.name for p in EXAMPLES.glob("[0-9][0-9]_*.py"))
    assert names, "no examples found"
    tested = {n[len("test_example_"):] for n in globals() if n.startswith("test_example_")}
    listed = (EXAMPLES / "README.md").read_text()
    for name in names:
        assert name[:-3] in tested, f"{name} has no test_example_{name[:-3]} in this file"
        assert name in listed, f"{name} is not listed in examples/README.md"


def test_example_01_build_and_run(tmp_path):
    import engine

    out = run_example("01_build_and_run.py", tmp_path)
    assert "status: completed" in out
    scene = engine.load_scene(tmp_path / "scene.json")
    steps = int(number(r"^steps: (\d+)$", out))
    dt = number(r"^dt: (\S+) s$", out)
    # the run loop does round(duration / dt) steps; dt is printed to 6 significant digits,
    # so the quotient is known to 1e-5 relative: far below a missed or extra step
    assert steps == round(scene.run.duration / dt)
    assert number(r"^node-steps per second: (\S+)$", out) > 0
    assert re.search(r"^dt limited by: \S", out, re.MULTILINE)
    with engine.open_result(tmp_path / "run.h5") as res:
        assert res.status == "completed"
        assert res.summary["steps"] == steps
        # frames at t = 0 and every record interval to the end
        assert res.n_frames == round(scene.run.duration / scene.run.record_interval) + 1


def test_example_02_force_depth(tmp_path):
    out = run_example("02_force_depth.py", tmp_path)
    rows = [(float(d), float(f)) for d, f in
            re.findall(r"^depth (\S+) mm \(t = \S+ s\): force (\S+) N$", out, re.MULTILINE)]
    # 4 steps of 1 mm, read at the end of each dwell (the wedge stands still there)
    assert [d for d, _ in rows] == pytest.approx([1.0, 2.0, 3.0, 4.0], abs=1e-3)
    forces = [f for _, f in rows]
    assert forces[0] > 0, out
    assert forces[-1] > forces[0], out   # the deeper the wedge, the more bristles bend
    png = (tmp_path / "force_depth.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    # run again into the same folder: the finished result is read, not recomputed
    again = run_example("02_force_depth.py", tmp_path)
    assert f"reusing {tmp_path / 'wedge.h5'}" in again
    assert re.findall(r"^depth .*$", again, re.MULTILINE) == \
        re.findall(r"^depth .*$", out, re.MULTILINE)


def test_example_03_study_on_dask(tmp_path):
    out = run_example("03_study_on_dask.py", tmp_path)
    assert "study completed (exit code 0)" in out
    rows = re.findall(r"^\s+(\d+)\s+([\d.]+)\s+(-?[\d.]+)$", out, re.MULTILINE)
    table = {(float(a), float(d)): float(f) for a, d, f in rows}
    # the requested rows: two wedges, each recorded at rest (0) and pressed 1 and 2 mm
    assert sorted(table) == [(a, d) for a in (45.0, 60.0) for d in (0.0, 1.0, 2.0)], out
    for angle in (45.0, 60.0):
        assert table[(angle, 0.0)] == 0.0   # the force is zeroed at rest: exactly 0
        assert table[(angle, 2.0)] > table[(angle, 1.0)], out
        assert table[(angle, 2.0)] > 0.1, out   # mN; 0.28 and 0.50 mN measured
    outcomes = json.loads((tmp_path / "outcomes.json").read_text())
    runs = outcomes["runs"] if isinstance(outcomes, dict) else outcomes
    assert sorted(o["run_id"] for o in runs) == ["wedge_45", "wedge_60"]
    assert all(o["status"] == "completed" for o in runs)


def test_example_04_service_client(tmp_path):
    import engine

    out = run_example("04_service_client.py", tmp_path)
    run_id = re.search(r"^submitted run ([0-9a-f]{12})$", out, re.MULTILINE).group(1)
    assert re.search(rf"^run {run_id}: completed, \d+ steps", out, re.MULTILINE), out
    with engine.open_result(tmp_path / "run.h5") as res:   # the downloaded file
        assert res.status == "completed"
        assert res.n_frames == round(res.scene.run.duration / res.scene.run.record_interval) + 1
        # the example cut the shipped preset to 10 ms: the server ran what was submitted
        assert res.scene.run.duration == 0.01 and res.scene.name == "gripper"
    assert "server stopped (exit code 0)" in out


def test_example_05_mission_detumble(tmp_path):
    out = run_example("05_mission_detumble.py", tmp_path)
    preset = json.loads((ROOT / "static_presets" / "detumble_upper_stage.json").read_text())
    w0 = math.degrees(math.hypot(*preset["bodies"][0]["angular_velocity"]))
    start = number(r"^\|omega\| from (\S+) to", out)
    end = number(r"^\|omega\| from \S+ to (\S+) deg/s", out)
    # the first frame is the preset's spin, printed to 4 decimals
    assert start == pytest.approx(w0, abs=1e-4)
    # the brush takes spin out: at least 1 % in 4 s
    assert end < 0.99 * start, out
    table = [float(v) for v in re.findall(r"^\s*\d+\.\d\d\s+(\d+\.\d+)$", out, re.MULTILINE)]
    assert len(table) == 9   # 0, 0.5, ..., 4 s
    assert (tmp_path / "omega.csv").read_text().startswith("time_s,omega_deg_per_s")


@pytest.mark.slow
def test_example_06_optimum_stiffness(tmp_path):
    """The seed's question: per cube, spin_left changes sign across the scan and brentq's root
    lies inside the bracket the scan found; the robust choice lies between the smallest and
    the largest per-cube optimum (where the worst |spin_left| of curves that cross zero at
    different stiffnesses is smallest); the refinement check is reported."""
    out = run_example("06_optimum_stiffness.py", tmp_path)
    roots = {}
    for m in re.finditer(r"^cube (\S+) mm: optimum E d\^4 = (\S+) Pa m\^4 .* bracketed in "
                         r"\[(\S+), (\S+)\]$", out, re.MULTILINE):
        cube, root, lo, hi = m.group(1), *map(float, m.group(2, 3, 4))
        assert lo <= root <= hi, m.group(0)
        roots[cube] = root
    assert len(roots) >= 2, out  # the sign change is found for at least two cube sizes
    robust = number(r"^robust choice over .*: E d\^4 = (\S+) Pa m\^4", out)
    # the search's range is the roots' span widened by 1.5 each way; the minimax lies
    # between the roots, 8 TPE trials land within that widening
    assert min(roots.values()) / 1.5 <= robust <= max(roots.values()) * 1.5
    assert re.search(r"^refinement \(5 nodes, half the time step\): worst \|spin_left\| \S+, "
                     r"(resolved|UNRESOLVED)", out, re.MULTILINE), out
    assert number(r"^runs: (\d+)$", out) >= 3 * len(roots)
    assert (tmp_path / "search" / "report.md").is_file()
    assert (tmp_path / "search" / "best.json").is_file()
