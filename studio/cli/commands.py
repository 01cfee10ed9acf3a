"""What the ``run``, ``validate`` and ``info`` commands do (their parsers are in
``studio.cli.main``; ``demo`` is in ``studio.cli.demo``). Each handler takes the parsed arguments and
returns an exit code of :mod:`studio.exit_codes`.
"""
from __future__ import annotations

import math
from pathlib import Path

from studio.console import err as _err, print_scene_error as _print_scene_error
from studio.exit_codes import EXIT_BAD_INPUT, EXIT_OK
from studio.cli.run_console import output_problem, run_in_terminal, summary_table


def _load_scene(path):
    """The scene file ``path`` or the preset of that name (``demo``, a name of
    static_presets/, as ``study`` and ``studio`` take), validated; None after printing every
    problem it has."""
    import engine

    from studio.presets import load_preset_or_file

    try:
        return load_preset_or_file(path)
    except engine.SceneError as exc:
        _print_scene_error(exc, f"invalid scene {path}")
        return None


def size_problem(scene, args, path) -> str:
    """Why ``scene`` is too large to build here (its estimate, ``engine.estimate``, against
    ``args.max_nodes`` and ``args.max_memory_mb``, 0 or None: no limit), or "". Called
    before anything is built: the estimate costs microseconds whatever the size, and it
    bounds the peak memory of the build and the run (``tests/engine/test_estimate.py``)."""
    import engine

    cost = engine.estimate(scene)
    for name, value, allowed, unit in (
            ("--max-nodes", cost.n_nodes, getattr(args, "max_nodes", None), "bristle nodes"),
            ("--max-memory-mb", cost.memory_bytes / 2**20, getattr(args, "max_memory_mb", None),
             "MiB of memory for the build and the run (estimated)")):
        if allowed and value > allowed:
            return (f"{path}: too large to build here: {value:.4g} {unit} against {name} "
                    f"{allowed:g} (raise {name} to build it anyway). Estimate: "
                    f"{cost.summary()}")
    return ""


# a scene this many steps long validates with a warning about its cost (1e7 steps of even a
# tiny scene take hours)
COSTLY_STEPS = 1e7


def cmd_run(args) -> int:
    scene = _load_scene(args.scene)
    if scene is None:
        return EXIT_BAD_INPUT
    problem = size_problem(scene, args, args.scene)
    if problem:
        _err(problem)
        return EXIT_BAD_INPUT
    if args.until is not None and not (math.isfinite(args.until) and args.until > 0):
        _err(f"--until = {args.until}: must be a finite time > 0 s")
        return EXIT_BAD_INPUT
    for path, what in ((args.output, "-o/--output"), (args.summary, "--summary")):
        problem = output_problem(Path(path), what, parents=args.parents) if path else None
        if problem:
            _err(problem)
            return EXIT_BAD_INPUT
    if Path(args.output).suffix.lower() not in (".h5", ".hdf5", ".hdf"):
        _err(f"note: {args.output} is written as an HDF5 result file (give it the .h5 "
             f"extension to say so)")
    code, _ = run_in_terminal(scene, Path(args.output),
                              Path(args.summary) if args.summary else None, args.until,
                              args.quiet)
    return code


def cmd_validate(args) -> int:
    import engine

    scene = _load_scene(args.scene)
    if scene is None:
        return EXIT_BAD_INPUT
    # the estimate first (microseconds whatever the size): a scene too large to build here
    # is refused before any array is allocated
    cost = engine.estimate(scene)
    problem = size_problem(scene, args, args.scene)
    if problem:
        print(f"estimate: {cost.summary()}", flush=True)
        _err(problem + " (--estimate-only prints the estimate without building)")
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
          f"{system.n_bristles:,} bristle{'s' if system.n_bristles != 1 else ''}, "
          f"{system.n_nodes:,} node{'s' if system.n_nodes != 1 else ''}, "
          f"{nbody} bod{'ies' if nbody != 1 else 'y'}; dt {system.dt:.3g} s limited by "
          f"{system.dt_limited_by}; {scene.run.duration:g} s to simulate")
    print(f"estimate: {cost.summary()}")
    for w in system.warnings:
        print(f"warning: {w}")
    if cost.steps >= COSTLY_STEPS:
        print(f"warning: {cost.steps:.3g} steps to simulate {scene.run.duration:g} s at dt "
              f"{system.dt:.3g} s: this run would take very long (a stiff material or fine "
              f"bristles make dt small; check the moduli, or shorten run.duration)")
    return EXIT_OK


def cmd_info(args) -> int:
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
