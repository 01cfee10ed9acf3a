"""engine.prescribe_motion: replacing a kinematic body's profile between runs."""
from __future__ import annotations

import math

import numpy as np
import pytest

import engine


def _system(tiny_scene):
    scene = tiny_scene()
    scene["bodies"][0]["motion"]["profile"] = {"kind": "constant", "velocity": [0, 0, 0],
                                               "duration": 0.001}
    scene["run"]["duration"] = 0.05
    return engine.build(engine.parse_scene(scene))


def test_stepwise_parabolic_steps_follow_the_closed_form(tiny_scene, tmp_path):
    system = _system(tiny_scene)
    z0 = float(system.bodies.pos[0, 2])
    a_m, step = 2.0, 2e-4
    t_d = math.sqrt(6 * step / a_m)  # seed 4.2
    for i in range(2):
        t_start = system.time
        engine.prescribe_motion(system, "box", {"kind": "stepped_parabolic", "step": step,
                                                "n_steps": 1, "max_acceleration": a_m})
        # halfway through the step: p = s (3 tau^2 - 2 tau^3) = s/2, v = 1.5 s / t_d
        engine.run(system, until=t_start + t_d / 2, output=tmp_path / f"a{i}.h5")
        tau = (system.time - t_start) / t_d
        expect = z0 - step * (i + 3 * tau**2 - 2 * tau**3)
        # to round-off: the Hermite cubic is exact, only the step grid sets tau
        assert abs(system.bodies.pos[0, 2] - expect) < 1e-12
        v_expect = 6 * step / t_d * tau * (1 - tau)
        assert abs(-system.bodies.v[0, 2] - v_expect) < 1e-9
        engine.run(system, until=t_start + t_d + 0.002, output=tmp_path / f"b{i}.h5")
        assert abs(system.bodies.pos[0, 2] - (z0 - step * (i + 1))) < 1e-12
        assert np.all(system.bodies.v[0] == 0.0)
    with engine.open_result(tmp_path / "b1.h5") as res:
        assert "prescribed_motions" in res.attrs


def test_bad_requests_name_the_problem(tiny_scene):
    system = _system(tiny_scene)
    with pytest.raises(engine.SceneError) as e:
        engine.prescribe_motion(system, "nope", {"kind": "constant"})
    assert e.value.problems[0].field == "body"
    with pytest.raises(engine.SceneError) as e:
        engine.prescribe_motion(system, "box", {"kind": "stepped_parabolic", "n_steps": 1})
    assert any("max_acceleration" in p.field for p in e.value.problems)
    with pytest.raises(engine.SceneError) as e:
        engine.prescribe_motion(system, "box", {"kind": "waypoints", "times": [0, 1],
                                                "positions": [[0, 0, 1], [0, 0, 2]]})
    assert e.value.problems[0].field == "profile.positions[0]"
