"""The same names for the same things across every study command's parser (issue 16).

A user who learnt ``--nodes`` on ``study wedge`` must not have to guess ``--n-nodes`` on
``study spin``; the HTTP API and the studio pass options by these names too.
"""
from __future__ import annotations

import argparse
import json

import pytest

from studio.cli.main import build_parser, main


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


TOP = _subparsers(build_parser())
STUDIES = _subparsers(TOP["study"])
# every command that runs many simulations through the studies' Dask layer
RUNNERS = {**{f"study {name}": p for name, p in STUDIES.items()},
           "convergence": TOP["convergence"]}
# the commands whose runs are one scene's (a file or a preset name) changed by the study;
# rod and spin run the seed's experiments from their own presets, so their --preset chooses
# among those (as --cases and --cubes do)
ONE_SCENE = ("study wedge", "study refinement", "study sensitivity", "study montecarlo",
             "convergence")
OWN_PRESETS = {"study rod": ("rod_weight_release", "rod_tip_impulse", "rod_root_impulse"),
               "study spin": ("spin_cube_20", "spin_cube_40", "spin_cube_60")}


def _flags(parser: argparse.ArgumentParser) -> set[str]:
    return {s for a in parser._actions for s in a.option_strings}


def test_every_study_is_checked():
    assert set(STUDIES) >= {"wedge", "refinement", "sensitivity", "montecarlo", "rod", "spin"}


@pytest.mark.parametrize("name", sorted(RUNNERS))
def test_execution_options_have_one_name_everywhere(name):
    flags = _flags(RUNNERS[name])
    missing = {"-o", "--output", "--workers", "--scheduler", "--no-progress"} - flags
    assert not missing, f"{name} lacks {sorted(missing)}"


def _parse(name: str, *argv: str) -> argparse.Namespace:
    return RUNNERS[name].parse_args([*argv, "-o", "out"] + (
        ["--quantity", "wedge_force@1mm"] if name == "convergence" else []))


@pytest.mark.parametrize("name", sorted(RUNNERS))
def test_nodes_per_bristle_is_nodes(name):
    """--nodes N sets the nodes per bristle of every run (convergence: of every level of a
    loading ladder; its resolution ladder is --ladder n_nodes=...); rod and spin still take
    their old spelling --n-nodes, as a deprecated alias with the same destination."""
    assert "--nodes" in _flags(RUNNERS[name]), f"{name}: nodes per bristle is --nodes"
    args = vars(_parse(name, "--nodes", "7"))
    assert "7" in args.values()  # the text typed; the study's model makes it an int
    if "--n-nodes" in _flags(RUNNERS[name]):
        assert vars(_parse(name, "--n-nodes", "7")) == args


@pytest.mark.parametrize("name", sorted(RUNNERS))
def test_the_scene_is_preset(name):
    """--preset NAME lands in ``preset`` everywhere: a list where the study runs several
    scenes (repeat it), the one name where it runs one (convergence)."""
    assert "--preset" in _flags(RUNNERS[name])
    (action,) = [a for a in RUNNERS[name]._actions if "--preset" in a.option_strings]
    assert action.dest == "preset"
    preset = _parse(name, "--preset", "wedge_30").preset
    if action.nargs is None and not isinstance(action, argparse._StoreAction):  # a list
        assert preset == ["wedge_30"]
        assert _parse(name, "--preset", "a", "--preset", "b").preset == ["a", "b"]
    else:
        assert preset == "wedge_30"


@pytest.mark.parametrize("name", sorted(OWN_PRESETS))
def test_rod_and_spin_name_their_presets(name):
    help_text = RUNNERS[name].format_help()
    for preset in OWN_PRESETS[name]:
        assert preset in help_text


@pytest.mark.parametrize("name, other", [("study rod", ["--cases", "tip_impulse"]),
                                         ("study spin", ["--cubes", "20"])])
def test_rod_and_spin_refuse_foreign_presets_and_double_choices(name, other, tmp_path,
                                                                capsys):
    """A scene file or another study's preset is refused with the presets it can run; --preset
    with --cases/--cubes (both choose the runs) is refused, before anything runs."""
    cmd = name.split()
    assert main([*cmd, "-o", str(tmp_path / "a"), "--preset", "wedge_60"]) == 2
    assert OWN_PRESETS[name][0] in capsys.readouterr().err
    assert main([*cmd, "-o", str(tmp_path / "b"), "--preset", OWN_PRESETS[name][0],
                 *other]) == 2
    assert "both choose the runs" in capsys.readouterr().err
    assert not (tmp_path / "a" / "runs").exists() and not (tmp_path / "b" / "runs").exists()


@pytest.mark.parametrize("name", sorted(OWN_PRESETS))
def test_rod_and_spin_take_their_presets_by_name_or_file(name):
    """The HTTP API passes a preset as its file (studio.studies.registry): the same choice."""
    from studio.presets import preset_path
    from studio.studies.preset_option import chosen

    own = {p: i for i, p in enumerate(OWN_PRESETS[name])}
    last = OWN_PRESETS[name][-1]
    assert chosen(name, [last, str(preset_path(OWN_PRESETS[name][0]))], own, "", "", "") \
        == [len(own) - 1, 0]


@pytest.mark.parametrize("name", sorted(RUNNERS))
def test_the_http_api_takes_the_same_names(name):
    """A job's options dict uses the command line's names: ``nodes`` (rod and spin keep the
    destination ``n_nodes`` of their older spelling, still accepted) and ``preset``."""
    from studio.studies.registry import make_options

    study = name.split()[-1]
    preset = OWN_PRESETS.get(name, ("wedge_60",))[0]
    extra = {"quantity": "wedge_force@1mm", "ladder": "qs_increments=1,2"} \
        if study == "convergence" else {}
    opts = make_options(study, {"nodes": 5, "preset": preset, **extra})
    nodes = "n_nodes" if name in OWN_PRESETS or study in ("detumble", "reduce") else "nodes"
    assert getattr(opts, nodes) == 5
    presets = opts.preset if isinstance(opts.preset, list) else [opts.preset]
    assert presets[0].endswith(f"{preset}.json")
    if name in OWN_PRESETS:
        assert make_options(study, {"n_nodes": 5}).n_nodes == 5


def test_rod_preset_runs_that_excitation_only(tmp_path):
    """``study rod --preset rod_tip_impulse`` runs the tip impulse case and nothing else (not
    the default three excitations and the 24-frequency response); about 15 CPU-s."""
    out = tmp_path / "rod"
    assert main(["study", "rod", "--preset", "rod_tip_impulse", "--nodes", "5",
                 "--free-duration", "0.3", "--workers", "1", "--no-progress",
                 "-o", str(out)]) == 0
    runs = [o["run_id"] for o in json.loads((out / "outcomes.json").read_text())]
    assert runs == ["tip_impulse"]


def test_fit_dissipation_writes_with_o():
    assert {"-o", "--output"} <= _flags(TOP["fit-dissipation"])
