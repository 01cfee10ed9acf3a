"""Build, rigid bodies: each body's shape turned into the ``Bodies`` bundle (engine.state).

Per body: its triangle mesh and mass properties (``engine.model.meshes``), its frame (the body frame
sits at the centre of mass along the principal axes; ``Body.pose`` places the shape's own
frame), its surface tables for the contact search (face normals, pseudo-normals, a triangle
grid, mesh-mesh contact points) and its motion: fixed, free, hinged, or kinematic along a
profile of piecewise Hermite segments.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from engine.model import meshes
from engine.kernels.bodies import FIXED, FREE, HINGE, KINEMATIC
from engine.kernels.contact_law import HISTORY_COLUMNS
from engine.errors import SceneError
from engine.model.layout import quat_conj, quat_mul, quat_to_matrix
from engine.kernels.mesh_contact import contact_points, point_contact_length
from engine.kernels.body_contacts import CELL_INSIDE, CELL_OUTSIDE, deep_closest
from engine.kernels.rotations import matrix_to_quat, qlog
from engine.model.spec import Scene
from engine.state import Bodies


@dataclass
class BodyPart:
    """What the other builders need of the bodies besides the bundle."""

    bodies: Bodies
    names: list[str]
    geometry: list            # engine.model.meshes.BodyGeometry per body
    shape_to_body: list       # per body, the quaternion body (principal) frame -> shape axes
    point_len: np.ndarray     # per body, the radius of a contact point's share of surface


def principal_frame(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments and a proper rotation whose columns are the principal axes."""
    if not np.any(inertia):
        return np.zeros(3), np.eye(3)
    vals, vecs = np.linalg.eigh(0.5 * (inertia + inertia.T))
    if np.linalg.det(vecs) < 0:
        vecs[:, 2] *= -1
    return vals, vecs


def kinematic_segments(profile, com0: np.ndarray, q0: np.ndarray, shape_to_body: np.ndarray,
                       com_in_shape: np.ndarray, duration: float):
    """Piecewise Hermite segments (t0, t1, p0, p1, v0, v1, omega, q0) of a kinematic profile
    for the body's centre of mass and body-frame orientation."""
    segs = []
    kind = profile.kind
    if kind == "constant":
        T = profile.duration if profile.duration is not None else duration
        v = np.asarray(profile.velocity, float)
        w = np.asarray(profile.angular_velocity, float)
        segs.append((0.0, T, com0, com0 + v * T, v, v, w, q0))
    elif kind == "stepped_parabolic":
        d = np.asarray(profile.direction, float)
        d /= np.linalg.norm(d)
        td = math.sqrt(6.0 * profile.step / profile.max_acceleration)  # seed 4.2
        t = profile.start_delay
        p = com0.copy()
        zero = np.zeros(3)
        if t > 0:
            segs.append((0.0, t, p, p, zero, zero, zero, q0))
        directions = [d] * profile.n_steps + ([-d] * profile.n_steps if profile.unload else [])
        for dd in directions:
            # Hermite with zero end velocities: p(tau) = p0 + s (3 tau^2 - 2 tau^3), whose
            # velocity 6 s/t_d tau (1 - tau) is the seed's v = k t (t_d - t), k = 6 s / t_d^3
            # = a_m / t_d.
            p1 = p + dd * profile.step
            segs.append((t, t + td, p, p1, zero, zero, zero, q0))
            t += td
            p = p1
            if profile.dwell > 0:
                segs.append((t, t + profile.dwell, p, p, zero, zero, zero, q0))
                t += profile.dwell
    elif kind == "waypoints":
        times = np.asarray(profile.times, float)
        pos = np.asarray(profile.positions, float)
        if profile.orientations is None:
            shape_q = np.repeat(quat_mul(q0, quat_conj(shape_to_body))[None, :], len(times),
                                axis=0)
        else:
            shape_q = np.asarray(profile.orientations, float)
        quats = np.array([quat_mul(sq, shape_to_body) for sq in shape_q])
        # waypoints place the shape's frame; the body frame sits at the centre of mass
        coms = np.array([p + quat_to_matrix(sq) @ com_in_shape for p, sq in zip(pos, shape_q)])
        n = len(times)
        vel = np.zeros_like(coms)
        for i in range(1, n - 1):  # Catmull-Rom velocities, zero at both ends
            vel[i] = (coms[i + 1] - coms[i - 1]) / (times[i + 1] - times[i - 1])
        zero = np.zeros(3)
        if times[0] > 0:
            segs.append((0.0, float(times[0]), coms[0], coms[0], zero, zero, zero, quats[0]))
        for i in range(n - 1):
            h = times[i + 1] - times[i]
            dq = quat_mul(quats[i + 1], quat_conj(quats[i]))
            w = np.array(qlog(*dq)) / h
            segs.append((float(times[i]), float(times[i + 1]), coms[i], coms[i + 1], vel[i],
                         vel[i + 1], w, quats[i]))
    return segs


class _Surfaces:
    """The bodies' surface tables, body after body, concatenated at the end: vertices and
    triangles in the body frames, face normals, in-plane edge normals, pseudo-normals, the triangle grids (CSR,
    offsets shifted to index the concatenated lists) and the mesh-mesh contact points."""

    def __init__(self, K: int):
        self.verts, self.tris, self.normals, self.pnormals = [], [], [], []
        self.edges = []
        self.support = []
        self.grid_origin = np.zeros((K, 3))
        self.grid_cell = np.ones(K)
        self.grid_dims = np.ones((K, 3), np.int64)
        self.grid_base = np.zeros(K, np.int64)
        self.grid_start, self.grid_tris = [], []
        self.points = []
        self.point_start = np.zeros(K + 1, np.int64)
        # radius of a point's share of surface (engine.kernels.mesh_contact)
        self.point_len = np.zeros(K)
        self.v_off = self.t_off = self.c_off = 0

    def add(self, k: int, vp: np.ndarray, tris: np.ndarray, spacing, field: str) -> None:
        """Body ``k``'s mesh, vertices ``vp`` in its body frame."""
        self.verts.append(vp)
        self.tris.append(tris + self.v_off)
        e1 = vp[tris[:, 1]] - vp[tris[:, 0]]
        e2 = vp[tris[:, 2]] - vp[tris[:, 0]]
        nrm = np.cross(e1, e2)
        ln = np.linalg.norm(nrm, axis=1)
        good = ln > 1e-300
        nrm[good] /= ln[good, None]
        nrm[~good] = 0.0
        self.normals.append(nrm)
        self.support.append(np.where(meshes.supporting_faces(vp, tris, nrm), k, -1))
        self.pnormals.append(meshes.pseudo_normals(vp, tris))
        self.edges.append(meshes.edge_normals(vp, tris))
        origin, cell, dims, start, gtris = meshes.triangle_grid(vp, tris)
        self.grid_origin[k] = origin
        self.grid_cell[k] = cell
        self.grid_dims[k] = dims
        self.grid_base[k] = self.c_off
        # this body's CSR offsets, shifted to index the concatenated triangle lists
        self.grid_start.append(np.asarray(start, np.int64)[:-1]
                               + sum(len(x) for x in self.grid_tris))
        self.grid_tris.append(np.asarray(gtris, np.int64) + self.t_off)
        self.c_off += int(np.prod(dims))
        self.v_off += len(vp)
        self.t_off += len(tris)
        try:
            self.points.append(contact_points(vp, tris, spacing))
        except ValueError as exc:
            raise SceneError.single(f"{field}.contact_spacing", spacing, str(exc)) from None
        self.point_start[k + 1] = self.point_start[k] + len(self.points[-1])
        self.point_len[k] = point_contact_length(vp, tris, len(self.points[-1]))

    def tables(self) -> dict:
        """The surface fields of the Bodies bundle (one dummy row of each without bodies)."""
        K = len(self.verts)
        if K:
            verts = np.concatenate(self.verts)
            tris = np.concatenate(self.tris)
            normals = np.concatenate(self.normals)
            pnormals = np.concatenate(self.pnormals)
            edges = np.concatenate(self.edges)
            support = np.concatenate(self.support)
            g_start = np.concatenate(self.grid_start
                                     + [np.array([sum(len(x) for x in self.grid_tris)])])
            g_tris = np.concatenate(self.grid_tris) if self.grid_tris else np.zeros(0, np.int64)
        else:
            verts = np.zeros((1, 3))
            tris = np.zeros((1, 3), np.int64)
            normals = np.zeros((1, 3))
            pnormals = np.zeros((1, 7, 3))
            edges = np.zeros((1, 3, 3))
            support = np.full(1, -1)
            g_start = np.zeros(1, np.int64)
            g_tris = np.zeros(0, np.int64)
        return dict(verts=np.ascontiguousarray(verts, float),
                    tris=np.ascontiguousarray(tris, np.int64),
                    tnormal=np.ascontiguousarray(normals),
                    tedge=np.ascontiguousarray(edges),
                    tsupport=np.ascontiguousarray(support, np.int64),
                    pnormal=np.ascontiguousarray(pnormals),
                    grid_origin=self.grid_origin, grid_cell=self.grid_cell,
                    grid_dims=self.grid_dims, grid_base=self.grid_base,
                    grid_start=np.ascontiguousarray(g_start, np.int64),
                    grid_tris=np.ascontiguousarray(g_tris, np.int64),
                    grid_side=np.zeros(max(self.c_off, 1), np.int8),
                    point_start=self.point_start,
                    points=np.concatenate(self.points) if K else np.zeros((1, 3)))


def _face_regions(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """The face-connected regions of the True cells of a 3-D ``mask``: (a label per cell,
    flat in C order, 0 for a False cell and 1..n for the regions; n). The connected
    components of the graph of face neighbours (``scipy.sparse.csgraph``, which the process
    has already imported with scipy.linalg; ``scipy.ndimage.label`` gives the same regions
    but its import costs about 0.15 CPU-s of every build with a mesh body)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    cells = np.flatnonzero(mask)
    index = np.full(mask.size, -1, np.int64)
    index[cells] = np.arange(len(cells))
    ids = index.reshape(mask.shape)
    rows, cols = [], []
    for axis in range(3):      # the pairs of face neighbours along each axis, both True
        lo = ids[tuple(slice(0, -1) if a == axis else slice(None) for a in range(3))]
        hi = ids[tuple(slice(1, None) if a == axis else slice(None) for a in range(3))]
        both = (lo >= 0) & (hi >= 0)
        rows.append(lo[both])
        cols.append(hi[both])
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(len(cells), len(cells)))
    n, comp = connected_components(graph, directed=False)
    labels = np.zeros(mask.size, np.int64)
    labels[cells] = comp + 1
    return labels, int(n)


def classify_empty_cells(bd: Bodies) -> None:
    """Fill ``bd.grid_side`` for each watertight mesh body: every grid cell that no triangle's
    box overlaps is marked inside or outside the body. The surface passes through none of
    those cells nor through a face two of them share (a triangle touching a cell face is
    listed in the cell above it), so each face-connected region of empty cells lies wholly
    on one side, which one exact test at one cell's centre (``deep_closest``) decides. The
    contact search then knows a point in an empty outside cell is outside without looking
    for its closest triangle (``engine.kernels.body_contacts.deep_closest``)."""
    for k in range(len(bd.pos)):
        if not bd.watertight[k] or bd.sphere_r[k] > 0.0:
            continue
        dims = tuple(int(d) for d in bd.grid_dims[k])
        n = int(np.prod(dims))
        base = int(bd.grid_base[k])
        empty = (np.diff(bd.grid_start[base:base + n + 1]) == 0).reshape(dims)
        if not empty.any():
            continue
        flat, n_regions = _face_regions(empty)
        regions, first = np.unique(flat, return_index=True)
        side = np.zeros(n_regions + 1, np.int8)
        for region, cell_id in zip(regions, first):
            if region == 0:
                continue
            centre = bd.grid_origin[k] + (np.array(np.unravel_index(cell_id, dims)) + 0.5) \
                * bd.grid_cell[k]
            tri = deep_closest(k, centre, 0.5 * bd.grid_cell[k], bd.verts, bd.tris, bd.tnormal,
                               bd.tedge, bd.pnormal, bd.grid_origin, bd.grid_cell,
                               bd.grid_dims, bd.grid_base, bd.grid_start, bd.grid_tris,
                               bd.grid_side)[0]
            side[region] = CELL_INSIDE if tri >= 0 else CELL_OUTSIDE
        bd.grid_side[base:base + n] = side[flat]


def _set_motion(k: int, body, a: dict, vals: np.ndarray, geo, q_p: np.ndarray, orbit_n: float,
                duration: float, field: str) -> list:
    """Body ``k``'s motion type and initial velocities into the arrays ``a`` (named as the
    Bodies fields); returns its kinematic segments (none unless kinematic)."""
    R_b = quat_to_matrix(a["q"][k])
    I_world = R_b @ np.diag(vals) @ R_b.T
    m = body.motion
    v0 = np.asarray(body.velocity, float)
    w0 = np.asarray(body.angular_velocity, float)
    if m.type == "fixed":
        a["motion"][k] = FIXED
    elif m.type == "free":
        a["motion"][k] = FREE
        a["v"][k] = v0
        a["w"][k] = w0
        # w0 is relative to the (Hill) frame; L is inertial (engine.kernels.orbit)
        a["L"][k] = I_world @ (w0 + np.array([0.0, 0.0, orbit_n])) if orbit_n else I_world @ w0
    elif m.type == "hinge":
        a["motion"][k] = HINGE
        axis = np.asarray(m.axis, float)
        axis /= np.linalg.norm(axis)
        pos = a["pos"][k]
        p = pos if m.point is None else np.asarray(m.point, float)
        r = pos - p
        a["hinge_axis"][k] = axis
        a["hinge_point"][k] = p
        a["hinge_inertia"][k] = float(axis @ I_world @ axis + a["mass"][k] * np.dot(
            np.cross(axis, r), np.cross(axis, r)))
        a["hinge_k1"][k] = m.k1
        a["hinge_k2"][k] = m.k2
        om = float(w0 @ axis)
        a["w"][k] = om * axis
        a["v"][k] = np.cross(a["w"][k], r)
        if a["hinge_inertia"][k] <= 0:
            raise SceneError.single(f"{field}.mass_properties", None,
                                    "a hinge body needs a positive moment about its axis")
    else:
        a["motion"][k] = KINEMATIC
        a["after_free"][k] = m.after == "free"
        segs = kinematic_segments(m.profile, a["pos"][k].copy(), a["q"][k].copy(), q_p,
                                  geo.com_in_shape, duration)
        if not segs:
            raise SceneError.single(f"{field}.motion.profile", m.profile.kind,
                                    "the profile produces no motion segment")
        return segs
    return []


def build_bodies(scene: Scene, mat_index: dict, orbit_n: float, warnings: list) -> BodyPart:
    """The Bodies bundle of the scene's bodies at their poses (kinematic ones are put on their
    profile by :func:`start_on_profiles`, after the roots are placed on them)."""
    K = len(scene.bodies)
    a = dict(pos=np.zeros((K, 3)), q=np.zeros((K, 4)), v=np.zeros((K, 3)),
             w=np.zeros((K, 3)), L=np.zeros((K, 3)), mass=np.zeros(K), Ip=np.zeros((K, 3)),
             motion=np.zeros(K, np.int64), hinge_axis=np.zeros((K, 3)),
             hinge_point=np.zeros((K, 3)), hinge_inertia=np.ones(K), hinge_k1=np.zeros(K),
             hinge_k2=np.zeros(K), after_free=np.zeros(K, np.bool_), sphere_r=np.zeros(K),
             bound_r=np.zeros(K), watertight=np.zeros(K, np.bool_),
             material=np.zeros(K, np.int64), collide=np.zeros(K, np.bool_))
    a["q"][:, 0] = 1.0
    geoms, shape_to_body = [], []
    surfaces = _Surfaces(K)
    seg_rows = []
    seg_start = [0]
    for k, body in enumerate(scene.bodies):
        fld = f"bodies.{k}"
        geo = meshes.body_geometry(body, field=fld)
        geoms.append(geo)
        vals, R_p = principal_frame(np.asarray(geo.inertia, float))
        q_p = matrix_to_quat(R_p)  # body (principal) frame -> shape axes
        shape_to_body.append(q_p)
        q_pose = np.asarray(body.pose.orientation, float)
        a["pos"][k] = np.asarray(body.pose.position, float) + quat_to_matrix(q_pose) @ \
            geo.com_in_shape
        a["q"][k] = quat_mul(q_pose, q_p)
        a["mass"][k] = geo.mass
        a["Ip"][k] = vals
        # coordinates in the principal frame
        surfaces.add(k, geo.vertices @ R_p, np.asarray(geo.triangles, np.int64),
                     body.contact_spacing, fld)
        a["sphere_r"][k] = geo.sphere_radius
        a["bound_r"][k] = geo.bounding_radius
        a["watertight"][k] = geo.watertight
        a["material"][k] = mat_index[body.material]
        a["collide"][k] = body.collide
        if geo.n_degenerate:
            warnings.append(f"body {body.name!r}: {geo.n_degenerate} degenerate triangle(s) "
                            f"kept (their normals are unused)")
        seg_rows.extend(_set_motion(k, body, a, vals, geo, q_p, orbit_n, scene.run.duration,
                                    fld))
        seg_start.append(len(seg_rows))
    if not seg_rows:  # numba needs at least one row of each table
        seg_rows.append((0.0, 1.0, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3),
                         np.zeros(3), np.array([1.0, 0, 0, 0])))
    kin = list(zip(*seg_rows))
    pos = a["pos"]
    bodies = Bodies(
        **a, f=np.zeros((K, 3)), tq=np.zeros((K, 3)),
        seg_start=np.asarray(seg_start, np.int64), t0=np.asarray(kin[0], float),
        t1=np.asarray(kin[1], float), p0=np.asarray(kin[2], float), p1=np.asarray(kin[3], float),
        v0=np.asarray(kin[4], float), v1=np.asarray(kin[5], float), wseg=np.asarray(kin[6], float),
        q0=np.asarray(kin[7], float), cursor=np.zeros(K, np.int64),
        pos_build=pos.copy(), q_build=a["q"].copy(), pos0=pos.copy(), **surfaces.tables(),
        ft_bb=np.zeros((K, K, HISTORY_COLUMNS)), scratch=np.zeros(3), scratch2=np.zeros((2, 3)),
        mesh_kn=np.zeros((K, K)), mesh_len=np.zeros((K, K)),
        ft_mesh=np.zeros((0, K, HISTORY_COLUMNS)),  # rows only with history (build_contacts)
        f_contact=np.zeros((K, 3)), tq_contact=np.zeros((K, 3)))
    classify_empty_cells(bodies)
    return BodyPart(bodies=bodies, names=[b.name for b in scene.bodies], geometry=geoms,
                    shape_to_body=shape_to_body, point_len=surfaces.point_len)


def start_on_profiles(bodies: Bodies) -> None:
    """Put the kinematic bodies on their profile at t = 0, and record the build pose."""
    from engine.kernels.bodies import kinematic_state
    for k in range(len(bodies.motion)):
        if bodies.motion[k] == KINEMATIC:
            kinematic_state(k, 0.0, bodies.seg_start, bodies.t0, bodies.t1, bodies.p0,
                            bodies.p1, bodies.v0, bodies.v1, bodies.wseg, bodies.q0,
                            bodies.cursor, bodies.pos, bodies.v, bodies.q, bodies.w)
    bodies.pos_build[:] = bodies.pos
    bodies.q_build[:] = bodies.q
    bodies.pos0[:] = bodies.pos
