"""Initial overlap (engine/assembly/overlap.py): the geometry against closed forms, and build's
warning for a body that starts inside the brush (issue 14, defect 1)."""
from __future__ import annotations

import copy
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from engine.assembly import overlap


def _box(lo, hi):
    """A closed axis-aligned box mesh (outward winding) from corner lo to corner hi."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                  for z in (lo[2], hi[2])])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def test_signed_distance_of_a_box_inside_and_outside():
    # would catch a lost sign (inside reported as outside) or a distance to the wrong face
    v, f = _box((-1, -1, -1), (1, 1, 1))
    pts = np.array([[0, 0, 0], [0, 0, 0.7], [0, 0, 3], [2, 2, 0], [0.5, 0, 0]])
    d = overlap.signed_distances(pts, v, f)
    assert d == pytest.approx([-1.0, -0.3, 2.0, math.sqrt(2), -0.5], abs=1e-12)


def test_segment_distance_of_skew_and_parallel_segments():
    # skew segments 1 apart in z; parallel ones offset past their ends (end-point distance)
    p1, q1 = np.array([[-1, 0, 0], [0, 0, 0.]]), np.array([[1, 0, 0], [1, 0, 0.]])
    p2, q2 = np.array([[0, -1, 1], [2, 1, 0.]]), np.array([[0, 1, 1], [3, 1, 0.]])
    d, s, t = overlap.segment_distances(p1, q1, p2, q2)
    assert d == pytest.approx([1.0, math.sqrt(2)], abs=1e-12)
    assert s[0] == pytest.approx(0.5) and t[0] == pytest.approx(0.5)


def _two_bristles(gap):
    """Two straight vertical bristles of radius 0.5 with axes ``gap`` apart."""
    x = np.array([[0, 0, 0], [0, 0, 5], [gap, 0, 0], [gap, 0, 5.]])
    return dict(positions=x, radius=np.full(4, 0.5), bonds=np.array([[0, 1], [2, 3]]),
                node_bristle=np.array([0, 0, 1, 1]), bristle_names=["bristle 0", "bristle 1"],
                bristle_brush=np.array([0, 0]), brush_names=["brush"])


def test_touching_bristles_are_not_overlap_and_crossing_ones_are():
    # pitch = two radii: touching, not overlapping (a tolerance-free check would flag every
    # tightly packed brush)
    assert overlap.find_overlaps(**_two_bristles(1.0)) == []
    found = overlap.find_overlaps(**_two_bristles(0.8))
    assert len(found) == 1 and found[0].kind == "bristle-bristle"
    assert found[0].depth == pytest.approx(0.2)
    assert found[0].items == ["bristle 0 and bristle 1"]


def test_body_in_brush_depth_and_bristles():
    # a box whose bottom face is 1 below the tips of bristle 1 only: depth = 1 + radius
    args = _two_bristles(10.0)
    v, f = _box((8, -2, 4), (12, 2, 8))
    found = overlap.find_overlaps(**args, bodies=[overlap.BodyShape("box", v, f)])
    assert [o.kind for o in found] == ["body-bristle"]
    assert found[0].depth == pytest.approx(1.5)
    assert found[0].items == ["bristle 1"] and found[0].body == "box"
    assert "body 'box' starts inside 1 bristle of brush 'brush', up to" in str(found[0])
    # the brush is mounted on this body: its roots touching it are no overlap
    assert overlap.find_overlaps(**args, bodies=[overlap.BodyShape("box", v, f)],
                                 bristle_mount=np.array([0, 0])) == []


def test_interpenetrating_bodies():
    a = overlap.BodyShape("a", *_box((0, 0, 0), (2, 2, 2)))
    b = overlap.BodyShape("b", *_box((1.5, 0.5, 0.5), (3, 1.5, 1.5)))
    found = overlap.find_overlaps(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 2)),
                                  np.zeros(0), [], np.zeros(0), [], bodies=[a, b])
    assert [o.kind for o in found] == ["body-body"]
    assert found[0].depth == pytest.approx(0.5)


def _demo_with(demo, **changes):
    d = copy.deepcopy(demo)
    if "shape" in changes:
        d["bodies"][0]["shape"] = changes["shape"]
    if "bristle_length" in changes:
        d["brushes"][0]["bristle_length"] = changes["bristle_length"]
    return d


@pytest.mark.parametrize("changes,depth_mm", [
    # the reproductions: a 20 mm box at z = 33.5 mm reaches 23.5 mm, 9.5 mm below the
    # 33 mm tips, plus the 0.5 mm tip radius
    (dict(shape={"type": "box", "size": [0.02, 0.02, 0.02]}), 10.0),
    # 45 mm bristles under the 60 degree wedge's apex at (y = 0.5 mm, z = 33.5 mm): the
    # bristle row at y = 0 is 11.5 mm above the apex and 0.5 mm beside it, so
    # 11.5 sin 30 deg - 0.5 cos 30 deg from the nearer face, plus the tip radius
    (dict(bristle_length=0.045), 11.5 * 0.5 - 0.5 * math.cos(math.pi / 6) + 0.5),
])
def test_build_warns_of_a_body_inside_the_brush(demo_scene_dict, changes, depth_mm):
    import engine

    scene = engine.parse_scene(_demo_with(demo_scene_dict, **changes))
    (warning,) = [w for w in engine.build(scene).warnings if "initial overlap" in w]
    assert "body 'wedge' starts inside" in warning and "brush 'brush'" in warning
    assert "bodies.0.pose.position" in warning
    got = float(warning.split("up to ")[1].split(" mm")[0])
    # 3 % : the sampled capsule (tip radius interpolated along the last segment) and the
    # rounding to 3 significant digits
    assert got == pytest.approx(depth_mm, rel=0.03)


def test_validate_reports_the_overlap(demo_scene_dict, tmp_path):
    path = tmp_path / "box.json"
    path.write_text(json.dumps(_demo_with(demo_scene_dict,
                                          shape={"type": "box", "size": [0.02] * 3})))
    out = subprocess.run([sys.executable, "-m", "studio.cli", "validate", str(path)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "warning: initial overlap: body 'wedge' starts inside 35 bristles" in out.stdout
