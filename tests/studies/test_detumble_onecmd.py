"""``brush-studio study detumble --fidelity reduced`` without ``--law`` (issue 25: a brush
design to an hour-long detumble in one command): each brush design of the sweep gets its
own law, fitted by ``study reduce`` into ``OUT/laws/<design>/`` and reused by a re-run; and
the spot check's two windows (the whole spot check and the part after the first touch)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import engine
from studio.cli.main import main
from studio.studies import detumble

# a reduce protocol small enough for a quick test (2 x 2 bristles of 3 nodes): two sliding
# presses (samples from 10 to 30 mm), one slide, no held-out sliding press, the three
# held-out impacts at one speed
TINY = {"depths": [30.0], "rates": [20.0, 40.0], "slide_depths": [15.0], "speeds": [100.0],
        "check_depth": 0.0, "impact_speeds": [100.0]}


def _tiny(monkeypatch):
    full = detumble.reduce_options
    monkeypatch.setattr(detumble, "reduce_options",
                        lambda *a: full(*a).model_copy(update=TINY))


@pytest.mark.slow   # 8 DEM reduce runs and 2 detumble runs (test_runs_share_a_law_per_...)
def test_one_command_fits_the_law_uses_it_and_reuses_it(tmp_path, monkeypatch, capsys):
    _tiny(monkeypatch)
    out = tmp_path / "study"
    argv = ["study", "detumble", "-o", str(out), "--fidelity", "reduced", "--rows", "2",
            "--columns", "2", "--nodes", "3", "--duration", "3", "--spot-check-s", "1.5",
            "--workers", "1", "--no-progress"]
    assert main(argv) == 0
    law_file = out / "laws" / "lenp_diap_rows2_cols2_nodes3" / "law.json"
    law = json.loads(law_file.read_text())
    assert law["brush"]["rows"] == 2 and law["brush"]["n_nodes"] == 3   # this design's
    outcomes = json.loads((out / "outcomes.json").read_text())
    (run,) = [o for o in outcomes if "spot_of" not in o["params"]]   # and its DEM spot check
    assert run["params"]["law_design"] == "lenp_diap_rows2_cols2_nodes3"
    # the reduced run's scene (recorded in its result file) carries the fitted law inline
    # (restated per bristle only when the law's brush has fewer bristles: the same 2 x 2)
    with engine.open_result(run["h5"]) as res:
        inline = json.loads(res.scene_json)["bodies"]
    (patch,) = [p for b in inline for p in (b.get("patches") or [])]
    assert patch["law"]["parameters"] == law["parameters"]
    assert patch["law"]["fit_digest"] == law["fit_digest"]
    first = capsys.readouterr().out
    assert "study reduce into" in first and "after the first touch" in first
    stamp = law_file.stat().st_mtime_ns
    # the same command again: the law is reused, not refitted (no reduce runs, the file
    # untouched), and the detumble runs are skipped as finished
    assert main(argv) == 0
    again = capsys.readouterr().out
    assert "fitted before: reused" in again and "Reduced law" not in again
    assert law_file.stat().st_mtime_ns == stamp
    assert all(o["skipped"] for o in json.loads((out / "outcomes.json").read_text()))


def test_runs_share_a_law_per_brush_design():
    # two target sizes x two spins x two lengths x one diameter: two designs, each run
    # reduced with its own design's law (parameters told apart by k) and named by it
    opts = detumble.Options(fidelity="reduced", sizes=[1.0, 1.5], spins=[1.0, 2.0],
                            lengths=[40.0, 60.0], rows=2, columns=2, n_nodes=3,
                            spot_check_s=0.0)
    grid = detumble._grid(opts)
    ids = detumble.design_ids(opts, grid)
    assert ids == {"len40_diap_rows2_cols2_nodes3": (40.0, None),
                   "len60_diap_rows2_cols2_nodes3": (60.0, None)}
    base = json.loads(json.dumps(LAW))
    grid["laws"] = {}
    for i, did in enumerate(ids):
        grid["laws"][did] = json.loads(json.dumps(base))
        grid["laws"][did]["parameters"]["k"] = 100.0 * (i + 1)
    specs = detumble.build_specs(opts, grid)
    assert len(specs) == 8
    for s in specs:
        did = s.params["law_design"]
        assert ids[did][0] == s.params["length_mm"]
        (patch,) = next(b for b in s.scene["bodies"] if b["name"] == "chaser")["patches"]
        assert patch["law"]["parameters"]["k"] == grid["laws"][did]["parameters"]["k"]
    # a design whose fit failed: its runs fail naming it, the other design's run as before
    grid["laws"]["len60_diap_rows2_cols2_nodes3"] = "no reduced law for brush design len60"
    specs = detumble.build_specs(opts, grid)
    failing = [s for s in specs if s.params.get("law_error")]
    assert {s.params["length_mm"] for s in failing} == {60.0} and len(failing) == 4
    with pytest.raises(RuntimeError, match="len60"):
        detumble.detumble_task(None, None, failing[0].params)


LAW = {"law_version": 1,
       "parameters": {"k": 400.0, "p": 1.2, "c": 0.5, "eta": 0.7, "mu": 0.5, "q": 0.0,
                      "v_s": 0.01},
       "ranges": {"interference": [0.0, 0.02], "rate": [-0.1, 0.1],
                  "slip_speed": [0.0, 0.1]},
       "patch": {"size": [0.02, 0.005]}}


def _series(t, w_axis, torque, force, contact_from):
    """A run's arrays as read_detumble gives them: spin about z, torque about z, |F| along
    x, contact from ``contact_from``; L = I w with I = 2 about z."""
    t = np.asarray(t, float)
    z = np.zeros_like(t)
    omega = np.column_stack([z, z, w_axis])
    return {"time": t, "omega": omega, "angular_momentum": 2.0 * omega,
            "target_torque": np.column_stack([z, z, torque]),
            "target_force": np.column_stack([force, z, z]),
            "n_contacts": (t >= contact_from).astype(int)}


def test_spot_check_windows_by_hand():
    # DEM: frames every 0.5 s; first contact at 1.0 s, a force spike of 20 N at 1.0 s, then
    # 3 N; spin 1.0 falling by 0.1 rad/s per second from 1 s on
    t = np.arange(0.0, 4.01, 0.5)
    w = np.where(t < 1.0, 1.0, 1.0 - 0.1 * (t - 1.0))
    dem = _series(t, w, np.where(t >= 1.0, -0.2, 0.0),
                  np.where(t == 1.0, 20.0, np.where(t > 1.0, 3.0, 0.0)), 1.0)
    # reduced: frames every 1 s, spin falling 0.09 rad/s per second from 1 s on, 3.3 N
    tr = np.arange(0.0, 4.01, 1.0)
    wr = np.where(tr < 1.0, 1.0, 1.0 - 0.09 * (tr - 1.0))
    red = _series(tr, wr, np.where(tr >= 1.0, -0.18, 0.0), np.where(tr >= 1.0, 3.3, 0.0),
                  1.0)
    sc = detumble.spot_check(dem, red, 4.0, settle_s=0.5)
    # whole window 0-4 s: delta-omega -0.3 (DEM) / -0.27, peak force 20 / 3.3 N
    assert sc["dem"]["delta_omega"] == pytest.approx(-0.3)
    assert sc["relative_error"]["delta_omega"] == pytest.approx((-0.27 + 0.3) / 0.3)
    assert sc["relative_error"]["peak_force"] == pytest.approx((3.3 - 20.0) / 20.0)
    # mean torque: I delta-omega over the window, 2 x -0.3 / 4
    assert sc["dem"]["mean_torque"] == pytest.approx(-0.15)
    # after the touch: 1.5-4 s; DEM -0.25 rad/s, 3 N; reduced interpolated at 1.5 s
    # (1 - 0.045) to 0.73 at 4 s: -0.225; its force 3.3 N (the interpolated 1.5 s value too)
    after = sc["after_touch"]
    assert after["first_contact"] == 1.0 and after["dem"]["start_s"] == 1.5
    assert after["dem"]["delta_omega"] == pytest.approx(-0.25)
    assert after["reduced"]["delta_omega"] == pytest.approx(-0.225)
    assert after["relative_error"]["delta_omega"] == pytest.approx(0.1)
    assert after["relative_error"]["peak_force"] == pytest.approx(0.1)
    assert after["dem"]["peak_torque"] == pytest.approx(0.2)
    assert after["relative_error"]["peak_torque"] == pytest.approx(-0.1)
    # a touch too late for a second window: reported as such, not a window of nothing
    late = detumble.spot_check(dem, red, 1.2, settle_s=0.5)
    assert late["after_touch"] is None and "1.2" in late["after_touch_why"]
    assert math.isfinite(late["relative_error"]["delta_omega"])
