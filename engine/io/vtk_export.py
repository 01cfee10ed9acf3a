"""A result as a ParaView time series: ``NAME.pvd`` plus one VTK ``.vtu`` file per frame.

``export_vtk_series("run.h5", "out/")`` writes ``out/run.pvd`` and ``out/run_00000.vtu``...
The ``.pvd`` (ParaView's collection file) lists the frames with their simulated time; ParaView
opens it as one animated dataset, and every ``.vtu`` (VTK's XML unstructured grid, written
with meshio) is read by VTK's ``vtkXMLUnstructuredGridReader``, meshio, PyVista... on its
own. Each frame holds, in metres, world frame:

* the bristles: the nodes (``nodes/positions`` of that frame) joined by the bonds as 2-node
  ``line`` cells;
* each body: its triangle mesh moved to the frame's pose (``position + R(orientation) @
  vertices``, docs/results.md), so a body moves in ParaView as in the studio;
* point data ``radius`` (node radius, m; 0 on body vertices) and ``part`` (0 for bristles,
  ``k + 1`` for the ``k``-th body of ``bodies`` in the file's order); cell data ``part`` and,
  when recorded, ``bending_moment`` (N m, per bond; 0 on body triangles).

This replaces the XDMF description for ParaView and Python tools: readers disagree on XDMF
(meshio reads one grid, VTK's XDMF2 reader fails on hyperslabs) and XDMF cannot move a body's
mesh (issue 29, item 3).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Optional, Union

import numpy as np

from engine.errors import BrushStudioError


def _body_meshes(res) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, vertices (body frame), triangles) of every body with a mesh in the file."""
    out = []
    for path in res.statics():
        parts = path.split("/")
        if len(parts) == 3 and parts[0] == "bodies" and parts[2] == "vertices":
            name = parts[1]
            tri_path = f"bodies/{name}/triangles"
            if tri_path in res.statics():
                out.append((name, np.asarray(res.static(path), float),
                            np.asarray(res.static(tri_path), np.int64)))
    return out


def frame_mesh(res, i: int, bodies=None) -> tuple[np.ndarray, list, dict, dict]:
    """(points, cell blocks [(type, connectivity)], point data, cell data) of frame ``i`` of
    an open result, in the layout described in the module's docstring."""
    from engine.model.layout import quat_to_matrix

    bodies = _body_meshes(res) if bodies is None else bodies
    channels = set(res.channels())
    points, cells, radius, part_p, part_c, moment = [], [], [], [], [], []
    n = 0
    if "nodes/positions" in channels and "bonds/nodes" in res.statics():
        pos = np.asarray(res.frame("nodes/positions", i), float)
        bonds = np.asarray(res.static("bonds/nodes"), np.int64)
        points.append(pos)
        radius.append(np.asarray(res.static("nodes/radius"), float)
                      if "nodes/radius" in res.statics() else np.zeros(len(pos)))
        part_p.append(np.zeros(len(pos), np.int32))
        cells.append(("line", bonds))
        part_c.append(np.zeros(len(bonds), np.int32))
        moment.append(np.asarray(res.frame("bonds/bending_moment", i), float)
                      if "bonds/bending_moment" in channels else np.zeros(len(bonds)))
        n = len(pos)
    for k, (name, vertices, triangles) in enumerate(bodies):
        position = np.asarray(res.frame(f"bodies/{name}/position", i), float) \
            if f"bodies/{name}/position" in channels else np.zeros(3)
        wxyz = np.asarray(res.frame(f"bodies/{name}/orientation", i), float) \
            if f"bodies/{name}/orientation" in channels else np.array([1.0, 0, 0, 0])
        world = vertices @ quat_to_matrix(wxyz / np.linalg.norm(wxyz)).T + position
        points.append(world)
        radius.append(np.zeros(len(world)))
        part_p.append(np.full(len(world), k + 1, np.int32))
        cells.append(("triangle", triangles + n))
        part_c.append(np.full(len(triangles), k + 1, np.int32))
        moment.append(np.zeros(len(triangles)))
        n += len(world)
    if not points:
        raise BrushStudioError(f"{res.path}: nothing to draw (no nodes, no body meshes)")
    point_data = {"radius": np.concatenate(radius), "part": np.concatenate(part_p)}
    cell_data = {"part": part_c}
    if "bonds/bending_moment" in channels:
        cell_data["bending_moment"] = moment
    return np.concatenate(points), cells, point_data, cell_data


def export_vtk_series(result_path: Union[str, Path], out_dir: Union[str, Path],
                      name: Optional[str] = None, every: int = 1) -> Path:
    """Write result ``result_path`` as ``out_dir/NAME.pvd`` + ``NAME_#####.vtu`` (every
    ``every``-th recorded frame; NAME defaults to the result's file stem). Returns the
    ``.pvd``'s path."""
    import meshio

    from engine.io.results import open_result

    if every < 1:
        raise ValueError(f"every = {every}: must be at least 1")
    result_path, out_dir = Path(result_path), Path(out_dir)
    name = name or result_path.stem
    out_dir.mkdir(parents=True, exist_ok=True)
    with open_result(result_path) as res:
        if res.n_frames <= 0:
            raise BrushStudioError(f"{result_path}: no recorded frame to export")
        times = np.asarray(res.time, float)
        bodies = _body_meshes(res)
        root = ET.Element("VTKFile", type="Collection", version="0.1",
                          byte_order="LittleEndian")
        collection = ET.SubElement(root, "Collection")
        for i in range(0, res.n_frames, every):
            points, cells, point_data, cell_data = frame_mesh(res, i, bodies)
            file_name = f"{name}_{i:05d}.vtu"
            meshio.write(out_dir / file_name,
                         meshio.Mesh(points, cells, point_data=point_data,
                                     cell_data=cell_data), file_format="vtu")
            ET.SubElement(collection, "DataSet", timestep=repr(float(times[i])), group="",
                          part="0", file=file_name)
    ET.indent(root)
    pvd = out_dir / f"{name}.pvd"
    tmp = pvd.with_suffix(".pvd.tmp")
    tmp.write_text('<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n")
    tmp.replace(pvd)
    return pvd


def export_vtk_zip(result_path: Union[str, Path], name: str, every: int = 1) -> bytes:
    """The series of :func:`export_vtk_series` as a zip archive (a download): ``NAME.pvd``
    and its ``.vtu`` files in one folder ``NAME/``."""
    import io
    import tempfile
    import zipfile

    with tempfile.TemporaryDirectory(prefix="brush-export-") as tmp:
        pvd = export_vtk_series(result_path, Path(tmp) / name, name=name, every=every)
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
            for path in sorted(pvd.parent.iterdir()):
                z.write(path, f"{name}/{path.name}")
        return buf.getvalue()
