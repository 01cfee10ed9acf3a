"""Body-body contact between two closed triangle meshes (the chaser's hull against the debris).

Law: vertex-in-body penalty, both ways. Every vertex p of body A that lies inside the closed
(watertight) mesh of body B is pushed out along the shortest way to B's surface:

    U = 1/2 k_n d(p)^2,   F_A = -grad_p U = k_n (c - p),   F_B = -F_A, both at p,

with c the closest point of B's surface and d = |c - p| the vertex's depth; the same for B's
vertices inside A. Why this law:

* **Conservative.** U is a function of the relative pose of the two bodies only. Moving B
  rigidly moves p relative to B the opposite way, so -F_A applied at p is exactly B's part
  of -grad U (force and torque), and frictionless, undamped contact keeps the total energy
  up to leapfrog's O(dt^2) error. U and its gradient are continuous where a vertex enters
  (d = 0), so the penalty starts smoothly.
* **Momentum.** Equal and opposite forces at one point: total linear and angular momentum
  are conserved to round-off (seed appendix H found YADE losing it in clump collisions).
* **Reuses the engine's tested pieces**: the closest triangle within reach
  (``body_contacts.closest_triangle``, per-body uniform grid), the inside test by the
  feature's angle-weighted pseudo-normal (``body_contacts.feature_normal``), and the
  Cundall-Strack law of ``contact_law.contact_force`` for restitution and friction, with a
  tangential spring kept per (point, other body).

Contact points (``contact_points``): the mesh's vertices, and with the body's
``contact_spacing`` also points along its edges and inside its faces, at most that far
apart; what is said of vertices here holds for every contact point.

Stiffness (``pair_stiffness``): each point carries the body's mean share of its surface,
a disc of radius ``a = sqrt(S / (pi P))`` (S surface area, P point count); a rigid flat
punch of radius a on an elastic half-space has stiffness 2 E a, two in series give seed eq.
3.6 with both lengths a: ``k_n = 2 E1 a1 E2 a2 / (E1 a1 + E2 a2)``. It is one number per
body pair, so a box resting on a face carries its weight equally on its four corners.

Limits (docs/scene.md): only contact points are tested, so two edges crossing with no
point of either body inside the other (two boxes meeting edge to edge, crossed; a box's
face against a cylinder's side, whose vertices are on its rims) do not touch until a point
enters: a ``contact_spacing`` bounds that depth; a point pushed past the middle of the
other body (deeper than half its thickness) is pushed out of the far side. Both meshes must
be closed (watertight): an open mesh has no inside. Without a spacing, a face resting on a
face touches at the resting body's vertices only.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .bodies import FIXED, KINEMATIC, push_body
from .body_contacts import closest_triangle, deep_closest, feature_normal
from .contact_law import HISTORY_COLUMNS, adhesion, contact_force, normal_stiffness
from .jit import item_kernel
from .rotations import qrot, qrot_inv


MAX_CONTACT_POINTS = 200_000  # per body: memory (history per point and body) and cost


def contact_points(vertices: np.ndarray, triangles: np.ndarray,
                   spacing: float | None = None) -> np.ndarray:
    """The points of a body's surface (its frame) that are tested against other meshes: the
    vertices, and with a ``spacing`` (m) also points along every edge longer than it (at
    most ``spacing`` apart) and inside every triangle whose longest edge exceeds it (a
    barycentric grid of the same step). Points are fixed to the body, so the law stays
    conservative; they let a face touch where the mesh has no vertex (a box's face against a
    cylinder's side)."""
    v = np.asarray(vertices, float)
    t = np.asarray(triangles, np.int64)
    pts = [v]
    if spacing is not None and len(t):
        # a triangle of area A holds at most about 2 A / spacing^2 grid points
        estimate = len(v) + 2.0 * _area(v, t) / spacing ** 2
        if estimate > MAX_CONTACT_POINTS:
            raise ValueError(f"about {estimate:.3g} contact points (at most "
                             f"{MAX_CONTACT_POINTS}): use a spacing of at least "
                             f"{math.sqrt(2.0 * _area(v, t) / MAX_CONTACT_POINTS):.3g} m")
        edges = np.unique(np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]),
                                  axis=1), axis=0)
        for i, j in edges:
            n = math.ceil(np.linalg.norm(v[j] - v[i]) / spacing)
            if n > 1:
                f = np.arange(1, n)[:, None] / n
                pts.append(v[i] + f * (v[j] - v[i]))
        for tri in t:
            # a grid along the two edges that meet opposite the longest one, each step at
            # most ``spacing``: a long thin triangle (a cylinder's side) gets no more points
            # than its area needs
            lens = [np.linalg.norm(v[tri[(i + 2) % 3]] - v[tri[(i + 1) % 3]]) for i in range(3)]
            o = int(np.argmax(lens))
            a, b, c = v[tri[o]], v[tri[(o + 1) % 3]], v[tri[(o + 2) % 3]]
            m1 = math.ceil(np.linalg.norm(b - a) / spacing)
            m2 = math.ceil(np.linalg.norm(c - a) / spacing)
            ij = [(i / m1, j / m2) for i in range(1, m1) for j in range(1, m2)
                  if i / m1 + j / m2 < 1.0 - 1e-9]
            if ij:
                w = np.array(ij, float)
                pts.append(a + w[:, :1] * (b - a) + w[:, 1:] * (c - a))
    return np.concatenate(pts)


def point_contact_length(vertices: np.ndarray, triangles: np.ndarray, n_points: int) -> float:
    """The radius a = sqrt(S / (pi P)) of a contact point's mean share of the surface (m)."""
    v = np.asarray(vertices, float)
    t = np.asarray(triangles, np.int64)
    if n_points == 0 or len(t) == 0:
        return 0.0
    return math.sqrt(_area(v, t) / (math.pi * n_points))


def _area(v: np.ndarray, t: np.ndarray) -> float:
    return float(0.5 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]),
                                      axis=1).sum())


def pair_stiffness(E1: float, a1: float, E2: float, a2: float) -> float:
    """k_n of one vertex contact between bodies of moduli E1, E2 and vertex lengths a1, a2
    (two flat punches in series, seed eq. 3.6)."""
    return float(normal_stiffness(float(E1), float(a1), float(E2), float(a2)))


# at most this many contact points of a pair touch at once, for the automatic timestep: an
# assumption as ``timestep.BODY_CONTACTS`` is for bristles (counting every point of both
# bodies made dt 14x smaller than needed on a sampled 1.5 m hull against an upper stage);
# tests/engine/test_mesh_contact.py runs a face resting on a face with more points than
# this at the automatic dt
MESH_CONTACTS = 100


def mesh_contact_stiffness(bodies, k: int) -> float:
    """The summed normal stiffness that mesh-mesh contacts can put on body k (N/m), for the
    automatic timestep (``engine.assembly.timestep``): up to ``MESH_CONTACTS`` points of each pair
    touching at once, counted twice (two-sided rows: the partner is assumed no lighter), as
    for sphere contacts."""
    vs = bodies.point_start
    total = 0.0
    for j in range(bodies.mesh_kn.shape[0]):
        kn = float(bodies.mesh_kn[k, j])
        if kn > 0.0:
            n_contacts = min(int(vs[k + 1] - vs[k] + vs[j + 1] - vs[j]), MESH_CONTACTS)
            total += 2.0 * kn * n_contacts
    return total


def initial_overlap(bodies) -> tuple[int, float]:
    """(points inside another body, max depth / pair length) of the mesh-mesh pairs in the
    built state, by the exact inside test at any depth (``body_contacts.deep_closest``): the
    step loop only looks within the pair length of a surface, so a body built wholly inside
    another would pass unseen there."""
    bd = bodies
    count = 0
    worst = 0.0
    for a in range(bd.pos.shape[0]):
        for b in range(bd.pos.shape[0]):
            if a != b and bd.mesh_kn[a, b] > 0.0:
                n, depth = _deepest_points(a, b, bd.pos, bd.q, bd.point_start, bd.points,
                                           bd.verts, bd.tris, bd.tnormal, bd.tedge, bd.pnormal,
                                           bd.grid_origin, bd.grid_cell, bd.grid_dims,
                                           bd.grid_base, bd.grid_start, bd.grid_tris,
                                           bd.grid_side, np.zeros(3))
                count += n
                worst = max(worst, depth / bd.mesh_len[a, b])
    return count, worst


@njit(cache=True)
def _deepest_points(s, t, bpos, bq, point_start, points, verts, tris, tnormal, tedge, pnormal,
                    grid_origin, grid_cell, grid_dims, grid_base, grid_start, grid_tris,
                    grid_side, scratch):
    """(how many of body s's contact points lie inside body t, the deepest one's depth)."""
    n = 0
    deepest = 0.0
    for i in range(point_start[s], point_start[s + 1]):
        rx, ry, rz = qrot(bq[s, 0], bq[s, 1], bq[s, 2], bq[s, 3], points[i, 0], points[i, 1],
                          points[i, 2])
        scratch[0], scratch[1], scratch[2] = qrot_inv(
            bq[t, 0], bq[t, 1], bq[t, 2], bq[t, 3], bpos[s, 0] + rx - bpos[t, 0],
            bpos[s, 1] + ry - bpos[t, 1], bpos[s, 2] + rz - bpos[t, 2])
        tri, _u, _v, _w, d = deep_closest(t, scratch, 0.0, verts, tris, tnormal, tedge, pnormal,
                                          grid_origin, grid_cell, grid_dims, grid_base,
                                          grid_start, grid_tris, grid_side)
        if tri >= 0 and d > 0.0:
            n += 1
            deepest = max(deepest, d)
    return n, deepest


HIT_SIZE = 11  # a touching point: index, depth, normal (3), arms from both centres (3 + 3)


@njit(cache=True, inline="always")
def _let_go_point(ft, i, t):
    """Forget the history of point i against body t, which it does not touch; returns the
    energy it releases (``contact_law.clear_history``: column 3, 0 once forgotten)."""
    released = ft[i, t, 3]
    for c in range(HISTORY_COLUMNS):
        ft[i, t, c] = 0.0
    return released


@njit(cache=True)
def mesh_mesh_contacts(bd, tb, friction, stats, dt):
    """Point-in-body contacts of every body pair with ``pair_kn[a, b] > 0`` (set by
    ``build``: both closed meshes that collide, at least one moving). ``points`` holds each
    body's contact points (body frame), body k's from ``point_start[k]``; ``ft`` is the
    contact history per (global point, other body) (``contact_law.contact_with_history``'s
    columns), with rows only where the pairs have friction, damping or adhesion.
    The pair's n touching points are found first, then each point's damper is sized with the
    reduced mass shared among them, so that a patch of n points has the pair's damping ratio
    (with the whole mass per point, n dampers in parallel are sqrt(n) times too strong, and
    the explicit step overshoots once a face lands). Adds to ``stats`` (which the sphere
    contacts filled first): [count, stored energy, dissipated energy, max depth /
    pair_len]."""
    bpos, bq, bv, bw, bmass, motion = bd.pos, bd.q, bd.v, bd.w, bd.mass, bd.motion
    bound_r, body_material = bd.bound_r, bd.material
    point_start, points = bd.point_start, bd.points
    pair_kn, pair_len = bd.mesh_kn, bd.mesh_len
    verts, tris, tnormal, tedge, pnormal = bd.verts, bd.tris, bd.tnormal, bd.tedge, bd.pnormal
    grid_origin, grid_cell, grid_dims = bd.grid_origin, bd.grid_cell, bd.grid_dims
    grid_base, grid_start, grid_tris = bd.grid_base, bd.grid_start, bd.grid_tris
    mu_table, kt_table, zeta_table, adh_table = tb.mu, tb.kt, tb.zeta, tb.adhesion
    ft, scratch, bf, btq = bd.ft_mesh, bd.scratch, bd.f, bd.tq
    nk = bpos.shape[0]
    for a in range(nk):
        for b in range(a + 1, nk):
            kn = pair_kn[a, b]
            if kn <= 0.0:
                continue
            dx = bpos[a, 0] - bpos[b, 0]
            dy = bpos[a, 1] - bpos[b, 1]
            dz = bpos[a, 2] - bpos[b, 2]
            if dx * dx + dy * dy + dz * dz >= (bound_r[a] + bound_r[b]) ** 2:
                if ft.shape[0] > 0:
                    for s, t in ((a, b), (b, a)):
                        for i in range(point_start[s], point_start[s + 1]):
                            stats[2] += _let_go_point(ft, i, t)
                continue
            hits_a = np.empty((point_start[a + 1] - point_start[a], HIT_SIZE))
            hits_b = np.empty((point_start[b + 1] - point_start[b], HIT_SIZE))
            reach = pair_len[a, b]
            na = _find_points_in_body(a, b, reach, bpos, bq, bound_r, point_start, points, verts,
                                      tris, tnormal, tedge, pnormal, grid_origin, grid_cell,
                                      grid_dims, grid_base, grid_start, grid_tris, ft,
                                      scratch, hits_a, stats)
            nb = _find_points_in_body(b, a, reach, bpos, bq, bound_r, point_start, points, verts,
                                      tris, tnormal, tedge, pnormal, grid_origin, grid_cell,
                                      grid_dims, grid_base, grid_start, grid_tris, ft,
                                      scratch, hits_b, stats)
            if na + nb == 0:
                continue
            if motion[a] == FIXED or motion[a] == KINEMATIC:
                meff = bmass[b]
            elif motion[b] == FIXED or motion[b] == KINEMATIC:
                meff = bmass[a]
            else:
                meff = bmass[a] * bmass[b] / (bmass[a] + bmass[b])
            meff /= na + nb
            m1 = body_material[a]
            m2 = body_material[b]
            _apply_hits(a, b, na, hits_a, kn, kt_table[m1, m2] * kn, mu_table[m1, m2],
                        zeta_table[m1, m2], meff, pair_len[a, b], bv, bw, ft, friction, bf,
                        btq, stats, dt, adh_table[m1, m2])
            _apply_hits(b, a, nb, hits_b, kn, kt_table[m1, m2] * kn, mu_table[m1, m2],
                        zeta_table[m1, m2], meff, pair_len[a, b], bv, bw, ft, friction, bf,
                        btq, stats, dt, adh_table[m1, m2])


@item_kernel
def _find_points_in_body(s, t, reach, bpos, bq, bound_r, point_start, points, verts, tris,
                         tnormal, tedge, pnormal, grid_origin, grid_cell, grid_dims, grid_base,
                         grid_start, grid_tris, ft, scratch, hits, stats):
    """Body s's contact points (``contact_points``) inside body t, into ``hits`` rows
    [point, depth, outward normal (world), arm from s's centre, arm from t's centre];
    points outside forget their contact history, booking what it releases into
    ``stats[2]`` (the dissipated energy). Only points within ``reach`` (the
    pair's point length) of t's surface are looked at: the step loop stops once a point is
    half that deep (``MAX_OVERLAP_RATIO``), so none can be deeper, and a point near but
    outside costs a short search instead of one for the closest triangle at any distance
    (on a 1.5 m hull beside an upper stage sampled at 0.1 m: 914 -> 114 us per step).
    Returns how many."""
    sw, sx, sy, sz = bq[s, 0], bq[s, 1], bq[s, 2], bq[s, 3]
    tw, tx, ty, tz = bq[t, 0], bq[t, 1], bq[t, 2], bq[t, 3]
    reach2 = bound_r[t] * bound_r[t]
    n = 0
    for i in range(point_start[s], point_start[s + 1]):
        # the point in the world, then in t's frame
        rsx, rsy, rsz = qrot(sw, sx, sy, sz, points[i, 0], points[i, 1], points[i, 2])
        ex = bpos[s, 0] + rsx - bpos[t, 0]
        ey = bpos[s, 1] + rsy - bpos[t, 1]
        ez = bpos[s, 2] + rsz - bpos[t, 2]
        tri = -1
        u = v = w = d = 0.0
        if ex * ex + ey * ey + ez * ez <= reach2:
            scratch[0], scratch[1], scratch[2] = qrot_inv(tw, tx, ty, tz, ex, ey, ez)
            tri, _s, u, v, w, d = closest_triangle(t, scratch, scratch, reach, verts, tris,
                                                   tnormal, tedge, grid_origin, grid_cell, grid_dims,
                                                   grid_base, grid_start, grid_tris)
        if tri >= 0 and d > 0.0:
            va = verts[tris[tri, 0]]
            vb = verts[tris[tri, 1]]
            vc = verts[tris[tri, 2]]
            # inside: (point - closest point) against the feature's pseudo-normal
            fnx, fny, fnz = feature_normal(tri, u, v, w, pnormal)
            if ((scratch[0] - (u * va[0] + v * vb[0] + w * vc[0])) * fnx
                    + (scratch[1] - (u * va[1] + v * vb[1] + w * vc[1])) * fny
                    + (scratch[2] - (u * va[2] + v * vb[2] + w * vc[2])) * fnz) >= 0.0:
                tri = -1
        if tri < 0 or d <= 0.0:
            if ft.shape[0] > 0:
                stats[2] += _let_go_point(ft, i, t)
            continue
        va = verts[tris[tri, 0]]
        vb = verts[tris[tri, 1]]
        vc = verts[tris[tri, 2]]
        # outward: from the point to t's closest surface point (t's frame, then world)
        gx = (u * va[0] + v * vb[0] + w * vc[0] - scratch[0]) / d
        gy = (u * va[1] + v * vb[1] + w * vc[1] - scratch[1]) / d
        gz = (u * va[2] + v * vb[2] + w * vc[2] - scratch[2]) / d
        nx, ny, nz = qrot(tw, tx, ty, tz, gx, gy, gz)
        row = hits[n]
        row[0] = i
        row[1] = d
        row[2] = nx
        row[3] = ny
        row[4] = nz
        row[5] = rsx
        row[6] = rsy
        row[7] = rsz
        row[8] = ex
        row[9] = ey
        row[10] = ez
        n += 1
    return n


@item_kernel
def _apply_hits(s, t, n, hits, kn, kt, mu, zeta, meff, length, bv, bw, ft, friction, bf,
                btq, stats, dt, fa):
    """The contact forces of body s's points inside body t found by
    ``_find_points_in_body``: ``contact_force`` at each point (with ``contact_law.adhesion``
    of pull-off force ``fa`` per point where fa > 0), +F on s, -F on t, both at the point.
    Adds [count, stored, dissipated, max depth / length] to ``stats``."""
    for h in range(n):
        i = int(hits[h, 0])
        d = hits[h, 1]
        nx, ny, nz = hits[h, 2], hits[h, 3], hits[h, 4]
        rsx, rsy, rsz = hits[h, 5], hits[h, 6], hits[h, 7]
        ex, ey, ez = hits[h, 8], hits[h, 9], hits[h, 10]
        # velocity of s's material point at p relative to t's
        vx = (bv[s, 0] + bw[s, 1] * rsz - bw[s, 2] * rsy) - (bv[t, 0] + bw[t, 1] * ez
                                                             - bw[t, 2] * ey)
        vy = (bv[s, 1] + bw[s, 2] * rsx - bw[s, 0] * rsz) - (bv[t, 1] + bw[t, 2] * ex
                                                             - bw[t, 0] * ez)
        vz = (bv[s, 2] + bw[s, 0] * rsy - bw[s, 1] * rsx) - (bv[t, 2] + bw[t, 0] * ey
                                                             - bw[t, 1] * ex)
        kept = ft.shape[0] > 0  # a history: friction or damping (build_contacts)
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        fd_prev = 0.0
        if kept:
            if friction:
                f0 = ft[i, t, 0]
                f1 = ft[i, t, 1]
                f2 = ft[i, t, 2]
            fd_prev = ft[i, t, 4]
        Fx, Fy, Fz, f0, f1, f2, fd, dis, sto, rel = contact_force(
            nx, ny, nz, d, vx, vy, vz, kn, kt, mu, zeta, meff, f0, f1, f2, friction, dt,
            fd_prev)
        if fa > 0.0 and kept:
            fadh, state, d_a, s_a, r_a = adhesion(fa, int(ft[i, t, 5]), d,
                                                   vx * nx + vy * ny + vz * nz, dt)
            ft[i, t, 5] = state
            Fx += fadh * nx
            Fy += fadh * ny
            Fz += fadh * nz
            dis += d_a
            sto += s_a
            rel += r_a
        if kept:
            ft[i, t, 0] = f0
            ft[i, t, 1] = f1
            ft[i, t, 2] = f2
            ft[i, t, 3] = rel
            ft[i, t, 4] = fd
        push_body(bf, btq, s, rsx, rsy, rsz, Fx, Fy, Fz)
        push_body(bf, btq, t, ex, ey, ez, -Fx, -Fy, -Fz)
        stats[0] += 1
        stats[1] += sto
        stats[2] += dis
        if length > 0.0:
            stats[3] = max(stats[3], d / length)
