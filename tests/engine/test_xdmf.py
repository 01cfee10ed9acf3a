"""The XDMF description written beside a result (issue 14, item 11): valid XML whose every
HDF5 reference names a dataset that exists, with the shape the DataItem declares, and whose
hyperslabs select rows that were recorded. Parsed with the standard library (no meshio)."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest


@pytest.fixture
def result(tmp_path, tiny_scene):
    import engine

    out = tmp_path / "tiny.h5"
    engine.run(engine.build(engine.parse_scene(tiny_scene())), output=out)
    return out


def test_xdmf_beside_the_result_references_existing_datasets(result):
    import h5py

    xdmf = result.with_suffix(".xdmf")
    assert xdmf.exists()  # written when the recorder closed the file
    root = ET.parse(xdmf).getroot()
    assert root.tag == "Xdmf" and root.get("Version") == "3.0"
    with h5py.File(result, "r") as f:
        n = int(f.attrs["n_frames"])
        checked = 0
        for item in root.iter("DataItem"):
            if item.get("Format") != "HDF":
                continue
            file_name, path = item.text.strip().split(":", 1)
            assert file_name == result.name  # relative: the two files travel together
            assert path in f, path
            dims = tuple(int(d) for d in item.get("Dimensions").split())
            assert dims == f[path].shape, path
            checked += 1
        assert checked > 0
        # one grid per recorded frame, with its time; hyperslabs pick recorded rows only
        bristles = root.find("./Domain/Grid[@Name='bristles']")
        grids = bristles.findall("Grid")
        assert len(grids) == n
        times = [float(g.find("Time").get("Value")) for g in grids]
        assert times == pytest.approx(list(f["time"][:n]))
        for slab in root.iter("DataItem"):
            if slab.get("ItemType") == "HyperSlab":
                start = [int(v) for v in slab[0].text.split()[:1]]
                assert 0 <= start[0] < n
        # the topology: every bond a 2-node polyline over the recorded nodes
        topo = grids[0].find("Topology")
        assert topo.get("TopologyType") == "Polyline"
        assert int(topo.get("NumberOfElements")) == f["bonds/nodes"].shape[0]
        assert int(np.max(f["bonds/nodes"][:])) < f["nodes/positions"].shape[1]
        assert root.find("./Domain/Grid[@Name='body_box']") is not None
