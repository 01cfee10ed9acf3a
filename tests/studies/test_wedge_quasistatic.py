"""The quasi-static wedge method against the plain dynamic protocol (seed 4.2): the 60 degree
wedge preset, 5 nodes per bristle, 0 -> 10 mm, loading only.

The reference is the dynamic method at a slow rate (a_m = 0.1 m/s^2, t_d = 245 ms per mm);
its remaining rate error is bounded by how much it moved from a_m = 0.4 (four times faster).
Each method stops a hold within the study's equilibrium tolerance ``max(threshold,
rel_threshold |F|)`` of an equilibrium, so two records of the same equilibrium may differ by
twice that, plus the reference's rate error.

Bug this catches: without the frozen slip (``engine.stepping.quasistatic.freeze_slip``) the fast
quasi-static moves lose friction (27 % low at 10 mm with a_m = 4); a hold that stops before
equilibrium (a wrong out-of-balance sum, a kinetic criterion in the wrong units) shows as a
force off by more than the tolerance.
"""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from studio.cli.main import main
from studio.studies.wedge.protocol import PROTOCOL_DEFAULTS


def _curve(out) -> dict[float, float]:
    with open(out / "force_depth.csv", newline="") as fh:
        return {round(float(r["depth_m"]) * 1e3, 6): float(r["force_N"])
                for r in csv.DictReader(fh)}


def _study(tmp_path, name: str, *extra: str) -> dict[float, float]:
    out = tmp_path / name
    assert main(["study", "wedge", "--preset", "wedge_60", "--nodes", "5", "--depth-mm", "10",
                 "--no-unload", "--workers", "1", "--no-progress", "-o", str(out),
                 *extra]) == 0
    return _curve(out)


# slow (about 35 s: three wedge studies); the quick pass keeps the rate, increment and
# first-contact checks below, and test_wedge_single_bristle.py's single bristle against
# the elastica
@pytest.mark.slow
def test_quasi_static_matches_the_slow_dynamic_protocol(tmp_path):
    qs = _study(tmp_path, "qs")
    slow = _study(tmp_path, "slow", "--method", "dynamic", "--max-acceleration", "0.1")
    fast = _study(tmp_path, "fast", "--method", "dynamic", "--max-acceleration", "0.4")
    depths = sorted(d for d in slow if d > 0)
    assert depths == [float(k) for k in range(1, 11)]
    thr, rel = PROTOCOL_DEFAULTS["threshold"], PROTOCOL_DEFAULTS["rel_threshold"]
    for d in depths:
        tol = 2 * max(thr, rel * abs(slow[d])) + abs(fast[d] - slow[d])
        assert abs(qs[d] - slow[d]) <= tol, (d, qs[d], slow[d], fast[d])
    # the curve is the seed's: stiffening, mN at 10 mm (no force would pass the loop above
    # only if both methods failed the same way)
    assert 5e-3 < qs[10.0] < 1e-2 and qs[10.0] / 10 > qs[1.0]
    # and the quasi-static method agrees with the slow reference more closely than the
    # seed's rate does with it: the slip no longer depends on the loading rate
    err_qs = np.mean([abs(qs[d] - slow[d]) for d in depths])
    err_fast = np.mean([abs(fast[d] - slow[d]) for d in depths])
    assert err_qs < err_fast


def test_quasi_static_does_not_depend_on_the_move_rate(tmp_path):
    """With the slip committed per increment, a_m 4 and 16 m/s^2 (t_d 39 and 19 ms per mm)
    reach the same equilibria: at 3 mm, where one step's stick-slip is settled (the first
    millimetre: ``test_first_contact_does_not_depend_on_the_increment``), within twice the
    equilibrium tolerance plus 1 %
    (an increment's return mapping differs slightly with the path inside it).
    Bug caught: the dynamics' per-step slip (27 % apart at a_m 4 against 0.4)."""
    a = _study(tmp_path, "a4", "--depth-mm", "3")
    b = _study(tmp_path, "a16", "--depth-mm", "3", "--qs-max-acceleration", "16")
    thr, rel = PROTOCOL_DEFAULTS["threshold"], PROTOCOL_DEFAULTS["rel_threshold"]
    tol = 2 * max(thr, rel * a[3.0]) + 0.01 * a[3.0]
    assert a[3.0] == pytest.approx(b[3.0], abs=tol)


def test_first_contact_does_not_depend_on_the_increment(tmp_path):
    """The wedge's first millimetre (8 nodes, the preset's): only the tips of the row under
    the apex touch the wedge's face, and the fast move of a single 1 mm increment (a_m 4,
    t_d 39 ms) throws them off the face as the wedge slows down (no contact from 34.6 to
    53 ms); they touch again while the bristles relax. The contact must keep its frozen
    trial slip through that gap, else its friction follows only the tips' slide back down
    the face and points the wrong way. Bug caught: 0.060 mN at 1 increment against 0.205 mN
    at 4 (and 0.087 mN without friction on the wedge); with the trial kept, 0.2065 and
    0.2040 mN. Tolerance: the study's absolute equilibrium tolerance (``threshold``, 2e-5 N,
    also the accuracy tables' absolute floor), far below the 1.5e-4 N of the bug."""
    one = _study(tmp_path, "one", "--nodes", "8", "--depth-mm", "1")
    four = _study(tmp_path, "four", "--nodes", "8", "--depth-mm", "1", "--qs-increments", "4")
    assert four[1.0] > 1e-4  # the tips touch and the wedge is pushed (N)
    assert one[1.0] == pytest.approx(four[1.0], abs=PROTOCOL_DEFAULTS["threshold"])


def test_increment_check_compares_the_run_with_halved_increments(tmp_path):
    """``--check-increment`` reruns the scene with each step in twice as many increments and
    reports the largest relative change of the recorded force. Checked against the two runs'
    own HDF5 tables, recomputed here (bug caught: comparing a run with itself, the wrong
    protocol for the check run, or records at different depths)."""
    from studio.studies.wedge.cycle import INCREMENT_TOLERANCE, read_run_h5

    out = tmp_path / "inc"
    assert main(["study", "wedge", "--preset", "wedge_60", "--nodes", "3", "--depth-mm", "3",
                 "--no-unload", "--workers", "1", "--no-progress", "--check-increment",
                 "-o", str(out)]) == 0
    check = json.loads((out / "study.json").read_text())["increment_check"]["wedge_60"]
    coarse = read_run_h5(out / "runs" / "wedge_60.h5")
    fine = read_run_h5(out / "runs" / "wedge_60_half_increment.h5")
    assert coarse["protocol"]["qs_increments"] == 1 and fine["protocol"]["qs_increments"] == 2
    np.testing.assert_allclose(coarse["depth_m"], fine["depth_m"], atol=1e-12)
    keep = np.abs(fine["force_N"]) > check["compared_above_N"]
    assert keep.sum() >= 2
    rel = np.abs(coarse["force_N"][keep] - fine["force_N"][keep]) / np.abs(fine["force_N"][keep])
    assert check["max_rel_change"] == pytest.approx(rel.max(), rel=1e-12)
    assert 0.0 < check["max_rel_change"]  # two different paths: not the same run twice
    assert check["converged"] == (rel.max() <= INCREMENT_TOLERANCE)
    # the study's own curve is the coarse run's only
    with open(out / "force_depth.csv", newline="") as fh:
        assert len(list(csv.DictReader(fh))) == len(coarse["depth_m"])


def test_increment_check_refuses_the_dynamic_method(tmp_path, capsys):
    assert main(["study", "wedge", "--preset", "wedge_60", "--nodes", "3", "--depth-mm", "1",
                 "--workers", "1", "--no-progress", "--method", "dynamic",
                 "--check-increment", "-o", str(tmp_path / "d")]) == 2
    assert "quasi-static" in capsys.readouterr().err
