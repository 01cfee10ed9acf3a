"""Print issue 22's contact-law figures: the oblique damped frictional impact against the law
integrated by scipy, and the energy books of a sphere into a frictional 5 x 5 brush.

    python benchmarks/contact_law_figures.py [--dt-fraction F] [--books] [--rods]

It reuses the scenes and the reference of ``tests/engine/test_verification_impact.py`` and
``tests/engine/test_energy_books.py``, so the numbers are those the tests assert on.
Impact: rebound normal and tangential speed and spin against the reference, the largest
|F_t| / F_n over the recorded frames with F_n > 0, the frames where F_n = 0 but |F_t| > 0
and the largest |F_t| there. Books: the largest |total + dissipated - external work - E0|
/ E0 over the run at the automatic dt and at 1/2, 1/4, 1/8 of it (``--books``, slower).
Rods (``--rods``): the automatic dt of one steel rod of the rod presets (0.4 m, 36 nodes)
against two of them 0.2 m apart (their tips can reach each other), and of 0.05 m rods (they
cannot).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "engine"))
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import engine  # noqa: E402
import test_energy_books as books  # noqa: E402
import test_verification_impact as impact  # noqa: E402
from engine.kernels.contact_law import normal_stiffness, restitution_damping_ratio  # noqa: E402


def impact_figures(dt_fraction: float) -> None:
    auto = engine.build(impact._scene(1.0)).dt
    system = engine.build(impact._scene(auto * dt_fraction))
    mass = float(system.bodies.mass[1])
    inertia = float(system.bodies.Ip[1, 0])
    kn = normal_stiffness(impact.E, impact.RADIUS, impact.E, impact.RADIUS)
    ref = impact.reference_rebound(mass, inertia, kn, impact.TANGENTIAL_RATIO * kn, impact.MU,
                                   restitution_damping_ratio(impact.RESTITUTION))
    period = math.pi * math.sqrt(mass / kn)
    result = engine.run(system, until=impact.GAP / impact.V_N + 3.0 * period)
    v, w = system.bodies.v[1], system.bodies.w[1]
    with result.open() as res:
        force = res.series("bodies/ball/contact_force")
    f_n = force[:, 2]
    f_t = np.hypot(force[:, 0], force[:, 1])
    pressed = f_n > 0.0
    loose = (f_n <= 0.0) & (f_t > 0.0)
    print(f"impact at dt {system.dt:.4g} s ({dt_fraction:g} x automatic {auto:.4g} s), "
          f"{int((pressed | loose).sum())} contact frames")
    for name, got, want in (("rebound v_n", v[2], ref[0]), ("rebound v_t", v[0], ref[1]),
                            ("rebound spin", w[1], ref[2])):
        print(f"  {name:13s} {got:+.6g}  reference {want:+.6g}  error {got / want - 1:+.3%}")
    print(f"  max |F_t|/F_n (F_n > 0): {float((f_t[pressed] / f_n[pressed]).max()):.6g} "
          f"(mu = {impact.MU})")
    print(f"  frames with F_n = 0 and |F_t| > 0: {int(loose.sum())}, largest |F_t| there: "
          f"{float(f_t[loose].max()) if loose.any() else 0.0:.4g} N")


def books_figures() -> None:
    for e in (1.0, 0.5):
        for fac in (1.0, 0.5, 0.25, 0.125):
            err, diss, n_bb, n_body = books.balance(e, fac)
            print(f"books e={e:g} dt x {fac:g}: max |error| / E0 = {err:.4%}, dissipated "
                  f"{diss:.2%} of E0, contacts bb {n_bb} body {n_body}", flush=True)


def rods_figures() -> None:
    import copy
    import json
    preset = json.loads((ROOT / "static_presets" / "rod_tip_impulse.json").read_text())
    scene = preset.get("scene", preset)

    def dt_of(n_rods: int, length: float) -> tuple[float, str]:
        s = copy.deepcopy(scene)
        rod = dict(s["brushes"][0], bristle_length=length)
        s["brushes"] = [dict(copy.deepcopy(rod), name=f"rod{i}",
                             base=dict(rod["base"], position=[0.0, 0.2 * i, 0.0]))
                        for i in range(n_rods)]
        s.pop("loads", None)
        system = engine.build(engine.parse_scene(s))
        return system.dt, system.dt_limited_by

    for length in (0.4, 0.05):
        one, two = dt_of(1, length), dt_of(2, length)
        print(f"rods {length:g} m: one {one[0]:.4g} s ({one[1]}), two 0.2 m apart "
              f"{two[0]:.4g} s ({two[1]}): {one[0] / two[0]:.3g}x smaller")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dt-fraction", type=float, default=impact.DT_FRACTION)
    ap.add_argument("--books", action="store_true")
    ap.add_argument("--rods", action="store_true")
    args = ap.parse_args()
    if args.rods:
        rods_figures()
        return
    impact_figures(args.dt_fraction)
    if args.books:
        books_figures()


if __name__ == "__main__":
    main()
