"""Durations, rates and lengths as people read them, the same in the terminal and in the
studio."""
from __future__ import annotations

import math


def fmt_seconds(s, decimals: int = 2) -> str:
    """``12.34 s``, ``250 ms``, ``3 min 05 s``; ``?`` for a missing or non-finite value.
    ``decimals``: digits of the seconds between 1 s and 2 min."""
    if not isinstance(s, (int, float)) or not math.isfinite(s):
        return "?"
    if s <= 0:
        return "0 s"
    if s < 1e-3:
        return f"{s * 1e6:.0f} us"
    if s < 1:
        return f"{s * 1e3:.0f} ms"
    if s < 120:
        return f"{s:.{decimals}f} s"
    return f"{int(s // 60)} min {s % 60:02.0f} s"


def fmt_rate(x) -> str:
    """A rate with a k/M/G suffix and 3 significant digits; ``?`` when missing."""
    if not isinstance(x, (int, float)) or not math.isfinite(x):
        return "?"
    for div, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if abs(x) >= div:
            return f"{x / div:.3g}{suffix}"
    return f"{x:.3g}"


def fmt_length(metres: float, number=lambda v: f"{v:g}") -> str:
    """A length in the unit a person reads it best in: ``5 km`` from 1 km, ``2 m`` from 1 m,
    else ``0.5 mm``; ``number`` writes the value in that unit (default ``:g``)."""
    if metres >= 1000.0:
        return f"{number(metres / 1000.0)} km"
    if metres >= 1.0:
        return f"{number(metres)} m"
    return f"{number(metres * 1e3)} mm"
