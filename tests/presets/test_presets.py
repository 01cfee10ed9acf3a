"""The presets in static_presets/ and the studio.presets API: every preset validates, builds,
says which part of the seed thesis it reproduces, follows the shared naming, and runs
(smoke tests); the appendix H scenes conserve angular momentum through a real contact."""
from __future__ import annotations

import importlib
import math
import re
import runpy
from pathlib import Path

import numpy as np
import pytest

import engine
from studio import presets

EXPECTED = (
    "rod_weight_release", "rod_weight_static", "rod_tip_impulse", "rod_root_impulse",
    "wedge_30", "wedge_45", "wedge_60", "wedge_75",
    "spin_cube_20", "spin_cube_40", "spin_cube_60",
    "momentum_two_brushes", "momentum_spheres_cube",
    "space_fur", "solid_plate", "gripper",
)
# "Seed 4.2", "Seed 4.1.3", "Seed appendix H", "Seed chapter 5"
SECTION = re.compile(r"\bSeed (\d\.\d(\.\d)?|appendix [A-H]|chapter 5)\b")
FIGURE = re.compile(r"\bfigs?\. [0-9A-H]")
MATERIALS = {"silicone", "pla", "foam", "steel"}
BRUSHES = {"brush", "brush_left", "brush_right"}
BODY_KINDS = ("wedge", "cube", "sphere", "plate", "target")
DEG = math.pi / 180


# ----------------------------------------------------------------------------- API
def test_list_presets_lists_every_preset_sorted_with_name_title_description():
    items = presets.list_presets()
    names = [p["name"] for p in items]
    assert names == sorted(names)
    assert set(EXPECTED) <= set(names)
    for p in items:
        assert set(p) == {"name", "title", "description"}
        assert p["title"] and p["description"]
    # the generator script is not a preset
    assert "generate" not in names


def test_preset_path_is_the_json_file_in_the_preset_dir():
    path = presets.preset_path("wedge_60")
    assert path == Path(presets.PRESET_DIR) / "wedge_60.json"
    assert path.is_file()
    repo = Path(__file__).resolve().parents[2]
    assert Path(presets.PRESET_DIR).resolve() == repo / "static_presets"


@pytest.mark.parametrize("bad", ["../x", "..", ".", "", "a/b", "/etc/passwd", "..\\x",
                                 "wedge_60.json", "static_presets/wedge_60", "../wedge_60",
                                 "generate", "no_such_preset", "./wedge_60", None, 3])
def test_preset_path_rejects_names_that_are_not_presets(bad):
    with pytest.raises(KeyError):
        presets.preset_path(bad)


def test_load_preset_returns_a_scene_and_rejects_unknown_names():
    scene = presets.load_preset("gripper")
    assert isinstance(scene, engine.Scene)
    assert scene.name == "gripper"
    with pytest.raises(KeyError):
        presets.load_preset("../static_presets/gripper")


def test_env_var_overrides_the_preset_dir(tmp_path, monkeypatch, tiny_scene, write_scene):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "tiny.json").write_text(write_scene(tiny_scene()).read_text())
    (tmp_path / "outside.json").write_text(write_scene(tiny_scene()).read_text())
    monkeypatch.setenv("BRUSH_STUDIO_PRESETS", str(folder))
    try:
        importlib.reload(presets)
        assert Path(presets.PRESET_DIR) == folder
        assert [p["name"] for p in presets.list_presets()] == ["tiny"]
        assert presets.load_preset("tiny").name == "tiny"
        with pytest.raises(KeyError):
            presets.preset_path("../outside")
    finally:
        monkeypatch.delenv("BRUSH_STUDIO_PRESETS")
        importlib.reload(presets)
    assert "wedge_60" in [p["name"] for p in presets.list_presets()]


def test_an_invalid_preset_file_is_listed_but_fails_to_load_with_scene_error(tmp_path,
                                                                             monkeypatch):
    (tmp_path / "broken.json").write_text('{"name": "broken", "run": {"duration": -1}}')
    (tmp_path / "garbage.json").write_text("not json")
    monkeypatch.setattr(presets, "PRESET_DIR", tmp_path)
    assert [p["name"] for p in presets.list_presets()] == ["broken", "garbage"]
    for name in ("broken", "garbage"):
        with pytest.raises(engine.SceneError):
            presets.load_preset(name)


def test_preset_files_match_their_generator():
    generator = runpy.run_path(str(Path(presets.PRESET_DIR) / "generate.py"))
    assert generator["main"](["--check"]) == 0, "run python static_presets/generate.py"


# ----------------------------------------------------------------------------- content
@pytest.mark.parametrize("name", EXPECTED)
def test_preset_validates_builds_and_describes_itself(name):
    scene = presets.load_preset(name)
    assert scene.name == name
    system = engine.build(scene)
    assert system.dt > 0
    text = scene.description
    assert SECTION.search(text), "the description names the seed's section"
    assert FIGURE.search(text), "the description names the seed's figure"
    assert "assum" in text, "the description states its assumptions"
    assert "record interval" in text and "duration" in text.lower(), "and its resolution"
    assert set(scene.materials) <= MATERIALS
    assert {b.name for b in scene.brushes} <= BRUSHES
    for body in scene.bodies:
        assert body.name.split("_")[0] in BODY_KINDS, body.name


@pytest.mark.parametrize("angle", [30, 45, 60, 75])
def test_wedge_presets_follow_the_seed_static_test(angle):
    scene = presets.load_preset(f"wedge_{angle}")
    (brush,) = scene.brushes
    assert (brush.rows, brush.columns) == (17, 5)
    assert brush.pitch == (0.003, 0.003) or list(brush.pitch) == [0.003, 0.003]
    assert (brush.bristle_length, brush.root_radius, brush.tip_radius) == (0.033, 0.001, 0.0005)
    silicone = scene.materials["silicone"]
    assert (silicone.youngs_modulus, silicone.poisson_ratio,
            silicone.density) == (2.7e6, 0.48, 1700.0)
    friction = {frozenset(p.materials): p.friction_angle for p in scene.contact_pairs}
    assert friction[frozenset({"silicone"})] == pytest.approx(44 * DEG)
    assert friction[frozenset({"silicone", "pla"})] == pytest.approx(24 * DEG)
    assert scene.environment.gravity[2] == pytest.approx(-9.81)
    (wedge,) = scene.bodies
    assert wedge.shape.angle == pytest.approx(angle * DEG)
    # apex along x (parallel to the 5-bristle rows), 0.5 mm beside the middle row (y = 0)
    assert list(wedge.pose.position[:2]) == pytest.approx([0.0, 0.0005])
    assert wedge.pose.position[2] == pytest.approx(0.033 + 0.0005)
    p = wedge.motion.profile
    assert p.kind == "stepped_parabolic" and p.unload and p.dwell > 0
    assert p.step == 0.001 and p.n_steps * p.step == pytest.approx(0.033)  # seed: 33 mm
    t_d = math.sqrt(6 * p.step / p.max_acceleration)  # seed eq. 4.3
    assert 2 * p.n_steps * (t_d + p.dwell) < scene.run.duration


def test_rod_presets_follow_table_4_1_and_the_impulse_of_fig_4_3():
    for name in ("rod_weight_release", "rod_tip_impulse", "rod_root_impulse"):
        scene = presets.load_preset(name)
        steel = scene.materials["steel"]
        assert (steel.youngs_modulus, steel.poisson_ratio, steel.density) == (200e9, 0.3, 7640.0)
        (rod,) = scene.brushes
        assert rod.bristle_length == 0.4
        assert 2 * rod.root_radius == pytest.approx(1.42e-3) == 2 * rod.tip_radius
    for name, node_x in (("rod_tip_impulse", 0.4), ("rod_root_impulse", 0.0458)):
        scene = presets.load_preset(name)
        (load,) = scene.loads
        rod = scene.brushes[0]
        node = load.node % rod.n_nodes
        # the loaded node within 0.1 mm of the seed's point (0.0458 m: no node is closer)
        assert node * 0.4 / (rod.n_nodes - 1) == pytest.approx(node_x, abs=1e-4)
        t, v = np.array(load.profile.times), np.array(load.profile.values)
        peak = np.abs(v).max() * np.linalg.norm(load.force)
        assert peak == pytest.approx(1.0)
        assert t[np.argmax(v)] == pytest.approx(0.0025) and t[-1] == pytest.approx(0.005)
        # triangular impulse: 1/2 * 1 N * 5 ms
        assert np.trapezoid(v, t) * np.linalg.norm(load.force) == pytest.approx(2.5e-3)
    scene = presets.load_preset("rod_weight_release")
    (load,) = scene.loads
    assert np.linalg.norm(load.force) == pytest.approx(0.020 * 9.81)
    assert load.profile.values[-1] == 0.0   # released


# ----------------------------------------------------------------------------- smoke
@pytest.mark.parametrize("name", EXPECTED)
def test_smoke_run_of_each_preset_stays_finite(name, smoke_run):
    smoke_run(name)  # (its checks: tests/presets/conftest.py)


# ----------------------------------------------------------------------------- appendix H
def _relative_change(a, b):
    return float(np.linalg.norm(b - a) / np.linalg.norm(a))


def _run_with_momentum(scene: dict, until: float, path: Path):
    """Build and run ``scene``; return (L before, L after, p before, p after, result)."""
    system = engine.build(engine.parse_scene(scene))
    L0, p0 = engine.angular_momentum(system), engine.linear_momentum(system)
    result = engine.run(system, until=until, output=path)
    return L0, engine.angular_momentum(system), p0, engine.linear_momentum(system), result


def test_momentum_spheres_cube_conserves_angular_momentum_through_the_impact(preset_dict,
                                                                            tmp_path):
    # both spheres hit the cube at ~18 ms and once more by ~25 ms
    L0, L1, p0, p1, result = _run_with_momentum(preset_dict("momentum_spheres_cube"), 0.03,
                                                tmp_path / "h.h5")
    with result.open() as res:
        assert res.series("contacts/body_body").max() >= 2        # both spheres touched it
        spin = abs(res.series("bodies/cube/angular_velocity")[-1, 1])
    assert spin > 1.0, "the impacts set the cube spinning (a real exchange of momentum)"
    # float64 round-off over ~6e4 steps is ~1e-12 relative; 1e-6 is the bound
    # (YADE lost percents in this test, seed fig. H.2)
    assert _relative_change(L0, L1) < 1e-6
    assert np.linalg.norm(p1 - p0) < 1e-9 * 2 * 0.0056 * 1.0   # of the spheres' |p|


def test_momentum_two_brushes_conserve_angular_momentum_through_the_contact(preset_dict,
                                                                           tmp_path):
    # 0.1 s: the cube turns about 1 rad, its corners sweep through both brushes
    L0, L1, p0, p1, result = _run_with_momentum(preset_dict("momentum_two_brushes"), 0.1,
                                                tmp_path / "h.h5")
    with result.open() as res:
        assert res.series("contacts/bristle_body").max() > 0
        w = res.series("bodies/cube/angular_velocity")[:, 1]
    assert abs(w[-1] - w[0]) > 0.01 * abs(w[0]), "the brushes slowed the cube"
    # round-off of ~7e3 steps on ~1e3 nodes is ~1e-12 relative; 1e-6 is the bound
    assert _relative_change(L0, L1) < 1e-6


# ----------------------------------------------------------------------------- space fur
def _peak_transmitted_force(result, fur: bool) -> float:
    """Peak |force on the plate|: the plate's contact force, plus (fur) minus the force the
    base exerts on the fur's roots (the roots push the plate with its opposite)."""
    with result.open() as res:
        force = res.series("bodies/plate/contact_force")
        if fur:
            force = force - res.series("brushes/brush/root_force")
    return float(np.linalg.norm(force, axis=1).max())


def test_space_fur_transmits_at_least_ten_times_less_peak_force_than_a_bare_plate(
        preset_dict, run_scene):
    bare = preset_dict("solid_plate")
    _, bare_result = run_scene(bare, until=1e-4, name="bare")  # the hit is at ~61 us
    fur = preset_dict("space_fur")
    # reduced resolution: a 5 x 15 strip of the fur along the sphere's path (the preset's
    # 11 x 21 gives the same peak, 768.5 N) and the first 0.4 ms (the peak is at ~73 us)
    fur["brushes"][0].update(rows=5, columns=15)
    _, fur_result = run_scene(fur, until=4e-4, name="fur")
    with fur_result.open() as res:
        assert res.series("contacts/bristle_body").max() > 0      # the sphere hit the fur
        vz = res.series("bodies/sphere/velocity")[:, 2]
        z = res.series("bodies/sphere/position")[:, 2]
    assert abs(vz[-1]) < 0.25 * abs(vz[0]), "the fur took most of the normal velocity"
    assert z.min() > fur["bodies"][1]["shape"]["radius"], "without the sphere touching the plate"
    bare_peak = _peak_transmitted_force(bare_result, fur=False)
    fur_peak = _peak_transmitted_force(fur_result, fur=True)
    # a rigid-rigid hit, v_n sqrt(k m) with k = E r: 50 * sqrt(2e11 * 2e-3 * 2.56e-4) = 16 kN
    assert bare_peak == pytest.approx(16e3, rel=0.1)
    # the seed's fig. 5.1 shows "orders of magnitude"; the issue asks for at least 10x
    assert bare_peak / fur_peak >= 10.0
