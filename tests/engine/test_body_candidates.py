"""Bristle-body candidate lists: tight (only segments within the skin of a body's surface, or
inside a closed body) and complete (deep penetration into a closed body is listed and pushed
out), checked against brute-force distances from trimesh, independent of the engine's grid.
"""
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

import engine
from engine.assembly.bodies import classify_empty_cells
from engine.kernels.body_contacts import (BSLOT, CELL_INSIDE, CELL_OUTSIDE, deep_closest,
                                         nearest_triangle)
from engine.errors import InstabilityError
from engine.model import spec_bodies
from engine.model.meshes import shape_mesh
from engine.state import LIMIT_SKIN

ROOT = Path(__file__).resolve().parents[2]
SILICONE = {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1700.0}
PLA = {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1240.0}
LENGTH = 0.033  # bristle length; 5 nodes: at z = 0, 8.25, 16.5, 24.75, 33 mm


def _wedge_preset(n_nodes=5):
    data = json.loads((ROOT / "static_presets" / "wedge_60.json").read_text())
    data["brushes"][0]["n_nodes"] = n_nodes
    data["run"]["record_interval"] = 1.0
    data["run"]["channels"] = ["root_force"]
    return data


def _one_bristle(body, n_nodes=5):
    """A single upright bristle at the origin (root radius 1 mm, tip 0.5 mm) and one body."""
    return engine.parse_scene({
        "materials": {"silicone": SILICONE, "pla": PLA},
        "brushes": [{"name": "brush", "material": "silicone", "bristle_length": LENGTH,
                     "root_radius": 0.001, "tip_radius": 0.0005, "n_nodes": n_nodes}],
        "bodies": [dict({"name": "body", "material": "pla", "motion": {"type": "fixed"}},
                        **body)],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 0.01, "record_interval": 0.01, "channels": ["root_force"]}})


def _candidates(system):
    bl = system.body_pairs
    n = int(bl.n[0])
    return set(zip(bl.s[:n].tolist(), bl.b[:n].tolist()))


def _reach(system):
    """Per segment: the larger end radius plus the list's skin (the capsule the list keeps)."""
    nd, bn = system.nodes, system.bonds
    return np.maximum(nd.rad[bn.i], nd.rad[bn.j]) + float(system.limits[LIMIT_SKIN])


def _distance(points, mesh):
    """Exact distance from each point to the mesh: trimesh's closest point on every triangle,
    in mm (trimesh's absolute tolerances misplace closest points on mm-sized triangles in m)."""
    points = 1e3 * np.asarray(points, float)
    tri = 1e3 * mesh.triangles
    pp = np.repeat(points, len(tri), axis=0)
    q = trimesh.triangles.closest_point(np.tile(tri, (len(points), 1, 1)), pp)
    return 1e-3 * np.linalg.norm(pp - q, axis=1).reshape(len(points), len(tri)).min(axis=1)


def _inside(points, mesh):
    """Inside a closed outward mesh: winding number 1 (the triangles' solid angles, Van
    Oosterom & Strackee, sum to 4 pi), outside 0."""
    a = mesh.triangles[None] - np.asarray(points, float)[:, None, None]   # (P, T, 3, 3)
    la = np.linalg.norm(a, axis=-1)
    a0, a1, a2 = a[..., 0, :], a[..., 1, :], a[..., 2, :]
    num = np.einsum("ptk,ptk->pt", a0, np.cross(a1, a2))
    den = (la[..., 0] * la[..., 1] * la[..., 2] + np.einsum("ptk,ptk->pt", a0, a1) * la[..., 2]
           + np.einsum("ptk,ptk->pt", a1, a2) * la[..., 0]
           + np.einsum("ptk,ptk->pt", a2, a0) * la[..., 1])
    winding = 2.0 * np.arctan2(num, den).sum(axis=1) / (4.0 * np.pi)
    return winding > 0.5


def _signed_distance(points, mesh):
    """Distance to the surface, positive inside (trimesh's convention)."""
    return np.where(_inside(points, mesh), 1.0, -1.0) * _distance(points, mesh)


def _sampled_distance(system, mesh, h=2e-5):
    """Per segment: min distance from points ``h`` apart along it to the world-frame ``mesh``
    (trimesh's exact point-triangle distance, all triangles). The true segment-mesh distance
    lies in [d - h/2, d] (distance is 1-Lipschitz along the segment)."""
    x, bn = system.nodes.x, system.bonds
    out = np.empty(len(bn.i))
    for s, (i, j) in enumerate(zip(bn.i, bn.j)):
        n = int(np.ceil(np.linalg.norm(x[j] - x[i]) / h)) + 1
        out[s] = _distance(x[i] + np.linspace(0.0, 1.0, n)[:, None] * (x[j] - x[i]),
                           mesh).min()
    return out


def _world_mesh(scene, k=0):
    b = scene.bodies[k]
    mesh = shape_mesh(b.shape).copy()
    assert np.allclose(b.pose.orientation, (1.0, 0.0, 0.0, 0.0))  # no rotation to apply
    mesh.apply_translation(np.asarray(b.pose.position, float))
    return mesh


def test_wedge_candidates_are_the_segments_within_the_skin():
    """The 60 degree wedge pressed 5 mm into the seed's brush (pose moved down, 5 nodes): the
    list holds every segment within reach of the wedge's surface (brute force over all
    triangles) and no segment farther than that (up to the sampling's h/2), so at most 3x the
    segments really near (the issue's acceptance; exact up to sampling). Catches the old
    bounding-sphere clause that listed ~250 of 340 segments for ~10 near ones, and a filter
    that loses a near segment (forces would silently vanish)."""
    data = _wedge_preset()
    data["bodies"][0]["pose"]["position"][2] -= 0.005
    scene = engine.parse_scene(data)
    system = engine.build(scene)
    cand = {s for s, _ in _candidates(system)}
    mesh = _world_mesh(scene)
    assert mesh.is_watertight
    d = _sampled_distance(system, mesh)
    reach = _reach(system)
    h = 2e-5
    surely = set(np.flatnonzero(d < reach).tolist())
    maybe = set(np.flatnonzero(d - 0.5 * h < reach).tolist())
    # a segment inside the closed wedge without crossing its surface: an end inside
    ends_in = _inside(system.nodes.x[system.bonds.i], mesh)
    maybe |= set(np.flatnonzero(ends_in).tolist())
    assert len(surely) >= 10
    assert surely <= cand, f"near segments not listed: {sorted(surely - cand)}"
    assert cand <= maybe, f"far segments listed: {sorted(cand - maybe)}"
    assert len(cand) <= 3 * len(surely)


@pytest.mark.parametrize("shape", ["box", "icosphere"])
def test_segment_deep_inside_a_closed_body_is_listed_and_pushed_out(shape, tmp_path):
    """Segment 1 (nodes at z = 8.25 and 16.5 mm) lies wholly inside a closed body, its nodes
    2 mm (box) or ~7.9 mm (icosphere, 5120 triangles, many grid cells) from the nearest face,
    farther than reach from every face. It must be a candidate, and the narrow phase must give
    its nodes contacts with overlap r + depth (brute-force distance and winding number, an
    independent reference; tolerance 1e-9 relative: both are exact closest-point distances),
    which the first step reports as a bristle-body overlap. Catches dropping the inside test (segment not
    listed) and a narrow phase that only sees faces within a node's radius (the old one: a
    node deeper than its radius had no contact at all and stayed inside)."""
    if shape == "box":
        body = {"shape": {"type": "box", "size": [0.01, 0.01, 0.01225]},
                "pose": {"position": [0.0, 0.0, 0.012375]}}
    else:
        path = tmp_path / "ico.stl"
        trimesh.creation.icosphere(subdivisions=4, radius=0.012).export(path)
        body = {"shape": {"type": "mesh", "file": str(path)},
                "pose": {"position": [0.0, 0.0, 0.012375]}}
    scene = _one_bristle(body)
    system = engine.build(scene)
    bd = system.bodies
    assert bd.watertight[0]
    if shape == "icosphere":
        assert np.prod(bd.grid_dims[0]) > 100  # the expanding search crosses many cells
    x, rad = system.nodes.x, system.nodes.rad
    mesh = trimesh.Trimesh(bd.verts, bd.tris)  # the body-frame mesh, moved to the world
    mesh.apply_translation(bd.pos[0])
    depth = _signed_distance(x[1:3], mesh)  # > 0 inside
    reach = _reach(system)
    assert np.all(depth > reach[1])
    cand = _candidates(system)
    assert (1, 0) in cand and (2, 0) in cand
    with pytest.raises(InstabilityError, match="bristle-body contact overlap"):
        engine.run(system, until=system.dt)
    bl = system.body_pairs
    n = int(bl.n[0])
    for seg in (1, 2):  # slot 0 of segment s is its start node s
        c = [i for i in range(n) if bl.s[i] == seg][0]
        slot = c * BSLOT
        assert bl.active[slot] == 1
        node = system.bonds.i[seg]
        assert bl.ratio[slot] == pytest.approx((rad[node] + depth[seg - 1]) / rad[node],
                                               rel=1e-9)
        # pushed out through the nearest face: the force on the node points out of it
        tri = mesh.triangles
        q = trimesh.triangles.closest_point(tri, np.repeat(x[node:node + 1], len(tri), 0))
        nearest = q[np.argmin(np.linalg.norm(q - x[node], axis=1))]
        assert np.dot(bl.fc[slot], nearest - x[node]) > 0.0


def _beside_wedge_scene(tmp_path, closed):
    """The wedge's apex edge 12 mm to the side of the bristle (y = 12 mm) at z = 20 mm: the
    bristle is inside the old "half the bounding radius of the apex" zone but at least 2 mm
    from the wedge. Open: the same wedge without its end caps, from a mesh file."""
    shape = {"type": "wedge", "angle": np.pi / 3, "height": 0.04, "length": 0.02}
    if not closed:
        m = shape_mesh(spec_bodies.WedgeShape(**shape))
        open_mesh = trimesh.Trimesh(m.vertices, m.faces[2:], process=False)  # no end caps
        path = tmp_path / "open_wedge.stl"
        open_mesh.export(path)
        shape = {"type": "mesh", "file": str(path)}
    return _one_bristle({"shape": shape, "pose": {"position": [0.0, 0.012, 0.020]}})


@pytest.mark.parametrize("closed", [True, False])
def test_segment_near_the_reference_point_but_outside_is_not_listed(closed, tmp_path):
    """Every segment is within the wedge's bounding sphere (and within half its radius of the
    apex, the old clause), yet > 2 mm outside the closed or open wedge (trimesh distance):
    none is a candidate. Catches a bounding-sphere test standing in for the inside test."""
    scene = _beside_wedge_scene(tmp_path, closed)
    system = engine.build(scene)
    bd = system.bodies
    assert bool(bd.watertight[0]) == closed
    mesh = trimesh.Trimesh(bd.verts, bd.tris, process=False)
    mesh.apply_translation(bd.pos[0])
    x = system.nodes.x
    d = _sampled_distance(system, mesh)
    assert np.all(d > 2e-3)
    assert np.all(np.linalg.norm(x - bd.pos[0], axis=1) < 0.5 * bd.bound_r[0])
    assert _candidates(system) == set()


def test_nearest_triangle_and_inside_test_match_trimesh():
    """The expanding grid search and the pseudo-normal sign on a 5120-triangle icosphere with
    a multi-cell grid, at points from the centre to outside the grid: inside exactly where
    trimesh's signed distance is positive, closest distance equal to trimesh's (1e-12 m: both
    exact). Catches a grid search that stops at a box holding no triangle's closest point, and
    a sign from the face normal alone near edges."""
    from engine.model.meshes import triangle_grid
    ico = trimesh.creation.icosphere(subdivisions=4, radius=0.012)
    v, t = np.ascontiguousarray(ico.vertices), np.ascontiguousarray(ico.faces, np.int64)
    origin, cell, dims, start, gtris = triangle_grid(v, t)
    assert dims.prod() > 1000
    from engine.model.meshes import edge_normals, pseudo_normals
    tn = ico.face_normals.copy()
    pn = pseudo_normals(v, t)
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(400, 3))
    pts *= (rng.uniform(0.0, 0.02, 400) / np.linalg.norm(pts, axis=1))[:, None]
    sd = _signed_distance(pts, ico)
    te = edge_normals(v, t)
    args = (v, t, tn, te, origin[None], np.array([cell]), dims[None], np.zeros(1, np.int64),
            start, gtris)
    # the empty cells' sides as the build marks them (and, below, all unmarked: a search
    # for every point); both must give the same answer
    bd = SimpleNamespace(pos=np.zeros((1, 3)), watertight=np.array([True]),
                         sphere_r=np.zeros(1), verts=v, tris=t, tnormal=tn, tedge=te,
                         pnormal=pn, grid_origin=origin[None], grid_cell=np.array([cell]),
                         grid_dims=dims[None], grid_base=np.zeros(1, np.int64),
                         grid_start=start, grid_tris=gtris,
                         grid_side=np.zeros(int(dims.prod()), np.int8))
    classify_empty_cells(bd)
    assert {CELL_INSIDE, CELL_OUTSIDE} <= set(np.unique(bd.grid_side))
    for side in (bd.grid_side, np.zeros_like(bd.grid_side)):
        for p, ref in zip(pts, sd):
            tri, u, vv, w, d = nearest_triangle(0, p, 1e-4, *args)
            assert tri >= 0 and d == pytest.approx(abs(ref), abs=1e-12)
            inside = deep_closest(0, p, 1e-4, v, t, tn, te, pn, *args[4:], side)[0] >= 0
            assert inside == (ref > 1e-12) or abs(ref) < 1e-12


@pytest.mark.parametrize("shape", [(1, 1, 1), (5, 1, 7), (8, 9, 10), (3, 30, 2)])
def test_empty_cell_regions_are_the_face_connected_components(shape):
    """The regions the build's side marking tests once each are scipy.ndimage.label's
    face-connected components (its default 3-D structure), cell for cell."""
    from scipy import ndimage

    from engine.assembly.bodies import _face_regions

    rng = np.random.default_rng(len(shape) * shape[1])
    for fill in (0.0, 0.2, 0.5, 0.8, 1.0):
        mask = rng.random(shape) < fill
        got, n = _face_regions(mask)
        ref, n_ref = ndimage.label(mask)
        assert n == n_ref and got.shape == (mask.size,)
        assert np.array_equal(got == 0, ~mask.ravel())
        # one label of ours for each of the reference's, and no label shared
        pairs = set(zip(got[mask.ravel()].tolist(), ref.ravel()[mask.ravel()].tolist()))
        assert len(pairs) == n


def test_wedge_run_forces_equal_with_every_segment_listed():
    """A short press of the wedge into the brush (0.2 m/s for 7.5 ms, 1.5 mm into the tips)
    with the default skin and with a 6 mm skin, where the list also holds every segment within
    6 mm (a superset of what any filter keeps): root force and step count must be identical,
    because segments left out had no contact (no force, and their friction history is empty).
    dt is fixed so that the skin cannot change it. Catches a filter that drops segments in
    contact, or in contact before the next rebuild."""
    def run(skin):
        data = _wedge_preset()
        data["bodies"][0]["motion"] = {
            "type": "kinematic", "after": "hold",
            "profile": {"kind": "constant", "velocity": [0.0, 0.0, -0.2], "duration": 0.0075}}
        data["run"]["dt"] = 1.5e-5
        data["run"]["verlet_skin"] = skin
        system = engine.build(engine.parse_scene(data))
        engine.run(system, until=0.0085)
        from engine.stepping.observables import root_reactions
        return system, root_reactions(system)["brush"][0]

    tight, f_tight = run(None)
    loose, f_loose = run(0.006)
    assert loose.body_pairs.n[0] > 3 * tight.body_pairs.n[0]  # the reference lists much more
    assert tight.steps == loose.steps
    assert f_tight[2] > 0.01  # the wedge really presses (N)
    np.testing.assert_array_equal(f_tight, f_loose)


# --------------------------------------------------------------------------- fade gradient
def _closest_s_edge(l0, l1, A, B):
    """Segment parameter s of the closest points of segment l0-l1 and line A-B (interior)."""
    d1, d2, r0 = l1 - l0, B - A, l0 - A
    a11, a22, a12 = d1 @ d1, d2 @ d2, d1 @ d2
    c1, c2 = d1 @ r0, d2 @ r0
    det = a11 * a22 - a12 * a12
    s = (a12 * c2 - a22 * c1) / det
    t = (a11 * c2 - a12 * c1) / det
    return s, t


@pytest.mark.parametrize("feature", ["vertex", "edge"])
def test_mesh_fade_forces_are_minus_g_grad_s(feature):
    """The fade/taper part of a segment-interior contact's force is -dU/ds grad s, with s the
    segment's closest point to a mesh vertex or edge. Checked against central finite
    differences of s itself (numpy, independent of the kernel), on the segment's nodes and
    the feature's vertices, and the body's torque as the sum of r x F. Bug caught: a wrong
    sign or index in the differentiated closest-point conditions."""
    from engine.kernels.body_contacts import _mesh_fade_forces

    l0, l1 = np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.2, 0.1])
    A, B = np.array([0.4, -0.5, 0.3]), np.array([0.6, 0.7, 0.2])
    g = 0.37
    out = np.zeros((4, 3))
    if feature == "vertex":
        s = float(((A - l0) @ (l1 - l0)) / ((l1 - l0) @ (l1 - l0)))
        _mesh_fade_forces(l0, l1, s, 1.0, 0.0, 0.0, A, B, B + 1.0, g, out)

        def s_of(p):  # p = (l0, l1, A)
            e = p[1] - p[0]
            return ((p[2] - p[0]) @ e) / (e @ e)
        pts = [l0, l1, A]
    else:
        s, t = _closest_s_edge(l0, l1, A, B)
        assert 0 < s < 1 and 0 < t < 1
        # through the dispatcher, with A-B as edge ab of triangle (A, B, C): w = 0
        _mesh_fade_forces(l0, l1, s, 1.0 - t, t, 0.0, A, B, B + 1.0, g, out)

        def s_of(p):
            return _closest_s_edge(*p)[0]
        pts = [l0, l1, A, B]
    h = 1e-6
    grads = []
    for i in range(len(pts)):
        gi = np.zeros(3)
        for c in range(3):
            hi = [p.copy() for p in pts]
            lo = [p.copy() for p in pts]
            hi[i][c] += h
            lo[i][c] -= h
            gi[c] = (s_of(hi) - s_of(lo)) / (2 * h)
        grads.append(gi)
    np.testing.assert_allclose(out[0], -g * grads[0], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(out[1], -g * grads[1], rtol=1e-6, atol=1e-9)
    body = -g * sum(grads[2:])
    torque = sum(np.cross(p, -g * gr) for p, gr in zip(pts[2:], grads[2:]))
    np.testing.assert_allclose(out[2], body, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(out[3], torque, rtol=1e-6, atol=1e-9)
    # translation invariance of s: the forces sum to zero
    np.testing.assert_allclose(out[0] + out[1] + out[2], 0.0, atol=1e-12)


def _edge_face_fade_numpy(d1, nF, nG, lo=0.0, hi=0.01):
    """chi = S(sin^2 to face F's plane) S(... face G's), S the smoothstep over [lo, hi]."""
    def smooth(c):
        u = min(max((c - lo) / (hi - lo), 0.0), 1.0)
        return u * u * (3.0 - 2.0 * u)
    a = d1 @ d1
    return smooth((d1 @ nF) ** 2 / a) * smooth((d1 @ nG) ** 2 / a)


@pytest.mark.parametrize("tilt_deg", [0.0, 2.0, 4.0, 5.0, 40.0, 90.0])
def test_edge_face_fade_and_its_gradient(tilt_deg):
    """An edge contact's angle fade: chi is the product of the smoothsteps of the squared
    sines between the segment and the edge's two faces (the second face found from the edge's
    pseudo-normal), and the kernel's gradient matches central finite differences of that
    numpy chi. Two faces of a 60 deg wedge's apex (edge along x); the segment crosses the
    edge, tilted by ``tilt_deg`` from face F's plane. Bugs caught: the other face's normal
    reflected the wrong way (the fade of a knife edge's or a flat edge's neighbour), a wrong
    sign or factor in dchi/dd1."""
    from engine.kernels.body_contacts import edge_face_fade
    from engine.model.meshes import pseudo_normals

    half = math.radians(30.0)
    # apex edge A-B along x; faces F = (A, B, C) and G = (B, A, D) below it, 60 deg apart
    A, B = np.array([-1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
    C = np.array([0.0, math.sin(half), math.cos(half)])
    D = np.array([0.0, -math.sin(half), math.cos(half)])
    verts = np.array([A, B, C, D])
    tris = np.array([[0, 1, 2], [1, 0, 3]])
    pn = pseudo_normals(verts, tris)
    tnormal = pn[:, 0].copy()
    nF, nG = pn[0, 0], pn[1, 0]
    # a direction in face F's plane across the edge, tilted out of it by tilt_deg
    along = (C - 0.5 * (A + B))
    along /= np.linalg.norm(along)
    tilt = math.radians(tilt_deg)
    d1 = 2.0 * (math.cos(tilt) * (0.6 * along + 0.8 * np.array([1.0, 0, 0]))
                / np.linalg.norm(0.6 * along + 0.8 * np.array([1.0, 0, 0]))
                + math.sin(tilt) * nF)
    l0 = np.array([0.1, 0.2, -0.3]) - 0.5 * d1
    l1 = l0 + d1
    # the closest point on edge ab of triangle 0: w = 0
    chi, gx, gy, gz = edge_face_fade(l0, l1, 0, 0.5, 0.5, 0.0, tnormal, pn)
    assert chi == pytest.approx(_edge_face_fade_numpy(d1, nF, nG), rel=1e-12, abs=1e-15)
    h = 1e-7
    fd = np.array([(_edge_face_fade_numpy(d1 + h * e, nF, nG)
                    - _edge_face_fade_numpy(d1 - h * e, nF, nG)) / (2 * h)
                   for e in np.eye(3)])
    # 1e-6: central differences of a smooth function at h = 1e-7 are good to ~1e-8
    np.testing.assert_allclose([gx, gy, gz], fd, rtol=1e-6, atol=1e-8)
    if tilt_deg == 0.0:
        assert chi == pytest.approx(0.0, abs=1e-20)  # parallel to face F: no edge contact
    elif tilt_deg < 5.7:
        assert 0.0 < chi < 1.0  # within the band (sin^2 < 0.01)
    else:
        assert chi > 0.0


def test_closest_triangle_with_edge_rejection_matches_brute_force():
    """The grid search with its plane and edge-plane rejections against an independent brute
    force (the segment-triangle distance of every triangle): a 64-facet cylinder (long thin
    facets, the case the edge rejection is for) and random segments and points near its
    surface, with search radii from 0.1 mm to 50 mm. Within reach the same distance (the
    closest triangle may differ only between equidistant ones); nothing within reach is
    reported as none. Catches an edge normal pointing the wrong way or a rejection that is
    not exact."""
    import trimesh
    from engine.kernels.body_contacts import closest_triangle
    from engine.kernels.geometry import segment_triangle_closest
    from engine.model.meshes import edge_normals, triangle_grid

    cyl = trimesh.creation.cylinder(radius=0.62, height=1.4, sections=64)
    v, t = np.ascontiguousarray(cyl.vertices), np.ascontiguousarray(cyl.faces, np.int64)
    origin, cell, dims, start, gtris = triangle_grid(v, t)
    tn = np.ascontiguousarray(cyl.face_normals)
    te = edge_normals(v, t)
    # every triangle lies behind its own three edge planes (the rejection's premise)
    for e in range(3):
        for corner in range(3):
            g = np.einsum("ij,ij->i", te[:, e], v[t[:, corner]] - v[t[:, e]])
            assert np.all(g <= 1e-12)
    args = (v, t, tn, te, origin[None], np.array([cell]), dims[None], np.zeros(1, np.int64),
            start, gtris)
    rng = np.random.default_rng(7)
    n_hit = 0
    for _ in range(400):
        theta, z = rng.uniform(0.0, 2.0 * math.pi), rng.uniform(-0.75, 0.75)
        rr = 0.62 + rng.uniform(-0.03, 0.03)
        p0 = np.array([rr * math.cos(theta), rr * math.sin(theta), z])
        p1 = p0 + (rng.normal(size=3) * 0.02 if rng.uniform() < 0.7 else 0.0)
        reach = 10.0 ** rng.uniform(-4.0, math.log10(0.05))
        tri, s, u, vv, w, d = closest_triangle(0, p0, p1, reach, *args)
        brute = min(segment_triangle_closest(p0, p1, v[a], v[b], v[c])[4] for a, b, c in t)
        if brute < reach * (1.0 - 1e-9):
            n_hit += 1
            assert tri >= 0 and d == pytest.approx(brute, rel=1e-12, abs=1e-15)
        elif brute > reach * (1.0 + 1e-9):
            assert tri == -1
    assert n_hit > 100  # the draw reaches the surface often enough to test something


def _test_mesh(shape):
    """(mesh, vertices, triangles, the walk's arguments after the body index) of a test
    body: a 64-facet cylinder (long thin facets), a box (few large triangles, most in every
    cell) or an annulus (a tube: concave)."""
    from engine.model.meshes import edge_normals, triangle_grid

    if shape == "cylinder":
        mesh = trimesh.creation.cylinder(radius=0.62, height=1.4, sections=64)
    elif shape == "box":
        mesh = trimesh.creation.box(extents=[0.13, 0.085, 0.01])
    else:
        mesh = trimesh.creation.annulus(r_min=0.2, r_max=0.3, height=0.1, sections=48)
    v, t = np.ascontiguousarray(mesh.vertices), np.ascontiguousarray(mesh.faces, np.int64)
    origin, cell, dims, start, gtris = triangle_grid(v, t)
    args = (v, t, np.ascontiguousarray(mesh.face_normals), edge_normals(v, t), origin[None],
            np.array([cell]), dims[None], np.zeros(1, np.int64), start, gtris)
    return mesh, v, t, args


def _near_candidate(rng, v, t):
    """A random candidate near the surface: a segment from a random surface point moved
    along a random direction, node radii 0.05 to 20 mm, a tip or an inner segment."""
    bary = rng.dirichlet(np.ones(3))
    p0 = bary @ v[t[rng.integers(len(t))]] + rng.normal(size=3) * 0.004
    p1 = p0 + rng.normal(size=3) * 0.005
    r0, r1 = 10.0 ** rng.uniform(-4.3, -1.7, size=2)
    return p0, p1, r0, r1, max(r0, r1), bool(rng.uniform() < 0.5)


@pytest.mark.parametrize("shape", ["cylinder", "box"])
def test_closest_features_in_one_walk_match_brute_force_and_the_separate_searches(shape):
    """The narrow phase's one grid walk for a candidate's three queries (start node within
    its radius, end node within its radius, segment within the larger) against an
    independent brute force (the segment-triangle distance of every triangle) and against
    the three separate ``closest_triangle`` walks it replaces, which it must equal bit for
    bit (same triangle, weights and distance: the wedge curve does not move). A 64-facet
    cylinder (long thin facets) and a box (few large triangles, most in every cell), random
    segments near the surface, radii 0.05 to 20 mm, tips and inner segments."""
    from engine.kernels.body_contacts import closest_features, closest_triangle
    from engine.kernels.geometry import segment_triangle_closest

    mesh, v, t, args = _test_mesh(shape)
    rng = np.random.default_rng(11)
    hits = [0, 0, 0]
    for _ in range(400):
        p0, p1, r0, r1, rmax, tip = _near_candidate(rng, v, t)
        got = closest_features(0, p0, p1, r0, r1, rmax, tip, *args)
        want = (closest_triangle(0, p0, p0, r0, *args), closest_triangle(0, p1, p1, r1, *args),
                closest_triangle(0, p0, p1, rmax, *args))
        assert got[0:5] == (want[0][0],) + want[0][2:] or (got[0] == want[0][0] == -1)
        if tip:
            assert got[5:10] == (want[1][0],) + want[1][2:] or (got[5] == want[1][0] == -1)
        else:
            assert got[5] == -1
        assert got[10:16] == want[2] or (got[10] == want[2][0] == -1)
        queries = [(p0, p0, r0, got[0], got[4]), (p1, p1, r1, got[5], got[9]),
                   (p0, p1, rmax, got[10], got[15])]
        for q, (a, b, r, tri, d) in enumerate(queries):
            if q == 1 and not tip:
                continue
            brute = min(segment_triangle_closest(a, b, v[i], v[j], v[k])[4] for i, j, k in t)
            # the separate searches are exact to rounding (closest_triangle's test): the
            # brute-force distance to 1e-12 relative, none within reach reported as none
            if brute < r * (1.0 - 1e-9):
                hits[q] += 1
                assert tri >= 0 and d == pytest.approx(brute, rel=1e-12, abs=1e-15)
            elif brute > r * (1.0 + 1e-9):
                assert tri == -1
    assert min(hits) > 30  # each query reaches the surface often enough to test something


@pytest.mark.parametrize("shape", ["cylinder", "box", "annulus"])
def test_supporting_faces_with_and_without_the_convex_hull(shape, monkeypatch):
    """A small mesh has all its vertices tested against each face's plane, a large one only
    its convex hull's (the farthest vertex in front of a plane is a hull vertex): both give
    the faces that support the mesh, which for the convex cylinder and box are all of them
    and for the annulus (a tube) all but its inner wall."""
    from engine.model import meshes

    _mesh, v, t, args = _test_mesh(shape)
    normals = args[2]
    every = meshes.supporting_faces(v, t, normals)
    monkeypatch.setattr(meshes, "_SUPPORT_CHUNK", 8)   # below triangles x vertices: the hull
    hull = meshes.supporting_faces(v, t, normals)
    assert np.array_equal(every, hull)
    if shape == "annulus":
        centre = v[t].mean(axis=1)
        inner = (np.abs(normals[:, 2]) < 0.5) & (np.hypot(centre[:, 0], centre[:, 1]) < 0.25)
        assert inner.any() and np.array_equal(every, ~inner)
    else:
        assert every.all()


@pytest.mark.parametrize("shape", ["cylinder", "box", "annulus"])
def test_supported_face_settles_only_what_the_walk_would_find(shape):
    """The narrow phase answers a candidate's closest-feature queries from last step's face,
    without walking the grid, where that face's plane supports the mesh (``supported_face``).
    Against the walk (``closest_features``) and an independent closest point (the nearest
    of trimesh's per-triangle ``triangles.closest_point``), on random segments near a
    64-facet cylinder and a box
    (convex: every face supports) and an annulus (a tube: its inner faces do not), with the
    hint the narrow phase keeps (the walk's face) or any triangle of the mesh: whenever the
    hint settles the queries, each node's triangle, weights and distance are the walk's bit
    for bit (and the distance trimesh's to 1e-9), and the segment meets no edge or vertex
    within reach (the walk finds none, or a face's interior); it must settle most queries
    whose nodes sit in front of one face, or it saves nothing."""
    from engine.kernels.body_contacts import FACE_MARGIN, closest_features, supported_face
    from engine.model.meshes import supporting_faces

    mesh, v, t, args = _test_mesh(shape)
    normals = args[2]
    support = supporting_faces(v, t, normals)
    if shape == "annulus":
        # the outer wall and the two rings support the tube, the inner wall does not
        centre = v[t].mean(axis=1)
        radial = np.hypot(centre[:, 0], centre[:, 1])
        wall = np.abs(normals[:, 2]) < 0.5
        assert not support[wall & (radial < 0.25)].any()
        assert support[wall & (radial > 0.25)].all() and support[~wall].all()
    else:
        assert support.all()
    tsupport = np.where(support, 0, -1).astype(np.int64)
    rng = np.random.default_rng(5)
    settled = on_face = touched = 0
    for trial in range(600):
        p0, p1, r0, r1, rmax, tip = _near_candidate(rng, v, t)
        walk = closest_features(0, p0, p1, r0, r1, rmax, tip, *args)
        kept = walk[0] if walk[0] >= 0 else (walk[5] if walk[5] >= 0 else walk[16])
        hint = kept if trial % 3 else int(rng.integers(len(t)))
        got = supported_face(hint, 0, p0, p1, r0, r1, rmax, tip, v, t, normals, tsupport)
        h = ([float(normals[hint] @ (p - v[t[hint, 0]])) for p in (p0, p1)] if hint >= 0
             else [-1.0, -1.0])
        if hint >= 0 and support[hint] and min(h) >= 0.0:
            b = [np.linalg.lstsq(np.c_[v[t[hint, 1]] - v[t[hint, 0]], v[t[hint, 2]]
                                       - v[t[hint, 0]]], p - v[t[hint, 0]], rcond=None)[0]
                 for p in (p0, p1)]
            inner = [min(1 - x[0] - x[1], x[0], x[1]) > 2 * FACE_MARGIN for x in b]
            # the nearer node (both if equally near) and each node within its radius must
            # project inside: the other is farther than its reach from the whole mesh
            want = [h[0] <= h[1] or h[0] <= r0, h[1] <= h[0] or (tip and h[1] <= r1)]
            inside = all(i or not w for i, w in zip(inner, want))
            on_face += inside
            if inside:
                assert got[0], "a supporting face under both nodes must settle the queries"
        if not got[0]:
            continue
        settled += 1
        # the segment: nothing within reach, or the interior of a face (slot 2 takes neither)
        assert walk[10] == -1 or min(walk[12:15]) > 1e-9
        for q, (p, r, tw, tg) in enumerate(((p0, r0, walk[0:5], got[1:6]),
                                            (p1, r1, walk[5:10], got[6:11]))):
            if q == 1 and not tip:
                assert tg[0] == -1
                continue
            assert tg[0] == tw[0]
            if tg[0] >= 0:
                touched += 1
                assert tg[1:5] == tw[1:5]  # the walk's own bits
                near = trimesh.triangles.closest_point(mesh.triangles,
                                                       np.repeat(p[None], len(t), axis=0))
                ref = float(np.linalg.norm(near - p, axis=1).min())
                assert tg[4] == pytest.approx(ref, rel=1e-9, abs=1e-15)
    # (about 70-90 of the 600 draws settle, 45-55 touching; 50-60 sit over a face)
    assert settled > 50 and touched > 25 and on_face > 30


@pytest.mark.parametrize("skin", [None, 0.006])
def test_rebuild_shortcut_by_supporting_faces_lists_what_the_searches_list(skin):
    """The rebuild settles a segment as far and outside, or a node as outside, from a
    supporting face of a node's grid cell (``_cell_face_in_front``) before its searches.
    Along a wedge press into a 5-node brush (the default skin and a 6 mm one, which lists
    far more segments), the list, its order and the deep flags must equal those of the same
    rebuild with no face marked as supporting (every segment searched), and the shortcut must
    settle segments there (else it saves nothing)."""
    from engine.kernels.body_contacts import _cell_face_in_front
    from engine.kernels.neighbours import build_body_list
    from engine.kernels.rotations import qrot_inv

    data = _wedge_preset()
    data["bodies"][0]["motion"] = {
        "type": "kinematic", "after": "hold",
        "profile": {"kind": "constant", "velocity": [0.0, 0.0, -0.2], "duration": 0.0075}}
    data["run"]["verlet_skin"] = skin
    system = engine.build(engine.parse_scene(data))
    nd, bn, bl = system.nodes, system.bonds, system.body_pairs
    skin_m = float(system.limits[LIMIT_SKIN])
    settled = listed = 0
    for until in (0.002, 0.004, 0.006, 0.0085):
        engine.run(system, until=until)
        bd = system.bodies
        assert (bd.tsupport >= 0).sum() > 0
        lists = []
        for support in (np.full_like(bd.tsupport, -1), bd.tsupport):
            n = build_body_list(nd, bn, bd._replace(tsupport=support), bl, skin_m)
            lists.append((bl.s2[:n].copy(), bl.b2[:n].copy(), bl.deep2[:n].copy()))
        for a, b in zip(*lists):
            np.testing.assert_array_equal(a, b)
        listed += len(lists[0][0])
        # how many segments near the body the shortcut settles (both ends in front)
        for s in range(len(bn.i)):
            ends = [np.array(qrot_inv(*bd.q[0], *(nd.x[i] - bd.pos[0])))
                    for i in (bn.i[s], bn.j[s])]
            reach = max(nd.rad[bn.i[s]], nd.rad[bn.j[s]]) + skin_m
            settled += _cell_face_in_front(0, ends[1], ends[0], reach * (1 + 1e-9), bd.verts,
                                           bd.tris, bd.tnormal, bd.tsupport, bd.grid_origin,
                                           bd.grid_cell, bd.grid_dims, bd.grid_base,
                                           bd.grid_start, bd.grid_tris)
    assert listed > 10 and settled > 100  # (20 listed, 210 settled at the default skin)
