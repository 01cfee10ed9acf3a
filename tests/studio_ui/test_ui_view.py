"""The studio's 3D view geometry (studio/web/view.py) and the app's design logic driven
without a browser (studio/web/app.py: a real viser server, no job pool)."""
from __future__ import annotations

import math
import socket

import numpy as np
import pytest

from engine.model.layout import quat_to_matrix
from studio.web import view as uv


def _brush(**kw):
    b = {"name": "brush", "material": "m", "rows": 2, "columns": 3, "pitch": [0.004, 0.005],
         "bristle_length": 0.02, "root_radius": 0.001, "tip_radius": 0.0005, "n_nodes": 5}
    b.update(kw)
    return {"brushes": [b], "bodies": []}


def test_view_grid_layout_is_centred():
    b = uv.design_bristles(_brush())
    assert b.positions.shape == (2 * 3 * 5, 3) and b.n_bristles == 6
    roots = b.positions[::5]
    # docs/scene.md: columns along x at pitch[0], rows along y at pitch[1], centred
    expect = [(x, y, 0.0) for y in (-0.0025, 0.0025) for x in (-0.004, 0.0, 0.004)]
    assert roots == pytest.approx(np.array(expect), abs=1e-15)
    tips = b.positions[4::5]
    assert tips[:, 2] == pytest.approx(0.02, abs=1e-15)
    assert b.radius[:5] == pytest.approx([0.001, 0.000875, 0.00075, 0.000625, 0.0005])
    assert b.bonds.tolist()[:4] == [[0, 1], [1, 2], [2, 3], [3, 4]]
    assert len(b.bonds) == 6 * 4 == uv.n_design_segments(_brush())


def test_view_staggered_rows_shift_half_a_pitch():
    roots = uv.design_bristles(_brush(pattern="staggered")).positions[::5]
    assert roots[:3, 0] == pytest.approx([-0.004, 0.0, 0.004])
    assert roots[3:, 0] == pytest.approx([-0.002, 0.002, 0.006])


def test_view_base_pose_places_the_brush():
    q = [math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0]  # +90 deg about x
    b = uv.design_bristles(_brush(rows=1, columns=1, base={"position": [0.1, 0.0, 0.0],
                                                           "orientation": q}))
    # the bristle grows along the base's +z, which the turn maps to world -y
    assert b.positions[-1] == pytest.approx([0.1, -0.02, 0.0], abs=1e-12)


def test_view_tip_perturbation_is_seeded_and_sized():
    var = 1e-8  # m^2: sd 0.1 mm
    a = uv.design_bristles(_brush(rows=40, columns=50, tip_variance=var, seed=3))
    b = uv.design_bristles(_brush(rows=40, columns=50, tip_variance=var, seed=3))
    c = uv.design_bristles(_brush(rows=40, columns=50, tip_variance=var, seed=4))
    assert np.array_equal(a.positions, b.positions)
    assert not np.array_equal(a.positions, c.positions)
    roots, tips = a.positions[::5], a.positions[4::5]
    # bristles keep their length; the tip offset direction has the given variance: with 2000
    # bristles the sample variance is within ~3 sd (sqrt(2/2000) = 3 %) of it: 12 %
    assert np.linalg.norm(tips - roots, axis=1) == pytest.approx(0.02, rel=1e-12)
    lateral = (tips - roots)[:, :2] / ((tips - roots)[:, 2:3]) * 0.02
    assert lateral.var(axis=0) == pytest.approx([var, var], rel=0.12)


def test_view_segment_instances_match_the_segments():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(6, 3))
    x[3] = x[2] + (0, 0, -0.5)  # a segment pointing straight down (the degenerate case)
    radius = np.linspace(0.1, 0.2, 6)
    bonds = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [4, 5]])
    centres, wxyz, scales = uv.segment_instances(x, radius, bonds)
    d = x[bonds[:, 1]] - x[bonds[:, 0]]
    assert centres == pytest.approx(500.0 * (x[bonds[:, 0]] + x[bonds[:, 1]]))
    assert scales[:, 2] == pytest.approx(1000.0 * np.linalg.norm(d, axis=1))
    assert scales[:, 0] == pytest.approx(1000.0 * 0.5 * (radius[:-1] + radius[1:]))
    for q, di in zip(wxyz, d):  # the unit cylinder's axis (+z) turned onto the segment
        axis = quat_to_matrix(q) @ np.array([0.0, 0.0, 1.0])
        assert axis == pytest.approx(di / np.linalg.norm(di), abs=1e-12)


def test_view_wedge_mesh_as_documented():
    m = uv.shape_mesh({"type": "wedge", "angle": math.radians(60), "height": 0.02,
                       "length": 0.03})
    # docs/scene.md: volume length h^2 tan(a/2), centroid at z = 2h/3, apex on the x axis
    assert m.volume == pytest.approx(0.03 * 0.02 ** 2 * math.tan(math.radians(30)), rel=1e-12)
    assert m.center_mass[2] == pytest.approx(2 * 0.02 / 3, rel=1e-12)
    assert m.bounds[0][2] == 0.0 and m.is_watertight


def test_view_colormap_ends():
    c = uv.colormap(np.array([0.0, 1.0, 2.0, np.nan]), 1.0)
    assert c.dtype == np.uint8
    assert c[0].tolist() == [68, 1, 84] and c[1].tolist() == [253, 231, 37]
    assert c[2].tolist() == c[1].tolist() and c[3].tolist() == c[0].tolist()


# --------------------------------------------------------------------------- the app
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def studio_app():
    import viser

    from studio.web.app import Studio, demo_scene

    server = viser.ViserServer(host="127.0.0.1", port=_free_port(), verbose=False)
    app = Studio(server, None, demo_scene())
    yield app
    app.close()
    server.stop()


def test_app_edit_redraws_and_refuses(studio_app):
    app = studio_app
    assert app.state()["n_segments"] == 17 * 5 * 5
    handle = app.view.bristles
    assert app.edit("rows", 3)
    assert app.state()["n_segments"] == 3 * 5 * 5
    assert app.widgets["rows"].value == 3
    assert app.edit("bristle_length", 40.0)  # same count: the batched node is updated
    assert app.view.bristles is not handle  # (it was replaced once, for the new count)
    kept = app.view.bristles
    assert app.edit("root_radius", 1.2)
    assert app.view.bristles is kept
    assert app.scene["brushes"][0]["root_radius"] == pytest.approx(0.0012)
    # refused: the design is unchanged, the message is shown next to the field
    assert not app.edit("n_nodes", 1)
    st = app.state()
    assert st["scene"]["brushes"][0]["n_nodes"] == 6
    assert st["errors"]["n_nodes"][0] == "nodes per bristle = 1 refused (the design keeps 6)"
    assert app.widgets["n_nodes"].value == 6  # the box goes back to the design's value
    assert app.error_md["n_nodes"].visible
    assert "brushes.0.n_nodes = 1" in app.error_md["n_nodes"].content
    assert app.edit("n_nodes", 3)
    assert not app.state()["errors"] and not app.error_md["n_nodes"].visible
    assert app.state()["n_segments"] == 3 * 5 * 2


def test_app_shape_change_and_json_round_trip(studio_app):
    import engine

    app = studio_app
    assert app.edit("shape_type", "sphere")
    assert app.widgets["sphere_radius"].visible and not app.widgets["wedge_angle"].visible
    assert app.state()["bodies"]["wedge"]["position_mm"] == pytest.approx([0.0, 0.5, 33.5])
    text = app.design_json()
    app.load_preset("demo")
    assert app.scene["bodies"][0]["shape"]["type"] == "wedge"
    app.set_design(engine.parse_scene(text))
    assert engine.parse_scene(app.design_json()).model_dump() == \
        engine.parse_scene(text).model_dump()
    assert app.scene["bodies"][0]["shape"] == {"type": "sphere", "radius": 0.01,
                                               "subdivisions": 3}


def test_app_gizmo_moves_the_body(studio_app):
    from types import SimpleNamespace

    app = studio_app
    q = (math.cos(math.pi / 8), 0.0, 0.0, math.sin(math.pi / 8))  # 45 deg about z
    app._on_gizmo(SimpleNamespace(target=SimpleNamespace(position=(1.0, 2.0, 40.0), wxyz=q)))
    pose = app.scene["bodies"][0]["pose"]
    assert pose["position"] == pytest.approx([0.001, 0.002, 0.040])  # view mm -> scene m
    assert pose["orientation"] == pytest.approx(list(q))
    assert app.widgets["body_position"].value == pytest.approx((1.0, 2.0, 40.0))
    assert app.widgets["body_orientation"].value == pytest.approx((0.0, 0.0, 45.0))
    assert app.state()["bodies"]["wedge"]["position_mm"] == pytest.approx([1.0, 2.0, 40.0])
