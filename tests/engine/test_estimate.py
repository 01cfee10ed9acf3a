"""engine.estimate: a scene's cost from the scene alone (issue 13, item 2). The timestep it
estimates must never exceed the build's (a limit on steps would otherwise let through runs
that take longer than it says) and must be the build's where a bristle sets it."""
from __future__ import annotations

import glob
import time
from pathlib import Path

import numpy as np
import pytest

import engine
from engine.assembly.estimate import estimate

PRESETS = sorted(glob.glob(str(Path(__file__).resolve().parents[2] / "static_presets" /
                                "*.json")))


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: Path(p).stem)
def test_estimated_dt_is_the_builds_where_bristles_set_it(path):
    scene = engine.load_scene(path)
    if not scene.brushes:
        pytest.skip("no bristles: bodies alone set dt (the estimate leaves them out)")
    cost = estimate(scene)
    system = engine.build(scene)
    assert cost.n_nodes == system.n_nodes and cost.n_bristles == system.n_bristles
    # the same Gershgorin bound on the same bristle: equal to rounding where the bristles set
    # the build's dt; bodies (a fast body's tunnelling cap, a small bead's contact rotation:
    # micro_trap) can only lower it below the estimate, which leaves them out
    if system.dt_limited_by.startswith("the bristles"):
        assert cost.dt == pytest.approx(system.dt, rel=1e-9)
    else:
        assert cost.dt >= system.dt * (1 - 1e-9)
    assert cost.steps == pytest.approx(np.ceil(scene.run.duration / cost.dt))


def test_one_element_for_the_build_and_the_estimate():
    # catches a second copy of the element's formulas (the estimate's dt drifting from the
    # build's bristles) and masses that lose part of the bristle
    import math

    import engine.assembly.bristles as build_bristles
    import engine.assembly.estimate as estimate_module
    from engine.assembly.element import frustum_bond_stiffness, node_masses

    assert build_bristles.frustum_bond_stiffness is frustum_bond_stiffness
    assert build_bristles.node_masses is node_masses
    assert not hasattr(estimate_module, "_frustum")
    # the segments of a linear taper partition one frustum: the node masses sum to its
    # closed-form mass rho pi L (R0^2 + R0 R1 + R1^2) / 3 (round-off only: 1e-12)
    rho, length, R0, R1, n = 1100.0, 0.03, 8e-4, 3e-4, 9
    r = R0 + (R1 - R0) * np.linspace(0, 1, n)
    mass, inertia = node_masses(rho, r, length / (n - 1))
    whole = rho * math.pi * length * (R0 * R0 + R0 * R1 + R1 * R1) / 3.0
    assert mass.sum() == pytest.approx(whole, rel=1e-12)
    assert inertia == pytest.approx(0.5 * mass * r ** 2, rel=1e-15)
    # a uniform bond is the seed's beam (eq. 3.1): 12 E I / L^3 and E I / L, no coupling
    E, G, rad, L = 2e9, 7e8, 2e-4, 1e-3
    I = math.pi * rad ** 4 / 4
    kn, ks, kb, ksb, kt = frustum_bond_stiffness(E, G, rad, rad, L)
    assert (kn, ks, kb, ksb, kt) == pytest.approx(
        (E * math.pi * rad ** 2 / L, 12 * E * I / L ** 3, E * I / L, 0.0, G * 2 * I / L),
        rel=1e-12)


def test_a_huge_scene_is_estimated_at_once(tiny_scene):
    data = tiny_scene()
    data["brushes"][0].update(rows=100_000, columns=100_000, n_nodes=4096)
    scene = engine.parse_scene(data)
    t0 = time.perf_counter()
    cost = estimate(scene)
    assert time.perf_counter() - t0 < 0.5  # one bristle of 4096 nodes, not 4e13 of them
    assert cost.n_nodes == 100_000 * 100_000 * 4096
    assert cost.memory_bytes > 1e15 and cost.steps > 1e6
