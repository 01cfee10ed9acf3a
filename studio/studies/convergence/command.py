"""``brush-studio convergence``: the typed Options, ``run`` and the command line."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Literal, Optional

from pydantic import Field

from ...console import print_scene_error
from ...exit_codes import EXIT_CANCELLED, EXIT_FAILED, EXIT_OK
from .quantities import ConvergenceError, QUANTITY_HELP, parse_quantity
from .ladder import parse_factors, parse_ladder
from .protocol_ladder import parse_protocol_ladder
from .running import run_convergence
from .. import api
from ..options import StudyOptions
from ..study_command import set_command


def _err(msg: str) -> None:
    print(msg, file=sys.stderr)


class Options(StudyOptions):
    """``brush-studio convergence``: ``scene`` (a scene file) or ``preset`` (a preset name or
    scene file, as the studies' ``--preset``) run at a ladder of resolutions (``ladder``
    "n_nodes=3,5,9" and/or ``dt_factor`` [1, 0.5]) or of the wedge's loading (``ladder``
    "qs_increments=1,2,4"), ``quantity`` measured in each against ``reference``."""

    scene: Optional[str] = Field(None, description="the scene file (or give --preset)",
                                 json_schema_extra={"positional": True, "design": True,
                                                    "metavar": "SCENE.json", "scene": True})
    quantity: str = Field(description="quantity of interest (below)",
                          json_schema_extra={"short": "-Q", "metavar": "NAME"})
    preset: Optional[str] = Field(None, description="preset name or scene file, as the "
                                                    "studies' --preset (instead of SCENE.json)",
                                  json_schema_extra={"metavar": "SCENE", "scene": True})
    ladder: Optional[str] = Field(
        None, description="nodes per bristle of each level (every brush), increasing; or the "
                          "wedge's loading: qs_increments=N1,N2,... (increments per step, "
                          "increasing) or qs_max_acceleration=A1,A2,... (m/s^2, decreasing), "
                          "each level a wedge study cycle (quantity wedge_force@DEPTH)",
        json_schema_extra={"metavar": "n_nodes=N1,N2,..."})
    nodes: Optional[int] = Field(None, ge=2, le=4096,
                                 description="nodes per bristle of every level (default: the "
                                             "scene's; not with --ladder n_nodes=..., whose "
                                             "levels set their own)",
                                 json_schema_extra={"metavar": "N"})
    dt_factor: list[Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)]] = Field(
        default_factory=list,
        description="run.dt = factor x the level's automatic dt, decreasing; one value "
                    "applies to every level, several pair up with --ladder",
        json_schema_extra={"metavar": "F1,F2,..."})
    reference: Literal["auto", "analytic", "richardson", "finest"] = Field(
        "auto", description="what the errors are measured against (default auto: analytic, "
                            "else Richardson, else the finest level)")
    serial: bool = Field(False, description="run the levels one after another in this "
                                            "process, without Dask (wall times undisturbed "
                                            "by parallel levels)")
    no_progress: bool = Field(False, description="no progress bar",
                              json_schema_extra={"flags": ["-q", "--quiet", "--no-progress"],
                                                 "group": "output and execution"})


def _run_study(options: Options, out: Path) -> int:
    import engine

    source = options.scene or options.preset
    try:
        q = parse_quantity(options.quantity)
        protocol = parse_protocol_ladder(options.ladder) if options.ladder else None
        n_nodes = parse_ladder(options.ladder) if options.ladder and not protocol else None
        factors = (parse_factors(",".join(repr(f) for f in options.dt_factor))
                   if options.dt_factor else None)
        if n_nodes is None and factors is None and protocol is None:
            raise ConvergenceError("give --ladder n_nodes=... and/or --dt-factor ..., or a "
                                   "loading ladder --ladder qs_increments=...")
        if (options.scene is None) == (options.preset is None):
            raise ConvergenceError("give the scene once: a SCENE.json argument or --preset "
                                   "NAME|FILE")
        if options.nodes is not None and n_nodes is not None:
            raise ConvergenceError(f"--nodes = {options.nodes}: leave it out with an n_nodes "
                                   f"ladder (each level sets its own)")
        scene = engine.load_scene(_scene_path(source))
        if options.nodes is not None:
            scene = _with_nodes(scene, options.nodes)
    except ConvergenceError as exc:
        raise api.StudyInputError(str(exc)) from None
    except engine.SceneError as exc:
        print_scene_error(exc, f"invalid scene {source}")
        raise api.StudyInputError(f"invalid scene {source}: "
                                  + "; ".join(str(p) for p in exc.problems)) from None
    try:
        table = run_convergence(scene, q, out, n_nodes=n_nodes, dt_factors=factors,
                                reference=options.reference, serial=options.serial,
                                scheduler=options.scheduler, workers=options.workers,
                                progress=not options.no_progress, protocol=protocol)
    except ConvergenceError as exc:
        raise api.StudyInputError(str(exc)) from None
    except engine.SceneError as exc:
        print_scene_error(exc, "invalid level scene")
        raise api.StudyInputError("invalid level scene: "
                                  + "; ".join(str(p) for p in exc.problems)) from None
    except KeyboardInterrupt:
        _err("cancelled: finished levels are kept in the runs folder and reused next time")
        return EXIT_CANCELLED
    print(table.text())
    print(f"wrote {Path(out) / 'convergence.csv'}, convergence.h5, convergence.json, "
          "convergence.png")
    return EXIT_OK if all(r["status"] in ("completed", "stopped") for r in table.rows) \
        else EXIT_FAILED


# the convergence study of ``options`` into ``out_dir``: a ``StudyResult``
run = api.study_run("convergence", _run_study)


def _scene_path(ref: str) -> Path:
    """A scene file, or the file of the preset named ``ref`` (as the studies' ``--preset``)."""
    path = Path(ref)
    if path.exists():
        return path
    from studio.presets import preset_path

    try:
        return preset_path(ref)
    except KeyError:
        raise ConvergenceError(f"{ref}: no such scene file or preset") from None


def _with_nodes(scene, n_nodes: int):
    """``scene`` with every brush at ``n_nodes`` nodes per bristle."""
    import json

    import engine

    data = json.loads(scene.to_json())
    for brush in data.get("brushes", []):
        brush["n_nodes"] = int(n_nodes)
    return engine.parse_scene(data)


def register(subparsers) -> None:
    import argparse
    import textwrap

    p = subparsers.add_parser(
        "convergence", help="error against wall time for a ladder of resolutions",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.fill(
                    "Run a scene at a ladder of resolutions (nodes per bristle, time-step "
                    "factor) in parallel through the studies' Dask layer, measure a quantity "
                    "of interest in each, and report its error against a reference (analytic "
                    "where one exists, else Richardson/finest level), the observed order and "
                    "the wall time. Writes DIR/convergence.csv "
                    "(level,n_nodes,dt,quantity,error,wall_s), convergence.h5, "
                    "convergence.json and convergence.png (log-log error vs wall time).", 90),
        epilog=QUANTITY_HELP + "\n\nexample:\n  brush-studio convergence rod.json --quantity "
               "tip_deflection --ladder n_nodes=5,9,17 -o rod-convergence\n  "
               "(rod.json: a static scene, e.g. static_presets/rod_weight_static.json)\n  "
               "brush-studio convergence --preset wedge_60 --quantity wedge_force@2mm "
               "--ladder qs_increments=1,2,4 -o wedge-increments")
    set_command(p, run, Options)
