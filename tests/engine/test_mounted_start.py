"""A brush mounted on a moving or spinning body starts with the body's rigid motion
(engine.assembly.bristles.start_with_mounts): no jerk in the first steps, so the root force of
a brush carried through free space without contact is its own inertial load."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

import engine

PRESET = Path(__file__).resolve().parents[2] / "static_presets" / "detumble_upper_stage.json"


def _chaser_scene(velocity, angular_velocity, duration, record_interval=0.002):
    """The detumble_upper_stage preset's chaser (300 kg, 1 m box, 50 kg m^2) with its brush
    (5 x 17 silicone bristles, 165 mm, on the -x face, pointing along -x), alone in free
    space: no target, no controller, no orbit, no gravity."""
    d = json.loads(PRESET.read_text())
    chaser = next(b for b in d["bodies"] if b["name"] == "chaser")
    chaser = dict(chaser, velocity=list(velocity), angular_velocity=list(angular_velocity))
    return engine.parse_scene({
        "materials": d["materials"], "contact_pairs": d.get("contact_pairs", []),
        "brushes": d["brushes"], "bodies": [chaser],
        "run": {"duration": duration, "record_interval": record_interval,
                "channels": ["root_force", "bodies"]}})


def _run(scene, tmp_path, name):
    sys = engine.build(scene)
    res = engine.run(sys, output=tmp_path / f"{name}.h5")
    assert res.status == "completed"
    with res.open() as r:
        f = r.series("brushes/brush/root_force")
    return sys, np.linalg.norm(f, axis=1)


def _brush_mass_and_reach(sys):
    """The brush's mass and the largest distance of its nodes from the chaser's centre."""
    nd = sys.nodes
    r = np.linalg.norm(nd.x - sys.bodies.pos[0], axis=1)
    return float(nd.mass.sum()), float(r.max())


def test_nodes_start_with_the_rigid_motion_of_their_mount():
    # every node: v = v_body + omega x r, spin = omega, to rounding (1e-12 m/s); the old
    # build left them at rest
    v0, w0 = np.array([-0.05, 0.01, 0.0]), np.array([0.0, 0.1, math.radians(10)])
    sys = engine.build(_chaser_scene(v0, w0, 0.01))
    nd, bd = sys.nodes, sys.bodies
    want = bd.v[0] + np.cross(bd.w[0], nd.x - bd.pos[0])
    assert np.allclose(nd.v, want, rtol=0, atol=1e-12)
    assert np.allclose(nd.w, bd.w[0], rtol=0, atol=1e-12)
    assert np.abs(nd.v).max() > 0.04


def test_approach_at_5_cm_s_has_no_root_force(tmp_path):
    # a uniformly moving body with no contact and no loads: the brush carries no load at
    # all, so the root force is rounding (bond stiffness ~5e3 N/m x position rounding
    # ~1e-15 m ~ 1e-11 N; 1e-6 N leaves margin). Starting at rest, the old build showed
    # 17.4 N as the chaser's motion hit the resting brush.
    _, f = _run(_chaser_scene([-0.05, 0.0, 0.0], [0.0, 0.0, 0.0], 0.2), tmp_path, "approach")
    assert f.max() < 1e-6


def test_spin_at_10_deg_s_root_force_is_the_centripetal_load(tmp_path):
    # spinning at omega about z: the bristles need the centripetal force m omega^2 r, so the
    # root carries at most M omega^2 R (M the brush's mass, R its farthest node from the
    # centre); the load comes on as a step at t = 0 on bristles that start straight, which
    # can overshoot the static deflection's force by up to 2x: bound 2 M omega^2 R (44 mN
    # here). The old build started the brush at rest: 3.2 N.
    w = math.radians(10.0)
    sys, f = _run(_chaser_scene([0.0, 0.0, 0.0], [0.0, 0.0, w], 0.3), tmp_path, "spin")
    M, R = _brush_mass_and_reach(sys)
    bound = 2.0 * M * w * w * R
    assert bound < 0.1
    assert f.max() < bound, (f.max(), bound)


def test_fast_mounted_brush_runs_stably(tmp_path):
    # 2 m/s and 0.3 rad/s: the old build failed with an instability at 0.22 s; the root
    # force stays below the centripetal bound 2 M omega^2 R of the test above
    w = 0.3
    sys, f = _run(_chaser_scene([-2.0, 0.0, 0.0], [0.0, 0.0, w], 0.4), tmp_path, "fast")
    M, R = _brush_mass_and_reach(sys)
    assert sys.time == pytest.approx(0.4, abs=sys.dt)
    assert f.max() < 2.0 * M * w * w * R, (f.max(), 2.0 * M * w * w * R)
