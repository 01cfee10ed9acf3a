"""What the bonds and the integration cost per step, kernel by kernel, on two real states:
the seed's wedge pressed 20 mm into the 17 x 5 brush (the wedge_60 preset's 8 nodes per
bristle, undamped bonds) and the detumble_upper_stage preset in contact (5 nodes per bristle,
damped bonds, energy tracked, orbit on), beside a plain bonds-only chain of the same size.

Each state is built, advanced into contact and saved (``System.save_state``); every kernel is
then called on it many times, the state restored before each repeat, and timed with
``time.process_time`` (CPU seconds of this process); the figure is the median of the
repeats, in ns per bond or per node. Printed per state:

* ``bonds``: ``bond_node_forces`` as the step loop calls it on all but a call's last step
  (a damped, energy-tracking scene writes the bonds' dissipation every step), and its
  variants without damping, with damping, and with damping and the energies;
* ``kick+drift`` and ``kick``: the node integration (the Hill-frame drift with an orbit);
* ``step``: a whole step of the engine (``engine.run`` without recording), per node;
* ``plain chain``: the same bond law on the same number of nodes as one contiguous
  loop (bond b joins nodes b and b + 1 of one chain, no index arrays, no damping) with its
  kick-drift-kick, per node: the floor the engine's bonds and integration are compared with.

Usage (from the repository root)::

    NUMBA_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bond_kernel.py [--repeats 7]
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
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


# ---- the plain chain: the bond law of engine.kernels.bonds on one contiguous chain

def chain_kernel():
    from engine.kernels.bonds import _bond_eval
    from engine.kernels.rotations import qexp, qmul, qnormalize

    if _bond_eval.py_func.__code__.co_argcount == 23:
        # before the dissipation had its own switch
        @njit(inline="always")
        def bond(b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, e, dt):
            return _bond_eval(b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cn, cn, cn,
                              e, e, e, False, False, dt)
    else:
        @njit(inline="always")
        def bond(b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, e, dt):
            return _bond_eval(b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cn, cn, cn,
                              e, e, e, False, False, False, dt)

    @njit
    def steps(x, v, q, w, f, t, bi, bj, kn, ks, kb, ksb, kt, L0, cn, e, im, ii, dt, n_steps):
        n = x.shape[0]
        h = 0.5 * dt
        for _ in range(n_steps):
            for k in range(1, n):
                for a in range(3):
                    v[k, a] += h * f[k, a] * im
                    x[k, a] += dt * v[k, a]
                    w[k, a] += h * t[k, a] * ii
                ew, ex, ey, ez = qexp(dt * w[k, 0], dt * w[k, 1], dt * w[k, 2])
                nw, nx, ny, nz = qmul(ew, ex, ey, ez, q[k, 0], q[k, 1], q[k, 2], q[k, 3])
                q[k, 0], q[k, 1], q[k, 2], q[k, 3] = qnormalize(nw, nx, ny, nz)
            f[:] = 0.0
            t[:] = 0.0
            for b in range(n - 1):
                Fx, Fy, Fz, Tix, Tiy, Tiz, Tjx, Tjy, Tjz = bond(
                    b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, e, dt)
                f[b, 0] += Fx
                f[b, 1] += Fy
                f[b, 2] += Fz
                f[b + 1, 0] -= Fx
                f[b + 1, 1] -= Fy
                f[b + 1, 2] -= Fz
                t[b, 0] += Tix
                t[b, 1] += Tiy
                t[b, 2] += Tiz
                t[b + 1, 0] += Tjx
                t[b + 1, 1] += Tjy
                t[b + 1, 2] += Tjz
            for k in range(1, n):
                for a in range(3):
                    v[k, a] += h * f[k, a] * im
                    w[k, a] += h * t[k, a] * ii
    return steps


def plain_chain_ns(n_nodes: int, repeats: int) -> float:
    """CPU ns per node and step of a bent chain of ``n_nodes`` silicone nodes (a 1 mm bristle
    section per bond), bonds and kick-drift-kick."""
    steps = chain_kernel()
    L = 0.033 / 7
    E, G, r = 2.7e6, 2.7e6 / 2.96, 0.75e-3
    A, I = np.pi * r * r, np.pi * r ** 4 / 4
    nb = n_nodes - 1
    # an arc of radius R in the x-z plane, each node's frame along the arc (bond rotations
    # of 0.05 rad, as in a pressed bristle); no bond is at rest, so the chain moves
    R = L / 0.05
    ang = np.arange(n_nodes) * 0.05
    x = np.zeros((n_nodes, 3))
    x[:, 0] = R * (1.0 - np.cos(ang))
    x[:, 2] = R * np.sin(ang)
    q = np.zeros((n_nodes, 4))
    q[:, 0] = np.cos(0.5 * ang)
    q[:, 2] = np.sin(0.5 * ang)
    v, w, f, t = (np.zeros((n_nodes, 3)) for _ in range(4))
    bi = np.arange(nb)
    bj = bi + 1
    full = lambda val: np.full(nb, val)  # noqa: E731
    kn, ks, kb, kt = full(E * A / L), full(12 * E * I / L ** 3), full(E * I / L), full(
        G * 2 * I / L)
    ksb, L0, cn, e = full(0.0), full(L), full(0.0), np.zeros(nb)
    m = 1700.0 * A * L
    im, ii = 1.0 / m, 1.0 / (m * r * r / 2)
    dt = 0.2 * np.sqrt(m / kn[0])
    args = (x, v, q, w, f, t, bi, bj, kn, ks, kb, ksb, kt, L0, cn, e, im, ii, dt)
    saved = [a.copy() for a in (x, v, q, w, f, t)]

    def restore():
        for a, s_ in zip((x, v, q, w, f, t), saved):
            a[...] = s_

    n_steps = 200
    ns = median_ns(lambda: steps(*args, n_steps), restore, 5, repeats) / (n_steps * n_nodes)
    if not np.all(np.isfinite(x)):
        raise RuntimeError("the plain chain went unstable: its figure would time NaNs")
    return ns


def kernel_figures(system, repeats: int) -> dict:
    import engine
    from engine.kernels.bonds import bond_node_forces
    from engine.kernels.orbit import nodes_kick_drift_cw
    from engine.kernels.stepper import nodes_kick, nodes_kick_drift
    fl = system.flags
    nd, bn = system.nodes, system.bonds
    dt = system.dt
    n_nodes, n_bonds = nd.x.shape[0], bn.i.shape[0]
    snap = system.save_state()

    def restore():
        system.restore_state(snap)

    calls = max(200, 400_000 // n_nodes)
    per_bond = lambda fn: median_ns(fn, restore, calls, repeats) / n_bonds  # noqa: E731
    per_node = lambda fn: median_ns(fn, restore, calls, repeats) / n_nodes  # noqa: E731
    loop_diss = bool(fl.track_energy and fl.bond_damping)
    if bond_node_forces.py_func.__code__.co_argcount == 5:
        # before the dissipation had its own switch (one want_energy wrote all three)
        bonds = lambda damped, energy, diss: bond_node_forces(  # noqa: E731
            nd, bn, damped, energy or diss, dt)
    else:
        bonds = lambda damped, energy, diss: bond_node_forces(  # noqa: E731
            nd, bn, damped, energy, diss, dt)
    r = {"nodes": n_nodes, "bonds": n_bonds, "damped": bool(fl.bond_damping),
         "diss_every_step": loop_diss, "orbit": bool(fl.orbit)}
    r["bonds as the loop"] = per_bond(lambda: bonds(fl.bond_damping, False, loop_diss))
    r["bonds undamped"] = per_bond(lambda: bonds(False, False, False))
    r["bonds damped"] = per_bond(lambda: bonds(True, False, False))
    r["bonds damped+energy"] = per_bond(lambda: bonds(True, True, True))
    if fl.orbit:
        orbit_n = system.mission.orbit[0]
        kd = lambda: nodes_kick_drift_cw(nd.x, nd.v, nd.q, nd.w, nd.f, nd.t,  # noqa: E731
                                         nd.inv_mass, nd.inv_inertia, dt, orbit_n)
    else:
        kd = lambda: nodes_kick_drift(nd.x, nd.v, nd.q, nd.w, nd.f, nd.t,  # noqa: E731
                                      nd.inv_mass, nd.inv_inertia, dt)
    r["kick+drift"] = per_node(kd)
    r["kick"] = per_node(lambda: nodes_kick(nd.v, nd.w, nd.f, nd.t, nd.inv_mass,
                                            nd.inv_inertia, dt))
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
        for k in ("kick+drift", "kick", "step"):
            print(f"  {k:<20} {r[k]:7.1f} ns/node")
        chain = plain_chain_ns(r["nodes"], a.repeats)
        print(f"  {'plain chain':<20} {chain:7.1f} ns/node (bonds + kick-drift-kick, "
              f"{r['nodes']} nodes)", flush=True)


if __name__ == "__main__":
    main()
