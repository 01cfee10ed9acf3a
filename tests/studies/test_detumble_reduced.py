"""``brush-studio study detumble --fidelity reduced`` (issue 25 item 4): the chaser's brush
replaced by a reduced-law patch of its footprint at its tip plane, run through the same
controller, orbit and recorders, with a DEM spot check of the first seconds beside it."""
from __future__ import annotations

import json

import numpy as np
import pytest

import engine
from engine.model.layout import quat_to_matrix
from studio.cli.main import main
from studio.studies import detumble

# a law of the kind study reduce writes, for a 1 x 2 brush of the detumble design
LAW = {"law_version": 1,
       "parameters": {"k": 400.0, "p": 1.2, "c": 0.5, "eta": 0.7, "mu": 0.5, "q": 0.0,
                      "v_s": 0.01},
       "ranges": {"interference": [0.0, 0.02], "rate": [-0.1, 0.1],
                  "slip_speed": [0.0, 0.1]},
       "patch": {"size": [0.02, 0.005]},
       "brush": {"rows": 1, "columns": 2, "pitch": [0.015, 0.015]}}


def test_reduced_scene_puts_the_footprint_where_the_tips_are():
    # the preset starts the chaser with the undeformed tips START_GAP (10 mm) outside the
    # upper stage's side (radius 0.62 m, on +x): the patch's tip plane must be there, facing
    # the target (-x), of the brush's footprint (16 x 4 pitches plus a tip diameter)
    dem = detumble.detumble_scene("detumble_upper_stage")
    scene = detumble.reduced_scene(dem, LAW)
    assert not [b for b in scene["brushes"] if b.get("mount") == "chaser"]
    chaser = next(b for b in scene["bodies"] if b["name"] == "chaser")
    (patch,) = chaser["patches"]
    centre = np.asarray(chaser["pose"]["position"]) + np.asarray(patch["pose"]["position"])
    assert centre == pytest.approx([0.62 + 0.01, 0.0, 0.0], abs=1e-12)
    normal = quat_to_matrix(np.asarray(patch["pose"]["orientation"])) @ [0.0, 0.0, 1.0]
    assert normal == pytest.approx([-1.0, 0.0, 0.0], abs=1e-12)
    assert patch["size"] == pytest.approx([16 * 0.015 + 0.005, 4 * 0.015 + 0.005])
    # per bristle: the law's 2 bristles carry 2/85 of the footprint's area
    a, b = patch["law"]["patch"]["size"]
    assert a * b == pytest.approx(patch["size"][0] * patch["size"][1] * 2 / 85, rel=1e-12)
    system = engine.build(engine.parse_scene(scene))
    assert "patch_contacts" in system.stages and system.n_nodes == 0


def test_per_bristle_law_keeps_each_bristles_friction_at_its_load():
    # a law fitted on 2 bristles with a load-dependent friction (q = -0.5) put on the 85
    # bristles of the preset: the element takes mu_eff at the whole patch's F_n, so the
    # friction of the whole brush at a load F must be 85/2 times the law's at the 2
    # bristles' share 2F/85 (closed form). Without the restated mu it is off by
    # (85/2)^0.5 = 6.5: the 1 x 2 law's friction fell ~90 % short that way (q = -1)
    from engine.model.reduced_law import friction_coefficient

    law = json.loads(json.dumps(LAW))
    law["parameters"]["q"] = -0.5
    scene = detumble.reduced_scene(detumble.detumble_scene("detumble_upper_stage"), law)
    chaser = next(b for b in scene["bodies"] if b["name"] == "chaser")
    par = chaser["patches"][0]["law"]["parameters"]
    p0 = law["parameters"]
    for F in (0.5, 3.0, 40.0):
        share = F * 2 / 85
        whole = friction_coefficient(F, 0.1, par["mu"], par["q"], par["v_s"]) * F
        per = friction_coefficient(share, 0.1, p0["mu"], p0["q"], p0["v_s"]) * share
        assert whole == pytest.approx(85 / 2 * per, rel=1e-12)   # round-off only


def test_study_detumble_reduced_with_a_dem_spot_check(tmp_path):
    law = tmp_path / "law.json"
    law.write_text(json.dumps(LAW))
    out = tmp_path / "study"
    code = main(["study", "detumble", "-o", str(out), "--fidelity", "reduced", "--law",
                 str(law), "--rows", "3", "--columns", "3", "--nodes", "3", "--duration", "4",
                 "--spot-check-s", "2", "--workers", "1", "--no-progress"])
    assert code == 0
    (r,) = json.loads((out / "detumble_summary.json").read_text())["runs"]
    assert r["status"] in ("completed", "stopped") and r["fidelity"] == "reduced"
    assert r["first_contact"] is not None and r["first_contact"] < 2.0
    assert r["peak_target_torque"] > 0 and r["time_in_contact"] > 0
    assert r["omega_end"] < r["omega0"]          # the patch's friction takes spin
    assert r["peak_bending_stress"] is None      # no bristles
    assert r["patches"][0]["steps_in_contact"] > 0
    # a reduced brush has no single contacts; its push is spread over the patch's footprint
    assert r["peak_contact_force"] is None and r["peak_contact_pressure"] is None
    assert r["peak_footprint_pressure"] == pytest.approx(
        r["peak_target_force"] / r["footprint_area"], rel=1e-12)
    spot = r["spot_check"]
    assert spot["dem"]["window_s"] == spot["reduced"]["window_s"] == 2.0
    for key in ("delta_omega", "mean_torque", "peak_torque"):
        rel = spot["relative_error"][key]
        assert rel == pytest.approx((spot["reduced"][key] - spot["dem"][key])
                                    / abs(spot["dem"][key]))
    assert (out / "omega.png").stat().st_size > 1000


def test_reduced_fidelity_refuses_a_law_file_it_cannot_read(tmp_path, capsys):
    # (without --law the study fits one: tests/studies/test_detumble_onecmd.py)
    assert main(["study", "detumble", "-o", str(tmp_path / "o"), "--fidelity", "reduced",
                 "--law", str(tmp_path / "missing.json")]) == 2
    assert "--law" in capsys.readouterr().err
    assert not (tmp_path / "o" / "laws").exists()
