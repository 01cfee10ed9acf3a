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
from engine.estimate import _frustum, estimate

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
    # the same Gershgorin bound on the same bristle: equal to rounding, unless the build's
    # tunnelling cap (fast bodies) lowers it below the estimate
    if "speed of body" not in system.dt_limited_by:
        assert cost.dt == pytest.approx(system.dt, rel=1e-9)
    assert cost.steps == pytest.approx(np.ceil(scene.run.duration / cost.dt))


def test_the_frustum_stiffnesses_are_the_builds():
    # catches the copy drifting from the build's element (a tapered or a uniform bond)
    from engine.build_bristles import frustum_bond_stiffness

    for r0, r1 in ((2e-4, 2e-4), (3e-4, 1e-4)):
        assert _frustum(2e9, 7e8, r0, r1, 1e-3) == pytest.approx(
            frustum_bond_stiffness(2e9, 7e8, r0, r1, 1e-3), rel=1e-12)


def test_a_huge_scene_is_estimated_at_once(tiny_scene):
    data = tiny_scene()
    data["brushes"][0].update(rows=100_000, columns=100_000, n_nodes=4096)
    scene = engine.parse_scene(data)
    t0 = time.perf_counter()
    cost = estimate(scene)
    assert time.perf_counter() - t0 < 0.5  # one bristle of 4096 nodes, not 4e13 of them
    assert cost.n_nodes == 100_000 * 100_000 * 4096
    assert cost.memory_bytes > 1e15 and cost.steps > 1e6
