"""Brush Studio's DEM engine: bristles as chains of beam-bonded nodes, rigid debris bodies
from triangle meshes, Cundall-Strack contacts with friction and history, HDF5 results.

The public API is small::

    import engine
    scene = engine.load_scene("scene.json")        # or engine.parse_scene(dict_or_json)
    system = engine.build(scene)                   # arrays + flags switching on the stages it needs
    result = engine.run(system, output="run.h5", on_progress=print, cancel=event)
    with engine.open_result(result.path) as res:   # reader, also for files of killed runs
        t, f = res.time, res.series("brushes/brush/root_force")

Errors: :class:`SceneError` (bad input: field, value, what is allowed),
:class:`InstabilityError` (quantity, where, time, what to change), both
:class:`BrushStudioError`.

``import engine`` is light: each public name is imported from its module when first used
(PEP 562), so that loading or validating a scene, or reading a result, does not import numba,
the kernels, trimesh or scipy; ``engine.build`` and ``engine.run`` do.
"""
from __future__ import annotations

import importlib
import sys
import types

from ._cache import ensure_fresh_cache

# Here, not in a kernel module: every ``engine.<module>`` import runs this file first, so the
# stale-cache check always comes before numba loads any cached kernel.
ensure_fresh_cache()

# public name -> the module that defines it
_EXPORTS = {
    "Scene": "spec", "SCHEMA_VERSION": "spec", "load_scene": "spec", "parse_scene": "spec",
    "save_scene": "spec",
    "build": "build", "System": "build",
    "run": "run", "RunResult": "run", "Progress": "run", "energies": "observables",
    "angular_momentum": "observables", "linear_momentum": "observables", "run_steps": "run",
    "open_result": "results", "ResultFile": "results", "MemoryObserver": "observe",
    "prescribe_motion": "motion", "estimate": "estimate", "Cost": "estimate",
    "BrushStudioError": "errors", "SceneError": "errors", "InstabilityError": "errors",
}

__all__ = ["Scene", "SCHEMA_VERSION", "load_scene", "parse_scene", "save_scene", "build",
           "System", "run", "RunResult", "Progress", "open_result", "ResultFile",
           "prescribe_motion", "estimate", "Cost", "energies", "angular_momentum",
           "linear_momentum", "run_steps", "MemoryObserver",
           "BrushStudioError", "SceneError", "InstabilityError"]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        if name.startswith("_"):
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
        try:  # ``engine.state`` and the like, as after an eager import
            return importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


class _Engine(types.ModuleType):
    """The package's module type: ``engine.build`` and ``engine.run`` stay the functions.

    Importing the submodule ``engine/build.py`` (or ``run.py``) binds it to the package under
    the same name; an eager ``from .build import build`` used to rebind the function right
    after, and this keeps it so when the submodule is first imported later."""

    def __setattr__(self, name: str, value) -> None:
        if (isinstance(value, types.ModuleType) and _EXPORTS.get(name) == name
                and value.__name__ == f"{__name__}.{name}"):
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Engine
