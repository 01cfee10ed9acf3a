"""The study's files: convergence.csv, .h5, .json and .png, and reading them back."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from engine.jsonable import json_text

from .quantities import CSV_COLUMNS, FORMAT, TOLERANCES
from .table import ConvergenceTable


def _num(v) -> str:
    return "nan" if v is None else repr(float(v))


def write_outputs(table: ConvergenceTable, out_dir, scene_json: str = "") -> None:
    """convergence.csv, convergence.json, convergence.h5 (group /convergence) and
    convergence.png into ``out_dir``; each written to a temporary name and renamed."""
    import h5py

    from engine.io.output_paths import check_output_dir

    # a folder, never a file, a device or a named pipe (created if missing)
    out_dir = check_output_dir(out_dir, "output folder", parents=True)
    tmp = out_dir / ".convergence.csv.tmp"
    with tmp.open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(CSV_COLUMNS)
        for r in table.rows:
            w.writerow([r["level"], "" if r["n_nodes"] is None else r["n_nodes"],
                        _num(r["dt"]), _num(r["quantity"]), _num(r["error"]),
                        _num(r["wall_s"])])
    tmp.replace(out_dir / "convergence.csv")
    data = {"format": FORMAT, "format_version": 1, **table.to_dict()}
    tmp = out_dir / ".convergence.json.tmp"
    tmp.write_text(json_text(data, "null", indent=1) + "\n")
    tmp.replace(out_dir / "convergence.json")
    tmp = out_dir / ".convergence.h5.tmp"
    with h5py.File(tmp, "w") as f:
        g = f.create_group("convergence")
        n = len(table.rows)

        def col(key, fill=math.nan):
            return np.array([fill if r[key] is None else r[key] for r in table.rows], float)

        g.create_dataset("level", data=np.arange(n, dtype=np.int64))
        g.create_dataset("n_nodes", data=np.array(
            [-1 if r["n_nodes"] is None else r["n_nodes"] for r in table.rows], np.int64))
        for key in ("dt", "dt_factor", "quantity", "error", "wall_s"):
            g.create_dataset(key, data=col(key))
        g.create_dataset("status", data=np.array([r["status"] for r in table.rows],
                                                 dtype=h5py.string_dtype()))
        g.create_dataset("run_id", data=np.array([r["run_id"] for r in table.rows],
                                                 dtype=h5py.string_dtype()))
        g.attrs["quantity"] = table.quantity
        g.attrs["unit"] = table.unit
        g.attrs["reference"] = math.nan if table.reference is None else table.reference
        g.attrs["reference_kind"] = table.reference_kind or ""
        g.attrs["reference_note"] = table.reference_note
        g.attrs["observed_order"] = math.nan if table.fitted_order is None else table.fitted_order
        g.attrs["richardson"] = math.nan if table.richardson is None else table.richardson
        g.attrs["richardson_order"] = (math.nan if table.richardson_order is None
                                       else table.richardson_order)
        g.attrs["resolution"] = table.resolution
        if table.setting:  # a loading ladder: its setting's name and value per level
            g.attrs["setting"] = table.setting
            g.create_dataset("setting", data=col("setting"))
        g.attrs["analysis"] = json_text(data, "null")
        g.attrs["scene"] = scene_json
    tmp.replace(out_dir / "convergence.h5")
    plot_convergence(table, out_dir / "convergence.png")


def plot_convergence(table: ConvergenceTable, png_path, ax=None) -> None:
    """Log-log |relative error| against wall time, each point labelled with its level."""
    import matplotlib

    if ax is None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
    pts = [r for r in table.rows if r["error"] not in (None, 0) and r["wall_s"]]
    x = [r["wall_s"] for r in pts]
    y = [abs(r["error"]) for r in pts]
    ax.loglog(x, y, "o-", color="tab:blue")
    for r, xi, yi in zip(pts, x, y):
        label = f"n={r['n_nodes']}" if r["n_nodes"] is not None else ""
        if r["dt_factor"] is not None:
            label += f" dt×{r['dt_factor']:g}"
        ax.annotate(label.strip(), (xi, yi), textcoords="offset points", xytext=(4, 4),
                    fontsize=8)
    for tol, style in zip(TOLERANCES, (":", "--")):
        ax.axhline(tol, color="grey", ls=style, lw=0.8, label=f"{100 * tol:g} %")
    ax.set_xlabel("wall time of the run [s]")
    ax.set_ylabel(f"|relative error| vs {table.reference_kind or '?'} reference")
    ax.set_title(f"{table.scene_name}: {table.quantity}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    if own:
        fig.tight_layout()
        fig.savefig(png_path, dpi=120)
        plt.close(fig)


def load_convergence(out_dir) -> ConvergenceTable:
    """Read a finished convergence study back from its folder (``convergence.json``; the
    studio shows it as a table and a plot)."""
    path = Path(out_dir) / "convergence.json"
    if not path.exists():
        raise FileNotFoundError(f"{path}: not a convergence study folder (no convergence.json)")
    data = json.loads(path.read_text())
    if data.get("format") != FORMAT:
        raise ValueError(f"{path}: not a convergence study (format {data.get('format')!r})")
    data.pop("format", None)
    data.pop("format_version", None)
    return ConvergenceTable(**data)
