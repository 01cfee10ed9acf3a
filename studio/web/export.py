"""Exports for other tools (issue 29, item 3): a run for ParaView and Python tools (the
``.pvd`` + ``.vtu`` series of ``engine.io.vtk_export``), the designed brush as STL for CAD, and
the plotted series as CSV.

    brush-studio export RESULT.h5 -o OUT_FOLDER [--every N] [--name NAME]
    brush-studio export SCENE.json -o BRUSH.stl

The studio's Results tab (*Export…*) and the HTTP API (``GET /api/runs/{id}/export``) give
the same files.
"""
from __future__ import annotations

import csv
import io
import sys
from pathlib import Path

import numpy as np

from studio.exit_codes import EXIT_BAD_INPUT, EXIT_OK

#: facets around one bristle segment in the STL (a 16-gon: radius within 2 % of the circle)
STL_SECTIONS = 16


def brush_mesh(scene: dict):
    """The designed brushes at rest (every bristle as its segments, each a cylinder of the
    mean radius of its two nodes, DESIGN §3, with a sphere at each node so that the
    segments join), in millimetres, as one trimesh (not merged into one solid: CAD tools
    import the touching parts as one body or several)."""
    import trimesh

    from studio.web.view import design_bristles

    br = design_bristles(scene)
    if len(br.bonds) == 0:
        raise ValueError("the design has no bristles to export")
    x, r = br.positions * 1e3, br.radius * 1e3
    parts = []
    for i, j in br.bonds:
        parts.append(trimesh.creation.cylinder(radius=0.5 * (r[i] + r[j]),
                                               segment=np.array([x[i], x[j]]),
                                               sections=STL_SECTIONS))
    sphere = trimesh.creation.icosphere(subdivisions=1)
    for k in range(len(x)):
        s = sphere.copy()
        s.apply_scale(r[k])
        s.apply_translation(x[k])
        parts.append(s)
    return trimesh.util.concatenate(parts)


def brush_stl(scene: dict) -> bytes:
    """:func:`brush_mesh` as a binary STL (millimetres)."""
    return brush_mesh(scene).export(file_type="stl")


def figures_csv(figures: dict) -> str:
    """The series of plotly figures ``{title: figure}`` as one CSV table in long form: one
    row per point, columns ``plot, series, x_label, x, y_label, y`` (the axis titles carry
    the units)."""
    out = io.StringIO()
    w = csv.writer(out)
    w.writerow(["plot", "series", "x_label", "x", "y_label", "y"])
    for title, fig in figures.items():
        x_label = fig.layout.xaxis.title.text or "x"
        y_label = fig.layout.yaxis.title.text or "y"
        for trace in fig.data:
            if trace.x is None or trace.y is None:
                continue
            for x, y in zip(trace.x, trace.y):
                w.writerow([title, trace.name or "", x_label, repr(float(x)), y_label,
                            repr(float(y))])
    return out.getvalue()


def _cmd_export(args) -> int:
    import engine

    src, out = Path(args.input), Path(args.output)
    if not src.is_file():
        print(f"export: {src}: no such file", file=sys.stderr)
        return EXIT_BAD_INPUT
    if src.suffix.lower() == ".json":
        try:
            scene = engine.parse_scene(src.read_text()).model_dump(mode="json")
        except engine.SceneError as exc:
            print(f"export: {src}: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        out.write_bytes(brush_stl(scene))
        print(f"wrote {out} (the designed brush, mm)")
        return EXIT_OK
    from engine.io.vtk_export import export_vtk_series

    try:
        pvd = export_vtk_series(src, out, name=args.name, every=args.every)
    except (engine.BrushStudioError, OSError, ValueError) as exc:
        print(f"export: {src}: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    n = sum(1 for _ in out.glob(f"{pvd.stem}_*.vtu"))
    print(f"wrote {pvd} and {n} .vtu frames: open the .pvd in ParaView (metres, world "
          f"frame)")
    return EXIT_OK


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "export", help="a result for ParaView/Python (.pvd + .vtu), a design as STL",
        description="RESULT.h5 -> OUT/NAME.pvd and one VTK .vtu file per frame (bristles as "
                    "lines, bodies as triangles in the world frame, metres): ParaView opens "
                    "the .pvd as a time series, VTK/meshio/PyVista read each .vtu. "
                    "SCENE.json -> OUT.stl: the designed brush at rest, millimetres.")
    p.add_argument("input", metavar="RESULT.h5|SCENE.json")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="folder for the .pvd series (a result), or the .stl file (a scene)")
    p.add_argument("--every", type=int, default=1, metavar="N",
                   help="export every N-th recorded frame (default 1: all)")
    p.add_argument("--name", default=None,
                   help="file name stem of the series (default: the result's)")
    p.set_defaults(func=_cmd_export)
