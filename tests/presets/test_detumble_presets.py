"""The detumble presets (issue 15, item 5): the layout the study relies on, the geometry their
descriptions state, and a short run that stays finite."""
from __future__ import annotations


import numpy as np
import pytest

import engine
from studio import presets

DETUMBLE = ("detumble_upper_stage", "detumble_box_satellite")
INTERFERENCE = 0.03   # m: the held tip interference the descriptions state


@pytest.mark.parametrize("name", DETUMBLE)
def test_preset_has_the_detumble_layout_and_describes_itself(name):
    scene = presets.load_preset(name)
    assert scene.name == name
    text = scene.description
    assert "Seed chapter 5" in text and "issue 15" in text
    assert "assum" in text and "record interval" in text and "duration" in text
    bodies = {b.name: b for b in scene.bodies}
    target, chaser = bodies["target"], bodies["chaser"]
    assert target.motion.type == "free" and chaser.motion.type == "free"
    assert not chaser.collide         # hull contact off: it would cut dt 11-17x (item 2)
    assert scene.brushes and all(b.mount == "chaser" for b in scene.brushes)
    (ctl,) = scene.controllers
    assert (ctl.name, ctl.body, ctl.reference) == ("chaser_control", "chaser", "target")
    assert scene.environment.orbit is not None and scene.environment.orbit.gravity_gradient
    assert scene.run.stop.body == "target"
    system = engine.build(scene)
    assert system.dt > 0
    # the spin is about the target's major principal axis (stated: a stable spin)
    k = system.body_names.index("target")
    Ip = system.bodies.Ip[k]
    from engine.model.layout import quat_to_matrix
    R = quat_to_matrix(system.bodies.q[k])
    major = R[:, int(np.argmax(Ip))]
    w = np.asarray(target.angular_velocity)
    assert abs(major @ w) == pytest.approx(np.linalg.norm(w), rel=1e-12)


@pytest.mark.parametrize("name, surface", [("detumble_upper_stage", 0.62),
                                           ("detumble_box_satellite", 0.5)])
def test_held_offset_puts_the_tips_the_stated_depth_into_the_surface(name, surface):
    # independent of the generator's arithmetic: from the built system, where the tips of
    # the bristles would be with the chaser at the held offset (no deformation)
    scene = presets.load_preset(name)
    system = engine.build(scene)
    (ctl,) = scene.controllers
    offset = np.asarray(ctl.position)
    axis = offset / np.linalg.norm(offset)
    k = system.body_names.index("chaser")
    chaser_pos = system.bodies.pos[k]
    brush = scene.brushes[0]
    tips = system.nodes.x[np.asarray(system.bristle_first_node)[1:] - 1]  # last nodes
    reach = float(np.mean((tips - chaser_pos) @ axis)) - brush.tip_radius  # tip ends
    target_pos = system.bodies.pos[system.body_names.index("target")]
    held_tip = (target_pos + offset) @ axis + reach     # along the approach axis
    # 10 um: the box satellite's tips scatter sideways by 1 mm, which lowers a 165 mm
    # bristle's tip by d^2 / 2L ~ 3 um; a wrong reach or surface is off by millimetres
    assert held_tip == pytest.approx(target_pos @ axis + surface - INTERFERENCE, abs=1e-5)
    # and at the start they are outside the surface
    start_tip = float(np.min((tips - target_pos) @ axis)) - brush.tip_radius
    assert start_tip > surface


def test_box_satellite_inertia_is_the_bus_plus_panel():
    # independent composite: sample the two solid blocks on a grid (midpoint rule) and sum
    # m r^2 about the centre of mass; 1e-3 covers the grid's discretisation (h^2/12 terms)
    scene = presets.load_preset("detumble_box_satellite")
    target = next(b for b in scene.bodies if b.name == "target")
    mp = target.mass_properties

    def block(size, centre, mass, n=40):
        axes = [(np.arange(n) + 0.5) / n * s - s / 2 + c for s, c in zip(size, centre)]
        g = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        return g, np.full(len(g), mass / len(g))

    pb, mb = block((1.0, 1.0, 1.0), (0.0, 0.0, 0.0), 200.0)
    pp, mpn = block((1.0, 2.0, 0.03), (0.0, 1.5, 0.0), 20.0, n=40)
    p = np.concatenate([pb, pp])
    m = np.concatenate([mb, mpn])
    com = (m[:, None] * p).sum(0) / m.sum()
    r = p - com
    inertia = np.einsum("n,nij->ij", m, np.einsum("ni,ni->n", r, r)[:, None, None]
                        * np.eye(3) - np.einsum("ni,nj->nij", r, r))
    assert mp.mass == pytest.approx(m.sum())
    assert np.asarray(mp.center_of_mass) == pytest.approx(com, abs=1e-9)
    assert np.asarray(mp.inertia) == pytest.approx(inertia, rel=1e-3, abs=1e-3)
    # the centre of mass is at the origin of the scene
    assert np.asarray(target.pose.position) + com == pytest.approx(np.zeros(3), abs=1e-12)


@pytest.mark.parametrize("name", DETUMBLE)
def test_smoke_run_of_each_detumble_preset_stays_finite(name, smoke_run):
    smoke_run(name)  # (its checks: tests/presets/conftest.py)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="issue 15 item 1, open: the brushes take the spin through zero at "
                          "21.8 s, then spin the target back (-1.38 deg/s at 30 s); "
                          "docs/mission.md")
def test_box_satellite_detumbles_and_stays_detumbled(preset_dict, run_scene):
    """The whole preset, 30 s (60 CPU-s, 90 s wall on the shared machine), with the stop's hold
    made 10 s: the target must come below 5 % of its initial spin and stay there for 10 s,
    a fifth of the brushes' 47 s torsional period (an undamped spin-back crosses the
    threshold within about 1 s of the stop, so the preset's 1 s hold can miss it). Strict,
    assertions only: once a preset change makes it pass, the marker must go."""
    import engine

    scene = preset_dict("detumble_box_satellite")
    stop = scene["run"]["stop"]
    stop["hold"] = 10.0
    system, result = run_scene(scene)
    with engine.open_result(result.path) as res:
        t = np.asarray(res.time)
        speed = np.linalg.norm(np.asarray(res.series("bodies/target/angular_velocity")),
                               axis=1)
    threshold = 0.05 * speed[0]
    assert stop["value"] == pytest.approx(threshold, rel=1e-12)
    above = np.flatnonzero(speed >= threshold)
    assert above[-1] + 1 < len(t), "spun back above the threshold by the end"
    t_detumbled = t[above[-1] + 1]
    # below the threshold from then on for the whole hold (one record interval of slack:
    # the stop is checked at records), and the stop condition ended the run
    assert t[-1] - t_detumbled >= stop["hold"] - scene["run"]["record_interval"]
    assert result.status == "stopped"
