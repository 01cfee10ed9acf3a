"""An XDMF 3 description beside a result file, so that ParaView and VisIt open a run directly.

``write_xdmf("run.h5")`` writes ``run.xdmf`` next to it: no data is copied, every array is a
reference into the HDF5 file (``run.h5:/nodes/positions``...), one frame a hyperslab of the
recorded channel. What it describes (docs/results.md, "Opening a result in ParaView"):

* ``bristles``: a temporal collection, one grid per recorded frame: the nodes
  (``nodes/positions`` row ``i``) joined by the bonds (``bonds/nodes``) as 2-node polylines,
  with ``radius`` per node and, when recorded, ``bending_moment`` per segment;
* ``bodies``: each body's triangle mesh (``bodies/<name>/vertices``, body frame, origin at its
  centre of mass) in a temporal collection whose grids carry the body's ``position`` and
  ``orientation`` (w, x, y, z) of that frame as grid-level attributes. XDMF has no rigid
  transform, so ParaView shows the mesh in its body frame; the pose is there to apply (the
  Transform filter), not applied.

Pure standard library (``xml.etree``) plus ``h5py`` to read shapes.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import NamedTuple, Optional, Union

import numpy as np


class _Meta(NamedTuple):
    """What the description needs of a dataset (its path, shape and type), read once: each
    h5py property access costs tens of microseconds, and a description has hundreds of
    frames."""

    name: str
    shape: tuple
    dtype: np.dtype


def _meta(dataset) -> _Meta:
    return _Meta(dataset.name, tuple(dataset.shape), dataset.dtype)


def _number(dtype) -> tuple[str, int]:
    kind = dtype.kind
    if kind in "iu":
        return ("Int" if kind == "i" else "UInt"), dtype.itemsize
    return "Float", dtype.itemsize


def _slab(parent, dataset, frame: int, h5name: str):
    """Row ``frame`` of a (frames, ...) dataset as an XDMF hyperslab DataItem."""
    shape = dataset.shape
    rest = list(shape[1:])
    slab = ET.SubElement(parent, "DataItem", ItemType="HyperSlab",
                         Dimensions=" ".join(str(d) for d in rest), Type="HyperSlab")
    sel = ET.SubElement(slab, "DataItem", Dimensions=f"3 {len(shape)}", Format="XML")
    start = [frame] + [0] * len(rest)
    stride = [1] * len(shape)
    count = [1] + rest
    sel.text = " ".join(map(str, start)) + "\n" + " ".join(map(str, stride)) + "\n" + \
        " ".join(map(str, count))
    number, precision = _number(dataset.dtype)
    src = ET.SubElement(slab, "DataItem", Dimensions=" ".join(map(str, shape)),
                        NumberType=number, Precision=str(precision), Format="HDF")
    src.text = f"{h5name}:{dataset.name}"
    return slab


def _whole(parent, dataset, h5name: str):
    number, precision = _number(dataset.dtype)
    item = ET.SubElement(parent, "DataItem", Dimensions=" ".join(map(str, dataset.shape)),
                         NumberType=number, Precision=str(precision), Format="HDF")
    item.text = f"{h5name}:{dataset.name}"
    return item


def write_xdmf(h5_path: Union[str, Path], xdmf_path: Optional[Union[str, Path]] = None
               ) -> Optional[Path]:
    """Write the XDMF description of result ``h5_path`` (default: same name, ``.xdmf``).
    Returns its path, or None when the file has no frames or nothing drawable."""
    import h5py

    h5_path = Path(h5_path)
    xdmf_path = Path(xdmf_path) if xdmf_path is not None else h5_path.with_suffix(".xdmf")
    h5name = h5_path.name  # relative: the two files travel together
    with h5py.File(h5_path, "r") as f:
        n = int(f.attrs.get("n_frames", 0))
        if n <= 0 or "time" not in f:
            return None
        times = f["time"][:n]
        root = ET.Element("Xdmf", Version="3.0")
        domain = ET.SubElement(root, "Domain")
        wrote = False
        if "nodes/positions" in f and "bonds/nodes" in f:
            pos, bonds = _meta(f["nodes/positions"]), _meta(f["bonds/nodes"])
            radius = _meta(f["nodes/radius"]) if "nodes/radius" in f else None
            moment = (_meta(f["bonds/bending_moment"]) if "bonds/bending_moment" in f
                      else None)
            n_bonds = bonds.shape[0]
            series = ET.SubElement(domain, "Grid", Name="bristles", GridType="Collection",
                                   CollectionType="Temporal")
            for i in range(n):
                g = ET.SubElement(series, "Grid", Name=f"bristles_{i}", GridType="Uniform")
                ET.SubElement(g, "Time", Value=repr(float(times[i])))
                topo = ET.SubElement(g, "Topology", TopologyType="Polyline",
                                     NumberOfElements=str(n_bonds), NodesPerElement="2")
                _whole(topo, bonds, h5name)
                geo = ET.SubElement(g, "Geometry", GeometryType="XYZ")
                _slab(geo, pos, i, h5name)
                if radius is not None:
                    a = ET.SubElement(g, "Attribute", Name="radius", AttributeType="Scalar",
                                      Center="Node")
                    _whole(a, radius, h5name)
                if moment is not None:
                    a = ET.SubElement(g, "Attribute", Name="bending_moment",
                                      AttributeType="Scalar", Center="Cell")
                    _slab(a, moment, i, h5name)
            wrote = True
        for name in (f["bodies"] if "bodies" in f else {}):
            body = f["bodies"][name]
            if not hasattr(body, "keys") or "vertices" not in body or "triangles" not in body:
                continue
            tris, verts = _meta(body["triangles"]), _meta(body["vertices"])
            pose = [(channel, _meta(body[channel])) for channel in ("position", "orientation")
                    if channel in body]
            series = ET.SubElement(domain, "Grid", Name=f"body_{name}", GridType="Collection",
                                   CollectionType="Temporal")
            for i in range(n):
                g = ET.SubElement(series, "Grid", Name=f"body_{name}_{i}", GridType="Uniform")
                ET.SubElement(g, "Time", Value=repr(float(times[i])))
                topo = ET.SubElement(g, "Topology", TopologyType="Triangle",
                                     NumberOfElements=str(tris.shape[0]))
                _whole(topo, tris, h5name)
                geo = ET.SubElement(g, "Geometry", GeometryType="XYZ")
                _whole(geo, verts, h5name)
                for channel, data in pose:
                    a = ET.SubElement(g, "Attribute", Name=channel, Center="Grid",
                                      AttributeType="Vector" if channel == "position"
                                      else "Matrix")
                    _slab(a, data, i, h5name)
            wrote = True
        if not wrote:
            return None
    ET.indent(root)
    text = '<?xml version="1.0" ?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n' + \
        ET.tostring(root, encoding="unicode") + "\n"
    tmp = xdmf_path.with_suffix(".xdmf.tmp")
    from engine.io.output_paths import refuse_special

    refuse_special(xdmf_path, "XDMF file")  # never onto a device or a named pipe
    refuse_special(tmp, "XDMF temporary file")
    tmp.write_text(text)
    tmp.replace(xdmf_path)
    return xdmf_path
