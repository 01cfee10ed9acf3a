"""Bristle-body candidate filter on the seed's wedge scene: how many (segment, body)
candidates the list keeps and what the step loop costs with the wedge pressed into the brush.

The 60 degree wedge preset with 5 nodes per bristle; the wedge is driven down at a constant
0.1 m/s for 50 ms (5 mm into the tips), then held while ``--steps`` more steps are timed with
``time.process_time`` (CPU seconds of this process, all threads). Printed: dt, the candidate
count, the segments really within the skin of the wedge (brute force against every triangle),
CPU seconds for the timed steps and the vertical root force at the end.

Usage::

    python benchmarks/body_candidates.py [--steps 4000] [--depth 0.005]
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def wedge_scene(depth: float, speed: float = 0.1, n_nodes: int = 5):
    import engine
    data = json.loads((ROOT / "static_presets" / "wedge_60.json").read_text())
    data["brushes"][0]["n_nodes"] = n_nodes
    data["bodies"][0]["motion"] = {
        "type": "kinematic", "after": "hold",
        "profile": {"kind": "constant", "velocity": [0.0, 0.0, -speed],
                    "duration": depth / speed}}
    data["run"]["record_interval"] = 1.0
    data["run"]["channels"] = ["root_force"]
    return engine.parse_scene(data)


def segments_within_skin(system) -> int:
    """Segments whose capsule (largest end radius) is within the skin of a body triangle,
    by brute force over every (segment, triangle) pair (independent of the engine's grid)."""
    from engine.kernels.geometry import segment_triangle_closest
    from engine.kernels.rotations import qrot_inv
    bd, bn, nd = system.bodies, system.bonds, system.nodes
    skin = float(system.limits[3])
    count = 0
    k = 0
    for s in range(bn.i.shape[0]):
        i0, i1 = bn.i[s], bn.j[s]
        reach = float(bn.rmax[s]) + skin
        ends = []
        for i in (i0, i1):
            d = nd.x[i] - bd.pos[k]
            ends.append(np.array(qrot_inv(*bd.q[k], *d)))
        best = min(segment_triangle_closest(ends[0], ends[1], *bd.verts[bd.tris[t]])[4]
                   for t in range(bd.tris.shape[0]))
        count += best < reach
    return count


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--depth", type=float, default=0.005)
    a = ap.parse_args()
    import engine
    scene = wedge_scene(a.depth)
    system = engine.build(scene)
    out = Path(tempfile.mkdtemp(prefix="cand-bench-")) / "r.h5"
    t_press = a.depth / 0.1
    engine.run(system, until=t_press, output=out)
    n_cand = int(system.body_pairs.n[0])
    near = segments_within_skin(system)
    c0 = time.process_time()
    engine.run(system, until=system.time + a.steps * system.dt, output=out)
    cpu = time.process_time() - c0
    from engine.stepping.observables import root_reactions
    fz = float(root_reactions(system)["brush"][0][2])
    print(f"engine {engine.__file__}")
    print(f"dt {system.dt:.3e} s, {system.n_bristles * 4} segments, steps to press "
          f"{int(round(t_press / system.dt))}")
    print(f"candidates {n_cand}, segments within skin {near} (brute force)")
    print(f"timed {a.steps} steps: {cpu:.3f} CPU s ({1e3 * cpu / a.steps:.3f} ms/step)")
    print(f"root force z {fz!r} N at t = {system.time:.6f} s, steps {system.steps}")


if __name__ == "__main__":
    main()
