"""study capture (issue 27 item 2): the capture criterion on synthetic series, the chaser's
load from the jaw servos, a physics check of the preset scene (momentum), and a tiny study
run with a trend that must hold."""
from __future__ import annotations

import copy
import csv
import json
import math

import numpy as np
import pytest

import engine
from studio.studies.capture.criterion import between_jaws, capture
from studio.studies.capture.task import chaser_load

T = np.arange(0.0, 3.0 + 1e-9, 0.01)
LIMITS = {"max_speed": 2e-3, "max_rate": math.radians(1.0), "hold": 0.5}


def _inside(n=len(T)):
    return np.ones(n, bool)


# ----------------------------------------------------------------------------- criterion
def test_a_target_slowed_to_rest_is_captured_when_it_falls_below_the_thresholds():
    # the relative rate decays as 10 deg/s exp(-t / 0.3 s): it falls below 1 deg/s at
    # t = 0.3 ln 10 = 0.691 s (closed form) and stays there; the speed is always small
    rate = math.radians(10.0) * np.exp(-T / 0.3)
    out = capture(T, np.full_like(T, 1e-4), rate, _inside(), **LIMITS)
    assert out["captured"] and not out["lost"]
    # one frame (10 ms): the criterion works on the recorded frames
    assert out["time_to_capture"] == pytest.approx(0.3 * math.log(10.0), abs=0.01)
    assert out["first_hold"] == out["time_to_capture"]


def test_a_target_that_keeps_spinning_is_never_captured():
    rate = np.full_like(T, math.radians(5.0))
    out = capture(T, np.zeros_like(T), rate, _inside(), **LIMITS)
    assert out == {"captured": False, "time_to_capture": None, "first_hold": None,
                   "lost": False}


def test_a_target_held_then_lost_is_not_captured_but_its_first_hold_is_reported():
    # held (slow, between the jaws) from 0.5 s to 1.5 s, then it slips out of the jaws
    between = (T < 1.5)
    rate = np.where(T >= 0.5, 0.0, 1.0)
    out = capture(T, np.zeros_like(T), rate, between, **LIMITS)
    assert not out["captured"] and out["lost"]
    assert out["first_hold"] == pytest.approx(0.5)


def test_a_hold_shorter_than_the_hold_time_does_not_count_and_the_last_stretch_does():
    # slow from 0.5 to 0.8 s (0.3 s < hold), spun up again, slow again from 2.0 s to the end
    # (1.0 s >= hold): captured at 2.0 s, never lost
    rate = np.where(((T >= 0.5) & (T < 0.8)) | (T >= 2.0 - 1e-9), 0.0, 1.0)
    out = capture(T, np.zeros_like(T), rate, _inside(), **LIMITS)
    assert out["captured"] and out["time_to_capture"] == pytest.approx(2.0)
    assert out["first_hold"] == pytest.approx(2.0)
    # a stretch reaching the end but shorter than the hold is not yet a capture
    out = capture(T, np.zeros_like(T), np.where(T >= 2.7, 0.0, 1.0), _inside(), **LIMITS)
    assert not out["captured"] and not out["lost"]


def test_a_still_target_is_captured_only_once_the_brushes_touch_it():
    # below every threshold from the start, but the jaws reach it at 0.8 s: held from then;
    # never touched (None): never held
    zeros = np.zeros_like(T)
    out = capture(T, zeros, zeros, _inside(), first_contact=0.8, **LIMITS)
    assert out["captured"] and out["time_to_capture"] == pytest.approx(0.8)
    assert not capture(T, zeros, zeros, _inside(), first_contact=None, **LIMITS)["captured"]


def test_speed_alone_can_refuse_a_capture():
    speed = np.full_like(T, 3e-3)          # 3 mm/s > 2 mm/s, the rate is zero
    assert not capture(T, speed, np.zeros_like(T), _inside(), **LIMITS)["captured"]


def test_between_jaws_needs_the_centre_inside_the_segment_and_near_the_line():
    left = np.tile([-0.2, 0.0, 0.0], (5, 1))
    right = np.tile([0.2, 0.0, 0.0], (5, 1))
    target = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.049], [0.0, 0.0, 0.051],
                       [0.25, 0.0, 0.0], [-0.19, 0.03, 0.0]])
    assert between_jaws(target, left, right, 0.05).tolist() == [True, True, False, False,
                                                                 True]


def test_the_chaser_load_is_minus_the_servo_forces_and_their_moments():
    # two jaws 0.2 m either side of the chaser's centre along x, each servo pushing its jaw
    # inward with 1 N: the forces cancel, and so do their moments (both act along the line
    # through the centre); a 1 N push along +y on the right jaw alone gives -1 N and a
    # torque -(r x F) = -(0.2 x 1) about z
    c = np.zeros((1, 3))
    pos = [np.array([[-0.2, 0.0, 0.0]]), np.array([[0.2, 0.0, 0.0]])]
    f, tq = chaser_load(c, pos, [np.array([[1.0, 0, 0]]), np.array([[-1.0, 0, 0]])],
                        [np.zeros((1, 3))] * 2)
    assert np.allclose(f, 0.0) and np.allclose(tq, 0.0)
    f, tq = chaser_load(c, pos, [np.zeros((1, 3)), np.array([[0.0, 1.0, 0]])],
                        [np.zeros((1, 3)), np.array([[0.0, 0.0, 0.5]])])
    assert np.allclose(f, [[0.0, -1.0, 0.0]]) and np.allclose(tq, [[0.0, 0.0, -0.2 - 0.5]])


# ----------------------------------------------------------------------------- physics
def _free_space_collision():
    """The preset in free space (mean_motion 0, no gravity gradient), its servos and the
    chaser's controller removed, the jaws thrown at the spinning target with unequal
    speeds (so the total momentum is not zero): only contacts and the brushes' mounts act."""
    from studio import presets

    scene = json.loads(presets.preset_path("gripper_capture_orbit").read_text())
    scene = copy.deepcopy(scene)
    scene["environment"] = {"orbit": {"mean_motion": 0.0}}
    scene["controllers"] = []
    for body in scene["bodies"]:
        if body["name"] == "jaw_left":
            body["velocity"] = [0.3, 0.0, 0.01]
        elif body["name"] == "jaw_right":
            body["velocity"] = [-0.1, 0.02, 0.0]
    scene["run"].update(duration=0.15, channels=["bodies"])
    return engine.parse_scene(scene)


def test_free_space_grip_conserves_linear_and_angular_momentum(tmp_path):
    # No external force or torque acts (free space, no thrust), so the total linear momentum
    # of jaws, bristles, target and chaser, and the angular momentum about the origin, must
    # stay what they were, through the bristles' hits on the tumbling target (friction on:
    # it is pairwise too) and the brushes' root reactions on the free jaws. Bugs caught: a
    # root reaction not passed to the jaw it is mounted on, a contact force applied to one
    # side only, a torque about the wrong point (a missing r x F), each O(1).
    system = engine.build(_free_space_collision())
    p0, l0 = engine.linear_momentum(system), engine.angular_momentum(system)
    result = engine.run(system, output=tmp_path / "free.h5")
    assert result.status == "completed"
    with engine.open_result(tmp_path / "free.h5") as res:
        touched = np.linalg.norm(res.series("bodies/target/contact_force"), axis=1).max()
    assert touched > 0.01, "the jaws' brushes hit the target within the run"
    p1, l1 = engine.linear_momentum(system), engine.angular_momentum(system)
    # scale: the momenta that were exchanged (jaw mass x closing speed; the target's spin
    # angular momentum); 1e-9: pairwise exchange leaves round-off only (~1e-16 per step
    # over ~1,400 steps and a few hundred contacts), far below a missing reaction (O(1))
    p_scale = 0.5 * (0.3 + 0.1)
    l_scale = p_scale * 0.2 + np.linalg.norm(l0)
    assert np.linalg.norm(p1 - p0) / p_scale < 1e-9
    assert np.linalg.norm(l1 - l0) / l_scale < 1e-9


# ----------------------------------------------------------------------------- the study
def test_tiny_capture_study_writes_its_outputs_and_a_target_outside_the_jaws_is_not_captured(
        tmp_path):
    # two still targets (no spin, so the outcome depends on the geometry alone): centred
    # between the jaws, and 150 mm across them along z (its faces span 100..200 mm, the
    # brushes' tips at most 20 + 5 mm from the axis: the brushes never reach it). The
    # centred one is held from the brushes' first touch; the other is never touched nor
    # between the jaws, so never captured. Bugs caught: a criterion that ignores where the
    # target is, or counts frames before the jaws arrive, or a missing/garbled output.
    from studio.studies.capture import Options, run

    options = Options(spins=[0.0], offsets=[0.0, 150.0], duration=1.0, hold=0.2,
                      nodes=3, workers=1, no_progress=True)
    result = run(options, tmp_path)
    assert result.exit_code == 0
    for name in ("capture.csv", "capture.png", "summary.json"):
        assert (tmp_path / name).is_file(), name
    rows = {r["run_id"]: r for r in csv.DictReader((tmp_path / "capture.csv").open())}
    centred, outside = rows["w0_d0"], rows["w0_d150"]
    assert centred["captured"] == "True" and outside["captured"] == "False"
    assert float(centred["time_to_capture"]) == pytest.approx(
        float(centred["first_contact"]))
    assert outside["first_contact"] == "" and float(outside["peak_target_force"]) == 0.0
    assert float(centred["first_contact"]) > 0.0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["runs"] == 2 and summary["captured"] == 1
    assert len(list((tmp_path / "runs").glob("*.h5"))) == 2
