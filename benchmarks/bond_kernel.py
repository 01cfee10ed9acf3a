"""What the bonds and the integration cost per step, kernel by kernel, on two real states:
the seed's wedge pressed 20 mm into the 17 x 5 brush (the wedge_60 preset's 8 nodes per
bristle, undamped bonds) and the detumble_upper_stage preset in contact (5 nodes per bristle,
damped bonds, energy tracked, orbit on).

Each state is built, advanced into contact and saved (``System.save_state``); every kernel is
then called on it many times, the state restored before each repeat, and timed with
``time.process_time`` (CPU seconds of this process); the figure is the median of the
repeats, in ns per bond or per node. Printed per state:

* ``bonds``: ``bond_node_forces`` as the step loop calls it on all but a call's last step
  (a damped, energy-tracking scene writes the bonds' dissipation every step), and its
  variants without damping, with damping, and with damping and the energies;
* ``kick+drift`` and ``kick``: the node integration (the Hill-frame drift with an orbit);
  these and the bonds are timed from a compiled loop, so no call from Python is counted;
* ``local damping`` and ``local damping +diss``: Cundall's damping of the node forces
  (``stepper.local_damping``), without and with the dissipation's running sum (a run that
  books energy), timed with a zero coefficient so that repeated calls leave the forces
  alone (the same instructions as any coefficient);
* ``step``: a whole step of the engine (``engine.run`` without recording), per node.

It runs on older commits too (``bond_node_forces`` before the dissipation had its own switch
took one ``want_energy`` for all three), so a figure can be set beside the commit before a
change. Until the bonds were evaluated in SIMD blocks it also timed a plain bonds-only chain
with the per-bond law (``_bond_eval``, gone with that change).

Usage (from the repository root)::

    NUMBA_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bond_kernel.py [--repeats 7]
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from numba import njit

ROOT = Path(__file__).resolve().parent.parent


def wedge_system(depth: float = 0.020):
    """The wedge_60 preset's brush (8 nodes per bristle) with the wedge driven ``depth`` (m)
    down at 0.2 m/s (the study drives it more slowly; the bonds' cost does not depend on
    how the state was reached)."""
    import engine
    data = json.loads((ROOT / "static_presets" / "wedge_60.json").read_text())
    speed = 0.2
    data["bodies"][0]["motion"] = {
        "type": "kinematic", "after": "hold",
        "profile": {"kind": "constant", "velocity": [0.0, 0.0, -speed],
                    "duration": depth / speed}}
    data["run"]["record_interval"] = 1.0
    data["run"]["channels"] = ["root_force"]
    system = engine.build(engine.parse_scene(data))
    engine.run(system, until=depth / speed, output=False)
    return system


def detumble_system(steps: int = 3000):
    """detumble_upper_stage as the preset has it, ``steps`` steps in (the brush in contact)."""
    import engine
    system = engine.build(engine.load_scene(ROOT / "static_presets" /
                                            "detumble_upper_stage.json"))
    engine.run(system, until=steps * system.dt, output=False)
    return system


def median_ns(call, restore, calls: int, repeats: int) -> float:
    """Median over ``repeats`` of the CPU ns of one ``call()`` (``calls`` calls timed,
    ``restore()`` before each repeat, not timed)."""
    call()
    out = []
    for _ in range(repeats):
        restore()
        t0 = time.process_time()
        for _ in range(calls):
            call()
        out.append((time.process_time() - t0) / calls * 1e9)
    return statistics.median(out)


def kernel_figures(system, repeats: int) -> dict:
    import engine
    from engine.kernels.bonds import bond_node_forces
    from engine.kernels.orbit import nodes_kick_drift_cw
    from engine.kernels.stepper import local_damping, nodes_kick, nodes_kick_drift
    fl = system.flags
    nd, bn = system.nodes, system.bonds
    dt = system.dt
    n_nodes, n_bonds = nd.x.shape[0], bn.i.shape[0]
    snap = system.save_state()

    def restore():
        system.restore_state(snap)

    # each figure from a compiled loop of ``calls`` calls (a call from Python unboxes the
    # node and bond bundles, some tens of arrays: about as long as the bonds of a small brush)
    calls = max(200, 400_000 // n_nodes)
    per_bond = lambda fn: median_ns(lambda: fn(calls), restore, 1, repeats) / (  # noqa: E731
        calls * n_bonds)
    per_node = lambda fn: median_ns(lambda: fn(calls), restore, 1, repeats) / (  # noqa: E731
        calls * n_nodes)
    loop_diss = bool(fl.track_energy and fl.bond_damping)
    if bond_node_forces.py_func.__code__.co_argcount == 5:
        # before the dissipation had its own switch (one want_energy wrote all three)
        @njit
        def bond_loop(nd, bn, damped, energy, diss, dt, n):
            for _ in range(n):
                bond_node_forces(nd, bn, damped, energy or diss, dt)
    else:
        @njit
        def bond_loop(nd, bn, damped, energy, diss, dt, n):
            for _ in range(n):
                bond_node_forces(nd, bn, damped, diss, energy, dt)

    def bonds(damped, energy, diss):
        return lambda n: bond_loop(nd, bn, damped, energy, diss, dt, n)

    r = {"nodes": n_nodes, "bonds": n_bonds, "damped": bool(fl.bond_damping),
         "diss_every_step": loop_diss, "orbit": bool(fl.orbit)}
    r["bonds as the loop"] = per_bond(bonds(fl.bond_damping, False, loop_diss))
    r["bonds undamped"] = per_bond(bonds(False, False, False))
    r["bonds damped"] = per_bond(bonds(True, False, False))
    r["bonds damped+energy"] = per_bond(bonds(True, True, True))

    @njit
    def kd_loop(x, v, q, w, f, t, im, ii, dt, orbit_n, n):
        for _ in range(n):
            if orbit_n != 0.0:
                nodes_kick_drift_cw(x, v, q, w, f, t, im, ii, dt, orbit_n)
            else:
                nodes_kick_drift(x, v, q, w, f, t, im, ii, dt)

    @njit
    def kick_loop(v, w, f, t, im, ii, dt, n):
        for _ in range(n):
            nodes_kick(v, w, f, t, im, ii, dt)

    if local_damping.py_func.__code__.co_argcount == 7:
        # before a run that books no energy had the loop without the dissipation's sum
        @njit
        def damping_loop(f, t, v, w, im, diss, n):
            for _ in range(n):
                local_damping(f, t, v, w, im, 0.0, dt)
    else:
        @njit
        def damping_loop(f, t, v, w, im, diss, n):
            for _ in range(n):
                local_damping(f, t, v, w, im, 0.0, dt, diss)

    orbit_n = float(system.mission.orbit[0]) if fl.orbit else 0.0
    r["kick+drift"] = per_node(lambda n: kd_loop(nd.x, nd.v, nd.q, nd.w, nd.f, nd.t,
                                                 nd.inv_mass, nd.inv_inertia, dt, orbit_n, n))
    r["kick"] = per_node(lambda n: kick_loop(nd.v, nd.w, nd.f, nd.t, nd.inv_mass,
                                             nd.inv_inertia, dt, n))
    for diss in (False, True):
        r[f"local damping{' +diss' if diss else ''}"] = per_node(
            lambda n: damping_loop(nd.f, nd.t, nd.v, nd.w, nd.inv_mass, diss, n))
    n_steps = max(200, 200_000 // n_nodes)
    step = lambda: engine.run(system, until=system.time + n_steps * dt,  # noqa: E731
                              output=False)
    r["step"] = median_ns(step, restore, 1, repeats) / (n_steps * n_nodes)
    restore()
    return r


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args()
    import engine
    print(f"engine {engine.__file__}; CPU ns, median of {a.repeats} repeats")
    for name, make in (("wedge 20 mm", wedge_system), ("detumble", detumble_system)):
        system = make()
        r = kernel_figures(system, a.repeats)
        print(f"{name}: {r['nodes']} nodes, {r['bonds']} bonds, damped {r['damped']}, "
              f"dissipation every step {r['diss_every_step']}, orbit {r['orbit']}")
        for k in ("bonds as the loop", "bonds undamped", "bonds damped", "bonds damped+energy"):
            print(f"  {k:<20} {r[k]:7.1f} ns/bond")
        for k in ("kick+drift", "kick", "local damping", "local damping +diss", "step"):
            print(f"  {k:<20} {r[k]:7.1f} ns/node")


if __name__ == "__main__":
    main()
