"""Closest-point queries between the engine's primitives (numba, allocation free).

Bristles are chains of capsules whose axes are segments; rigid bodies are triangle meshes.
The contact kernels therefore need, millions of times per second:

* ``segment_segment_closest(p0, p1, q0, q1) -> (s, t)``     capsule axis vs capsule axis
* ``point_triangle_closest(p, a, b, c) -> (u, v, w)``       node / sphere vs mesh face
* ``segment_triangle_closest(p0, p1, a, b, c) -> (s, u, v, w, dist)``  capsule vs mesh face
* ``segment_point_closest(p0, p1, c) -> s``                 capsule axis vs point

Conventions
-----------
* Points are float64 sequences of length 3: rows ``x[i]`` of an (N, 3) array, or 3-tuples of
  floats. Every function reads them with scalar indexing and returns tuples of floats; nothing
  allocates (no arrays are created), so they are safe to call from ``prange`` hot loops.
* A segment point is ``P(s) = p0 + s (p1 - p0)``, ``s`` in [0, 1].
* A triangle point is ``T = u a + v b + w c`` with ``u + v + w = 1`` and ``u, v, w >= 0``.
* The tolerance tests are relative, so results do not depend on the unit of length; but
  intermediate products reach the 6th power of lengths (segment-triangle parallel test), so
  accuracy holds for lengths and coordinates between ~1e-45 and ~1e45. Outside that range
  (and up to |coordinate| ~1e150) results stay finite and in range, never NaN, but may be
  inaccurate.

Tolerances (all relative, so the functions are unit-free)
---------------------------------------------------------
* ``PARALLEL_SIN2`` = 1e-16: two directions (segment/segment, or segment/triangle plane) are
  treated as parallel when sin^2 of their angle is <= 1e-16 (angle <= 1e-8 rad). Exactly
  parallel input built with rounding error gives sin^2 ~ 1e-31, far below. The midpoint
  tie-break changes the distance by at most angle x overlap length (<= 1e-8 L); above the
  threshold the general formula is used and stays exact to rounding (its parameter error grows
  like eps / angle^2, but the distance is flat along the near-parallel valley).
* ``POINT_REL2`` = 1e-30: a segment whose squared length is <= 1e-30 x (sum of the squared
  lengths involved) is treated as a point (its length is below double-precision resolution
  of the other primitive).
* ``TRI_DEG_REL`` = 1e-20: a triangle is degenerate when |ab x ac|^2 <= 1e-20 x (longest
  edge)^4, i.e. its height is below 1e-10 x its longest edge; it is then replaced by its
  longest edge (distance error <= 1e-10 x longest edge).
* ``TIE_REL`` = 1e-10: in segment-triangle, an endpoint candidate replaces an edge candidate
  only if its squared distance is smaller by more than this relative margin (plus a tiny
  absolute one), so rounding noise cannot break a parallel tie in favour of an endpoint.

Methods after C. Ericson, *Real-Time Collision Detection*, Morgan Kaufmann 2005:
§5.1.2 (point-segment), §5.1.5 (point-triangle, Voronoi regions), §5.1.9 (segment-segment),
§5.1.10 (segment-triangle candidates); the code is written from the maths, with the
parallel/degenerate tie-break rules of this engine added.
"""
from __future__ import annotations

import math

import numba

__all__ = [
    "PARALLEL_SIN2",
    "POINT_REL2",
    "TRI_DEG_REL",
    "TIE_REL",
    "dot3",
    "sub3",
    "add3",
    "cross3",
    "norm2_3",
    "dist3",
    "lerp3",
    "bary_point",
    "clamp01",
    "segment_point_closest",
    "segment_segment_closest",
    "point_triangle_closest",
    "segment_triangle_closest",
]

PARALLEL_SIN2 = 1e-16
POINT_REL2 = 1e-30
TRI_DEG_REL = 1e-20
TIE_REL = 1e-10
# absolute part of the tie margin, relative to the squared size of the primitives:
# (1e-13 x size)^2, a few ulps of a squared distance at unit scale.
_TIE_ABS = 1e-26

_jit = numba.njit(cache=True, fastmath=False)
# The closest-point routines' inner steps, inlined into their callers by numba (in its IR, before
# LLVM sees them): compiled apart, each was a call that passes its tuples through memory (numba
# does not inline a separately compiled function), and the bristle-body narrow phase's
# closest-feature search spent about a fifth of its time in those calls (body_kernel.py: box
# search 762 -> 649 ns per candidate, detumble_upper_stage's 1228 -> 982). Inlining keeps every
# operation and its order (no fastmath): the same bits. The safety nets for rounding cases
# (``_pt_edges``, ``_pt_longest_edge``) stay calls: rare, and inlined into every copy of
# ``_pt_tri`` they would lengthen the cold compile for nothing.
_jit_inline = numba.njit(cache=True, fastmath=False, inline="always")


# ----------------------------------------------------------------------------------------
# small vector helpers (accept arrays or 3-tuples, return floats or 3-tuples)
# ----------------------------------------------------------------------------------------
@_jit
def dot3(a, b):
    """Dot product a . b of two 3-vectors (arrays or tuples)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_jit
def sub3(a, b):
    """a - b as a 3-tuple."""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@_jit
def add3(a, b):
    """a + b as a 3-tuple."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@_jit
def cross3(a, b):
    """Cross product a x b as a 3-tuple."""
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


@_jit
def norm2_3(a):
    """Squared Euclidean norm |a|^2."""
    return a[0] * a[0] + a[1] * a[1] + a[2] * a[2]


@_jit
def dist3(a, b):
    """Euclidean distance |a - b|."""
    x = a[0] - b[0]
    y = a[1] - b[1]
    z = a[2] - b[2]
    return math.sqrt(x * x + y * y + z * z)


@_jit
def lerp3(p0, p1, s):
    """Point p0 + s (p1 - p0) of a segment, as a 3-tuple."""
    return (
        p0[0] + s * (p1[0] - p0[0]),
        p0[1] + s * (p1[1] - p0[1]),
        p0[2] + s * (p1[2] - p0[2]),
    )


@_jit
def bary_point(a, b, c, u, v, w):
    """Point u a + v b + w c of triangle abc, as a 3-tuple (u + v + w = 1 assumed)."""
    return (
        u * a[0] + v * b[0] + w * c[0],
        u * a[1] + v * b[1] + w * c[1],
        u * a[2] + v * b[2] + w * c[2],
    )


@_jit
def clamp01(x):
    """Clamp x to [0, 1]; NaN maps to 0 (defensive, never produced by this module)."""
    if not (x > 0.0):
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@numba.njit(cache=True, inline="always")
def row3(x, i):
    """Row ``i`` of an (n, 3) array as a float 3-tuple. Kernels pass rows this way rather
    than as array views: a view costs a reference-count increment and decrement (two atomic
    operations), which made up most of the contact kernels' time."""
    return (x[i, 0], x[i, 1], x[i, 2])


@_jit
def _t3(a):
    """Read a 3-vector (array row or tuple) into a float 3-tuple (no allocation)."""
    return (float(a[0]), float(a[1]), float(a[2]))


@_jit
def _axpy(p, s, d):
    """p + s d as a 3-tuple."""
    return (p[0] + s * d[0], p[1] + s * d[1], p[2] + s * d[2])


@_jit
def _tri_at(a, ab, ac, v, w):
    """Triangle point a + v ab + w ac (same as u a + v b + w c, better rounding near a)."""
    return (
        a[0] + v * ab[0] + w * ac[0],
        a[1] + v * ab[1] + w * ac[1],
        a[2] + v * ab[2] + w * ac[2],
    )


@_jit_inline
def _norm_bary(u, v, w):
    """Clip barycentrics to >= 0 and rescale them to sum 1 (removes rounding residue)."""
    if u < 0.0:
        u = 0.0
    if v < 0.0:
        v = 0.0
    if w < 0.0:
        w = 0.0
    tot = u + v + w
    if tot > 0.0:
        return u / tot, v / tot, w / tot
    return 1.0, 0.0, 0.0


# ----------------------------------------------------------------------------------------
# point - segment  (Ericson 2005, §5.1.2)
# ----------------------------------------------------------------------------------------
@_jit_inline
def _seg_pt(p0, d, dd, c):
    """Parameter of the point of segment p0 + s d (dd = d.d) closest to c; 0 if dd == 0."""
    if dd <= 0.0:
        return 0.0
    return clamp01(
        ((c[0] - p0[0]) * d[0] + (c[1] - p0[1]) * d[1] + (c[2] - p0[2]) * d[2]) / dd
    )


@_jit
def segment_point_closest(p0, p1, c):
    """Parameter s in [0, 1] of the point of segment p0-p1 closest to point c.

    The closest point is p0 + s (p1 - p0) with s = clamp((c - p0).d / d.d) (Ericson 2005,
    §5.1.2). A zero-length segment (p0 == p1) returns 0.0. The answer is unique otherwise.
    """
    P0 = _t3(p0)
    d = sub3(_t3(p1), P0)
    return _seg_pt(P0, d, norm2_3(d), _t3(c))


# ----------------------------------------------------------------------------------------
# segment - segment  (after Ericson 2005, §5.1.9)
# ----------------------------------------------------------------------------------------
@_jit_inline
def _seg_seg(p0, d1, q0, d2):
    """Closest parameters (s, t) of segments p0 + s d1 and q0 + t d2 (tuples)."""
    a = norm2_3(d1)
    e = norm2_3(d2)
    r = sub3(p0, q0)
    c = dot3(d1, r)
    f = dot3(d2, r)
    tiny = POINT_REL2 * (a + e)
    if a <= tiny:
        if e <= tiny:
            return 0.0, 0.0  # two points
        return 0.0, clamp01(f / e)  # point p0 vs segment 2
    if e <= tiny:
        return clamp01(-c / a), 0.0  # segment 1 vs point q0
    b = dot3(d1, d2)
    n = cross3(d1, d2)
    n2 = norm2_3(n)  # = a e - b^2, but without the cancellation
    if n2 <= PARALLEL_SIN2 * a * e:
        # Parallel / collinear: the closest set is an interval. Project segment 2 onto the
        # parameter line of segment 1 and take the midpoint of the overlap with [0, 1];
        # without overlap, the nearest ends.
        s0 = -c / a
        s1 = (b - c) / a
        lo = min(s0, s1)
        hi = max(s0, s1)
        if hi < 0.0:
            s = 0.0
        elif lo > 1.0:
            s = 1.0
        else:
            s = 0.5 * (max(lo, 0.0) + min(hi, 1.0))
        # point of segment 2 closest to P(s): the midpoint of the overlap seen from segment 2
        return s, clamp01((b * s + f) / e)
    # General position. Unconstrained line-line parameter s = (b f - c e) / (a e - b^2),
    # written with the identity (d1 x d2).(d2 x r) = b f - c e for accuracy, then clamped;
    # t follows from s and, if t had to be clamped, s is recomputed for the clamped t.
    # (Ericson's clamping order yields the exact box optimum of this convex quadratic.)
    s = clamp01(dot3(n, cross3(d2, r)) / n2)
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = clamp01(-c / a)
    elif t > 1.0:
        t = 1.0
        s = clamp01((b - c) / a)
    return s, t


@_jit
def segment_segment_closest(p0, p1, q0, q1):
    """Parameters (s, t) in [0, 1]^2 of the closest points of two segments.

    P = p0 + s (p1 - p0) and Q = q0 + t (q1 - q0) minimise |P - Q| (after Ericson 2005,
    §5.1.9). Tie-break rules, where the minimiser is not unique:

    * parallel or collinear segments (sin^2 of the angle <= PARALLEL_SIN2): s is the
      midpoint of the overlap of segment 2's projection onto segment 1 with [0, 1], and t is
      the matching point of segment 2 (the midpoint of the overlap seen from segment 2); if
      the projections do not overlap, the nearest endpoints;
    * crossing axes: the intersection point (distance 0), as in general position;
    * a zero-length segment (squared length <= POINT_REL2 x sum of squared lengths) is a
      point with parameter 0.0; two points give (0.0, 0.0).
    """
    P0 = _t3(p0)
    Q0 = _t3(q0)
    return _seg_seg(P0, sub3(_t3(p1), P0), Q0, sub3(_t3(q1), Q0))


# ----------------------------------------------------------------------------------------
# point - triangle  (after Ericson 2005, §5.1.5)
# ----------------------------------------------------------------------------------------
@_jit_inline
def _tri_longest_edge(lab, lac, lbc):
    """0: ab, 1: ac, 2: bc -- index of the longest edge (first one on ties)."""
    if lab >= lac and lab >= lbc:
        return 0
    if lac >= lbc:
        return 1
    return 2


@_jit_inline
def _edge_bary(k, t):
    """Barycentrics of parameter t on edge k (0: a->b, 1: a->c, 2: b->c)."""
    if k == 0:
        return 1.0 - t, t, 0.0
    if k == 1:
        return 1.0 - t, 0.0, t
    return 0.0, 1.0 - t, t


@_jit
def _pt_longest_edge(p, a, b, ab, ac, bc, lab, lac, lbc):
    """Closest point of p on the longest edge of a (degenerate) triangle, as barycentrics."""
    k = _tri_longest_edge(lab, lac, lbc)
    if k == 0:
        t = _seg_pt(a, ab, lab, p)
    elif k == 1:
        t = _seg_pt(a, ac, lac, p)
    else:
        t = _seg_pt(b, bc, lbc, p)
    return _edge_bary(k, t)


@_jit
def _pt_edges(p, a, b, ab, ac, bc, lab, lac, lbc):
    """Closest point of p on the boundary (three edges) of triangle abc, as barycentrics.

    Safety net for the rare rounding case where the Voronoi-region tests send a point to the
    face region although its projection is (numerically) outside the triangle.
    """
    t0 = _seg_pt(a, ab, lab, p)
    t1 = _seg_pt(a, ac, lac, p)
    t2 = _seg_pt(b, bc, lbc, p)
    d0 = norm2_3(sub3(_axpy(a, t0, ab), p))
    d1 = norm2_3(sub3(_axpy(a, t1, ac), p))
    d2 = norm2_3(sub3(_axpy(b, t2, bc), p))
    if d0 <= d1 and d0 <= d2:
        return _edge_bary(0, t0)
    if d1 <= d2:
        return _edge_bary(1, t1)
    return _edge_bary(2, t2)


@_jit_inline
def _pt_tri(p, a, b, c, ab, ac, bc, lab, lac, lbc, n, n2):
    """Barycentrics of the point of non-degenerate triangle abc closest to p.

    Voronoi-region walk of Ericson 2005, §5.1.5. The region "determinants" va, vb, vc are
    evaluated as n.(bp x cp), n.(cp x ap), n.(ap x bp) (the same numbers as Ericson's
    differences of dot products, by the Binet-Cauchy identity, with far less cancellation);
    edge parameters are divided by the exact squared edge lengths.
    """
    ap = sub3(p, a)
    d1 = dot3(ab, ap)
    d2 = dot3(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return 1.0, 0.0, 0.0  # vertex region a
    bp = sub3(p, b)
    d3 = dot3(ab, bp)
    d4 = dot3(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return 0.0, 1.0, 0.0  # vertex region b
    vc = dot3(n, cross3(ap, bp))
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = clamp01(d1 / lab)  # edge region ab
        return 1.0 - v, v, 0.0
    cp = sub3(p, c)
    d5 = dot3(ab, cp)
    d6 = dot3(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return 0.0, 0.0, 1.0  # vertex region c
    vb = dot3(n, cross3(cp, ap))
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = clamp01(d2 / lac)  # edge region ac
        return 1.0 - w, 0.0, w
    va = dot3(n, cross3(bp, cp))
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = clamp01((d4 - d3) / lbc)  # edge region bc
        return 0.0, 1.0 - w, w
    # face region: the projection of p, barycentrics = signed sub-areas / total area
    if va >= 0.0 and vb >= 0.0 and vc >= 0.0:
        tot = va + vb + vc
        if tot > 0.0:
            return va / tot, vb / tot, vc / tot
    return _pt_edges(p, a, b, ab, ac, bc, lab, lac, lbc)


@_jit_inline
def _tri_setup(a, b, c):
    """Edge vectors, squared lengths, normal, |normal|^2 and longest squared edge."""
    ab = sub3(b, a)
    ac = sub3(c, a)
    bc = sub3(c, b)
    lab = norm2_3(ab)
    lac = norm2_3(ac)
    lbc = norm2_3(bc)
    n = cross3(ab, ac)
    n2 = norm2_3(n)
    lmax = max(lab, max(lac, lbc))
    return ab, ac, bc, lab, lac, lbc, n, n2, lmax


@_jit_inline
def _pt_tri_any(p, a, b, c, ab, ac, bc, lab, lac, lbc, n, n2, lmax):
    """Point vs triangle, with the degenerate-triangle fallback."""
    if n2 <= TRI_DEG_REL * lmax * lmax:
        if lmax <= 0.0:
            return 1.0, 0.0, 0.0  # all three vertices coincide
        return _pt_longest_edge(p, a, b, ab, ac, bc, lab, lac, lbc)
    return _pt_tri(p, a, b, c, ab, ac, bc, lab, lac, lbc, n, n2)


@_jit
def point_triangle_closest(p, a, b, c):
    """Barycentrics (u, v, w) of the point of triangle abc closest to p.

    u + v + w = 1, all >= 0; the closest point is u a + v b + w c (Voronoi-region method
    after Ericson 2005, §5.1.5). The closest point of a triangle is unique, so there are no
    ties in the non-degenerate case. A degenerate triangle (|ab x ac|^2 <= TRI_DEG_REL x
    longest-edge^4: collinear, coincident or sliver vertices) is replaced by its longest edge
    (ties between equally long edges: ab, then ac, then bc); three coincident vertices give
    (1, 0, 0).
    """
    A = _t3(a)
    B = _t3(b)
    C = _t3(c)
    ab, ac, bc, lab, lac, lbc, n, n2, lmax = _tri_setup(A, B, C)
    return _pt_tri_any(_t3(p), A, B, C, ab, ac, bc, lab, lac, lbc, n, n2, lmax)


# ----------------------------------------------------------------------------------------
# segment - triangle  (candidates after Ericson 2005, §5.1.10 / §5.3.6)
# ----------------------------------------------------------------------------------------
@_jit_inline
def _seg_edge_d2(p0, d, q0, e):
    """(s, t, squared distance) between segment p0 + s d and edge q0 + t e."""
    s, t = _seg_seg(p0, d, q0, e)
    return s, t, norm2_3(sub3(_axpy(p0, s, d), _axpy(q0, t, e)))


@_jit_inline
def _clip_ge0(lo, hi, f0, df):
    """Clip [lo, hi] to the s where f0 + s df >= 0 (empty interval: lo > hi)."""
    if df > 0.0:
        r = -f0 / df
        if r > lo:
            lo = r
    elif df < 0.0:
        r = -f0 / df
        if r < hi:
            hi = r
    elif f0 < 0.0:
        lo = 1.0
        hi = 0.0
    return lo, hi


@_jit_inline
def _seg_tri(p0, p1, a, b, c):
    """Closest (s, u, v, w, dist) between segment p0-p1 and triangle abc (tuples)."""
    d = sub3(p1, p0)
    dd = norm2_3(d)
    ab, ac, bc, lab, lac, lbc, n, n2, lmax = _tri_setup(a, b, c)

    # zero-length segment: a point
    if dd <= POINT_REL2 * (dd + lmax):
        u, v, w = _pt_tri_any(p0, a, b, c, ab, ac, bc, lab, lac, lbc, n, n2, lmax)
        return 0.0, u, v, w, dist3(p0, _tri_at(a, ab, ac, v, w))

    # degenerate triangle: segment vs its longest edge
    if n2 <= TRI_DEG_REL * lmax * lmax:
        k = _tri_longest_edge(lab, lac, lbc)
        if k == 0:
            s, t = _seg_seg(p0, d, a, ab)
        elif k == 1:
            s, t = _seg_seg(p0, d, a, ac)
        else:
            s, t = _seg_seg(p0, d, b, bc)
        u, v, w = _edge_bary(k, t)
        return s, u, v, w, dist3(_axpy(p0, s, d), _tri_at(a, ab, ac, v, w))

    ap0 = sub3(p0, a)
    h0 = dot3(n, ap0)  # signed height of p0 above the plane, times |n|
    hd = dot3(n, d)  # rate of change of that height along the segment

    if hd * hd <= PARALLEL_SIN2 * dd * n2:
        # Segment parallel to the plane: every point whose projection is inside the triangle
        # is at the same distance. The unnormalised barycentrics of the projection of P(s)
        # are linear in s: U = n.(bP x cP), V = n.(cP x aP), W = n.(aP x bP).
        bp0 = sub3(p0, b)
        cp0 = sub3(p0, c)
        U0 = dot3(n, cross3(bp0, cp0))
        V0 = dot3(n, cross3(cp0, ap0))
        W0 = dot3(n, cross3(ap0, bp0))
        dU = dot3(n, cross3(bc, d))
        dV = dot3(n, cross3(d, ac))
        dW = dot3(n, cross3(ab, d))
        lo, hi = _clip_ge0(0.0, 1.0, U0, dU)
        lo, hi = _clip_ge0(lo, hi, V0, dV)
        lo, hi = _clip_ge0(lo, hi, W0, dW)
        if lo <= hi:
            s = 0.5 * (lo + hi)  # midpoint of the part lying over the triangle
            u, v, w = _norm_bary(U0 + s * dU, V0 + s * dV, W0 + s * dW)
            return s, u, v, w, dist3(_axpy(p0, s, d), _tri_at(a, ab, ac, v, w))
        # projection entirely outside: the closest points are on the boundary (below)
    else:
        h1 = h0 + hd
        if (h0 <= 0.0 and h1 >= 0.0) or (h0 >= 0.0 and h1 <= 0.0):
            # the segment crosses the plane at s = h0 / (h0 - h1); inside the triangle?
            s = clamp01(-h0 / hd)
            x = _axpy(p0, s, d)
            ax = sub3(x, a)
            bx = sub3(x, b)
            cx = sub3(x, c)
            U = dot3(n, cross3(bx, cx))
            V = dot3(n, cross3(cx, ax))
            W = dot3(n, cross3(ax, bx))
            if U >= 0.0 and V >= 0.0 and W >= 0.0:
                u, v, w = _norm_bary(U, V, W)
                return s, u, v, w, 0.0

    # No intersection: the minimum is attained by the segment against an edge, or by an
    # endpoint against the triangle. Edges first, so that a segment parallel to an edge gets
    # the midpoint-of-overlap answer; an endpoint wins only if clearly closer.
    s, t, best = _seg_edge_d2(p0, d, a, ab)
    k = 0
    s1, t1, d1 = _seg_edge_d2(p0, d, a, ac)
    if d1 < best:
        s, t, best, k = s1, t1, d1, 1
    s2, t2, d2 = _seg_edge_d2(p0, d, b, bc)
    if d2 < best:
        s, t, best, k = s2, t2, d2, 2
    u, v, w = _edge_bary(k, t)

    margin_abs = _TIE_ABS * (lmax + dd)
    ue, ve, we = _pt_tri(p0, a, b, c, ab, ac, bc, lab, lac, lbc, n, n2)
    de = norm2_3(sub3(p0, _tri_at(a, ab, ac, ve, we)))
    if de < best - (TIE_REL * best + margin_abs):
        s, u, v, w, best = 0.0, ue, ve, we, de
    ue, ve, we = _pt_tri(p1, a, b, c, ab, ac, bc, lab, lac, lbc, n, n2)
    de = norm2_3(sub3(p1, _tri_at(a, ab, ac, ve, we)))
    if de < best - (TIE_REL * best + margin_abs):
        s, u, v, w, best = 1.0, ue, ve, we, de
    return s, u, v, w, math.sqrt(best)


@_jit
def segment_triangle_closest(p0, p1, a, b, c):
    """Closest points between segment p0-p1 and triangle abc: (s, u, v, w, dist).

    P = p0 + s (p1 - p0), T = u a + v b + w c, dist = |P - T| (candidates after Ericson 2005,
    §5.1.10). Tie-break rules, where the minimiser is not unique:

    * segment crossing the triangle: the crossing point, dist = 0.0 exactly;
    * segment parallel to the triangle's plane (sin^2 of the angle <= PARALLEL_SIN2) whose
      projection lies (partly) inside the triangle, including a segment lying in the face:
      s is the midpoint of the s-interval whose projection is inside (the three edge
      half-planes clip [0, 1]), T is the projection of P(s);
    * otherwise the segment vs the three edges (ab, ac, bc; each with the segment-segment
      rules, so a segment parallel to an edge gets the midpoint of the overlap) and each
      endpoint vs the triangle; an endpoint replaces an edge answer only if its squared
      distance is smaller by more than TIE_REL (relative);
    * zero-length segment: s = 0.0 and the point-triangle answer;
    * degenerate triangle (see point_triangle_closest): the segment vs its longest edge.
    """
    return _seg_tri(_t3(p0), _t3(p1), _t3(a), _t3(b), _t3(c))
