"""Print the engine's verification figures: each quantity, its independent reference, the
error, and the wall time of the run that measured it.

    python benchmarks/verification_figures.py

It reuses the scenes and references of the verification tests (``tests/engine``), so the
numbers it prints are those the tests assert on, measured now.
"""
from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "engine"))
sys.path.insert(0, str(ROOT))

import analytic  # noqa: E402
import test_verification_beams as beams  # noqa: E402
import test_verification_bodies as bodies  # noqa: E402
from engine.analysis.spectrum import peak_frequencies  # noqa: E402


def timed(fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


def main() -> None:
    tmp = Path(tempfile.mkdtemp(prefix="brush-verification-"))
    rows = []
    # steel rod, small tip load, 21 nodes
    force = 1e-3
    I = analytic.circle_second_moment(beams.ROD_RADIUS)
    ref = analytic.cantilever_tip_deflection(force, beams.ROD_LENGTH,
                                             beams.STEEL["youngs_modulus"], I)
    scene = beams.cantilever_scene(n_nodes=21, length=beams.ROD_LENGTH,
                                   root_radius=beams.ROD_RADIUS, tip_radius=beams.ROD_RADIUS,
                                   material=beams.STEEL, tip_force=force,
                                   profile=beams.quasi_static(), duration=1.0,
                                   record_interval=0.05, local_damping=0.7)
    (_, _, tip), wall = timed(beams.run_tip, scene, tmp / "rod.h5")
    rows.append(("steel rod tip deflection, 21 nodes (m)", -tip[-1, 2], ref,
                 -tip[-1, 2] / ref - 1, wall))
    # conical bristle, tip stiffness against the tapered-beam integral
    for n in (8, 16, 32):
        err, wall = timed(beams.cone_tip_error, n, tmp)
        rows.append((f"cone tip compliance, {n} nodes (rel. error)", None, None, err, wall))
    # large deflection against the elastica
    for n in (11, 21):
        (ex, ey), wall = timed(beams.elastica_tip_error, n, tmp)
        rows.append((f"elastica tip (x, y) error / L, {n} nodes", ex, ey, max(abs(ex), abs(ey)),
                     wall))
    # bending frequencies from a free-vibration spectrum
    E, rho = beams.STEEL["youngs_modulus"], beams.STEEL["density"]
    A = analytic.circle_area(beams.ROD_RADIUS)
    fref = analytic.cantilever_frequencies(beams.ROD_LENGTH, E, I, rho, A, n_modes=3)
    pulse = {"times": [0.0, 0.001, 0.002], "values": [0.0, 1.0, 0.0]}
    scene = beams.cantilever_scene(n_nodes=16, length=beams.ROD_LENGTH,
                                   root_radius=beams.ROD_RADIUS, tip_radius=beams.ROD_RADIUS,
                                   material=beams.STEEL, tip_force=0.1, profile=pulse,
                                   duration=2.0, record_interval=1e-3, local_damping=0.0)
    (_, t, tip), wall = timed(beams.run_tip, scene, tmp / "freq.h5")
    free = t > 0.002
    peaks = peak_frequencies(t[free], tip[free, 2], 3)
    for k in range(3):
        rows.append((f"bending mode {k + 1}, 16 nodes (Hz)", peaks[k], fref[k],
                     peaks[k] / fref[k] - 1, wall if k == 0 else math.nan))
    print(f"{'quantity':46s} {'measured':>12s} {'reference':>12s} {'error':>10s} {'wall s':>7s}")
    for name, meas, ref_, err, wall in rows:
        m = "" if meas is None else f"{meas:12.6g}"
        r = "" if ref_ is None else f"{ref_:12.6g}"
        w = "" if math.isnan(wall) else f"{wall:7.2f}"
        print(f"{name:46s} {m:>12s} {r:>12s} {err:10.2e} {w:>7s}")
    print()
    print("Conservation and friction (independent references: exact conservation laws, Coulomb)")
    tests = [bodies.test_intermediate_axis_flip_conserves_momentum_and_energy,
             bodies.test_two_spheres_striking_a_free_cube_conserve_angular_momentum,
             bodies.test_cube_spinning_between_two_free_brushes_conserves_angular_momentum,
             lambda: bodies.test_bristle_on_incline_sticks_or_slides(20.0, False),
             lambda: bodies.test_bristle_on_incline_sticks_or_slides(40.0, True),
             bodies.test_energy_is_conserved_in_a_vibrating_brush_with_elastic_contacts,
             bodies.test_free_sphere_on_tapered_brush_conserves_energy,
             bodies.test_free_box_edge_first_on_tapered_brush_conserves_energy]
    for test in tests:
        t0 = time.perf_counter()
        test()
        wall = time.perf_counter() - t0
        print(f"  ({wall:.2f} s)")
    for name, value in bodies.FIGURES.items():
        print(f"{name:52s} {value:10.2e}")


if __name__ == "__main__":
    main()
