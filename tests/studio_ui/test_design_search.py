"""The Studies tab's design search without a browser (studio.web.design_search): the design's
fields and their bounds, the study's variable text in SI, a search's progress read from an
Optuna journal, its charts, and a trial's design as a scene."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from studio.web import design_search as ds
from studio.studies.optimise.variables import get_path, parse_variable

ROOT = Path(__file__).resolve().parents[2]


def _demo() -> dict:
    return json.loads((ROOT / "studio" / "data" / "demo_scene.json").read_text())


def test_fields_of_the_design_with_values_in_ui_units():
    scene = _demo()
    fields = {f.key: f for f in ds.search_fields(scene)}
    r = fields["root_radius"]
    # the UI shows mm; the study's path reaches the scene's metres
    assert r.unit == "mm" and r.title == "root radius [mm]"
    assert r.value == pytest.approx(get_path(scene, r.path) * 1e3)
    assert fields["rows"].integer and fields["rows"].value == scene["brushes"][0]["rows"]
    # a material field follows the brush to its material (not the body's)
    assert fields["youngs_modulus"].path == "brushes.0.material.youngs_modulus"
    assert "bending_stiffness" in fields and "n_nodes" not in fields


def test_default_bounds_bracket_the_value_and_convert_to_si():
    scene = _demo()
    fields = {f.key: f for f in ds.search_fields(scene)}
    r = fields["root_radius"]
    low, high, log = ds.default_bounds(r)
    assert low == pytest.approx(r.value / 2, rel=1e-3) and high == pytest.approx(
        2 * r.value, rel=1e-3) and not log
    text = ds.variable_text(r, low, high, log)
    v = parse_variable(text, scene)  # the study's own parser takes it
    # mm -> m: a factor 1000 slip would put the bounds a thousand times off the value
    assert v.low < get_path(scene, r.path) < v.high
    assert v.high == pytest.approx(2 * get_path(scene, r.path), rel=1e-3)
    e = fields["youngs_modulus"]
    assert ds.default_bounds(e)[2]  # spans decades: log
    v = parse_variable(ds.variable_text(e, *ds.default_bounds(e)), scene)
    assert v.log and v.low < get_path(scene, e.path) < v.high  # MPa -> Pa
    rows = fields["rows"]
    v = parse_variable(ds.variable_text(rows, *ds.default_bounds(rows)), scene)
    assert v.integer
    with pytest.raises(ValueError, match="below the high"):
        ds.variable_text(r, 2.0, 1.0)
    with pytest.raises(ValueError, match="whole-number"):
        ds.variable_text(rows, 1.5, 4)
    p = fields["poisson_ratio"]
    assert ds.default_bounds(p)[1] < 0.5  # never past the field's own limit


def _journal(tmp_path: Path, values: list, objectives=("abs_spin_left:worst",),
             constraints=None) -> Path:
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    from studio.studies.optimise.search import STUDY_NAME

    storage = JournalStorage(JournalFileBackend(str(tmp_path / "optuna.journal")))
    study = optuna.create_study(storage=storage, study_name=STUDY_NAME,
                                directions=["minimize"] * len(objectives))
    study.set_user_attr("objectives", list(objectives))
    dist = optuna.distributions.FloatDistribution(1e-4, 1e-3)
    for k, v in enumerate(values):
        t = study.ask({"brushes.0.root_radius": dist})
        if constraints is not None:
            t.set_user_attr("constraints", [constraints[k]])
        study.tell(t, v)
    return tmp_path


def test_progress_best_so_far_and_chart(tmp_path):
    folder = _journal(tmp_path, [3.0, 1.0, 2.0, 0.5], constraints=[0, 0, 0, 1.0])
    prog = ds.read_progress(folder)
    assert len(prog.done) == 4
    best = prog.best()
    # trial 3 has the lowest value but breaks its constraint: trial 1 is the best
    assert best.number == 1 and best.values == [1.0]
    assert prog.best_so_far() == [(0, 3.0), (1, 1.0), (2, 1.0), (3, 1.0)]
    text = ds.progress_text(prog, 20)
    assert "trials done 4 of 20" in text and "trial 1" in text and "= 1" in text
    (title, fig), = ds.search_figures(prog)
    names = [d.name for d in fig.data]
    assert names == ["trial (feasible)", "trial (infeasible)", "best so far"]
    assert list(fig.data[2].y) == [3.0, 1.0, 1.0, 1.0]
    assert ds.trial_of(ds.trial_label(best, prog.objectives)) == 1
    assert ds.read_progress(tmp_path / "none") is None


def test_pareto_front_of_two_objectives(tmp_path):
    folder = _journal(tmp_path, [[1.0, 3.0], [2.0, 2.0], [3.0, 3.0], [3.0, 1.0]],
                      objectives=("abs_spin_left:worst", "peak_force:worst"))
    prog = ds.read_progress(folder)
    assert [t.number for t in prog.pareto()] == [0, 1, 3]  # trial 2 is dominated by 1
    figs = ds.search_figures(prog)
    assert [t for t, _ in figs] == ["objective per trial", "Pareto front"]
    front = figs[1][1].data[1]
    assert list(front.x) == [1.0, 2.0, 3.0]


def test_trial_scene_is_the_start_design_with_the_trial_values(tmp_path):
    path = tmp_path / "design.json"
    scene = _demo()
    scene["brushes"] = scene["brushes"][:1]
    path.write_text(json.dumps(scene))
    out = ds.trial_scene({"preset": str(path)}, {"brushes.0.root_radius": 4e-4,
                                                 "brushes.0.rows": 3}, "demo_trial2")
    assert out["brushes"][0]["root_radius"] == pytest.approx(4e-4)
    assert out["brushes"][0]["rows"] == 3 and isinstance(out["brushes"][0]["rows"], int)
    assert out["name"] == "demo_trial2"
    # the rest of the design is the design's (not the search's spin rig)
    assert out["bodies"] == json.loads(json.dumps(out["bodies"]))
    assert [b["name"] for b in out["bodies"]] == [b["name"] for b in scene["bodies"]]


def test_form_sends_a_default_on_flag_unticked():
    """optimise's refine is on by default: unticked in the form it must reach the study as
    False (the form sent only ticked flags, so the winner was always re-run)."""
    from studio.web.panels.studies_tab import form_options

    assert form_options("optimise", {"refine": False}) == {"refine": False}
    assert form_options("optimise", {"refine": True}) == {}


def test_number_boxes_keep_three_significant_digits():
    """viser takes a box's decimals from its step: 0.4 s gave one decimal (0.02 -> 0.0)."""
    from studio.web.panels.studies_tab import fine_step

    assert fine_step(0.4) == pytest.approx(1e-4)
    assert fine_step(0.5, 2.0) == pytest.approx(1e-3)
    assert fine_step(0.0) == pytest.approx(1e-3)
