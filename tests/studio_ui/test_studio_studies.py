"""The Studies tab's helpers: form values -> study options (and on to the study's command
line), the convergence table as markdown and its log-log plot, PNG plots as image arrays."""
from __future__ import annotations

import math

import numpy as np
import pytest

from studio.service.jobs import StudyOptionError, make_options
from studio.web.panels.studies_tab import (CURRENT_DESIGN, DEFAULT_CHOICE, STUDY_NAMES, FormError,
                                       _initial, convergence_figure, convergence_markdown,
                                       form_options, form_spec, png_array)


def _defaults(study: str) -> dict:
    return {f["name"]: _initial(f) for f in form_spec(study)}


def test_every_form_default_is_the_study_models_default():
    """The form is generated from the model: untouched, it sends nothing the model would not
    default to (no second set of defaults, issue 23), so the scene's resolution and depth
    stay the scene's (issue 29 item 6)."""
    for study in STUDY_NAMES:
        options = form_options(study, _defaults(study))
        extra = {"quantity": "tip_deflection", "ladder": "n_nodes=3,5",
                 "scene": "rod_weight_static"} if study == "convergence" else {}
        assert options == {}, (study, options)
        typed = make_options(study, {**options, **extra})
        model = type(typed)
        for f in form_spec(study):
            if f["name"] not in extra:
                assert getattr(typed, f["name"]) == model.model_fields[f["name"]].get_default(
                    call_default_factory=True), (study, f["name"])
    assert "nodes" not in form_options("wedge", dict(_defaults("wedge"), nodes="  "))


def test_form_values_map_to_options():
    values = dict(_defaults("wedge"), depth_mm="3", nodes="4", no_unload=True,
                  preset="wedge_60")
    assert form_options("wedge", values) == {"preset": ["wedge_60"], "depth_mm": "3",
                                             "nodes": "4", "no_unload": True}
    typed = make_options("wedge", form_options("wedge", values))
    assert typed.depth_mm == 3.0 and typed.nodes == 4 and typed.no_unload
    # empty text fields and false flags are left out; "other options" JSON overrides
    conv = dict(_defaults("convergence"), dt_factor="  ")
    opts = form_options("convergence", conv, '{"reference": "finest", "ladder": "n_nodes=3,5"}')
    assert "dt_factor" not in opts and opts["reference"] == "finest"
    assert opts["ladder"] == "n_nodes=3,5"
    assert "no_unload" not in form_options("wedge", _defaults("wedge"))
    assert form_options("wedge", {"preset": DEFAULT_CHOICE}) == {}


def test_form_labels_carry_the_models_units():
    labels = {f["name"]: f["label"] for f in form_spec("wedge")}
    assert labels["depth_mm"] == "depth [mm]" and labels["preset"] == "preset"
    # a scene option that takes any design starts the form on the current design
    assert {f["name"] for f in form_spec("wedge") if f["design"]} == {"preset"}
    assert CURRENT_DESIGN == "(current design)"


@pytest.mark.parametrize("study, values, extra, text", [
    ("wedge", {}, "{not json", "not JSON"),
    ("wedge", {}, "[1, 2]", "JSON object"),
    ("wedge", {"bogus": 1}, "", "not an option"),
    ("nope", {}, "", "unknown study"),
])
def test_bad_form_values_are_refused(study, values, extra, text):
    with pytest.raises(FormError, match=text):
        form_options(study, values, extra)


@pytest.mark.parametrize("values, where, text", [
    ({"nodes": "3.5"}, "nodes", "valid integer"),
    ({"depth_mm": "deep"}, "depth_mm", "valid number"),
    ({"depth_mm": "-1"}, "depth_mm", "greater than 0"),
    ({"depth_mm": math.inf}, "depth_mm", "finite"),
])
def test_bad_form_values_are_refused_by_the_model(values, where, text):
    with pytest.raises(StudyOptionError) as exc:
        make_options("wedge", form_options("wedge", values))
    assert exc.value.problems[0][0] == where and text in str(exc.value)


def test_options_the_server_sets_are_refused_from_the_form_too():
    opts = form_options("wedge", _defaults("wedge"), '{"output": "/tmp/x"}')
    with pytest.raises(StudyOptionError, match="output folder is the job's own"):
        make_options("wedge", opts)


def _table():
    from studio.studies.convergence import ConvergenceTable

    rows = [{"level": 0, "n_nodes": 3, "dt": 1e-5, "dt_factor": 1.0, "quantity": 0.9,
             "error": -0.1, "wall_s": 1.0, "status": "completed"},
            {"level": 1, "n_nodes": 5, "dt": 5e-6, "dt_factor": 1.0, "quantity": 0.99,
             "error": -0.01, "wall_s": 4.0, "status": "completed"},
            {"level": 2, "n_nodes": 9, "dt": None, "dt_factor": 1.0, "quantity": None,
             "error": None, "wall_s": None, "status": "failed"}]
    return ConvergenceTable(quantity="tip_deflection", unit="m", scene_name="rod",
                            reference=1.0, reference_kind="analytic", reference_note="elastica",
                            resolution="h", observed_orders=[2.0], fitted_order=2.0,
                            richardson=None, richardson_order=None, rows=rows,
                            cheapest={"0.01": None, "0.05": rows[1]})


def test_convergence_table_markdown_has_every_level():
    md = convergence_markdown(_table())
    lines = [ln for ln in md.splitlines() if ln.startswith("| ")]
    assert len(lines) == 1 + 3  # header + one row per level
    # one short line per level (readable in the side panel): dt in µs, the error in %
    assert "| 1 | 5 | 5 | 0.99 | -1 | 4.0 | ok |" in md
    assert "| 2 | 9 | auto | – | – | – | failed |" in md
    assert "reference: 1 m (analytic: elastica)" in md
    assert "cheapest within 5 %: level 1 in 4.00 s" in md


def test_convergence_figure_is_log_log_error_against_wall_time():
    fig = convergence_figure(_table())
    assert fig.layout.xaxis.type == "log" and fig.layout.yaxis.type == "log"
    (trace,) = fig.data
    # the failed level has no error: left out; errors as magnitudes
    assert list(trace.x) == [1.0, 4.0] and list(trace.y) == [0.1, 0.01]


def test_png_array_reads_a_plot(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4, 3), dpi=100)
    ax.plot([0, 1], [0, 1])
    fig.savefig(tmp_path / "p.png")
    plt.close(fig)
    img = png_array(tmp_path / "p.png")
    assert img.dtype == np.uint8 and img.shape == (300, 400, 3)
    small = png_array(tmp_path / "p.png", max_side=200)
    assert max(small.shape[:2]) == 200


def test_convergence_figure_leaves_room_for_the_end_labels():
    fig = convergence_figure(_table())
    lo, hi = fig.layout.xaxis.range  # log10 of wall time: 1 s and 4 s with a quarter decade
    assert lo == pytest.approx(-0.25) and hi == pytest.approx(math.log10(4.0) + 0.25)
