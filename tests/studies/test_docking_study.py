"""study docking (issue 27): the hull-on-hull reference obeys the impact law it documents,
and the study's figures come out of a real run."""
from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from studio.studies.docking.study import docking_scene
from studio.studies.docking.task import hull_gap


def test_rigid_head_on_docking_rebounds_at_e_times_the_closing_speed(tmp_path):
    # Two equal free cubes face to face, the pair's restitution e = 0.5: Newton's impact law
    # gives a separation speed of e times the closing speed, whatever the contact's
    # stiffness (the engine sizes its dashpot for the clipped linear law), and no external
    # force acts, so the total momentum is what it was. Bug caught: a dashpot sized for the
    # unclipped law (e too high by ~10 %), a face contact counting its points' restitution
    # once per point, a force applied to one body only (momentum changes at O(1)).
    scene = engine.parse_scene(docking_scene(0.03, 0.0, 0.0, brush=False))
    e = scene.contact_pairs[0].restitution
    system = engine.build(scene)
    p0 = engine.linear_momentum(system)
    engine.run(system, output=tmp_path / "rigid.h5")
    p1 = engine.linear_momentum(system)
    with engine.open_result(tmp_path / "rigid.h5") as res:
        vc = res.series("bodies/chaser/velocity")[:, 0]
        vt = res.series("bodies/target/velocity")[:, 0]
        f = np.linalg.norm(res.series("bodies/target/contact_force"), axis=1)
    assert f.max() > 0 and f[-1] == 0.0, "they touched and came apart within the run"
    # 3 %: the contact's start and end fall between steps; measured over a dt ladder
    # (dt_safety 0.5 / 0.25 / 0.1: 0.486 / 0.505 / 0.493 of the closing speed) the rebound
    # scatters by +-1.5 % around e without a trend, so 2x that is the bound
    assert (vt[-1] - vc[-1]) == pytest.approx(e * 0.03, rel=0.03)
    # 1e-10: momentum is exchanged pairwise (equal and opposite), so only round-off
    assert np.linalg.norm(p1 - p0) / np.linalg.norm(p0) < 1e-10


def test_hull_gap_is_the_distance_from_the_docking_face_to_the_nearest_vertex():
    # a 0.2 m target cube turned 30 deg about z, centre 0.3 m ahead of a chaser whose face is
    # at x = 0.1: its nearest corner reaches 0.1 (cos 30 + sin 30) = 0.1366 m toward the
    # chaser, so the gap is 0.3 - 0.1366 - 0.1 (a closed form, not the engine)
    v = np.array([[sx, sy, sz] for sx in (-0.1, 0.1) for sy in (-0.1, 0.1) for sz in (-0.1, 0.1)])
    a = math.radians(30)
    qt = np.array([[math.cos(a / 2), 0, 0, math.sin(a / 2)]])
    gap = hull_gap(0.1, np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]]),
                   np.array([[0.3, 0.0, 0.0]]), qt, v)
    assert gap[0] == pytest.approx(0.3 - 0.1 * (math.cos(a) + math.sin(a)) - 0.1, abs=1e-12)


def test_a_misaligned_target_starts_clear_of_the_brush_tips():
    # the study turns and shifts the target: its hull must start the preset's clearance
    # outside the brush's reach, never inside it (an overlapping start is refused by build)
    for mis in (0.0, 15.0, 30.0):
        scene = docking_scene(0.03, 0.01, math.radians(mis), brush=True)
        target = next(b for b in scene["bodies"] if b["name"] == "target")
        chaser = next(b for b in scene["bodies"] if b["name"] == "chaser")
        brush = scene["brushes"][0]
        tips = chaser["shape"]["size"][0] / 2 + brush["bristle_length"] + brush["tip_radius"]
        a, b = target["shape"]["size"][0] / 2, target["shape"]["size"][1] / 2
        q = target["pose"]["orientation"]
        angle = 2 * math.atan2(q[3], q[0])
        near = target["pose"]["position"][0] - (a * math.cos(angle) + b * math.sin(abs(angle)))
        assert near - tips == pytest.approx(0.005, abs=1e-9)


@pytest.mark.parametrize("name", ["docking", "docking_rigid"])
def test_smoke_run_of_the_docking_presets_stays_finite(name, tmp_path):
    # a smoke test (it catches a preset the engine refuses, a NaN, a crash; not a number):
    # 40 of the preset's own steps, every recorded channel finite
    from studio import presets

    scene = presets.load_preset(name)
    system = engine.build(scene)
    result = engine.run(system, until=40 * system.dt, output=tmp_path / f"{name}.h5")
    assert result.status == "completed"
    with result.open() as res:
        for channel in res.channels():
            assert np.all(np.isfinite(res.series(channel))), channel
    assert "Seed chapter 5" in scene.description and "assum" in scene.description
