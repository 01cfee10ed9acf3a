"""Initial overlap: elements that start inside one another, found before any step is taken.

A scene whose body starts inside the brush (a box lowered too far, an uploaded mesh larger than
the gap, bristles lengthened under a wedge), whose bristles cross, or whose bodies
interpenetrate, would run a few hundred steps of meaningless contact forces and then stop with
an instability that points at the timestep. ``find_overlaps`` names such starts instead: which
body, which bristles, how deep. ``engine.build`` warns about each (``System.warnings``, which
``validate`` prints); the studio calls the same function on its design view and refuses to
start a design whose body starts inside the brush or inside another body.

Pure numpy (no numba, no trimesh): the studio imports it for every edit.

Geometry, as the contact kernels see it: a bristle is a chain of capsule segments whose
radius varies linearly from node to node; a body is its triangle mesh (closed meshes have an
inside, found with the generalised winding number; open ones only a surface). The reported
depth is how far the capsule surface reaches past the body surface (``r - signed distance``
at the deepest sample point), or, for two bristles, ``r_a + r_b - distance`` of the two
segments' axes. Depths below ``tolerance`` (default 1 % of the smallest radius involved)
are contact, not overlap: touching bristles at a pitch of exactly two radii are fine.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

TOLERANCE_RATIO = 0.01     # overlap below this fraction of the radius is touching, not overlap
MAX_CHECKED_SEGMENTS = 200_000  # above this, bristle-bristle pairs are not searched (too slow)
_CHUNK = 200_000            # point x triangle pairs evaluated at once (~ 20 temporaries of
                            # (pairs, 3) float64 alive: ~ 100 MB peak whatever the scene)


@dataclass
class BodyShape:
    """A body for the check: world-frame triangle mesh (SI) and whether it takes contacts."""

    name: str
    vertices: np.ndarray      # (V, 3) world
    triangles: np.ndarray     # (T, 3) int
    closed: bool = True       # watertight: it has an inside
    collide: bool = True


@dataclass
class Overlap:
    """One overlapping pair of things: ``kind`` is "body-bristle", "bristle-bristle" or
    "body-body"; ``first``/``second`` name them; ``depth`` (m) is the deepest overlap;
    ``items`` lists every overlapping bristle (or bristle pair) as text."""

    kind: str
    first: str
    second: str
    depth: float
    items: list[str] = field(default_factory=list)
    body: Optional[str] = None   # the body involved (body-bristle, body-body), for the UI
    bristles: list[int] = field(default_factory=list)  # global indices of those bristles

    def __str__(self) -> str:
        shown = ", ".join(self.items[:6]) + (f" and {len(self.items) - 6} more"
                                             if len(self.items) > 6 else "")
        what = {"body-bristle": f"{self.first} starts inside {len(self.items)} bristle"
                                f"{'s' if len(self.items) != 1 else ''} of {self.second}",
                "bristle-bristle": f"{len(self.items)} pair{'s' if len(self.items) != 1 else ''}"
                                   f" of bristles of {self.first}"
                                   + (f" and {self.second}" if self.second != "itself" else "")
                                   + " start crossed",
                "body-body": f"{self.first} and {self.second} start interpenetrating"}[self.kind]
        return (f"initial overlap: {what}, up to {self.depth * 1e3:.3g} mm deep"
                + (f" ({shown})" if shown else ""))


# --------------------------------------------------------------------------- geometry
def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray,
                                c: np.ndarray) -> np.ndarray:
    """Closest point of each triangle (a, b, c) to each point p (all broadcast to (..., 3)),
    by Voronoi regions (Ericson, Real-Time Collision Detection, 5.1.5)."""
    ab, ac, ap = b - a, c - a, p - a
    d1 = np.einsum("...i,...i", ab, ap)
    d2 = np.einsum("...i,...i", ac, ap)
    bp = p - b
    d3 = np.einsum("...i,...i", ab, bp)
    d4 = np.einsum("...i,...i", ac, bp)
    cp = p - c
    d5 = np.einsum("...i,...i", ab, cp)
    d6 = np.einsum("...i,...i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = np.where(denom != 0, vb / denom, 0.0)
        w = np.where(denom != 0, vc / denom, 0.0)
        out = a + ab * v[..., None] + ac * w[..., None]           # inside the face
        # edges
        t_ab = np.where(d1 - d3 != 0, d1 / (d1 - d3), 0.0)
        e_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        t_ac = np.where(d2 - d6 != 0, d2 / (d2 - d6), 0.0)
        e_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        t_bc = np.where((d4 - d3) + (d5 - d6) != 0, (d4 - d3) / ((d4 - d3) + (d5 - d6)), 0.0)
        e_bc = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    out = np.where(e_bc[..., None], b + (c - b) * t_bc[..., None], out)
    out = np.where(e_ac[..., None], a + ac * t_ac[..., None], out)
    out = np.where(e_ab[..., None], a + ab * t_ab[..., None], out)
    # vertices
    out = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, out)
    return out


def signed_distances(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray,
                     closed: bool = True) -> np.ndarray:
    """Distance of each point to the mesh surface, negative inside a closed mesh (inside:
    generalised winding number above one half, Jacobson et al. 2013)."""
    points = np.asarray(points, float).reshape(-1, 3)
    out = np.full(len(points), np.inf)
    if len(points) == 0 or len(triangles) == 0:
        return out
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    step = max(1, _CHUNK // len(triangles))
    for s in range(0, len(points), step):
        p = points[s:s + step, None, :]
        q = closest_points_on_triangles(p, a[None], b[None], c[None])
        d = np.sqrt(((q - p) ** 2).sum(-1)).min(axis=1)
        if closed:
            # solid angle of each triangle seen from p (van Oosterom and Strackee 1983)
            ra, rb, rc = a[None] - p, b[None] - p, c[None] - p
            la, lb, lc = (np.linalg.norm(r, axis=-1) for r in (ra, rb, rc))
            num = np.einsum("...i,...i", ra, np.cross(rb, rc))
            den = (la * lb * lc + np.einsum("...i,...i", ra, rb) * lc
                   + np.einsum("...i,...i", rb, rc) * la + np.einsum("...i,...i", rc, ra) * lb)
            winding = (2.0 * np.arctan2(num, den)).sum(axis=1) / (4.0 * math.pi)
            d = np.where(np.abs(winding) > 0.5, -d, d)
        out[s:s + step] = d
    return out


def segment_distances(p1, q1, p2, q2):
    """Closest distance between segments p1-q1 and p2-q2 (arrays (n, 3)), and the parameters
    s, t in [0, 1] of the closest points (Ericson 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(denom > 1e-30 * a * e, np.clip((b * f - c * e) / denom, 0, 1), 0.0)
        t = np.where(e > 0, (b * s + f) / e, 0.0)
        s = np.where(t < 0, np.where(a > 0, np.clip(-c / a, 0, 1), 0.0), s)
        s = np.where(t > 1, np.where(a > 0, np.clip((b - c) / a, 0, 1), 0.0), s)
    t = np.clip(t, 0, 1)
    gap = (p1 + d1 * s[:, None]) - (p2 + d2 * t[:, None])
    return np.sqrt(np.einsum("ij,ij->i", gap, gap)), s, t


# --------------------------------------------------------------------------- the check
def find_overlaps(positions: np.ndarray, radius: np.ndarray, bonds: np.ndarray,
                  node_bristle: np.ndarray, bristle_names: Sequence[str],
                  bristle_brush: np.ndarray, brush_names: Sequence[str],
                  bodies: Sequence[BodyShape] = (),
                  bristle_mount: Optional[np.ndarray] = None,
                  tolerance: Optional[float] = None) -> list[Overlap]:
    """Every initial overlap of a scene at rest. ``positions`` (N, 3) and ``radius`` (N,):
    bristle nodes (SI); ``bonds`` (S, 2): the segments; ``node_bristle``: the bristle of each
    node; ``bristle_names``: how to call each bristle ("bristle 12"); ``bristle_brush``: its
    brush index into ``brush_names``; ``bristle_mount``: per bristle the index of the body its
    brush is mounted on (-1: none; a bristle's roots touch its own mount, which is not an
    overlap). Returns one :class:`Overlap` per (body, brush), (brush, brush) and (body, body)
    that overlap, deepest first."""
    positions = np.asarray(positions, float).reshape(-1, 3)
    radius = np.asarray(radius, float)
    bonds = np.asarray(bonds, np.int64).reshape(-1, 2)
    node_bristle = np.asarray(node_bristle, np.int64)
    bristle_brush = np.asarray(bristle_brush, np.int64)
    if bristle_mount is None:
        bristle_mount = np.full(len(bristle_brush), -1, np.int64)
    r_min = float(radius.min()) if radius.size else 1e-3
    tol = TOLERANCE_RATIO * r_min if tolerance is None else float(tolerance)
    out: list[Overlap] = []
    out += _body_bristle(positions, radius, bonds, node_bristle, bristle_names, bristle_brush,
                         brush_names, bodies, bristle_mount, tol)
    out += _bristle_bristle(positions, radius, bonds, node_bristle, bristle_names,
                            bristle_brush, brush_names, tol)
    out += _body_body(bodies, tol)
    out.sort(key=lambda o: -o.depth)
    return out


def _segment_samples(positions, radius, bonds):
    """Points along every segment (nodes, and enough points between them that no gap is
    larger than the local radius), with the radius there and the segment index."""
    p0, p1 = positions[bonds[:, 0]], positions[bonds[:, 1]]
    r0, r1 = radius[bonds[:, 0]], radius[bonds[:, 1]]
    length = np.linalg.norm(p1 - p0, axis=1)
    n = np.clip(np.ceil(length / np.maximum(np.minimum(r0, r1), 1e-12)), 1, 16).astype(int)
    seg = np.repeat(np.arange(len(bonds)), n + 1)
    # k / n for k = 0..n of each segment, without a Python loop over the segments
    start = np.cumsum(n + 1) - (n + 1)
    k = np.arange(len(seg)) - np.repeat(start, n + 1)
    frac = k / n[seg] if len(seg) else np.zeros(0)
    pts = p0[seg] + (p1 - p0)[seg] * frac[:, None]
    rad = r0[seg] + (r1 - r0)[seg] * frac
    return pts, rad, seg


def _body_bristle(positions, radius, bonds, node_bristle, bristle_names, bristle_brush,
                  brush_names, bodies, bristle_mount, tol) -> list[Overlap]:
    out = []
    if not len(bonds) or not bodies:
        return out
    seg_bristle = node_bristle[bonds[:, 0]]
    pts, rad, seg = None, None, None
    for k, body in enumerate(bodies):
        if not body.collide or not len(body.triangles):
            continue
        v = np.asarray(body.vertices, float)
        lo, hi = v.min(0), v.max(0)
        if pts is None:
            pts, rad, seg = _segment_samples(positions, radius, bonds)
        # a point farther than its radius from the body's bounding box cannot reach its
        # surface: only the rest go to the (point x triangle) distances
        outside = np.maximum(np.maximum(lo - pts, pts - hi), 0.0)
        near = np.einsum("ij,ij->i", outside, outside) <= rad * rad
        near &= bristle_mount[seg_bristle[seg]] != k
        if not near.any():
            continue
        idx = np.flatnonzero(near)
        depth = rad[idx] - signed_distances(pts[idx], v, np.asarray(body.triangles, np.int64),
                                            body.closed)
        hit = depth > tol
        if not hit.any():
            continue
        bristles = seg_bristle[seg[idx[hit]]]
        deepest = np.zeros(len(bristle_brush))
        np.maximum.at(deepest, bristles, depth[hit])
        for brush in np.unique(bristle_brush[bristles]):
            mine = np.flatnonzero((deepest > 0) & (bristle_brush == brush))
            out.append(Overlap("body-bristle", f"body {body.name!r}",
                               f"brush {brush_names[brush]!r}", float(deepest[mine].max()),
                               [bristle_names[b] for b in mine], body=body.name,
                               bristles=[int(b) for b in mine]))
    return out


def _bristle_bristle(positions, radius, bonds, node_bristle, bristle_names, bristle_brush,
                     brush_names, tol) -> list[Overlap]:
    S = len(bonds)
    if S < 2 or S > MAX_CHECKED_SEGMENTS:
        return []
    p0, p1 = positions[bonds[:, 0]], positions[bonds[:, 1]]
    r0, r1 = radius[bonds[:, 0]], radius[bonds[:, 1]]
    mid = 0.5 * (p0 + p1)
    half = 0.5 * np.linalg.norm(p1 - p0, axis=1)
    r_max = np.maximum(r0, r1)
    reach = float((half + r_max).max()) * 2.0
    if S * S <= 4_000_000:
        i, j = np.triu_indices(S, 1)
        keep = np.linalg.norm(mid[i] - mid[j], axis=1) <= reach
        i, j = i[keep], j[keep]
    else:
        from scipy.spatial import cKDTree

        pairs = cKDTree(mid).query_pairs(reach, output_type="ndarray")
        i, j = pairs[:, 0], pairs[:, 1]
    bi, bj = node_bristle[bonds[i, 0]], node_bristle[bonds[j, 0]]
    # different bristles whose bounding spheres (mid, half length + radius) meet
    gap = mid[i] - mid[j]
    bound = half[i] + half[j] + r_max[i] + r_max[j]
    other = (bi != bj) & (np.einsum("ij,ij->i", gap, gap) <= bound * bound)
    del gap, bound
    i, j, bi, bj = i[other], j[other], bi[other], bj[other]
    if not len(i):
        return []
    hit = np.zeros(len(i), bool)
    depth = np.zeros(len(i))
    for s in range(0, len(i), _CHUNK):  # a bounded number of pairs at once
        c = slice(s, s + _CHUNK)
        ic, jc = i[c], j[c]
        d, sa, tb = segment_distances(p0[ic], p1[ic], p0[jc], p1[jc])
        depth[c] = (r0[ic] + (r1[ic] - r0[ic]) * sa) + (r0[jc] + (r1[jc] - r0[jc]) * tb) - d
    hit = depth > tol
    out = []
    if not hit.any():
        return out
    a, b = np.minimum(bi[hit], bj[hit]), np.maximum(bi[hit], bj[hit])
    dep = depth[hit]
    pairs: dict[tuple[int, int], dict[tuple[int, int], float]] = {}
    for x, y, z in zip(a, b, dep):
        key = tuple(sorted((int(bristle_brush[x]), int(bristle_brush[y]))))
        group = pairs.setdefault(key, {})
        group[(int(x), int(y))] = max(group.get((int(x), int(y)), 0.0), float(z))
    for (ba, bb), group in pairs.items():
        out.append(Overlap("bristle-bristle", f"brush {brush_names[ba]!r}",
                           f"brush {brush_names[bb]!r}" if bb != ba else "itself",
                           max(group.values()),
                           [f"{bristle_names[x]} and {bristle_names[y]}" for x, y in group],
                           bristles=sorted({b for xy in group for b in xy})))
    return out


def _body_body(bodies, tol) -> list[Overlap]:
    out = []
    live = [b for b in bodies if b.collide and len(b.triangles)]
    for m in range(len(live)):
        for n in range(m + 1, len(live)):
            A, B = live[m], live[n]
            va, vb = np.asarray(A.vertices, float), np.asarray(B.vertices, float)
            ca, cb = 0.5 * (va.min(0) + va.max(0)), 0.5 * (vb.min(0) + vb.max(0))
            ra = float(np.linalg.norm(va - ca, axis=1).max())
            rb = float(np.linalg.norm(vb - cb, axis=1).max())
            if np.linalg.norm(ca - cb) > ra + rb:
                continue
            depth = 0.0
            for P, Q in ((A, B), (B, A)):
                if not Q.closed:
                    continue
                pts = _surface_points(P)
                d = signed_distances(pts, np.asarray(Q.vertices, float),
                                     np.asarray(Q.triangles, np.int64), True)
                depth = max(depth, float(-d.min()) if d.size else 0.0)
            if depth > tol:
                out.append(Overlap("body-body", f"body {A.name!r}", f"body {B.name!r}",
                                   depth, [], body=A.name))
    return out


def _surface_points(body: BodyShape) -> np.ndarray:
    """Vertices, edge midpoints and face centres of a body's mesh (world)."""
    v = np.asarray(body.vertices, float)
    t = np.asarray(body.triangles, np.int64)
    tri = v[t]
    edges = 0.5 * (tri + np.roll(tri, 1, axis=1)).reshape(-1, 3)
    return np.concatenate([v, edges, tri.mean(axis=1)])


# --------------------------------------------------------------------------- build's use
def check_build(scene, x, radius, bonds, node_bristle, bristle_brush, brushes, body_vertices,
                body_triangles, body_closed, body_collide, warnings: list) -> list[Overlap]:
    """``engine.build``'s call: one warning per initial overlap, naming the body, the
    bristles and the depth. A warning, not an error: a start in contact is a legitimate
    engine input (the verification tests start a tip inside a plate to measure k_n, or a
    segment deep in a body to watch it pushed out), but in a design it is almost always a
    mistake, which is why the studio refuses to start such a design and ``validate`` prints
    the warning. ``brushes``: (name, first bristle, mount body index or -1) per brush."""
    bristle_brush = np.asarray(bristle_brush, np.int64)
    first = np.array([b[1] for b in brushes], np.int64)
    names = [f"bristle {int(i - first[bb])}" for i, bb in enumerate(bristle_brush)]
    mount = np.array([brushes[bb][2] for bb in bristle_brush], np.int64)
    bodies = [BodyShape(scene.bodies[k].name, np.asarray(body_vertices[k], float),
                        np.asarray(body_triangles[k], np.int64), bool(body_closed[k]),
                        bool(body_collide[k])) for k in range(len(scene.bodies))]
    found = find_overlaps(x, radius, bonds, node_bristle, names, bristle_brush,
                          [b[0] for b in brushes], bodies, bristle_mount=mount)
    index = {b.name: k for k, b in enumerate(scene.bodies)}
    for o in found:
        if o.kind == "bristle-bristle":
            warnings.append(f"{o}: the contact pushes them apart in the first steps; "
                            f"increase the pitch or reduce tip_variance")
        else:
            k = index[o.body]
            warnings.append(f"{o} (bodies.{k}.pose.position = "
                            f"{[float(c) for c in scene.bodies[k].pose.position]}): the first "
                            f"steps push them apart with forces no design meant; move the "
                            f"body (or the brush base) apart, or shorten the bristles")
    return found
