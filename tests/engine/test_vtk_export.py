"""A result exported for ParaView and Python tools (issue 29, item 3): the ``.pvd`` series
opens in VTK's own XML reader and in meshio, and a frame's node positions and the body's
world-frame vertices equal what the HDF5 file records (read here with h5py and scipy, not
with the exporter's code)."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest


@pytest.fixture
def tiny_result(tmp_path, tiny_scene):
    import engine

    scene = tiny_scene(duration=0.004)
    # a free box, so that its pose changes between frames: a mesh left in its body frame
    # would then differ from the recorded world position
    scene["bodies"][0]["motion"] = {"type": "free"}
    scene["bodies"][0]["velocity"] = [0.01, 0.0, -0.02]
    scene["bodies"][0]["angular_velocity"] = [0.0, 5.0, 3.0]
    scene["bodies"][0]["mass_properties"] = {"density": 1000.0}
    out = tmp_path / "tiny run.h5"
    engine.run(engine.build(engine.parse_scene(scene)), output=out)
    return out


def _world_vertices(h5, name: str, i: int) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    w, x, y, z = h5[f"bodies/{name}/orientation"][i]
    rot = Rotation.from_quat([x, y, z, w])  # scipy is scalar-last
    return rot.apply(h5[f"bodies/{name}/vertices"][:]) + h5[f"bodies/{name}/position"][i]


def test_exported_series_opens_in_vtk_and_meshio_with_the_recorded_positions(tiny_result,
                                                                              tmp_path):
    import h5py
    import meshio
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    from engine.io.vtk_export import export_vtk_series

    pvd = export_vtk_series(tiny_result, tmp_path / "out")
    assert pvd.name == "tiny run.pvd"
    datasets = ET.parse(pvd).getroot().findall("./Collection/DataSet")
    with h5py.File(tiny_result, "r") as h5:
        n = int(h5.attrs["n_frames"])
        assert len(datasets) == n > 2
        times = [float(d.get("timestep")) for d in datasets]
        assert times == pytest.approx(list(h5["time"][:n]), abs=0)
        i = n - 1   # the last frame: the box has moved and turned
        path = pvd.parent / datasets[i].get("file")
        nodes = h5["nodes/positions"][i]
        body = _world_vertices(h5, "box", i)
        assert np.ptp(h5["bodies/box/position"][:n], axis=0).max() > 1e-6  # it did move
        expected = np.concatenate([nodes, body])
        # VTK's own reader (what ParaView uses for each .vtu of the .pvd)
        reader = vtk.vtkXMLUnstructuredGridReader()
        reader.SetFileName(str(path))
        reader.Update()
        grid = reader.GetOutput()
        pts = vtk_to_numpy(grid.GetPoints().GetData())
        # float64 written and read back: equal to round-off (1e-12 m of a 10 mm scene)
        np.testing.assert_allclose(pts, expected, rtol=0, atol=1e-12)
        n_bonds, n_tri = len(h5["bonds/nodes"]), len(h5["bodies/box/triangles"])
        assert grid.GetNumberOfCells() == n_bonds + n_tri
        assert grid.GetCellType(0) == vtk.VTK_LINE
        assert grid.GetCellType(n_bonds) == vtk.VTK_TRIANGLE
        radius = vtk_to_numpy(grid.GetPointData().GetArray("radius"))
        np.testing.assert_allclose(radius[:len(nodes)], h5["nodes/radius"][:], rtol=0,
                                   atol=0)
        # meshio (Python tools)
        mesh = meshio.read(path)
        np.testing.assert_allclose(mesh.points, expected, rtol=0, atol=1e-12)
        lines = np.concatenate([c.data for c in mesh.cells if c.type == "line"])
        np.testing.assert_array_equal(lines, h5["bonds/nodes"][:])
        tris = np.concatenate([c.data for c in mesh.cells if c.type == "triangle"])
        np.testing.assert_array_equal(tris, h5["bodies/box/triangles"][:] + len(nodes))


def test_every_nth_frame_and_the_zip(tiny_result, tmp_path):
    import io
    import zipfile

    from engine.io.vtk_export import export_vtk_series, export_vtk_zip

    pvd = export_vtk_series(tiny_result, tmp_path / "out", name="run", every=2)
    files = [d.get("file") for d in ET.parse(pvd).getroot().iter("DataSet")]
    assert files[:2] == ["run_00000.vtu", "run_00002.vtu"]
    data = export_vtk_zip(tiny_result, "my_run")
    names = zipfile.ZipFile(io.BytesIO(data)).namelist()
    assert "my_run/my_run.pvd" in names and "my_run/my_run_00000.vtu" in names
