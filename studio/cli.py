"""The ``brush-studio`` command line: run, validate and inspect scenes and results.

    brush-studio demo [-o DIR]                  run the embedded default scene, plot it
    brush-studio run SCENE.json -o RESULT.h5    run a scene (progress bar, Ctrl-C cancels)
    brush-studio validate SCENE.json            check a scene without running it
    brush-studio info RESULT.h5                 what a result file holds

A thin layer: everything it knows about scenes, runs and results comes from the engine's
public API (``import engine``). Exit codes: 0 completed or stopped, 1 failed (instability or
another engine error), 2 bad input (an invalid scene, a bad command line), 130 cancelled.
"""
from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
from pathlib import Path
from typing import Optional

from . import __version__, app, serve_cli
from .console import err as _err, print_scene_error as _print_scene_error
from .fmt import fmt_rate, fmt_seconds
from .exit_codes import EXIT_BAD_INPUT, EXIT_CANCELLED, EXIT_FAILED, EXIT_OK
from engine.jsonable import json_text
from .presets import demo_scene_text
from .studies import cli as studies_cli
from .studies import convergence, dissipation


DEMO_DIR = "brush-studio-demo"

# Modules that add their own subcommands: each has ``register(subparsers)`` and imports its
# heavy dependencies (dask, fastapi, viser) only inside the command it runs. This module is
# the composition root: it imports them, none of them imports it.
COMMAND_MODULES = (app, convergence, studies_cli, serve_cli, dissipation)


# ----------------------------------------------------------------------------- output helpers
def _write_summary(path: Path, summary: dict, result_path) -> None:
    data = dict(summary)
    data["result"] = str(result_path) if result_path is not None else None
    path.parent.mkdir(parents=True, exist_ok=True)
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
    if "node_steps_per_s" in summary:
        speed = f"{fmt_rate(summary['node_steps_per_s'])} node-steps/s"
        if "steps_per_s" in summary:
            speed += f" ({fmt_rate(summary['steps_per_s'])} steps/s"
            if "n_nodes" in summary:
                speed += f", {summary['n_nodes']:,} nodes"
            speed += ")"
        rows.append(("speed", speed))
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


# ----------------------------------------------------------------------------- running
class _ProgressBar:
    """A tqdm bar over simulated time, with steps/s and the engine's ETA as postfix."""

    # until the first progress report the engine may be compiling (a cold numba cache:
    # minutes): the bar says so and shows no ETA; the rate and ETA then come from the steps
    # between reports, so that the compile does not count in them (it gave "ETA 825 min")
    STARTING = "compiling the engine (first run only) / starting"

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

    def __call__(self, p) -> None:
        import time as _time

        now = _time.monotonic()
        if self.last is None:
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
        if completed:  # the last step lands within rounding of the end time: show 100 %
            self.bar.n = self.bar.total
            self.bar.refresh()
        self.bar.close()


class _CtrlC:
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


def _execute(scene, output: Path, summary_path: Optional[Path], until: Optional[float],
             quiet: bool) -> tuple[int, Optional[dict]]:
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
    bar = _ProgressBar(end, system.time, disable=quiet)
    result = None
    code = EXIT_OK
    try:
        with _CtrlC(cancel):
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


def output_problem(path: Path, what: str) -> Optional[str]:
    """Why ``path`` cannot be written as the file ``what`` (one line), or None: checked
    before a run starts by creating its folder and opening the file for writing (a file
    that did not exist is removed again), so that a bad ``-o`` or ``--summary`` does not
    cost a whole run."""
    import errno

    path = Path(path)
    if path.is_dir():
        return f"{what} {path}: is a directory (give a file name)"
    existed = path.exists()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "ab"):
            pass
    except OSError as exc:
        reason = exc.strerror or str(exc)
        if exc.errno in (errno.ENOTDIR, errno.EEXIST):
            reason = "a part of the path is a file, not a folder"
        return f"{what} {path}: cannot be written ({reason})"
    if not existed:
        try:
            path.unlink()
        except OSError:
            pass
    return None


def _cmd_run(args) -> int:
    import engine

    try:
        scene = engine.load_scene(args.scene)
    except engine.SceneError as exc:
        _print_scene_error(exc, f"invalid scene {args.scene}")
        return EXIT_BAD_INPUT
    if args.until is not None and not (math.isfinite(args.until) and args.until > 0):
        _err(f"--until = {args.until}: must be a finite time > 0 s")
        return EXIT_BAD_INPUT
    for path, what in ((args.output, "-o/--output"), (args.summary, "--summary")):
        problem = output_problem(Path(path), what) if path else None
        if problem:
            _err(problem)
            return EXIT_BAD_INPUT
    code, _ = _execute(scene, Path(args.output), Path(args.summary) if args.summary else None,
                       args.until, args.quiet)
    return code


# ----------------------------------------------------------------------------- demo
def _describe_demo(scene) -> str:
    try:
        brush = scene.brushes[0]
        body = scene.bodies[0]
        prof = body.motion.profile
        deg = math.degrees
        pairs = {tuple(sorted(p.materials)): deg(p.friction_angle)
                 for p in scene.contact_pairs}
        same = pairs.get((brush.material, brush.material))
        other = pairs.get(tuple(sorted((brush.material, body.material))))
        friction = ""
        if same is not None and other is not None:
            friction = (f" Friction angles are {same:.0f} deg between bristles and {other:.0f} "
                        f"deg against the {body.material} {body.name}.")
        depth = prof.step * prof.n_steps
        return (
            f"What was simulated: a {brush.rows} x {brush.columns} {brush.material} brush "
            f"(the seed's static test, section 4.2) with "
            f"{brush.bristle_length * 1e3:g} mm conical bristles (radius "
            f"{brush.root_radius * 1e3:g} -> {brush.tip_radius * 1e3:g} mm, pitch "
            f"{brush.pitch[0] * 1e3:g} mm), each a chain of {brush.n_nodes} beam-bonded nodes, "
            f"is pressed {depth * 1e3:g} mm deep by a rigid "
            f"{deg(body.shape.angle):.0f} deg {body.material} {body.name} in "
            f"{prof.step * 1e3:g} mm steps with a parabolic velocity profile, resting "
            f"{prof.dwell * 1e3:g} ms after each step"
            f"{', and then pulled back out the same way' if prof.unload else ''}. "
            f"The bristles bend and slide on each other and on the {body.name}.{friction} "
            f"root_force.png shows, against time, the total vertical force the base exerts on "
            f"the bristle roots (the brush's weight plus what the {body.name} pushes), the "
            f"{body.name}'s depth, and the vertical force the bristles push back on the "
            f"{body.name} with. The model is coarse (and gravity starts at t = 0) so that it "
            f"runs in seconds; it is a demonstration, not a verification.")
    except (AttributeError, IndexError, TypeError):
        return f"What was simulated: {scene.description}"


def plot_root_force(result_path, png_path) -> None:
    """From a result file, a PNG of the total vertical root force (all brushes) and the depth
    of each moving body against time, and below it the vertical contact force on each moving
    body (the force the brush pushes back with)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import engine

    with engine.open_result(result_path) as res:
        t = res.time
        channels = res.channels()
        fz = np.zeros_like(t)
        for c in channels:
            if c.startswith("brushes/") and c.endswith("/root_force"):
                fz = fz + res.series(c)[:, 2]
        depths, pushes = {}, {}
        for c in channels:
            if c.startswith("bodies/") and c.endswith("/position"):
                name = c.split("/")[1]
                z = res.series(c)[:, 2]
                if len(z) and np.ptp(z) > 0:
                    depths[name] = (z[0] - z) * 1e3
                    force = f"bodies/{name}/contact_force"
                    if force in channels:
                        pushes[name] = res.series(force)[:, 2]
        status, title = res.status, res.scene.name
    fig, axes = plt.subplots(2 if pushes else 1, 1, sharex=True, squeeze=False,
                             figsize=(8, 6.5 if pushes else 4.5),
                             gridspec_kw={"height_ratios": [3, 2]} if pushes else None)
    ax = axes[0, 0]
    ax.plot(t, fz, color="tab:blue", lw=1.2, label="total vertical root force")
    ax.set_ylabel("vertical root force F_z [N]", color="tab:blue")
    ax.tick_params(axis="y", labelcolor="tab:blue")
    ax.grid(alpha=0.3)
    handles = list(ax.get_lines())
    if depths:
        ax2 = ax.twinx()
        for name, d in depths.items():
            ax2.plot(t, d, color="tab:orange", lw=1.2, ls="--", label=f"{name} depth")
        ax2.set_ylabel("depth [mm]", color="tab:orange")
        ax2.tick_params(axis="y", labelcolor="tab:orange")
        ax2.set_ylim(bottom=min(0.0, ax2.get_ylim()[0]))
        handles += list(ax2.get_lines())
    ax.legend(handles, [h.get_label() for h in handles], loc="upper left", fontsize=9)
    ax.set_title(f"{title} ({status})")
    if pushes:
        axb = axes[1, 0]
        for name, f in pushes.items():
            axb.plot(t, f * 1e3, lw=1.2, label=f"vertical contact force on {name}")
        axb.set_ylabel("F_z on body [mN]")
        axb.grid(alpha=0.3)
        axb.legend(loc="upper left", fontsize=9)
    axes[-1, 0].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(png_path, dpi=120)
    plt.close(fig)


def _cmd_demo(args) -> int:
    import engine

    out = Path(args.output)
    try:
        scene = engine.parse_scene(demo_scene_text())
    except engine.SceneError as exc:  # a broken package, not a user error
        _print_scene_error(exc, "the embedded demo scene is invalid")
        return EXIT_FAILED
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _err(f"-o/--output {out}: cannot be made a folder ({exc.strerror or exc})")
        return EXIT_BAD_INPUT
    for name in (("scene.json",) if args.scene_only else
                 ("demo.h5", "summary.json", "root_force.png")):
        problem = output_problem(out / name, "-o/--output")
        if problem:
            _err(problem)
            return EXIT_BAD_INPUT
    if args.scene_only:  # a scene file to start from, for the docs' snippets and own edits
        path = out / "scene.json"
        engine.save_scene(scene, path)
        print(f"wrote {path} (the demo scene {scene.name!r}; run it with "
              f"brush-studio run {path} -o run.h5)")
        return EXIT_OK
    h5, summary_json, png = out / "demo.h5", out / "summary.json", out / "root_force.png"
    print(f"Running the embedded demo scene {scene.name!r} into {out}/ "
          f"(the first run compiles the engine: a minute or two; later runs take seconds)")
    code, summary = _execute(scene, h5, summary_json, None, args.quiet)
    if summary is None:
        return code
    plotted = False
    try:
        plot_root_force(h5, png)
        plotted = True
    except Exception as exc:  # the run's files are still worth pointing at
        _err(f"could not plot {png}: {type(exc).__name__}: {exc}")
        code = code or EXIT_FAILED
    print()
    print("Wrote:")
    print(f"  {h5}  the result file (HDF5, layout in docs/results.md)")
    print(f"  {summary_json}  the run summary")
    if plotted:
        print(f"  {png}  vertical root force, wedge depth and wedge force against time")
    print()
    print(_describe_demo(scene))
    print()
    print(f"To look at the results: open {png}, or read {h5} with engine.open_result:")
    print(f"  python -c \"import engine; r = engine.open_result('{h5}'); "
          f"print(r.status, r.n_frames, r.channels())\"")
    print()
    print("To design brushes, run scenes and scrub results in the browser, start the studio")
    print("(it opens on this demo scene; Ctrl-C stops it):")
    print("  brush-studio studio        then open http://127.0.0.1:8080")
    return code


# ----------------------------------------------------------------------------- validate
def _cmd_validate(args) -> int:
    import engine

    try:
        scene = engine.load_scene(args.scene)
    except engine.SceneError as exc:
        _print_scene_error(exc, f"invalid scene {args.scene}")
        return EXIT_BAD_INPUT
    # the estimate first (microseconds whatever the size): a scene too large to build here
    # is refused before any array is allocated
    cost = engine.estimate(scene)
    for name, value, allowed in (("--max-nodes", cost.n_nodes, args.max_nodes),
                                 ("--max-memory-mb", cost.memory_bytes / 2**20,
                                  args.max_memory_mb)):
        if allowed and value > allowed:
            print(f"estimate: {cost.summary()}", flush=True)
            _err(f"{args.scene}: too large to build here: {value:.4g} against {name} "
                 f"{allowed:g} (raise {name} to build it anyway, or --estimate-only)")
            return EXIT_BAD_INPUT
    if args.estimate_only:
        print(f"estimate: {cost.summary()}")
        return EXIT_OK
    try:
        system = engine.build(scene)
    except engine.SceneError as exc:
        _print_scene_error(exc, f"invalid scene {args.scene}")
        return EXIT_BAD_INPUT
    nb = len(scene.brushes)
    nbody = len(scene.bodies)
    print(f"OK: {scene.name!r}: {nb} brush{'es' if nb != 1 else ''}, "
          f"{system.n_bristles:,} bristles, {system.n_nodes:,} nodes, "
          f"{nbody} bod{'ies' if nbody != 1 else 'y'}; dt {system.dt:.3g} s limited by "
          f"{system.dt_limited_by}; {scene.run.duration:g} s to simulate")
    print(f"estimate: {cost.summary()}")
    for w in system.warnings:
        print(f"warning: {w}")
    return EXIT_OK


# ----------------------------------------------------------------------------- info
def _cmd_info(args) -> int:
    import engine

    try:
        res = engine.open_result(args.result)
    except engine.BrushStudioError as exc:
        _err(f"error: {exc}")
        return EXIT_BAD_INPUT
    with res:
        t = res.time if res.n_frames else []
        span = f"{t[0]:.6g} .. {t[-1]:.6g} s" if len(t) else "(no frames)"
        try:
            name = res.scene.name
        except Exception:
            name = "?"
        print(f"{res.path}")
        print(f"  scene     {name}")
        status = res.status
        if res.interrupted:
            status += " (still being written, or its writer died)"
        print(f"  status    {status}")
        print(f"  frames    {res.n_frames}")
        print(f"  time      {span}")
        dt = res.attrs.get("dt")
        if isinstance(dt, (int, float)):
            print(f"  dt        {dt:.4g} s, limited by {res.attrs.get('dt_limited_by', '?')}")
        err = res.error
        if err:
            print(f"  error     {err.get('message', err)}")
        summary = res.summary
        if summary:
            print("summary:")
            print(summary_table(summary))
        print("channels:")
        for c in res.channels():
            try:
                shape = res.series(c, slice(0, 0)).shape  # no rows read: just the shape
                per_frame = "x".join(str(s) for s in shape[1:]) or "scalar"
            except Exception:
                per_frame = "?"
            print(f"  {c}  [{per_frame}]")
    return EXIT_OK


# ----------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="brush-studio",
        description="Brush Studio: DEM simulation of brushes touching space debris.",
        epilog="Exit codes: 0 completed/stopped, 1 failed, 2 bad input, 130 cancelled.")
    p.add_argument("--version", action="version", version=f"brush-studio {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    r = sub.add_parser("run", help="run a scene and record it to an HDF5 result file",
                       description="Load, build and run a scene with a progress bar. "
                                   "Ctrl-C cancels cleanly (the file keeps the frames so far "
                                   "and has status cancelled).")
    r.add_argument("scene", metavar="SCENE.json")
    r.add_argument("-o", "--output", metavar="RESULT.h5", required=True,
                   help="result file to write")
    r.add_argument("--summary", metavar="SUMMARY.json",
                   help="also write the run summary as JSON (written for failed runs too)")
    r.add_argument("--until", type=float, metavar="T",
                   help="simulated time to run to, s (default: the scene's run.duration)")
    r.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bar and no summary table")
    r.set_defaults(func=_cmd_run)

    d = sub.add_parser("demo", help="run the embedded default scene and plot it",
                       description="Run the embedded demo (a 17 x 5 silicone brush pressed by "
                                   "a wedge) and write demo.h5, summary.json and "
                                   "root_force.png into DIR.")
    d.add_argument("-o", "--output", metavar="DIR", default=DEMO_DIR,
                   help=f"output folder (default ./{DEMO_DIR})")
    d.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    d.add_argument("--scene-only", action="store_true",
                   help="write only the demo scene, DIR/scene.json, without running it")
    d.set_defaults(func=_cmd_demo)

    v = sub.add_parser("validate", help="check a scene without running it")
    v.add_argument("scene", metavar="SCENE.json")
    v.add_argument("--max-nodes", type=int, default=2_000_000, metavar="N",
                   help="refuse to build a scene with more bristle nodes (default 2000000; "
                        "0: no limit)")
    v.add_argument("--max-memory-mb", type=float, default=8192.0, metavar="MB",
                   help="refuse to build a scene estimated to need more memory (default "
                        "8192; 0: no limit)")
    v.add_argument("--estimate-only", action="store_true",
                   help="print the cost estimate and stop (no build)")
    v.set_defaults(func=_cmd_validate)

    i = sub.add_parser("info", help="describe a result file")
    i.add_argument("result", metavar="RESULT.h5")
    i.set_defaults(func=_cmd_info)

    for module in COMMAND_MODULES:
        module.register(sub)
    return p


def main(argv: Optional[list[str]] = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors: return, do not exit
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    try:
        return int(args.func(args))
    except KeyboardInterrupt:  # Ctrl-C outside a run (loading, building, plotting)
        _err("interrupted")
        return EXIT_CANCELLED
    except BrokenPipeError:  # output piped into `head` and the like: stop quietly
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
