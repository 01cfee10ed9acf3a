"""Runs side by side (issue 29, item 7): the force, angular velocity and force–depth curves
of two or more runs overlaid (and a measured curve the user uploads as CSV), with a table of
their headline figures, each run labelled by what differs between the designs. Numpy and
plotly only, no viser: the Results tab's *Compare* panel shows them
(``studio.web.panels.compare``).
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from studio.plots.result_plots import BODY_COLORS, press_depth_of

#: scene entries that never make a difference worth a label
_IGNORED = {"name", "description", "schema_version"}


@dataclass
class RunCurves:
    """What the comparison reads of one run (SI; the plots convert)."""

    job: str
    name: str
    status: str
    scene: dict
    time: np.ndarray
    root_force: Optional[np.ndarray] = None         # (F, 3), summed over brushes
    contact_force: dict = field(default_factory=dict)   # body -> (F, 3)
    omega: dict = field(default_factory=dict)           # moving body -> (F, 3) rad/s
    depth: Optional[tuple[str, np.ndarray]] = None      # (pressed body, depth per frame)
    label: str = ""


def read_run(job: str, name: str, path: Path, scene: Optional[dict] = None) -> RunCurves:
    """The curves of a run's result file (``engine.open_result``)."""
    import engine

    with engine.open_result(path) as r:
        channels = set(r.channels())
        t = np.asarray(r.time, float)
        scene = scene if scene is not None else (r.json_attr("scene") or {})
        bodies = [b.get("name") for b in scene.get("bodies") or []]
        motions = {b.get("name"): (b.get("motion") or {}).get("type")
                   for b in scene.get("bodies") or []}
        run = RunCurves(job, name, r.status, scene, t)
        forces = [np.asarray(r.series(c), float) for c in sorted(channels)
                  if c.startswith("brushes/") and c.endswith("/root_force")]
        if forces:
            run.root_force = np.sum(forces, axis=0)
        for b in bodies:
            c = f"bodies/{b}/contact_force"
            if c in channels:
                run.contact_force[b] = np.asarray(r.series(c), float)
            w = f"bodies/{b}/angular_velocity"
            if w in channels and motions.get(b) != "fixed":
                run.omega[b] = np.asarray(r.series(w), float)
        run.depth = press_depth_of(r, bodies)
    return run


def _flatten(obj, prefix: str = "") -> dict:
    out = {}
    if isinstance(obj, dict):
        for k, v in obj.items():
            if not prefix and k in _IGNORED:
                continue
            out.update(_flatten(v, f"{prefix}{k}."))
    elif isinstance(obj, list) and obj and all(isinstance(v, (dict, list)) for v in obj):
        for i, v in enumerate(obj):
            out.update(_flatten(v, f"{prefix}{i}."))
    else:
        out[prefix.rstrip(".")] = obj
    return out


def _short(path: str) -> str:
    """``brushes.0.root_radius`` -> ``root_radius``; ``bodies.0.pose.position`` ->
    ``pose.position`` (the last names, without list indices)."""
    parts = [p for p in path.split(".") if not p.isdigit()]
    return ".".join(parts[-2:]) if len(parts) > 1 and parts[-2] not in (
        "brushes", "bodies", "materials", "run", "environment") else parts[-1]


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


def label_runs(runs: list[RunCurves], max_items: int = 3) -> None:
    """Label each run by the scene entries that differ between the runs (SI values, as in
    the scene file), e.g. ``rows = 3, root_radius = 0.0008``; runs of one same design keep
    their name and job id."""
    flats = [_flatten(r.scene) for r in runs]
    keys = sorted(set().union(*flats)) if flats else []
    differing = [k for k in keys if len({repr(f.get(k)) for f in flats}) > 1]
    for run, flat in zip(runs, flats):
        items = [f"{_short(k)} = {_fmt(flat.get(k))}" for k in differing[:max_items]]
        more = len(differing) - max_items
        label = ", ".join(items) + (f" (+{more} more)" if more > 0 else "")
        run.label = f"{label} · {run.job}" if label else f"{run.name} · {run.job}"


def headline(run: RunCurves) -> dict:
    """The figures of the comparison table: how the run ended, how long it ran, the peak
    root force, the peak contact force on a body, the deepest press, the final |ω|."""
    out = {"run": run.label, "status": run.status,
           "t_end_s": float(run.time[-1]) if len(run.time) else 0.0,
           "frames": int(len(run.time))}
    out["peak_root_force_N"] = float(np.linalg.norm(run.root_force, axis=1).max()) \
        if run.root_force is not None and len(run.root_force) else None
    peaks = [float(np.linalg.norm(f, axis=1).max()) for f in run.contact_force.values()
             if len(f)]
    out["peak_contact_force_N"] = max(peaks) if peaks else None
    out["max_depth_mm"] = float(np.max(run.depth[1]) * 1e3) if run.depth is not None \
        else None
    finals = [float(np.degrees(np.linalg.norm(w[-1]))) for w in run.omega.values() if len(w)]
    out["final_omega_deg_s"] = max(finals) if finals else None
    return out


def table_markdown(rows: list[dict]) -> str:
    heads = [("run", "run"), ("status", "status"), ("t_end_s", "t end [s]"),
             ("frames", "frames"), ("peak_root_force_N", "peak root force [N]"),
             ("peak_contact_force_N", "peak contact force [N]"),
             ("max_depth_mm", "max depth [mm]"), ("final_omega_deg_s", "final spin rate [deg/s]")]
    used = [(k, h) for k, h in heads if any(r.get(k) is not None for r in rows)]
    lines = ["| " + " | ".join(h for _, h in used) + " |",
             "|" + "---|" * len(used)]
    for r in rows:
        cells = []
        for k, _ in used:
            v = r.get(k)
            cells.append("–" if v is None else (f"{v:.4g}" if isinstance(v, float)
                                                else str(v).replace("|", "\\|")))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


@dataclass
class Measured:
    """A measured curve the user uploaded: x is the time [s] or the depth [mm]."""

    name: str
    x_kind: str        # "time" or "depth"
    x: np.ndarray
    y: np.ndarray      # force [N]


def parse_measured_csv(name: str, text: str) -> Measured:
    """A CSV of two columns with a header: ``time [s]`` (or ``depth [mm]``) and
    ``force [N]``. Raises ValueError naming the problem."""
    rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)]
    if len(rows) < 3:
        raise ValueError(f"{name}: a header and at least two rows of numbers are needed")
    head = [c.strip().lower() for c in rows[0]]
    if len(head) < 2:
        raise ValueError(f"{name}: two columns are needed (time [s] or depth [mm], "
                         f"force [N])")
    x_kind = "depth" if "depth" in head[0] else "time" if "time" in head[0] else None
    if x_kind is None:
        raise ValueError(f"{name}: the first column must be 'time [s]' or 'depth [mm]', "
                         f"not {rows[0][0]!r}")
    try:
        data = np.array([[float(r[0]), float(r[1])] for r in rows[1:]])
    except (ValueError, IndexError):
        raise ValueError(f"{name}: every row after the header must be two numbers") from None
    if not np.all(np.isfinite(data)):
        raise ValueError(f"{name}: non-finite numbers")
    return Measured(name, x_kind, data[:, 0], data[:, 1])


def compare_figures(runs: list[RunCurves], measured: Optional[Measured] = None) -> dict:
    """The overlay plots by title: root |F| against time, contact |F| on the bodies against
    time, |ω| against time, root |F| against depth (runs with a press); a measured curve
    on the plot its x belongs to. One colour per run."""
    import plotly.graph_objects as go

    figs = {}
    color = {r.job: BODY_COLORS[n % len(BODY_COLORS)] for n, r in enumerate(runs)}

    def fig(title, x_title):
        if title not in figs:
            f = go.Figure()
            f.update_layout(title=dict(text=title, font=dict(size=14)),
                            xaxis_title=x_title, margin=dict(l=50, r=10, t=34, b=40),
                            legend=dict(font=dict(size=11), orientation="h", y=-0.25))
            figs[title] = f
        return figs[title]

    for r in runs:
        if r.root_force is not None:
            fig("root |F| [N]", "time [s]").add_scatter(
                x=r.time, y=np.linalg.norm(r.root_force, axis=1), name=r.label,
                mode="lines", line=dict(color=color[r.job]))
        dashes = ("solid", "dash", "dot", "dashdot")
        for n, (b, f) in enumerate(r.contact_force.items()):
            if np.any(f):
                fig("contact |F| on bodies [N]", "time [s]").add_scatter(
                    x=r.time, y=np.linalg.norm(f, axis=1), name=f"{r.label}: {b}",
                    mode="lines", line=dict(color=color[r.job], dash=dashes[n % 4]))
        for n, (b, w) in enumerate(r.omega.items()):
            if np.any(w):
                fig("|ω| [deg/s]", "time [s]").add_scatter(
                    x=r.time, y=np.degrees(np.linalg.norm(w, axis=1)),
                    name=f"{r.label}: {b}", mode="lines",
                    line=dict(color=color[r.job], dash=dashes[n % 4]))
        if r.depth is not None and r.root_force is not None:
            fig("root |F| [N] against depth [mm]", "depth [mm]").add_scatter(
                x=r.depth[1] * 1e3, y=np.linalg.norm(r.root_force, axis=1), name=r.label,
                mode="lines", line=dict(color=color[r.job]))
    if measured is not None:
        title = "root |F| [N] against depth [mm]" if measured.x_kind == "depth" \
            else "root |F| [N]"
        fig(title, "depth [mm]" if measured.x_kind == "depth" else "time [s]").add_scatter(
            x=measured.x, y=measured.y, name=f"measured: {measured.name}",
            mode="lines+markers", line=dict(color="#000000", dash="dot"),
            marker=dict(size=4))
    return figs
