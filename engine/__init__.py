"""Brush Studio's DEM engine: bristles as chains of beam-bonded nodes, rigid debris bodies
from triangle meshes, Cundall-Strack contacts with friction and history, HDF5 results.

Its folders follow the data: ``model/`` (the scene model: spec, layout, shapes, the reduced
law's file), ``assembly/`` (scene -> arrays: bristles, bodies, contacts, loads, the time step
and the cost estimate), ``stepping/`` (the run loop in Python around the compiled step, what
it records and checks, prescribed motions), ``kernels/`` (the numba step itself, typed on the bundles
of ``state.py``), ``io/`` (the recorder, the result reader, exports) and ``analysis/``
(closed forms and spectra used to check and read runs).

The public API is small::

    import engine
    scene = engine.load_scene("scene.json")        # or engine.parse_scene(dict_or_json)
    system = engine.build(scene)                   # arrays + flags switching on the stages it needs
    result = engine.run(system, output="run.h5", on_progress=print, cancel=event)
    with engine.open_result(result.path) as res:   # reader, also for files of killed runs
        t, f = res.time, res.series("brushes/brush/root_force")
    snap = system.save_state()                     # the state only (engine.state.STATE_FIELDS)
    system.restore_state(snap); child = system.branch()  # rerun, or branch sharing the model

Errors: :class:`SceneError` (bad input: field, value, what is allowed),
:class:`InstabilityError` (quantity, where, time, what to change), both
:class:`BrushStudioError`.

``import engine`` is light: each public name is imported from its module when first used
(PEP 562), so that loading or validating a scene, or reading a result, does not import numba,
the kernels, trimesh or scipy; ``engine.build`` and ``engine.run`` do.
"""
from __future__ import annotations

import importlib

from engine._cache import ensure_fresh_cache

# Here, not in a kernel module: every ``engine.<module>`` import runs this file first, so the
# stale-cache check always comes before numba loads any cached kernel.
ensure_fresh_cache()

# public name -> the module that defines it
_EXPORTS = {
    "Scene": "model.spec", "SCHEMA_VERSION": "model.spec", "load_scene": "model.spec",
    "parse_scene": "model.spec", "save_scene": "model.spec",
    "build": "assembly.system", "System": "assembly.system",
    "StateSnapshot": "assembly.system",
    "run": "stepping.loop", "RunResult": "stepping.loop", "Progress": "stepping.loop",
    "run_steps": "stepping.loop", "energies": "stepping.observables",
    "angular_momentum": "stepping.observables", "linear_momentum": "stepping.observables",
    "open_result": "io.results", "ResultFile": "io.results",
    "MemoryObserver": "stepping.observe", "prescribe_motion": "stepping.motion",
    "estimate": "assembly.estimate", "Cost": "assembly.estimate",
    "BrushStudioError": "errors", "SceneError": "errors", "InstabilityError": "errors",
}

__all__ = ["Scene", "SCHEMA_VERSION", "load_scene", "parse_scene", "save_scene", "build",
           "System", "StateSnapshot", "run", "RunResult", "Progress", "open_result", "ResultFile",
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
