"""``brush-studio convergence`` with a loading ladder (issue 11 item 1): the wedge study's
quasi-static cycle at refined increments, the force at a depth and the whole curve's change.

Reduced wedge: the wedge_60 preset at 5 nodes per bristle, 0 -> 2 mm, loading only (about
5 CPU-s for three levels once the kernels are compiled).
"""
from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from studio.cli.main import main
from studio.studies import convergence as cv
from studio.studies.convergence import protocol_ladder
from studio.studies.wedge.cycle import INCREMENT_TOLERANCE
from studio.studies.wedge.protocol import PROTOCOL_DEFAULTS

LADDER = (1, 2, 4)
PRESET_FILE = Path(__file__).resolve().parents[2] / "static_presets" / "wedge_60.json"


def _force_depth(path) -> tuple[dict, dict]:
    """The run's force-depth table and protocol read straight from its HDF5 (not through the
    study's reader), so that a wrong record picked by the ladder shows."""
    with h5py.File(path, "r") as f:
        g = f["force_depth"]
        phases = [p.decode() if isinstance(p, bytes) else str(p) for p in g["phase"][()]]
        table = {round(float(d) * 1e3, 6): float(F) for d, F, p in
                 zip(g["depth_m"][()], g["force_N"][()], phases) if p == "load"}
        return table, json.loads(f.attrs["protocol"])


@pytest.fixture(scope="module")
def increment_ladder(tmp_path_factory):
    out = tmp_path_factory.mktemp("increments")
    code = main(["convergence", "--preset", "wedge_60", "--nodes", "5", "--quantity",
                 "wedge_force@2mm", "--ladder", "qs_increments=" + ",".join(map(str, LADDER)),
                 "--serial", "-q", "-o", str(out)])
    assert code == 0
    return out, cv.load_convergence(out)


def test_each_level_is_the_wedge_cycle_at_its_increment(increment_ladder):
    """Bug caught: every level run with the default protocol (the same run three times), or
    the quantity read at another depth or from the unloading branch."""
    out, table = increment_ladder
    assert table.setting == "qs_increments"
    assert [r["setting"] for r in table.rows] == list(LADDER)
    forces = []
    for r, n in zip(table.rows, LADDER):
        curve, protocol = _force_depth(r["h5"])
        assert protocol["qs_increments"] == n and protocol["method"] == "quasi_static"
        assert protocol["n_steps"] == 2 and protocol["unload"] is False
        assert r["n_nodes"] is None and r["status"] == "completed"
        assert r["quantity"] == curve[2.0]
        forces.append(curve[2.0])
    # the reference of a loading ladder is its finest level; errors are relative to it
    assert table.reference == forces[-1] and table.reference_kind == "finest"
    for r, f in zip(table.rows, forces):
        assert r["error"] == pytest.approx((f - forces[-1]) / abs(forces[-1]), rel=1e-12)
    assert len(set(forces)) == len(forces)  # three different paths, not one run thrice


def test_the_force_does_not_depend_on_the_increment(increment_ladder):
    """Past the first millimetre (whose lone contacts are bistable), halving the increment
    moves the recorded force by at most twice the study's equilibrium tolerance
    ``max(threshold, rel_threshold |F|)`` (each hold stops within it of an equilibrium) plus
    1 % for the return mapping's path inside an increment. Bug caught: the slip not frozen per
    increment (the force then follows the move's rate: 27 % low at 10 mm)."""
    _, table = increment_ladder
    thr, rel = PROTOCOL_DEFAULTS["threshold"], PROTOCOL_DEFAULTS["rel_threshold"]
    values = [r["quantity"] for r in table.rows]
    assert 2e-4 < values[-1] < 2e-3  # the seed's sub-mN force at 2 mm, not a zero record
    for a, b in zip(values, values[1:]):
        assert abs(a - b) <= 2 * max(thr, rel * abs(b)) + 0.01 * abs(b), values


def test_the_whole_curve_is_compared_level_by_level(increment_ladder):
    """``curve_changes`` is the largest relative change between successive levels over the
    records whose force is above ten times the absolute tolerance, recomputed here."""
    _, table = increment_ladder
    changes = table.curve_changes
    assert [c["level"] for c in changes] == [1, 2]
    limit = 10 * PROTOCOL_DEFAULTS["threshold"]
    for c, (coarse, fine) in zip(changes, zip(table.rows, table.rows[1:])):
        a, _ = _force_depth(coarse["h5"])
        b, _ = _force_depth(fine["h5"])
        rel = [abs(a[d] - b[d]) / abs(b[d]) for d in b if abs(b[d]) > limit]
        assert rel and c["max_rel_change"] == pytest.approx(max(rel), rel=1e-12)
        assert c["converged"] == (max(rel) <= INCREMENT_TOLERANCE)
        assert c["against_level"] == c["level"] - 1


def test_the_table_names_the_setting(increment_ladder, capsys):
    out, table = increment_ladder
    text = table.text()
    assert text.splitlines()[0].split()[0] == "qs_increments"
    assert "whole curve, level 1 against 0" in text
    assert np.isfinite(json.loads((out / "convergence.json").read_text())["reference"])
    with h5py.File(out / "convergence.h5", "r") as f:
        assert f["convergence"].attrs["setting"] == "qs_increments"
        assert list(f["convergence/setting"][()]) == list(LADDER)


@pytest.mark.parametrize("argv, message", [
    (["--quantity", "tip_deflection", "--ladder", "qs_increments=1,2"], "wedge_force@DEPTH"),
    (["--quantity", "wedge_force@2mm", "--ladder", "qs_increments=2,1"], "must increase"),
    (["--quantity", "wedge_force@2mm", "--ladder", "qs_max_acceleration=4,8"],
     "must decrease"),
    (["--quantity", "wedge_force@2mm", "--ladder", "qs_increments=1,2", "--dt-factor",
      "0.5"], "loading only"),
    (["--quantity", "wedge_force@2mm", "--ladder", "n_nodes=3,5", "--nodes", "5"],
     "leave it out"),
    (["--quantity", "wedge_force@2.5mm", "--ladder", "qs_increments=1,2"], "whole number"),
])
def test_bad_loading_ladders_are_refused_before_running(tmp_path, capsys, argv, message):
    out = tmp_path / "o"
    assert main(["convergence", "--preset", "wedge_60", "-o", str(out), "--serial", "-q",
                 *argv]) == 2
    assert message in capsys.readouterr().err
    assert not (out / "runs").exists()


def test_the_scene_is_given_once(tmp_path, capsys):
    args = ["--quantity", "wedge_force@2mm", "--ladder", "qs_increments=1,2", "-o",
            str(tmp_path / "o")]
    assert main(["convergence", *args]) == 2
    assert "give the scene once" in capsys.readouterr().err
    assert main(["convergence", str(PRESET_FILE), "--preset", "wedge_60",
                 *args]) == 2
    assert "give the scene once" in capsys.readouterr().err
    assert main(["convergence", "--preset", "no_such_preset", *args]) == 2
    assert "no such scene file or preset" in capsys.readouterr().err


def test_a_rate_ladder_sets_the_move_acceleration_of_each_level():
    """``qs_max_acceleration=16,8,4``: each level's protocol has that a_m and nothing else
    changed; h is a_m (bug caught: the setting written to the dynamic method's
    max_acceleration, which the quasi-static cycle does not use)."""
    scene = json.loads(PRESET_FILE.read_text())
    key, values = protocol_ladder.parse_protocol_ladder("qs_max_acceleration=16,8,4")
    levels = protocol_ladder.protocol_levels(scene, cv.parse_quantity("wedge_force@3mm"),
                                                key, values)
    assert [lv.protocol["qs_max_acceleration"] for lv in levels] == [16.0, 8.0, 4.0]
    base = {k: v for k, v in levels[0].protocol.items() if k != "qs_max_acceleration"}
    for lv in levels:
        assert {k: v for k, v in lv.protocol.items() if k != "qs_max_acceleration"} == base
    assert base["max_acceleration"] == scene["bodies"][0]["motion"]["profile"]["max_acceleration"]
    assert base["n_steps"] == 3 and base["qs_increments"] == PROTOCOL_DEFAULTS["qs_increments"]
    assert cv.level_resolution(levels)[0] == [16.0, 8.0, 4.0]
    assert len({lv.run_id for lv in levels}) == 3
    assert protocol_ladder.parse_protocol_ladder("n_nodes=3,5") is None
