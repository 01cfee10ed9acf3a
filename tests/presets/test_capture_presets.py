"""The capture preset (issue 27 item 2): the layout study capture relies on, the geometry its
description states (tips 20 mm outside the faces at the start, servo targets 5 mm inside),
what it says it does not model, and a short run that stays finite."""
from __future__ import annotations

import numpy as np
import pytest

import engine
from studio import presets

NAME = "gripper_capture_orbit"
OPEN_GAP, INTERFERENCE = 0.02, 0.005     # m: as the description states


def test_capture_preset_is_listed_and_has_the_layout_the_study_relies_on():
    assert NAME in presets.preset_names()
    scene = presets.load_preset(NAME)
    text = scene.description
    assert "Seed chapter 5" in text and "issue 27" in text and "assum" in text
    assert "NOT modelled" in text and "record interval" in text and "Duration" in text
    bodies = {b.name: b for b in scene.bodies}
    assert {b.motion.type for b in bodies.values()} == {"free"}
    assert not bodies["chaser"].collide and not bodies["jaw_left"].collide
    assert {b.name: b.mount for b in scene.brushes} == {"brush_left": "jaw_left",
                                                       "brush_right": "jaw_right"}
    ctl = {c.name: c for c in scene.controllers}
    assert set(ctl) == {"jaw_left_servo", "jaw_right_servo", "chaser_control"}
    assert ctl["jaw_left_servo"].reference == "chaser"
    assert scene.environment.orbit is not None and scene.environment.orbit.altitude == 400e3
    assert engine.build(scene).dt > 0


@pytest.mark.parametrize("side, sign", [("left", -1.0), ("right", 1.0)])
def test_jaws_open_clear_of_the_target_and_servo_to_the_stated_interference(side, sign):
    # geometry from the scene's own numbers (not the generator's): the base is on the
    # jaw's inner face, the bristles point at the target, the tip's surface reaches
    # bristle_length + tip_radius beyond the base
    scene = presets.load_preset(NAME)
    bodies = {b.name: b for b in scene.bodies}
    jaw, target, chaser = bodies[f"jaw_{side}"], bodies["target"], bodies["chaser"]
    brush = next(b for b in scene.brushes if b.mount == jaw.name)
    face = target.shape.size[0] / 2
    inner = jaw.shape.size[0] / 2
    reach = brush.bristle_length + brush.tip_radius
    tips_open = sign * jaw.pose.position[0] - inner - reach
    assert tips_open - face == pytest.approx(OPEN_GAP, abs=1e-12)
    servo = next(c for c in scene.controllers if c.name == f"jaw_{side}_servo")
    closed = np.asarray(chaser.pose.position) + np.asarray(servo.position)
    assert closed[1:] == pytest.approx([0.0, 0.0], abs=1e-12)   # on the target's x axis
    assert face - (sign * closed[0] - inner - reach) == pytest.approx(INTERFERENCE, abs=1e-12)


def test_smoke_run_of_the_capture_preset_stays_finite(smoke_run):
    smoke_run(NAME)  # (its checks: tests/presets/conftest.py)
