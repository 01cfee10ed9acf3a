"""Result files that check their own physics: ``ResultFile.energy`` / ``kinetic_energy`` /
``angular_momentum`` / ``linear_momentum`` against the live System's ``engine.energies`` /
``engine.angular_momentum`` / ``engine.linear_momentum``.

The scene is static_presets/momentum_two_brushes.json at low resolution (3 x 2 bristles per
brush) with the cube made a box (20 x 24 x 16 mm) and turned 0.4 rad about x: its inertia is
anisotropic and its body frame is not the world frame, so a body spin taken as ``I_p * w`` in
the world frame instead of ``R diag(I_p) R^T w`` is wrong from frame 0. The brushes are
mounted on free plates, so the whole scene is closed (momentum conserved) and its root nodes
move (a reader that counts them as free nodes double-counts the plates' carried mass).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import engine
from engine.errors import BrushStudioError
from engine.io.results import MissingChannelError

PRESET = Path(__file__).resolve().parents[2] / "static_presets" / "momentum_two_brushes.json"
ABOUT = (0.01, -0.02, 0.03)   # not the origin: the orbital term r x p must use the point
STEPS = 400                   # ~5.5 ms: the box's corners reach into both brushes


def _scene(gravity=(0.0, 0.0, 0.0), channels=None) -> dict:
    scene = json.loads(PRESET.read_text())
    for brush in scene["brushes"]:
        brush.update(rows=3, columns=2)
    cube = scene["bodies"][0]
    cube["shape"]["size"] = [0.02, 0.024, 0.016]
    cube["pose"] = {"orientation": [np.cos(0.2), np.sin(0.2), 0.0, 0.0]}  # 0.4 rad about x
    scene["environment"] = {**scene.get("environment", {}), "gravity": list(gravity)}
    scene["run"]["channels"] = channels or ["nodes", "bodies", "energy", "contacts",
                                            "node_velocities"]
    return scene


def _run(scene: dict, path: Path, steps: int = STEPS):
    system = engine.build(engine.parse_scene(scene))
    system_dt = system.dt
    scene["run"]["record_interval"] = steps * system_dt / 8   # 9 frames
    system = engine.build(engine.parse_scene(scene))
    result = engine.run(system, until=steps * system_dt, output=path)
    assert result.status == "completed"
    return system, result


@pytest.fixture(scope="module")
def closed_run(tmp_path_factory):
    return _run(_scene(), tmp_path_factory.mktemp("closed") / "closed.h5")


@pytest.fixture(scope="module")
def gravity_run(tmp_path_factory):
    return _run(_scene(gravity=(1.0, -2.0, -9.81)),
                tmp_path_factory.mktemp("gravity") / "gravity.h5")


def test_last_frame_momentum_and_energy_equal_the_live_systems(closed_run):
    # Bugs caught: a node spin term I w left out, root nodes counted as free nodes, a body
    # spin taken as I_p * w in the world frame, r x p about the origin instead of ``about``.
    system, result = closed_run
    live_L = engine.angular_momentum(system, ABOUT)
    live_p = engine.linear_momentum(system)
    live_e = engine.energies(system)
    with result.open() as res:
        assert np.isclose(res.time[-1], system.time, rtol=0, atol=1e-15)
        assert res.series("contacts/bristle_body").max() > 0, "the box touched the brushes"
        file_L = res.angular_momentum(about=ABOUT, frame=-1)
        file_p = res.linear_momentum(frame=-1)
        file_e = res.energy(frame=-1)
        assert res.kinetic_energy(frame=-1) == file_e["kinetic"]
    # the same float64 sums in a different order and a rotation round trip: ~1e-15
    # relative; 1e-12 leaves room for ~1e3 terms and still fails under any of the bugs
    assert np.allclose(file_L, live_L, rtol=0, atol=1e-12 * np.linalg.norm(live_L))
    # |p| is ~0 (closed system at rest but for the spin): compare on the scale m_box v_corner
    p_scale = 0.0054 * 10.0 * 0.016
    assert np.allclose(file_p, live_p, rtol=0, atol=1e-12 * p_scale)
    assert file_e.keys() == live_e.keys()
    for key in ("kinetic", "total"):
        assert file_e[key] == pytest.approx(live_e[key], rel=1e-12, abs=0), key
    for key in ("bond", "contact", "dissipated", "external_work"):
        assert file_e[key] == live_e[key], key   # copied from the energy channel
    assert file_e["gravity"] == 0.0


def test_every_frame_matches_what_the_run_loop_recorded(closed_run):
    # energy/kinetic is engine.energies(system) of the live system at each frame: the file's
    # own kinetic energy, from velocities, spins and mass statics, must reproduce it
    _, result = closed_run
    with result.open() as res:
        recorded = res.series("energy/kinetic")
        from_state = res.kinetic_energy()
        assert from_state.shape == (res.n_frames,) == (9,)
        assert np.allclose(from_state, recorded, rtol=1e-12, atol=0)
        assert np.array_equal(res.energy()["kinetic"], from_state)


def test_angular_and_linear_momentum_are_conserved_across_frames(closed_run):
    # box + free plates + bristles, no gravity, no damping: a closed system, so L about any
    # fixed point and p are constant (friction dissipates energy, not momentum). The preset
    # test bounds |dL|/|L| by 1e-6 over 7e3 steps; round-off over 400 steps is ~1e-13.
    _, result = closed_run
    with result.open() as res:
        L = res.angular_momentum(about=ABOUT)
        p = res.linear_momentum()
        e = res.energy()
    assert L.shape == p.shape == (9, 3)
    assert np.linalg.norm(L - L[0], axis=1).max() < 1e-9 * np.linalg.norm(L[0])
    assert np.linalg.norm(p, axis=1).max() < 1e-9 * 0.0054 * 10.0 * 0.016
    assert e["kinetic"][-1] < e["kinetic"][0], "friction took energy: the contact was real"


def test_with_gravity_energy_and_momentum_match_the_live_system(gravity_run):
    # Bugs caught: gravity energy with the sign of g flipped, of root nodes (they ride on the
    # free plates, so they move), or of bodies left out; and, now that gravity gave the
    # scene a net momentum p, r x p taken about the origin instead of ``about`` (it differs
    # by about x p, which vanishes in the closed run where p = 0)
    system, result = gravity_run
    with result.open() as res:
        e = res.energy()
        recorded = {key: res.series(f"energy/{key}") for key in e}
        last = res.energy(frame=-1)
        file_L = res.angular_momentum(about=ABOUT, frame=-1)
        file_p = res.linear_momentum(frame=-1)
    live = engine.energies(system)
    live_L, live_p = engine.angular_momentum(system, ABOUT), engine.linear_momentum(system)
    assert np.linalg.norm(np.cross(ABOUT, live_p)) > 1e-3 * np.linalg.norm(live_L)
    # round-off of reordered float64 sums, as in the closed run
    assert np.allclose(file_L, live_L, rtol=0, atol=1e-12 * np.linalg.norm(live_L))
    assert np.allclose(file_p, live_p, rtol=0, atol=1e-12 * np.linalg.norm(live_p))
    # bodies fall ~0.15 mm in 5.5 ms: gravity energy ~1e-8 J next to ~3e-5 J of kinetic
    assert abs(recorded["gravity"][-1]) > 1e-10
    for key in ("gravity", "kinetic", "total"):
        scale = np.abs(recorded[key]).max()
        assert np.allclose(e[key], recorded[key], rtol=0, atol=1e-12 * scale), key
        assert last[key] == pytest.approx(live[key], rel=1e-12, abs=1e-12 * scale), key


def test_missing_channels_raise_an_error_that_names_the_group(tmp_path):
    scene = _scene(channels=["nodes", "bodies"])
    _, result = _run(scene, tmp_path / "plain.h5", steps=8)
    with result.open() as res:
        assert "nodes/velocities" not in res.channels()
        for read in (res.angular_momentum, res.linear_momentum, res.kinetic_energy):
            with pytest.raises(MissingChannelError, match="node_velocities") as info:
                read()
            assert isinstance(info.value, BrushStudioError)
            assert info.value.group == "node_velocities"
    scene = _scene(channels=["nodes", "bodies", "node_velocities"])
    _, result = _run(scene, tmp_path / "no_energy.h5", steps=8)
    with result.open() as res:
        res.kinetic_energy()   # computable without the energy channel
        with pytest.raises(MissingChannelError, match="'energy'.*energy/bond"):
            res.energy()
    scene = _scene(channels=["nodes", "energy", "node_velocities"])
    _, result = _run(scene, tmp_path / "no_bodies.h5", steps=8)
    with result.open() as res:
        with pytest.raises(MissingChannelError, match="'bodies'"):
            res.angular_momentum()


def test_node_velocities_are_off_by_default():
    scene = json.loads(PRESET.read_text())
    scene["run"].pop("channels", None)
    assert "node_velocities" not in engine.parse_scene(scene).run.channels
