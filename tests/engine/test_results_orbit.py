"""Result files of a scene in orbit (issue 15): ``ResultFile.energy`` and
``body_angular_momentum`` hold the Hill frame's terms, the same as the live
``engine.energies`` (the Jacobi integral) and the engine's inertial ``L``."""
from __future__ import annotations

import math

import pytest

import engine

AL = {"youngs_modulus": 70e9, "density": 2700.0}
STEEL = {"youngs_modulus": 200e9, "poisson_ratio": 0.3, "density": 7640.0}


def _scene(gravity_gradient: bool) -> dict:
    # a free box off the reference orbit, turned off the axes and spinning; a hinge body off
    # the origin; a rod in the tidal field: every term of the orbital energy is non-zero
    q = [math.cos(0.4), math.sin(0.4) * 0.6, math.sin(0.4) * 0.0, math.sin(0.4) * 0.8]
    return {
        "materials": {"al": AL, "steel": STEEL},
        "brushes": [{"name": "rod", "material": "steel", "bristle_length": 0.2,
                     "root_radius": 1e-3, "tip_radius": 1e-3, "n_nodes": 4,
                     "base": {"position": [0.3, 0.2, 0.1]}}],
        "bodies": [
            {"name": "box", "material": "al", "shape": {"type": "box", "size": [0.4, 0.3, 0.2]},
             "mass_properties": {"density": 500.0}, "motion": {"type": "free"},
             "pose": {"position": [1.0, -0.5, 0.4], "orientation": q},
             "velocity": [0.01, 0.02, -0.01], "angular_velocity": [0.2, -0.1, 0.3]},
            {"name": "wheel", "material": "al", "shape": {"type": "box", "size": [0.2, 0.1, 0.3]},
             "mass_properties": {"density": 500.0},
             "motion": {"type": "hinge", "axis": [0.0, 0.6, 0.8]},
             "pose": {"position": [-1.0, 0.5, -0.3], "orientation": q},
             "angular_velocity": [0.0, 0.3, 0.4]}],
        "environment": {"orbit": {"mean_motion": 0.05, "gravity_gradient": gravity_gradient}},
        "run": {"duration": 0.02, "record_interval": 0.01,
                "channels": ["nodes", "bodies", "energy", "node_velocities"]}}


@pytest.mark.parametrize("gravity_gradient", [False, True])
def test_file_energy_is_the_live_jacobi_integral(tmp_path, gravity_gradient):
    # same state, the same terms: equal to rounding (1e-12 of the largest term). Before
    # the file's reader knew the orbit, its gravity energy missed the tidal and frame terms
    # (~1e-3 J here) and its kinetic energy used the relative spin in L.
    system = engine.build(engine.parse_scene(_scene(gravity_gradient)))
    result = engine.run(system, output=tmp_path / "o.h5")
    live = engine.energies(system)
    from engine.stepping.observables import orbit_energy
    assert abs(orbit_energy(system)) > 1e-4          # the orbital terms matter here
    with result.open() as res:
        e = res.energy(frame=-1)
        L = res.body_angular_momentum("box", frame=-1)
    scale = max(abs(v) for v in live.values())
    for key in ("kinetic", "gravity", "total"):
        assert e[key] == pytest.approx(live[key], rel=0, abs=1e-12 * scale), key
    k = system.body_names.index("box")
    assert L == pytest.approx(system.bodies.L[k], rel=1e-12)
