"""Messages to the terminal that several commands print the same way."""
from __future__ import annotations

import sys


def err(msg: str) -> None:
    """One line on stderr."""
    print(msg, file=sys.stderr)


def print_scene_error(exc, what: str) -> None:
    """Every problem of a SceneError, one per line: ``field = value: allowed``."""
    err(f"{what}: {len(exc.problems)} problem(s)")
    for p in exc.problems:
        err(f"  {p}")
