"""``brush-studio study optimise``: which brush serves a range of spinning targets best?

A design search (seed 4.3.4; docs/design.md): design variables addressed by their path in the
scene (plus the bristle bending stiffness E d^4), a scenario set (targets, spin rates and
axes, contact offsets, material draws), objectives and constraints from each run aggregated
over the scenarios, Optuna's samplers with its storage in the output folder (resume, extend),
the scenario runs on the Dask cluster the other studies use, and a refinement re-run of the
winner.

    from studio.studies.registry import get
    from studio.studies.optimise import Options

    result = get("optimise").run(Options(trials=10, cubes_mm=[20, 40]), "out")

Modules: :mod:`.options` (the options model),
:mod:`.variables`, :mod:`.scenarios`, :mod:`.metrics` (the run task and the metric list),
:mod:`.groups` (non-dimensional groups), :mod:`.search` (the Optuna loop),
:mod:`.executor` (Dask or this process), :mod:`.outputs`, :mod:`.study` (the command).
"""
from .errors import StudyInputError
from .options import Options, StudyOptions
from .study import add_parser, run

__all__ = ["Options", "StudyOptions", "StudyInputError", "add_parser", "run"]
