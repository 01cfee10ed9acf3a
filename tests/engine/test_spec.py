"""The scene model: the documented example validates and round-trips; every kind of bad input
gives a SceneError naming the dotted field and the bad value."""
from __future__ import annotations

import copy
import json
import math
import re
from pathlib import Path

import pytest

from engine.errors import SceneError
from engine.model.spec import load_scene, parse_scene, save_scene

DOC = Path(__file__).resolve().parents[2] / "docs" / "scene.md"

# discriminator tags pydantic puts into the error path of tagged unions (bodies.0.shape.box.size)
_TAGS = {"box", "sphere", "cylinder", "wedge", "mesh", "fixed", "free", "hinge", "kinematic",
         "constant", "stepped_parabolic", "waypoints"}


def _doc_example() -> dict:
    """The one complete JSON example of docs/scene.md."""
    blocks = re.findall(r"```json\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) == 1, "docs/scene.md must hold exactly one ```json example"
    return json.loads(blocks[0])


def _field(path: str) -> str:
    """A problem's dotted path with pydantic's union tags removed (the JSON path)."""
    return ".".join(p for p in path.split(".") if p not in _TAGS)


def _problems(data) -> dict[str, object]:
    with pytest.raises(SceneError) as info:
        parse_scene(data)
    return {_field(p.field): p.value for p in info.value.problems}


@pytest.fixture
def scene_dict() -> dict:
    return copy.deepcopy(_doc_example())


# --------------------------------------------------------------------------- valid scenes
def test_doc_example_validates(scene_dict):
    scene = parse_scene(scene_dict)
    assert scene.brushes[0].n_bristles == 9
    assert scene.bodies[0].shape.type == "wedge"
    assert scene.bodies[0].motion.profile.kind == "stepped_parabolic"
    assert scene.bodies[0].motion.after == "hold"


def test_doc_example_fits_the_run(scene_dict):
    """The example's text says its 10 steps fit in the run: check that arithmetic."""
    scene = parse_scene(scene_dict)
    prof = scene.bodies[0].motion.profile
    t_d = math.sqrt(6 * prof.step / prof.max_acceleration)  # seed 4.2
    n = prof.n_steps * (2 if prof.unload else 1)
    assert prof.start_delay + n * (t_d + prof.dwell) < scene.run.duration


def test_json_round_trip(scene_dict, tmp_path):
    scene = parse_scene(scene_dict)
    again = parse_scene(scene.to_json())
    assert again == scene
    assert again.model_dump() == scene.model_dump()
    path = tmp_path / "scene.json"
    save_scene(scene, path)
    assert load_scene(path) == scene


def test_round_trip_keeps_a_changed_value(scene_dict):
    """The round trip compares values, not just types: a changed field must show."""
    scene = parse_scene(scene_dict)
    other = dict(json.loads(scene.to_json()))
    other["brushes"][0]["tip_radius"] = 0.0004
    assert parse_scene(other) != scene


def test_undefined_pair_is_frictionless_and_elastic(scene_dict):
    scene = parse_scene(scene_dict)
    law = scene.pair("pla", "pla")
    assert law.friction_angle == 0.0 and law.restitution == 1.0
    friction = scene.pair("pla", "silicone").friction_angle
    assert friction == pytest.approx(math.radians(24), abs=1e-6)  # 6 digits in the JSON


# --------------------------------------------------------------------------- bad scenes
def test_negative_radius(scene_dict):
    scene_dict["brushes"][0]["root_radius"] = -0.001
    assert _problems(scene_dict) == {"brushes.0.root_radius": -0.001}


def test_nan_through_json(scene_dict):
    scene_dict["brushes"][0]["tip_radius"] = float("nan")
    text = json.dumps(scene_dict)  # Python's json writes NaN, and reads it back
    assert "NaN" in text
    problems = _problems(text)
    assert list(problems) == ["brushes.0.tip_radius"]
    assert math.isnan(problems["brushes.0.tip_radius"])


def test_unknown_schema_version(scene_dict):
    scene_dict["schema_version"] = 2
    assert _problems(scene_dict) == {"schema_version": 2}


def test_unknown_field(scene_dict):
    scene_dict["run"]["time_step"] = 1e-6
    assert _problems(scene_dict) == {"run.time_step": 1e-6}


def test_non_unit_quaternion(scene_dict):
    scene_dict["bodies"][0]["pose"]["orientation"] = [1.0, 1.0, 0.0, 0.0]
    problems = _problems(scene_dict)
    assert list(problems) == ["bodies.0.pose.orientation"]
    assert list(problems["bodies.0.pose.orientation"]) == [1.0, 1.0, 0.0, 0.0]


def test_unknown_material_reference(scene_dict):
    scene_dict["bodies"][0]["material"] = "steel"
    assert _problems(scene_dict) == {"bodies.0.material": "steel"}


def test_unknown_material_in_contact_pair(scene_dict):
    scene_dict["contact_pairs"][1]["materials"] = ["silicone", "foam"]
    assert _problems(scene_dict) == {"contact_pairs.1.materials": "foam"}


def test_free_body_without_mass_properties(scene_dict):
    scene_dict["bodies"][0]["motion"] = {"type": "free"}
    assert _problems(scene_dict) == {"bodies.0.mass_properties": None}


def test_kinematic_then_free_needs_mass_properties(scene_dict):
    scene_dict["bodies"][0]["motion"]["after"] = "free"
    assert _problems(scene_dict) == {"bodies.0.mass_properties": None}
    scene_dict["bodies"][0]["mass_properties"] = {"density": 1250.0}
    parse_scene(scene_dict)  # the same body with a density is fine


def test_bad_load_node(scene_dict):
    scene_dict["loads"] = [{"brush": "brush", "node": 8, "force": [0.0, 0.0, -1.0]}]
    assert _problems(scene_dict) == {"loads.0.node": 8}  # n_nodes = 8: nodes 0..7
    scene_dict["loads"][0]["node"] = -8  # the root, counted from the tip
    parse_scene(scene_dict)


def test_stop_body_unknown(scene_dict):
    scene_dict["run"]["stop"] = {"quantity": "body_angular_speed", "value": 0.1,
                                 "body": "cube"}
    assert _problems(scene_dict) == {"run.stop.body": "cube"}


def test_duplicated_pair(scene_dict):
    scene_dict["contact_pairs"].append({"materials": ["pla", "silicone"]})  # same, reversed
    assert _problems(scene_dict) == {"contact_pairs.2.materials": ["pla", "silicone"]}


def test_waypoint_times_not_increasing(scene_dict):
    scene_dict["bodies"][0]["motion"]["profile"] = {
        "kind": "waypoints", "times": [0.0, 0.5, 0.5],
        "positions": [[0, 0, 0.034], [0, 0, 0.03], [0, 0, 0.029]]}
    problems = _problems(scene_dict)
    assert len(problems) == 1
    (field, value), = problems.items()
    # today the whole profile is named; a field-level validator would name .times
    assert field in ("bodies.0.motion.profile", "bodies.0.motion.profile.times")
    times = value["times"] if isinstance(value, dict) else value
    assert list(times) == [0.0, 0.5, 0.5]


def test_every_problem_is_reported(scene_dict):
    """Several independent field errors come back together, not one at a time."""
    scene_dict["brushes"][0]["root_radius"] = -1.0
    scene_dict["brushes"][0]["n_nodes"] = 1
    scene_dict["run"]["record_interval"] = 0.0
    assert set(_problems(scene_dict)) == {"brushes.0.root_radius", "brushes.0.n_nodes",
                                          "run.record_interval"}


def test_error_message_names_field_value_and_allowed(scene_dict):
    scene_dict["brushes"][0]["root_radius"] = -0.001
    with pytest.raises(SceneError) as info:
        parse_scene(scene_dict)
    (problem,) = info.value.problems
    assert problem.allowed  # says what is allowed
    text = str(info.value)
    assert "brushes.0.root_radius" in text and "-0.001" in text and problem.allowed in text


# --------------------------------------------------------------------------- files
def test_load_scene_missing_file(tmp_path):
    missing = tmp_path / "nope.json"
    with pytest.raises(SceneError) as info:
        load_scene(missing)
    (problem,) = info.value.problems
    assert problem.field == "(file)" and problem.value == str(missing)


def test_load_scene_invalid_json(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"materials": {,}')
    with pytest.raises(SceneError) as info:
        load_scene(path)
    (problem,) = info.value.problems
    assert problem.field == "(file)" and "JSON" in problem.allowed


def test_load_scene_resolves_relative_mesh(scene_dict, tmp_path):
    scene_dict["bodies"][0]["shape"] = {"type": "mesh", "file": "parts/wedge.stl"}
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene_dict))
    scene = load_scene(path)
    assert Path(scene.bodies[0].shape.file) == (tmp_path / "parts" / "wedge.stl").resolve()



def test_invalid_json_names_file_line_and_column(tmp_path):
    """A scene file with a syntax error says where: file, line, column (not `(file) = None`)."""
    path = tmp_path / "broken.json"
    path.write_text('{"name": "x",\n  "brushes": [}\n')
    with pytest.raises(SceneError) as info:
        load_scene(path)
    (problem,) = info.value.problems
    assert problem.field == "(file)" and problem.value == str(path)
    assert "line 2, column 15" in problem.allowed and "not valid JSON" in problem.allowed


def test_missing_field_names_the_field_not_the_enclosing_object(tiny_scene):
    scene = tiny_scene()
    del scene["brushes"][0]["bristle_length"]
    with pytest.raises(SceneError) as info:
        parse_scene(scene)
    (problem,) = info.value.problems
    assert problem.field == "brushes.0.bristle_length"
    assert problem.value is None          # before: the whole brush dict
    assert str(problem) == "brushes.0.bristle_length = None: required field is missing"
