"""``import engine`` is light: a scene can be loaded and validated, and a result opened,
without importing numba, the kernels, trimesh or scipy; the public names all resolve."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("numba", "trimesh", "scipy", "distributed", "engine.kernels.stepper",
         "engine.kernels.orbit", "engine.assembly.system")

_CODE = """
import json, sys
import engine
scene = engine.load_scene(sys.argv[1])
orbit = engine.load_scene(sys.argv[2]).environment.orbit
assert orbit.altitude is not None and orbit.n > 0   # the closed form, without the kernels
try:
    engine.parse_scene({"schema_version": 1, "brushes": "no"})
except engine.SceneError:
    pass
engine.open_result, engine.ResultFile, engine.BrushStudioError, engine.InstabilityError
print(json.dumps(sorted(m for m in sys.argv[3:] if m in sys.modules)))
"""


def test_loading_a_scene_imports_no_kernels():
    scene = ROOT / "static_presets" / "wedge_60.json"
    orbiting = ROOT / "static_presets" / "detumble_upper_stage.json"   # orbit by altitude
    p = subprocess.run([sys.executable, "-c", _CODE, str(scene), str(orbiting), *HEAVY],
                       cwd=ROOT,
                       capture_output=True, text=True, check=True)
    assert json.loads(p.stdout) == []


def test_public_names_resolve_to_the_functions(tiny_scene):
    import engine

    for name in engine.__all__:
        assert getattr(engine, name) is not None
    import engine.assembly.system  # noqa: F401  (binds the submodule to the package, as imports do)
    import engine.stepping.loop  # noqa: F401

    # the names stay the functions, not the modules of the same name
    assert callable(engine.build) and callable(engine.run)
    system = engine.build(engine.parse_scene(tiny_scene()))
    assert isinstance(system, engine.System)
    assert engine.state.OK == 0  # a submodule reached as an attribute, as before


_DESIGN_CODE = """
import json, sys
from studio.web import view as uv
scene = json.load(open(sys.argv[1]))
assert len(uv.design_bristles(scene).positions) and len(uv.design_bodies(scene))
print(json.dumps(sorted(m for m in sys.argv[3:] if m in sys.modules)))
"""


def test_design_view_imports_no_kernels():
    # the studio draws a design with engine.model.layout and engine.model.meshes (numpy, trimesh): a
    # kernel module imported on the way (say engine.kernels.rotations for a quaternion) would
    # make the first design view wait for numba
    scene = ROOT / "static_presets" / "gripper.json"
    p = subprocess.run([sys.executable, "-c", _DESIGN_CODE, str(scene), "numba",
                        "engine.kernels.stepper", "engine.assembly.system", "engine.kernels.rotations"],
                       cwd=ROOT, capture_output=True, text=True, check=True)
    assert json.loads(p.stdout) == []
