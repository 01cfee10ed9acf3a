"""``brush-studio study spin`` (seed 4.3): geometry of the six configurations, contact and
rest detection on known signals, and the acceptance checks of the brush dynamic test at a
reduced resolution (a 7 x 3 brush of 5-node bristles and the 20 mm cube, through the Dask
runner): the cube comes to rest, omega changes by different amounts at different contacts,
and the brush closer to the axis stops the cube sooner (seed 4.3.5).

Why 5 nodes: with the exact frustum element (issue 11) 3-node bristles are no longer too
compliant, and at 3 nodes the seed's order does not hold (3 s runs: configuration 1 rests at
1.77 s, configuration 2 at 1.41 s); at 5 nodes it does (0.79 s; 2.40 s). The old element's
3-node softness had let the tips slide, and so dissipate, more.
"""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

import engine
from studio.cli.main import main
from studio.studies.spin import runs as spin


# ----------------------------------------------------------------------------- geometry
@pytest.mark.parametrize("cube_mm", [20, 60])
@pytest.mark.parametrize("config", sorted(spin.CONFIGS))
def test_configuration_geometry(cube_mm, config):
    scene = spin.spin_scene(cube_mm, config)
    engine.parse_scene(scene)  # valid
    a = cube_mm / 1000
    brush = scene["brushes"][0]
    orientation, level, position = spin.CONFIGS[config]
    x_base, y_base, z_base = brush["base"]["position"]
    tips = x_base - brush["bristle_length"] - brush["tip_radius"]
    # seed fig. 4.24: P1 on the face plane; P2 halfway between it and the edge's circle a/sqrt2
    expected = a / 2 if position == "P1" else 0.5 * (a / 2 + a / math.sqrt(2))
    assert tips == pytest.approx(expected, abs=1e-12)
    assert z_base == pytest.approx(0.0 if level == "axis" else a / 2, abs=1e-12)
    assert y_base == 0.0
    # horizontal: the 17-bristle rows (stacked along base y = world y) run along the axis
    long_along_axis = brush["rows"] == 17 and brush["columns"] == 5
    assert long_along_axis == (orientation == "horizontal")
    # the bristles point at the cube: base local +z is world -x
    w, x, y, z = brush["base"]["orientation"]
    local_z_world = (2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y))
    assert local_z_world == pytest.approx((-1.0, 0.0, 0.0), abs=1e-12)
    # the hinge, the spin and the rest of the preset are kept
    cube = scene["bodies"][0]
    assert cube["motion"]["type"] == "hinge" and cube["motion"]["axis"] == [0.0, 1.0, 0.0]
    assert cube["shape"]["size"] == pytest.approx([a, a, a])


def test_overrides_reach_the_scene():
    scene = spin.spin_scene(40, 5, n_nodes=4, omega0=-3.0, duration=0.7, grid=(7, 3),
                            tip_variance=4e-10, seed=2, k1=0.2, k2=0.1)
    brush, cube = scene["brushes"][0], scene["bodies"][0]
    assert (brush["rows"], brush["columns"], brush["n_nodes"]) == (3, 7, 4)  # vertical
    assert (brush["tip_variance"], brush["seed"]) == (4e-10, 2)
    assert cube["angular_velocity"] == [0.0, -3.0, 0.0]
    assert (cube["motion"]["k1"], cube["motion"]["k2"]) == (0.2, 0.1)
    assert scene["run"]["duration"] == 0.7
    engine.parse_scene(scene)


# ----------------------------------------------------------------------------- analysis
def test_contact_intervals_on_a_known_signal():
    t = np.arange(0.0, 1.0, 0.01)
    force = np.zeros((t.size, 3))
    force[10:15, 0] = 1.0     # 0.10-0.14 s
    force[40:42, 2] = -0.5    # 0.40-0.41 s
    force[43:45, 2] = -0.5    # one quiet frame later: the same contact
    force[70, 1] = 0.001      # below 2 % of the largest force: not a contact
    omega = 10.0 - 5.0 * (t > 0.12) - 2.0 * (t > 0.42)
    cs = spin.contact_intervals(t, force, omega)
    assert len(cs) == 2
    assert (cs[0]["t_start"], cs[0]["t_end"]) == pytest.approx((0.10, 0.14))
    assert cs[0]["duration"] == pytest.approx(0.05)  # five frames in contact
    assert cs[0]["delta_omega"] == pytest.approx(-5.0)
    assert cs[1]["t_start"] == pytest.approx(0.40) and cs[1]["t_end"] == pytest.approx(0.44)
    assert cs[1]["delta_omega"] == pytest.approx(-2.0)
    assert cs[1]["peak_force"] == pytest.approx(0.5)
    assert spin.contact_intervals(t, np.zeros((t.size, 3)), omega) == []


def test_rest_time_is_the_spin_down_time():
    t = np.arange(0.0, 2.0, 0.002)
    # spins down linearly to rest at 1 s, then rocks in the brush at 0.2 rad/s
    omega = np.where(t < 1.0, 5.0 * (1.0 - t), 0.2 * np.sin(25.0 * (t - 1.0)))
    # from then on below 5 % of the initial 5 rad/s: 5 (1 - t) < 0.25 from t = 0.95 s,
    # exact to one 2 ms frame
    assert spin.rest_time(t, omega) == pytest.approx(0.95, abs=0.0021)
    # rocking fast without turning (a cube caught in its well at once) is not rest
    assert spin.rest_time(t, 5.0 * np.sin(400.0 * t) + 5.0 * (t == 0)) is None
    assert spin.rest_time(t, np.where(t < 1.0, 5.0, 2.0)) is None
    # slow at the very end only: not long enough to call it rest
    assert spin.rest_time(t, np.where(t < 1.9, 5.0, 0.0)) is None
    # ...unless the engine stopped the run at rest (omega exactly 0)
    assert spin.rest_time(t, np.where(t < 1.9, 5.0, 0.0), stopped=True) == pytest.approx(
        1.9, abs=0.0021)


# ----------------------------------------------------------------------------- acceptance
@pytest.fixture(scope="module")
def spin_study(tmp_path_factory):
    """The study at reduced resolution through the CLI and the Dask runner: the 20 mm cube,
    configurations 1 (tips on the face plane) and 2 (halfway to the edge), a 7 x 3 brush of
    5-node bristles, at most 1.5 s (a rest needs 0.3 s of calm after it); one run with
    random tips."""
    out = tmp_path_factory.mktemp("spin_study")
    code = main(["study", "spin", "-o", str(out), "--cubes", "20", "--configs", "1,2",
                 "--grid", "7,3", "--n-nodes", "5", "--duration", "1.5",
                 "--random-seeds", "1", "--random-cube", "20", "--random-config", "1",
                 "--workers", "2", "--no-progress"])
    assert code == 0
    rows = {r["run_id"]: r for r in csv.DictReader((out / "spin_summary.csv").open())}
    return out, rows


def test_spin_study_writes_its_outputs(spin_study):
    out, rows = spin_study
    assert set(rows) == {"cube20_config1", "cube20_config2", "cube20_config1_random1"}
    for name in ("contacts.csv", "omega.csv", "spin.h5", "omega_20mm.png",
                 "delta_omega_vs_duration.png", "randomness.png", "rest_times.png",
                 "outcomes.json"):
        assert (out / name).stat().st_size > 0, name
    outcomes = json.loads((out / "outcomes.json").read_text())
    assert all(o["status"] in ("completed", "stopped") for o in outcomes)
    with engine.open_result(out / "runs" / "cube20_config1.h5") as res:
        assert res.scene.brushes[0].rows == 7 and res.scene.brushes[0].n_nodes == 5


def test_cube_comes_to_rest(spin_study):
    out, rows = spin_study
    r = rows["cube20_config1"]
    assert r["at_rest"] == "True", r
    rest = float(r["rest_time"])
    assert 0.0 < rest < 1.0
    # after the rest time |omega| stays below 5 % of the initial 10 rad/s: check omega.csv
    t, om = [], []
    for row in csv.DictReader((out / "omega.csv").open()):
        if row["run_id"] == "cube20_config1":
            t.append(float(row["time"]))
            om.append(float(row["omega"]))
    t, om = np.array(t), np.array(om)
    after = t >= rest
    assert np.max(np.abs(om[after])) < spin.REST_FRACTION * 10.0
    assert t[-1] - rest >= spin.REST_HOLD - 0.01
    # it was spinning before, and it turned: the brush did the stopping
    assert abs(om[0]) == pytest.approx(10.0, rel=1e-9)
    assert np.ptp(spin.turned_angle(t, om)) > 0.1


def test_delta_omega_differs_between_contacts(spin_study):
    out, _ = spin_study
    deltas = [float(r["delta_omega"]) for r in csv.DictReader((out / "contacts.csv").open())
              if r["run_id"] == "cube20_config1"]
    assert len(deltas) >= 3
    # seed 4.3.2: not the same change at every contact; 10 % of the initial spin is far
    # above the record's resolution of omega (exact to round-off)
    assert np.ptp(deltas) > 1.0
    # and no change repeats contact after contact: a state reset at each contact (a periodic
    # bounce) would give one value at every contact; two of a dozen may coincide to 0.01
    # rad/s by chance (measured: 0.52 twice among 12 in one cold CI run)
    big = np.round([d for d in deltas if abs(d) > 0.5], 2)
    _, repeats = np.unique(big, return_counts=True)
    assert repeats.max() <= 2, big


def test_closer_brush_stops_the_cube_sooner(spin_study):
    _, rows = spin_study
    near, far = rows["cube20_config1"], rows["cube20_config2"]
    assert near["at_rest"] == "True"
    # seed 4.3.5: configuration 1 (more overlap) stops the cube sooner than the farther one
    assert far["at_rest"] == "False" or float(far["rest_time"]) > float(near["rest_time"])


def test_bad_options_exit_2(tmp_path, capsys):
    assert main(["study", "spin", "-o", str(tmp_path), "--cubes", "30"]) == 2
    assert "--cubes" in capsys.readouterr().err
    assert main(["study", "spin", "-o", str(tmp_path), "--configs", "7"]) == 2
    assert main(["study", "spin", "-o", str(tmp_path), "--grid", "3"]) == 2
