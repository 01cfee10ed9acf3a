"""Hour-long detumble with the reduced brush (issue 25 target): 1 h of simulated contact of an
upper-stage-class target (I about 1e5 kg m^2, 2 deg/s) with the chaser's brush replaced by
the reduced law's patch (``engine.kernels.patch``), in at most 60 CPU-s.

The scene is ``study detumble``'s: the ``detumble_upper_stage`` preset with the target
scaled (its density kept: inertia x s^5) so that its axial moment is ``--inertia``, spinning
at ``--spin`` deg/s, the brush replaced by the patch (``detumble.reduced_scene``), the
chaser's approach, controller, Clohessy-Wiltshire orbit and gravity-gradient torque as in
the preset; the run's stop rule (the target detumbled) is removed so that it runs the whole
``--duration``. Frames every ``--record-interval`` (default 10 s; 1 s frames cost about
2 ms each, written a block at a time). A
short warm-up run (compiling or loading the kernels) comes first and is not timed. Prints the CPU seconds of the timed run (this process and its children,
``resource.getrusage``), its wall time, steps, dt, final spin, time in contact and where the
step's time went; writes into a fresh output folder each run (``--out``, default a new
temporary folder).

Usage::

    python benchmarks/mission_hour.py --law benchmarks/data/detumble_brush_17x5_sliding_law.json
"""
from __future__ import annotations

import argparse
import json
import math
import resource
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

TARGET_CPU_S = 60.0
PRESET_AXIAL_INERTIA = 130.0 * 0.62 ** 2   # kg m^2: detumble_upper_stage's m r^2


def cpu_s() -> float:
    """CPU seconds of this process and its waited-for children."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + ch.ru_utime + ch.ru_stime


def scene(law: dict, inertia: float, spin_deg: float, duration: float,
          record_interval: float) -> dict:
    from studio.studies.detumble import detumble_scene, reduced_scene

    size = (inertia / PRESET_AXIAL_INERTIA) ** 0.2
    sc = detumble_scene("detumble_upper_stage", size=size, spin_deg=spin_deg,
                        duration=duration, record_interval=record_interval)
    sc["run"].pop("stop", None)
    return reduced_scene(sc, law)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--law", required=True, help="law.json of brush-studio study reduce")
    ap.add_argument("--inertia", type=float, default=1e5, help="target axial inertia, kg m^2")
    ap.add_argument("--spin", type=float, default=2.0, help="initial spin, deg/s")
    ap.add_argument("--duration", type=float, default=3600.0, help="simulated s")
    ap.add_argument("--record-interval", type=float, default=10.0,
                    help="s between frames (each frame is flushed to disk: at 1 s the 3 600 "
                         "frames cost more than the physics here)")
    ap.add_argument("--out", default=None, help="output folder (must not exist)")
    args = ap.parse_args(argv)

    import numpy as np

    import engine
    from engine.model.reduced_law import load_law

    law = load_law(args.law)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="mission-hour-"))
    out.mkdir(parents=True, exist_ok=args.out is None)
    sc = scene(law, args.inertia, args.spin, args.duration, args.record_interval)
    (out / "scene.json").write_text(json.dumps(sc, indent=1))
    # warm-up: the same scene for a few steps (kernels compiled or loaded), not timed
    warm = engine.build(engine.parse_scene(dict(sc, run=dict(sc["run"], duration=1.0))))
    engine.run(warm, output=out / "warmup.h5")
    c0, w0 = cpu_s(), time.perf_counter()
    system = engine.build(engine.parse_scene(sc))
    result = engine.run(system, output=out / "result.h5")
    cpu, wall = cpu_s() - c0, time.perf_counter() - w0
    s = result.summary
    k = system.body_names.index("target")
    w_end = float(np.linalg.norm(system.bodies.w[k]))
    with engine.open_result(out / "result.h5") as res:
        n_bb = np.asarray(res.series("contacts/body_body"))
        t = np.asarray(res.time)
    contact_s = float(np.sum(np.diff(t, append=t[-1])[n_bb > 0]))
    report = {"cpu_s": cpu, "wall_s": wall, "target_cpu_s": TARGET_CPU_S,
              "met": cpu <= TARGET_CPU_S, "steps": s["steps"], "dt": s["dt"],
              "dt_limited_by": s["dt_limited_by"], "simulated_s": s["time"],
              "time_in_contact_s": contact_s,
              "target_inertia_axial": float(system.bodies.Ip[k].max()),
              "spin0_deg_s": args.spin, "spin_end_deg_s": math.degrees(w_end),
              "stages_wall_s": s["stages"], "patches": s.get("patches"),
              "warnings": s["warnings"], "out": str(out)}
    (out / "mission_hour.json").write_text(json.dumps(report, indent=1))
    print(f"target: axial inertia {report['target_inertia_axial']:.3g} kg m^2, "
          f"{args.spin:g} deg/s -> {report['spin_end_deg_s']:.3g} deg/s after "
          f"{s['time']:g} s ({contact_s:.0f} s in contact)")
    print(f"steps {s['steps']}, dt {s['dt']:.3g} s ({s['dt_limited_by']})")
    print(f"CPU {cpu:.1f} s (target <= {TARGET_CPU_S:g}: "
          f"{'met' if report['met'] else 'NOT met'}), wall {wall:.1f} s")
    print("stages (wall s): " + ", ".join(f"{k} {v:.2f}" for k, v in s["stages"].items()))
    for w in s["warnings"]:
        print(f"warning: {w}")
    print(f"Wrote {out}/mission_hour.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
