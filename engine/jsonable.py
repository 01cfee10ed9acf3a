"""Strict JSON for result-file attributes, scene errors, summaries, API answers and study
files: one conversion for every writer, the engine's and the studio's.

Plain Python (numpy values are recognised by their ``tolist``), so that the light modules
(``engine.errors``) can use it without importing numpy.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Mapping, Optional


def jsonable(value: Any, nonfinite: str = "text") -> Any:
    """A strict-JSON copy of ``value``: dict keys as text, tuples as lists, numpy arrays and
    scalars as Python lists and numbers, paths as text, anything else as its str().
    Non-finite floats become the strings "nan", "inf", "-inf" (``nonfinite="text"``, as
    result files write them) or null (``nonfinite="null"``, for the HTTP API)."""
    if isinstance(value, bool) or value is None or isinstance(value, (str, int)):
        return value
    if isinstance(value, float):
        if math.isfinite(value):
            return value
        if nonfinite == "null":
            return None
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, Mapping):
        return {str(k): jsonable(v, nonfinite) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v, nonfinite) for v in value]
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "tolist"):  # numpy arrays and scalars
        return jsonable(value.tolist(), nonfinite)
    return str(value)


def jsonable_null(value: Any) -> Any:
    """:func:`jsonable` with non-finite floats as null: what the HTTP API and the job
    database hold."""
    return jsonable(value, nonfinite="null")


def finite_or_none(value: Any) -> Optional[float]:
    """``value`` as a finite float, or None (JSON null) when it is not a number (a CSV
    cell, a missing field) or not finite: what a chart plots and a job's row stores."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def json_text(value: Any, nonfinite: str = "text", **dumps) -> str:
    """Strict JSON text of :func:`jsonable` ``(value, nonfinite)``: no NaN or Infinity token
    can reach it (``json.dumps(..., allow_nan=False)``); ``dumps``: e.g. ``indent``."""
    return json.dumps(jsonable(value, nonfinite), allow_nan=False, **dumps)
