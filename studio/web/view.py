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

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from engine.model import layout
from studio.plots.colors import colormap, colormap_css  # noqa: F401  (the view's colours)

VIEW_SCALE = 1000.0  # view units (mm) per metre
CYLINDER_SECTIONS = 10
BRISTLE_COLOR = (70, 150, 230)
BODY_COLOR = (230, 140, 60)


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


def _brush_field(brush: dict, name: str):
    """A brush field of a scene dict, or the scene model's default (engine.model.spec.Brush)."""
    from engine.model.spec import Brush

    value = brush.get(name)
    return Brush.model_fields[name].default if value is None else value


def _n_bristles(brush: dict) -> int:
    return int(_brush_field(brush, "rows")) * int(_brush_field(brush, "columns"))


def design_layout(scene: dict, brush: dict) -> layout.BristleLayout:
    """The rest layout (``engine.model.layout.brush_layout``, the one ``engine.build`` uses) of one
    brush of a (validated) scene dict."""
    f = lambda name: _brush_field(brush, name)  # noqa: E731
    mount_position = mount_orientation = None
    if brush.get("mount"):
        body = next(b for b in scene.get("bodies") or [] if b["name"] == brush["mount"])
        mount_position, mount_orientation = _pose(body.get("pose"))
    base_position, base_orientation = _pose(brush.get("base"))
    return layout.brush_layout(
        rows=int(f("rows")), columns=int(f("columns")), pitch=tuple(f("pitch")),
        pattern=f("pattern"), bristle_length=float(brush["bristle_length"]),
        root_radius=float(brush["root_radius"]), tip_radius=float(brush["tip_radius"]),
        n_nodes=int(f("n_nodes")), tip_variance=float(f("tip_variance")), seed=int(f("seed")),
        base_position=base_position, base_orientation=base_orientation,
        mount_position=mount_position, mount_orientation=mount_orientation)


def design_bristles(scene: dict) -> Bristles:
    """The rest geometry of every brush of a (validated) scene dict, as docs/scene.md
    describes it and ``engine.build`` places it (``engine.model.layout``)."""
    pos_all, rad_all, bonds_all = [], [], []
    n_node = 0
    n_bristles = 0
    for br in scene.get("brushes") or []:
        lay = design_layout(scene, br)
        pos_all.append(lay.positions)
        rad_all.append(lay.node_radius)
        bonds_all.append(lay.bonds(n_node))
        n_node += len(lay.positions)
        n_bristles += lay.n_bristles
    if not pos_all:
        return Bristles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 2), np.int64), 0)
    return Bristles(np.concatenate(pos_all), np.concatenate(rad_all),
                    np.concatenate(bonds_all).astype(np.int64), n_bristles)


def n_design_segments(scene: dict) -> int:
    """How many segments a scene's brushes have (without building them)."""
    return sum(_n_bristles(b) * (int(_brush_field(b, "n_nodes")) - 1)
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
    wxyz = layout.quats_z_to(d)
    scales = np.empty((len(bonds), 3))
    scales[:, 0] = r * VIEW_SCALE
    scales[:, 1] = r * VIEW_SCALE
    scales[:, 2] = length * VIEW_SCALE
    return centres, wxyz, scales


def unit_cylinder(sections: int = CYLINDER_SECTIONS) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a closed cylinder of radius 1 and height 1 along z, centred."""
    import trimesh

    m = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=sections)
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.uint32)


def shape_mesh(shape: dict):
    """A body shape (scene dict, SI) as a trimesh in the shape's own frame: the mesh
    ``engine.build`` makes of it (``engine.model.meshes.shape_mesh``)."""
    from pydantic import TypeAdapter

    from engine.model import meshes
    from engine.model import spec_bodies

    return meshes.shape_mesh(TypeAdapter(spec_bodies.Shape).validate_python(shape))


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
    """The initial overlaps of a design (``engine.assembly.overlap.find_overlaps`` on the rest
    geometry the view draws): the same check ``engine.build`` makes, named the same way
    ("bristle 12" of brush 'brush', counted row by row within its brush)."""
    from engine.assembly import overlap

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
        nb = _n_bristles(br)
        n = int(_brush_field(br, "n_nodes"))
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
    shapes = [overlap.BodyShape(b.name, b.vertices @ layout.quat_to_matrix(b.wxyz).T + b.position,
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
    counts = [np.full(_n_bristles(b), int(_brush_field(b, "n_nodes")))
              for b in scene.get("brushes") or []]
    counts = np.concatenate(counts) if counts else np.zeros(0, np.int64)
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
