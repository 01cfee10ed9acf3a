"""Interactive charts of a study's results for the Studies tab (issue 14, item 10): plotly
figures read from the CSV files the studies write (their documented columns, SI), shown
in millimetres, degrees per second... at this edge. No viser in here.

``study_charts(study, folder, files)`` -> ``[(title, figure), ...]``; a study (or a file)
with no chart here keeps its PNG plots in the tab. ``study_eta`` is the progress line's
time left.
"""
from __future__ import annotations

import csv
import math
import time
from pathlib import Path
from typing import Optional

from engine.jsonable import finite_or_none

HEIGHT = 420              # px of one chart in the side panel (a plot area over 250 px tall)
MAX_SERIES = 12           # traces in one chart (more runs: the first ones)


def read_csv(path: Path) -> list[dict]:
    """Rows of a CSV file as dicts of text."""
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _layout(fig, title: str, x: str, y: str, legend: bool = True) -> None:
    # (the title sits above the plot area, clear of plotly's toolbar at the top right)
    fig.update_layout(title=dict(text=title, font=dict(size=13), x=0.02, y=0.97),
                      xaxis=dict(title=x), yaxis=dict(title=y), height=HEIGHT,
                      margin=dict(l=55, r=10, t=55, b=115 if legend else 45),
                      showlegend=legend,
                      # below the x-axis title, not over it (issue 29, item 6): anchored by
                      # its top, under the title's band (a fraction of the plot area's
                      # height: 0.3 of the side panel's ~200 px is 60 px, past the tick
                      # labels and the title)
                      legend=dict(orientation="h", x=0.0, y=-0.3, yanchor="top",
                                  font=dict(size=10)),
                      hovermode="closest")


def force_depth_figure(rows: list[dict]):
    """The wedge study's force against depth (force_depth.csv: depth_m, force_N, phase
    [, angle_deg, run_id]): one line per run and phase, depth in mm."""
    import plotly.graph_objects as go

    series: dict[tuple, tuple[list, list]] = {}
    for r in rows:
        d, f = finite_or_none(r.get("depth_m")), finite_or_none(r.get("force_N"))
        if d is None or f is None:
            continue
        run = r.get("run_id") or (f"{r['angle_deg']} deg" if r.get("angle_deg") else "")
        xs, ys = series.setdefault((run, r.get("phase") or ""), ([], []))
        xs.append(d * 1e3)
        ys.append(f)
    fig = go.Figure()
    for (run, phase), (xs, ys) in list(series.items())[:MAX_SERIES]:
        name = " ".join(p for p in (run, phase) if p) or "force"
        fig.add_scatter(x=xs, y=ys, mode="lines+markers", name=name,
                        line=dict(dash="dot" if phase == "unload" else "solid"))
    _layout(fig, "wedge force against depth", "depth [mm]", "force on the wedge [N]",
            legend=len(series) > 1)
    return fig


def omega_figure(rows: list[dict]):
    """The spin study's angular velocity about the hinge (omega.csv: run_id, time, omega
    [rad/s], contact_force [N]): one line per run, in deg/s."""
    import plotly.graph_objects as go

    series: dict[str, tuple[list, list]] = {}
    for r in rows:
        t, w = finite_or_none(r.get("time")), finite_or_none(r.get("omega"))
        if t is None or w is None:
            continue
        xs, ys = series.setdefault(r.get("run_id") or "run", ([], []))
        xs.append(t)
        ys.append(math.degrees(w))
    fig = go.Figure()
    for run, (xs, ys) in list(series.items())[:MAX_SERIES]:
        fig.add_scatter(x=xs, y=ys, mode="lines", name=run)
    _layout(fig, "cube angular velocity about the hinge", "time [s]", "ω [deg/s]")
    return fig


def refinement_figure(rows: list[dict]):
    """The refinement study (refinement.csv): force and wall time against nodes per
    bristle, wall time on a second axis."""
    import plotly.graph_objects as go

    pts = [(finite_or_none(r.get("nodes_per_bristle")), finite_or_none(r.get("force_N")),
            finite_or_none(r.get("wall_s"))) for r in rows]
    pts = [p for p in pts if p[0] is not None]
    fig = go.Figure()
    fig.add_scatter(x=[p[0] for p in pts], y=[p[1] for p in pts], mode="lines+markers",
                    name="force [N]")
    fig.add_scatter(x=[p[0] for p in pts], y=[p[2] for p in pts], mode="lines+markers",
                    name="wall time [s]", yaxis="y2", line=dict(dash="dot"))
    _layout(fig, "force at full depth against refinement", "nodes per bristle",
            "force [N]")
    fig.update_layout(yaxis2=dict(title="wall time [s]", overlaying="y", side="right"),
                      margin=dict(l=55, r=55, t=55, b=45))
    return fig


#: study -> [(file, chart builder)]: the charts the tab draws for that study
CHARTS = {
    "wedge": [("force_depth.csv", force_depth_figure)],
    "spin": [("omega.csv", omega_figure)],
    "refinement": [("refinement.csv", refinement_figure)],
}


def study_charts(study: Optional[str], folder: Path, files: list[str]) -> list:
    """``[(file, figure), ...]`` for a finished study's files in ``folder``; a file that
    cannot be read gives ``(file, error text)`` instead of a figure."""
    out = []
    for name, build in CHARTS.get(study or "", []):
        if name not in files:
            continue
        try:
            out.append((name, build(read_csv(Path(folder) / name))))
        except (OSError, ValueError, KeyError) as exc:
            out.append((name, f"cannot chart {name}: {exc}"))
    return out


def study_eta(info, now: Optional[float] = None) -> Optional[float]:
    """Seconds left of a running study job (``studio.service.jobs`` JobInfo): the job's own
    estimate when it has one, else the elapsed time scaled by the progress left (None
    before any progress)."""
    if info.status != "running":
        return None
    if info.eta_s is not None and math.isfinite(info.eta_s):
        return max(float(info.eta_s), 0.0)
    p = float(info.progress or 0.0)
    if info.started is None or not 0.0 < p <= 1.0:
        return None
    elapsed = (time.time() if now is None else now) - float(info.started)
    return max(elapsed * (1.0 - p) / p, 0.0)


LARGE_HEIGHT = 600        # px of one chart in the pop-out window


def large_layout(fig):
    """``fig`` laid out for the pop-out window (issue 29, item 7): taller, larger type,
    the legend at the right of the plot area (clear of both axis titles). Returns it."""
    fig.update_layout(height=LARGE_HEIGHT, font=dict(size=14),
                      title=dict(font=dict(size=17)),
                      margin=dict(l=80, r=30, t=60, b=70),
                      legend=dict(orientation="v", x=1.02, y=1.0, xanchor="left",
                                  yanchor="top", font=dict(size=13)))
    if "yaxis2" in fig.layout and fig.layout.yaxis2.overlaying:
        # (a second y axis at the right: the legend goes right of its title)
        fig.update_layout(legend=dict(x=1.12), margin=dict(r=30))
    return fig
