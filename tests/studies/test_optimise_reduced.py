"""The design search at mission scale (``study optimise --fidelity reduced``, issue 25 item
4): its inputs are checked against the fidelity, a design is held at the preset's tip
interference, a detumble summary becomes the search's metrics, a design's law is fitted
once however many of its runs ask at the same time, the spot check judges the after-touch
errors by the issue's bounds, and (slow) the command searches two designs of a tiny brush,
each with its own fitted law, and a re-run reuses every law and run.
"""
from __future__ import annotations

import csv
import json
import math
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from studio.studies import detumble
from studio.studies.optimise import Options, StudyInputError
from studio.studies.optimise import reduced
from studio.studies.optimise.search import Problem

ROOT = Path(__file__).resolve().parents[2]
LENGTH = "brushes.0.bristle_length"


def _options(**kw) -> Options:
    base = dict(fidelity="reduced", preset="detumble_upper_stage",
                variables=[f"{LENGTH}=0.1:0.2"], workers=1, no_progress=True)
    base.update(kw)
    return Options(**base)


def test_scenarios_are_detumbles_of_the_preset_for_an_hour_by_default():
    p = Problem.from_options(_options(sizes=[1.0, 2.0], spins_deg=[2.0], tilts_deg=[0, 20],
                                      offsets_m=[0.0]))
    assert p.reduced and p.duration == reduced.DEFAULT_DURATION == 3600.0
    assert [s.scenario_id for s in p.scenarios] == [
        "size1_spin2", "size1_spin2_tilt20", "size2_spin2", "size2_spin2_tilt20"]
    specs = p.specs({LENGTH: 0.15})
    assert {s.task for s in specs} == {reduced.TASK}
    # the runs of one design share its law's folder key
    assert {s.params["law_key"] for s in specs} == {specs[0].run_id.split("_")[0]}
    scene = specs[3].scene
    w = np.asarray(next(b for b in scene["bodies"] if b["name"] == "target")
                   ["angular_velocity"])
    assert np.linalg.norm(w) == pytest.approx(math.radians(2.0))   # the scenario's spin
    assert scene["run"]["duration"] == 3600.0
    # the spot-check specs are the DEM scene's first seconds
    spot = p.specs({LENGTH: 0.15}, refined=True)
    assert {s.task for s in spot} == {reduced.SPOT_TASK}
    assert all(s.scene["run"]["duration"] == pytest.approx(5.0 + detumble.SPOT_MARGIN)
               for s in spot)
    # the thrusters' specific impulse (the propellant metric) reaches every run's task
    assert {s.params["isp"] for s in specs + spot} == {220.0}
    p = Problem.from_options(_options(isp=300.0))
    assert {s.params["isp"] for s in p.specs({LENGTH: 0.15})
            + p.specs({LENGTH: 0.15}, refined=True)} == {300.0}


@pytest.mark.parametrize("bad, words", [
    (dict(cubes_mm=[30.0]), "--cubes-mm: an option of --fidelity dem"),
    (dict(preset="spin_cube_40"), "not a detumble scene"),
    (dict(objectives=["peak_stress_ratio"]), "unknown metric 'peak_stress_ratio' with "
                                             "--fidelity reduced"),
    (dict(constraints=["propellant_mass:worst<=x"]), "LIMIT must be a number"),
    (dict(sizes=[0.0]), "sizes: [0.0]: scale factors > 0"),
])
def test_bad_reduced_options_are_refused_naming_the_option(bad, words):
    with pytest.raises(StudyInputError) as err:
        Problem.from_options(_options(**bad))
    assert words in str(err.value)


def test_a_dem_search_refuses_the_reduced_scenario_options():
    with pytest.raises(StudyInputError, match="--sizes, --spot-check-s, --isp: an option of "
                                              "--fidelity reduced"):
        Problem.from_options(Options(sizes=[2.0], spot_check_s=3.0, isp=300.0))
    # and a dem search keeps its defaults (3 nodes, 0.4 s), so old searches resume
    p = Problem.from_options(Options())
    assert (p.nodes, p.duration, p.fidelity) == (3, 0.4, "dem")


def test_a_design_is_held_at_the_presets_tip_interference():
    """A longer bristle reaches farther: the held offset moves out by the change of reach
    (the bristle's length along the offset axis plus the tip radius), so the tips press the
    surface as deep as the preset's."""
    p = Problem.from_options(_options())
    base = p.base
    s = p.scenarios[0]
    hold0 = np.asarray(p.scene({LENGTH: base["brushes"][0]["bristle_length"]}, s)
                       ["controllers"][0]["position"])
    for length in (0.1, 0.2):
        for via, stiff in (("youngs_modulus", None), ("diameter", 1e-5)):
            design = {LENGTH: length} if stiff is None else {LENGTH: length,
                                                             "bending_stiffness": stiff}
            p.stiffness_via = via
            scene = p.scene(design, s)
            brush = scene["brushes"][0]
            hold = np.asarray(scene["controllers"][0]["position"])
            b0 = base["brushes"][0]
            # the upper stage's brush points straight at the target along the hold axis
            reach = (brush["bristle_length"] - b0["bristle_length"]) \
                + (brush["tip_radius"] - b0["tip_radius"])
            assert hold - hold0 == pytest.approx([reach, 0, 0], abs=1e-12)
            assert brush["bristle_length"] == pytest.approx(length)


def test_a_detumble_summary_becomes_the_search_metrics():
    s = {"omega0": 0.04, "omega_end": 0.01, "detumble_time": None, "time_in_contact": 2400.0,
         "peak_target_force": 3.5, "peak_target_torque": 1.2, "delta_v_gimballed": 0.8,
         "delta_v": 0.8, "propellant_gimballed": 0.37, "wheel_momentum": 40.0,
         "peak_chaser_torque_com": 2.1, "thrust_saturation": [0.1, 0.3, 0.0],
         "peak_footprint_pressure": 150.0}
    m = reduced.metrics_of(s)
    assert m["spin_left"] == m["abs_spin_left"] == pytest.approx(0.25)
    assert m["delta_omega"] == pytest.approx(-0.03)
    assert m["rest_time"] == math.inf            # never below 5 % within the run
    assert m["thrust_saturation"] == 0.3         # the worst axis
    assert (m["peak_force"], m["chaser_delta_v"], m["propellant_mass"],
            m["peak_chaser_torque"], m["peak_contact_pressure"]) == (3.5, 0.8, 0.37, 2.1, 150.)
    assert set(m) | {"brush_mass"} == set(reduced.METRICS)
    assert reduced.metrics_of(dict(s, detumble_time=812.5))["rest_time"] == 812.5


def test_a_designs_law_is_fitted_once_when_its_runs_ask_together(tmp_path, monkeypatch):
    """Two runs of one design ask for its law at once: one fits (study reduce), the other
    waits on the folder's lock and reuses the fitted file."""
    from engine.model.reduced_law import load_law, save_law
    from studio.studies import reduce

    law = load_law(ROOT / "benchmarks" / "data" / "detumble_brush_17x5_sliding_law.json")
    fits = []

    def fake_fit(ropts, folder):
        fits.append(folder)
        time.sleep(0.3)          # long enough for the other thread to reach the lock
        save_law(folder / "law.json",
                 dict(law, fit_digest=reduce.fit_digest(ropts, reduce.design_of(ropts))))
        return 0

    monkeypatch.setattr(reduce, "_run_study", fake_fit)
    scene = Problem.from_options(_options()).scene({LENGTH: 0.15},
                                                   reduced.DetumbleScenario("s"))
    got = []
    threads = [threading.Thread(target=lambda: got.append(
        reduced.law_for(scene, tmp_path / "d1"))) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(fits) == 1
    assert sorted(reused for _, reused in got) == [False, True]
    assert got[0][0]["parameters"] == got[1][0]["parameters"] == law["parameters"]


def test_a_failed_fit_fails_the_run_naming_the_folder(tmp_path, monkeypatch):
    from studio.studies import reduce

    monkeypatch.setattr(reduce, "_run_study", lambda ropts, folder: 1)
    scene = Problem.from_options(_options()).scene({LENGTH: 0.15},
                                                   reduced.DetumbleScenario("s"))
    with pytest.raises(RuntimeError, match="study reduce failed .*d2/outcomes.json"):
        reduced.law_for(scene, tmp_path / "d2")


def test_the_spot_check_judges_the_after_touch_errors_by_the_issues_bounds(monkeypatch):
    def fake(errors):
        def check(dem, red, spot_s):
            return {"dem": {"first_contact": 0.8}, "relative_error": {"delta_omega": -0.5},
                    "after_touch": None if errors is None else {"relative_error": errors},
                    "after_touch_why": "touched late"}
        return check

    monkeypatch.setattr("studio.studies.detumble_analysis.read_detumble", lambda h5: {})
    ok = {"status": "completed", "h5": "x.h5"}
    cases = [({"delta_omega": -0.09, "peak_force": 0.14}, True, ""),
             ({"delta_omega": 0.11, "peak_force": 0.0}, False, "delta_omega off by +11.0 %"),
             ({"delta_omega": 0.0, "peak_force": -0.16}, False, "peak_force off by -16.0 %"),
             (None, False, "touched late")]
    for errors, resolved, words in cases:
        monkeypatch.setattr(detumble, "spot_check", fake(errors))
        r = reduced.spot_check_report([ok], [ok], ["s1"], 5.0)
        assert r["resolved"] is resolved and words in r["why"]
    failed = reduced.spot_check_report([ok], [{"status": "failed", "error": "boom"}],
                                       ["s1"], 5.0)
    assert not failed["resolved"] and "DEM spot check failed (boom)" in failed["why"]


# a reduce protocol small enough for a test (2 x 2 bristles of 3 nodes), as
# test_detumble_onecmd's
TINY = {"depths": [30.0], "rates": [20.0, 40.0], "slide_depths": [15.0], "speeds": [100.0],
        "check_depth": 0.0, "impact_speeds": [100.0]}


@pytest.mark.slow   # two designs' law fits (8 DEM runs each), 2 x 3 s reduced runs, 1.5 s DEM
def test_the_search_fits_a_law_per_design_and_a_rerun_reuses_everything(tmp_path,
                                                                         monkeypatch, capsys):
    import engine
    from studio.cli.main import main
    from studio.studies.optimise import search as search_mod

    tiny = json.loads(json.dumps(Problem.from_options(_options()).base))
    tiny["brushes"][0].update(rows=2, columns=2, n_nodes=3)
    scene_file = tmp_path / "tiny_upper_stage.json"
    scene_file.write_text(json.dumps(tiny))
    made = search_mod.Problem.from_options.__func__

    def with_tiny_protocol(cls, options):
        problem = made(cls, options)
        problem.protocol = TINY
        return problem

    monkeypatch.setattr(search_mod.Problem, "from_options", classmethod(with_tiny_protocol))
    out = tmp_path / "search"
    argv = ["study", "optimise", "--fidelity", "reduced", "--preset", str(scene_file),
            "--variables", f"{LENGTH}=0.12:0.2", "--spins-deg", "2", "--trials", "2",
            "--duration-s", "3", "--spot-check-s", "1.5", "--objectives",
            "abs_spin_left:worst,chaser_delta_v:mean", "--workers", "1", "--no-progress",
            "-o", str(out)]
    assert main(argv) == 0
    rows = list(csv.DictReader(open(out / "trials.csv")))
    assert len(rows) == 2 and rows[0]["size"] == "1.0" and rows[0]["law_reused"] == "False"
    for row in rows:
        law = json.loads((out / "laws" / row["design_key"] / "law.json").read_text())
        # the design's own brush: its bristle length is the trial's
        assert law["brush"]["bristle_length"] == pytest.approx(float(row[LENGTH]))
        run = json.loads((out / "runs" / f"{row['design_key']}_size1_spin2.json").read_text())
        with engine.open_result(run["h5"]) as res:
            inline = json.loads(res.scene_json)
        (patch,) = [p for b in inline["bodies"] for p in (b.get("patches") or [])]
        assert patch["law"]["fit_digest"] == law["fit_digest"]
        assert not inline["brushes"]                     # the brush ran as its law
        assert float(row["spin_left"]) < 1.0             # and slowed the target
    report = (out / "report.md").read_text()
    assert "## DEM spot check" in report and "size1_spin2" in report
    spot = json.loads((out / "spot_check.json").read_text())
    assert spot["rows"][0]["after_touch"] is not None
    engine.load_scene(out / "best.json")                 # a valid scene: the reduced brush
    capsys.readouterr()
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("laws/*/law.json")}
    # extend the search by nothing: the same command again refits no law and reruns no run
    assert main(argv) == 0
    assert {p: p.stat().st_mtime_ns for p in out.glob("laws/*/law.json")} == stamps
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs_run"] == 0
