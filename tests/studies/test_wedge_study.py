"""The wedge study (seed 4.2): the hold-until-steady protocol, its files, and (slow) the seed's
observations at reduced resolution."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from studio.cli.main import main
from studio.studies.run_files import load_outcome, run_paths
from studio.studies.wedge.cycle import curve_checks, read_run_h5
from studio.studies.wedge.protocol import PROTOCOL_DEFAULTS


def test_wedge_command_writes_cycle_and_restarts(small_wedge_scene, write_scene, tmp_path,
                                                 capsys):
    path = write_scene(small_wedge_scene(rows=5, n_nodes=4), "wedge_small.json")
    out = tmp_path / "out"
    args = ["study", "wedge", "--preset", str(path), "-o", str(out), "--depth-mm", "2",
            "--workers", "1", "--no-progress"]
    assert main(args) == 0

    with open(out / "force_depth.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["depth_m", "force_N", "phase", "converged"]
    assert [r[3] for r in rows[1:]] == ["1"] * (len(rows) - 1)
    depth = [float(r[0]) for r in rows[1:]]
    force = [float(r[1]) for r in rows[1:]]
    phase = [r[2] for r in rows[1:]]
    assert phase == ["load"] * 3 + ["unload"] * 2
    assert depth == pytest.approx([0, 0.001, 0.002, 0.001, 0.0])
    assert force[0] == 0.0 and force[1] > 0 and force[2] > force[1]
    assert force[3] < force[1]  # friction: unloading lies below loading (seed 4.2.2)
    for name in ("force_depth.png", "wedge_records.csv", "study.json", "outcomes.json"):
        assert (out / name).stat().st_size > 0

    h5 = run_paths(out, "wedge_small")[0]
    table = read_run_h5(h5)
    assert table["status"] == "completed"
    np.testing.assert_allclose(table["force_N"], force, rtol=1e-6, atol=1e-12)
    # the wedge is kinematic: each step lands exactly on its 1 mm (to round-off of the
    # integrated parabolic velocity, far below a micrometre)
    np.testing.assert_allclose(table["measured_depth_m"], depth, atol=1e-7)
    # equilibrium check from an independent channel: at rest, the base's extra push on the
    # roots equals the bristles' push on the wedge; what the window mean can still hold is
    # bristle momentum change, bounded by the steadiness threshold itself
    np.testing.assert_allclose(table["force_N"], table["wedge_force_z_N"],
                               atol=PROTOCOL_DEFAULTS["threshold"])
    assert table["converged"].all() or (table["hold_s"] >= PROTOCOL_DEFAULTS["max_hold"]).any()

    # a restart skips the finished run and rewrites the same table
    first = load_outcome(out, "wedge_small")
    capsys.readouterr()
    assert main(args) == 0
    assert load_outcome(out, "wedge_small")["finished"] == first["finished"]
    outcomes = json.loads((out / "outcomes.json").read_text())
    assert outcomes[0]["skipped"] is True


def test_wedge_command_bad_input(tmp_path, capsys):
    assert main(["study", "wedge", "--preset", str(tmp_path / "none.json"), "-o",
                 str(tmp_path / "o")]) == 2
    assert "no such scene file or preset" in capsys.readouterr().err
    assert main(["study", "wedge", "--angles", "30,abc", "-o", str(tmp_path / "o")]) == 2
    assert main(["study", "wedge", "--depth-mm", "2.5", "-o", str(tmp_path / "o")]) == 2
    assert "whole number" in capsys.readouterr().err
    assert main(["study", "wedge", "--workers", "0", "-o", str(tmp_path / "o")]) == 2


def test_curve_checks_on_known_curves():
    d = [0.0, 0.001, 0.002, 0.003, 0.002, 0.001, 0.0]
    ph = ["load"] * 4 + ["unload"] * 3
    convex = [0.0, 1.0, 4.0, 9.0, 2.0, 0.5, 0.0]
    c = curve_checks(d, convex, ph)
    assert c["stiffening"] and c["unload_below_load"] and c["peak_force_N"] == 9.0
    linear_above = [0.0, 1.0, 2.0, 3.0, 2.5, 1.5, 0.0]
    c = curve_checks(d, linear_above, ph)
    assert not c["stiffening"] and not c["unload_below_load"]


@pytest.mark.slow
def test_wedge_acceptance_reduced_resolution(small_wedge_scene, write_scene, tmp_path):
    """Seed 4.2.2 at reduced resolution (the seed's full 17 x 5 brush, 5 nodes per bristle,
    5 mm): the force grows non-linearly (stiffens) with depth, unloading lies below loading,
    and the peak force grows with the wedge angle."""
    out = tmp_path / "out"
    presets = []
    for angle in (30, 60, 75):
        presets += ["--preset", str(write_scene(small_wedge_scene(angle, rows=17, n_nodes=5),
                                                f"wedge_{angle}.json"))]
    assert main(["study", "wedge", *presets, "-o", str(out), "--depth-mm", "5",
                 "--no-progress"]) == 0
    checks = json.loads((out / "study.json").read_text())["checks"]
    peaks = []
    for angle in (30, 60, 75):
        c = checks[f"wedge_{angle}"]
        assert c["stiffening"], c
        assert c["unload_below_load"], c
        peaks.append(c["peak_force_N"])
    assert peaks[0] < peaks[1] < peaks[2]
