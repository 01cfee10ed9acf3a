"""Observed orders of convergence and Richardson extrapolation; the convergence table and its
analysis (:func:`analyse`)."""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from typing import Optional, Sequence

import numpy as np

from engine.jsonable import jsonable_null as _json_null
from .quantities import ConvergenceError, Quantity, TOLERANCES
from .references import Reference
from .ladder import Level, level_resolution


def observed_orders(h: Sequence[float], errors: Sequence[float]) -> list[float]:
    """Order between successive levels, log(e_i / e_{i+1}) / log(h_i / h_{i+1}) (NaN where an
    error is zero or the resolutions are equal)."""
    out = []
    for i in range(len(h) - 1):
        e0, e1 = abs(errors[i]), abs(errors[i + 1])
        if e0 > 0 and e1 > 0 and h[i] != h[i + 1]:
            out.append(math.log(e0 / e1) / math.log(h[i] / h[i + 1]))
        else:
            out.append(math.nan)
    return out


def fitted_order(h: Sequence[float], errors: Sequence[float]) -> float:
    """Least-squares slope of log|error| against log h (NaN with fewer than two usable
    levels)."""
    pts = [(math.log(a), math.log(abs(e))) for a, e in zip(h, errors) if e != 0 and a > 0]
    if len(pts) < 2 or len({p[0] for p in pts}) < 2:
        return math.nan
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])


def richardson(h: Sequence[float], q: Sequence[float]) -> tuple[float, float]:
    """Richardson extrapolation from the last three levels (h decreasing): the observed order
    p solving (q1 - q2) / (q2 - q3) = (h1^p - h2^p) / (h2^p - h3^p) (any refinement ratios),
    and the extrapolated value q3 + (q3 - q2) / ((h2 / h3)^p - 1).

    Returns (estimate, p); (NaN, NaN) when the three do not converge monotonically (the
    differences change sign or do not shrink) or p falls outside (0.1, 12)."""
    from scipy.optimize import brentq

    if len(q) < 3:
        return math.nan, math.nan
    h1, h2, h3 = (float(v) for v in h[-3:])
    q1, q2, q3 = (float(v) for v in q[-3:])
    d12, d23 = q1 - q2, q2 - q3
    if not (h1 > h2 > h3 > 0) or d23 == 0 or d12 == 0 or d12 * d23 < 0:
        return math.nan, math.nan
    ratio = d12 / d23

    def f(p):
        return (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - ratio

    lo, hi = 0.1, 12.0
    if f(lo) * f(hi) > 0:
        return math.nan, math.nan
    p = brentq(f, lo, hi, xtol=1e-12)
    return q3 + (q3 - q2) / ((h2 / h3) ** p - 1.0), p


@dataclass
class ConvergenceTable:
    """A convergence study: one row per level plus the reference and the observed order.

    ``rows``: dicts with level, n_nodes, dt, dt_factor, quantity, error (relative, against
    ``reference``), wall_s (the run's own wall time), status, run_id, h5, message.
    ``cheapest``: ``{"0.01": row or None, "0.05": ...}``, the level with the least wall time
    whose |error| is within that tolerance (for a ``finest`` reference the finest level itself
    is excluded)."""

    quantity: str
    unit: str
    scene_name: str
    reference: Optional[float]
    reference_kind: Optional[str]
    reference_note: str
    resolution: str
    observed_orders: list
    fitted_order: Optional[float]
    richardson: Optional[float]
    richardson_order: Optional[float]
    rows: list = field(default_factory=list)
    cheapest: dict = field(default_factory=dict)
    measured_at: str = ""
    setting: Optional[str] = None      # a loading ladder's protocol setting (rows' "setting")
    curve_changes: list = field(default_factory=list)  # each level's curve against the last

    def to_dict(self) -> dict:
        return _json_null(asdict(self))

    def text(self) -> str:
        """A printable table and the analysis below it."""
        name = f"{self.quantity} [{self.unit}]"
        lines = [f"{'level':>5} {'n_nodes':>7} {'dt [s]':>11} {name:>24} "
                 f"{'error':>10} {'wall [s]':>9}  status"]
        if self.setting:
            lines[0] = f"{self.setting:>19} " + lines[0]
        for r in self.rows:
            q = "nan" if r["quantity"] is None else f"{r['quantity']:.6g}"
            e = "nan" if r["error"] is None else f"{r['error']:+.3e}"
            w = "nan" if r["wall_s"] is None else f"{r['wall_s']:.2f}"
            dt = "auto" if r["dt"] is None else f"{r['dt']:.4g}"
            n = "" if r["n_nodes"] is None else str(r["n_nodes"])
            lines.append(("" if not self.setting else f"{r['setting']:>19g} ") +
                         f"{r['level']:>5} {n:>7} {dt:>11} {q:>24} {e:>10} {w:>9}  "
                         f"{r['status']}{'  ' + r['message'] if r.get('message') else ''}")
        ref = "none" if self.reference is None else f"{self.reference:.8g} {self.unit}"
        lines.append(f"reference: {ref} ({self.reference_kind}: {self.reference_note})")
        if self.richardson is not None:
            lines.append(f"Richardson estimate of the three finest levels: "
                         f"{self.richardson:.8g} {self.unit}, observed order "
                         f"{self.richardson_order:.3g}")
        orders = ", ".join("nan" if o is None else f"{o:.3g}" for o in self.observed_orders)
        if orders:
            fit = "nan" if self.fitted_order is None else f"{self.fitted_order:.3g}"
            lines.append(f"observed order between levels (h = {self.resolution}): {orders}; "
                         f"least-squares fit: {fit}")
        for c in self.curve_changes:
            if c is None:
                continue
            where = "" if c["at_depth_m"] is None else f" (at {c['at_depth_m'] * 1e3:g} mm)"
            lines.append(f"whole curve, level {c['level']} against {c['against_level']}: "
                         f"largest change {c['max_rel_change']:.2%}{where} over forces above "
                         f"{c['compared_above_N']:.3g} N; "
                         f"{'within' if c['converged'] else 'NOT within'} "
                         f"{c['tolerance']:.0%}")
        for tol, row in self.cheapest.items():
            pct = f"{100 * float(tol):g} %"
            lines.append(f"cheapest level within {pct}: " + (
                "none" if row is None else
                f"level {row['level']} (" + (
                    f"{self.setting} {row['setting']:g}" if self.setting else
                    f"n_nodes {row['n_nodes']}, dt {row['dt']:.4g} s") +
                f") in {row['wall_s']:.2f} s"))
        return "\n".join(lines)


def analyse(quantity: Quantity, levels: Sequence[Level], values: Sequence[float],
            walls: Sequence[float], statuses: Sequence[str], messages: Sequence[str],
            dts: Sequence[Optional[float]], analytic: Optional[Reference],
            reference: str = "auto", scene_name: str = "", run_ids=None,
            h5s=None) -> ConvergenceTable:
    """Errors, observed orders, Richardson estimate and cheapest levels of a finished
    ladder. ``reference``: auto | analytic | richardson | finest."""
    h_all, resolution = level_resolution(levels)
    ok = [i for i, v in enumerate(values) if v is not None and math.isfinite(v)]
    h_ok = [h_all[i] for i in ok]
    q_ok = [values[i] for i in ok]
    rich, rich_p = richardson(h_ok, q_ok) if len(ok) >= 3 else (math.nan, math.nan)
    ref: Optional[Reference] = None
    if reference in ("auto", "analytic") and analytic is not None:
        ref = analytic
    elif reference == "analytic":
        raise ConvergenceError(f"no analytic reference for {quantity.text} in this scene "
                               "(analytic references: single-bristle rod cases)")
    if ref is None and reference in ("auto", "richardson") and math.isfinite(rich):
        ref = Reference(rich, "richardson", f"Richardson extrapolation of the three finest "
                        f"levels, observed order {rich_p:.3g}")
    if ref is None and reference == "richardson":
        raise ConvergenceError("no Richardson estimate: it needs three finished levels that "
                               "converge monotonically")
    finest_index = None
    if ref is None and ok:
        finest_index = ok[-1]
        ref = Reference(values[finest_index], "finest",
                        f"the finest level ({finest_index}) itself")
    errors = []
    for v in values:
        if ref is None or v is None or not math.isfinite(v) or ref.value == 0:
            errors.append(None)
        else:
            errors.append((v - ref.value) / abs(ref.value))
    if ref is not None and ref.kind == "finest":
        e_ok = [errors[i] for i in ok[:-1]]
        orders = observed_orders(h_ok[:-1], e_ok)
        fit = fitted_order(h_ok[:-1], e_ok)
    else:
        e_ok = [errors[i] for i in ok]
        orders = observed_orders(h_ok, e_ok)
        fit = fitted_order(h_ok, e_ok)
    rows = []
    for i, lv in enumerate(levels):
        rows.append({"level": lv.level, "n_nodes": lv.n_nodes, "dt": dts[i],
                     "dt_factor": lv.dt_factor,
                     "setting": None if lv.setting is None else lv.setting[1],
                     "quantity": values[i], "error": errors[i],
                     "wall_s": walls[i], "status": statuses[i], "message": messages[i],
                     "run_id": run_ids[i] if run_ids else lv.run_id,
                     "h5": str(h5s[i]) if h5s else None})
    cheapest = {}
    for tol in TOLERANCES:
        best = None
        for i, r in enumerate(rows):
            if r["error"] is None or r["wall_s"] is None or i == finest_index:
                continue
            if abs(r["error"]) <= tol and (best is None or r["wall_s"] < best["wall_s"]):
                best = r
        cheapest[f"{tol:g}"] = best
    table = ConvergenceTable(
        quantity=quantity.text, unit=quantity.unit, scene_name=scene_name,
        reference=None if ref is None else ref.value,
        reference_kind=None if ref is None else ref.kind,
        reference_note="" if ref is None else ref.note, resolution=resolution,
        observed_orders=[None if not math.isfinite(o) else o for o in orders],
        fitted_order=fit if math.isfinite(fit) else None,
        richardson=rich if math.isfinite(rich) else None,
        richardson_order=rich_p if math.isfinite(rich_p) else None,
        rows=rows, cheapest=cheapest,
        measured_at=time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
        setting=levels[0].setting[0] if levels and levels[0].setting else None)
    return table
