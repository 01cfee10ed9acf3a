"""The same names for the same things across every study command's parser (issue 16).

A user who learnt ``--nodes`` on ``study wedge`` must not have to guess ``--n-nodes`` on
``study spin``; the HTTP API and the studio pass options by these names too.
"""
from __future__ import annotations

import argparse

import pytest

from studio.cli import build_parser


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


TOP = _subparsers(build_parser())
STUDIES = _subparsers(TOP["study"])
# every command that runs many simulations through the studies' Dask layer
RUNNERS = {**{f"study {name}": p for name, p in STUDIES.items()},
           "convergence": TOP["convergence"]}
# the commands whose runs are one scene's (a file or a preset name) changed by the study;
# rod and spin run the seed's experiments, chosen by --cases and --cubes/--configs
ONE_SCENE = ("study wedge", "study refinement", "study sensitivity", "study montecarlo")


def _flags(parser: argparse.ArgumentParser) -> set[str]:
    return {s for a in parser._actions for s in a.option_strings}


def test_every_study_is_checked():
    assert set(STUDIES) >= {"wedge", "refinement", "sensitivity", "montecarlo", "rod", "spin"}


@pytest.mark.parametrize("name", sorted(RUNNERS))
def test_execution_options_have_one_name_everywhere(name):
    flags = _flags(RUNNERS[name])
    missing = {"-o", "--output", "--workers", "--scheduler", "--no-progress"} - flags
    assert not missing, f"{name} lacks {sorted(missing)}"


@pytest.mark.parametrize("name", sorted(n for n in RUNNERS if n != "convergence"))
def test_nodes_per_bristle_is_nodes(name):
    """convergence has a ladder of them instead (--ladder n_nodes=...)."""
    assert "--nodes" in _flags(RUNNERS[name]), f"{name}: nodes per bristle is --nodes"


@pytest.mark.parametrize("name", ONE_SCENE)
def test_the_scene_is_preset(name):
    assert "--preset" in _flags(RUNNERS[name])


def test_fit_dissipation_writes_with_o():
    assert {"-o", "--output"} <= _flags(TOP["fit-dissipation"])
