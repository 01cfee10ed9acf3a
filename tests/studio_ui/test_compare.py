"""Runs side by side (issue 29, item 7): labels say what differs, the table's figures are
the curves' own peaks, a measured CSV lands on the plot of its x."""
from __future__ import annotations

import numpy as np
import pytest

from studio.plots import compare as cmp


def _run(job, rows, radius, force_z):
    t = np.linspace(0.0, 0.1, 6)
    scene = {"name": "same name", "brushes": [{"rows": rows, "root_radius": radius,
                                                "columns": 5}],
             "run": {"duration": 0.1}}
    return cmp.RunCurves(job, "same name", "completed", scene, t,
                         root_force=np.stack([0 * t, 0 * t, force_z * t], 1),
                         omega={"disc": np.tile([0.0, 0.0, 0.5], (6, 1))})


def test_runs_are_labelled_by_what_differs():
    a, b = _run("a1", 17, 0.001, 10.0), _run("b2", 7, 0.001, 20.0)
    cmp.label_runs([a, b])
    # only the rows differ: the label names them (not the shared name, columns, radius)
    assert a.label == "rows = 17 · a1" and b.label == "rows = 7 · b2"
    c = _run("c3", 17, 0.0008, 10.0)
    cmp.label_runs([a, c])
    assert a.label == "root_radius = 0.001 · a1" and c.label == "root_radius = 0.0008 · c3"
    same = _run("d4", 17, 0.001, 10.0)
    cmp.label_runs([a, same])
    assert a.label == "same name · a1"  # nothing differs: name and job


def test_headline_figures_are_the_curves_peaks():
    a = _run("a1", 17, 0.001, 10.0)
    cmp.label_runs([a])
    row = cmp.headline(a)
    # |F| = 10 N/s x t, peak at t = 0.1 s: 1 N; |ω| = 0.5 rad/s = 28.648 deg/s
    assert row["peak_root_force_N"] == pytest.approx(1.0, rel=1e-12)
    assert row["final_omega_deg_s"] == pytest.approx(np.degrees(0.5), rel=1e-12)
    assert row["max_depth_mm"] is None and row["frames"] == 6
    md = cmp.table_markdown([row])
    assert md.splitlines()[0].count("|") == 7  # 6 columns (no "|" inside a header)
    assert "max depth" not in md  # a column no run has is left out


def test_measured_csv_goes_on_the_plot_of_its_x():
    m = cmp.parse_measured_csv("bench.csv", "depth [mm],force [N]\n0,0\n0.5,0.2\n1.0,0.5\n")
    assert m.x_kind == "depth" and list(m.y) == [0.0, 0.2, 0.5]
    a = _run("a1", 17, 0.001, 10.0)
    a.depth = ("wedge", np.linspace(0.0, 0.001, 6))
    cmp.label_runs([a])
    figs = cmp.compare_figures([a], m)
    names = [d.name for d in figs["root |F| [N] against depth [mm]"].data]
    assert names == [a.label, "measured: bench.csv"]
    with pytest.raises(ValueError, match="first column"):
        cmp.parse_measured_csv("x.csv", "force,time\n1,2\n3,4\n")
    with pytest.raises(ValueError, match="two numbers"):
        cmp.parse_measured_csv("x.csv", "time [s],force [N]\n0,a\n1,2\n")
