"""Figures of a run's start (issue 22; docs/accuracy.md, "Time integration from t = 0"), from
the scenes of ``tests/engine/test_first_step.py`` and ``tests/engine/test_mounted_start.py``:
a constant force from t = 0, the gravity-gradient pitch libration against scipy at three
dt, and the detumble chaser's brush alone in free space (largest root force).

    python benchmarks/start_figures.py
"""
from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "engine")]

import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

import engine  # noqa: E402
from test_first_step import (INERTIA, N_ORBIT, THETA0, _pitch, _pitch_scene,  # noqa: E402
                             _pushed_body)
from test_mounted_start import _brush_mass_and_reach, _chaser_scene  # noqa: E402


def main() -> None:
    for dt in (0.1, 0.05):
        s = engine.build(_pushed_body(dt))
        engine.run(s)
        print(f"constant force F/m = 1, T = 1 s, dt {dt}: v(T) = {s.bodies.v[0, 0]:.15f}, "
              f"x(T) = {s.bodies.pos[0, 0]:.15f}")
    I1, I2, I3 = INERTIA
    T = 20.0
    c = 3 * N_ORBIT ** 2 * (I2 - I1) / I3
    ref = solve_ivp(lambda t, y: [y[1], -c * math.sin(y[0]) * math.cos(y[0])], (0, T),
                    [THETA0, 0], rtol=1e-12, atol=1e-14).y[0, -1]
    errs = []
    for dt in (0.2, 0.1, 0.05):
        s = engine.build(_pitch_scene(dt, T))
        engine.run(s)
        errs.append(abs(_pitch(s) - ref))
        print(f"gravity-gradient pitch {THETA0} rad, T = {T:g} s, dt {dt}: error "
              f"{errs[-1]:.4g} rad")
    print("error ratios per halving:", ", ".join(f"{errs[i] / errs[i + 1]:.5f}"
                                                 for i in range(len(errs) - 1)))
    tmp = Path(tempfile.mkdtemp())
    for name, v, w, t_end in [("approach 5 cm/s", [-0.05, 0, 0], [0, 0, 0], 0.2),
                              ("spin 10 deg/s", [0, 0, 0], [0, 0, math.radians(10)], 0.3),
                              ("2 m/s and 0.3 rad/s", [-2.0, 0, 0], [0, 0, 0.3], 0.4)]:
        s = engine.build(_chaser_scene(v, w, t_end))
        try:
            res = engine.run(s, output=tmp / "r.h5")
        except engine.InstabilityError as exc:
            print(f"{name}: failed: {str(exc)[:150]}")
            continue
        with res.open() as r:
            f = np.linalg.norm(r.series("brushes/brush/root_force"), axis=1)
        M, R = _brush_mass_and_reach(s)
        print(f"{name}: {res.status}, largest |root force| {f.max():.4g} N over {t_end} s; "
              f"2 M w^2 R = {2 * M * w[2] ** 2 * R:.4g} N (M {M:.4g} kg, R {R:.4g} m)")


if __name__ == "__main__":
    main()
