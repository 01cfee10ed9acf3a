"""The step loop frees every array it makes: memory that scales with the state, not with the
number of steps. The hot kernels are compiled without reference counting
(``engine.kernels.jit.item_kernel``), so an array one of them (or a function it calls) makes
is never freed: ``cw_coefficients`` made one per free body per step in orbit, 433 bytes a
step for ``detumble_upper_stage``, 17 GB over the 4e7 steps of an hour of DEM contact.

Numba's own allocation counters (``NUMBA_NRT_STATS``, read in a child process, since the
variable must be set before numba starts) must balance over a call of the compiled loop, for
scenes that exercise orbit and controllers (the detumble preset), a hinge (the spin rig), a
kinematic body (the wedge) and a reduced-brush patch.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

CHILD = r"""
import json, sys
import engine
from engine.stepping.loop import _advance
from numba.core.runtime import rtsys
from studio import presets
from studio.studies.detumble import detumble_scene, reduced_scene
from engine.model.reduced_law import load_law

out = {}
for name in ("detumble_upper_stage", "spin_cube_40", "wedge_60", "reduced"):
    if name == "reduced":
        law = load_law(sys.argv[1])
        scene = reduced_scene(detumble_scene("detumble_upper_stage", duration=5.0), law)
    else:
        scene = json.loads(presets.load_preset_or_file(name).to_json())
    system = engine.build(engine.parse_scene(scene))
    _advance(system, 20)                     # compiled or loaded; lists built
    a = rtsys.get_allocation_stats()
    _advance(system, 300)
    b = rtsys.get_allocation_stats()
    out[name] = [b.alloc - a.alloc, b.free - a.free]
print(json.dumps(out))
"""


def test_the_step_loop_frees_every_array_it_makes():
    env = dict(os.environ, NUMBA_NRT_STATS="1", NUMBA_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    law = ROOT / "benchmarks" / "data" / "detumble_brush_17x5_sliding_law.json"
    proc = subprocess.run([sys.executable, "-c", CHILD, str(law)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    counts = json.loads(proc.stdout.strip().splitlines()[-1])
    for name, (made, freed) in counts.items():
        # exact: an array made and not freed in 300 steps is a leak, whatever its size
        assert made == freed, f"{name}: {made} arrays made, {freed} freed over 300 steps"
