"""Build: turn a validated scene into flat arrays, assembling only the stages it needs.

``build(scene) -> System``. The System owns the compiled state (``engine.state`` bundles), the
list of assembled stages, the timestep and the element that limits it, and the names that map
array indices back to brushes, bristles, nodes and bodies.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from . import meshes, overlap
from .bodies import FIXED, FREE, HINGE, KINEMATIC
from .contact_law import NO_FRICTION, SLIP_EACH_STEP, restitution_damping_ratio
from .errors import SceneError
from .mesh_contact import (contact_points, initial_overlap, mesh_contact_stiffness,
                           pair_stiffness, point_contact_length)
from .layout import BristleLayout, brush_layout, quat_conj, quat_mul, quat_to_matrix, rotate_rows
from .rotations import matrix_to_quat, qlog
from .spec import Scene
from .state import (ACC_SIZE, STAGES, Bodies, BodyList, Bonds, Flags, Loads, Mission, Nodes,
                    PairList,
                    Roots, Tables)
from .timestep import BRISTLE_CONTACTS_PER_NODE, automatic_dt, equalizing_scales

MAX_OVERLAP_RATIO = 0.5      # contact overlap / radius that counts as a blow-up
MAX_NODE_STEP_RATIO = 0.5    # node displacement per step / its radius
MAX_BODY_STEP_RATIO = 0.25   # body surface displacement per step / smallest bristle radius
CHECK_EVERY = 16
TIME_EVERY = 64


@dataclass
class BrushInfo:
    name: str
    first_bristle: int
    n_bristles: int
    n_nodes: int              # per bristle
    first_node: int
    base_position: np.ndarray  # world, t = 0
    base_orientation: np.ndarray
    mount: int                # body index or -1
    root_index: np.ndarray    # indices into the Roots bundle
    base_local: np.ndarray    # base origin in the mount body's frame (world if not mounted)


@dataclass
class System:
    """A scene compiled for the step loop. ``run`` advances it; it can be run again to
    continue from where it stopped."""

    scene: Scene
    nodes: Nodes
    bonds: Bonds
    roots: Roots
    bodies: Bodies
    pairs: PairList
    body_pairs: BodyList
    loads: Loads
    tables: Tables
    flags: Flags
    acc: np.ndarray
    err: np.ndarray
    stage_time: np.ndarray
    limits: np.ndarray
    dt: float
    dt_limited_by: str
    dt_stable: float
    stages: list[str]
    brushes: list[BrushInfo]
    body_names: list[str]
    bristle_first_node: np.ndarray   # (n_bristles + 1,)
    bristle_brush: np.ndarray        # (n_bristles,)
    node_bristle: np.ndarray
    warnings: list[str] = field(default_factory=list)
    body_geometry: list = field(default_factory=list)
    body_frame_offset: list = field(default_factory=list)  # quaternion shape->body per body
    prescribed_motions: list = field(default_factory=list)  # changes by prescribe_motion
    mission: Optional[Mission] = None   # orbit, controllers, external body loads

    @property
    def controller_names(self) -> list[str]:
        return [c.name for c in self.scene.controllers]

    @property
    def time(self) -> float:
        return float(self.acc[11])

    @property
    def steps(self) -> int:
        return int(self.acc[12])

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.x.shape[0])

    @property
    def n_bristles(self) -> int:
        return int(self.bristle_brush.shape[0])

    def node_label(self, n: int) -> str:
        b = int(self.node_bristle[n])
        if b < 0:
            return f"node {n}"
        brush = self.brushes[int(self.bristle_brush[b])]
        return (f"brush {brush.name!r} bristle {b - brush.first_bristle} node "
                f"{n - int(self.bristle_first_node[b])}")

    def segment_label(self, s: int) -> str:
        return self.node_label(int(self.bonds.i[s])).replace(" node ", " segment ")


# ----------------------------------------------------------------------------- helpers
def _rot(q) -> np.ndarray:
    return quat_to_matrix(np.asarray(q, dtype=float))


def _qmul(a, b) -> np.ndarray:
    return quat_mul(a, b)


def brush_layout_of(scene: Scene, brush) -> BristleLayout:
    """The rest layout (``engine.layout``) of one of the scene's brushes, in world
    coordinates: the base pose is relative to the mount body's pose when it has one."""
    mount_pose = (None, None)
    if brush.mount is not None:
        body = next(b for b in scene.bodies if b.name == brush.mount)
        mount_pose = (body.pose.position, body.pose.orientation)
    return brush_layout(rows=brush.rows, columns=brush.columns, pitch=brush.pitch,
                        pattern=brush.pattern, bristle_length=brush.bristle_length,
                        root_radius=brush.root_radius, tip_radius=brush.tip_radius,
                        n_nodes=brush.n_nodes, tip_variance=brush.tip_variance,
                        seed=brush.seed, base_position=brush.base.position,
                        base_orientation=brush.base.orientation,
                        mount_position=mount_pose[0], mount_orientation=mount_pose[1])


def _principal(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
            shape_q = np.repeat(_qmul(q0, _conj(shape_to_body))[None, :], len(times), axis=0)
        else:
            shape_q = np.asarray(profile.orientations, float)
        quats = np.array([_qmul(sq, shape_to_body) for sq in shape_q])
        # waypoints place the shape's frame; the body frame sits at the centre of mass
        coms = np.array([p + _rot(sq) @ com_in_shape for p, sq in zip(pos, shape_q)])
        n = len(times)
        vel = np.zeros_like(coms)
        for i in range(1, n - 1):  # Catmull-Rom velocities, zero at both ends
            vel[i] = (coms[i + 1] - coms[i - 1]) / (times[i + 1] - times[i - 1])
        zero = np.zeros(3)
        if times[0] > 0:
            segs.append((0.0, float(times[0]), coms[0], coms[0], zero, zero, zero, quats[0]))
        for i in range(n - 1):
            h = times[i + 1] - times[i]
            dq = _qmul(quats[i + 1], _conj(quats[i]))
            w = np.array(qlog(*dq)) / h
            segs.append((float(times[i]), float(times[i + 1]), coms[i], coms[i + 1], vel[i],
                         vel[i + 1], w, quats[i]))
    return segs


def frustum_bond_stiffness(E, G, r0, r1, length):
    """Stiffnesses of the bond between nodes of radii ``r0`` (node i) and ``r1`` (node j), a
    linearly tapered solid circular Euler-Bernoulli frustum of ``length`` (arrays or floats):
    ``(kn, ks, kb, ksb, kt)`` for the energy of ``bonds._bond_eval``.

    Axial and twist are the exact frustum compliances, ``1/kn = int dx / (E A(x))`` and
    ``1/kt = int dx / (G J(x))``: ``kn = E pi r0 r1 / L``, ``kt = G pi/2 * 3 r0^3 r1^3 /
    (L (r0^2 + r0 r1 + r1^2))`` (seed eq. 3.1 for a uniform bond).

    Bending: the bond's energy in one plane is ``1/2 ks d^2 + ksb d phi + 1/2 kb phi^2`` with
    ``d`` the midpoint shear displacement and ``phi`` the relative rotation, whose conjugate
    forces are the shear force V and the bending moment at the midpoint. For a beam whose
    node i is clamped these are ``[d, phi] = C [V, M_mid]`` with the exact flexibility

        C = int_0^L [xi^2, xi; xi, 1] / (E I(x)) dx,   xi = L/2 - x,

    and the stiffness is ``C^-1``. With ``I = pi r^4 / 4`` and r linear in x the integrals are
    rational in r0, r1 (E0 = E pi r0^4 / 4, beta = r1 / r0):
    ``C = [L^3 (b^2 - b + 1) / 12, L^2 (b^2 - 1) / 6; ., L (b^2 + b + 1) / 3] / (E0 b^3)``,
    determinant ``L^4 / (12 E0^2 b^4)``, so

        ks  = E pi r0 r1 (r0^2 + r0 r1 + r1^2) / L^3
        kb  = E pi r0 r1 (r0^2 - r0 r1 + r1^2) / (4 L)
        ksb = E pi r0 r1 (r0^2 - r1^2) / (2 L^2)

    (uniform: ``12 E I / L^3``, ``E I / L``, 0, seed eq. 3.1). The element is then the exact
    Euler-Bernoulli stiffness of the frustum for any end loads, so a tapered cantilever under
    tip loads is exact at any resolution, as the uniform one already was; ``ks kb - ksb^2 =
    3 (E pi r0^2 r1^2)^2 / (4 L^4) > 0``.
    """
    s2 = r0 * r0 + r1 * r1
    p = r0 * r1
    e = E * math.pi * p
    kn = e / length
    ks = e * (s2 + p) / length ** 3
    kb = e * (s2 - p) / (4.0 * length)
    ksb = e * (r0 * r0 - r1 * r1) / (2.0 * length ** 2)
    kt = G * math.pi / 2.0 * 3.0 * p ** 3 / (length * (s2 + p))
    return kn, ks, kb, ksb, kt


def _conj(q) -> np.ndarray:
    return quat_conj(q)


# ----------------------------------------------------------------------------- build
def build(scene: Scene) -> System:
    """Compile a validated scene. Raises SceneError for problems only the build can see
    (unreadable meshes, a dt override above the stability limit is only warned about)."""
    if not isinstance(scene, Scene):
        raise SceneError.single("(scene)", type(scene).__name__,
                                "build() takes an engine.Scene (see engine.load_scene)")
    warnings: list[str] = []
    mat_names = list(scene.materials)
    mat_index = {m: i for i, m in enumerate(mat_names)}
    M = len(mat_names)
    E_tab = np.array([scene.materials[m].youngs_modulus for m in mat_names], float)
    mu = np.zeros((M, M))
    ktr = np.full((M, M), 0.25)
    zeta = np.zeros((M, M))
    for a in range(M):
        for b in range(M):
            pair = scene.pair(mat_names[a], mat_names[b])
            mu[a, b] = math.tan(pair.friction_angle)
            ktr[a, b] = pair.tangential_ratio
            zeta[a, b] = restitution_damping_ratio(pair.restitution)
    gravity = np.asarray(scene.environment.gravity, float)
    orbit = scene.environment.orbit
    orbit_n = orbit.n if orbit is not None else 0.0

    # ------------------------------------------------------------------ bodies
    K = len(scene.bodies)
    body_names = [b.name for b in scene.bodies]
    geoms = []
    pos = np.zeros((K, 3))
    q = np.zeros((K, 4))
    q[:, 0] = 1.0
    vel = np.zeros((K, 3))
    omg = np.zeros((K, 3))
    L = np.zeros((K, 3))
    mass = np.zeros(K)
    Ip = np.zeros((K, 3))
    motion = np.zeros(K, np.int64)
    h_axis = np.zeros((K, 3))
    h_point = np.zeros((K, 3))
    h_inertia = np.ones(K)
    h_k1 = np.zeros(K)
    h_k2 = np.zeros(K)
    after_free = np.zeros(K, np.bool_)
    sphere_r = np.zeros(K)
    bound_r = np.zeros(K)
    watertight = np.zeros(K, np.bool_)
    bmat = np.zeros(K, np.int64)
    collide = np.zeros(K, np.bool_)
    point_len = np.zeros(K)   # engine.mesh_contact: radius of a point's share of surface
    point_start = np.zeros(K + 1, np.int64)
    points_all = []
    seg_rows = []
    seg_start = [0]
    verts_all, tris_all, normals_all, pnormals_all = [], [], [], []
    g_origin = np.zeros((K, 3))
    g_cell = np.ones(K)
    g_dims = np.ones((K, 3), np.int64)
    g_base = np.zeros(K, np.int64)
    g_start_all, g_tris_all = [], []
    v_off = 0
    t_off = 0
    c_off = 0
    shape_to_body_list = []
    for k, body in enumerate(scene.bodies):
        fld = f"bodies.{k}"
        geo = meshes.body_geometry(body, field=fld)
        geoms.append(geo)
        vals, R_p = _principal(np.asarray(geo.inertia, float))
        q_p = matrix_to_quat(R_p)  # body (principal) frame -> shape axes
        shape_to_body_list.append(q_p)
        q_pose = np.asarray(body.pose.orientation, float)
        R_pose = _rot(q_pose)
        pos[k] = np.asarray(body.pose.position, float) + R_pose @ geo.com_in_shape
        q[k] = _qmul(q_pose, q_p)
        mass[k] = geo.mass
        Ip[k] = vals
        vp = geo.vertices @ R_p  # coordinates in the principal frame
        tris = np.asarray(geo.triangles, np.int64)
        verts_all.append(vp)
        tris_all.append(tris + v_off)
        e1 = vp[tris[:, 1]] - vp[tris[:, 0]]
        e2 = vp[tris[:, 2]] - vp[tris[:, 0]]
        nrm = np.cross(e1, e2)
        ln = np.linalg.norm(nrm, axis=1)
        good = ln > 1e-300
        nrm[good] /= ln[good, None]
        nrm[~good] = 0.0
        normals_all.append(nrm)
        pnormals_all.append(meshes.pseudo_normals(vp, tris))
        origin, cell, dims, start, gtris = meshes.triangle_grid(vp, tris)
        g_origin[k] = origin
        g_cell[k] = cell
        g_dims[k] = dims
        g_base[k] = c_off
        # this body's CSR offsets, shifted to index the concatenated triangle lists
        g_start_all.append(np.asarray(start, np.int64)[:-1] + sum(len(x) for x in g_tris_all))
        g_tris_all.append(np.asarray(gtris, np.int64) + t_off)
        c_off += int(np.prod(dims))
        v_off += len(vp)
        t_off += len(tris)
        try:
            points_all.append(contact_points(vp, tris, body.contact_spacing))
        except ValueError as exc:
            raise SceneError.single(f"{fld}.contact_spacing", body.contact_spacing,
                                    str(exc)) from None
        point_start[k + 1] = point_start[k] + len(points_all[-1])
        point_len[k] = point_contact_length(vp, tris, len(points_all[-1]))
        sphere_r[k] = geo.sphere_radius
        bound_r[k] = geo.bounding_radius
        watertight[k] = geo.watertight
        bmat[k] = mat_index[body.material]
        collide[k] = body.collide
        if geo.n_degenerate:
            warnings.append(f"body {body.name!r}: {geo.n_degenerate} degenerate triangle(s) "
                            f"kept (their normals are unused)")
        R_b = _rot(q[k])
        I_world = R_b @ np.diag(vals) @ R_b.T
        m = body.motion
        v0 = np.asarray(body.velocity, float)
        w0 = np.asarray(body.angular_velocity, float)
        if m.type == "fixed":
            motion[k] = FIXED
        elif m.type == "free":
            motion[k] = FREE
            vel[k] = v0
            omg[k] = w0
            # w0 is relative to the (Hill) frame; L is inertial (engine.orbit)
            L[k] = I_world @ (w0 + np.array([0.0, 0.0, orbit_n])) if orbit_n else I_world @ w0
        elif m.type == "hinge":
            motion[k] = HINGE
            a = np.asarray(m.axis, float)
            a /= np.linalg.norm(a)
            p = pos[k] if m.point is None else np.asarray(m.point, float)
            r = pos[k] - p
            h_axis[k] = a
            h_point[k] = p
            h_inertia[k] = float(a @ I_world @ a + mass[k] * np.dot(np.cross(a, r), np.cross(a, r)))
            h_k1[k] = m.k1
            h_k2[k] = m.k2
            om = float(w0 @ a)
            omg[k] = om * a
            vel[k] = np.cross(omg[k], r)
            if h_inertia[k] <= 0:
                raise SceneError.single(f"{fld}.mass_properties", None,
                                        "a hinge body needs a positive moment about its axis")
        else:
            motion[k] = KINEMATIC
            after_free[k] = m.after == "free"
            segs = kinematic_segments(m.profile, pos[k].copy(), q[k].copy(), q_p,
                                      geo.com_in_shape, scene.run.duration)
            if not segs:
                raise SceneError.single(f"{fld}.motion.profile", m.profile.kind,
                                        "the profile produces no motion segment")
            seg_rows.extend(segs)
        seg_start.append(len(seg_rows))
    if not seg_rows:  # numba needs at least one row of each table
        seg_rows.append((0.0, 1.0, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3),
                         np.zeros(3), np.array([1.0, 0, 0, 0])))
    kin = list(zip(*seg_rows))
    if K:
        verts = np.concatenate(verts_all)
        tris = np.concatenate(tris_all)
        normals = np.concatenate(normals_all)
        pnormals = np.concatenate(pnormals_all)
        g_start = np.concatenate(g_start_all + [np.array([sum(len(x) for x in g_tris_all)])])
        g_tris = np.concatenate(g_tris_all) if g_tris_all else np.zeros(0, np.int64)
    else:
        verts = np.zeros((1, 3))
        tris = np.zeros((1, 3), np.int64)
        normals = np.zeros((1, 3))
        pnormals = np.zeros((1, 7, 3))
        g_start = np.zeros(1, np.int64)
        g_tris = np.zeros(0, np.int64)

    # ------------------------------------------------------------------ bristles
    xs, qs, rads, masses, inertias, node_bristle, node_mat = [], [], [], [], [], [], []
    bi_l, bj_l, kn_l, ks_l, kb_l, ksb_l, kt_l, L0_l = [], [], [], [], [], [], [], []
    cn_l, cs_l, cb_l, ct_l = [], [], [], []
    bond_bristle, bond_mat, bond_mount, has_next = [], [], [], []
    root_node, root_body, root_lpos, root_lq = [], [], [], []
    brushes: list[BrushInfo] = []
    bristle_first = [0]
    bristle_brush = []
    n_node = 0
    n_bristle = 0
    n_root = 0
    for bidx, br in enumerate(scene.brushes):
        mat = scene.materials[br.material]
        E = mat.youngs_modulus
        G = E / (2.0 * (1.0 + mat.poisson_ratio))
        rho = mat.density
        zb = mat.bond_damping
        mount = body_names.index(br.mount) if br.mount is not None else -1
        lay = brush_layout_of(scene, br)
        n = br.n_nodes
        nb = br.n_bristles
        r_node = lay.radius
        seg_len = lay.segment_length
        r0, r1 = r_node[:-1], r_node[1:]
        seg_mass = rho * math.pi * seg_len * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0  # frustum
        m_node = np.zeros(n)
        m_node[:-1] += 0.5 * seg_mass
        m_node[1:] += 0.5 * seg_mass
        I_node = 0.5 * m_node * r_node ** 2  # isotropic: the node's own twist inertia
        kn, ks, kb, ksb, kt = frustum_bond_stiffness(E, G, r0, r1, seg_len)
        mi, mj = m_node[:-1], m_node[1:]
        meff = np.where(np.arange(n - 1) == 0, mj, mi * mj / (mi + mj))
        Ii, Ij = I_node[:-1], I_node[1:]
        Ieff = np.where(np.arange(n - 1) == 0, Ij, Ii * Ij / (Ii + Ij))
        first_bristle = n_bristle
        first_node = n_node
        bristle_ids = n_bristle + np.arange(nb)
        per_bond = lambda a: np.tile(a, nb)  # noqa: E731  (the same bonds on every bristle)
        xs.append(lay.positions)
        qs.append(lay.node_orientations)
        rads.append(lay.node_radius)
        masses.append(np.tile(m_node, nb))
        inertias.append(np.tile(I_node, nb))
        node_bristle.append(np.repeat(bristle_ids, n))
        node_mat.append(np.full(nb * n, mat_index[br.material]))
        pairs_here = lay.bonds(first_node)
        bi_l.append(pairs_here[:, 0])
        bj_l.append(pairs_here[:, 1])
        kn_l.append(per_bond(kn))
        ks_l.append(per_bond(ks))
        kb_l.append(per_bond(kb))
        ksb_l.append(per_bond(ksb))
        kt_l.append(per_bond(kt))
        L0_l.append(np.full(nb * (n - 1), seg_len))
        cn_l.append(per_bond(2 * zb * np.sqrt(kn * meff)))
        cs_l.append(per_bond(2 * zb * np.sqrt(ks * meff)))
        cb_l.append(per_bond(2 * zb * np.sqrt(kb * Ieff)))
        ct_l.append(per_bond(2 * zb * np.sqrt(kt * Ieff)))
        bond_bristle.append(np.repeat(bristle_ids, n - 1))
        bond_mat.append(np.full(nb * (n - 1), mat_index[br.material]))
        bond_mount.append(np.full(nb * (n - 1), mount))
        hn = np.ones(n - 1, np.bool_)
        hn[-1] = False
        has_next.append(per_bond(hn))
        root_node.append(first_node + n * np.arange(nb))
        root_body.append(np.full(nb, mount))
        if mount >= 0:
            Rk = _rot(q[mount])
            root_lpos.append(rotate_rows(Rk.T, lay.roots - pos[mount]))
            root_lq.append(quat_mul(_conj(q[mount]), lay.orientations))
        else:
            root_lpos.append(lay.roots)
            root_lq.append(lay.orientations)
        n_node += nb * n
        n_bristle += nb
        bristle_first.extend(first_node + n * (1 + np.arange(nb)))
        bristle_brush.extend([bidx] * nb)
        pb_w, qb_w = lay.base_position, lay.base_orientation
        base_local = (_rot(q[mount]).T @ (pb_w - pos[mount])) if mount >= 0 else pb_w
        brushes.append(BrushInfo(br.name, first_bristle, nb, n, first_node, pb_w, qb_w, mount,
                                 n_root + np.arange(nb, dtype=np.int64), base_local))
        n_root += nb

    N = n_node
    cat = lambda lst, shape, dt=float: (np.concatenate(lst).astype(dt) if lst
                                        else np.zeros(shape, dt))
    x = np.concatenate(xs) if xs else np.zeros((0, 3))
    qn = np.concatenate(qs) if qs else np.zeros((0, 4))
    rad = cat(rads, 0)
    nmass = cat(masses, 0)
    ninertia = cat(inertias, 0)
    nbristle = cat(node_bristle, 0, np.int64)
    bi = cat(bi_l, 0, np.int64)
    bj = cat(bj_l, 0, np.int64)
    B = bi.shape[0]
    bond_prev = np.full(N, -1, np.int64)
    bond_next = np.full(N, -1, np.int64)
    bond_next[bi] = np.arange(B)
    bond_prev[bj] = np.arange(B)
    inv_mass = np.where(nmass > 0, 1.0 / np.where(nmass > 0, nmass, 1.0), 0.0)
    inv_inertia = np.where(ninertia > 0, 1.0 / np.where(ninertia > 0, ninertia, 1.0), 0.0)
    root_node_a = cat(root_node, 0, np.int64)
    inv_mass[root_node_a] = 0.0
    inv_inertia[root_node_a] = 0.0
    node_free = inv_mass > 0

    nodes = Nodes(x=x, v=np.zeros((N, 3)), q=qn, w=np.zeros((N, 3)), f=np.zeros((N, 3)),
                  t=np.zeros((N, 3)), mass=nmass, inv_mass=inv_mass, inertia=ninertia,
                  inv_inertia=inv_inertia, rad=rad, bond_prev=bond_prev, bond_next=bond_next,
                  x_build=x.copy(), x0=x.copy())
    bonds = Bonds(i=bi, j=bj, kn=cat(kn_l, 0), ks=cat(ks_l, 0), kb=cat(kb_l, 0),
                  ksb=cat(ksb_l, 0), kt=cat(kt_l, 0), L0=cat(L0_l, 0), cn=cat(cn_l, 0),
                  cs=cat(cs_l, 0), cb=cat(cb_l, 0), ct=cat(ct_l, 0), f=np.zeros((B, 3)), ti=np.zeros((B, 3)),
                  tj=np.zeros((B, 3)), energy=np.zeros(B), diss=np.zeros(B), bend=np.zeros(B),
                  has_next=cat(has_next, 0, np.bool_), bristle=cat(bond_bristle, 0, np.int64),
                  material=cat(bond_mat, 0, np.int64), mount=cat(bond_mount, 0, np.int64),
                  mid=np.zeros((B, 3)), bound=np.zeros(B),
                  rmax=np.maximum(rad[bi], rad[bj]) if B else np.zeros(0))
    roots = Roots(node=root_node_a, body=cat(root_body, 0, np.int64),
                  local_pos=cat(root_lpos, (0, 3)), local_q=cat(root_lq, (0, 4)))
    bodies = Bodies(
        pos=pos, q=q, v=vel, w=omg, L=L, mass=mass, Ip=Ip, motion=motion,
        f=np.zeros((K, 3)), tq=np.zeros((K, 3)), hinge_axis=h_axis, hinge_point=h_point,
        hinge_inertia=h_inertia, hinge_k1=h_k1, hinge_k2=h_k2, after_free=after_free,
        seg_start=np.asarray(seg_start, np.int64), t0=np.asarray(kin[0], float),
        t1=np.asarray(kin[1], float), p0=np.asarray(kin[2], float), p1=np.asarray(kin[3], float),
        v0=np.asarray(kin[4], float), v1=np.asarray(kin[5], float), wseg=np.asarray(kin[6], float),
        q0=np.asarray(kin[7], float), cursor=np.zeros(K, np.int64), sphere_r=sphere_r,
        bound_r=bound_r, watertight=watertight, material=bmat, collide=collide,
        pos_build=pos.copy(), q_build=q.copy(), pos0=pos.copy(), verts=np.ascontiguousarray(verts, float),
        tris=np.ascontiguousarray(tris, np.int64), tnormal=np.ascontiguousarray(normals),
        pnormal=np.ascontiguousarray(pnormals),
        grid_origin=g_origin, grid_cell=g_cell, grid_dims=g_dims, grid_base=g_base,
        grid_start=np.ascontiguousarray(g_start, np.int64),
        grid_tris=np.ascontiguousarray(g_tris, np.int64), ft_bb=np.zeros((K, K, 3)),
        scratch=np.zeros(3), scratch2=np.zeros((2, 3)), point_start=point_start,
        points=np.concatenate(points_all) if K else np.zeros((1, 3)),
        mesh_kn=np.zeros((K, K)), mesh_len=np.zeros((K, K)), ft_mesh=np.zeros((1, 1, 3)))
    # kinematic bodies start on their profile
    from .bodies import kinematic_state
    for k in range(K):
        if motion[k] == KINEMATIC:
            kinematic_state(k, 0.0, bodies.seg_start, bodies.t0, bodies.t1, bodies.p0,
                            bodies.p1, bodies.v0, bodies.v1, bodies.wseg, bodies.q0,
                            bodies.cursor, bodies.pos, bodies.v, bodies.q, bodies.w)
    bodies.pos_build[:] = bodies.pos
    bodies.q_build[:] = bodies.q
    bodies.pos0[:] = bodies.pos

    # ------------------------------------------------------------------ initial overlap
    overlap.check_build(scene, x, rad, np.stack([bi, bj], 1), nbristle, bristle_brush,
                        [(b.name, b.first_bristle, b.mount) for b in brushes],
                        [pos[k] + geoms[k].vertices @ _rot(scene.bodies[k].pose.orientation).T
                         for k in range(K)], [g.triangles for g in geoms],
                        [bool(g.watertight) for g in geoms], collide, warnings)

    # ------------------------------------------------------------------ stages
    bristle_mats = sorted({mat_index[b.material] for b in scene.brushes})
    body_mats = sorted({int(bmat[k]) for k in range(K) if collide[k]})
    node_partners = _bristle_partners(brushes, x, rad, nbristle, bristle_first, n_bristle,
                                      motion)
    bb_needed = bool(node_partners.any())
    bbody_needed = N > 0 and bool(collide.any())
    spheres = [k for k in range(K) if collide[k] and sphere_r[k] > 0]
    meshmesh_needed = False
    bodybody_needed = False
    for k1 in range(K):
        for k2 in range(k1 + 1, K):
            if not (collide[k1] and collide[k2]):
                continue
            if not any(motion[k] in (FREE, HINGE) or after_free[k] for k in (k1, k2)):
                continue
            excluded = (body_names[k2] in scene.bodies[k1].no_contact_with
                        or body_names[k1] in scene.bodies[k2].no_contact_with)
            if sphere_r[k1] <= 0 and sphere_r[k2] <= 0:
                if excluded:
                    continue
                if not (watertight[k1] and watertight[k2]):
                    warnings.append(f"bodies {body_names[k1]!r} and {body_names[k2]!r}: "
                                    f"mesh-mesh contact needs two closed (watertight) "
                                    f"meshes; this pair does not touch")
                    continue
                kn_pair = pair_stiffness(E_tab[bmat[k1]], point_len[k1], E_tab[bmat[k2]],
                                         point_len[k2])
                bodies.mesh_kn[k1, k2] = bodies.mesh_kn[k2, k1] = kn_pair
                bodies.mesh_len[k1, k2] = bodies.mesh_len[k2, k1] = min(point_len[k1],
                                                                        point_len[k2])
                meshmesh_needed = True
            elif excluded:
                raise SceneError.single(f"bodies.{k1}.no_contact_with", body_names[k2],
                                        "only pairs of mesh bodies can be excluded; a "
                                        "sphere body touches every colliding body")
            bodybody_needed = True
    fr_bb = bb_needed and any(mu[a, b] > 0 for a in bristle_mats for b in bristle_mats)
    fr_body = bbody_needed and any(mu[a, b] > 0 for a in bristle_mats for b in body_mats)
    fr_bodybody = bodybody_needed and any(mu[a, b] > 0 for a in body_mats for b in body_mats)
    if meshmesh_needed and fr_bodybody:
        bodies = bodies._replace(ft_mesh=np.zeros((int(point_start[-1]), K, 3)))
    rigid = bool(np.any(motion != FIXED))
    mounted = bool(np.any(roots.body >= 0))
    has_gravity = bool(np.any(gravity != 0)) and (bool(node_free.any()) or rigid)
    channels = list(scene.run.channels)
    track_energy = "energy" in channels
    bond_damped = bool(np.any(bonds.cn > 0) or np.any(bonds.cb > 0))
    alpha = scene.environment.local_damping

    # loads
    load_nodes, load_of, lforce, lstart, ltimes, lvalues, lfreq, lphase = [], [], [], [0], [], [], [], []
    brush_by_name = {b.name: i for i, b in enumerate(brushes)}
    for li, ldef in enumerate(scene.loads):
        info = brushes[brush_by_name[ldef.brush]]
        idx = range(info.n_bristles) if ldef.bristles == "all" else ldef.bristles
        node_in = ldef.node % info.n_nodes
        for b in idx:
            n_glob = info.first_node + b * info.n_nodes + node_in
            if inv_mass[n_glob] == 0:
                raise SceneError.single(f"loads.{li}.node", ldef.node,
                                        "a load on a root node does nothing: roots are clamped")
            load_nodes.append(n_glob)
            load_of.append(li)
        lforce.append(ldef.force)
        ltimes.extend(ldef.profile.times)
        lvalues.extend(ldef.profile.values)
        lstart.append(len(ltimes))
        lfreq.append(ldef.profile.frequency)
        lphase.append(ldef.profile.phase)
    NL = len(scene.loads)
    loads = Loads(node=np.asarray(load_nodes, np.int64), load=np.asarray(load_of, np.int64),
                  force=np.asarray(lforce, float).reshape(NL, 3),
                  start=np.asarray(lstart, np.int64), times=np.asarray(ltimes or [0.0], float),
                  values=np.asarray(lvalues or [0.0], float), frequency=np.asarray(lfreq, float),
                  phase=np.asarray(lphase, float), amp=np.zeros(NL))

    # ------------------------------------------------------------------ timestep
    E_node = E_tab[cat(node_mat, 0, np.int64)] if N else np.zeros(0)
    bodies_info = []
    r_min = float(rad.min()) if N else 0.0
    E_br_max = float(E_node.max()) if N else 0.0
    r_max = float(rad.max()) if N else 0.0
    n_segments = max(B, 1)
    for k in range(K):
        if (motion[k] in (FREE, HINGE) or after_free[k]) and collide[k]:
            k_body = 0.0
            if bbody_needed and N:
                Ek = float(E_tab[bmat[k]])
                k_body += min(n_segments, 100) * 2.0 * E_br_max * Ek / (E_br_max + Ek) * r_max
            if bodybody_needed and sphere_r[k] > 0:
                k_body += 2.0 * float(E_tab[bmat[k]]) * sphere_r[k] * 2
            elif bodybody_needed and spheres:
                k_body += 2.0 * float(E_tab[bmat[k]]) * max(sphere_r[s] for s in spheres) * 2
            k_body += mesh_contact_stiffness(bodies, k)
            bodies_info.append((body_names[k], float(mass[k]), float(Ip[k].min()), k_body,
                                float(bound_r[k])))
    kt_bb = max([ktr[a, b] for a in bristle_mats for b in bristle_mats if mu[a, b] > 0],
                default=0.0)
    kt_body = max([ktr[a, b] for a in bristle_mats for b in body_mats if mu[a, b] > 0],
                  default=0.0)
    node_k_body = (_node_body_stiffness(brushes, bodies, x, rad, E_node, nbristle, bristle_first,
                                        E_tab, after_free) if bbody_needed else np.zeros(N))
    sysinfo = dict(node_mass=np.where(nmass > 0, nmass, 1.0),
                   node_inertia=np.where(ninertia > 0, ninertia, 1.0),
                   node_radius=rad, node_E=E_node, node_free=node_free,
                   node_bristle_contacts=np.minimum(node_partners, BRISTLE_CONTACTS_PER_NODE),
                   node_k_body=node_k_body, kt_ratio_bristle=float(kt_bb),
                   kt_ratio_body=float(kt_body),
                   bond_arrays=(bi, bj, bonds.kn, bonds.ks, bonds.kb, bonds.ksb, bonds.kt,
                                bonds.L0),
                   bodies=bodies_info, node_label=None)
    node_bristle_arr = nbristle
    bristle_first_arr = np.asarray(bristle_first, np.int64)
    bristle_brush_arr = np.asarray(bristle_brush, np.int64)

    def label(n):
        b = int(node_bristle_arr[n])
        brush = brushes[int(bristle_brush_arr[b])]
        return (f"brush {brush.name!r} bristle {b - brush.first_bristle} node "
                f"{n - int(bristle_first_arr[b])}")
    sysinfo["node_label"] = label
    if scene.environment.inertia_scaling == "equalize" and N:
        mass_scale, inertia_scale = equalizing_scales(sysinfo)
        nodes.inv_mass[:] /= mass_scale          # the weight (nodes.mass) stays physical
        nodes.inertia[:] *= inertia_scale
        nodes.inv_inertia[:] /= inertia_scale
        sysinfo["node_mass"] = sysinfo["node_mass"] * mass_scale
        sysinfo["node_inertia"] = sysinfo["node_inertia"] * inertia_scale
    dt_stable, limited_by, _ = automatic_dt(sysinfo)
    if scene.run.dt is None:
        dt = scene.run.dt_safety * dt_stable
        if not math.isfinite(dt):
            dt = scene.run.record_interval
            limited_by = "nothing moves elastically: dt = record_interval"
    else:
        dt = scene.run.dt
        if dt > dt_stable:
            warnings.append(f"run.dt = {dt:.3g} s exceeds the estimated stability limit "
                            f"{dt_stable:.3g} s (set by {limited_by}); the run may "
                            f"become unstable")
        limited_by = "given in the scene (run.dt)"
    # tunnelling: a body's surface must not move more than a fraction of the smallest
    # bristle radius per step (the step loop's check); the automatic dt keeps half of that
    if N and (bbody_needed or bodybody_needed):
        step_max = MAX_BODY_STEP_RATIO * r_min
        speed, fastest = _max_body_speeds(bodies, collide)
        if speed > 0:
            dt_speed = 0.5 * step_max / speed
            if scene.run.dt is None and dt_speed < dt:
                dt = dt_speed
                limited_by = (f"speed of body {body_names[fastest]!r} (up to {speed:.3g} m/s; "
                              f"half of {MAX_BODY_STEP_RATIO:g} x the smallest bristle radius "
                              f"per step, against tunnelling)")
            elif scene.run.dt is not None and scene.run.dt > 2 * dt_speed:
                warnings.append(f"run.dt = {scene.run.dt:.3g} s lets body "
                                f"{body_names[fastest]!r} ({speed:.3g} m/s) move more than "
                                f"{MAX_BODY_STEP_RATIO:g} x the smallest bristle radius per "
                                f"step: the run will stop on the tunnelling check")
    dt = min(dt, scene.run.record_interval, scene.run.duration)

    skin = scene.run.verlet_skin if scene.run.verlet_skin is not None else (r_min or 1e-3)
    cap_pairs = 16
    cap_body = 16
    pairs = _pair_list(cap_pairs, fr_bb)
    body_pairs = _body_list(cap_body, fr_body)

    flags = Flags(bonds=B > 0, bond_damping=bond_damped, bristle_bristle=bb_needed,
                  bristle_body=bbody_needed, body_body=bodybody_needed,
                  friction_bristle=SLIP_EACH_STEP if fr_bb else NO_FRICTION,
                  friction_body=SLIP_EACH_STEP if fr_body else NO_FRICTION,
                  friction_body_body=SLIP_EACH_STEP if fr_bodybody else NO_FRICTION,
                  rigid_bodies=rigid, mounted_roots=mounted,
                  gravity=has_gravity, loads=NL > 0 and len(load_nodes) > 0,
                  local_damping=alpha > 0, track_energy=track_energy,
                  check_every=CHECK_EVERY, time_every=TIME_EVERY,
                  orbit=orbit_n != 0.0, controllers=len(scene.controllers) > 0,
                  external_loads=any(any(b.external_force) or any(b.external_torque)
                                     for b in scene.bodies))
    mission = _mission(scene, orbit_n, body_names, shape_to_body_list)
    stages = []
    if flags.bonds:
        stages.append("bonds")
    if flags.bond_damping:
        stages.append("bond_damping")
    if bb_needed or bbody_needed:
        stages.append("neighbour_list")
    if bb_needed:
        stages.append("bristle_bristle_contacts")
    if bbody_needed:
        stages.append("bristle_body_contacts")
    if bodybody_needed:
        stages.append("body_body_contacts")
    if meshmesh_needed:
        stages.append("mesh_mesh_contacts")
    if fr_bb or fr_body or fr_bodybody:
        stages.append("tangential_history")
    if rigid:
        stages.append("rigid_bodies")
    if mounted:
        stages.append("mounted_roots")
    if has_gravity:
        stages.append("gravity")
    if flags.loads:
        stages.append("loads")
    if flags.local_damping:
        stages.append("local_damping")
    if track_energy:
        stages.append("energy_tracking")
    if flags.orbit:
        stages.append("orbit")
    if flags.controllers:
        stages.append("controllers")
    if flags.external_loads:
        stages.append("external_body_loads")

    limits = np.array([MAX_OVERLAP_RATIO, MAX_NODE_STEP_RATIO,
                       MAX_BODY_STEP_RATIO * (r_min if N else 1.0), skin, alpha])
    acc = np.zeros(ACC_SIZE)
    tables = Tables(E=E_tab, mu=mu, kt=ktr, zeta=zeta, gravity=gravity)
    if meshmesh_needed:
        touching, depth = initial_overlap(bodies)
        if depth > MAX_OVERLAP_RATIO:
            raise SceneError.single("bodies", body_names, (
                f"two mesh bodies start interpenetrating ({depth:.3g} x the contact point "
                f"length deep, limit {MAX_OVERLAP_RATIO}): move them apart, or list one in "
                f"the other's no_contact_with"))
        if touching:
            warnings.append(f"{touching} mesh-mesh contact point(s) start inside another "
                            f"body (at most {depth:.3g} x the contact point length deep)")
    system = System(scene=scene, nodes=nodes, bonds=bonds, roots=roots, bodies=bodies,
                    pairs=pairs, body_pairs=body_pairs, loads=loads, tables=tables,
                    flags=flags, acc=acc, err=np.zeros(4), stage_time=np.zeros(len(STAGES)),
                    limits=limits, dt=float(dt), dt_limited_by=limited_by,
                    dt_stable=float(dt_stable), stages=stages, brushes=brushes,
                    body_names=body_names, bristle_first_node=bristle_first_arr,
                    bristle_brush=bristle_brush_arr, node_bristle=node_bristle_arr,
                    warnings=warnings, body_geometry=geoms,
                    body_frame_offset=shape_to_body_list, mission=mission)
    if bb_needed or bbody_needed:
        initial_lists(system)
    return system


def _mission(scene: Scene, orbit_n: float, body_names: list[str],
             shape_to_body: list) -> Mission:
    """The mission layer's arrays: orbit, controllers (engine.control), external loads."""
    from . import control as C
    orbit = scene.environment.orbit
    orbit_arr = np.array([orbit_n, 1.0 if (orbit is not None and orbit.gravity_gradient)
                          else 0.0])
    nc = len(scene.controllers)
    ci = np.full((max(nc, 1), 2), -1, np.int64)
    cp = np.zeros((max(nc, 1), C.P_SIZE))
    cs = np.zeros((max(nc, 1), C.S_SIZE))
    for i, c in enumerate(scene.controllers):
        ci[i, 0] = body_names.index(c.body)
        ci[i, 1] = body_names.index(c.reference) if c.reference is not None else -1
        g, a = c.position_gains, c.attitude_gains
        cp[i, [C.P_KP, C.P_KD, C.P_KI]] = g.proportional, g.derivative, g.integral
        cp[i, [C.P_KPA, C.P_KDA, C.P_KIA]] = a.proportional, a.derivative, a.integral
        cp[i, C.P_INTERVAL] = c.sample_interval
        cp[i, C.P_MAXF:C.P_MAXF + 3] = c.max_force if c.max_force is not None else np.inf
        cp[i, C.P_MAXT:C.P_MAXT + 3] = c.max_torque if c.max_torque is not None else np.inf
        cp[i, C.P_DB_POS] = c.position_deadband
        cp[i, C.P_DB_ATT] = c.attitude_deadband
        cp[i, C.P_TARGET:C.P_TARGET + 3] = c.position
        cp[i, C.P_QTARGET:C.P_QTARGET + 4] = c.orientation
        # q_body = q_pose q_p (principal -> shape): the mesh axes are q_body q_p^-1
        cp[i, C.P_QBM:C.P_QBM + 4] = _conj(np.asarray(shape_to_body[ci[i, 0]], float))
    ext = np.zeros((len(scene.bodies), 6))
    for k, b in enumerate(scene.bodies):
        ext[k, :3] = b.external_force
        ext[k, 3:] = b.external_torque
    return Mission(orbit=orbit_arr, ctl_index=ci, ctl_par=cp, ctl_state=cs, external=ext)


def _max_body_speeds(bodies: Bodies, collide) -> tuple[float, int]:
    """The largest surface speed |v| + |omega| r_bound any colliding body reaches: along its
    whole profile for a kinematic body (the Hermite velocity sampled densely), its initial
    state for free and hinge bodies. Returns (speed, body index)."""
    best, who = 0.0, -1
    tau = np.linspace(0.0, 1.0, 33)
    for k in range(len(bodies.mass)):
        if not collide[k]:
            continue
        if bodies.motion[k] == KINEMATIC:
            sp = 0.0
            for c in range(int(bodies.seg_start[k]), int(bodies.seg_start[k + 1])):
                h = bodies.t1[c] - bodies.t0[c]
                if h <= 0:
                    continue
                d00 = (6 * tau ** 2 - 6 * tau) / h
                d10 = 3 * tau ** 2 - 4 * tau + 1
                d11 = 3 * tau ** 2 - 2 * tau
                vel = (np.outer(d00, bodies.p0[c]) + np.outer(d10, bodies.v0[c])
                       - np.outer(d00, bodies.p1[c]) + np.outer(d11, bodies.v1[c]))
                sp = max(sp, float(np.linalg.norm(vel, axis=1).max())
                         + float(np.linalg.norm(bodies.wseg[c])) * bodies.bound_r[k])
        elif bodies.motion[k] == FIXED:
            continue
        else:
            sp = float(np.linalg.norm(bodies.v[k])
                       + np.linalg.norm(bodies.w[k]) * bodies.bound_r[k])
        if sp > best:
            best, who = sp, k
    return best, who


def _pair_list(cap: int, friction: bool) -> PairList:
    """Segment pairs (capacity ``cap``) with ``NSLOT`` contact slots each; tangential
    history only where there is friction."""
    from .contacts import NSLOT
    c = cap * NSLOT
    h = c if friction else 1
    return PairList(a=np.zeros(cap, np.int64), b=np.zeros(cap, np.int64), ft=np.zeros((h, 3)),
                    active=np.zeros(c, np.int8), fc=np.zeros((c, 3)), cp=np.zeros((c, 3)),
                    s=np.zeros(c), t=np.zeros(c), energy=np.zeros(c), diss=np.zeros(c),
                    ratio=np.zeros(c), n=np.zeros(2, np.int64), a2=np.zeros(cap, np.int64),
                    b2=np.zeros(cap, np.int64), ft2=np.zeros((h, 3)),
                    xf=np.zeros((c, 4, 3)))


def _body_list(cap: int, friction: bool) -> BodyList:
    """(segment, body) candidates (capacity ``cap``) with ``BSLOT`` contact slots each."""
    from .body_contacts import BSLOT
    c = cap * BSLOT
    h = c if friction else 1
    return BodyList(s=np.zeros(cap, np.int64), b=np.zeros(cap, np.int64), ft=np.zeros((h, 3)),
                    active=np.zeros(c, np.int8), fc=np.zeros((c, 3)), cp=np.zeros((c, 3)),
                    par=np.zeros(c), energy=np.zeros(c), diss=np.zeros(c),
                    ratio=np.zeros(c), local=np.zeros((cap, 2, 3)), n=np.zeros(2, np.int64),
                    s2=np.zeros(cap, np.int64), b2=np.zeros(cap, np.int64),
                    ft2=np.zeros((h, 3)), xf=np.zeros((c, 4, 3)),
                    deep=np.zeros(cap, np.int8), deep2=np.zeros(cap, np.int8))


def grow_lists(system: System, which: int, needed: int) -> None:
    """Replace a neighbour list by a larger one, keeping its contents."""
    cap = int(needed * 1.5) + 64
    if which == 1:
        old = system.pairs
        new = _pair_list(cap, system.flags.friction_bristle)
        n = int(old.n[0])
        new.a[:n] = old.a[:n]
        new.b[:n] = old.b[:n]
        if system.flags.friction_bristle:
            from .contacts import NSLOT
            new.ft[:n * NSLOT] = old.ft[:n * NSLOT]
        new.n[0] = n
        system.pairs = new
    else:
        old = system.body_pairs
        new = _body_list(cap, system.flags.friction_body)
        n = int(old.n[0])
        new.s[:n] = old.s[:n]
        new.b[:n] = old.b[:n]
        new.deep[:n] = old.deep[:n]
        if system.flags.friction_body:
            from .body_contacts import BSLOT
            new.ft[:n * BSLOT] = old.ft[:n * BSLOT]
        new.n[0] = n
        system.body_pairs = new


def initial_lists(system: System) -> None:
    from .state import OK
    from .stepper import rebuild_lists
    while True:
        code = rebuild_lists(system.nodes, system.bonds, system.bodies, system.pairs,
                             system.body_pairs, system.flags, system.limits[3])
        if code == OK:
            return
        which = 1 if code == 1 else 2
        needed = int((system.pairs if which == 1 else system.body_pairs).n[1])
        grow_lists(system, which, needed)


STRETCH_MARGIN = 0.05  # reach of a node: its arc length from the root x (1 + this)


def _node_reach(x, rad, nbristle, bristle_first):
    """Per node, the root of its bristle and how far from it any point of the node's segments
    can get: the arc length of the next node (bristles start straight), stretched by
    ``STRETCH_MARGIN``, plus the bristle's largest radius. Contacts on a segment act on both
    of its nodes (``contacts.add_segment_force``), hence the next node's arc length."""
    N = x.shape[0]
    first = np.asarray(bristle_first, np.int64)[nbristle]
    last = np.asarray(bristle_first, np.int64)[nbristle + 1] - 1
    root = x[first]
    far = x[np.minimum(np.arange(N) + 1, last)]
    r_max = np.zeros(len(bristle_first) - 1)
    np.maximum.at(r_max, nbristle, rad)
    reach = (1.0 + STRETCH_MARGIN) * np.linalg.norm(far - root, axis=1) + r_max[nbristle]
    return root, reach


def _roots_move(brushes, motion) -> np.ndarray:
    """Per brush: does its base move (mounted on a body that is not fixed)?"""
    return np.array([b.mount >= 0 and motion[b.mount] != FIXED for b in brushes], bool)


def _bristle_partners(brushes, x, rad, nbristle, bristle_first, n_bristle, motion):
    """Per node, how many other bristles can touch its segments. Bristles whose roots are
    fixed, or ride on one rigid base, keep their roots' distances, and a point of a bristle
    stays within its reach (``_node_reach``) of its root: node i of bristle b and bristle c
    can meet only if |root_b - root_c| <= reach_i + reach of c's tip. A bristle on a moving
    base can meet every bristle of the other bases."""
    N = x.shape[0]
    count = np.zeros(N, np.int64)
    if n_bristle < 2:
        return count
    root, reach = _node_reach(x, rad, nbristle, bristle_first)
    bf = np.asarray(bristle_first, np.int64)
    tips = bf[1:] - 1
    moving = _roots_move(brushes, motion)
    brush_of = np.zeros(n_bristle, np.int64)
    for i, info in enumerate(brushes):
        brush_of[info.first_bristle:info.first_bristle + info.n_bristles] = i
    # a rigid frame per bristle: -1 for the world, else the moving mount body
    frame = np.array([brushes[b].mount if moving[b] else -1 for b in brush_of], np.int64)
    for f in np.unique(frame):
        members = np.flatnonzero(frame == f)
        reach_tip = reach[tips[members]]
        nodes = np.flatnonzero(np.isin(nbristle, members))
        hits = _roots_within(root[bf[members]], root[nodes], reach[nodes] + reach_tip.max())
        for n, h in zip(nodes, hits):
            h = np.asarray(h, np.int64)
            d = np.linalg.norm(root[bf[members[h]]] - root[n], axis=1)
            count[n] += int(np.count_nonzero((d <= reach[n] + reach_tip[h])
                                             & (members[h] != nbristle[n])))
        others = int(np.count_nonzero(frame != f))
        if others and (f >= 0 or np.any(frame >= 0)):
            # another base moves relative to this one: any bristle of it may come
            count[nodes] += others if f >= 0 else int(np.count_nonzero(frame >= 0))
    return count


_BRUTE_PAIRS = 1_000_000  # up to this many root-node pairs numpy compares all of them


def _roots_within(roots, points, radius):
    """Per point, the indices of the roots within its radius. A k-d tree for large brushes;
    small ones compare every pair, which costs less than importing scipy.spatial."""
    if roots.shape[0] * points.shape[0] > _BRUTE_PAIRS:
        from scipy.spatial import cKDTree
        return cKDTree(roots).query_ball_point(points, radius)
    d2 = ((points[:, None, :] - roots[None, :, :]) ** 2).sum(axis=2)
    return [np.flatnonzero(row <= r * r) for row, r in zip(d2, radius)]


def _body_regions(bodies, after_free):
    """Per body, capsules (a, b, radius) that contain its surface over the whole run, or None
    where its travel cannot be bounded (free bodies, kinematic ones freed at the end). A
    kinematic Hermite segment p(tau) = p0 + (p1 - p0) h01 + h (h10 v0 + h11 v1) stays within
    4/27 h (|v0| + |v1|) of [p0, p1] (|h10|, |h11| <= 4/27, 0 <= h01 <= 1)."""
    regions = []
    for k in range(bodies.pos.shape[0]):
        R = float(bodies.bound_r[k])
        m = bodies.motion[k]
        if m == FIXED:
            regions.append([(bodies.pos[k], bodies.pos[k], R)])
        elif m == HINGE:
            c = bodies.hinge_point[k]
            regions.append([(c, c, float(np.linalg.norm(bodies.pos[k] - c)) + R)])
        elif m == KINEMATIC and not after_free[k]:
            segs = range(bodies.seg_start[k], bodies.seg_start[k + 1])
            regions.append([(bodies.p0[c], bodies.p1[c], R + 4.0 / 27.0 * (
                bodies.t1[c] - bodies.t0[c]) * (np.linalg.norm(bodies.v0[c])
                                                 + np.linalg.norm(bodies.v1[c])))
                            for c in segs])
        else:
            regions.append(None)
    return regions


def _node_body_stiffness(brushes, bodies, x, rad, E_node, nbristle, bristle_first, E_tab,
                         after_free) -> np.ndarray:
    """Per node, the sum over the bodies that can touch it of the contact's normal stiffness
    ``2 E_b E_k r / (E_b + E_k)`` (seed eq. 3.6), doubled (a two-sided row) for bodies that
    move under forces. A body can touch a node if the node's reach around its root
    (``_node_reach``) meets the body's region (``_body_regions``); nodes of a brush on a moving
    base can touch every body but their own mount."""
    N = x.shape[0]
    out = np.zeros(N)
    root, reach = _node_reach(x, rad, nbristle, bristle_first)
    moving = _roots_move(brushes, bodies.motion)
    brush_of = np.zeros(N, np.int64)
    mount_of = np.zeros(N, np.int64)
    for i, info in enumerate(brushes):
        sl = slice(info.first_node, info.first_node + info.n_bristles * info.n_nodes)
        brush_of[sl] = i
        mount_of[sl] = info.mount
    node_moves = moving[brush_of]
    for k, region in enumerate(_body_regions(bodies, after_free)):
        if not bodies.collide[k]:
            continue
        if region is None:
            can = np.ones(N, bool)
        else:
            gap = np.full(N, np.inf)
            for a, b, R in region:
                ab = b - a
                L2 = float(ab @ ab)
                t = np.clip((root - a) @ ab / L2, 0.0, 1.0) if L2 > 0 else np.zeros(N)
                d = np.linalg.norm(root - (a + t[:, None] * ab), axis=1) - R
                gap = np.minimum(gap, d)
            can = (gap <= reach) | node_moves
        can &= mount_of != k
        Ek = float(E_tab[bodies.material[k]])
        two_sided = bodies.motion[k] in (FREE, HINGE) or after_free[k]
        out += np.where(can, (2.0 if two_sided else 1.0) * 2.0 * E_node * Ek / (E_node + Ek)
                        * rad, 0.0)
    return out
