"""The ``brush-studio`` command line: run, validate and inspect scenes and results.

    brush-studio demo [-o DIR]                  run the embedded default scene, plot it
    brush-studio run SCENE.json -o RESULT.h5    run a scene (progress bar, Ctrl-C cancels)
    brush-studio validate SCENE.json            check a scene without running it
    brush-studio info RESULT.h5                 what a result file holds

This module holds the parsers and ``main``; what each command does is in ``studio.cli.commands``
(run, validate, info), ``studio.cli.demo`` and ``studio.cli.run_console`` (the progress bar, Ctrl-C,
the summary table). A thin layer: everything it knows about scenes, runs and results comes
from the engine's public API (``import engine``). Exit codes: 0 completed or stopped, 1 failed
(instability or another engine error), 2 bad input (an invalid scene, a bad command line), 130
cancelled.
"""
from __future__ import annotations

import argparse
import gc
import sys
from typing import Optional

from studio import __version__
from studio.cli.commands import cmd_info as _cmd_info, cmd_run as _cmd_run, cmd_validate as _cmd_validate
from studio.console import err as _err
from studio.cli.demo import DEMO_DIR, cmd_demo as _cmd_demo
from studio.exit_codes import EXIT_BAD_INPUT, EXIT_CANCELLED, EXIT_OK

__all__ = ["build_parser", "main", "COMMAND_MODULES"]

# The modules that add their own subcommands, by the command each adds, in the order
# ``--help`` lists them: each has ``register(subparsers)`` and imports its heavy dependencies
# (dask, fastapi, viser) only inside the command it runs. This module is the composition
# root: it imports them, none of them imports it. A command line naming one of them imports
# that module alone (the studio, the job service and the other studies cost about half a
# CPU second of imports that ``study wedge`` never uses); ``--help``, ``--version`` and a
# command that is not known build the whole parser. Each loader is a plain import, which
# the import graph (tests/test_import_graph.py) sees.
def _studio():
    import studio.web.app as module
    return module


def _convergence():
    import studio.studies.convergence as module
    return module


def _study():
    import studio.studies.cli as module
    return module


def _serve():
    import studio.cli.serve as module
    return module


def _fit_dissipation():
    import studio.studies.dissipation as module
    return module


def _export():
    import studio.web.export as module
    return module


COMMAND_MODULES = {
    "studio": _studio,
    "convergence": _convergence,
    "study": _study,
    "serve": _serve,
    "fit-dissipation": _fit_dissipation,
    "export": _export,
}


# ----------------------------------------------------------------------------- parser
def _size_options(parser) -> None:
    """The size guard of ``run`` and ``validate``: the scene's estimate against these limits,
    before anything is built (``studio.cli.commands.size_problem``)."""
    parser.add_argument("--max-nodes", type=int, default=2_000_000, metavar="N",
                        help="refuse to build a scene with more bristle nodes (default "
                             "2000000; 0: no limit)")
    parser.add_argument("--max-memory-mb", type=float, default=8192.0, metavar="MB",
                        help="refuse to build a scene estimated to need more memory for its "
                             "build and run (default 8192; 0: no limit)")


def build_parser(argv: Optional[list[str]] = None) -> argparse.ArgumentParser:
    """The ``brush-studio`` parser. With ``argv`` (the command line it will parse) whose first
    word is a command of :data:`COMMAND_MODULES`, only that command's module is imported and
    registered (and it may do the same with the rest of ``argv``); otherwise every command is."""
    p = argparse.ArgumentParser(
        prog="brush-studio",
        description="Brush Studio: DEM simulation of brushes touching space debris.",
        epilog="Exit codes: 0 completed/stopped, 1 failed, 2 bad input, 130 cancelled.")
    p.add_argument("--version", action="version", version=f"brush-studio {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    r = sub.add_parser("run", help="run a scene and record it to an HDF5 result file",
                       description="Load, build and run a scene with a progress bar. "
                                   "Ctrl-C cancels cleanly (the file keeps the frames so far "
                                   "and has status cancelled).")
    r.add_argument("scene", metavar="SCENE.json",
                   help="a scene file, or a preset's name (demo, wedge_30, ...)")
    r.add_argument("-o", "--output", metavar="RESULT.h5", required=True,
                   help="result file to write")
    r.add_argument("--summary", metavar="SUMMARY.json",
                   help="also write the run summary as JSON (written for failed runs too)")
    r.add_argument("--parents", action="store_true",
                   help="create the missing folders of -o and --summary (without it a "
                        "missing folder is refused; outputs are only written as regular "
                        "files, never onto a device, a named pipe or a folder)")
    r.add_argument("--until", type=float, metavar="T",
                   help="simulated time to run to, s (default: the scene's run.duration)")
    r.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bar and no summary table")
    _size_options(r)
    r.set_defaults(func=_cmd_run)

    d = sub.add_parser("demo", help="run the embedded default scene and plot it",
                       description="Run the embedded demo (a 17 x 5 silicone brush pressed by "
                                   "a wedge) and write demo.h5, summary.json and "
                                   "root_force.png into DIR.")
    d.add_argument("-o", "--output", metavar="DIR", default=DEMO_DIR,
                   help=f"output folder (default ./{DEMO_DIR})")
    d.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    d.add_argument("--scene-only", action="store_true",
                   help="write only the demo scene, DIR/scene.json, without running it")
    d.set_defaults(func=_cmd_demo)

    v = sub.add_parser("validate", help="check a scene without running it")
    v.add_argument("scene", metavar="SCENE.json",
                   help="a scene file, or a preset's name (demo, wedge_30, ...)")
    _size_options(v)
    v.add_argument("--estimate-only", action="store_true",
                   help="print the cost estimate and stop (no build)")
    v.set_defaults(func=_cmd_validate)

    i = sub.add_parser("info", help="describe a result file")
    i.add_argument("result", metavar="RESULT.h5")
    i.set_defaults(func=_cmd_info)

    command = argv[0] if argv else None
    for name, module in COMMAND_MODULES.items():
        if command in COMMAND_MODULES and name != command:
            continue
        module = module()
        if name == command == "study":  # ``study NAME``: that study's module alone
            module.register(sub, argv[1:])
        else:
            module.register(sub)
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Run the command line ``argv``; its exit code. Without ``argv`` this is the program
    (``brush-studio`` and ``python -m studio.cli`` call it so and exit with its code): the
    command line is ``sys.argv``, and the process is about to end."""
    if argv is not None:
        return _main(list(argv))
    code = _main(sys.argv[1:])
    # Leave what is left out of the cyclic garbage collector's reach: the interpreter's
    # shutdown then frees it by reference counts only, without traversing the ~190,000
    # tracked objects numba, matplotlib and h5py made (about 0.4 CPU-s of a study process at
    # commit b052d44). Exit handlers still run, and files close, as before.
    gc.freeze()
    return code


def _main(argv: list[str]) -> int:
    parser = build_parser(argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors: return, do not exit
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    try:
        return int(args.func(args))
    except KeyboardInterrupt:  # Ctrl-C outside a run (loading, building, plotting)
        _err("interrupted")
        return EXIT_CANCELLED
    except BrokenPipeError:  # output piped into `head` and the like: stop quietly
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
