"""``brush-studio study <name> ...``: the studies as command-line subcommands.

Each module in :data:`STUDY_MODULES` exposes ``add_parser(study_subparsers)``, which adds its
subcommand with ``set_defaults(func=...)`` (a function of the parsed arguments returning an
exit code: 0 ok, 1 some runs failed, 2 bad input, 130 cancelled). Common options
(``-o/--output``, ``--scheduler``, ``--workers``, ``--no-progress``) come from
:func:`studio.studies.study_command.set_command` (``-o/--output``) and the study's options
model (:class:`studio.studies.options.StudyOptions`). Study modules import dask, matplotlib and
the engine inside their commands only, so that ``brush-studio --help`` stays fast.
"""
from __future__ import annotations

from . import capture, detumble, docking, fur, optimise, reduce, refinement, sensitivity, trap
from .rod import study as rod_study
from .spin import study as spin_study
from .wedge import study as wedge_study

STUDY_MODULES = (wedge_study, refinement, sensitivity, rod_study, spin_study, detumble,
                 reduce, fur, docking, capture, trap, optimise)


def register(subparsers) -> None:
    """Add ``study`` and its sub-subcommands to the top-level ``brush-studio`` parser."""
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
    for module in STUDY_MODULES:
        module.add_parser(sub)
