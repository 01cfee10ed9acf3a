"""The ``demo`` command: run the embedded demo scene, plot its root force and say what was
simulated and where to look next."""
from __future__ import annotations

import math
from pathlib import Path

from studio.console import err as _err, print_scene_error as _print_scene_error
from studio.exit_codes import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK
from studio.presets import demo_scene_text
from studio.cli.run_console import output_problem, run_in_terminal

DEMO_DIR = "brush-studio-demo"


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
            f"{body.name} with, also against the depth (loading and unloading). The model "
            f"is coarse (and gravity starts at t = 0) so that it runs in seconds; it is a "
            f"demonstration, not a verification.")
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
        from studio.plots.result_plots import press_depth_of

        press = press_depth_of(res)  # (body, depth per frame in m) of a kinematic press
    rows = 2 if pushes else 1
    fig = plt.figure(figsize=(14 if press else 8, 6.5 if pushes else 4.5))
    grid = fig.add_gridspec(rows, 2 if press else 1,
                            height_ratios=[3, 2] if pushes else None,
                            width_ratios=[1.0, 0.75] if press else None)
    ax = fig.add_subplot(grid[0, 0])
    axes = [ax] + ([fig.add_subplot(grid[1, 0], sharex=ax)] if pushes else [])
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
        axb = axes[1]
        for name, f in pushes.items():
            axb.plot(t, f * 1e3, lw=1.2, label=f"vertical contact force on {name}")
        axb.set_ylabel("F_z on body [mN]")
        axb.grid(alpha=0.3)
        axb.legend(loc="upper left", fontsize=9)
    axes[-1].set_xlabel("time [s]")
    if press is not None:  # the force against the depth of the press (issue 14, item 9)
        body, depth = press
        axd = fig.add_subplot(grid[:, 1])
        if body in pushes:  # what a scale under the press would read (the root force
            # also carries the brush's weight)
            axd.plot(depth * 1e3, pushes[body] * 1e3, color="tab:blue", lw=1.2)
            axd.set_ylabel(f"vertical contact force on {body} [mN]")
        else:
            axd.plot(depth * 1e3, fz, color="tab:blue", lw=1.2)
            axd.set_ylabel("vertical root force F_z [N]")
        axd.set_xlabel(f"depth of {body} [mm]")
        axd.set_title(f"force against the {body}'s depth (loading and unloading)")
        axd.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png_path, dpi=120)
    plt.close(fig)


def cmd_demo(args) -> int:
    import engine

    out = Path(args.output)
    try:
        scene = engine.parse_scene(demo_scene_text())
    except engine.SceneError as exc:  # a broken package, not a user error
        _print_scene_error(exc, "the embedded demo scene is invalid")
        return EXIT_FAILED
    from engine.io.output_paths import OutputPathError, check_output_dir

    try:  # a folder (created if missing, its parent must exist), never a file or a device
        check_output_dir(out, "-o/--output")
    except OutputPathError as exc:
        _err(str(exc))
        return EXIT_BAD_INPUT
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
    code, summary = run_in_terminal(scene, h5, summary_json, None, args.quiet)
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
        print(f"  {png}  vertical root force, wedge depth and wedge force against time, "
              f"and the wedge force against its depth")
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
