"""Interactive charts and time left of studies in the Studies tab (studio.plots.study_charts,
issue 14 item 10), and studies on a design the studio stored (``design:<id>``)."""
from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from studio.plots import study_charts as sc
from studio.service.jobs import StudyOptionError, make_options


def _write(path, text):
    path.write_text(text)
    return path.name


def test_wedge_force_depth_chart_in_millimetres_by_phase(tmp_path):
    name = _write(tmp_path / "force_depth.csv",
                  "depth_m,force_N,phase\n0.001,0.01,load\n0.002,0.03,load\n"
                  "0.001,0.005,unload\n")
    ((file, fig),) = sc.study_charts("wedge", tmp_path, [name, "force_depth.png"])
    assert file == "force_depth.csv"
    load, unload = fig.data
    assert list(load.x) == [1.0, 2.0] and list(load.y) == [0.01, 0.03]  # m -> mm
    assert unload.name == "unload" and unload.line.dash == "dot"
    assert fig.layout.xaxis.title.text == "depth [mm]"
    assert fig.layout.yaxis.title.text == "force on the wedge [N]"


def test_wedge_chart_one_line_per_angle(tmp_path):
    name = _write(tmp_path / "force_depth.csv",
                  "depth_m,force_N,phase,angle_deg,run_id\n"
                  "0.001,0.01,load,30,wedge_30\n0.001,0.02,load,60,wedge_60\n")
    ((_, fig),) = sc.study_charts("wedge", tmp_path, [name])
    assert [t.name for t in fig.data] == ["wedge_30 load", "wedge_60 load"]


def test_spin_chart_in_degrees_per_second(tmp_path):
    name = _write(tmp_path / "omega.csv", "run_id,time,omega,contact_force\n"
                                          f"cube20,0,{math.pi},0\ncube20,0.1,0,1\n")
    ((_, fig),) = sc.study_charts("spin", tmp_path, [name])
    assert list(fig.data[0].y) == pytest.approx([180.0, 0.0])  # rad/s -> deg/s, exact


def test_refinement_chart_has_wall_time_on_a_second_axis(tmp_path):
    name = _write(tmp_path / "refinement.csv", "nodes_per_bristle,force_N,wall_s\n"
                                               "3,0.1,2.0\n4,0.12,3.5\n")
    ((_, fig),) = sc.study_charts("refinement", tmp_path, [name])
    force, wall = fig.data
    assert list(force.y) == [0.1, 0.12] and list(wall.y) == [2.0, 3.5]
    assert wall.yaxis == "y2"


def test_no_chart_for_a_study_without_one_or_a_missing_file(tmp_path):
    assert sc.study_charts("rod", tmp_path, ["tip_trajectories.png"]) == []
    assert sc.study_charts("wedge", tmp_path, ["wedge_records.csv"]) == []


def test_a_broken_csv_gives_a_message_not_a_crash(tmp_path):
    (tmp_path / "omega.csv").write_bytes(b"\xff\xfe\x00bad")
    ((_, text),) = sc.study_charts("spin", tmp_path, ["omega.csv"])
    assert isinstance(text, str) and text.startswith("cannot chart omega.csv")


def _job(**kw):
    base = dict(status="running", eta_s=None, progress=0.25, started=100.0)
    return SimpleNamespace(**dict(base, **kw))


def test_study_eta_from_progress_and_elapsed_time():
    # a quarter done after 30 s: three quarters left take 90 s
    assert sc.study_eta(_job(), now=130.0) == pytest.approx(90.0)
    assert sc.study_eta(_job(eta_s=12.0), now=130.0) == 12.0  # the job's own estimate
    assert sc.study_eta(_job(progress=0.0), now=130.0) is None
    assert sc.study_eta(_job(status="completed"), now=130.0) is None


def test_a_stored_design_is_a_study_scene(tmp_path):
    (tmp_path / "abc123.json").write_text("{}")
    opts = make_options("wedge", {"preset": "design:abc123"}, designs_dir=tmp_path)
    assert opts.preset == [str(tmp_path / "abc123.json")]
    for bad in ("design:../abc123", "design:nothere", "design:"):
        with pytest.raises(StudyOptionError,
                           match="no stored design"):
            make_options("wedge", {"preset": bad}, designs_dir=tmp_path)
    with pytest.raises(StudyOptionError, match="not available"):
        make_options("wedge", {"preset": "design:abc123"})  # no designs folder: refused
