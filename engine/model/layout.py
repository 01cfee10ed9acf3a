"""The rest layout of a brush's bristles, and the numpy quaternion helpers it needs.

One source for the geometry that ``engine.build`` compiles and the studio's design view
draws (docs/scene.md "Brushes"): a grid of ``rows`` x ``columns`` roots centred on the base
origin (columns along the base's x at ``pitch[0]``, rows along its y at ``pitch[1]``, odd
rows shifted half a pitch along x when ``staggered``), each bristle straight from its root
to its tip at ``bristle_length`` along the base's +z, the tip perturbed in the base's x-y
plane by two Gaussian draws of variance ``tip_variance`` per bristle, row by row, from
``numpy.random.default_rng(seed)``; ``n_nodes`` nodes evenly spaced from root to tip, the
radius tapering linearly from ``root_radius`` to ``tip_radius``. A mounted base's pose is
relative to its body's shape frame (the body's ``pose``).

numpy only (no numba, no trimesh), so that the studio can import it. Quaternions are
``[w, x, y, z]`` and rotate local coordinates into world coordinates; the numba kernels of
``engine.kernels.rotations`` are the step loop's versions of the same formulas.

Every per-row product goes through numpy's ``matmul`` on stacks of rows, which calls, per
row, the same routine as ``R @ v`` and ``np.dot(v, v)`` on one row: the layout is the same
to the last bit as the bristle-by-bristle loop ``build`` used before, at numpy speed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

IDENTITY = (1.0, 0.0, 0.0, 0.0)
Z_AXIS = np.array([0.0, 0.0, 1.0])


# --------------------------------------------------------------------------- quaternions
def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion [w, x, y, z] (not normalised here): (4,) -> (3, 3),
    or a stack (..., 4) -> (..., 3, 3)."""
    q = np.asarray(q, float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def quat_mul(a, b) -> np.ndarray:
    """Hamilton product a*b of quaternions (4,) or stacks (M, 4), broadcast."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def quat_conj(q) -> np.ndarray:
    """The conjugate (the inverse of a unit quaternion), (4,) or (M, 4)."""
    q = np.array(q, float)
    q[..., 1:] *= -1.0
    return q


def row_dots(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per row ``np.dot(a[k], b[k])`` of two (M, 3) or (M, 4) stacks."""
    return np.matmul(a[:, None, :], b[:, :, None])[:, 0, 0]


def rotate_rows(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Per row ``R @ v[k]`` of an (M, 3) stack (R a 3x3 matrix)."""
    v = np.asarray(v, float)
    return np.matmul(R[None], v[:, :, None])[:, :, 0]


def quat_from_two_vectors(a, b) -> np.ndarray:
    """The shortest rotation taking direction a to direction b (any lengths > 0)."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    c = np.cross(a, b)
    d = float(np.dot(a, b))
    if d < -1 + 1e-12:
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return np.array([0.0, *axis])
    q = np.array([1.0 + d, *c])
    return q / np.linalg.norm(q)


def quats_z_to(d) -> np.ndarray:
    """(M, 4) unit quaternions rotating +z onto each row of ``d`` (M, 3): per row
    ``quat_from_two_vectors(+z, d[k])``, bit for bit. A zero row gets the identity."""
    d = np.asarray(d, float).reshape(-1, 3)
    n = np.sqrt(row_dots(d, d))
    n[n == 0] = 1.0
    b = d / n[:, None]
    bx, by, bz = b[:, 0], b[:, 1], b[:, 2]
    q = np.empty((len(d), 4))
    # 1 + z.b and z x b, as np.dot and np.cross compute them for a = +z (the same products
    # by 0 and 1, so the same signs of zero)
    q[:, 0] = 1.0 + bz
    q[:, 1] = 0.0 * bz - by
    q[:, 2] = bx - 0.0 * bz
    q[:, 3] = 0.0 * by - 0.0 * bx
    # d along -z: half a turn about y (+z x +x), as quat_from_two_vectors takes it
    q[bz < -1 + 1e-12] = (0.0, 0.0, 1.0, 0.0)
    q /= np.sqrt(row_dots(q, q))[:, None]
    return q


def compose_pose(parent_position, parent_orientation, position, orientation
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The world pose of a frame placed at (position, orientation) in a parent frame."""
    pp = np.asarray(parent_position, float)
    pq = np.asarray(parent_orientation, float)
    return (pp + quat_to_matrix(pq) @ np.asarray(position, float),
            quat_mul(pq, np.asarray(orientation, float)))


# --------------------------------------------------------------------------- layout
@dataclass
class BristleLayout:
    """The rest geometry of one brush, world coordinates (SI), bristles row by row.

    ``positions`` (n_bristles * n_nodes, 3): the nodes, bristle after bristle, root first;
    ``radius`` (n_nodes,): the node radii of every bristle, root to tip;
    ``orientations`` (n_bristles, 4): the frame of each bristle's nodes (z along the bristle);
    ``roots`` and ``directions`` (n_bristles, 3): root points and unit root->tip directions."""

    base_position: np.ndarray
    base_orientation: np.ndarray
    roots: np.ndarray
    directions: np.ndarray
    orientations: np.ndarray
    positions: np.ndarray
    radius: np.ndarray
    segment_length: float
    n_nodes: int

    @property
    def n_bristles(self) -> int:
        return int(self.roots.shape[0])

    @property
    def node_radius(self) -> np.ndarray:
        """(n_bristles * n_nodes,) the radius of every node."""
        return np.tile(self.radius, self.n_bristles)

    @property
    def node_orientations(self) -> np.ndarray:
        """(n_bristles * n_nodes, 4) the orientation of every node."""
        return np.repeat(self.orientations, self.n_nodes, axis=0)

    def bonds(self, first_node: int = 0) -> np.ndarray:
        """(n_bristles * (n_nodes - 1), 2) the node pairs of the segments, root to tip,
        numbering the nodes from ``first_node``."""
        starts = first_node + np.arange(self.n_bristles) * self.n_nodes
        i = (starts[:, None] + np.arange(self.n_nodes - 1)[None, :]).ravel()
        return np.stack([i, i + 1], axis=1).astype(np.int64)


def grid_roots(rows: int, columns: int, pitch: Sequence[float], pattern: str = "grid"
               ) -> np.ndarray:
    """(rows * columns, 3) root points in the base frame, row by row."""
    x = np.tile((np.arange(columns) - 0.5 * (columns - 1)) * pitch[0], (rows, 1))
    if pattern == "staggered":
        x[1::2] += 0.5 * pitch[0]
    y = np.repeat((np.arange(rows) - 0.5 * (rows - 1)) * pitch[1], columns)
    return np.stack([x.ravel(), y, np.zeros(rows * columns)], axis=1)


def brush_layout(*, rows: int, columns: int, pitch: Sequence[float], pattern: str,
                 bristle_length: float, root_radius: float, tip_radius: float, n_nodes: int,
                 tip_variance: float, seed: int, base_position=(0.0, 0.0, 0.0),
                 base_orientation=IDENTITY, mount_position=None,
                 mount_orientation: Optional[Sequence[float]] = None) -> BristleLayout:
    """The rest layout of one brush (the fields of ``engine.model.spec.Brush``); the base pose is
    relative to the mount's pose (a body's ``pose``: its shape frame) when one is given."""
    n = int(n_nodes)
    pb = np.asarray(base_position, float)
    qb = np.asarray(base_orientation, float)
    if mount_position is not None:
        pb, qb = compose_pose(mount_position, mount_orientation, pb, qb)
    Rb = quat_to_matrix(qb)
    roots_l = grid_roots(rows, columns, pitch, pattern)
    tips_l = roots_l + np.array([0.0, 0.0, bristle_length])
    if tip_variance > 0:
        rng = np.random.default_rng(seed)
        tips_l[:, :2] += rng.normal(0.0, math.sqrt(tip_variance), (len(tips_l), 2))
    d_l = tips_l - roots_l
    d_l /= np.sqrt(row_dots(d_l, d_l))[:, None]
    orientations = quat_mul(qb, quats_z_to(d_l))
    roots_w = pb + rotate_rows(Rb, roots_l)
    d_w = rotate_rows(Rb, d_l)
    seg_len = bristle_length / (n - 1)
    along = np.arange(n) * seg_len
    positions = roots_w[:, None, :] + d_w[:, None, :] * along[None, :, None]
    radius = root_radius + (tip_radius - root_radius) * np.linspace(0.0, 1.0, n)
    return BristleLayout(base_position=pb, base_orientation=qb, roots=roots_w, directions=d_w,
                         orientations=orientations, positions=positions.reshape(-1, 3),
                         radius=radius, segment_length=seg_len, n_nodes=n)
