"""Newcomer friction and small CLI items of issue 28 (items 9 and 10): ``run`` and
``validate`` take preset names like ``study`` does; "1 bristle" in the singular; no
"0 node-steps/s" for a scene without bristles; a scene whose run would take enormously many
steps validates with a warning about its cost; no "(issue N)" in help lines."""
from __future__ import annotations

import re

from studio.cli.main import build_parser, main
from studio.cli.run_console import summary_table


def test_run_and_validate_take_a_preset_name(tmp_path, capsys):
    # bug caught: `run wedge_30` looked for a file named wedge_30 while `study` took names
    assert main(["validate", "demo", "--estimate-only"]) == 0
    assert main(["run", "demo", "-o", str(tmp_path / "d.h5"), "-q", "--until", "1e-4"]) == 0
    assert (tmp_path / "d.h5").is_file()


def test_one_bristle_is_singular(tiny_scene, write_scene, capsys):
    scene = tiny_scene()
    scene["brushes"][0].update(rows=1, columns=1)
    assert main(["validate", str(write_scene(scene))]) == 0
    out = capsys.readouterr().out
    assert "1 bristle," in out and "1 bristles" not in out


def test_a_stiff_scene_validates_with_a_warning_about_its_cost(tiny_scene, write_scene,
                                                              capsys):
    # bug caught: E = 2e14 Pa gave 8e8 steps and validated "OK" without a word about it
    scene = tiny_scene(duration=1.0)
    scene["materials"]["silicone"]["youngs_modulus"] = 2e14
    assert main(["validate", str(write_scene(scene))]) == 0
    out = capsys.readouterr().out
    assert re.search(r"warning: \S+ steps .* would take very long", out), out
    assert main(["validate", str(write_scene(tiny_scene()))]) == 0
    assert "would take very long" not in capsys.readouterr().out  # not for a normal scene


def test_no_node_steps_for_a_scene_without_bristles():
    summary = {"status": "completed", "steps": 100, "steps_per_s": 5e4,
               "node_steps_per_s": 0.0, "n_nodes": 0}
    text = summary_table(summary)
    assert "0 node-steps/s" not in text and "steps/s (no bristles)" in text


def test_help_lines_name_no_issue_numbers():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    helps = {c.dest: c.help or "" for c in sub._choices_actions}
    bad = {k: v for k, v in helps.items() if re.search(r"\(issue \d+", v)}
    assert not bad, bad
