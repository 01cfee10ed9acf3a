"""The typed face of every study: ``Options`` in, :class:`StudyResult` out.

Each study module defines a pydantic model ``Options`` (its parameters, declared once with
defaults, bounds, units and help; the common execution options come from
:class:`studio.studies.options.StudyOptions`) and::

    run(options, out_dir, *, progress=None, cancel=None) -> StudyResult

Bad input raises :class:`StudyInputError` (its whole message is the job's error); the
result carries the study's data: ``summary`` (headline figures), ``tables`` (name -> CSV)
and ``figures`` (PNG paths).

``progress(fraction, message)`` is told how far the study is (0..1, and a line such as
``"wedge runs: 1.5/3 run"``); ``cancel`` is a ``threading.Event`` (or anything with
``is_set()``): once it is set the study stops at its next check (between runs, between the
chunks of a run), keeps the runs already finished and returns exit code 130, like Ctrl-C.

The command line parses its argv into ``Options`` (:func:`studio.studies.options.options_from_args`)
and the job service checks a client's dict with the same model (:mod:`studio.studies.registry`);
both call ``run``. The study's report (tables, file names) is printed on stdout as before.

How progress and cancel reach the runs: :func:`session` makes them the *current* study's, for
the thread that runs the study; the runner (:mod:`studio.studies.runner`) and the study tasks
running in this process ask :func:`current` at their check points. Tasks on remote Dask
workers do not see them: a cancel there cancels the queued tasks and stops waiting.
"""
from __future__ import annotations

import contextlib
import contextvars
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Optional

from ..exit_codes import EXIT_BAD_INPUT, EXIT_CANCELLED, EXIT_OK, describe

ProgressFn = Callable[[float, str], None]


class StudyInputError(ValueError):
    """A study's input it cannot run (a scene without a wedge, a depth that is not a whole
    number of steps, an option the scene contradicts): raised by ``run`` before anything
    runs; the command line prints it and exits 2, the job layer keeps the whole message as
    the job's error."""


class StudyCancelled(KeyboardInterrupt):
    """Raised at a check point once the study's cancel is set. A KeyboardInterrupt on
    purpose: a cancel takes the same path as Ctrl-C (finished runs kept, exit code 130)."""


@dataclass
class StudyResult:
    """What became of a study: its exit code (0 ok, 1 some runs failed, 130 cancelled; bad
    input raises :class:`StudyInputError` instead), its output folder and wall time, and its
    data: ``summary`` (headline figures, JSON-able), ``tables`` (name -> CSV file) and
    ``figures`` (plot files). ``files`` lists everything it wrote."""

    study: str
    exit_code: int
    out_dir: Path
    wall_s: float = 0.0
    summary: dict = field(default_factory=dict)
    tables: dict = field(default_factory=dict)
    figures: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.exit_code == EXIT_OK

    @property
    def status(self) -> str:
        """completed | failed | bad_input | cancelled."""
        if self.exit_code == EXIT_OK:
            return "completed"
        if self.exit_code == EXIT_CANCELLED:
            return "cancelled"
        if self.exit_code == EXIT_BAD_INPUT:
            return "bad_input"
        return "failed"

    @property
    def meaning(self) -> str:
        return describe(self.exit_code)

    @property
    def files(self) -> list[str]:
        """The output files (relative POSIX paths, sorted; hidden and scratch files and
        links left out)."""
        return study_files(self.out_dir)


def study_files(folder: Path) -> list[str]:
    """The files of a study's output folder: relative POSIX paths, sorted (hidden and
    scratch files and links left out)."""
    import os

    folder = Path(folder)
    if not folder.is_dir():
        return []
    out = []
    for root, dirs, files in os.walk(folder, followlinks=False):
        dirs[:] = [d for d in dirs if not d.startswith(".")]
        for f in files:
            p = Path(root) / f
            if f.startswith(".") or f.endswith(".tmp") or p.is_symlink() or not p.is_file():
                continue
            out.append(p.relative_to(folder).as_posix())
    return sorted(out)


# ----------------------------------------------------------------------------- session
@dataclass
class Session:
    """The progress callback and cancel flag of the study running in this thread."""

    progress: Optional[ProgressFn] = None
    cancel: Any = None
    _last: float = field(default=0.0, repr=False)

    def cancelled(self) -> bool:
        c = self.cancel
        if c is None:
            return False
        return bool(c.is_set() if hasattr(c, "is_set") else c())

    def check(self) -> None:
        """Raise :class:`StudyCancelled` if the cancel is set."""
        if self.cancelled():
            raise StudyCancelled()

    def report(self, fraction: float, message: str, *, force: bool = False) -> None:
        """Tell the progress callback (at most four times a second unless ``force``)."""
        if self.progress is None:
            return
        now = time.monotonic()
        if not force and now - self._last < 0.25:
            return
        self._last = now
        try:
            self.progress(min(max(float(fraction), 0.0), 1.0), message)
        except Exception:  # progress is a nicety: a broken callback never fails a study
            pass


_NO_SESSION = Session()
_CURRENT: contextvars.ContextVar[Session] = contextvars.ContextVar("study_session",
                                                                  default=_NO_SESSION)


def current() -> Session:
    """The session of the study running in this thread (an empty one outside a study)."""
    return _CURRENT.get()


@contextlib.contextmanager
def session(progress: Optional[ProgressFn] = None, cancel: Any = None) -> Iterator[Session]:
    s = Session(progress, cancel)
    token = _CURRENT.set(s)
    try:
        yield s
    finally:
        _CURRENT.reset(token)


def check_cancel() -> None:
    """A check point: raise :class:`StudyCancelled` if the current study's cancel is set."""
    current().check()


def cancel_requested() -> bool:
    """Whether the current study's cancel is set (for ``engine.run(cancel=...)``)."""
    return current().cancelled()


def study_run(study: str, body: Callable[[Any, Path], Any]) -> Callable[..., StudyResult]:
    """A study's ``run(options, out_dir, *, progress=None, cancel=None) -> StudyResult``:
    its body ``body(options, out_dir)`` (returning an exit code, or ``(exit code,
    summary)``) through :func:`run_body`."""

    def run(options, out_dir, *, progress: Optional[ProgressFn] = None,
            cancel: Any = None) -> StudyResult:
        return run_body(study, body, options, out_dir, progress, cancel)

    run.__doc__ = (f"The {study} study of ``options`` into ``out_dir`` (progress and cancel: "
                   f":func:`studio.studies.api.run_body`).")
    return run


def run_body(study: str, body: Callable[[Any, Path], Any], options, out_dir,
             progress: Optional[ProgressFn] = None, cancel: Any = None) -> StudyResult:
    """Run a study's body ``body(options, out_dir)`` in a session of ``progress`` and
    ``cancel``; a cancel (or Ctrl-C) that escapes the body is exit 130. The body returns an
    exit code, or ``(exit code, summary dict)``; without a summary it is the study's
    ``study.json`` where it wrote one. ``tables`` are the CSV files and ``figures`` the PNG
    files of the output folder's top level. :class:`StudyInputError` propagates."""
    out = Path(out_dir)
    t0 = time.perf_counter()
    options = options.model_copy(deep=True)  # the body may fill in defaults: not the caller's
    summary = None
    with session(progress, cancel):
        try:
            returned = body(options, out)
            if isinstance(returned, tuple):
                returned, summary = returned
            code = int(returned or 0)
        except KeyboardInterrupt:
            import sys

            print("cancelled: finished runs are kept; run the same command again to go on",
                  file=sys.stderr)
            code = EXIT_CANCELLED
    return StudyResult(study, code, out, time.perf_counter() - t0,
                       summary=summary if summary is not None else _study_json(out),
                       tables={p.stem: p for p in sorted(out.glob("*.csv"))},
                       figures=sorted(out.glob("*.png")))


def _study_json(out: Path) -> dict:
    """The ``study.json`` a study wrote into ``out`` (empty when none or unreadable)."""
    import json

    try:
        data = json.loads((out / "study.json").read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}
