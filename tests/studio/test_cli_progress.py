"""The run's progress bar (issue 13, item 9): before the first report (a cold numba cache
compiles for minutes) it says it is compiling and shows no ETA; its rate and ETA come from
the steps between reports, so the compile does not inflate them (it showed "ETA 825 min")."""
from __future__ import annotations

import types

from studio.cli.run_console import ProgressBar as _ProgressBar


def _report(steps, total=10_000):
    # the engine's own figures include the compile: a rate of 1 step/s, an ETA of 14 h
    return types.SimpleNamespace(time=steps / total, steps=steps, total_steps=total,
                                 steps_per_s=1.0, eta_s=49_500.0)


def _numba_compiles():
    from numba.core import event

    event.start_event("numba:compile", data={"dispatcher": None, "args": ()})
    event.end_event("numba:compile", data={"dispatcher": None, "args": ()})


def test_compiling_is_said_only_when_numba_compiles_and_the_clock_moves(capsys):
    """Issue 28, item 10. Bugs caught: "compiling the engine (first run only)" printed on
    every run, warm ones too; the bar's elapsed time sat at [00:00] for the whole compile."""
    import time

    bar = _ProgressBar(1.0, 0.0, disable=False)
    time.sleep(2.5)  # no report: a ticker redraws the bar
    warm = capsys.readouterr().err
    assert "compiling" not in warm and "starting" in warm
    import re

    shown = re.findall(r"\[(\d\d):(\d\d)", warm)
    assert max(int(m) * 60 + int(s) for m, s in shown) >= 1, warm  # moved, with no report
    _numba_compiles()
    time.sleep(1.5)
    bar(_report(1000))
    assert "compiling the engine" in capsys.readouterr().err
    _numba_compiles()  # a later compile (a kernel first used while recording): not said
    assert bar.desc == "simulating"
    bar.close()


def test_no_eta_while_compiling_and_none_from_the_compile(monkeypatch):
    clock = [100.0]
    monkeypatch.setattr("time.monotonic", lambda: clock[0])
    bar = _ProgressBar(1.0, 0.0, disable=True)
    assert bar.desc == "starting" and "ETA" not in bar.postfix
    _numba_compiles()  # numba says it compiles: the bar says so
    assert "compiling the engine" in bar.desc and "ETA" not in bar.postfix
    clock[0] += 300.0  # the compile
    bar(_report(1000))
    assert bar.desc == "simulating" and "ETA" not in bar.postfix
    clock[0] += 1.0  # then 1000 steps a second
    bar(_report(2000))
    assert "1k steps/s" in bar.postfix and "ETA 8" in bar.postfix  # 8000 steps left
    bar.close()


def test_the_summary_shows_the_compile_apart_from_the_speed():
    from studio.cli.run_console import summary_table

    summary = {"status": "completed", "wall_s": 130.0, "compile_s": 120.0, "steps": 10_000,
               "steps_per_s": 1000.0, "node_steps_per_s": 4e4, "n_nodes": 40,
               "stages": {"bonds": 6.0, "recording": 4.0}}
    text = summary_table(summary)
    assert "2 min 10 s  (of which 2 min 00 s compiling the engine" in text
    # the shares are of the stages' own total (10 s), the compile is not among them
    assert "60.0 %" in text and "40.0 %" in text
    warm = summary_table(dict(summary, compile_s=0.001, wall_s=10.0))
    assert "compiling" not in warm
