"""The Studies tab's helpers: form values -> study options (and on to the study's command
line), the convergence table as markdown and its log-log plot, PNG plots as image arrays."""
from __future__ import annotations

import math

import numpy as np
import pytest

from studio.jobs import StudyOptionError, study_argv
from studio.panels.studies_tab import (FORMS, FormError, convergence_figure, convergence_markdown,
                               form_options, png_array)


def _defaults(study: str) -> dict:
    return {name: default for name, _kind, default, _label in FORMS[study]}


def test_every_form_default_is_a_valid_study_command_line():
    for study in FORMS:
        options = form_options(study, _defaults(study))
        argv = study_argv(study, options)  # the study's own parser accepts it
        assert argv, study
    assert set(FORMS) >= {"wedge", "spin", "refinement", "convergence"}


def test_form_values_map_to_options():
    values = dict(_defaults("wedge"), depth_mm=3.0, nodes=4.0, no_unload=True)
    assert form_options("wedge", values) == {"preset": "wedge_60", "depth_mm": 3.0,
                                             "nodes": 4, "no_unload": True}
    # empty text fields and false flags are left out; "other options" JSON overrides
    conv = dict(_defaults("convergence"), dt_factor="  ")
    opts = form_options("convergence", conv, '{"reference": "finest", "ladder": "n_nodes=3,5"}')
    assert "dt_factor" not in opts and opts["reference"] == "finest"
    assert opts["ladder"] == "n_nodes=3,5" and opts["scene"] == "rod_weight_static"
    assert "no_unload" not in form_options("wedge", _defaults("wedge"))


@pytest.mark.parametrize("study, values, extra, text", [
    ("wedge", {"nodes": 3.5}, "", "whole number"),
    ("wedge", {"depth_mm": "deep"}, "", "not a number"),
    ("wedge", {"depth_mm": math.inf}, "", "finite"),
    ("wedge", {}, "{not json", "not JSON"),
    ("wedge", {}, "[1, 2]", "JSON object"),
    ("nope", {}, "", "unknown study"),
])
def test_bad_form_values_are_refused(study, values, extra, text):
    with pytest.raises(FormError, match=text):
        form_options(study, values, extra)


def test_options_the_server_sets_are_refused_from_the_form_too():
    opts = form_options("wedge", _defaults("wedge"), '{"output": "/tmp/x"}')
    with pytest.raises(StudyOptionError, match="output folder is the job's own"):
        study_argv("wedge", opts)


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
