"""Contacts with rigid bodies: bristle capsules against body triangle meshes (closest points
in the body frame, triangles found through each body's uniform grid) or against exact
spheres, and sphere bodies against other bodies.

One contact per (segment, body) pair: the closest triangle wins, so a capsule touching a
shared edge or vertex is not counted twice, and the tangential history is kept per
(segment, body) across triangle changes. As for bristle-bristle contacts, a contact exactly at
the joint between two segments of one bristle is counted by the segment after the joint.
"""
from __future__ import annotations

import math


from numba import njit, prange

from .bodies import FIXED, KINEMATIC, push_body
from .bonds import PARALLEL_MIN_CANDIDATES
from .contact_law import (HISTORY_COLUMNS, adhesion, clear_history, contact_force,
                          contact_with_history, normal_stiffness, smoothstep)
from .contacts import add_segment_force, segment_point_velocity
from .jit import item_kernel
from .geometry import row3, segment_point_closest, segment_triangle_closest
from .rotations import qrot, qrot_inv


@njit(cache=True)
def build_body_candidates(mid, bound, seg_mount, pos, bound_r, collide, skin, out_s, out_b,
                          out_deep, x, rad, bi, bj, seg_rmax, q, sphere_r, watertight, verts,
                          tris, tnormal, tedge, pnormal, grid_origin, grid_cell, grid_dims,
                          grid_base, grid_start, grid_tris, grid_side, local, tsupport):
    """(segment, body) pairs whose capsule and body surface are closer than ``skin``, or
    whose segment lies inside a closed body (a sphere, or a watertight mesh: then it may be
    farther than the skin from every face), sorted by (segment, body); the bounding spheres
    prefilter. Segments of a brush mounted on a body never touch that body. Open meshes have
    no inside: surface distance only. ``local`` is (2, 3) scratch.

    ``out_deep`` gets, per candidate against a watertight mesh, bit 0 (the segment's start
    node) and bit 1 (its end node) set where that node may lie deeper inside the body than its
    radius before the next rebuild: it is inside now, or half the skin (the most a node and a
    body move relative to each other between rebuilds, ``neighbours.predicted_displacement``)
    reaches its radius. A node outside now is then at most half the skin inside, within its
    radius of a face, where the narrow phase finds it without the deep search.

    Before those searches, a supporting face in a node's grid cell (``tsupport``) that both
    ends lie farther in front of than the reach settles a segment as far and outside, and
    one a node lies in front of settles the node as outside (``_cell_face_in_front``): the
    same list, without the searches."""
    ns = mid.shape[0]
    nk = pos.shape[0]
    cap = out_s.shape[0]
    n = 0
    l0 = local[0]
    l1 = local[1]
    for s in range(ns):
        for k in range(nk):
            if not collide[k] or seg_mount[s] == k:
                continue
            dx = mid[s, 0] - pos[k, 0]
            dy = mid[s, 1] - pos[k, 1]
            dz = mid[s, 2] - pos[k, 2]
            lim = bound[s] + bound_r[k] + skin
            if dx * dx + dy * dy + dz * dz >= lim * lim:
                continue
            i0 = bi[s]
            i1 = bj[s]
            reach = seg_rmax[s] + skin
            if sphere_r[k] > 0.0:
                u = segment_point_closest(row3(x, i0), row3(x, i1), row3(pos, k))
                ex = x[i0, 0] + u * (x[i1, 0] - x[i0, 0]) - pos[k, 0]
                ey = x[i0, 1] + u * (x[i1, 1] - x[i0, 1]) - pos[k, 1]
                ez = x[i0, 2] + u * (x[i1, 2] - x[i0, 2]) - pos[k, 2]
                near = math.sqrt(ex * ex + ey * ey + ez * ez) < sphere_r[k] + reach
            else:
                qw, qx, qy, qz = q[k, 0], q[k, 1], q[k, 2], q[k, 3]
                l0[0], l0[1], l0[2] = qrot_inv(qw, qx, qy, qz, x[i0, 0] - pos[k, 0],
                                               x[i0, 1] - pos[k, 1], x[i0, 2] - pos[k, 2])
                l1[0], l1[1], l1[2] = qrot_inv(qw, qx, qy, qz, x[i1, 0] - pos[k, 0],
                                               x[i1, 1] - pos[k, 1], x[i1, 2] - pos[k, 2])
                if _cell_face_in_front(k, l1, l0, reach * (1.0 + 1e-9) + 1e-300, verts, tris,
                                       tnormal, tsupport, grid_origin, grid_cell, grid_dims,
                                       grid_base, grid_start, grid_tris):
                    continue  # farther than the reach from the whole mesh, and outside it
                tri, _s, _u, _v, _w, d = closest_triangle(k, l0, l1, reach, verts, tris, tnormal, tedge,
                                                          grid_origin, grid_cell, grid_dims,
                                                          grid_base, grid_start, grid_tris)
                near = tri >= 0 and d < reach
                if not near and watertight[k]:
                    # no face within reach: the segment does not cross the surface, so both
                    # ends are on the same side; one deep inside a closed body stays listed
                    near = deep_closest(k, l0, reach, verts, tris, tnormal, tedge, pnormal,
                                        grid_origin, grid_cell, grid_dims, grid_base,
                                        grid_start, grid_tris, grid_side)[0] >= 0
            if near:
                if n < cap:
                    out_s[n] = s
                    out_b[n] = k
                    flags = 0
                    if sphere_r[k] <= 0.0 and watertight[k]:
                        # a node in front of a supporting face is outside: no deep search
                        front = FRONT_MARGIN * grid_cell[k]
                        if 0.5 * skin >= rad[i0] or not _cell_face_in_front(
                                k, l0, l0, front, verts, tris, tnormal, tsupport, grid_origin,
                                grid_cell, grid_dims, grid_base, grid_start,
                                grid_tris) and deep_closest(
                                k, l0, rad[i0], verts, tris, tnormal, tedge, pnormal, grid_origin,
                                grid_cell, grid_dims, grid_base, grid_start, grid_tris,
                                grid_side)[0] >= 0:
                            flags |= 1
                        if 0.5 * skin >= rad[i1] or not _cell_face_in_front(
                                k, l1, l1, front, verts, tris, tnormal, tsupport, grid_origin,
                                grid_cell, grid_dims, grid_base, grid_start,
                                grid_tris) and deep_closest(
                                k, l1, rad[i1], verts, tris, tnormal, tedge, pnormal, grid_origin,
                                grid_cell, grid_dims, grid_base, grid_start, grid_tris,
                                grid_side)[0] >= 0:
                            flags |= 2
                    out_deep[n] = flags
                n += 1
    return n


@njit(cache=True, inline="always")
def _grid_cell_of(k, p, grid_origin, grid_cell, grid_dims, grid_base):
    """The index (in the concatenated grids) of body k's grid cell holding point p (body
    frame), or -1 where p is outside the grid's box."""
    lo = grid_origin[k]
    cell = grid_cell[k]
    for a in range(3):
        if p[a] < lo[a] or p[a] > lo[a] + grid_dims[k, a] * cell:
            return -1
    d1 = grid_dims[k, 1]
    d2 = grid_dims[k, 2]
    c0 = min(int(math.floor((p[0] - lo[0]) / cell)), grid_dims[k, 0] - 1)
    c1 = min(int(math.floor((p[1] - lo[1]) / cell)), d1 - 1)
    c2 = min(int(math.floor((p[2] - lo[2]) / cell)), d2 - 1)
    return grid_base[k] + (c0 * d1 + c1) * d2 + c2


@njit(cache=True, inline="always")
def _heights(tri, p, q, verts, tris, tnormal):
    """The heights of points p and q above triangle tri's plane, along its unit normal."""
    ia = tris[tri, 0]
    nx = tnormal[tri, 0]
    ny = tnormal[tri, 1]
    nz = tnormal[tri, 2]
    ax = verts[ia, 0]
    ay = verts[ia, 1]
    az = verts[ia, 2]
    return (nx * (p[0] - ax) + ny * (p[1] - ay) + nz * (p[2] - az),
            nx * (q[0] - ax) + ny * (q[1] - ay) + nz * (q[2] - az))


# how far (a fraction of the grid cell) a node must lie in front of a supporting face for
# the rebuild to take it as outside without the deep search: well above the rounding of the
# plane distance, far below any contact's scale
FRONT_MARGIN = 1e-9


@item_kernel
def _cell_face_in_front(k, p, q, lim, verts, tris, tnormal, tsupport, grid_origin, grid_cell,
                        grid_dims, grid_base, grid_start, grid_tris):
    """Whether a triangle of body k listed in the grid cell holding p (body frame; False if
    p is outside the grid's box) has a plane that supports the mesh (``tsupport``) with both
    p and q farther than ``lim`` in front of it. Then every point of the segment pq is
    farther than lim from the mesh, and outside it (the mesh lies behind that plane)."""
    cc = _grid_cell_of(k, p, grid_origin, grid_cell, grid_dims, grid_base)
    if cc < 0:
        return False
    for idx in range(grid_start[cc], grid_start[cc + 1]):
        tri = grid_tris[idx]
        if tsupport[tri] != k:
            continue
        hp, hq = _heights(tri, p, q, verts, tris, tnormal)
        if hp > lim and hq > lim:
            return True
    return False


@item_kernel
def closest_triangle(k, l0, l1, rmax, verts, tris, tnormal, tedge, grid_origin, grid_cell,
                     grid_dims, grid_base, grid_start, grid_tris):
    """Closest triangle of body k to the segment l0-l1 (body frame) among the grid cells its
    box (inflated by rmax) overlaps, ignoring triangles whose plane both ends of the segment
    are farther than rmax from (on the same side), or that both ends lie more than rmax
    beyond one edge of (``_beyond_an_edge``): they cannot be within rmax. Returns
    (tri, s, u, v, w, dist); tri = -1 if none."""
    lo = grid_origin[k]
    cell = grid_cell[k]
    # rejection beyond an edge only past this (ties at rmax are left to the exact test)
    lim = rmax * (1.0 + 1e-9) + 1e-300
    best = -1
    bs = 0.0
    bu = 0.0
    bv = 0.0
    bw = 0.0
    bd = 1e300
    c_lo0 = int(math.floor((min(l0[0], l1[0]) - rmax - lo[0]) / cell))
    c_lo1 = int(math.floor((min(l0[1], l1[1]) - rmax - lo[1]) / cell))
    c_lo2 = int(math.floor((min(l0[2], l1[2]) - rmax - lo[2]) / cell))
    c_hi0 = int(math.floor((max(l0[0], l1[0]) + rmax - lo[0]) / cell))
    c_hi1 = int(math.floor((max(l0[1], l1[1]) + rmax - lo[1]) / cell))
    c_hi2 = int(math.floor((max(l0[2], l1[2]) + rmax - lo[2]) / cell))
    d0 = grid_dims[k, 0]
    d1 = grid_dims[k, 1]
    d2 = grid_dims[k, 2]
    c_lo0 = max(c_lo0, 0)
    c_lo1 = max(c_lo1, 0)
    c_lo2 = max(c_lo2, 0)
    c_hi0 = min(c_hi0, d0 - 1)
    c_hi1 = min(c_hi1, d1 - 1)
    c_hi2 = min(c_hi2, d2 - 1)
    for e0 in range(c_lo0, c_hi0 + 1):
        for e1 in range(c_lo1, c_hi1 + 1):
            for e2 in range(c_lo2, c_hi2 + 1):
                cc = grid_base[k] + (e0 * d1 + e1) * d2 + e2
                for idx in range(grid_start[cc], grid_start[cc + 1]):
                    tri = grid_tris[idx]
                    a0 = verts[tris[tri, 0]]
                    nx = tnormal[tri, 0]
                    ny = tnormal[tri, 1]
                    nz = tnormal[tri, 2]
                    h0 = nx * (l0[0] - a0[0]) + ny * (l0[1] - a0[1]) + nz * (l0[2] - a0[2])
                    h1 = nx * (l1[0] - a0[0]) + ny * (l1[1] - a0[1]) + nz * (l1[2] - a0[2])
                    if (h0 > rmax and h1 > rmax) or (h0 < -rmax and h1 < -rmax):
                        continue
                    if _beyond_an_edge(tri, l0, l1, lim, verts, tris, tedge):
                        continue
                    s, u, v, w, d = segment_triangle_closest(
                        l0, l1, verts[tris[tri, 0]], verts[tris[tri, 1]], verts[tris[tri, 2]])
                    if d < bd:
                        bd = d
                        best = tri
                        bs = s
                        bu = u
                        bv = v
                        bw = w
    if bd > rmax:
        # nothing within reach (a pruned search does not know the true closest beyond it)
        return -1, bs, bu, bv, bw, bd
    return best, bs, bu, bv, bw, bd


@item_kernel
def closest_features(k, l0, l1, r0, r1, rmax, tip, verts, tris, tnormal, tedge, grid_origin,
                     grid_cell, grid_dims, grid_base, grid_start, grid_tris):
    """The three closest-triangle queries of a (segment, body) candidate in one walk of body
    k's grid: its start node l0 within ``r0``, its end node l1 within ``r1`` (only where
    ``tip``; else none is found) and the segment l0-l1 within ``rmax`` (>= r0, r1), all in
    the body frame. Returns (t0, u0, v0, w0, d0, t1, u1, v1, w1, d1, t2, s2, u2, v2, w2, d2),
    each query's (tri, [s,] u, v, w, dist) exactly as ``closest_triangle`` gives it: each
    query keeps its own box of cells (the same expressions) and meets its triangles in the
    same order, the walk covering the union of the boxes in the same cell order; the plane
    and edge-plane rejections are the same tests, their dot products shared. Saves two of
    three walks over the cells and their triangles' rejection tests. The 17th value is the
    triangle met whose plane both nodes are farthest in front of (-1 if none was met): the
    narrow phase keeps it as a hint for the next step (``supported_face``)."""
    lo = grid_origin[k]
    cell = grid_cell[k]
    d0 = grid_dims[k, 0]
    d1 = grid_dims[k, 1]
    d2 = grid_dims[k, 2]
    lim0 = r0 * (1.0 + 1e-9) + 1e-300
    lim1 = r1 * (1.0 + 1e-9) + 1e-300
    lim2 = rmax * (1.0 + 1e-9) + 1e-300
    # each query's box, as closest_triangle computes it (min(p, p) = p for a node)
    a_lo0 = max(int(math.floor((min(l0[0], l0[0]) - r0 - lo[0]) / cell)), 0)
    a_lo1 = max(int(math.floor((min(l0[1], l0[1]) - r0 - lo[1]) / cell)), 0)
    a_lo2 = max(int(math.floor((min(l0[2], l0[2]) - r0 - lo[2]) / cell)), 0)
    a_hi0 = min(int(math.floor((max(l0[0], l0[0]) + r0 - lo[0]) / cell)), d0 - 1)
    a_hi1 = min(int(math.floor((max(l0[1], l0[1]) + r0 - lo[1]) / cell)), d1 - 1)
    a_hi2 = min(int(math.floor((max(l0[2], l0[2]) + r0 - lo[2]) / cell)), d2 - 1)
    b_lo0 = max(int(math.floor((min(l1[0], l1[0]) - r1 - lo[0]) / cell)), 0)
    b_lo1 = max(int(math.floor((min(l1[1], l1[1]) - r1 - lo[1]) / cell)), 0)
    b_lo2 = max(int(math.floor((min(l1[2], l1[2]) - r1 - lo[2]) / cell)), 0)
    b_hi0 = min(int(math.floor((max(l1[0], l1[0]) + r1 - lo[0]) / cell)), d0 - 1)
    b_hi1 = min(int(math.floor((max(l1[1], l1[1]) + r1 - lo[1]) / cell)), d1 - 1)
    b_hi2 = min(int(math.floor((max(l1[2], l1[2]) + r1 - lo[2]) / cell)), d2 - 1)
    if not tip:
        b_lo0 = d0  # an empty box
    c_lo0 = max(int(math.floor((min(l0[0], l1[0]) - rmax - lo[0]) / cell)), 0)
    c_lo1 = max(int(math.floor((min(l0[1], l1[1]) - rmax - lo[1]) / cell)), 0)
    c_lo2 = max(int(math.floor((min(l0[2], l1[2]) - rmax - lo[2]) / cell)), 0)
    c_hi0 = min(int(math.floor((max(l0[0], l1[0]) + rmax - lo[0]) / cell)), d0 - 1)
    c_hi1 = min(int(math.floor((max(l0[1], l1[1]) + rmax - lo[1]) / cell)), d1 - 1)
    c_hi2 = min(int(math.floor((max(l0[2], l1[2]) + rmax - lo[2]) / cell)), d2 - 1)
    t0 = -1
    u0 = v0 = w0 = 0.0
    e0d = 1e300
    t1 = -1
    u1 = v1 = w1 = 0.0
    e1d = 1e300
    t2 = -1
    s2 = u2 = v2 = w2 = 0.0
    e2d = 1e300
    sep = -1
    sep_h = -1e300
    for e0 in range(min(a_lo0, min(b_lo0, c_lo0)), max(a_hi0, max(b_hi0, c_hi0)) + 1):
        for e1 in range(min(a_lo1, min(b_lo1, c_lo1)), max(a_hi1, max(b_hi1, c_hi1)) + 1):
            for e2 in range(min(a_lo2, min(b_lo2, c_lo2)), max(a_hi2, max(b_hi2, c_hi2)) + 1):
                in0 = (a_lo0 <= e0 <= a_hi0 and a_lo1 <= e1 <= a_hi1
                       and a_lo2 <= e2 <= a_hi2)
                in1 = (b_lo0 <= e0 <= b_hi0 and b_lo1 <= e1 <= b_hi1
                       and b_lo2 <= e2 <= b_hi2)
                in2 = (c_lo0 <= e0 <= c_hi0 and c_lo1 <= e1 <= c_hi1
                       and c_lo2 <= e2 <= c_hi2)
                if not (in0 or in1 or in2):
                    continue
                cc = grid_base[k] + (e0 * d1 + e1) * d2 + e2
                for idx in range(grid_start[cc], grid_start[cc + 1]):
                    tri = grid_tris[idx]
                    a0 = verts[tris[tri, 0]]
                    nx = tnormal[tri, 0]
                    ny = tnormal[tri, 1]
                    nz = tnormal[tri, 2]
                    h0 = nx * (l0[0] - a0[0]) + ny * (l0[1] - a0[1]) + nz * (l0[2] - a0[2])
                    h1 = nx * (l1[0] - a0[0]) + ny * (l1[1] - a0[1]) + nz * (l1[2] - a0[2])
                    if min(h0, h1) > sep_h:
                        sep_h = min(h0, h1)
                        sep = tri
                    q0 = in0 and not (h0 > r0 or h0 < -r0)
                    q1 = in1 and not (h1 > r1 or h1 < -r1)
                    q2 = in2 and not ((h0 > rmax and h1 > rmax) or (h0 < -rmax and h1 < -rmax))
                    if not (q0 or q1 or q2):
                        continue
                    for e in range(3):
                        a = verts[tris[tri, e]]
                        mx = tedge[tri, e, 0]
                        my = tedge[tri, e, 1]
                        mz = tedge[tri, e, 2]
                        g0 = mx * (l0[0] - a[0]) + my * (l0[1] - a[1]) + mz * (l0[2] - a[2])
                        g1 = mx * (l1[0] - a[0]) + my * (l1[1] - a[1]) + mz * (l1[2] - a[2])
                        if g0 > lim0:
                            q0 = False
                        if g1 > lim1:
                            q1 = False
                        if g0 > lim2 and g1 > lim2:
                            q2 = False
                    if q0:
                        _s, u, v, w, d = segment_triangle_closest(
                            l0, l0, verts[tris[tri, 0]], verts[tris[tri, 1]],
                            verts[tris[tri, 2]])
                        if d < e0d:
                            e0d = d
                            t0 = tri
                            u0 = u
                            v0 = v
                            w0 = w
                    if q1:
                        _s, u, v, w, d = segment_triangle_closest(
                            l1, l1, verts[tris[tri, 0]], verts[tris[tri, 1]],
                            verts[tris[tri, 2]])
                        if d < e1d:
                            e1d = d
                            t1 = tri
                            u1 = u
                            v1 = v
                            w1 = w
                    if q2:
                        s, u, v, w, d = segment_triangle_closest(
                            l0, l1, verts[tris[tri, 0]], verts[tris[tri, 1]],
                            verts[tris[tri, 2]])
                        if d < e2d:
                            e2d = d
                            t2 = tri
                            s2 = s
                            u2 = u
                            v2 = v
                            w2 = w
    # nothing within reach (as closest_triangle: a pruned search knows no farther closest)
    if e0d > r0:
        t0 = -1
    if e1d > r1:
        t1 = -1
    if e2d > rmax:
        t2 = -1
    return t0, u0, v0, w0, e0d, t1, u1, v1, w1, e1d, t2, s2, u2, v2, w2, e2d, sep


# the smallest barycentric weight of a node's projection on a cached face for that face to
# settle the candidate's queries without the walk; nearer an edge the walk decides (so a tie
# between neighbouring triangles is still broken the walk's way)
FACE_MARGIN = 1e-6


@item_kernel
def supported_face(F, k, l0, l1, r0, r1, rmax, tip, verts, tris, tnormal, tsupport):
    """The queries of ``closest_features`` settled from one triangle F of body k alone, where
    F's plane supports the mesh (``tsupport[F] == k``: every vertex of body k on or behind
    it, as for each face of a convex body), without walking the grid. Returns (ok, t0, u0,
    v0, w0, d0, t1, u1, v1, w1, d1); when ok, the segment's query (slot 2) finds no edge or
    vertex (t2 = -1) and the node queries are what ``closest_features`` gives, bit for bit
    (the same routine on the triangle the walk would pick), so the forces do not change;
    when not ok the caller walks.

    With both nodes on or in front of F's plane (h0, h1 >= 0): no mesh point is nearer to a
    point x in front of the plane than the plane, h(x), as the mesh lies behind it.

    * Separated: both nodes farther than ``rmax`` (>= r0, r1) in front: so is every point
      of the segment, and nothing is within reach.
    * A node farther in front than its radius has nothing within reach.
    * A node within its radius that projects inside F (every weight >= ``FACE_MARGIN``)
      has its projection as its closest point of the mesh, at the plane distance.
    * The segment: the node nearer the plane (both where h0 = h1) projecting inside F, its
      projection is the closest point of the mesh to the whole segment (every other point
      x has h(x) above that node's), a face's interior, which slot 2 leaves to the nodes."""
    if F < 0 or tsupport[F] != k:
        return False, -1, 0.0, 0.0, 0.0, 0.0, -1, 0.0, 0.0, 0.0, 0.0
    h0, h1 = _heights(F, l0, l1, verts, tris, tnormal)
    lim = rmax * (1.0 + 1e-9) + 1e-300
    if h0 > lim and h1 > lim:
        return True, -1, 0.0, 0.0, 0.0, h0, -1, 0.0, 0.0, 0.0, h1
    if h0 < 0.0 or h1 < 0.0:
        return False, -1, 0.0, 0.0, 0.0, 0.0, -1, 0.0, 0.0, 0.0, 0.0
    # which nodes must project inside F: the nearer one (the segment's closest point), and
    # each one within its radius (its own closest point)
    lim0 = r0 * (1.0 + 1e-9) + 1e-300
    lim1 = r1 * (1.0 + 1e-9) + 1e-300
    need0 = h0 <= h1 or h0 <= lim0
    need1 = h1 <= h0 or (tip and h1 <= lim1)
    ia = tris[F, 0]
    ib = tris[F, 1]
    ic = tris[F, 2]
    ax = verts[ia, 0]
    ay = verts[ia, 1]
    az = verts[ia, 2]
    e1x = verts[ib, 0] - ax
    e1y = verts[ib, 1] - ay
    e1z = verts[ib, 2] - az
    e2x = verts[ic, 0] - ax
    e2y = verts[ic, 1] - ay
    e2z = verts[ic, 2] - az
    d00 = e1x * e1x + e1y * e1y + e1z * e1z
    d01 = e1x * e2x + e1y * e2y + e1z * e2z
    d11 = e2x * e2x + e2y * e2y + e2z * e2z
    den = d00 * d11 - d01 * d01
    if not den > 0.0:
        return False, -1, 0.0, 0.0, 0.0, 0.0, -1, 0.0, 0.0, 0.0, 0.0
    inv = 1.0 / den
    u0 = v0 = w0 = u1 = v1 = w1 = 0.0
    if need0:
        u0, v0, w0 = _plane_weights(l0[0] - ax, l0[1] - ay, l0[2] - az, e1x, e1y, e1z, e2x,
                                    e2y, e2z, d00, d01, d11, inv)
        if min(u0, min(v0, w0)) < FACE_MARGIN:
            return False, -1, 0.0, 0.0, 0.0, 0.0, -1, 0.0, 0.0, 0.0, 0.0
    if need1:
        u1, v1, w1 = _plane_weights(l1[0] - ax, l1[1] - ay, l1[2] - az, e1x, e1y, e1z, e2x,
                                    e2y, e2z, d00, d01, d11, inv)
        if min(u1, min(v1, w1)) < FACE_MARGIN:
            return False, -1, 0.0, 0.0, 0.0, 0.0, -1, 0.0, 0.0, 0.0, 0.0
    # each node's answer as the walk computes it: the walk measures a triangle that its
    # plane test (h <= r) lets through with this routine and keeps it within r; F is its
    # unique closest triangle, so the same bits
    t0 = -1
    t1 = -1
    if h0 <= r0:
        _s, u0, v0, w0, h0 = segment_triangle_closest(l0, l0, verts[ia], verts[ib], verts[ic])
        if h0 <= r0:
            t0 = F
    if tip and h1 <= r1:
        _s, u1, v1, w1, h1 = segment_triangle_closest(l1, l1, verts[ia], verts[ib], verts[ic])
        if h1 <= r1:
            t1 = F
    return True, t0, u0, v0, w0, h0, t1, u1, v1, w1, h1


@njit(cache=True, inline="always")
def _plane_weights(px, py, pz, e1x, e1y, e1z, e2x, e2y, e2z, d00, d01, d11, inv):
    """Barycentric weights (of corners a, b, c) of the projection onto a triangle's plane of
    the point a + p, the edges e1 = b - a and e2 = c - a, their Gram entries d00 = e1.e1,
    d01 = e1.e2, d11 = e2.e2 and inv = 1 / (d00 d11 - d01^2)."""
    p1 = px * e1x + py * e1y + pz * e1z
    p2 = px * e2x + py * e2y + pz * e2z
    v = (d11 * p1 - d01 * p2) * inv
    w = (d00 * p2 - d01 * p1) * inv
    return 1.0 - v - w, v, w


@item_kernel
def _beyond_an_edge(tri, l0, l1, lim, verts, tris, tedge):
    """Whether both ends of the segment l0-l1 lie more than ``lim`` beyond one of triangle
    ``tri``'s edge planes (``tedge``: in-plane unit normals of edges ab, bc, ca pointing away
    from the opposite vertex; zeros for slivers). The triangle lies behind each, so then the
    whole segment is farther than ``lim`` from it: exact, and much cheaper than the
    segment-triangle distance, which a cylinder's long facets otherwise all need."""
    for e in range(3):
        a = verts[tris[tri, e]]
        mx = tedge[tri, e, 0]
        my = tedge[tri, e, 1]
        mz = tedge[tri, e, 2]
        g0 = mx * (l0[0] - a[0]) + my * (l0[1] - a[1]) + mz * (l0[2] - a[2])
        g1 = mx * (l1[0] - a[0]) + my * (l1[1] - a[1]) + mz * (l1[2] - a[2])
        if g0 > lim and g1 > lim:
            return True
    return False


@item_kernel
def nearest_triangle(k, p, r0, verts, tris, tnormal, tedge, grid_origin, grid_cell, grid_dims,
                     grid_base, grid_start, grid_tris):
    """The closest triangle of body k to the point p (body frame) at any distance, by
    ``closest_triangle`` over a box that doubles from half-size ``r0`` until a triangle is
    found within it (exact then: a triangle within r of p is listed in the cell that holds
    its closest point, which the box covers). The box stops growing once it holds the whole
    grid, so the cost follows the distance to the surface, not the triangle count. Returns
    (tri, u, v, w, dist); tri = -1 only for a body without triangles."""
    lo = grid_origin[k]
    cell = grid_cell[k]
    far = 0.0  # distance to the grid's farthest corner: a box this big scans every cell
    for a in range(3):
        e = max(abs(p[a] - lo[a]), abs(p[a] - lo[a] - grid_dims[k, a] * cell))
        far += e * e
    far = math.sqrt(far)
    r = min(max(r0, 0.5 * cell), far)
    while True:
        tri, _s, u, v, w, d = closest_triangle(k, p, p, r, verts, tris, tnormal, tedge, grid_origin,
                                               grid_cell, grid_dims, grid_base, grid_start,
                                               grid_tris)
        if tri >= 0 or r >= far:
            return tri, u, v, w, d
        r = min(2.0 * r, far)


@item_kernel
def deep_closest(k, p, r0, verts, tris, tnormal, tedge, pnormal, grid_origin, grid_cell, grid_dims,
                 grid_base, grid_start, grid_tris, grid_side):
    """For a point p (body frame) of a closed (watertight) mesh body k: its closest triangle
    (tri, u, v, w, dist) if p lies inside the body, else tri = -1. Outside the grid's box
    (which holds every triangle) is outside without a search; inside it, the closest
    triangle at any distance (``nearest_triangle`` from half-size ``r0``) and the sign of
    (p - closest point) along the feature's angle-weighted pseudo-normal decide, as in the
    narrow phase. Only meaningful for watertight meshes. A point in a grid cell that no
    triangle's box overlaps takes that cell's side from ``grid_side`` (``CELL_OUTSIDE``:
    outside without a search; the surface does not pass through such a cell, see
    ``engine.assembly.bodies.classify_empty_cells``)."""
    cc = _grid_cell_of(k, p, grid_origin, grid_cell, grid_dims, grid_base)
    if cc < 0 or grid_side[cc] == CELL_OUTSIDE:
        return -1, 0.0, 0.0, 0.0, 0.0
    tri, u, v, w, d = nearest_triangle(k, p, r0, verts, tris, tnormal, tedge, grid_origin, grid_cell,
                                       grid_dims, grid_base, grid_start, grid_tris)
    if tri < 0:
        return -1, 0.0, 0.0, 0.0, 0.0
    a0 = verts[tris[tri, 0]]
    b0 = verts[tris[tri, 1]]
    c0 = verts[tris[tri, 2]]
    gx = p[0] - (u * a0[0] + v * b0[0] + w * c0[0])
    gy = p[1] - (u * a0[1] + v * b0[1] + w * c0[1])
    gz = p[2] - (u * a0[2] + v * b0[2] + w * c0[2])
    fnx, fny, fnz = feature_normal(tri, u, v, w, pnormal)
    if gx * fnx + gy * fny + gz * fnz < 0.0:
        return tri, u, v, w, d
    return -1, 0.0, 0.0, 0.0, 0.0


@item_kernel
def feature_normal(tri, u, v, w, pnormal):
    """The angle-weighted pseudo-normal (Baerentzen & Aanaes 2005) of the feature of triangle
    ``tri`` that holds the closest point with barycentric weights (u, v, w): the face, an edge
    or a vertex. A point is inside a closed mesh exactly when (point - closest point) has a
    negative component along it; the face normal alone misjudges points near an edge that lie
    behind one of the edge's two faces but in front of the other (outside the body).
    ``pnormal[t]`` rows: 0 face, 1-3 edges ab, bc, ca, 4-6 vertices a, b, c."""
    eps = 1e-9
    zu = u <= eps
    zv = v <= eps
    zw = w <= eps
    nz = int(zu) + int(zv) + int(zw)
    if nz == 0:
        f = 0
    elif nz == 1:
        if zw:
            f = 1
        elif zu:
            f = 2
        else:
            f = 3
    elif u >= v and u >= w:
        f = 4
    elif v >= w:
        f = 5
    else:
        f = 6
    return pnormal[tri, f, 0], pnormal[tri, f, 1], pnormal[tri, f, 2]


CELL_UNKNOWN = 0   # grid_side: a cell some triangle's box overlaps (or a mesh never asked)
CELL_OUTSIDE = 1   # an empty cell outside the closed body
CELL_INSIDE = 2    # an empty cell inside it
BSLOT = 3          # contacts a (segment, body) candidate holds: two nodes + one interior
BODY_CROSS_END = 0.25


@njit(cache=True, parallel=True)
def bristle_body_narrow(nd, bn, bl, bd, tb, friction, dt):
    """Bristle-body contacts of the first ``n_cand`` candidates, up to ``BSLOT`` each:
    slot 0 the segment's start node (a sphere of the node's radius) against the body, slot 1
    the tip node of a bristle's last segment, slot 2 the segment between its nodes against an
    edge or vertex of the mesh (or a sphere body), weighted smoothly to zero towards the
    segment's ends where the node contacts take over. A bristle lying along a face therefore
    touches it at every node (a line contact), and a wedge's edge across a bristle touches it
    between nodes. ``fc`` is the force on the segment (the body gets ``-fc`` at ``cp``)."""
    x, v, w, rad, mass = nd.x, nd.v, nd.w, nd.rad, nd.mass
    bi, bj, seg_has_next, seg_material = bn.i, bn.j, bn.has_next, bn.material
    cs, cb, deep, n_cand, ft, local = bl.s, bl.b, bl.deep, bl.n[0], bl.ft, bl.local
    bpos, bq, bv, bw, bmass, motion = bd.pos, bd.q, bd.v, bd.w, bd.mass, bd.motion
    sphere_r, watertight, body_material = bd.sphere_r, bd.watertight, bd.material
    verts, tris, tnormal, tedge, pnormal = bd.verts, bd.tris, bd.tnormal, bd.tedge, bd.pnormal
    grid_origin, grid_cell, grid_dims = bd.grid_origin, bd.grid_cell, bd.grid_dims
    grid_base, grid_start, grid_tris = bd.grid_base, bd.grid_start, bd.grid_tris
    grid_side = bd.grid_side
    E, mu_table, kt_table, zeta_table, adh_table = tb.E, tb.mu, tb.kt, tb.zeta, tb.adhesion
    active, fc, cp, par_s = bl.active, bl.fc, bl.cp, bl.par
    energy, diss, overlap_ratio, xf = bl.energy, bl.diss, bl.ratio, bl.xf
    # the candidate kernel's arrays in seven tuples, not as 51 arguments: a call of more than
    # 30 arguments is compiled by CPython 3.11 as f(*args), and numba's call through that one
    # big tuple cost 1.08 us per candidate on the box scene (half of its narrow phase), against
    # 0.19 us with the tuples (benchmarks/body_kernel.py's frozen box state)
    nodes = (x, v, w, rad, mass)
    segs = (bi, bj, seg_has_next, seg_material)
    lst = (cs, cb, deep, ft, local, bl.face)
    body = (bpos, bq, bv, bw, bmass, motion, sphere_r, watertight, body_material)
    surf = (verts, tris, tnormal, tedge, pnormal, grid_origin, grid_cell, grid_dims, grid_base,
            grid_start, grid_tris, grid_side, bd.tsupport)
    tabs = (E, mu_table, kt_table, zeta_table, adh_table)
    out = (active, fc, cp, par_s, energy, diss, overlap_ratio, xf)
    if n_cand >= PARALLEL_MIN_CANDIDATES:
        for c in prange(n_cand):
            _bristle_body_candidate(c, nodes, segs, lst, body, surf, tabs, out, friction,
                                    dt)
    else:
        for c in range(n_cand):
            _bristle_body_candidate(c, nodes, segs, lst, body, surf, tabs, out, friction,
                                    dt)


@item_kernel
def _bristle_body_candidate(c, nodes, segs, lst, body, surf, tabs, out, friction, dt):
    x, v, w, rad, mass = nodes
    bi, bj, seg_has_next, seg_material = segs
    cs, cb, deep, ft, local, face = lst
    bpos, bq, bv, bw, bmass, motion, sphere_r, watertight, body_material = body
    (verts, tris, tnormal, tedge, pnormal, grid_origin, grid_cell, grid_dims, grid_base,
     grid_start, grid_tris, grid_side, tsupport) = surf
    E, mu_table, kt_table, zeta_table, adh_table = tabs
    active, fc, cp, par_s, energy, diss, overlap_ratio, xf = out
    sg = cs[c]
    k = cb[c]
    i0 = bi[sg]
    i1 = bj[sg]
    qw = bq[k, 0]
    qx = bq[k, 1]
    qy = bq[k, 2]
    qz = bq[k, 3]
    l0 = local[c, 0]
    l1 = local[c, 1]
    l0[0], l0[1], l0[2] = qrot_inv(qw, qx, qy, qz, x[i0, 0] - bpos[k, 0],
                                   x[i0, 1] - bpos[k, 1], x[i0, 2] - bpos[k, 2])
    l1[0], l1[1], l1[2] = qrot_inv(qw, qx, qy, qz, x[i1, 0] - bpos[k, 0],
                                   x[i1, 1] - bpos[k, 1], x[i1, 2] - bpos[k, 2])
    mesh = sphere_r[k] <= 0.0
    if mesh:
        # the three slots' closest triangles: from last step's face where its plane settles
        # them, else in one walk of the body's grid (and that walk's face kept for the next)
        tip = not seg_has_next[sg]
        rm = max(rad[i0], rad[i1])
        t2 = -1
        s2 = u2 = v2 = w2 = f2 = 0.0
        ok, t0, u0, v0, w0, f0, t1, u1, v1, w1, f1 = supported_face(
            face[c], k, l0, l1, rad[i0], rad[i1], rm, tip, verts, tris, tnormal, tsupport)
        if not ok:
            (t0, u0, v0, w0, f0, t1, u1, v1, w1, f1, t2, s2, u2, v2, w2, f2,
             sep) = closest_features(k, l0, l1, rad[i0], rad[i1], rm, tip, verts, tris,
                                     tnormal, tedge, grid_origin, grid_cell, grid_dims,
                                     grid_base, grid_start, grid_tris)
            face[c] = t0 if t0 >= 0 else (t1 if t1 >= 0 else sep)
    else:
        t0 = t1 = t2 = -1
        u0 = v0 = w0 = f0 = u1 = v1 = w1 = f1 = s2 = u2 = v2 = w2 = f2 = 0.0
    for slot_k in range(BSLOT):
        slot = c * BSLOT + slot_k
        active[slot] = 0
        diss[slot] = 0.0
        dweight = 0.0
        inside = False
        # an edge contact's fade towards the faces' planes (``edge_face_fade``): chi, and its
        # gradient with respect to the segment's axis d1 = l1 - l0 (body frame)
        chi = 1.0
        cgx = 0.0
        cgy = 0.0
        cgz = 0.0
        if slot_k == 1 and seg_has_next[sg]:
            clear_history(ft, slot, friction, diss)
            continue
        weight = 1.0
        if sphere_r[k] > 0.0:
            if slot_k == 0:
                s = 0.0
            elif slot_k == 1:
                s = 1.0
            else:
                s = segment_point_closest(row3(x, i0), row3(x, i1), row3(bpos, k))
                weight = smoothstep(min(s, 1.0 - s) / BODY_CROSS_END)
                dweight = (_dsmooth01(min(s, 1.0 - s) / BODY_CROSS_END) / BODY_CROSS_END
                           * (1.0 if s < 0.5 else -1.0))
            px = x[i0, 0] + s * (x[i1, 0] - x[i0, 0])
            py = x[i0, 1] + s * (x[i1, 1] - x[i0, 1])
            pz = x[i0, 2] + s * (x[i1, 2] - x[i0, 2])
            r = rad[i0] + s * (rad[i1] - rad[i0])
            dx = px - bpos[k, 0]
            dy = py - bpos[k, 1]
            dz = pz - bpos[k, 2]
            d = math.sqrt(dx * dx + dy * dy + dz * dz)
            ov = r + sphere_r[k] - d
            if ov <= 0.0 or weight <= 0.0:
                clear_history(ft, slot, friction, diss)
                continue
            if d > 1e-12 * sphere_r[k]:
                nx = dx / d
                ny = dy / d
                nz = dz / d
            else:
                nx, ny, nz = 0.0, 0.0, 1.0
            hcp = r - 0.5 * ov
            cx = px - nx * hcp
            cy = py - ny * hcp
            cz = pz - nz * hcp
        else:
            if slot_k <= 1:
                pe = l0 if slot_k == 0 else l1
                re = rad[i0] if slot_k == 0 else rad[i1]
                if slot_k == 0:
                    tri, u, vv, ww, d = t0, u0, v0, w0, f0
                else:
                    tri, u, vv, ww, d = t1, u1, v1, w1, f1
                if tri < 0 and watertight[k] and (deep[c] >> slot_k) & 1:
                    # no face within the node's radius: the node may be deep inside a
                    # closed body, overlapping by more than its radius; push it out too
                    # (only where the candidate list says it can be: ``out_deep``)
                    tri, u, vv, ww, d = deep_closest(k, pe, 2.0 * re, verts, tris, tnormal, tedge,
                                                     pnormal, grid_origin, grid_cell,
                                                     grid_dims, grid_base, grid_start,
                                                     grid_tris, grid_side)
                s = float(slot_k)
            else:
                tri, s, u, vv, ww, d = t2, s2, u2, v2, w2, f2
                # between the nodes only against edges and vertices: a face touching a
                # segment's interior touches (or soon touches) its nodes too
                if tri >= 0 and min(u, min(vv, ww)) > 1e-9:
                    tri = -1
                weight = smoothstep(min(s, 1.0 - s) / BODY_CROSS_END)
                dweight = (_dsmooth01(min(s, 1.0 - s) / BODY_CROSS_END) / BODY_CROSS_END
                           * (1.0 if s < 0.5 else -1.0))
                if tri >= 0 and _holds_edge(u, vv, ww):
                    chi, cgx, cgy, cgz = edge_face_fade(l0, l1, tri, u, vv, ww, tnormal,
                                                        pnormal)
                    weight *= chi
                    dweight *= chi
            if tri < 0 or weight <= 0.0:
                clear_history(ft, slot, friction, diss)
                continue
            r = rad[i0] + s * (rad[i1] - rad[i0])
            psx = l0[0] + s * (l1[0] - l0[0])
            psy = l0[1] + s * (l1[1] - l0[1])
            psz = l0[2] + s * (l1[2] - l0[2])
            a = verts[tris[tri, 0]]
            b = verts[tris[tri, 1]]
            cc = verts[tris[tri, 2]]
            ptx = u * a[0] + vv * b[0] + ww * cc[0]
            pty = u * a[1] + vv * b[1] + ww * cc[1]
            ptz = u * a[2] + vv * b[2] + ww * cc[2]
            gx = psx - ptx
            gy = psy - pty
            gz = psz - ptz
            d = math.sqrt(gx * gx + gy * gy + gz * gz)
            fnx, fny, fnz = feature_normal(tri, u, vv, ww, pnormal)
            side = gx * fnx + gy * fny + gz * fnz
            if watertight[k] and side < 0.0:
                # the axis point lies inside a closed body: push it out along the face normal
                inside = True
                ov = r + d
                nlx, nly, nlz = fnx, fny, fnz
            else:
                ov = r - d
                if d > 1e-9 * r:
                    nlx = gx / d
                    nly = gy / d
                    nlz = gz / d
                elif fnx * fnx + fny * fny + fnz * fnz > 0.0:
                    nlx, nly, nlz = fnx, fny, fnz
                else:
                    nn = math.sqrt(psx * psx + psy * psy + psz * psz)
                    if nn > 0.0:
                        nlx, nly, nlz = psx / nn, psy / nn, psz / nn
                    else:
                        nlx, nly, nlz = 0.0, 0.0, 1.0
            if ov <= 0.0:
                clear_history(ft, slot, friction, diss)
                continue
            # contact point: middle of the overlap, between the body surface and the capsule's
            clx = ptx + 0.5 * (gx - nlx * r)
            cly = pty + 0.5 * (gy - nly * r)
            clz = ptz + 0.5 * (gz - nlz * r)
            nx, ny, nz = qrot(qw, qx, qy, qz, nlx, nly, nlz)
            cx, cy, cz = qrot(qw, qx, qy, qz, clx, cly, clz)
            cx += bpos[k, 0]
            cy += bpos[k, 1]
            cz += bpos[k, 2]
            px = x[i0, 0] + s * (x[i1, 0] - x[i0, 0])
            py = x[i0, 1] + s * (x[i1, 1] - x[i0, 1])
            pz = x[i0, 2] + s * (x[i1, 2] - x[i0, 2])
        vax, vay, vaz = segment_point_velocity(v, w, i0, i1, s, px, py, pz, cx, cy, cz)
        rx = cx - bpos[k, 0]
        ry = cy - bpos[k, 1]
        rz = cz - bpos[k, 2]
        vbx = bv[k, 0] + bw[k, 1] * rz - bw[k, 2] * ry
        vby = bv[k, 1] + bw[k, 2] * rx - bw[k, 0] * rz
        vbz = bv[k, 2] + bw[k, 0] * ry - bw[k, 1] * rx
        ma = mass[i0] + s * (mass[i1] - mass[i0])
        if motion[k] == FIXED or motion[k] == KINEMATIC:
            meff = ma
        else:
            meff = ma * bmass[k] / (ma + bmass[k])
        m1 = seg_material[sg]
        m2 = body_material[k]
        kn = weight * normal_stiffness(E[m1], r, E[m2], r)
        Fx, Fy, Fz, dis, sto, fadh = contact_with_history(
            ft, slot, friction, nx, ny, nz, ov, vax - vbx, vay - vby, vaz - vbz, kn,
            kt_table[m1, m2] * kn, mu_table[m1, m2], zeta_table[m1, m2], meff, dt,
            weight * adh_table[m1, m2])
        active[slot] = 1
        fc[slot, 0] = Fx
        fc[slot, 1] = Fy
        fc[slot, 2] = Fz
        cp[slot, 0] = cx
        cp[slot, 1] = cy
        cp[slot, 2] = cz
        par_s[slot] = s
        energy[slot] = sto
        diss[slot] = dis
        overlap_ratio[slot] = ov / r
        if slot_k == 2:
            # the fade forces of the slot between the nodes (a node's slot has none:
            # ``scatter_bristle_body`` reads these rows of slot 2 only)
            xf[slot, :, :] = 0.0
        if slot_k == 2 and not inside:
            # the energy U = 1/2 w(s) k(r(s)) ov^2 also changes with the axis parameter s (the
            # fade w, the taper r and k proportional to r); the distance is stationary in s,
            # so the rest of the gradient is dU/ds grad s (``_fade_forces``); an adhered
            # contact adds -w(s) fa ov (``contact_law.adhesion``; fa at full weight)
            k0 = normal_stiffness(E[m1], r, E[m2], r)
            dr = rad[i1] - rad[i0]
            fa0 = adh_table[m1, m2] if fadh != 0.0 else 0.0
            g = (0.5 * (dweight * k0 + weight * k0 * dr / r) * ov * ov
                 + weight * k0 * ov * dr) - (dweight * ov + weight * dr) * fa0
            if sphere_r[k] > 0.0:
                _point_fade_forces(x[i0, 0], x[i0, 1], x[i0, 2], x[i1, 0], x[i1, 1],
                                   x[i1, 2], bpos[k, 0], bpos[k, 1], bpos[k, 2], s, g,
                                   xf[slot])
                # a sphere's energy does not depend on its rotation: no torque (row 3 = 0)
            else:
                _mesh_fade_forces(l0, l1, s, u, vv, ww, verts[tris[tri, 0]],
                                  verts[tris[tri, 1]], verts[tris[tri, 2]], g, xf[slot])
                if chi < 1.0:
                    # and with the angle fade chi(d1): -1/2 w(s) k ov^2 grad chi, a couple on
                    # the segment's nodes (chi depends on d1 = l1 - l0 only) whose reaction
                    # on the body is the torque d1 x (that force on node 1)'s opposite
                    h = 0.5 * (weight / chi) * k0 * ov * ov - (weight / chi) * fa0 * ov
                    xf[slot, 0, 0] += h * cgx
                    xf[slot, 0, 1] += h * cgy
                    xf[slot, 0, 2] += h * cgz
                    xf[slot, 1, 0] -= h * cgx
                    xf[slot, 1, 1] -= h * cgy
                    xf[slot, 1, 2] -= h * cgz
                    dx1 = l1[0] - l0[0]
                    dy1 = l1[1] - l0[1]
                    dz1 = l1[2] - l0[2]
                    xf[slot, 3, 0] += h * (dy1 * cgz - dz1 * cgy)
                    xf[slot, 3, 1] += h * (dz1 * cgx - dx1 * cgz)
                    xf[slot, 3, 2] += h * (dx1 * cgy - dy1 * cgx)
                for row in range(4):
                    xf[slot, row, 0], xf[slot, row, 1], xf[slot, row, 2] = qrot(
                        qw, qx, qy, qz, xf[slot, row, 0], xf[slot, row, 1], xf[slot, row, 2])


@item_kernel
def _point_fade_forces(x0x, x0y, x0z, x1x, x1y, x1z, cx, cy, cz, s, g, out):
    """Forces -g grad s for s = (c - x0).e / e.e, the segment's point closest to the point c
    (interior): rows 0, 1 on the segment's nodes, row 2 on c, row 3 (torque) untouched."""
    ex = x1x - x0x
    ey = x1y - x0y
    ez = x1z - x0z
    L2 = ex * ex + ey * ey + ez * ez
    ax = cx - x0x
    ay = cy - x0y
    az = cz - x0z
    gc = -g / L2
    # grad_c s = e / L2; grad_x1 s = (a - 2 s e) / L2; grad_x0 s = -(the two)
    out[2, 0] = gc * ex
    out[2, 1] = gc * ey
    out[2, 2] = gc * ez
    out[1, 0] = gc * (ax - 2.0 * s * ex)
    out[1, 1] = gc * (ay - 2.0 * s * ey)
    out[1, 2] = gc * (az - 2.0 * s * ez)
    for a in range(3):
        out[0, a] = -(out[1, a] + out[2, a])


# An edge contact between a segment's nodes fades out as the segment turns parallel to either
# face of the edge: chi = S(c_F) S(c_G), c the squared sine of the angle between the segment
# and the face's plane, S the smoothstep from EDGE_FACE_SIN2_LO (0: no contact) to
# EDGE_FACE_SIN2_HI (0.01, 5.7 deg: full contact). Two reasons:
#   * the closest point's parameter s moves like 1 / sin^2 of the angle between the segment
#     and the edge (``_edge_fade_forces``), and that angle is at least the one between the
#     segment and either face's plane (the edge lies in both); S(c) <= 3 (c / 0.01)^2, so
#     chi grad s stays bounded (chi / c <= 113) and vanishes with the angle;
#   * the closest point leaves an edge for a face's interior exactly when the segment lies
#     parallel to that face (the axis-to-edge direction then reaches the face's normal, and
#     the axis is perpendicular to it): an edge contact still at full weight there would vanish
#     at once, a jump of its energy. Faded, it hands over to the node contacts (a segment lying
#     on a face touches it at its nodes), continuously. Flat edges (between coplanar
#     triangles) are then never counted: a segment whose closest point lies on one is parallel
#     to the face.
# The band is narrow because the node on the face's side is ``l sin(angle)`` above the face
# when the segment rests on the edge at a distance l from it: with the bristle-bristle
# crossing's band (sin^2 0.04 to 0.10) a box's edge let a bristle lying at 15 deg to a face
# sink to 0.78 of its radius (docs/stability.md).
EDGE_FACE_SIN2_LO = 0.0
EDGE_FACE_SIN2_HI = 0.01


@item_kernel
def _holds_edge(u, v, w):
    """Whether barycentric weights (u, v, w) put a triangle's point on an edge's interior
    (exactly two above the tolerance ``feature_normal`` uses)."""
    tiny = 1e-9
    return (1 if u > tiny else 0) + (1 if v > tiny else 0) + (1 if w > tiny else 0) == 2


@item_kernel
def edge_face_fade(l0, l1, tri, u, v, w, tnormal, pnormal):
    """(chi, dchi/dd1) of a segment l0-l1 (body frame, d1 = l1 - l0) against the edge of
    triangle ``tri`` that holds the point with weights (u, v, w): chi = S(c_F) S(c_G), with
    c = (d1.n)^2 / d1.d1 the squared sine of the angle between the segment and a face's plane,
    S the smoothstep from ``EDGE_FACE_SIN2_LO`` to ``EDGE_FACE_SIN2_HI``, n_F the triangle's
    normal and n_G the other face's, recovered from the edge's pseudo-normal m (the bisector
    of n_F and n_G: n_G = 2 (m.n_F) m - n_F; a boundary edge of an open mesh has m = n_F,
    hence n_G = n_F)."""
    tiny = 1e-9
    if w <= tiny:
        row = 1
    elif u <= tiny:
        row = 2
    else:
        row = 3
    fx, fy, fz = tnormal[tri, 0], tnormal[tri, 1], tnormal[tri, 2]
    mx, my, mz = pnormal[tri, row, 0], pnormal[tri, row, 1], pnormal[tri, row, 2]
    mf = 2.0 * (mx * fx + my * fy + mz * fz)
    gx, gy, gz = mf * mx - fx, mf * my - fy, mf * mz - fz
    dx = l1[0] - l0[0]
    dy = l1[1] - l0[1]
    dz = l1[2] - l0[2]
    a = dx * dx + dy * dy + dz * dz
    band = EDGE_FACE_SIN2_HI - EDGE_FACE_SIN2_LO
    pf = dx * fx + dy * fy + dz * fz
    pg = dx * gx + dy * gy + dz * gz
    cf = pf * pf / a
    cg = pg * pg / a
    sf = smoothstep((cf - EDGE_FACE_SIN2_LO) / band)
    sg = smoothstep((cg - EDGE_FACE_SIN2_LO) / band)
    chi = sf * sg
    # grad_d1 c = 2 (d1.n) n / a - 2 c d1 / a
    kf = _dsmooth01((cf - EDGE_FACE_SIN2_LO) / band) / band * sg
    kg = _dsmooth01((cg - EDGE_FACE_SIN2_LO) / band) / band * sf
    ox = (kf * (2.0 * pf * fx - 2.0 * cf * dx) + kg * (2.0 * pg * gx - 2.0 * cg * dx)) / a
    oy = (kf * (2.0 * pf * fy - 2.0 * cf * dy) + kg * (2.0 * pg * gy - 2.0 * cg * dy)) / a
    oz = (kf * (2.0 * pf * fz - 2.0 * cf * dz) + kg * (2.0 * pg * gz - 2.0 * cg * dz)) / a
    return chi, ox, oy, oz


@item_kernel
def _mesh_fade_forces(l0, l1, s, u, v, w, va, vb, vc, g, out):
    """``_point_fade_forces`` for a mesh feature in the body frame: a vertex (one barycentric
    weight 1), or an edge, where s and the edge's parameter t solve the segment-segment
    closest-point conditions and grad s follows by differentiating them. Row 2 gets the
    body's force, row 3 its torque about the centre of mass (the body frame's origin)."""
    tiny = 1e-9
    nz = (1 if u > tiny else 0) + (1 if v > tiny else 0) + (1 if w > tiny else 0)
    if nz == 1:
        if u > tiny:
            p = va
        elif v > tiny:
            p = vb
        else:
            p = vc
        _point_fade_forces(l0[0], l0[1], l0[2], l1[0], l1[1], l1[2], p[0], p[1], p[2], s,
                           g, out)
        out[3, 0] = p[1] * out[2, 2] - p[2] * out[2, 1]
        out[3, 1] = p[2] * out[2, 0] - p[0] * out[2, 2]
        out[3, 2] = p[0] * out[2, 1] - p[1] * out[2, 0]
        return
    # an edge A-B holding the closest point (1 - t) A + t B
    if u <= tiny:
        _edge_fade_forces(l0, l1, s, vb, vc, w / (v + w), g, out)
    elif v <= tiny:
        _edge_fade_forces(l0, l1, s, va, vc, w / (u + w), g, out)
    else:
        _edge_fade_forces(l0, l1, s, va, vb, v / (u + v), g, out)


@item_kernel
def _edge_fade_forces(l0, l1, s, A, B, t, g, out):
    """-g grad s for the segment l0-l1 and the mesh edge A-B whose closest points are at s
    and t (interior): s and t solve the closest-point conditions r.d1 = r.d2 = 0, whose
    derivatives give grad s (as in ``contacts.crossing_weight_forces``); it grows like
    1 / sin^2 of the angle between them, which ``edge_face_fade`` keeps away from 0. Rows as
    in ``_mesh_fade_forces``; the body's force and torque are the reactions of the nodes'
    (s does not change when the segment and the body move or turn together)."""
    d1 = (l1[0] - l0[0], l1[1] - l0[1], l1[2] - l0[2])
    d2 = (B[0] - A[0], B[1] - A[1], B[2] - A[2])
    a11 = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    a22 = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]
    a12 = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
    det = a12 * a12 - a11 * a22
    if -det <= 1e-12 * a11 * a22:
        # parallel: s is not defined by the conditions (the fade is 0 long before)
        out[:, :] = 0.0
        return
    for c in range(3):
        r = l0[c] + s * d1[c] - A[c] - t * d2[c]
        # closest-point conditions g1 = r.d1 = 0, g2 = r.d2 = 0: their derivatives per node
        e10 = (1.0 - s) * d1[c] - r
        e11 = s * d1[c] + r
        e20 = (1.0 - s) * d2[c]
        e21 = s * d2[c]
        out[0, c] = -g * (a22 * e10 - a12 * e20) / det
        out[1, c] = -g * (a22 * e11 - a12 * e21) / det
        out[2, c] = -(out[0, c] + out[1, c])
    out[3, 0] = -(l0[1] * out[0, 2] - l0[2] * out[0, 1] + l1[1] * out[1, 2] - l1[2] * out[1, 1])
    out[3, 1] = -(l0[2] * out[0, 0] - l0[0] * out[0, 2] + l1[2] * out[1, 0] - l1[0] * out[1, 2])
    out[3, 2] = -(l0[0] * out[0, 1] - l0[1] * out[0, 0] + l1[0] * out[1, 1] - l1[1] * out[1, 0])


@njit(cache=True, inline="always")
def _dsmooth01(u):
    """Derivative of ``smoothstep`` on (0, 1), zero outside."""
    if u <= 0.0 or u >= 1.0:
        return 0.0
    return 6.0 * u * (1.0 - u)


@njit(cache=True)
def scatter_bristle_body(nd, bn, bl, bd, stats):
    """Add candidate forces to nodes and bodies (serial). ``stats`` gets [count, stored,
    dissipated, max overlap ratio, candidate index of the max]."""
    x, f, t, bi, bj = nd.x, nd.f, nd.t, bn.i, bn.j
    cs, cb, n_cand = bl.s, bl.b, bl.n[0]
    active, fc, cp, par_s = bl.active, bl.fc, bl.cp, bl.par
    energy, diss, overlap_ratio, xf = bl.energy, bl.diss, bl.ratio, bl.xf
    bpos, bf, btq = bd.pos, bd.f, bd.tq
    count = 0
    e_sto = 0.0
    e_dis = 0.0
    worst = 0.0
    worst_c = -1
    for q in range(n_cand * BSLOT):
        # an inactive slot's diss holds what its forgotten tangential spring released
        # (``clear_history``), an active one's the step's dashpot and slip work
        e_dis += diss[q]
        if active[q] == 0:
            continue
        c = q
        sg = cs[q // BSLOT]
        k = cb[q // BSLOT]
        count += 1
        Fx = fc[c, 0]
        Fy = fc[c, 1]
        Fz = fc[c, 2]
        add_segment_force(x, f, t, bi[sg], bj[sg], par_s[c], Fx, Fy, Fz, cp[c, 0], cp[c, 1],
                          cp[c, 2])
        push_body(bf, btq, k, cp[c, 0] - bpos[k, 0], cp[c, 1] - bpos[k, 1],
                  cp[c, 2] - bpos[k, 2], -Fx, -Fy, -Fz)
        if q % BSLOT == 2:
            # the fade's and taper's part of the energy gradient (``_point_fade_forces``), of
            # the slot between the nodes only (the nodes' slots have none)
            i0 = bi[sg]
            i1 = bj[sg]
            for ax in range(3):
                f[i0, ax] += xf[c, 0, ax]
                f[i1, ax] += xf[c, 1, ax]
                bf[k, ax] += xf[c, 2, ax]
                btq[k, ax] += xf[c, 3, ax]
        e_sto += energy[c]
        if overlap_ratio[c] > worst:
            worst = overlap_ratio[c]
            worst_c = c
    stats[0] = count
    stats[1] = e_sto
    stats[2] = e_dis
    stats[3] = worst
    stats[4] = worst_c // BSLOT if worst_c >= 0 else -1


@njit(cache=True, inline="always")
def _let_go(ft, k1, k2):
    """Forget the history of body pair (k1, k2) that does not touch; returns the energy it
    releases (``contact_law.clear_history``: its column 3, 0 once forgotten)."""
    released = ft[k1, k2, 3]
    for c in range(HISTORY_COLUMNS):
        ft[k1, k2, c] = 0.0
    return released


@njit(cache=True)
def body_body_contacts(bd, tb, friction, stats, dt):
    """Sphere-sphere and sphere-mesh contacts between bodies (mesh-mesh pairs are not
    computed). ``ft`` is the (K, K, ``HISTORY_COLUMNS``) contact history
    (``contact_law.contact_with_history``'s columns), per pair k1 < k2; a pair that lets go
    books what it releases; ``scratch`` a (3,) array. ``stats`` gets [count, stored,
    dissipated, max overlap ratio]."""
    bpos, bq, bv, bw, bmass, motion = bd.pos, bd.q, bd.v, bd.w, bd.mass, bd.motion
    sphere_r, watertight, body_material = bd.sphere_r, bd.watertight, bd.material
    collide, verts, tris, tnormal, tedge, pnormal = bd.collide, bd.verts, bd.tris, bd.tnormal, bd.tedge, bd.pnormal
    grid_origin, grid_cell, grid_dims = bd.grid_origin, bd.grid_cell, bd.grid_dims
    grid_base, grid_start, grid_tris = bd.grid_base, bd.grid_start, bd.grid_tris
    E, mu_table, kt_table, zeta_table, adh_table = tb.E, tb.mu, tb.kt, tb.zeta, tb.adhesion
    ft, scratch, bf, btq = bd.ft_bb, bd.scratch, bd.f, bd.tq
    nk = bpos.shape[0]
    count = 0
    e_sto = 0.0
    e_dis = 0.0
    worst = 0.0
    for k1 in range(nk):
        for k2 in range(k1 + 1, nk):
            if not (collide[k1] and collide[k2]):
                continue
            static1 = motion[k1] == FIXED or motion[k1] == KINEMATIC
            static2 = motion[k2] == FIXED or motion[k2] == KINEMATIC
            if static1 and static2:
                continue
            if sphere_r[k1] <= 0.0 and sphere_r[k2] <= 0.0:
                continue
            # a = the sphere (normal points from b to a)
            if sphere_r[k1] > 0.0:
                a = k1
                b = k2
            else:
                a = k2
                b = k1
            ra = sphere_r[a]
            if sphere_r[b] > 0.0:
                dx = bpos[a, 0] - bpos[b, 0]
                dy = bpos[a, 1] - bpos[b, 1]
                dz = bpos[a, 2] - bpos[b, 2]
                d = math.sqrt(dx * dx + dy * dy + dz * dz)
                ov = ra + sphere_r[b] - d
                if ov <= 0.0:
                    e_dis += _let_go(ft, k1, k2)
                    continue
                if d > 0.0:
                    nx, ny, nz = dx / d, dy / d, dz / d
                else:
                    nx, ny, nz = 0.0, 0.0, 1.0
                rb = sphere_r[b]
            else:
                qw, qx, qy, qz = bq[b, 0], bq[b, 1], bq[b, 2], bq[b, 3]
                scratch[0], scratch[1], scratch[2] = qrot_inv(
                    qw, qx, qy, qz, bpos[a, 0] - bpos[b, 0], bpos[a, 1] - bpos[b, 1],
                    bpos[a, 2] - bpos[b, 2])
                tri, s_, u, vv, ww, d = closest_triangle(b, scratch, scratch, ra, verts, tris, tnormal, tedge,
                                                         grid_origin, grid_cell, grid_dims,
                                                         grid_base, grid_start, grid_tris)
                if tri < 0:
                    e_dis += _let_go(ft, k1, k2)
                    continue
                p0 = verts[tris[tri, 0]]
                p1 = verts[tris[tri, 1]]
                p2 = verts[tris[tri, 2]]
                gx = scratch[0] - (u * p0[0] + vv * p1[0] + ww * p2[0])
                gy = scratch[1] - (u * p0[1] + vv * p1[1] + ww * p2[1])
                gz = scratch[2] - (u * p0[2] + vv * p1[2] + ww * p2[2])
                fnx, fny, fnz = feature_normal(tri, u, vv, ww, pnormal)
                side = gx * fnx + gy * fny + gz * fnz
                if watertight[b] and side < 0.0:
                    ov = ra + d
                    nlx, nly, nlz = fnx, fny, fnz
                else:
                    ov = ra - d
                    if ov <= 0.0:
                        e_dis += _let_go(ft, k1, k2)
                        continue
                    if d > 0.0:
                        nlx, nly, nlz = gx / d, gy / d, gz / d
                    else:
                        nlx, nly, nlz = tnormal[tri, 0], tnormal[tri, 1], tnormal[tri, 2]
                nx, ny, nz = qrot(qw, qx, qy, qz, nlx, nly, nlz)
                rb = ra
            hcp = ra - 0.5 * ov
            cx = bpos[a, 0] - nx * hcp
            cy = bpos[a, 1] - ny * hcp
            cz = bpos[a, 2] - nz * hcp
            rax, ray, raz = cx - bpos[a, 0], cy - bpos[a, 1], cz - bpos[a, 2]
            rbx, rby, rbz = cx - bpos[b, 0], cy - bpos[b, 1], cz - bpos[b, 2]
            vx = (bv[a, 0] + bw[a, 1] * raz - bw[a, 2] * ray) - (bv[b, 0] + bw[b, 1] * rbz
                                                                 - bw[b, 2] * rby)
            vy = (bv[a, 1] + bw[a, 2] * rax - bw[a, 0] * raz) - (bv[b, 1] + bw[b, 2] * rbx
                                                                 - bw[b, 0] * rbz)
            vz = (bv[a, 2] + bw[a, 0] * ray - bw[a, 1] * rax) - (bv[b, 2] + bw[b, 0] * rby
                                                                 - bw[b, 1] * rbx)
            sa = motion[a] == FIXED or motion[a] == KINEMATIC
            sb = motion[b] == FIXED or motion[b] == KINEMATIC
            if sa:
                meff = bmass[b]
            elif sb:
                meff = bmass[a]
            else:
                meff = bmass[a] * bmass[b] / (bmass[a] + bmass[b])
            m1 = body_material[a]
            m2 = body_material[b]
            kn = normal_stiffness(E[m1], ra, E[m2], rb)
            Fx, Fy, Fz, f0, f1, f2, fd, dis, sto, rel = contact_force(
                nx, ny, nz, ov, vx, vy, vz, kn, kt_table[m1, m2] * kn, mu_table[m1, m2],
                zeta_table[m1, m2], meff, ft[k1, k2, 0], ft[k1, k2, 1], ft[k1, k2, 2],
                friction, dt, ft[k1, k2, 4])
            ft[k1, k2, 0] = f0
            ft[k1, k2, 1] = f1
            ft[k1, k2, 2] = f2
            if adh_table[m1, m2] > 0.0:
                fadh, state, d_a, s_a, r_a = adhesion(
                    adh_table[m1, m2], int(ft[k1, k2, 5]), ov, vx * nx + vy * ny + vz * nz, dt)
                ft[k1, k2, 5] = state
                Fx += fadh * nx
                Fy += fadh * ny
                Fz += fadh * nz
                dis += d_a
                sto += s_a
                rel += r_a
            ft[k1, k2, 3] = rel
            ft[k1, k2, 4] = fd
            push_body(bf, btq, a, rax, ray, raz, Fx, Fy, Fz)
            push_body(bf, btq, b, rbx, rby, rbz, -Fx, -Fy, -Fz)
            count += 1
            e_sto += sto
            e_dis += dis
            worst = max(worst, ov / ra)
    stats[0] = count
    stats[1] = e_sto
    stats[2] = e_dis
    stats[3] = worst
