"""``brush-studio study reduce``'s DEM scenes load the brush as the detumble presets do
(issue 25): the plate slides the way the target's surface moves under the brush, at the
speeds and interferences of the detumble, without running DEM."""
import json

import numpy as np
import pytest

from studio import presets
from studio.studies import reduce as red
from studio.studies.detumble import detumble_scene

DEG = np.pi / 180


def _scene(name):
    return json.loads(presets.load_preset_or_file(name).to_json())


def test_detumble_contact_of_the_upper_stage_is_its_spin_times_the_lever():
    # the preset: a 0.62 m cylinder at 10 deg/s, the tips held 30 mm inside its side, the
    # surface moving across the brush's rows (base y: the rows lie along the cylinder's
    # axis). Closed form: 10 deg/s x (0.62 - 0.03) m. A sign or frame slip in the helper
    # (the base's rotation applied the wrong way) would put it along x
    c = red.detumble_contact(_scene("detumble_upper_stage"))
    assert c["slip_speed"] == pytest.approx(10 * DEG * 0.59, rel=1e-9)  # round-off only
    assert c["slip_direction"] == pytest.approx([0.0, 1.0], abs=1e-12)
    assert c["interference"] == pytest.approx(0.03, rel=1e-9)


def test_default_protocol_covers_the_detumble_studies_contact():
    # the defaults of study reduce (preset detumble_upper_stage) must slide along the
    # detumble's slip direction and span its slip speed and interference, for the preset
    # and for the scaled hour of docs/mission.md (x4.57 at 2 deg/s); a default that slid
    # along the rows or stopped short of the slip (the 1 x 2 law's 50 mm/s) fails here
    opts = red.Options()
    design = red._design(opts.preset, slide_axis=opts.slide_axis)
    specs = red.build_specs(opts, design)
    for scene in (_scene("detumble_upper_stage"),
                  detumble_scene("detumble_upper_stage", size=4.57, spin_deg=2.0)):
        c = red.detumble_contact(scene)
        assert design["slide_axis"] == pytest.approx(c["slip_direction"], abs=1e-12)
        speeds = [s.params["speed"] for s in specs if s.params["kind"] in ("slide", "press")]
        depths = [s.params["depth"] for s in specs if s.params["kind"] in ("slide", "press")]
        assert min(speeds) <= c["slip_speed"] <= max(speeds)
        assert min(depths) <= c["interference"] <= max(depths)


@pytest.mark.parametrize("axis", ["x", "y"])
def test_sliding_press_path_moves_at_the_speed_along_the_axis(axis):
    # the kinematic plate of a sliding press: its waypoints' Catmull-Rom velocity (central
    # differences, as engine.assembly.bodies uses) is the slide speed along the axis and
    # the press rate normal to it between the ends; its face reaches `depth` below the
    # tips at mid-time. A path that pressed without sliding, or slid along the other
    # axis, fails
    design = red._design("detumble_upper_stage", rows=1, columns=2, slide_axis=axis)
    depth, rate, speed = 0.02, 0.05, 0.1
    sc = red.press_scene(design, depth, rate, speed)
    prof = sc["bodies"][0]["motion"]["profile"]
    t = np.asarray(prof["times"])
    p = np.asarray(prof["positions"])
    v = (p[2:] - p[:-2]) / (t[2:] - t[:-2])[:, None]
    e = np.array([*red.SLIDE_AXES[axis], 0.0])
    assert v[:, :3] @ e == pytest.approx(np.full(len(v), speed), rel=1e-9)
    face = p[:, 2] - red.PLATE_T / 2
    assert red.tip_plane(design["brush"]) - face.min() == pytest.approx(depth, rel=1e-9)
    mid = len(t) // 2
    assert abs(v[mid // 2, 2]) == pytest.approx(rate, rel=1e-9)  # on the way down
    # the plate still covers the footprint at the end of its travel along the axis
    a, b = red.patch_size(design["brush"])
    half = np.asarray(sc["bodies"][0]["shape"]["size"][:2]) / 2
    end = p[-1, :2]
    assert np.all(half - np.abs(end) >= np.array([a, b]) / 2)


def test_held_out_sliding_press_check_against_a_known_law():
    # synthetic "DEM" samples of a sliding press made by a known law: the check must give
    # zero errors; the same samples against a law with twice the friction coefficient must
    # give +100 % tangential impulse and 0 % normal (closed form: F_t is linear in mu). A
    # window that ignored fit_from, or an impulse of the wrong force, breaks one of these
    from engine.model.reduced_law import friction_coefficient, normal_force

    law = {"parameters": {"k": 12.0, "p": 0.4, "c": 0.1, "eta": 0.8, "mu": 0.6, "q": -0.05,
                          "v_s": 0.05}, "fit_from": 0.01}
    par = law["parameters"]
    t = np.linspace(0.0, 4.0, 801)
    d = 0.03 - np.abs(0.015 * t - 0.03) - 0.002
    dd = np.gradient(d, t)
    v = np.full_like(t, 0.1)
    fn = normal_force(d, dd, par["k"], par["p"], par["c"], par["eta"])
    ft = friction_coefficient(fn, v, par["mu"], par["q"], par["v_s"]) * fn
    # outside the window the "DEM" does something else (a first-touch spike): not counted
    fn = np.where(d < 0.01, fn + 30.0, fn)
    dem = {"time": t, "d": d, "dd": dd, "fn": fn, "v": v, "ft": ft}
    same = red.check_sliding_press(law, dem)
    for key, err in same["errors"].items():
        assert err == pytest.approx(0.0, abs=1e-12), key      # the same law: round-off only
    double = dict(law, parameters=dict(par, mu=1.2))
    e = red.check_sliding_press(double, dem)["errors"]
    assert e["tangential_impulse"] == pytest.approx(1.0, rel=1e-12)
    assert e["normal_impulse"] == pytest.approx(0.0, abs=1e-12)
    assert e["peak_fn"] == pytest.approx(0.0, abs=1e-12)
