"""Refinement, sensitivity and Monte Carlo studies: their pieces (quick) and, at reduced
resolution, their acceptance checks (slow)."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from studio.cli.main import main
from studio.studies.refinement import overlap_ceiling, parse_levels
from studio.studies.sensitivity import (PARAMETERS, apply_parameters, draw_samples,
                                        mean_std_table, nominal_values)


def test_overlap_ceiling_of_the_seed_brush():
    # 33 mm bristle, radius 1.0 -> 0.5 mm: with n nodes the root segment is 33/(n-1) mm
    # long and its nodes' radii add to 1 + (1 - 0.5/(n-1)) mm; n = 17 gives 2.0625 mm
    # against 1.969 mm (no overlap), n = 18 gives 1.941 mm against 1.971 mm (overlap)
    brush = {"bristle_length": 0.033, "root_radius": 0.001, "tip_radius": 0.0005}
    assert overlap_ceiling(brush) == 17
    # a cylinder of radius r and length L: nodes overlap once L/(n-1) < 2r
    assert overlap_ceiling({"bristle_length": 0.01, "root_radius": 0.001,
                            "tip_radius": 0.001}) == 6


def test_parse_levels():
    assert parse_levels("8,4,16,8") == [4, 8, 16]
    for bad in ("4", "1,4", "a,b"):
        with pytest.raises(ValueError):
            parse_levels(bad)


def test_apply_parameters_changes_only_the_bristles(demo_scene_dict):
    values = {"youngs_modulus": 3.8e6, "density": 1100.0, "poisson_ratio": 0.49,
              "friction_bristle_bristle": math.radians(46),
              "friction_bristle_wedge": math.radians(22)}
    scene = apply_parameters(demo_scene_dict, values)
    sil = scene["materials"]["silicone"]
    assert (sil["youngs_modulus"], sil["density"], sil["poisson_ratio"]) == (3.8e6, 1100.0, 0.49)
    assert scene["materials"]["pla"] == demo_scene_dict["materials"]["pla"]
    pairs = {tuple(sorted(p["materials"])): p["friction_angle"] for p in scene["contact_pairs"]}
    assert pairs[("silicone", "silicone")] == pytest.approx(math.radians(46))
    assert pairs[("pla", "silicone")] == pytest.approx(math.radians(22))
    assert demo_scene_dict["materials"]["silicone"]["youngs_modulus"] == 2.7e6  # a copy
    nom = nominal_values(demo_scene_dict)
    assert nom["youngs_modulus"] == 2.7e6 and nom["density"] == 1700.0
    assert nom["friction_bristle_wedge"] == pytest.approx(math.radians(24))


def test_samples_cover_the_ranges_reproducibly():
    a, b = draw_samples(400, seed=3), draw_samples(400, seed=3)
    assert a == b and a != draw_samples(400, seed=4)
    for name, (_, _, lo, hi, _) in PARAMETERS.items():
        x = np.array([s[name] for s in a])
        assert lo <= x.min() and x.max() <= hi
        # uniform on [lo, hi]: mean (lo+hi)/2 with std (hi-lo)/sqrt(12 n) = 0.014 (hi-lo);
        # 4 standard errors
        assert x.mean() == pytest.approx((lo + hi) / 2, abs=0.06 * (hi - lo))


def test_mean_std_table_against_numpy():
    runs = [{"depth_m": [0.0, 0.001, 0.0], "force_N": [0.0, f, f / 4],
             "phase": ["load", "load", "unload"]} for f in (1.0, 2.0, 4.0)]
    rows = mean_std_table(runs)
    assert [(r["phase"], r["depth_m"]) for r in rows] == [("load", 0.0), ("load", 0.001),
                                                          ("unload", 0.0)]
    assert rows[1]["mean_N"] == pytest.approx(np.mean([1, 2, 4]))
    assert rows[1]["std_N"] == pytest.approx(np.std([1, 2, 4], ddof=1))
    assert rows[2]["std_N"] == pytest.approx(np.std([0.25, 0.5, 1.0], ddof=1))
    assert rows[1]["n"] == 3


def test_study_commands_bad_input(tmp_path, capsys):
    o = str(tmp_path / "o")
    assert main(["study", "refinement", "--levels", "4", "-o", o]) == 2
    assert main(["study", "refinement", "--nodes", "5", "-o", o]) == 2
    assert main(["study", "montecarlo", "--samples", "1", "-o", o]) == 2
    assert main(["study", "sensitivity", "--preset", "no_such_preset", "-o", o]) == 2
    assert "no_such_preset" in capsys.readouterr().err


@pytest.mark.slow
def test_refinement_changes_shrink(small_wedge_scene, write_scene, tmp_path):
    """Appendix E at reduced size: the force at maximum penetration converges with nodes per
    bristle, i.e. the change between successive levels shrinks."""
    path = write_scene(small_wedge_scene(75, rows=9, n_nodes=4), "wedge_75.json")
    out = tmp_path / "ref"
    assert main(["study", "refinement", "--preset", str(path), "--levels", "3,5,9,17",
                 "--depth-mm", "3", "-o", str(out), "--no-progress"]) == 0
    with open(out / "refinement.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    changes = [abs(float(r["change_N"])) for r in rows[1:]]
    assert len(changes) == 3
    assert changes[-1] < changes[0]
    assert all(float(r["wall_s"]) > 0 for r in rows)
    assert (out / "refinement.png").stat().st_size > 0


@pytest.mark.slow
def test_sensitivity_and_montecarlo_small(small_wedge_scene, write_scene, tmp_path):
    """One parameter at a time: a stiffer bristle (E high) gives a larger force than a soft
    one (the force of bent bristles scales with E I). Monte Carlo: mean ± std per depth."""
    path = write_scene(small_wedge_scene(60, rows=5, n_nodes=4), "wedge_60.json")
    out = tmp_path / "sens"
    assert main(["study", "sensitivity", "--preset", str(path), "--depth-mm", "2",
                 "--no-unload", "-o", str(out), "--no-progress"]) == 0
    table = json.loads((out / "study.json").read_text())["peak_force_by_parameter"]
    e = table["wedge_60"]["youngs_modulus"]
    assert e["peak_low_N"] < e["peak_nominal_N"] < e["peak_high_N"]
    mc = tmp_path / "mc"
    assert main(["study", "montecarlo", "--samples", "4", "--preset", str(path),
                 "--depth-mm", "2", "--nodes", "4", "-o", str(mc), "--no-progress"]) == 0
    with open(mc / "montecarlo.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    deep = [r for r in rows if r["phase"] == "load" and float(r["depth_m"]) == 0.002][0]
    assert int(deep["n"]) == 4 and float(deep["std_N"]) > 0 and float(deep["mean_N"]) > 0
