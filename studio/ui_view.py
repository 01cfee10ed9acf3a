"""The studio's 3D view: bristle segments as instanced cylinders, bodies as meshes.

Geometry comes from two places only:

* a **design** (a scene dict): the rest layout of docs/scene.md ("Brushes": grid or
  staggered rows centred on the base, straight bristles from root to the randomly perturbed
  tip, radius tapering linearly) and each body's shape mesh at its pose;
* a **result file** (read with ``engine.open_result``): recorded node positions
  (``nodes/positions``), the bonds (``bonds/nodes``), node radii, body vertices in the body
  frame and the recorded body poses.

The view draws in millimetres (scene metres x 1000) so that a brush is a few tens of units
across. Every bristle segment is one instance of a unit cylinder, scaled per instance to its
own radius (x, y) and length (z): one ``add_batched_meshes_simple`` node for all bristles.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

VIEW_SCALE = 1000.0  # view units (mm) per metre
CYLINDER_SECTIONS = 10
BRISTLE_COLOR = (70, 150, 230)
BODY_COLOR = (230, 140, 60)


# --------------------------------------------------------------------------- rotations
def quat_to_matrix(q) -> np.ndarray:
    """[w, x, y, z] (any norm) -> 3x3 rotation matrix."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def quat_mul(a, b) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def quats_z_to(d: np.ndarray) -> np.ndarray:
    """(M, 4) unit quaternions [w, x, y, z] rotating +z onto each row of ``d`` (M, 3)
    (any length > 0): the half-way quaternion [1 + cos, z x d]."""
    n = np.sqrt(np.einsum("ij,ij->i", d, d))
    n[n == 0] = 1.0
    q = np.zeros((len(d), 4))
    q[:, 0] = 1.0 + d[:, 2] / n
    q[:, 1] = -d[:, 1] / n
    q[:, 2] = d[:, 0] / n
    qn = np.sqrt(np.einsum("ij,ij->i", q, q))
    flip = qn < 1e-9  # d along -z: half a turn about x
    if flip.any():
        q[flip] = (0.0, 1.0, 0.0, 0.0)
        qn[flip] = 1.0
    q /= qn[:, None]
    return q


# --------------------------------------------------------------------------- geometry
@dataclass
class Bristles:
    """Bristle nodes (SI): positions (N, 3), radius (N,), bonds (S, 2) node pairs."""

    positions: np.ndarray
    radius: np.ndarray
    bonds: np.ndarray
    n_bristles: int

    @property
    def n_segments(self) -> int:
        return int(len(self.bonds))


def _pose(pose: Optional[dict]) -> tuple[np.ndarray, np.ndarray]:
    pose = pose or {}
    return (np.asarray(pose.get("position", (0.0, 0.0, 0.0)), float),
            np.asarray(pose.get("orientation", (1.0, 0.0, 0.0, 0.0)), float))


def design_bristles(scene: dict) -> Bristles:
    """The rest geometry of every brush of a (validated) scene dict, as docs/scene.md
    describes it: grid centred on the base, odd rows shifted half a pitch when staggered,
    each tip perturbed in the base's x-y plane by a Gaussian of variance ``tip_variance``
    drawn from ``numpy.random.default_rng(seed)`` (two draws per bristle, row by row), nodes
    evenly spaced on the straight line from root to tip."""
    pos_all, rad_all, bonds_all = [], [], []
    n_node = 0
    n_bristles = 0
    bodies = {b["name"]: b for b in scene.get("bodies") or []}
    for br in scene.get("brushes") or []:
        rows, cols = int(br.get("rows", 1)), int(br.get("columns", 1))
        pitch = br.get("pitch", (0.003, 0.003))
        n = int(br.get("n_nodes", 8))
        length = float(br["bristle_length"])
        pb, qb = _pose(br.get("base"))
        if br.get("mount"):
            ps, qs = _pose(bodies[br["mount"]].get("pose"))
            pb = ps + quat_to_matrix(qs) @ pb
            qb = quat_mul(qs, qb)
        Rb = quat_to_matrix(qb)
        col = np.arange(cols, dtype=float)
        row = np.arange(rows, dtype=float)
        x = (col[None, :] - 0.5 * (cols - 1)) * pitch[0] + np.zeros((rows, 1))
        if br.get("pattern", "grid") == "staggered":
            x[1::2] += 0.5 * pitch[0]
        y = ((row - 0.5 * (rows - 1)) * pitch[1])[:, None] + np.zeros((1, cols))
        roots = np.stack([x.ravel(), y.ravel(), np.zeros(rows * cols)], axis=1)
        tips = roots + (0.0, 0.0, length)
        var = float(br.get("tip_variance", 0.0))
        if var > 0:
            rng = np.random.default_rng(int(br.get("seed", 0)))
            tips[:, :2] += rng.normal(0.0, math.sqrt(var), (rows * cols, 2))
        d = tips - roots
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        frac = np.arange(n) * (length / (n - 1))
        local = roots[:, None, :] + d[:, None, :] * frac[None, :, None]  # (nb, n, 3)
        world = local.reshape(-1, 3) @ Rb.T + pb
        r_node = float(br["root_radius"]) + (float(br["tip_radius"]) -
                                             float(br["root_radius"])) * np.linspace(0, 1, n)
        nb = rows * cols
        starts = n_node + np.arange(nb) * n
        i = (starts[:, None] + np.arange(n - 1)[None, :]).ravel()
        pos_all.append(world)
        rad_all.append(np.tile(r_node, nb))
        bonds_all.append(np.stack([i, i + 1], axis=1))
        n_node += nb * n
        n_bristles += nb
    if not pos_all:
        return Bristles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 2), np.int64), 0)
    return Bristles(np.concatenate(pos_all), np.concatenate(rad_all),
                    np.concatenate(bonds_all).astype(np.int64), n_bristles)


def n_design_segments(scene: dict) -> int:
    """How many segments a scene's brushes have (without building them)."""
    return sum(int(b.get("rows", 1)) * int(b.get("columns", 1)) * (int(b.get("n_nodes", 8)) - 1)
               for b in scene.get("brushes") or [])


def segment_instances(positions: np.ndarray, radius: np.ndarray, bonds: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Instances of the unit cylinder (radius 1, height 1 along z, centred) for each bond:
    (centres (S, 3), orientations (S, 4) wxyz, per-axis scales (S, 3)), in view units (mm).
    A segment's radius is the mean of its two nodes' radii (DESIGN §3)."""
    i, j = bonds[:, 0], bonds[:, 1]
    a = positions[i]
    b = positions[j]
    d = b - a
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    r = 0.5 * (radius[i] + radius[j])
    centres = (a + b) * (0.5 * VIEW_SCALE)
    wxyz = quats_z_to(d)
    scales = np.empty((len(bonds), 3))
    scales[:, 0] = r * VIEW_SCALE
    scales[:, 1] = r * VIEW_SCALE
    scales[:, 2] = length * VIEW_SCALE
    return centres, wxyz, scales


_VIRIDIS = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98],
                     [253, 231, 37]], float)


def colormap(values: np.ndarray, vmax: float) -> np.ndarray:
    """(S, 3) uint8 colours (viridis-like) of values in [0, vmax]."""
    t = np.clip(np.nan_to_num(np.asarray(values, float)) / (vmax if vmax > 0 else 1.0), 0, 1)
    x = t * (len(_VIRIDIS) - 1)
    i = np.minimum(x.astype(int), len(_VIRIDIS) - 2)
    f = (x - i)[:, None]
    return (_VIRIDIS[i] * (1 - f) + _VIRIDIS[i + 1] * f).astype(np.uint8)


def colormap_css() -> str:
    """The colour scale of :func:`colormap` as a CSS gradient, 0 on the left (for a legend)."""
    stops = ", ".join(f"rgb({r:.0f},{g:.0f},{b:.0f})" for r, g, b in _VIRIDIS)
    return f"linear-gradient(to right, {stops})"


def unit_cylinder(sections: int = CYLINDER_SECTIONS) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a closed cylinder of radius 1 and height 1 along z, centred."""
    import trimesh

    m = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=sections)
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.uint32)


def shape_mesh(shape: dict):
    """A body shape (scene dict, SI) as a trimesh in the shape's own frame, as docs/scene.md
    "Shapes" defines it."""
    import trimesh

    t = shape["type"]
    if t == "box":
        return trimesh.creation.box(extents=shape["size"])
    if t == "sphere":
        return trimesh.creation.icosphere(subdivisions=int(shape.get("subdivisions", 3)),
                                          radius=float(shape["radius"]))
    if t == "cylinder":
        return trimesh.creation.cylinder(radius=float(shape["radius"]),
                                         height=float(shape["height"]),
                                         sections=int(shape.get("sections", 32)))
    if t == "wedge":
        h, half = float(shape["height"]), 0.5 * float(shape["length"])
        w = h * math.tan(0.5 * float(shape["angle"]))
        section = [(0.0, 0.0), (-w, h), (w, h)]
        vertices = np.array([[x, y, z] for x in (-half, half) for y, z in section])
        faces = np.array([[0, 1, 2], [3, 5, 4], [0, 3, 4], [0, 4, 1], [0, 2, 5], [0, 5, 3],
                          [1, 4, 5], [1, 5, 2]])
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        if mesh.volume < 0:
            mesh.invert()
        return mesh
    if t == "mesh":
        loaded = trimesh.load(Path(shape["file"]), force="mesh")
        loaded.apply_scale(float(shape.get("scale", 1.0)))
        return loaded
    raise ValueError(f"unknown shape type {t!r}")


@dataclass
class BodyMesh:
    """A body to draw: vertices (V, 3) and faces in its own frame (SI), and its pose."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    position: np.ndarray
    wxyz: np.ndarray


def design_bodies(scene: dict) -> list[BodyMesh]:
    """Every body of a scene dict in its shape frame at its pose. A mesh file that cannot be
    read is skipped (the scene's validation names it)."""
    out = []
    for b in scene.get("bodies") or []:
        try:
            m = shape_mesh(b["shape"])
        except Exception:
            continue
        p, q = _pose(b.get("pose"))
        out.append(BodyMesh(b["name"], np.asarray(m.vertices, float),
                            np.asarray(m.faces, np.int64), p, q / np.linalg.norm(q)))
    return out


# --------------------------------------------------------------------------- viser drawing
class View:
    """The 3D scene of the studio: one batched cylinder node for all bristle segments, one
    mesh per body. Updates reuse the nodes (assignment inside ``server.atomic()``) when the
    number of instances is unchanged, and replace them otherwise."""

    def __init__(self, server, root: str = "/studio"):
        self.server = server
        self.root = root
        self.cyl_vertices, self.cyl_faces = unit_cylinder()
        self.bristles = None
        self.n_instances = -1
        self.bodies: dict[str, object] = {}
        self.body_shapes: dict[str, tuple[int, int, float]] = {}

    # bristles ---------------------------------------------------------------------
    def set_bristles(self, centres, wxyz, scales, colors=None) -> None:
        """Draw ``len(centres)`` cylinder instances (view units)."""
        n = len(centres)
        colors = np.asarray(BRISTLE_COLOR if colors is None else colors, np.uint8)
        if colors.ndim == 1:
            colors = np.broadcast_to(colors, (n, 3))
        if n == 0:
            if self.bristles is not None:
                self.bristles.remove()
                self.bristles = None
            self.n_instances = 0
            return
        if self.bristles is not None and self.n_instances == n:
            with self.server.atomic():
                self.bristles.batched_positions = centres.astype(np.float32)
                self.bristles.batched_wxyzs = wxyz.astype(np.float32)
                self.bristles.batched_scales = scales.astype(np.float32)
                self.bristles.batched_colors = colors
            return
        if self.bristles is not None:
            self.bristles.remove()
        self.bristles = self.server.scene.add_batched_meshes_simple(
            f"{self.root}/bristles", self.cyl_vertices, self.cyl_faces,
            batched_wxyzs=wxyz.astype(np.float32), batched_positions=centres.astype(np.float32),
            batched_scales=scales.astype(np.float32), batched_colors=np.ascontiguousarray(colors),
            lod="off", cast_shadow=False, receive_shadow=False)
        self.n_instances = n

    def mean_segment_position(self) -> Optional[list]:
        """The mean of the drawn segments' centres (view units), None when none are drawn:
        for tests and scripts, a number that moves when the drawn bristles bend."""
        if self.bristles is None or self.n_instances <= 0:
            return None
        return [float(c) for c in np.asarray(self.bristles.batched_positions, float).mean(0)]

    def set_bristle_nodes(self, bristles: Bristles, colors=None) -> None:
        self.set_bristles(*segment_instances(bristles.positions, bristles.radius,
                                             bristles.bonds), colors)

    # bodies -----------------------------------------------------------------------
    def set_bodies(self, bodies: Sequence[BodyMesh], highlight=()) -> None:
        """Draw these bodies (and remove the others); those named in ``highlight`` in red
        (an initial overlap)."""
        names = {b.name for b in bodies}
        for name in list(self.bodies):
            if name not in names:
                self.bodies.pop(name).remove()
                self.body_shapes.pop(name, None)
        for b in bodies:
            key = (len(b.vertices), len(b.faces), float(np.sum(b.vertices)))
            handle = self.bodies.get(b.name)
            if handle is None or self.body_shapes.get(b.name) != key:
                if handle is not None:
                    handle.remove()
                handle = self.server.scene.add_mesh_simple(
                    f"{self.root}/bodies/{b.name}",
                    (b.vertices * VIEW_SCALE).astype(np.float32),
                    np.asarray(b.faces, np.uint32), color=BODY_COLOR, opacity=0.85,
                    flat_shading=True, side="double")
                self.bodies[b.name] = handle
                self.body_shapes[b.name] = key
            handle.position = tuple(float(c) for c in b.position * VIEW_SCALE)
            handle.wxyz = tuple(float(c) for c in b.wxyz)
            color = OVERLAP_BODY_COLOR if b.name in highlight else BODY_COLOR
            if tuple(handle.color) != color:
                handle.color = color

    def set_body_pose(self, name: str, position, wxyz) -> None:
        handle = self.bodies.get(name)
        if handle is not None:
            handle.position = tuple(float(c) * VIEW_SCALE for c in position)
            handle.wxyz = tuple(float(c) for c in wxyz)

    def clear(self) -> None:
        self.set_bristles(np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)))
        self.set_bodies([])


# --------------------------------------------------------------------------- initial overlap
OVERLAP_COLOR = (230, 30, 30)
OVERLAP_BODY_COLOR = (235, 40, 40)
MAX_OVERLAP_CHECK_SEGMENTS = 200_000  # above this the design is not checked live (build does)


def design_overlaps(scene: dict, bristles: Optional[Bristles] = None,
                    bodies: Optional[Sequence[BodyMesh]] = None) -> list:
    """The initial overlaps of a design (``engine.overlap.find_overlaps`` on the rest
    geometry the view draws): the same check ``engine.build`` makes, named the same way
    ("bristle 12" of brush 'brush', counted row by row within its brush)."""
    from engine import overlap

    if n_design_segments(scene) > MAX_OVERLAP_CHECK_SEGMENTS:
        return []
    bristles = design_bristles(scene) if bristles is None else bristles
    bodies = design_bodies(scene) if bodies is None else bodies
    names, brush_of, mount_of, node_bristle = [], [], [], []
    body_index = {b["name"]: k for k, b in enumerate(scene.get("bodies") or [])}
    shown = {b.name: i for i, b in enumerate(bodies)}
    first = 0
    brush_names = []
    for i, br in enumerate(scene.get("brushes") or []):
        nb = int(br.get("rows", 1)) * int(br.get("columns", 1))
        n = int(br.get("n_nodes", 8))
        brush_names.append(br.get("name", f"brush{i}"))
        mount = br.get("mount")
        names += [f"bristle {j}" for j in range(nb)]
        brush_of += [i] * nb
        m = shown.get(mount, -1) if mount and mount in body_index else -1
        mount_of += [m] * nb
        node_bristle.append(np.repeat(np.arange(first, first + nb), n))
        first += nb
    closed = {}
    for b in scene.get("bodies") or []:
        closed[b["name"]] = b["shape"].get("type") != "mesh"
    shapes = [overlap.BodyShape(b.name, b.vertices @ quat_to_matrix(b.wxyz).T + b.position,
                                b.faces, closed.get(b.name, True) or _closed(b.faces),
                                bool(next((s.get("collide", True) for s in
                                           scene.get("bodies") or [] if s["name"] == b.name),
                                          True)))
              for b in bodies]
    return overlap.find_overlaps(
        bristles.positions, bristles.radius, bristles.bonds,
        np.concatenate(node_bristle) if node_bristle else np.zeros(0, np.int64), names,
        np.asarray(brush_of, np.int64), brush_names, shapes,
        bristle_mount=np.asarray(mount_of, np.int64))


def _closed(faces: np.ndarray) -> bool:
    """Every edge shared by exactly two faces (a watertight mesh has an inside)."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return bool(len(counts)) and bool(np.all(counts == 2))


def overlap_segment_colors(bristles: Bristles, overlaps: Sequence, n_nodes_of) -> Optional[
        np.ndarray]:
    """Per-segment colours with the overlapping bristles in red (None: nothing to mark).
    ``n_nodes_of``: per bristle, the index of its first node (len n_bristles + 1)."""
    marked = sorted({b for o in overlaps for b in getattr(o, "bristles", [])})
    if not marked:
        return None
    seg_bristle = np.searchsorted(n_nodes_of, bristles.bonds[:, 0], side="right") - 1
    colors = np.tile(np.asarray(BRISTLE_COLOR, np.uint8), (len(bristles.bonds), 1))
    colors[np.isin(seg_bristle, marked)] = OVERLAP_COLOR
    return colors


def design_bristle_first(scene: dict) -> np.ndarray:
    """Per bristle of a design, the index of its first node in ``design_bristles`` (and the
    node count at the end)."""
    counts = [np.full(int(b.get("rows", 1)) * int(b.get("columns", 1)), int(b.get("n_nodes", 8)))
              for b in scene.get("brushes") or []]
    counts = np.concatenate(counts) if counts else np.zeros(0, np.int64)
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
