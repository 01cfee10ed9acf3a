"""Reduced brush against the DEM brush in windows of a detumble spot check (issue 25).

Reads the folder of ``brush-studio study detumble --fidelity reduced --spot-check-s T``
(one scenario: its reduced run and its ``_dem_spot`` run) and prints, for each window
(default 0-3 s, 0-T and from the DEM brush's first contact plus the study's settle time
``detumble.SETTLE_S`` to T: the study's own after-touch window), the
target's spin change along its axis, the peak and mean contact force on it (|F| and the
normal part along the approach axis x), the mean tangential force (along y) and the peak
and mean contact torque about its axis, DEM, reduced and the relative error. Both runs'
frames are used as recorded (the DEM run every 20 ms, the reduced one every 1 s by default:
its peaks are those of its frames).

Usage::

    python benchmarks/reduced_spot_windows.py detumble-reduced-10
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def figures(d: dict, a: float, b: float) -> dict:
    t = np.asarray(d["time"], float)
    w = np.asarray(d["omega"], float)[:, 2]
    F = np.asarray(d["target_force"], float)
    M = np.asarray(d["target_torque"], float)[:, 2]
    m = (t >= a - 1e-9) & (t <= b + 1e-9)
    return {"delta_omega": float(np.interp(b, t, w) - np.interp(a, t, w)),
            "peak_force": float(np.linalg.norm(F[m], axis=1).max()),
            "peak_normal_force": float(np.abs(F[m, 0]).max()),
            "mean_normal_force": float(-F[m, 0].mean()),
            "mean_tangential_force": float(-F[m, 1].mean()),
            "peak_torque": float(np.abs(M[m]).max()),
            "mean_torque": float(M[m].mean())}


def main(argv=None) -> int:
    from studio.studies.detumble_analysis import read_detumble

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    args = ap.parse_args(argv)
    runs = Path(args.folder) / "runs"
    dem_h5 = next(runs.glob("*_dem_spot.h5"))
    red_h5 = runs / dem_h5.name.replace("_dem_spot.h5", ".h5")
    dem, red = read_detumble(dem_h5), read_detumble(red_h5)
    t_end = float(np.asarray(dem["time"])[-1])
    window = round(t_end - 0.1, 2)               # study detumble runs 0.1 s past the window
    from studio.studies.detumble import SETTLE_S, window_figures

    touch = window_figures(dem, window)["first_contact"]
    windows = [(0.0, min(3.0, window)), (0.0, window)]
    if touch is not None and touch + SETTLE_S < window:
        windows.append((touch + SETTLE_S, window))
    for a, b in windows:
        fd, fr = figures(dem, a, b), figures(red, a, b)
        print(f"window {a:g}-{b:g} s")
        for k in fd:
            err = (fr[k] - fd[k]) / abs(fd[k]) if fd[k] else float("nan")
            print(f"  {k:22s} DEM {fd[k]: .4g}  reduced {fr[k]: .4g}  error {err:+.1%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
