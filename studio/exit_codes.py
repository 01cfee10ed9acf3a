"""The exit codes of every ``brush-studio`` command and of every study, defined once.

0 completed (or stopped by the scene's stop condition), 1 failed (an engine error, or some
runs of a study failed), 2 bad input (an invalid scene or option), 130 cancelled (Ctrl-C, or a
job's cancel).
"""
from __future__ import annotations

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_CANCELLED = 130

#: what each code means, in words (the job service's messages, the CLI's epilogs)
MEANING = {EXIT_OK: "ok", EXIT_FAILED: "some runs failed", EXIT_BAD_INPUT: "bad input",
           EXIT_CANCELLED: "interrupted"}


def describe(code: int) -> str:
    """``code`` in words: ``"bad input"``, or ``"exit code 7"`` for a code of no meaning."""
    return MEANING.get(code, f"exit code {code}")
