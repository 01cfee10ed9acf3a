"""``brush-studio --help`` and a study's parser do not import numba, the kernels or Dask; a
command line that names one command (and one study) imports that command's module alone,
and the parser it gets is the one the whole ``--help`` parser has for that command."""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

from studio.cli.main import COMMAND_MODULES, build_parser
from studio.studies.cli import STUDY_COMMANDS

ROOT = Path(__file__).resolve().parents[2]

_CODE = """
import contextlib, io, json, sys
from studio.cli.main import main
with contextlib.redirect_stdout(io.StringIO()):
    codes = [main(["--help"]), main(["study", "wedge", "--help"])]
heavy = ("numba", "distributed", "dask", "trimesh", "scipy", "engine.kernels.stepper", "matplotlib")
print(json.dumps([codes, sorted(m for m in heavy if m in sys.modules)]))
"""

# what ``study wedge`` never uses: the studio (viser pages, its plots), the job service, the
# other commands and studies (about half a CPU second of imports at commit 680f367)
_ONE_STUDY = """
import contextlib, io, json, sys
from studio.cli.main import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(["study", "wedge", "--help"])
print(json.dumps([code, sorted(m for m in sys.argv[1:] if m in sys.modules)]))
"""
NOT_FOR_WEDGE = ("studio.web.app", "studio.web.export", "studio.service.jobs", "studio.cli.serve",
                 "studio.studies.registry", "studio.studies.convergence",
                 "studio.studies.dissipation", "studio.studies.capture",
                 "studio.studies.sensitivity", "studio.studies.fur", "studio.studies.optimise",
                 "studio.plots.result_frames", "matplotlib", "numba", "dask", "tqdm")


def test_help_imports_no_kernels_and_no_dask():
    p = subprocess.run([sys.executable, "-c", _CODE], cwd=ROOT, capture_output=True,
                       text=True, check=True)
    codes, heavy = json.loads(p.stdout.splitlines()[-1])
    assert codes == [0, 0] and heavy == []


def test_one_study_imports_its_module_alone():
    p = subprocess.run([sys.executable, "-c", _ONE_STUDY, *NOT_FOR_WEDGE], cwd=ROOT,
                       capture_output=True, text=True, check=True)
    code, imported = json.loads(p.stdout.splitlines()[-1])
    assert code == 0 and imported == []


def _sub(parser: argparse.ArgumentParser) -> dict:
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


def test_whole_parser_has_exactly_the_lazy_commands():
    # a command added to a module but not to COMMAND_MODULES would be lost when named
    full = _sub(build_parser())
    assert set(COMMAND_MODULES) <= set(full)
    assert set(_sub(full["study"])) == set(STUDY_COMMANDS)


@pytest.mark.parametrize("command", sorted(COMMAND_MODULES))
def test_a_named_command_gets_the_same_parser(command):
    full, lazy = _sub(build_parser())[command], _sub(build_parser([command]))
    assert command in lazy and lazy[command].format_help() == full.format_help()


@pytest.mark.parametrize("study", sorted(STUDY_COMMANDS))
def test_a_named_study_gets_the_same_parser(study):
    full = _sub(_sub(build_parser())["study"])[study]
    lazy = _sub(_sub(build_parser(["study", study, "--help"]))["study"])
    assert study in lazy and lazy[study].format_help() == full.format_help()


_FREEZE = """
import contextlib, gc, io, json, sys
from studio.cli.main import main
with contextlib.redirect_stdout(io.StringIO()):
    main(["study", "wedge", "--help"])   # called with a command line: a host process (tests, the service)
in_process = gc.get_freeze_count()
sys.argv = ["brush-studio", "--version"]
with contextlib.redirect_stdout(io.StringIO()):
    main()                                # the program itself: it is about to exit
print(json.dumps([in_process, gc.get_freeze_count() > 0]))
"""


def test_only_the_program_entry_freezes_the_garbage_collector():
    # main(argv) in a long-lived process must leave the cyclic collector alone (frozen
    # objects are never collected); main() as the program freezes before the exit
    p = subprocess.run([sys.executable, "-c", _FREEZE], cwd=ROOT, capture_output=True,
                       text=True, check=True)
    assert json.loads(p.stdout.splitlines()[-1]) == [0, True]
