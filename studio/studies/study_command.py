"""What every study command shares: the common options (``-o/--output``, ``--scheduler``,
``--workers``, ``--no-progress``), their check, and the common body of a command (build the
runs, check their scenes, run them, write ``outcomes.json``)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Callable, Optional, Sequence

from .run_files import RunOutcome, failures_text, write_outcomes
from ..exit_codes import EXIT_FAILED, EXIT_OK
from .runner import RunSpec, default_workers, run_many

def add_common_options(parser: argparse.ArgumentParser, default_output: Optional[str] = None,
                       ) -> None:
    """Options every study command has: ``-o/--output DIR``, ``--scheduler``, ``--workers``,
    ``--no-progress``."""
    g = parser.add_argument_group("output and execution")
    if default_output is None:
        g.add_argument("-o", "--output", metavar="DIR", required=True,
                       help="output folder (created; a restart in the same folder skips "
                            "runs already complete)")
    else:
        g.add_argument("-o", "--output", metavar="DIR", default=default_output,
                       help=f"output folder (default ./{default_output}; a restart in the "
                            f"same folder skips runs already complete)")
    g.add_argument("--scheduler", metavar="tcp://HOST:PORT", default=None,
                   help="address of an existing Dask scheduler (its workers must see DIR); "
                        "default: a local cluster, one single-threaded worker per core")
    g.add_argument("--workers", type=int, metavar="N", default=None,
                   help=f"worker processes of the local cluster (default: one per core, "
                        f"{default_workers()} here); 1 runs the runs in this process, "
                        f"one after another, without a cluster")
    g.add_argument("--no-progress", action="store_true", help="no progress bar")


def set_command(parser: argparse.ArgumentParser, run: Callable, options: type, *,
                default_output: Optional[str] = None, common_options: bool = True,
                **defaults) -> None:
    """Finish a study's parser: the common options (:func:`add_common_options`; with
    ``common_options=False`` the parser declares its own ``-o/--output`` and whatever
    execution options it has) and, as its ``func``, the command: the parsed arguments as
    ``options`` (``options.from_args``), run by ``run`` into ``--output``; it returns the
    exit code. ``defaults``: more ``set_defaults`` values."""
    if common_options:
        add_common_options(parser, default_output)

    def command(args) -> int:
        return run(options.from_args(args), args.output).exit_code

    parser.set_defaults(func=command, **defaults)


def number_list(text: str, convert: Callable = float,
                message: str = "expected comma-separated numbers") -> list:
    """The numbers of a comma-separated option value (``"20,40,60"``; empty items skipped),
    each through ``convert``; ValueError(``message``) where one is not a number."""
    try:
        return [convert(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(message) from None


def check_common_options(args) -> Optional[str]:
    """A message for a bad common option, or None."""
    if args.workers is not None and args.workers < 1:
        return f"--workers = {args.workers}: must be >= 1"
    if args.scheduler is not None and args.workers is not None:
        return "--workers applies to the local cluster only; leave it out with --scheduler"
    if args.scheduler is not None and "://" not in args.scheduler:
        return f"--scheduler = {args.scheduler!r}: expected an address like tcp://HOST:PORT"
    return None


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
    is bad input too: exit 2, before anything runs), run them with the common options into
    ``out_dir``, write ``outcomes.json``. Returns (exit code to return now, or None; the
    outcomes)."""
    import engine

    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2, []
    from engine.output_paths import OutputPathError, check_output_dir

    try:  # a folder (created if missing, its parent must exist), never a file or a device
        check_output_dir(out_dir, "-o/--output")
    except OutputPathError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2, []
    try:
        specs = make_specs()
        for s in specs:  # every scene valid before anything runs
            engine.parse_scene(s.scene)
    except engine.SceneError as exc:
        print("error: invalid scene: " + "; ".join(str(p) for p in exc.problems),
              file=sys.stderr)
        return 2, []
    except KeyError as exc:  # a missing preset
        print(f"error: {exc}", file=sys.stderr)
        return 2, []
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
