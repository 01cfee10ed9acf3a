"""Rigid-body geometry: a :class:`engine.model.spec_bodies.Body`'s shape turned into the arrays the
engine uses.

``body_geometry`` builds the shape's triangle mesh with trimesh (primitives or a file), takes the
mass, centre of mass and inertia from the closed mesh and a density or as given, moves the
vertices into the BODY frame (origin at the centre of mass, axes = the shape's own axes) and
builds a uniform grid over the triangles for the contact search.

Frames: ``Body.pose`` places the shape's own frame in the world; the body frame is that frame
shifted to the centre of mass, so a point ``p_shape`` of the shape is ``p_shape - com_in_shape``
in the body frame and the shape's origin sits at ``-com_in_shape`` (the exact sphere's centre).
"""
from __future__ import annotations

import math
import os
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Union

import numpy as np

from engine.model import spec_bodies
from engine.errors import SceneError

if TYPE_CHECKING:
    import trimesh

MAX_TRIANGLES = 200_000
MAX_GRID_CELLS = 64 ** 3
_MAX_GRID_ENTRIES = 4_000_000       # (triangle, cell) pairs: bounds the grid's memory
_DEGENERATE_RATIO = 1e-10           # 2*area <= ratio * longest_edge^2: (near) zero area
_INERTIA_RTOL = 1e-9                # slack of the principal-moment triangle inequality


@dataclass
class BodyGeometry:
    vertices: np.ndarray      # (V,3) float64, body frame (origin at the COM, shape's own axes)
    triangles: np.ndarray     # (T,3) int64, outward winding where the mesh allows
    mass: float               # kg; 0.0 = no mass properties (fixed/kinematic: infinite/driven)
    inertia: np.ndarray       # (3,3) kg m^2 about the COM, body frame; zeros when mass is 0
    com_in_shape: np.ndarray  # (3,) centre of mass in the shape's own frame
    bounding_radius: float    # max distance of the body's surface from the COM
    sphere_radius: float      # >0 only for SphereShape: contacts then use the exact sphere
    watertight: bool
    n_degenerate: int         # triangles of (near) zero area, kept but reported
    grid_origin: np.ndarray   # (3,) lower corner of the triangle grid, body frame
    grid_cell: float          # cell edge length, m
    grid_dims: np.ndarray     # (3,) int64 cell counts
    grid_start: np.ndarray    # (ncells+1,) int64 CSR offsets; cell id = (i*dims[1] + j)*dims[2] + k
    grid_tris: np.ndarray     # (M,) int64 triangle ids of each cell (every cell its AABB overlaps)

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    @property
    def shape_origin(self) -> np.ndarray:
        """The shape frame's origin in the body frame (the exact sphere's centre)."""
        return -self.com_in_shape


# --------------------------------------------------------------------------- shapes
def _wedge_mesh(shape: spec_bodies.WedgeShape) -> trimesh.Trimesh:
    """Triangular prism: apex edge on local x (z = 0), cross-section in y-z the triangle
    (0, 0), (-h tan(a/2), h), (h tan(a/2), h), from x = -length/2 to length/2."""
    h, half = shape.height, 0.5 * shape.length
    w = h * math.tan(0.5 * shape.angle)
    section = np.array([[0.0, 0.0], [-w, h], [w, h]])
    import trimesh
    vertices = np.array([[x, y, z] for x in (-half, half) for y, z in section])
    # outward winding (checked by the volume sign in the tests): end caps at -x (0,1,2) and
    # +x (3,5,4), then the three side quads split in two
    faces = np.array([[0, 1, 2], [3, 5, 4],
                      [0, 3, 4], [0, 4, 1],      # face towards -y
                      [0, 2, 5], [0, 5, 3],      # face towards +y
                      [1, 4, 5], [1, 5, 2]])     # flat top at z = h
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    if mesh.volume < 0:  # guard against a winding slip above: never ship an inverted wedge
        mesh.invert()
    return mesh


def shape_mesh(shape, field: str = "shape") -> trimesh.Trimesh:
    """The shape as a triangle mesh in its own frame (also used for display)."""
    import trimesh
    if isinstance(shape, spec_bodies.BoxShape):
        return trimesh.creation.box(extents=shape.size)
    if isinstance(shape, spec_bodies.SphereShape):
        return trimesh.creation.icosphere(subdivisions=shape.subdivisions, radius=shape.radius)
    if isinstance(shape, spec_bodies.CylinderShape):
        return trimesh.creation.cylinder(radius=shape.radius, height=shape.height,
                                         sections=shape.sections)
    if isinstance(shape, spec_bodies.WedgeShape):
        return _wedge_mesh(shape)
    if isinstance(shape, spec_bodies.MeshFileShape):
        return load_mesh_file(shape.file, shape.scale, field=f"{field}.file")
    raise SceneError.single(field, type(shape).__name__,
                            "must be a box, sphere, cylinder, wedge or mesh shape")


def load_mesh_file(path: Union[str, Path], scale: float = 1.0,
                   field: str = "shape.file") -> trimesh.Trimesh:
    """Read an STL/OBJ/PLY triangle mesh, times ``scale``. Duplicate vertices are merged;
    degenerate and open meshes are kept (contacts work on any triangle soup)."""
    import trimesh
    path = Path(path)
    if not path.is_file():
        raise SceneError.single(field, str(path), "must name an existing mesh file "
                                "(STL, OBJ or PLY)")
    from engine.model.mesh_limits import mesh_bytes_problem

    fmt = path.suffix.lower().lstrip(".")
    if fmt in ("stl", "obj", "ply"):  # counts read from the bytes before trimesh parses
        problem = mesh_bytes_problem(path.read_bytes(), fmt, MAX_TRIANGLES)
        if problem:
            raise SceneError.single(field, str(path), problem)
    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds on garbage input
        raise SceneError.single(field, str(path), f"cannot be read as a triangle mesh "
                                f"(STL, OBJ or PLY): {type(exc).__name__}: {exc}") from None
    if not isinstance(loaded, trimesh.Trimesh):
        raise SceneError.single(field, str(path), "holds no triangle mesh")
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64)
    if faces.ndim != 2 or faces.shape[0] == 0 or vertices.shape[0] == 0:
        raise SceneError.single(field, str(path), "holds no triangles (empty or unreadable "
                                "mesh file)")
    if faces.shape[0] > MAX_TRIANGLES:
        raise SceneError.single(field, str(path), f"has {faces.shape[0]} triangles; at most "
                                f"{MAX_TRIANGLES} are allowed (decimate the mesh)")
    if not np.isfinite(vertices).all():
        bad = int((~np.isfinite(vertices).all(axis=1)).sum())
        raise SceneError.single(field, str(path), f"has {bad} vertices with NaN or infinite "
                                "coordinates")
    if faces.min() < 0 or faces.max() >= vertices.shape[0]:
        raise SceneError.single(field, str(path), "has triangles referring to missing vertices")
    mesh = trimesh.Trimesh(vertices * float(scale), faces, process=True)
    _orient_outwards(mesh)
    return mesh


def _orient_outwards(mesh: trimesh.Trimesh) -> None:
    """Make the winding consistent and outward where the mesh allows (trimesh's repair)."""
    import trimesh
    if not mesh.is_winding_consistent:
        trimesh.repair.fix_winding(mesh)
    if mesh.is_watertight and mesh.volume < 0:
        mesh.invert()


# --------------------------------------------------------------------------- mass
def _check_inertia(inertia: np.ndarray, field: str) -> None:
    moments = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))  # ascending
    scale = max(abs(moments[-1]), 1e-300)
    if not np.all(np.isfinite(moments)) or moments[0] <= 0.0:
        raise SceneError.single(field, inertia.tolist(),
                                f"must be positive definite (principal moments "
                                f"{moments.tolist()})")
    if moments[0] + moments[1] < moments[2] - _INERTIA_RTOL * scale:
        raise SceneError.single(field, inertia.tolist(),
                                f"principal moments {moments.tolist()} break the triangle "
                                "inequality I1 + I2 >= I3 that every real body satisfies")


def _mass_properties(body: spec_bodies.Body, mesh: trimesh.Trimesh, field: str):
    """(mass, inertia about the COM in shape axes, com in shape frame)."""
    mp = body.mass_properties
    if mp is None:  # fixed / kinematic(hold): infinite or driven, the engine never divides
        return 0.0, np.zeros((3, 3)), np.zeros(3)
    if mp.density is not None and isinstance(body.shape, spec_bodies.SphereShape):
        # the exact sphere, as its contacts use (the icosphere is for display only: at the
        # default 3 subdivisions it is 0.9 % light with 1.4 % less inertia)
        r = float(body.shape.radius)
        mass = float(mp.density) * 4.0 / 3.0 * math.pi * r ** 3
        inertia = 0.4 * mass * r * r * np.eye(3)
        com = np.zeros(3)
        if mp.center_of_mass is not None:
            d = np.asarray(mp.center_of_mass, dtype=np.float64)
            inertia = inertia + mass * (d @ d * np.eye(3) - np.outer(d, d))
            com = d
        return mass, inertia, com
    if mp.density is not None:
        if not mesh.is_watertight:
            n_open = _n_open_edges(mesh)
            raise SceneError.single(
                f"{field}.mass_properties.density", mp.density,
                f"the mesh is not watertight ({n_open} open edges); give mass and inertia "
                "instead")
        mesh.density = float(mp.density)
        props = mesh.mass_properties
        if not props.volume > 0.0:
            raise SceneError.single(
                f"{field}.mass_properties.density", mp.density,
                f"the closed mesh has no positive volume ({float(props.volume):.6g} m^3); "
                "give mass and inertia instead")
        mass = float(props.mass)
        inertia = np.array(props.inertia, dtype=np.float64)
        if isinstance(body.shape, (spec_bodies.BoxShape, spec_bodies.SphereShape,
                                   spec_bodies.CylinderShape)):
            com = np.zeros(3)  # centred primitives: the COM is the origin by symmetry
        else:
            com = np.array(props.center_mass, dtype=np.float64)
        if mp.center_of_mass is not None:
            # ballasted body: the uniform body's inertia taken about the given point
            d = np.asarray(mp.center_of_mass, dtype=np.float64) - com
            inertia = inertia + mass * (d @ d * np.eye(3) - np.outer(d, d))
            com = np.asarray(mp.center_of_mass, dtype=np.float64)
        return mass, inertia, com
    inertia = np.array(mp.inertia, dtype=np.float64)
    _check_inertia(inertia, f"{field}.mass_properties.inertia")
    com = (np.zeros(3) if mp.center_of_mass is None
           else np.asarray(mp.center_of_mass, dtype=np.float64))
    return float(mp.mass), inertia, com


def _n_open_edges(mesh: trimesh.Trimesh) -> int:
    """Edges not shared by exactly two triangles."""
    edges = np.sort(mesh.edges, axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int((counts != 2).sum())


def _n_degenerate(vertices: np.ndarray, triangles: np.ndarray) -> int:
    tv = vertices[triangles]
    e0, e1, e2 = tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 1], tv[:, 0] - tv[:, 2]
    twice_area = np.linalg.norm(np.cross(e0, -e2), axis=1)
    longest2 = np.maximum(np.maximum((e0 * e0).sum(1), (e1 * e1).sum(1)), (e2 * e2).sum(1))
    return int((twice_area <= _DEGENERATE_RATIO * longest2).sum())


# --------------------------------------------------------------------------- body
def body_geometry(body: spec_bodies.Body, field: str = "bodies.?") -> BodyGeometry:
    """Geometry, mass properties and contact grid of one body. Raises SceneError naming
    ``{field}.shape.file`` / ``{field}.mass_properties.*`` on a bad mesh or mass.

    A body built before is read from the geometry cache (:func:`_cache_key`): trimesh, its
    import (about half a CPU-second, with scipy) and the mesh processing are then skipped."""
    key = _cache_key(body)
    geo = _cache_load(key)
    if geo is None:
        geo = _build_geometry(body, field)
        _cache_store(key, geo)
    return geo


def _build_geometry(body: spec_bodies.Body, field: str) -> BodyGeometry:
    mesh = shape_mesh(body.shape, field=f"{field}.shape")
    mass, inertia, com = _mass_properties(body, mesh, field)
    vertices = np.ascontiguousarray(np.asarray(mesh.vertices, dtype=np.float64) - com)
    triangles = np.ascontiguousarray(np.asarray(mesh.faces, dtype=np.int64))
    sphere_radius = (float(body.shape.radius)
                     if isinstance(body.shape, spec_bodies.SphereShape) else 0.0)
    bounding = float(np.sqrt((vertices * vertices).sum(axis=1)).max())
    if sphere_radius > 0.0:  # the exact sphere, centred at -com
        bounding = sphere_radius + float(np.linalg.norm(com))
    origin, cell, dims, start, tris = triangle_grid(vertices, triangles)
    return BodyGeometry(
        vertices=vertices, triangles=triangles, mass=mass,
        inertia=np.ascontiguousarray(inertia), com_in_shape=np.asarray(com, dtype=np.float64),
        bounding_radius=bounding, sphere_radius=sphere_radius,
        watertight=bool(mesh.is_watertight),
        n_degenerate=_n_degenerate(vertices, triangles),
        grid_origin=origin, grid_cell=cell, grid_dims=dims, grid_start=start, grid_tris=tris)


# --------------------------------------------------------------------------- cache
CACHE_ENTRIES = 64  # most recently used geometries kept; each is a few KB to a few MB
CACHE_ENV = "BRUSH_STUDIO_CACHE_DIR"


def geometry_cache_dir() -> Path:
    """Where built mesh geometries are cached: ``$BRUSH_STUDIO_CACHE_DIR/geometry`` if set,
    else the user's cache folder (``$XDG_CACHE_HOME``, default ``~/.cache``) under
    ``brush-studio/geometry``; never inside the package (read-only or shared when
    installed)."""
    own = os.environ.get(CACHE_ENV)
    if own:
        return Path(own).expanduser() / "geometry"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base).expanduser() / "brush-studio" / "geometry"


_CACHE_DIR = geometry_cache_dir()  # (read once, at import)


def _cache_key(body: spec_bodies.Body):
    """What a body's geometry depends on: its shape and mass properties as given, the mesh
    file's bytes, this module's source and limits, and trimesh's version. None when it
    cannot be told (an unreadable file: the full build then reports it). A geometry that
    failed to build is never stored, so its error is raised every time."""
    import hashlib
    from importlib import metadata
    digest = hashlib.sha256()
    try:
        digest.update(Path(__file__).read_bytes())
        digest.update(metadata.version("trimesh").encode())
        digest.update(repr((MAX_TRIANGLES, MAX_GRID_CELLS, _MAX_GRID_ENTRIES)).encode())
        digest.update(body.shape.model_dump_json().encode())
        mp = body.mass_properties
        digest.update(b"null" if mp is None else mp.model_dump_json().encode())
        if isinstance(body.shape, spec_bodies.MeshFileShape):
            digest.update(Path(body.shape.file).read_bytes())
    except (OSError, metadata.PackageNotFoundError):
        return None
    return digest.hexdigest()


def _cache_load(key):
    if key is None:
        return None
    path = _CACHE_DIR / f"{key}.npz"
    try:
        with np.load(path, allow_pickle=False) as z:
            fields = {name: z[name] for name in z.files}
        os.utime(path)  # most recently used
        scalars = {"mass": float, "bounding_radius": float, "sphere_radius": float,
                   "watertight": bool, "n_degenerate": int, "grid_cell": float}
        return BodyGeometry(**{name: (scalars[name](v) if name in scalars else v)
                               for name, v in fields.items()})
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile):
        return None  # absent, unreadable or from another layout: build it again


def _cache_store(key, geo: BodyGeometry) -> None:
    if key is None:
        return
    try:
        _CACHE_DIR.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=_CACHE_DIR, suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **{name: np.asarray(getattr(geo, name))
                           for name in BodyGeometry.__dataclass_fields__})
        os.replace(tmp, _CACHE_DIR / f"{key}.npz")  # atomic: readers never see half a file
        entries = sorted(_CACHE_DIR.glob("*.npz"), key=lambda p: p.stat().st_mtime)
        for old in entries[:-CACHE_ENTRIES]:
            old.unlink(missing_ok=True)
    except OSError:
        pass  # a read-only install: no cache, every build makes the mesh


# --------------------------------------------------------------------------- grid
def _grid_spans(lo, hi, origin, cell, dims):
    i0 = np.clip(np.floor((lo - origin) / cell).astype(np.int64), 0, dims - 1)
    i1 = np.clip(np.floor((hi - origin) / cell).astype(np.int64), 0, dims - 1)
    return i0, i1 - i0 + 1


def _grid_dims(extent: np.ndarray, cell: float) -> np.ndarray:
    return np.floor(extent / cell).astype(np.int64) + 1


def triangle_grid(vertices, triangles, target_per_cell: int = 8):
    """Uniform grid over the triangles' bounding boxes.

    Returns ``(origin, cell, dims, start, tris)``: the grid's lower corner, cell edge, cell
    counts (int64 (3,)), CSR offsets (ncells+1,) and the triangle ids of each cell, where cell
    id = (i*dims[1] + j)*dims[2] + k and a triangle is listed in every cell its AABB overlaps.
    A point p lies in cell floor((p - origin) / cell), clipped to [0, dims-1]. The cell is
    chosen for about ``target_per_cell`` triangles per non-empty cell, with at most
    ``MAX_GRID_CELLS`` cells.
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if t.shape[0] == 0:
        return (np.zeros(3), 1.0, np.ones(3, dtype=np.int64), np.zeros(2, dtype=np.int64),
                np.zeros(0, dtype=np.int64))
    tv = v[t]
    tlo, thi = tv.min(axis=1), tv.max(axis=1)
    origin = tlo.min(axis=0)
    extent = thi.max(axis=0) - origin
    size = float(extent.max())
    if size <= 0.0:  # every triangle collapsed onto one point
        size = 1.0
    n_tri = t.shape[0]

    # smallest cell allowed by the cell budget (bisection on log cell: counts fall with cell)
    lo_c, hi_c = size * 1e-6, size * 1.000001
    if np.prod(_grid_dims(extent, lo_c).astype(np.float64)) > MAX_GRID_CELLS:
        for _ in range(60):
            mid = math.sqrt(lo_c * hi_c)
            if np.prod(_grid_dims(extent, mid).astype(np.float64)) > MAX_GRID_CELLS:
                lo_c = mid
            else:
                hi_c = mid
        min_cell = hi_c
    else:
        min_cell = lo_c
    max_cell = size * 1.000001  # one cell (or two along the longest axis) holds everything

    def entries(cell):
        dims = _grid_dims(extent, cell)
        _, span = _grid_spans(tlo, thi, origin, cell, dims)
        return dims, span, span.prod(axis=1)

    # first guess: a cell of the triangles' mean size, grown to hold ~target surface patches
    mean_size = float(np.mean(thi - tlo)) * 1.5 + 1e-12 * size
    cell = min(max(mean_size * math.sqrt(target_per_cell) / 2.0, min_cell), max_cell)
    best = None
    for _ in range(6):
        while True:  # big triangles in small cells: grow the cell until the list fits
            dims, span, counts = entries(cell)
            total = int(counts.sum())
            if total <= _MAX_GRID_ENTRIES or cell >= max_cell:
                break
            cell = min(cell * 2.0, max_cell)
        i0, _ = _grid_spans(tlo, thi, origin, cell, dims)
        cell_ids = _expand(i0, span, counts, dims)
        occupied = np.count_nonzero(np.bincount(cell_ids, minlength=int(dims.prod())))
        per_cell = total / max(occupied, 1)
        err = abs(math.log(per_cell / target_per_cell))
        if best is None or err < best[0]:
            best = (err, cell, dims, counts, cell_ids)
        if err < math.log(1.5):
            break
        # triangles per occupied cell grow about like cell^2 on a surface
        factor = min(max(math.sqrt(target_per_cell / per_cell), 0.25), 4.0)
        new_cell = min(max(cell * factor, min_cell), max_cell)
        if abs(new_cell - cell) <= 1e-12 * cell:
            break
        cell = new_cell
    _, cell, dims, counts, cell_ids = best
    tri_ids = np.repeat(np.arange(n_tri, dtype=np.int64), counts)
    order = np.argsort(cell_ids, kind="stable")
    ncells = int(dims.prod())
    start = np.zeros(ncells + 1, dtype=np.int64)
    np.cumsum(np.bincount(cell_ids, minlength=ncells), out=start[1:])
    return (origin.astype(np.float64), float(cell), dims.astype(np.int64), start,
            np.ascontiguousarray(tri_ids[order]))


def _expand(i0, span, counts, dims):
    """Cell id of every (triangle, cell) pair, triangles in order, cells of each AABB."""
    total = int(counts.sum())
    offsets = np.cumsum(counts) - counts
    local = np.arange(total, dtype=np.int64) - np.repeat(offsets, counts)
    sy = np.repeat(span[:, 1], counts)
    sz = np.repeat(span[:, 2], counts)
    plane = sy * sz
    di = local // plane
    rem = local - di * plane
    dj = rem // sz
    dk = rem - dj * sz
    ci = np.repeat(i0[:, 0], counts) + di
    cj = np.repeat(i0[:, 1], counts) + dj
    ck = np.repeat(i0[:, 2], counts) + dk
    return (ci * dims[1] + cj) * dims[2] + ck


def _sound_faces(corners: np.ndarray) -> np.ndarray:
    """Per triangle (corners (T, 3, 3)), whether it is no sliver: |ab x ac|^2 above 1e-12 of
    its longest edge^4, a far wider margin than the contact geometry's own degenerate test.
    Only sound faces get edge normals (:func:`edge_normals`) or support the mesh
    (:func:`supporting_faces`)."""
    p = corners
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    longest = np.max(np.sum((p - np.roll(p, 1, axis=1)) ** 2, axis=2), axis=1)
    return np.sum(n * n, axis=1) > 1e-12 * longest * longest


def edge_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit normals of each triangle's edges ab, bc, ca in the triangle's plane, pointing
    away from the opposite vertex, shape (T, 3, 3). The triangle lies in each half-space
    (y - e0) . m <= 0 (e0 the edge's first vertex), so a point farther than r beyond one of
    them is farther than r from the triangle: the contact search's cheap rejection
    (``engine.kernels.body_contacts.closest_triangle``). Degenerate faces get zeros (never
    rejected)."""
    v = np.asarray(vertices, float)
    t = np.asarray(triangles, np.int64)
    out = np.zeros((len(t), 3, 3))
    if len(t) == 0:
        return out
    p = v[t]                                   # (T, 3 corners, 3)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    # slivers: rounding could tilt their edge normals, so they are never rejected this way
    sound = _sound_faces(p)
    for e in range(3):
        a, b, c = p[:, e], p[:, (e + 1) % 3], p[:, (e + 2) % 3]
        m = np.cross(b - a, n)
        m *= np.where(np.sum(m * (c - a), axis=1) > 0.0, -1.0, 1.0)[:, None]
        lm = np.linalg.norm(m, axis=1)
        good = sound & (lm > 0.0)
        out[good, e] = m[good] / lm[good, None]
    return out


# a vertex this far in front of a face's plane (a fraction of the mesh's extent) still counts
# as on it: coplanar faces (a box's two triangles a side) round to either side by ~1e-16
SUPPORT_TOLERANCE = 1e-9
# (triangles x hull vertices) a chunk of the support test holds at once
_SUPPORT_CHUNK = 4_000_000


def supporting_faces(vertices: np.ndarray, triangles: np.ndarray,
                     normals: np.ndarray) -> np.ndarray:
    """Per triangle, whether its plane supports the mesh: no vertex lies in front of it (along
    ``normals``, the unit face normals) by more than ``SUPPORT_TOLERANCE`` of the mesh's
    extent. Every face of a convex body does; a concave mesh's faces on its convex hull do.
    A point in front of such a face whose projection falls inside it has that projection as
    its closest point of the whole mesh (``engine.kernels.body_contacts.supported_face``).
    Slivers and degenerate faces (as in :func:`edge_normals`) never do. Only the convex
    hull's vertices need testing (the farthest vertex in front of a plane is one of them), so
    a mesh whose triangles x vertices fit one chunk of the test has all its vertices tested
    and no hull built (scipy.spatial's import alone costs a small study a sixth of a CPU
    second); a larger one has its hull's, or all of them where the hull cannot be built (a
    flat mesh)."""
    v = np.asarray(vertices, float)
    t = np.asarray(triangles, np.int64)
    n = np.asarray(normals, float)
    out = np.zeros(len(t), bool)
    if len(t) == 0:
        return out
    cand = v
    if len(t) * len(v) > _SUPPORT_CHUNK:
        from scipy.spatial import ConvexHull, QhullError
        try:
            cand = v[ConvexHull(v).vertices]
        except (QhullError, ValueError):
            pass
    p = v[t]
    sound = _sound_faces(p) & (np.abs(np.sum(n * n, axis=1) - 1.0) < 1e-6)
    tol = SUPPORT_TOLERANCE * max(float(np.ptp(v, axis=0).max()), 1e-300)
    offset = np.sum(n * p[:, 0], axis=1)
    step = max(1, _SUPPORT_CHUNK // max(len(cand), 1))
    for a in range(0, len(t), step):
        b = min(len(t), a + step)
        ahead = (cand @ n[a:b].T - offset[a:b]).max(axis=0)
        out[a:b] = ahead <= tol
    return out & sound


def pseudo_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Angle-weighted pseudo-normals (Baerentzen & Aanaes 2005) per triangle, shape (T, 7, 3):
    row 0 the face normal, rows 1-3 the normals of edges ab, bc, ca (the normalised sum of the
    normals of the faces sharing the edge), rows 4-6 those of vertices a, b, c (the sum of the
    incident faces' normals weighted by their angle at the vertex). With them, the sign of
    (point - closest point) . normal tells inside from outside for any closest feature of a
    closed mesh. Degenerate faces contribute nothing."""
    v = np.asarray(vertices, float)
    t = np.asarray(triangles, np.int64)
    T = len(t)
    out = np.zeros((T, 7, 3))
    if T == 0:
        return out
    p = v[t]                                   # (T, 3 corners, 3)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    ln = np.linalg.norm(n, axis=1)
    good = ln > 1e-300
    n[good] /= ln[good, None]
    n[~good] = 0.0
    out[:, 0] = n

    def unit(a):
        la = np.linalg.norm(a, axis=-1, keepdims=True)
        return np.where(la > 1e-300, a / np.where(la > 1e-300, la, 1.0), 0.0)

    # edges: (a,b), (b,c), (c,a), keyed by the sorted vertex pair
    ends = np.stack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=1).reshape(-1, 2)
    key = np.sort(ends, axis=1)
    _, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    sums = np.zeros((inverse.max() + 1, 3))
    np.add.at(sums, inverse, np.repeat(n, 3, axis=0))
    out[:, 1:4] = unit(sums[inverse]).reshape(T, 3, 3)
    # vertices: angle-weighted
    vsum = np.zeros((len(v), 3))
    for c in range(3):
        e1 = unit(p[:, (c + 1) % 3] - p[:, c])
        e2 = unit(p[:, (c + 2) % 3] - p[:, c])
        ang = np.arccos(np.clip(np.sum(e1 * e2, axis=1), -1.0, 1.0))
        np.add.at(vsum, t[:, c], n * ang[:, None])
    out[:, 4:7] = unit(vsum[t])
    return out
