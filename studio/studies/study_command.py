"""What every study command shares: its parser from its options model (``-o/--output`` and
the model's fields, :func:`set_command`), and the common body of a command (build the
runs, check their scenes, run them, write ``outcomes.json``)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Callable, Optional, Sequence

from .run_files import RunOutcome, failures_text, write_outcomes
from ..exit_codes import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK
from .runner import RunSpec, default_workers, run_many

EXECUTION_GROUP = "output and execution"


def add_output_option(parser: argparse.ArgumentParser, default_output: Optional[str] = None
                      ) -> None:
    """``-o/--output DIR`` (required unless ``default_output``): where a study writes. Not
    an option of the study's model: the job layer chooses the folder itself."""
    g = parser.add_argument_group(EXECUTION_GROUP)
    if default_output is None:
        g.add_argument("-o", "--output", metavar="DIR", required=True,
                       help="output folder (created; a restart in the same folder skips "
                            "runs already complete)")
    else:
        g.add_argument("-o", "--output", metavar="DIR", default=default_output,
                       help=f"output folder (default ./{default_output}; a restart in the "
                            f"same folder skips runs already complete)")
    return g


def set_command(parser: argparse.ArgumentParser, run: Callable, options: type, *,
                default_output: Optional[str] = None, skip: Sequence[str] = (),
                **defaults) -> None:
    """Finish a study's parser from its options model ``options``: ``-o/--output``
    (:func:`add_output_option`) and one argument per field
    (:func:`studio.studies.options.add_model_arguments`); as its ``func``, the command: the
    parsed arguments checked by the model, run by ``run`` into ``--output``. A refused
    option (:class:`StudyOptionError`, naming the flag, value and bound) or bad input
    (:class:`StudyInputError`) is printed and exits 2. ``skip``: fields the command does
    not offer (their defaults apply); ``defaults``: more ``set_defaults`` values."""
    from .options import add_model_arguments

    group = add_output_option(parser, default_output)
    add_model_arguments(parser, options, groups={EXECUTION_GROUP: group}, skip=skip)

    def command(args) -> int:
        from .api import StudyInputError
        from .options import StudyOptionError, options_from_args

        try:
            return run(options_from_args(options, args), args.output).exit_code
        except (StudyOptionError, StudyInputError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT

    parser.set_defaults(func=command, **defaults)


def number_list(text: str, convert: Callable = float,
                message: str = "expected comma-separated numbers") -> list:
    """The numbers of a comma-separated option value (``"20,40,60"``; empty items skipped),
    each through ``convert``; ValueError(``message``) where one is not a number."""
    try:
        return [convert(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(message) from None


def run_many_from_args(specs: Sequence[RunSpec], out_dir, args, desc: str = "runs"
                       ) -> list[RunOutcome]:
    """``run_many`` with the common options of ``args``."""
    return run_many(specs, out_dir, scheduler=args.scheduler, n_workers=args.workers,
                    progress=not args.no_progress, desc=desc)


def first_problem(problem: Optional[str], checks) -> Optional[str]:
    """``problem`` if set, else the message of the first ``(ok, message)`` check that fails."""
    for ok, message in checks:
        if problem is not None:
            break
        if not ok:
            problem = message
    return problem


def run_study(make_specs: Callable[[], Sequence[RunSpec]], out_dir: Path, args,
              desc: str, problem: Optional[str] = None
              ) -> tuple[Optional[int], list[RunOutcome]]:
    """The common body of a study command: refuse the ``problem`` the command found in its
    options (:func:`first_problem`), build the specs (a missing preset or an invalid scene
    is bad input too: all raise :class:`StudyInputError` before anything runs), run them with the common options into
    ``out_dir``, write ``outcomes.json``. Returns (exit code to return now, or None; the
    outcomes)."""
    import engine

    from .api import StudyInputError

    if problem:
        raise StudyInputError(problem)
    from engine.io.output_paths import OutputPathError, check_output_dir

    try:  # a folder (created if missing, its parent must exist), never a file or a device
        check_output_dir(out_dir, "-o/--output")
    except OutputPathError as exc:
        raise StudyInputError(str(exc)) from None
    try:
        specs = make_specs()
        for s in specs:  # every scene valid before anything runs
            engine.parse_scene(s.scene)
    except engine.SceneError as exc:
        raise StudyInputError("invalid scene: " + "; ".join(str(p) for p in exc.problems)
                              ) from None
    except KeyError as exc:  # a missing preset
        raise StudyInputError(str(exc.args[0] if exc.args else exc)) from None
    try:
        outcomes = run_many_from_args(specs, out_dir, args, desc=desc)
    except KeyboardInterrupt:
        print("cancelled: finished runs are kept; run the same command again to resume",
              file=sys.stderr)
        return 130, []
    write_outcomes(out_dir / "outcomes.json", outcomes)
    return None, outcomes


def report_failures(outcomes: Sequence[RunOutcome]) -> int:
    """A study's exit code from its outcomes: EXIT_OK when every run completed, else the
    runs that did not listed on stderr (:func:`failures_text`) and EXIT_FAILED."""
    failed = failures_text(outcomes)
    if failed:
        print("failed runs:\n" + failed, file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK
