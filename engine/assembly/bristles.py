"""Build, bristles: the ``Nodes``, ``Bonds`` and ``Roots`` bundles (engine.state) of every
brush, brush after brush and bristle after bristle, row by row.

The rest geometry is :mod:`engine.model.layout`'s (the studio draws the same); here it gets its
physics: node masses and twist inertias of the frustum segments and the exact frustum bond
stiffnesses (:mod:`engine.assembly.element`, which the estimate uses too) and their damping, and the roots clamped in the
world or to the body the brush is mounted on.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from engine.assembly.element import frustum_bond_stiffness, node_masses
from engine.model.layout import BristleLayout, brush_layout, quat_conj, quat_mul, quat_to_matrix, rotate_rows
from engine.model.spec import Scene
from engine.state import Bodies, Bonds, Nodes, Roots


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
class BristlePart:
    """The bristles' bundles and the maps from nodes and bristles to bristles and brushes."""

    nodes: Nodes
    bonds: Bonds
    roots: Roots
    brushes: list[BrushInfo]
    bristle_first: np.ndarray   # (n_bristles + 1,) first node of each bristle, then N
    bristle_brush: np.ndarray   # (n_bristles,)
    node_bristle: np.ndarray    # (N,)
    node_material: np.ndarray   # (N,) material index


def brush_layout_of(scene: Scene, brush) -> BristleLayout:
    """The rest layout (``engine.model.layout``) of one of the scene's brushes, in world
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


def _bristle_physics(material, r_node: np.ndarray, seg_len: float) -> dict:
    """One bristle's node masses and twist inertias (frustum segments, half to each end) and
    its bonds' stiffnesses and damping coefficients (``bond_damping`` of the critical value
    of each bond with its two nodes' reduced mass; the root's mass only for the first)."""
    E = material.youngs_modulus
    G = E / (2.0 * (1.0 + material.poisson_ratio))
    zb = material.bond_damping
    n = len(r_node)
    r0, r1 = r_node[:-1], r_node[1:]
    m_node, I_node = node_masses(material.density, r_node, seg_len)
    kn, ks, kb, ksb, kt = frustum_bond_stiffness(E, G, r0, r1, seg_len)
    mi, mj = m_node[:-1], m_node[1:]
    meff = np.where(np.arange(n - 1) == 0, mj, mi * mj / (mi + mj))
    Ii, Ij = I_node[:-1], I_node[1:]
    Ieff = np.where(np.arange(n - 1) == 0, Ij, Ii * Ij / (Ii + Ij))
    has_next = np.ones(n - 1, np.bool_)
    has_next[-1] = False
    return dict(mass=m_node, inertia=I_node, kn=kn, ks=ks, kb=kb, ksb=ksb, kt=kt,
                cn=2 * zb * np.sqrt(kn * meff), cs=2 * zb * np.sqrt(ks * meff),
                cb=2 * zb * np.sqrt(kb * Ieff), ct=2 * zb * np.sqrt(kt * Ieff),
                has_next=has_next)


def build_bristles(scene: Scene, mat_index: dict, body_names: list[str],
                   bodies: Bodies) -> BristlePart:
    """The bristles of every brush. Roots of a mounted brush are kept in the body frame of
    its mount at the body's build pose (``bodies.pos`` and ``bodies.q``)."""
    node_cols = {k: [] for k in ("x", "q", "rad", "mass", "inertia", "bristle", "material")}
    bond_cols = {k: [] for k in ("i", "j", "kn", "ks", "kb", "ksb", "kt", "L0", "cn", "cs",
                                 "cb", "ct", "has_next", "bristle", "material", "mount")}
    root_cols = {k: [] for k in ("node", "body", "local_pos", "local_q")}
    brushes: list[BrushInfo] = []
    bristle_first = [0]
    bristle_brush = []
    n_node = n_bristle = 0
    for bidx, br in enumerate(scene.brushes):
        mount = body_names.index(br.mount) if br.mount is not None else -1
        lay = brush_layout_of(scene, br)
        n, nb = br.n_nodes, br.n_bristles
        phys = _bristle_physics(scene.materials[br.material], lay.radius, lay.segment_length)
        first_node = n_node
        bristle_ids = n_bristle + np.arange(nb)
        material = mat_index[br.material]
        node_cols["x"].append(lay.positions)
        node_cols["q"].append(lay.node_orientations)
        node_cols["rad"].append(lay.node_radius)
        node_cols["mass"].append(np.tile(phys["mass"], nb))
        node_cols["inertia"].append(np.tile(phys["inertia"], nb))
        node_cols["bristle"].append(np.repeat(bristle_ids, n))
        node_cols["material"].append(np.full(nb * n, material))
        pairs = lay.bonds(first_node)
        bond_cols["i"].append(pairs[:, 0])
        bond_cols["j"].append(pairs[:, 1])
        for key in ("kn", "ks", "kb", "ksb", "kt", "cn", "cs", "cb", "ct", "has_next"):
            bond_cols[key].append(np.tile(phys[key], nb))  # the same bonds on every bristle
        bond_cols["L0"].append(np.full(nb * (n - 1), lay.segment_length))
        bond_cols["bristle"].append(np.repeat(bristle_ids, n - 1))
        bond_cols["material"].append(np.full(nb * (n - 1), material))
        bond_cols["mount"].append(np.full(nb * (n - 1), mount))
        root_cols["node"].append(first_node + n * np.arange(nb))
        root_cols["body"].append(np.full(nb, mount))
        pb_w = lay.base_position
        if mount >= 0:
            Rk = quat_to_matrix(bodies.q[mount])
            root_cols["local_pos"].append(rotate_rows(Rk.T, lay.roots - bodies.pos[mount]))
            root_cols["local_q"].append(quat_mul(quat_conj(bodies.q[mount]), lay.orientations))
            base_local = Rk.T @ (pb_w - bodies.pos[mount])
        else:
            root_cols["local_pos"].append(lay.roots)
            root_cols["local_q"].append(lay.orientations)
            base_local = pb_w
        brushes.append(BrushInfo(br.name, n_bristle, nb, n, first_node, pb_w,
                                 lay.base_orientation, mount,
                                 n_bristle + np.arange(nb, dtype=np.int64),  # a root a bristle
                                 base_local))
        n_node += nb * n
        n_bristle += nb
        bristle_first.extend(first_node + n * (1 + np.arange(nb)))
        bristle_brush.extend([bidx] * nb)

    def cat(key_cols, key, shape, dtype=float):
        lst = key_cols[key]
        return np.concatenate(lst).astype(dtype) if lst else np.zeros(shape, dtype)

    N = n_node
    x = cat(node_cols, "x", (0, 3))
    rad = cat(node_cols, "rad", 0)
    nmass = cat(node_cols, "mass", 0)
    ninertia = cat(node_cols, "inertia", 0)
    bi = cat(bond_cols, "i", 0, np.int64)
    bj = cat(bond_cols, "j", 0, np.int64)
    B = bi.shape[0]
    bond_prev = np.full(N, -1, np.int64)
    bond_next = np.full(N, -1, np.int64)
    bond_next[bi] = np.arange(B)
    bond_prev[bj] = np.arange(B)
    inv_mass = np.where(nmass > 0, 1.0 / np.where(nmass > 0, nmass, 1.0), 0.0)
    inv_inertia = np.where(ninertia > 0, 1.0 / np.where(ninertia > 0, ninertia, 1.0), 0.0)
    root_node = cat(root_cols, "node", 0, np.int64)
    inv_mass[root_node] = 0.0     # roots are clamped
    inv_inertia[root_node] = 0.0
    nodes = Nodes(x=x, v=np.zeros((N, 3)), q=cat(node_cols, "q", (0, 4)), w=np.zeros((N, 3)),
                  f=np.zeros((N, 3)), t=np.zeros((N, 3)), mass=nmass, inv_mass=inv_mass,
                  inertia=ninertia, inv_inertia=inv_inertia, rad=rad, bond_prev=bond_prev,
                  bond_next=bond_next, x_build=x.copy(), x0=x.copy())
    floats = {k: cat(bond_cols, k, 0) for k in ("kn", "ks", "kb", "ksb", "kt", "L0", "cn",
                                                 "cs", "cb", "ct")}
    bonds = Bonds(i=bi, j=bj, **floats, f=np.zeros((B, 3)), ti=np.zeros((B, 3)),
                  tj=np.zeros((B, 3)), energy=np.zeros(B), diss=np.zeros(B), bend=np.zeros(B),
                  has_next=cat(bond_cols, "has_next", 0, np.bool_),
                  bristle=cat(bond_cols, "bristle", 0, np.int64),
                  material=cat(bond_cols, "material", 0, np.int64),
                  mount=cat(bond_cols, "mount", 0, np.int64), mid=np.zeros((B, 3)),
                  bound=np.zeros(B), rmax=np.maximum(rad[bi], rad[bj]) if B else np.zeros(0))
    roots = Roots(node=root_node, body=cat(root_cols, "body", 0, np.int64),
                  local_pos=cat(root_cols, "local_pos", (0, 3)),
                  local_q=cat(root_cols, "local_q", (0, 4)))
    return BristlePart(nodes=nodes, bonds=bonds, roots=roots, brushes=brushes,
                       bristle_first=np.asarray(bristle_first, np.int64),
                       bristle_brush=np.asarray(bristle_brush, np.int64),
                       node_bristle=cat(node_cols, "bristle", 0, np.int64),
                       node_material=cat(node_cols, "material", 0, np.int64))


def start_with_mounts(part: BristlePart, bodies: Bodies, build_pos: np.ndarray,
                      build_q: np.ndarray) -> None:
    """Give every node of a mounted brush its mount's rigid motion at t = 0: the velocity
    ``v_body + omega x (x - x_body)`` and the spin ``omega`` (a brush carried by a moving or
    spinning body starts moving with it instead of at rest, which jerked it in the first
    steps), and, when the body's pose at t = 0 differs from the pose the roots were placed
    at (``build_pos``, ``build_q``: a kinematic profile that starts elsewhere), the whole
    brush moved rigidly with it so that its nodes stay on their roots' frames."""
    nd = part.nodes
    for b in part.brushes:
        k = b.mount
        if k < 0:
            continue
        sl = slice(b.first_node, b.first_node + b.n_bristles * b.n_nodes)
        if not (np.array_equal(bodies.pos[k], build_pos[k])
                and np.array_equal(bodies.q[k], build_q[k])):
            turn = quat_mul(bodies.q[k], quat_conj(build_q[k]))
            R = quat_to_matrix(turn)
            nd.x[sl] = bodies.pos[k] + rotate_rows(R, nd.x[sl] - build_pos[k])
            nd.q[sl] = quat_mul(turn, nd.q[sl])
            nd.x_build[sl] = nd.x[sl]
            nd.x0[sl] = nd.x[sl]
        v, w = _start_velocity(bodies, k)
        nd.v[sl] = v + np.cross(w, nd.x[sl] - bodies.pos[k])
        nd.w[sl] = w


def _start_velocity(bodies: Bodies, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Body k's velocity and angular velocity as the run starts: a kinematic body whose
    first profile segment starts at t = 0 moves off with that segment's initial velocity
    (``kinematic_state`` reports it at rest at the very instant t = 0)."""
    from engine.kernels.bodies import KINEMATIC
    if bodies.motion[k] == KINEMATIC:
        c = int(bodies.seg_start[k])
        if bodies.t0[c] <= 0.0 < bodies.t1[c]:
            return bodies.v0[c].copy(), bodies.wseg[c].copy()
    return bodies.v[k].copy(), bodies.w[k].copy()
