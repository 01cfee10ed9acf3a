"""Brush Studio's DEM engine: bristles as chains of beam-bonded nodes, rigid debris bodies
from triangle meshes, Cundall-Strack contacts with friction and history, HDF5 results.

The public API is small::

    import engine
    scene = engine.load_scene("scene.json")        # or engine.parse_scene(dict_or_json)
    system = engine.build(scene)                   # arrays + only the stages the scene needs
    result = engine.run(system, output="run.h5", on_progress=print, cancel=event)
    with engine.open_result(result.path) as res:   # reader, also for files of killed runs
        t, f = res.time, res.series("brushes/brush/root_force")

Errors: :class:`SceneError` (bad input: field, value, what is allowed),
:class:`InstabilityError` (quantity, where, time, what to change), both
:class:`BrushStudioError`.
"""
from ._cache import ensure_fresh_cache

ensure_fresh_cache()

from .build import System, build  # noqa: E402
from .errors import BrushStudioError, InstabilityError, SceneError
from .motion import prescribe_motion
from .results import ResultFile, open_result
from .run import Progress, RunResult, angular_momentum, energies, linear_momentum, run
from .spec import SCHEMA_VERSION, Scene, load_scene, parse_scene, save_scene

__all__ = ["Scene", "SCHEMA_VERSION", "load_scene", "parse_scene", "save_scene", "build",
           "System", "run", "RunResult", "Progress", "open_result", "ResultFile",
           "prescribe_motion", "energies", "angular_momentum", "linear_momentum", "BrushStudioError",
           "SceneError", "InstabilityError"]
