"""The studio's design view (``studio.web.view.design_bristles`` on a scene dict) draws the
bristles where ``engine.build`` puts them: the same node positions, radii and bonds.

The view used to carry its own copy of the layout maths; this test catches the two drifting
apart again: the view reading a brush field differently from the scene model (a default
``n_nodes``, the ``seed``, the ``pattern``: a missing half-pitch shift or another random
draw order), or placing a mounted base by another pose than build (the body's centre of
mass or principal frame instead of its shape frame, or the two rotations composed the other
way round), or numbering the second brush's nodes from zero.
"""
from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

import engine
from studio.web import view as uv

PRESETS = Path(__file__).resolve().parents[2] / "static_presets"

# both sides come from engine.model.layout, so they agree to rounding; any of the bugs above moves
# a node by at least a tip perturbation (here >= 1e-6 m) or a pitch (1e-3 m)
TOL = 1e-12  # m


def _preset(name: str) -> dict:
    return json.loads((PRESETS / f"{name}.json").read_text())


def _grid() -> dict:
    scene = _preset("wedge_60")  # a 17 x 5 grid brush in the world, a wedge body
    del scene["brushes"][0]["n_nodes"]  # the scene model's default (8) on both sides
    return scene


def _staggered() -> dict:
    scene = _preset("wedge_60")
    scene["brushes"][0].update(rows=6, columns=4, pattern="staggered", tip_variance=4e-7,
                               seed=11)  # tips moved by a Gaussian of sd 0.63 mm
    return scene


def _mounted() -> dict:
    """A brush on a free body turned about a skew axis, whose principal frame is not its
    shape frame (off-diagonal inertia), with a base itself tilted and offset on the body."""
    scene = _preset("wedge_60")
    a = 0.7
    scene["bodies"].append({
        "name": "plate", "material": "pla", "shape": {"type": "box", "size": [0.05, 0.05, 0.01]},
        "pose": {"position": [0.01, -0.2, 0.03],
                 "orientation": [math.cos(a / 2), 0.6 * math.sin(a / 2), 0.0,
                                 0.8 * math.sin(a / 2)]},
        "motion": {"type": "free"},
        "mass_properties": {"mass": 1.0, "inertia": [[1e-3, 2e-4, 0.0], [2e-4, 2e-3, 0.0],
                                                      [0.0, 0.0, 3e-3]]}})
    scene["brushes"][0].update(mount="plate", rows=3, columns=2, tip_variance=1e-7, seed=5,
                               base={"position": [0.004, 0.0, 0.005],
                                     "orientation": [math.cos(0.2), 0.0, math.sin(0.2), 0.0]})
    return scene


def _two_brushes() -> dict:
    return _preset("gripper")  # two 17 x 5 brushes, each on a plate turned 90 deg about y


@pytest.mark.parametrize("make", [_grid, _staggered, _mounted, _two_brushes],
                         ids=["grid", "staggered_tip_variance", "mounted_on_turned_body",
                              "two_brushes"])
def test_design_view_matches_build(make):
    scene = make()
    view = uv.design_bristles(copy.deepcopy(scene))
    system = engine.build(engine.parse_scene(scene))
    assert view.n_bristles == system.n_bristles
    assert view.positions.shape == system.nodes.x.shape
    assert np.abs(view.positions - system.nodes.x).max() <= TOL
    assert np.abs(view.radius - system.nodes.rad).max() <= TOL
    assert np.array_equal(view.bonds, np.stack([system.bonds.i, system.bonds.j], axis=1))
    assert np.array_equal(uv.design_bristle_first(scene), system.bristle_first_node)
    # the layout is not trivially the same everywhere: bristles differ from one another
    assert np.ptp(view.positions[:, 0]) > 1e-3
