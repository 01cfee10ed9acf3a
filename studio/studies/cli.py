"""``brush-studio study <name> ...``: the studies as command-line subcommands.

Each module loaded by :data:`STUDY_COMMANDS` exposes ``add_parser(study_subparsers)``, which adds its
subcommand with ``set_defaults(func=...)`` (a function of the parsed arguments returning an
exit code: 0 ok, 1 some runs failed, 2 bad input, 130 cancelled). Common options
(``-o/--output``, ``--scheduler``, ``--workers``, ``--no-progress``) come from
:func:`studio.studies.study_command.set_command` (``-o/--output``) and the study's options
model (:class:`studio.studies.options.StudyOptions`). Study modules import dask, matplotlib and
the engine inside their commands only, so that ``brush-studio --help`` stays fast.
"""
from __future__ import annotations

from typing import Optional, Sequence

# Each loader imports one study module (a plain import, so the import graph sees it)
def _wedge_study():
    import studio.studies.wedge.study as module
    return module


def _refinement():
    import studio.studies.refinement as module
    return module


def _sensitivity():
    import studio.studies.sensitivity as module
    return module


def _rod_study():
    import studio.studies.rod.study as module
    return module


def _spin_study():
    import studio.studies.spin.study as module
    return module


def _detumble():
    import studio.studies.detumble as module
    return module


def _reduce():
    import studio.studies.reduce as module
    return module


def _fur():
    import studio.studies.fur as module
    return module


def _docking():
    import studio.studies.docking as module
    return module


def _capture():
    import studio.studies.capture as module
    return module


def _trap():
    import studio.studies.trap as module
    return module


def _optimise():
    import studio.studies.optimise as module
    return module


#: ``study NAME`` -> the loader of the module whose ``add_parser`` adds it, in the order
#: ``study --help`` lists them (``sensitivity`` adds ``montecarlo`` too)
STUDY_COMMANDS = {
    "wedge": _wedge_study,
    "refinement": _refinement,
    "sensitivity": _sensitivity,
    "montecarlo": _sensitivity,
    "rod": _rod_study,
    "spin": _spin_study,
    "detumble": _detumble,
    "reduce": _reduce,
    "fur": _fur,
    "docking": _docking,
    "capture": _capture,
    "trap": _trap,
    "optimise": _optimise,
}


def study_modules(name: Optional[str] = None) -> list:
    """The modules that add ``study NAME`` (just the one for a known ``name``, else all of
    them, once each, in :data:`STUDY_COMMANDS`' order), imported."""
    loaders = [STUDY_COMMANDS[name]] if name in STUDY_COMMANDS else STUDY_COMMANDS.values()
    return [load() for load in dict.fromkeys(loaders)]


def register(subparsers, argv: Optional[Sequence[str]] = None) -> None:
    """Add ``study`` and its sub-subcommands to the top-level ``brush-studio`` parser;
    ``argv``, the words after ``study`` on the command line: when its first names a study,
    only that study's module is imported and its subcommand added (a run of one study does
    not pay the imports of the twelve others); otherwise (``study --help``, an unknown
    name) all are."""
    p = subparsers.add_parser(
        "study", help="run a study (many simulations) into an output folder",
        description="Studies run many simulations on Dask distributed (a local cluster using "
                    "every core by default, or --scheduler tcp://HOST:PORT; --workers 1 runs "
                    "them in this process, without a cluster) and write CSV, "
                    "HDF5 and PNG plots into an output folder. Restarting a study in the same "
                    "folder skips the runs already complete. See docs/studies.md.",
        epilog="Exit codes: 0 ok, 1 some runs failed (listed with their parameters), "
               "2 bad input, 130 cancelled.")
    sub = p.add_subparsers(dest="study", metavar="STUDY", required=True)
    for module in study_modules(argv[0] if argv else None):
        module.add_parser(sub)
