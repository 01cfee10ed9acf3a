"""What writing a result costs a run: the recorder's commits and the XDMF description.

Runs the ``detumble_upper_stage`` preset (51 recorded channels: nodes, bodies, controller,
energies) for 200 warm-up steps and then ``--steps`` more into a fresh temporary folder, with
``Recorder.flush`` (one commit: every channel's waiting rows extended and written, then
``n_frames`` bumped) and ``write_xdmf`` (the ParaView description written at the run's end)
timed with ``time.process_time`` (CPU seconds of this process). Prints the run's CPU, the
commits' count, total and mean, and the XDMF's CPU for the run's frames.

Usage (from the repository root)::

    NUMBA_NUM_THREADS=1 PYTHONPATH=. python benchmarks/recording.py [--steps 20000]
"""
from __future__ import annotations

import argparse
import subprocess
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000)
    args = ap.parse_args()

    import engine
    from engine.io import recorder, xdmf

    spent = {"flush": [0, 0.0], "xdmf": [0, 0.0]}

    def timed(name, fn):
        def wrapper(*a, **k):
            t = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                spent[name][0] += 1
                spent[name][1] += time.process_time() - t
        return wrapper

    recorder.Recorder.flush = timed("flush", recorder.Recorder.flush)
    # (the recorder's close imports it when it writes the description)
    xdmf.write_xdmf = timed("xdmf", xdmf.write_xdmf)

    system = engine.build(engine.load_scene(ROOT / "static_presets/detumble_upper_stage.json"))
    with tempfile.TemporaryDirectory(prefix="recording-") as out:
        engine.run(system, until=200 * system.dt, output=Path(out) / "warm.h5")
        for v in spent.values():
            v[:] = [0, 0.0]
        t = time.process_time()
        result = engine.run(system, until=system.time + args.steps * system.dt,
                            output=Path(out) / "timed.h5")
        cpu = time.process_time() - t
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                            capture_output=True, text=True).stdout.strip()
    n, c = spent["flush"]
    print(f"recording cost at commit {commit}: detumble_upper_stage, {args.steps} steps, "
          f"{result.summary['frames']} frames, {len(system.nodes.x)} nodes")
    print(f"  run             {cpu:8.3f} CPU-s")
    print(f"  commits         {c:8.3f} CPU-s in {n} ({1e3 * c / max(n, 1):.1f} ms each; the "
          f"last at the close)")
    print(f"  XDMF            {spent['xdmf'][1]:8.3f} CPU-s")


if __name__ == "__main__":
    main()
