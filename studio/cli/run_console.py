"""A scene run in the terminal: the progress bar, Ctrl-C as a clean cancel, the summary table
and the checks of output paths made before a run starts.

Used by the ``run`` and ``demo`` commands (``studio.cli.commands``, ``studio.cli.demo``); the exit
codes are those of :mod:`studio.exit_codes`.
"""
from __future__ import annotations

import math
import signal
import threading
from pathlib import Path
from typing import Optional

from engine.jsonable import json_text

from studio.console import err as _err, print_scene_error as _print_scene_error
from studio.exit_codes import EXIT_BAD_INPUT, EXIT_CANCELLED, EXIT_FAILED, EXIT_OK
from studio.fmt import fmt_rate, fmt_seconds


def _write_summary(path: Path, summary: dict, result_path) -> None:
    data = dict(summary)
    data["result"] = str(result_path) if result_path is not None else None
    from engine.io.output_paths import refuse_special

    refuse_special(path, "--summary")  # checked before the run; again right before writing
    path.write_text(json_text(data, indent=2) + "\n")


def summary_table(summary: dict, result_path=None) -> str:
    """The run summary as a short aligned table (the text ``run`` and ``info`` print)."""
    rows: list[tuple[str, str]] = []
    status = summary.get("status", "?")
    extra = []
    if isinstance(summary.get("time"), (int, float)):
        extra.append(f"t = {summary['time']:.6g} s simulated")
    if "frames" in summary:
        extra.append(f"{summary['frames']} frames")
    rows.append(("status", status + (f"  ({', '.join(extra)})" if extra else "")))
    if result_path is not None:
        rows.append(("result", str(result_path)))
    if isinstance(summary.get("dt"), (int, float)):
        line = f"{summary['dt']:.4g} s, limited by {summary.get('dt_limited_by', '?')}"
        if isinstance(summary.get("dt_stable"), (int, float)) and \
                math.isfinite(summary["dt_stable"]):
            line += f" (stability limit {summary['dt_stable']:.4g} s)"
        rows.append(("dt", line))
    if "steps" in summary:
        rows.append(("steps", f"{summary['steps']:,}"))
    if "wall_s" in summary:
        wall = fmt_seconds(summary["wall_s"])
        compiled = summary.get("compile_s")
        if isinstance(compiled, (int, float)) and compiled >= 0.5:
            wall += (f"  (of which {fmt_seconds(compiled)} compiling the engine: not in the "
                     f"speed nor the stages)")
        rows.append(("wall time", wall))
    if "node_steps_per_s" in summary and summary.get("n_nodes", 1) and \
            summary["node_steps_per_s"]:
        speed = f"{fmt_rate(summary['node_steps_per_s'])} node-steps/s"
        if "steps_per_s" in summary:
            speed += f" ({fmt_rate(summary['steps_per_s'])} steps/s"
            if "n_nodes" in summary:
                speed += f", {summary['n_nodes']:,} nodes"
            speed += ")"
        rows.append(("speed", speed))
    elif "steps_per_s" in summary:  # no bristles (bodies only): no node-steps to count
        rows.append(("speed", f"{fmt_rate(summary['steps_per_s'])} steps/s (no bristles)"))
    stages = summary.get("stages") or {}
    if stages:
        total = sum(v for v in stages.values() if isinstance(v, (int, float))) or 1.0
        width = max(len(name) for name in stages)
        first = True
        for name, wall in stages.items():
            share = f"{100 * wall / total:5.1f} %" if isinstance(wall, (int, float)) else ""
            rows.append(("stages" if first else "",
                         f"{name:<{width}}  {fmt_seconds(wall):>9}  {share}"))
            first = False
    warnings = summary.get("warnings") or []
    rows.append(("warnings", "none" if not warnings else warnings[0]))
    for w in warnings[1:]:
        rows.append(("", w))
    error = summary.get("error")
    if isinstance(error, dict) and error.get("message"):
        rows.append(("error", error["message"]))
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"  {k:<{width}}  {v}" for k, v in rows)


class ProgressBar:
    """A tqdm bar over simulated time, with steps/s and the engine's ETA as postfix."""

    # until the first progress report the engine may be compiling (a cold numba cache:
    # minutes): the bar says so only when numba reports a compile (a warm cache loads in
    # seconds and says "starting"), shows no ETA, and its elapsed time keeps counting (a
    # ticker thread redraws it: without reports it sat at [00:00]); the rate and ETA then
    # come from the steps between reports, so that the compile does not count in them
    STARTING = "starting"
    COMPILING = "compiling the engine (first run only)"
    TICK_S = 1.0

    def __init__(self, until: float, start: float, disable: bool):
        from tqdm import tqdm

        self.start = start
        self.last: Optional[tuple[float, int]] = None  # (monotonic time, steps) last report
        self.rate: Optional[float] = None
        self.bar = tqdm(total=max(until - start, 0.0), disable=disable, unit="s",
                        dynamic_ncols=True, leave=True,
                        bar_format="{desc} {percentage:3.0f}%|{bar}| "
                                   "t = {n:.4g}/{total:.4g} s [{elapsed}{postfix}]",
                        desc=self.STARTING)
        self.desc, self.postfix = self.STARTING, ""  # what the bar shows (also when off)
        self.bar.refresh()
        self._done = threading.Event()  # the first report came, or the bar was closed
        self._listener = _CompileSeen(self._compiling)
        from numba.core import event

        event.register("numba:compile", self._listener)
        self._ticker = None
        if not disable:
            self._ticker = threading.Thread(target=self._tick, name="progress-ticker",
                                            daemon=True)
            self._ticker.start()

    def _compiling(self) -> None:
        if not self._done.is_set() and self.desc != self.COMPILING:
            self.desc = self.COMPILING
            self.bar.set_description_str(self.desc, refresh=False)

    def _tick(self) -> None:
        while not self._done.wait(self.TICK_S):
            self.bar.refresh()  # the elapsed time moves while nothing is reported

    def _stop_ticking(self) -> None:
        if not self._done.is_set():
            self._done.set()
            from numba.core import event

            try:
                event.unregister("numba:compile", self._listener)
            except (ValueError, KeyError):
                pass
            if self._ticker is not None and self._ticker is not threading.current_thread():
                self._ticker.join(2.0)

    def __call__(self, p) -> None:
        import time as _time

        now = _time.monotonic()
        if self.last is None:
            self._stop_ticking()
            self.desc = "simulating"
            self.bar.set_description_str(self.desc, refresh=False)
        elif now > self.last[0] and p.steps > self.last[1]:
            rate = (p.steps - self.last[1]) / (now - self.last[0])
            self.rate = rate if self.rate is None else 0.7 * self.rate + 0.3 * rate
        self.last = (now, p.steps)
        self.bar.n = max(min(p.time - self.start, self.bar.total), 0.0)
        if self.rate:
            eta = fmt_seconds(max(p.total_steps - p.steps, 0) / self.rate)
            self.postfix = f"{fmt_rate(self.rate)} steps/s, ETA {eta}"
        else:
            self.postfix = "measuring speed"
        self.bar.set_postfix_str(self.postfix, refresh=False)
        self.bar.refresh()

    def close(self, completed: bool = False) -> None:
        self._stop_ticking()
        if completed:  # the last step lands within rounding of the end time: show 100 %
            self.bar.n = self.bar.total
            self.bar.refresh()
        self.bar.close()


class _CompileSeen:
    """A numba event listener that calls ``seen()`` when a compile starts."""

    def __new__(cls, seen):
        from numba.core import event

        class Listener(event.Listener):
            def on_start(self, ev):
                seen()

            def on_end(self, ev):
                pass

        return Listener()


class CtrlC:
    """While active, the first Ctrl-C (or SIGTERM, as sent by job schedulers and `kill`) sets
    ``event``: the run then stops within one chunk and closes its file as cancelled. A second
    one interrupts at once."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, event: threading.Event):
        self.event = event
        self._old: dict = {}

    def _handler(self, signum, frame):
        if self.event.is_set():
            raise KeyboardInterrupt
        self.event.set()
        what = "Ctrl-C" if signum == signal.SIGINT else "the signal"
        _err(f"\ncancelling ({what} again to abort at once)...")

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                self._old[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old = {}
        return False


def run_in_terminal(scene, output: Path, summary_path: Optional[Path],
                    until: Optional[float], quiet: bool) -> tuple[int, Optional[dict]]:
    """Build and run a validated scene, writing ``output`` (and ``summary_path``). Returns
    (exit code, summary or None)."""
    import engine

    try:
        system = engine.build(scene)
    except engine.SceneError as exc:
        _print_scene_error(exc, "invalid scene")
        return EXIT_BAD_INPUT, None
    if not quiet:
        for w in system.warnings:
            _err(f"warning: {w}")
    cancel = threading.Event()
    end = scene.run.duration if until is None else until
    bar = ProgressBar(end, system.time, disable=quiet)
    result = None
    code = EXIT_OK
    try:
        with CtrlC(cancel):
            result = engine.run(system, until=until, output=output, on_progress=bar,
                                cancel=cancel)
    except engine.InstabilityError as exc:
        bar.close()
        _err(str(exc))
        result = getattr(exc, "result", None)
        code = EXIT_FAILED
    except KeyboardInterrupt:
        bar.close()
        _err("aborted: the result file was closed with the frames recorded so far")
        return EXIT_CANCELLED, None
    except engine.BrushStudioError as exc:
        bar.close()
        _err(f"error: {exc}")
        return EXIT_FAILED, None
    else:
        bar.close(completed=result.status == "completed")
        if result.status == "cancelled":
            code = EXIT_CANCELLED
    summary = dict(result.summary) if result is not None else None
    if summary is not None:
        if summary_path is not None:
            _write_summary(summary_path, summary, result.path)
        if not quiet:
            print(summary_table(summary, result.path))
        else:
            print(f"{summary.get('status', '?')}: {result.path}")
    return code, summary


def output_problem(path: Path, what: str, parents: bool = False) -> Optional[str]:
    """Why ``path`` cannot be written as the file ``what`` (one line), or None: checked
    before a run starts, so that a bad ``-o`` or ``--summary`` does not cost a whole run.
    Only regular files are written (a device, a named pipe, a socket or a folder is refused
    without being opened); a missing folder is refused unless ``parents`` (``--parents``),
    which creates it. See :mod:`engine.io.output_paths`."""
    from engine.io.output_paths import output_file_problem

    import os

    problem = output_file_problem(path, what, parents=parents)
    if problem is not None:
        return problem
    path = Path(path)
    try:
        if parents:
            path.parent.mkdir(parents=True, exist_ok=True)
        # a regular file or nothing (checked above): opening it cannot block; a file made
        # by the probe is removed again
        existed = path.exists()
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK, 0o666)
        os.close(fd)
    except OSError as exc:
        return f"{what} {path}: cannot be written ({exc.strerror or exc})"
    if not existed:
        try:
            path.unlink()
        except OSError:
            pass
    return None
