"""The studio's UI <-> scene mapping: units at the edge, validation messages routed to the
fields they name (studio/web/scene.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from studio.web import scene as us

SEL = us.Selection()


def test_ui_units_read_from_demo(demo):
    # the demo scene (SI) as the panels show it: mm, degrees, MPa, ms
    assert us.get_ui_value("bristle_length", demo, SEL) == 33.0
    assert us.get_ui_value("root_radius", demo, SEL) == 1.0
    assert us.get_ui_value("pitch_y", demo, SEL) == 3.0
    assert us.get_ui_value("youngs_modulus", demo, SEL) == 2.7
    assert us.get_ui_value("friction_bristles", demo, SEL) == pytest.approx(44.0, abs=1e-9)
    assert us.get_ui_value("friction_body", demo, SEL) == pytest.approx(24.0, abs=1e-9)
    assert us.get_ui_value("wedge_angle", demo, SEL) == pytest.approx(60.0, abs=1e-9)
    assert us.get_ui_value("record_interval", demo, SEL) == 10.0
    assert us.get_ui_value("profile_dwell", demo, SEL) == 50.0
    assert us.get_ui_value("body_position", demo, SEL) == (0.0, 0.5, 33.5)
    assert us.get_ui_value("dt", demo, SEL) == 0.0  # automatic
    assert us.get_ui_value("mass_mode", demo, SEL) == "none"
    assert us.get_ui_value("rows", demo, SEL) == 17


def test_ui_units_written_as_si(demo):
    s = us.set_ui_value("pitch_x", demo, SEL, 2.5)
    assert s["brushes"][0]["pitch"] == [0.0025, 0.003]
    s = us.set_ui_value("wedge_angle", demo, SEL, 45.0)
    assert s["bodies"][0]["shape"]["angle"] == pytest.approx(math.pi / 4, rel=1e-15)
    s = us.set_ui_value("tip_variance", demo, SEL, 4e-4)       # mm^2 -> m^2 (seed: 4e-10)
    assert s["brushes"][0]["tip_variance"] == pytest.approx(4e-10, rel=1e-12)
    s = us.set_ui_value("youngs_modulus", demo, SEL, 3.8)
    assert s["materials"]["silicone"]["youngs_modulus"] == pytest.approx(3.8e6, rel=1e-15)
    s = us.set_ui_value("angular_velocity", demo, SEL, (0.0, 0.0, 180.0))
    assert s["bodies"][0]["angular_velocity"] == pytest.approx([0, 0, math.pi], rel=1e-15)
    s = us.set_ui_value("dt", demo, SEL, 2.0)                   # µs
    assert s["run"]["dt"] == pytest.approx(2e-6, rel=1e-15)
    assert us.set_ui_value("dt", s, SEL, 0)["run"]["dt"] is None  # 0 = automatic
    # the original is never modified
    assert demo["brushes"][0]["pitch"] == [0.003, 0.003]


def test_ui_orientation_as_roll_pitch_yaw(demo):
    # docs/scene.md: a 90 degree turn about world z is [cos 45, 0, 0, sin 45]
    s = us.set_ui_value("body_orientation", demo, SEL, (0.0, 0.0, 90.0))
    q = s["bodies"][0]["pose"]["orientation"]
    assert q == pytest.approx([math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)], abs=1e-12)
    assert us.get_ui_value("body_orientation", s, SEL) == pytest.approx((0, 0, 90), abs=1e-9)
    rpy = (10.0, -20.0, 30.0)
    back = us.get_ui_value("body_orientation",
                           us.set_ui_value("body_orientation", demo, SEL, rpy), SEL)
    assert back == pytest.approx(rpy, abs=1e-9)


def test_ui_bad_value_message_names_the_field(demo):
    s = us.set_ui_value("rows", demo, SEL, 0)
    v = us.validate(s)
    assert not v.ok
    msgs = [p.message for p in us.problems_for("rows", v.problems, s, SEL)]
    assert msgs and msgs[0].startswith("brushes.0.rows = 0:")
    # a wedge angle beyond 180 degrees: the tagged-union location maps back to the field
    s = us.set_ui_value("wedge_angle", demo, SEL, 200.0)
    v = us.validate(s)
    assert set(us.fields_for_problems(v.problems, s, SEL)) == {"wedge_angle"}
    # a tip thicker than the bristle is long: the engine names bristle_length
    s = us.set_ui_value("tip_radius", demo, SEL, 20.0)
    v = us.validate(s)
    assert "bristle_length" in us.fields_for_problems(v.problems, s, SEL)
    # friction angle of 90 degrees or more is refused on the contact pair's field
    s = us.set_ui_value("friction_body", demo, SEL, 95.0)
    v = us.validate(s)
    assert set(us.fields_for_problems(v.problems, s, SEL)) == {"friction_body"}


def test_ui_inexpressible_values_raise_value_error(demo):
    with pytest.raises(ValueError, match="whole number"):
        us.set_ui_value("rows", demo, SEL, 2.5)
    with pytest.raises(ValueError, match="number"):
        us.set_ui_value("bristle_length", demo, SEL, "abc")
    with pytest.raises(ValueError, match="finite"):
        us.set_ui_value("bristle_length", demo, SEL, float("nan"))
    with pytest.raises(ValueError, match="one of"):
        us.set_ui_value("pattern", demo, SEL, "hexagonal")
    with pytest.raises(ValueError, match="upload a mesh"):
        us.set_ui_value("shape_type", demo, SEL, "mesh")


def test_ui_fields_follow_shape_and_motion(demo):
    assert us.applicable("wedge_angle", demo, SEL)
    assert not us.applicable("box_size", demo, SEL)
    assert not us.applicable("hinge_axis", demo, SEL)
    s = us.set_ui_value("shape_type", demo, SEL, "box")
    assert s["bodies"][0]["shape"] == {"type": "box", "size": [0.02, 0.02, 0.02]}
    assert us.applicable("box_size", s, SEL) and not us.applicable("wedge_angle", s, SEL)
    s = us.set_ui_value("motion_type", s, SEL, "hinge")
    assert us.validate(s).ok
    assert us.applicable("hinge_axis", s, SEL) and not us.applicable("profile_kind", s, SEL)
    # a hinge needs mass properties: the body's material density is filled in
    assert s["bodies"][0]["mass_properties"] == {"density": 1240.0}
    no_body = dict(demo, bodies=[])
    assert not us.applicable("shape_type", no_body, SEL)
    assert not us.applicable("friction_body", no_body, SEL)
    assert us.applicable("rows", no_body, SEL)


def test_ui_mass_mode_gives_uniform_inertia(demo):
    s = us.set_ui_value("shape_type", demo, SEL, "box")
    s = us.set_ui_value("box_size", s, SEL, (10.0, 20.0, 30.0))
    s = us.set_ui_value("mass_mode", s, SEL, "mass")
    s = us.set_ui_value("body_mass", s, SEL, 12.0)  # g
    mp = s["bodies"][0]["mass_properties"]
    assert mp["mass"] == pytest.approx(0.012, rel=1e-15)
    a, b, c = 0.01, 0.02, 0.03
    # a uniform box: I_xx = m (b^2 + c^2) / 12 etc.; trimesh integrates the mesh exactly
    expect = np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) * 0.012 / 12
    assert np.asarray(mp["inertia"]) == pytest.approx(expect, rel=1e-9, abs=1e-18)
    assert us.validate(s).ok


def test_ui_material_preset_renames_and_pairs_follow(demo):
    s = us.set_material_preset(demo, SEL, "steel")
    assert "silicone" not in s["materials"]
    assert s["materials"]["steel"]["youngs_modulus"] == 2.0e11
    assert s["brushes"][0]["material"] == "steel"
    pairs = sorted(tuple(sorted(p["materials"])) for p in s["contact_pairs"])
    assert pairs == [("pla", "steel"), ("steel", "steel")]
    assert us.validate(s).ok
    # the friction angle field now reads the renamed pair
    assert us.get_ui_value("friction_bristles", s, SEL) == pytest.approx(44.0, abs=1e-9)


def test_ui_missing_contact_pair_is_created_on_write(demo):
    s = dict(demo, contact_pairs=[])
    assert us.get_ui_value("friction_bristles", s, SEL) == 0.0  # docs: unlisted = frictionless
    s2 = us.set_ui_value("friction_bristles", s, SEL, 30.0)
    assert s2["contact_pairs"] == [{"materials": ["silicone", "silicone"],
                                    "friction_angle": pytest.approx(math.radians(30))}]
    assert us.validate(s2).ok


def test_ui_add_body_above_the_tips(demo):
    s = us.add_body(dict(demo, bodies=[]), "sphere", 0.01)
    assert us.validate(s).ok
    body = s["bodies"][0]
    assert body["shape"] == {"type": "sphere", "radius": 0.005}
    # lowest point 1 mm above the 33 mm bristles' tips
    assert body["pose"]["position"][2] - 0.005 == pytest.approx(0.033 + 0.001)


def test_ui_add_body_clears_the_bodies_already_there(demo):
    """The demo's wedge rests on the tips (z = 33.5 mm); "Add body" put its cube at 34 mm,
    inside the wedge (issue 29, item 8). The wedge's top, from the scene alone: its pose
    (z = 33.5 mm) plus its height, the shape standing on its edge (docs/scene.md)."""
    wedge = demo["bodies"][0]
    top = wedge["pose"]["position"][2] + wedge["shape"]["height"]
    s = us.add_body(demo, "box", 0.02)
    assert us.validate(s).ok
    cube = s["bodies"][1]
    # the cube's lowest point 1 mm above the wedge's top (round-off of a mm sum: 1e-12 m)
    assert cube["pose"]["position"][2] - 0.01 == pytest.approx(top + 0.001, abs=1e-12)


@pytest.mark.parametrize("motion", [
    {"type": "fixed"},
    {"type": "hinge", "axis": [1.0, 0.0, 0.0]},
    {"type": "kinematic", "profile": {"kind": "constant"}},
    {"type": "kinematic", "profile": {"kind": "stepped_parabolic", "max_acceleration": 1.0,
                                      "n_steps": 2}},
])
def test_a_value_left_out_shows_what_the_engine_uses(motion):
    # the defaults shown for optional values come from the scene model (studio/web/fields.py
    # reads engine.Scene); the reference is independent of that reading: the engine's own
    # validation fills the scene in. A default restated in the studio and changed in
    # engine/model/spec.py since (or read from the wrong union member) shows a different value
    sparse = {
        "name": "sparse", "run": {"duration": 0.1, "record_interval": 0.01},
        "materials": {"silicone": {"youngs_modulus": 2.7e6, "density": 1700.0},
                      "pla": {"youngs_modulus": 3.5e9, "density": 1250.0}},
        "brushes": [{"material": "silicone", "bristle_length": 0.03, "root_radius": 0.001,
                     "tip_radius": 0.0005}],
        "bodies": [{"name": "b", "material": "pla",
                    "shape": {"type": "box", "size": [0.01, 0.01, 0.01]},
                    "mass_properties": {"density": 1250.0}, "motion": motion}],
    }  # no contact pair listed: the pair fields show the law's defaults
    listed = dict(sparse, contact_pairs=[{"materials": ["silicone", "silicone"]},
                                         {"materials": ["silicone", "pla"]}])
    filled = us.validate(listed)
    assert filled.ok, filled.problems
    full = us.scene_dict(filled.scene)
    compared = 0
    for f in us.FIELDS:
        if not us.applicable(f, full, SEL):
            continue
        try:
            expected = us.get_ui_value(f, full, SEL)
        except us.NotApplicable:
            continue
        # the same SI numbers through the same unit conversion: equal but for float rounding
        assert us.get_ui_value(f, sparse, SEL) == pytest.approx(expected, abs=1e-12), f.key
        compared += 1
    assert compared >= 30  # the check ran over the fields, not over an empty selection
