"""Run specs shared by the runner tests (a helper module, not a test file)."""
from __future__ import annotations


def modulus_sweep(tiny_scene, moduli) -> list:
    """One run per Young's modulus of ``tiny_scene()``, then one the engine refuses in the
    task (a negative root radius): what the runner tests send through each path."""
    from studio.studies.runner import RunSpec

    specs = []
    for i, E in enumerate(moduli):
        scene = tiny_scene()
        scene["materials"]["silicone"]["youngs_modulus"] = E
        specs.append(RunSpec(f"E{i}", scene, {"youngs_modulus": E}))
    bad = tiny_scene()
    bad["brushes"][0]["root_radius"] = -0.001  # the engine refuses it in the task
    specs.append(RunSpec("bad", bad, {"youngs_modulus": "broken radius"}))
    return specs
