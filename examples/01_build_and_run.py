"""Build a small scene from Python and run it
==============================================

A 3 x 3 silicone brush (20 mm bristles, 5 nodes each) is pressed 1 mm by a rigid PLA box for
10 ms. The scene is a plain dict validated by ``engine.parse_scene``; ``engine.build`` turns
it into arrays and picks the time step, ``engine.run`` runs it into an HDF5 result file and
returns its summary: the steps done, the time step and what limits it, and the speed in
node-steps per second. Units are SI throughout (docs/scene.md lists every field).

Run it from the repository root, with the package installed (``pip install -e .``)::

    python examples/01_build_and_run.py [OUT_DIR]

It writes ``OUT_DIR/scene.json`` and ``OUT_DIR/run.h5`` (default OUT_DIR:
``./example_output/01_build_and_run``). The first run compiles the engine's numba kernels
(a minute or two); later runs take a few seconds.
"""
import math
import sys
from pathlib import Path

import engine

out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "example_output/01_build_and_run")
out_dir.mkdir(parents=True, exist_ok=True)

# The scene: materials, the friction between them, one brush and one moving body.
scene_dict = {
    "schema_version": 1,
    "name": "example_press",
    "description": "3 x 3 silicone brush pressed 1 mm by a PLA box (examples/01)",
    "materials": {
        "silicone": {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1700.0},
        "pla": {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1240.0},
    },
    "contact_pairs": [
        {"materials": ["silicone", "silicone"], "friction_angle": math.radians(44.0)},
        {"materials": ["silicone", "pla"], "friction_angle": math.radians(24.0)},
    ],
    "brushes": [
        {"name": "brush", "material": "silicone", "rows": 3, "columns": 3,
         "pitch": [0.003, 0.003], "bristle_length": 0.02, "root_radius": 0.001,
         "tip_radius": 0.0005, "n_nodes": 5},
    ],
    "bodies": [
        # The box's bottom face starts 0.5 mm above the tips' surfaces (tip node at 20 mm
        # plus its 0.5 mm radius) and moves down 1.5 mm in 10 ms: 1 mm into the brush.
        {"name": "box", "material": "pla",
         "shape": {"type": "box", "size": [0.015, 0.015, 0.002]},
         "pose": {"position": [0.0, 0.0, 0.022]},
         "motion": {"type": "kinematic",
                    "profile": {"kind": "constant", "velocity": [0.0, 0.0, -0.15],
                                "duration": 0.01}}},
    ],
    "environment": {"gravity": [0.0, 0.0, -9.81]},
    "run": {"duration": 0.01, "record_interval": 0.0005},
}

scene = engine.parse_scene(scene_dict)   # engine.SceneError lists every bad field
engine.save_scene(scene, out_dir / "scene.json")

system = engine.build(scene)
print(f"built: {system.n_bristles} bristles, {system.n_nodes} nodes, stages {system.stages}")

result = engine.run(system, output=out_dir / "run.h5")
s = result.summary
print(f"status: {result.status}")
print(f"simulated time: {s['time']:.6g} s")
print(f"steps: {s['steps']}")
print(f"dt: {s['dt']:.6g} s")
print(f"dt limited by: {s['dt_limited_by']}")
print(f"node-steps per second: {s['node_steps_per_s']:.4g}")
print(f"wall time: {s['wall_s']:.2f} s")
print(f"result file: {result.path} ({result.frames} frames)")
