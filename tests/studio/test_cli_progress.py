"""The run's progress bar (issue 13, item 9): before the first report (a cold numba cache
compiles for minutes) it says it is compiling and shows no ETA; its rate and ETA come from
the steps between reports, so the compile does not inflate them (it showed "ETA 825 min")."""
from __future__ import annotations

import types

from studio.cli import _ProgressBar


def _report(steps, total=10_000):
    # the engine's own figures include the compile: a rate of 1 step/s, an ETA of 14 h
    return types.SimpleNamespace(time=steps / total, steps=steps, total_steps=total,
                                 steps_per_s=1.0, eta_s=49_500.0)


def test_no_eta_while_compiling_and_none_from_the_compile(monkeypatch):
    clock = [100.0]
    monkeypatch.setattr("time.monotonic", lambda: clock[0])
    bar = _ProgressBar(1.0, 0.0, disable=True)
    assert "compiling the engine" in bar.desc and "ETA" not in bar.postfix
    clock[0] += 300.0  # the compile
    bar(_report(1000))
    assert bar.desc == "simulating" and "ETA" not in bar.postfix
    clock[0] += 1.0  # then 1000 steps a second
    bar(_report(2000))
    assert "1k steps/s" in bar.postfix and "ETA 8" in bar.postfix  # 8000 steps left
    bar.close()
