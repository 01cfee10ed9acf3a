"""The cost line before Start, the dt warning and the colour-by note (issue 14, defects 4-6),
without a browser."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import pytest

from studio import presets
from studio.web.panels import run_cost as rc
from studio.plots.result_frames import color_note


def _scene(name, **run):
    data = json.loads(presets.preset_path(name).read_text())
    data["run"].update(run)
    return data


def test_wall_time_is_node_steps_over_the_rate():
    scene = _scene("spin_cube_20")
    cost = rc.run_cost(scene).cost
    n_nodes = 17 * 5 * 6                      # the preset's brush, counted by hand
    steps = math.ceil(3.0 / cost.dt)          # duration / dt
    assert cost.n_nodes == n_nodes and cost.steps == steps
    out = rc.run_cost(scene, measured=(2.0e6, "abc"))
    assert out.wall_s == pytest.approx(n_nodes * steps / 2.0e6, rel=1e-12)
    assert "measured by run `abc`" in rc.cost_line(out)
    assert rc.run_cost(scene).rate == rc.DEFAULT_NODE_STEPS_PER_S


def test_the_cost_line_names_dt_its_limit_steps_nodes_wall_and_file():
    out = rc.run_cost(_scene("spin_cube_20"))
    line = rc.cost_line(out)
    for part in (f"{out.cost.dt * 1e6:.4g} µs", "limited by the bristles of brush 'brush'",
                 f"{out.cost.steps:,.0f}** steps", "**510** nodes", "wall **~",
                 "result file **~", "1,501 frames"):
        assert part in line, part


def test_a_long_run_asks_for_confirmation_and_a_short_one_does_not():
    # wedge_60: 8.4e5 steps x 680 nodes = 5.7e8 node-steps, over 5 min at any rate < 1.9e6/s
    wedge = rc.run_cost(_scene("wedge_60"))
    assert wedge.wall_s > rc.CONFIRM_ABOVE_S and wedge.needs_confirmation
    assert "Start asks to confirm" in rc.cost_line(wedge)
    short = rc.run_cost(_scene("wedge_60", duration=0.05))
    assert not short.needs_confirmation and "confirm" not in rc.cost_line(short)


def test_dt_above_the_stability_limit_warns_with_the_limit():
    auto = rc.run_cost(_scene("spin_cube_40"))
    bound = auto.cost.dt_bound
    assert rc.dt_warning(auto) == ""                         # automatic dt: no warning
    assert rc.dt_warning(rc.run_cost(_scene("spin_cube_40", dt=0.9 * bound))) == ""
    over = rc.run_cost(_scene("spin_cube_40", dt=1e-3))     # the 1000 us
    text = rc.dt_warning(over)
    assert "1000 µs" in text and f"stability limit {bound * 1e6:.4g} µs" in text
    assert "brush 'brush'" in text
    assert "above the stability limit" in rc.cost_line(over)


def test_the_measured_rate_is_the_newest_completed_runs():
    def job(i, status, rate):
        return SimpleNamespace(id=i, status=status,
                               summary={} if rate is None else {"node_steps_per_s": rate})

    jobs = SimpleNamespace(list=lambda limit, kind: [
        job("new", "failed", 9e9), job("mid", "completed", None),
        job("old", "completed", 1.5e6), job("older", "completed", 3e6)])
    assert rc.measured_rate(jobs) == (1.5e6, "old")
    assert rc.measured_rate(None) is None


def test_colour_by_says_which_channel_is_missing():
    run = SimpleNamespace(has_nodes=False, has_bending=False, brush_names=["brush"])
    assert "channel `nodes`" in color_note(run, "deflection")
    assert "record nodes" in color_note(run, "bending moment")
    assert color_note(SimpleNamespace(has_nodes=False, has_bending=False, brush_names=[]),
                      "deflection") == ""          # no bristles, nothing to say
    nodes_only = SimpleNamespace(has_nodes=True, has_bending=False, brush_names=["brush"])
    assert "channel `bending`" in color_note(nodes_only, "bending moment")
    assert color_note(nodes_only, "deflection") == ""
    assert color_note(nodes_only, "none") == ""
