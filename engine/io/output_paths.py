"""Where Brush Studio may write: output files are only ever regular files.

Every writer (the recorder, the CLI's ``-o`` and ``--summary``, the studies' output folders,
the job service) checks its path here *before* any work: a path that exists and is not a
regular file (a device such as ``/dev/null`` or ``/dev/full``, a named pipe, a socket, a
folder where a file is expected) is refused, so that a result is never renamed over a device
node and opening a named pipe never hangs. A missing parent folder is refused too unless the
caller asks for it to be created (``parents=True``; the CLI's ``--parents``), so that a typo
such as ``-o /nonexistent/dir/x.h5`` does not create folders at the filesystem root.

Nothing here opens a path that is not a regular file.
"""
from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Optional, Union

from engine.errors import BrushStudioError

__all__ = ["OutputPathError", "output_file_problem", "output_dir_problem",
           "check_output_file", "check_output_dir", "refuse_special", "kind_of"]

PathLike = Union[str, "os.PathLike[str]"]


class OutputPathError(BrushStudioError, ValueError):
    """An output path that must not be written (not a regular file, no parent folder)."""


def kind_of(mode: int) -> str:
    """What a ``st_mode`` is, in words."""
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISFIFO(mode):
        return "a named pipe (FIFO)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISREG(mode):
        return "a regular file"
    return "not a regular file"


def _stat(path: Path) -> Optional[os.stat_result]:
    """``os.stat`` (following links: a link to /dev/null is a device), None if missing."""
    try:
        return os.stat(path)
    except (FileNotFoundError, NotADirectoryError):  # (a part of the path is a file)
        return None


def _parent_problem(path: Path, what: str, parents: bool) -> Optional[str]:
    parent = path.parent
    # the nearest folder that exists: everything below it would have to be created
    existing = parent
    while _stat(existing) is None and existing != existing.parent:
        existing = existing.parent
    st = _stat(existing)
    if st is not None and not stat.S_ISDIR(st.st_mode):
        return (f"{what} {path}: cannot be written ({existing} is {kind_of(st.st_mode)}, "
                f"not a folder)")
    if existing != parent:
        if not parents:
            return (f"{what} {path}: the folder {parent} does not exist (create it first, "
                    f"or pass --parents to create it)")
        if not os.access(existing, os.W_OK | os.X_OK):
            return f"{what} {path}: cannot create {parent} (no write permission in {existing})"
        return None
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"{what} {path}: cannot be written (no write permission in {parent})"
    return None


def output_file_problem(path: PathLike, what: str = "output", *,
                        parents: bool = False) -> Optional[str]:
    """Why ``path`` cannot be written as the output file ``what`` (one line), or None.

    Refused: a path that exists and is not a regular file (folder, device, named pipe,
    socket; a link is followed), a regular file without write permission, and a missing
    parent folder unless ``parents``. Nothing is created or opened."""
    path = Path(path)
    if str(path) in ("", "."):
        return f"{what}: an empty path (give a file name)"
    st = _stat(path)
    if st is not None:
        if not stat.S_ISREG(st.st_mode):
            hint = " (give a file name)" if stat.S_ISDIR(st.st_mode) else \
                " (outputs are only written as regular files)"
            return f"{what} {path}: is {kind_of(st.st_mode)}{hint}"
        if not os.access(path, os.W_OK):
            return f"{what} {path}: cannot be written (no write permission)"
        return None
    return _parent_problem(path, what, parents)


def output_dir_problem(path: PathLike, what: str = "output folder", *,
                       parents: bool = False) -> Optional[str]:
    """Why ``path`` cannot be used as the output folder ``what``, or None: it must be a
    folder or missing (it is then created, but its own parent must exist unless
    ``parents``)."""
    path = Path(path)
    st = _stat(path)
    if st is not None:
        if not stat.S_ISDIR(st.st_mode):
            return f"{what} {path}: is {kind_of(st.st_mode)}, not a folder"
        if not os.access(path, os.W_OK | os.X_OK):
            return f"{what} {path}: cannot be written (no write permission)"
        return None
    return _parent_problem(path, what, parents)


def check_output_file(path: PathLike, what: str = "output", *, parents: bool = False) -> Path:
    """``path`` as a Path if it may be written (its parent folders created when
    ``parents``); :class:`OutputPathError` otherwise."""
    problem = output_file_problem(path, what, parents=parents)
    if problem:
        raise OutputPathError(problem)
    path = Path(path)
    if parents:
        path.parent.mkdir(parents=True, exist_ok=True)
    return path


def check_output_dir(path: PathLike, what: str = "output folder", *,
                     parents: bool = False) -> Path:
    """``path`` as a Path, created if missing, if it may hold outputs;
    :class:`OutputPathError` otherwise."""
    problem = output_dir_problem(path, what, parents=parents)
    if problem:
        raise OutputPathError(problem)
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    return path


def refuse_special(path: PathLike, what: str = "output") -> None:
    """:class:`OutputPathError` if ``path`` exists and is not a regular file (the check a
    writer makes right before it opens or renames onto ``path``)."""
    st = _stat(Path(path))
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise OutputPathError(f"{what} {path}: is {kind_of(st.st_mode)} (outputs are only "
                              f"written as regular files)")
