"""Plots shared by the studies (matplotlib, Agg backend, PNG files)."""
from __future__ import annotations

from pathlib import Path
import textwrap
from typing import Optional, Sequence


class _Figures:
    """The part of pyplot these plots use, on matplotlib's object API: a Figure draws and
    saves without pyplot's state machine and backend machinery (about a third of
    matplotlib's import time, paid by every study that writes a plot)."""

    @staticmethod
    def subplots(*args, **kwargs):
        from matplotlib.figure import Figure

        figsize = kwargs.pop("figsize", None)
        fig = Figure(figsize=figsize)
        return fig, fig.subplots(*args, **kwargs)

    @staticmethod
    def close(fig) -> None:
        fig.clear()


def _plt():
    return _Figures


def _save(fig, path: Path) -> None:
    """Lay the figure out, write it as a PNG (120 dpi) and free it."""
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    _plt().close(fig)


def _finish_depth_plot(fig, ax, ylabel: str, title: str, path: Path) -> None:
    """Label a plot of curves against penetration depth (title, grid, legend) and save it."""
    ax.set_xlabel("penetration depth [mm]")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    _save(fig, path)


def split_phases(depths, forces, phases):
    """(loading depths, forces), (unloading depths, forces); the unloading curve starts at
    the deepest loading point so that the two curves meet there."""
    ld = [(d, f) for d, f, p in zip(depths, forces, phases) if p == "load"]
    ud = [(d, f) for d, f, p in zip(depths, forces, phases) if p == "unload"]
    if ud and ld:
        ud = [ld[-1]] + ud
    return ld, ud


def plot_force_depth(curves: Sequence[tuple], path: Path, title: str,
                     warning: Optional[str] = None) -> None:
    """Loading (solid) and unloading (dashed) force-depth curves: ``curves`` is a list of
    ``(label, depths_m, forces_N, phases)`` (NaN forces, unconverged holds, are left out);
    ``warning`` is written across the plot in red."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 5))
    if warning:
        ax.text(0.5, 0.5, "\n".join(textwrap.wrap(warning, 50)), transform=ax.transAxes,
                ha="center", va="center", color="red", fontsize=10, zorder=10,
                bbox=dict(facecolor="white", alpha=0.8, edgecolor="red"))
    for i, (label, depths, forces, phases) in enumerate(curves):
        color = f"C{i % 10}"
        ld, ud = split_phases(depths, forces, phases)
        if ld:
            ax.plot([d * 1e3 for d, _ in ld], [f for _, f in ld], "o-", color=color, ms=3,
                    label=f"{label} loading")
        if ud:
            ax.plot([d * 1e3 for d, _ in ud], [f for _, f in ud], "s--", color=color, ms=3,
                    mfc="none", label=f"{label} unloading")
    _finish_depth_plot(fig, ax, "vertical root force (change from rest) [N]", title, path)


def plot_mean_std(groups: Sequence[tuple], path: Path, title: str) -> None:
    """Mean ± std per depth (like seed fig. 4.18): ``groups`` is a list of
    ``(label, depths_m, mean_N, std_N, phase)``; loading solid, unloading dashed."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 5))
    colors: dict = {}
    for label, depths, mean, std, phase in groups:
        key = label
        colors.setdefault(key, f"C{len(colors) % 10}")
        ax.errorbar([d * 1e3 for d in depths], mean, yerr=std, color=colors[key],
                    fmt="o-" if phase == "load" else "s--", ms=3, capsize=2, lw=1,
                    mfc=None if phase == "load" else "none", label=f"{label} {phase}")
    _finish_depth_plot(fig, ax, "vertical root force [N] (mean ± std)", title, path)


def plot_refinement(nodes, forces, walls, path: Path, title: str, ceiling=None) -> None:
    """Force at maximum penetration and wall time against nodes per bristle."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4.2))
    a1.plot(nodes, forces, "o-")
    a1.set_xlabel("nodes per bristle")
    a1.set_ylabel("force at maximum penetration [N]")
    a1.grid(alpha=0.3)
    a2.loglog(nodes, walls, "o-")
    a2.set_xlabel("nodes per bristle")
    a2.set_ylabel("wall time per run [s]")
    a2.grid(alpha=0.3, which="both")
    if ceiling is not None:
        for ax in (a1, a2):
            ax.axvline(ceiling, color="grey", ls=":", lw=1)
        a1.text(ceiling, a1.get_ylim()[0], " seed's node-overlap ceiling", rotation=90,
                va="bottom", fontsize=7, color="grey")
    fig.suptitle(title, fontsize=10)
    _save(fig, path)


def plot_sensitivity(panels: Sequence[tuple], path: Path, title: str) -> None:
    """One panel per parameter: ``(parameter label, [(value label, depths, forces, phases)])``
    with loading curves of each value."""
    plt = _plt()
    n = len(panels)
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.8 * rows), squeeze=False)
    for ax, (plabel, curves) in zip(axes.flat, panels):
        for i, (vlabel, depths, forces, phases) in enumerate(curves):
            ld, ud = split_phases(depths, forces, phases)
            ax.plot([d * 1e3 for d, _ in ld], [f for _, f in ld], "o-", ms=2,
                    color=f"C{i}", label=vlabel)
            if ud:
                ax.plot([d * 1e3 for d, _ in ud], [f for _, f in ud], "--", lw=0.8,
                        color=f"C{i}")
        ax.set_title(plabel, fontsize=9)
        ax.set_xlabel("depth [mm]")
        ax.set_ylabel("root force [N]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.suptitle(title, fontsize=10)
    _save(fig, path)
