"""Tests of engine/kernels/geometry.py: closest points of segments, points and triangles.

References are independent of the module: dense sampling of the parameter domain followed by a
bounded scipy minimisation of the squared distance from the best sample. The squared distance
is a convex quadratic in the parameters (segment parameter s, barycentrics v, w), so the local
minimum the optimiser finds is the global one; the sample only makes the start good.
"""
from __future__ import annotations

import importlib.util
import math
import pathlib

import numba
import numpy as np
import pytest
from scipy.optimize import minimize

try:
    from engine.kernels import geometry as geo
except Exception:  # engine/__init__.py (written by others) may not import yet
    # Load the file alone, registered under its real name: numba's on-disk cache refers to
    # the module as "engine.kernels.geometry" and re-imports it by that name when loading.
    import sys

    _path = pathlib.Path(__file__).resolve().parents[2] / "engine" / "kernels" / "geometry.py"
    _spec = importlib.util.spec_from_file_location("engine.kernels.geometry", _path)
    geo = importlib.util.module_from_spec(_spec)
    sys.modules["engine.kernels.geometry"] = geo
    _spec.loader.exec_module(geo)


RNG_SEED = 20240611
# Hand-computed cases use O(1) numbers and a handful of operations, each rounding by at
# most 1.1e-16 (half an ulp of 1): 1e-15 allows ~9 roundings; any logic error is >= 1e-3.
EXACT = 1e-15


# ------------------------------------------------------------------------------------------
# brute-force references
# ------------------------------------------------------------------------------------------
def ref_seg_seg(p0, p1, q0, q1, n=41):
    """Minimum distance of two segments: 41x41 grid of (s, t), then SLSQP on [0,1]^2."""
    d1, d2 = p1 - p0, q1 - q0
    g = np.linspace(0.0, 1.0, n)
    P = p0 + g[:, None] * d1
    Q = q0 + g[:, None] * d2
    D2 = ((P[:, None, :] - Q[None, :, :]) ** 2).sum(-1)
    i, j = np.unravel_index(np.argmin(D2), D2.shape)

    def f(x):
        r = p0 + x[0] * d1 - q0 - x[1] * d2
        return r @ r, np.array([2.0 * (r @ d1), -2.0 * (r @ d2)])

    res = minimize(f, [g[i], g[j]], jac=True, method="SLSQP", bounds=[(0, 1), (0, 1)],
                   options=dict(ftol=1e-16, maxiter=500))
    return math.sqrt(max(0.0, min(res.fun, D2[i, j])))


def _tri_lattice(m):
    """Barycentric lattice (v, w) with v, w >= 0, v + w <= 1, spacing 1/m."""
    vv, ww = np.meshgrid(np.arange(m + 1) / m, np.arange(m + 1) / m, indexing="ij")
    keep = vv + ww <= 1.0 + 1e-12  # k/m + j/m == 1 may round above 1 by an ulp
    return vv[keep], ww[keep]


def ref_seg_tri(p0, p1, a, b, c, ns=17, m=24):
    """Minimum distance of segment p0-p1 and triangle abc (p0 == p1: point vs triangle).

    Dense sampling of s (ns values) x barycentric lattice (spacing 1/m), then SLSQP on
    (s, v, w) with bounds [0,1]^3 and the linear constraint v + w <= 1 (a convex QP).
    """
    d, ab, ac = p1 - p0, b - a, c - a
    s = np.linspace(0.0, 1.0, ns)
    v, w = _tri_lattice(m)
    P = p0 + s[:, None] * d
    T = a + v[:, None] * ab + w[:, None] * ac
    D2 = ((P[:, None, :] - T[None, :, :]) ** 2).sum(-1)
    i, j = np.unravel_index(np.argmin(D2), D2.shape)

    def f(x):
        r = p0 + x[0] * d - a - x[1] * ab - x[2] * ac
        return r @ r, np.array([2.0 * (r @ d), -2.0 * (r @ ab), -2.0 * (r @ ac)])

    cons = [dict(type="ineq", fun=lambda x: 1.0 - x[1] - x[2],
                 jac=lambda x: np.array([0.0, -1.0, -1.0]))]
    res = minimize(f, [s[i], v[j], w[j]], jac=True, method="SLSQP", bounds=[(0, 1)] * 3,
                   constraints=cons, options=dict(ftol=1e-16, maxiter=500))
    best = D2[i, j]
    x = res.x
    # accept the optimiser's point only if feasible; 1e-12 tolerates SLSQP's bound rounding
    # (a violation that small moves the distance by <= ~1e-12, far below the test tolerances)
    if x.min() >= -1e-12 and x.max() <= 1 + 1e-12 and x[1] + x[2] <= 1 + 1e-12:
        best = min(best, res.fun)
    return math.sqrt(max(0.0, best))


def ref_point_segment(p, a, b):
    """Distance from p to segment ab (closed form, clamped projection)."""
    d = b - a
    dd = d @ d
    t = 0.0 if dd == 0.0 else min(1.0, max(0.0, (p - a) @ d / dd))
    return float(np.linalg.norm(a + t * d - p))


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------
def seg_pt(p0, p1, s):
    return p0 + s * (p1 - p0)


def tri_pt(a, b, c, u, v, w):
    return u * a + v * b + w * c


def check_bary(u, v, w):
    """Barycentrics are finite, in [0, 1] and sum to 1."""
    assert all(math.isfinite(x) for x in (u, v, w))
    assert min(u, v, w) >= 0.0 and max(u, v, w) <= 1.0
    # sum of three doubles after one normalisation: a few ulps
    assert abs(u + v + w - 1.0) <= 1e-14


def check_param(s):
    assert math.isfinite(s) and 0.0 <= s <= 1.0


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


A = np.array([0.0, 0.0, 0.0])
B = np.array([1.0, 0.0, 0.0])
C = np.array([0.0, 1.0, 0.0])


def v3(*x):
    return np.array(x, dtype=np.float64)


# ------------------------------------------------------------------------------------------
# helpers of the module
# ------------------------------------------------------------------------------------------
def test_small_helpers():
    a, b = v3(1.0, 2.0, 3.0), v3(-4.0, 0.5, 2.0)
    assert geo.dot3(a, b) == float(a @ b)
    assert geo.cross3(a, b) == tuple(np.cross(a, b))
    assert geo.sub3(a, b) == tuple(a - b)
    assert geo.add3(a, b) == tuple(a + b)
    assert geo.norm2_3(a) == float(a @ a)
    # one sqrt of an exactly representable sum: exact
    assert geo.dist3(a, b) == math.sqrt(float((a - b) @ (a - b)))
    assert geo.lerp3(a, b, 0.25) == tuple(a + 0.25 * (b - a))
    assert geo.bary_point(a, b, A, 0.5, 0.5, 0.0) == tuple(0.5 * a + 0.5 * b)
    assert (geo.clamp01(-1.0), geo.clamp01(0.3), geo.clamp01(7.0)) == (0.0, 0.3, 1.0)
    assert geo.clamp01(float("nan")) == 0.0
    # works on rows of an (N, 3) array (the engine's calling convention)
    x = np.stack([a, b])
    assert geo.dot3(x[0], x[1]) == float(a @ b)


# ------------------------------------------------------------------------------------------
# segment - point
# ------------------------------------------------------------------------------------------
def test_segment_point():
    assert geo.segment_point_closest(A, B, v3(0.25, 3.0, -1.0)) == 0.25
    assert geo.segment_point_closest(A, B, v3(-2.0, 1.0, 0.0)) == 0.0
    assert geo.segment_point_closest(A, B, v3(5.0, 1.0, 0.0)) == 1.0
    assert geo.segment_point_closest(C, C, v3(5.0, 1.0, 0.0)) == 0.0  # degenerate
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(100):
        p0, p1, c = rng.uniform(-1, 1, size=(3, 3))
        s = geo.segment_point_closest(p0, p1, c)
        check_param(s)
        g = np.linspace(0, 1, 2001)
        dense = np.linalg.norm(p0 + g[:, None] * (p1 - p0) - c, axis=1).min()
        d = np.linalg.norm(seg_pt(p0, p1, s) - c)
        # the answer is the minimum, so no sample of the segment may beat it; distances of
        # O(1) points are exact to a few ulps (1e-15), 1e-14 is the margin
        assert d <= dense + 1e-14
        # and it agrees with an independent closed form (numpy) to the same rounding
        assert abs(d - ref_point_segment(c, p0, p1)) <= 1e-14


# ------------------------------------------------------------------------------------------
# segment - segment
# ------------------------------------------------------------------------------------------
def _ss_dist(p0, p1, q0, q1):
    s, t = geo.segment_segment_closest(p0, p1, q0, q1)
    check_param(s)
    check_param(t)
    return s, t, float(np.linalg.norm(seg_pt(p0, p1, s) - seg_pt(q0, q1, t)))


def test_segment_segment_random_vs_bruteforce():
    rng = np.random.default_rng(RNG_SEED)
    worst = 0.0
    for k in range(300):
        p0, p1, q0, q1 = rng.uniform(-1, 1, size=(4, 3))
        if k % 3 == 1:  # short segment vs long one: clamping of one parameter
            p1 = p0 + 0.05 * (p1 - p0)
        if k % 3 == 2:  # nearly touching: small distances
            q0 = seg_pt(p0, p1, rng.uniform()) + 0.01 * rng.normal(size=3)
        s, t, d = _ss_dist(p0, p1, q0, q1)
        dref = ref_seg_seg(p0, p1, q0, q1)
        worst = max(worst, abs(d - dref))
        # SLSQP solves this 2-variable QP to ~1e-14 in distance (measured 7e-15); a wrong
        # branch or clamping error changes the distance by >= 1e-4 in these configurations
        assert abs(d - dref) <= 1e-9, (k, d, dref)
        # symmetric problem, same distance with the roles swapped (rounding only)
        t2, s2 = geo.segment_segment_closest(q0, q1, p0, p1)
        d2 = np.linalg.norm(seg_pt(p0, p1, s2) - seg_pt(q0, q1, t2))
        assert abs(d2 - d) <= 1e-12  # both exact to ~1e-15; unique minimiser here


def ref_seg_seg_1d(p0, p1, q0, q1, n=201):
    """Minimum distance of two segments as a 1-D convex problem (independent of the 2-D one).

    g(s) = distance from p0 + s d1 to segment q0-q1 (closed form) is convex in s: sample it,
    then bounded Brent search (xatol 1e-14) in the bracket around the best sample. No
    ill-conditioning for near-parallel segments, unlike the 2-D optimiser in a flat valley.
    """
    from scipy.optimize import minimize_scalar

    d1 = p1 - p0

    def g(s):
        return ref_point_segment(p0 + s * d1, q0, q1)

    grid = np.linspace(0.0, 1.0, n)
    vals = [g(s) for s in grid]
    i = int(np.argmin(vals))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, n - 1)]
    res = minimize_scalar(g, bounds=(lo, hi), method="bounded", options=dict(xatol=1e-14))
    return min(vals[i], res.fun, g(lo), g(hi))


@pytest.mark.parametrize("angle", [1e-2, 1e-4, 1e-6, 1e-7, 2e-8, 1e-8, 1e-9, 1e-10, 1e-12, 1e-14])
def test_segment_segment_near_parallel_distances(angle):
    """Across the parallel threshold (sin^2 = 1e-16, angle 1e-8) the distance stays right."""
    rng = np.random.default_rng(RNG_SEED + 1)
    for _ in range(20):
        R = random_rotation(rng)
        off = rng.uniform(-1, 1, 3)
        p0, p1 = v3(0, 0, 0), v3(1, 0, 0)
        q0 = v3(rng.uniform(-0.5, 0.8), 0.02, 0.01)
        q1 = q0 + v3(math.cos(angle), math.sin(angle) * 0.6, math.sin(angle) * 0.8)
        p0, p1, q0, q1 = (R @ x + off for x in (p0, p1, q0, q1))
        _, _, d = _ss_dist(p0, p1, q0, q1)
        dref = ref_seg_seg_1d(p0, p1, q0, q1)
        # both sides are exact to rounding (~1e-16 at unit size; measured <1e-16): 1e-13
        assert d >= dref - 1e-13, (angle, d, dref)
        if angle > 1.0001e-8:  # general formula: exact
            assert d <= dref + 1e-13, (angle, d, dref)
        else:  # midpoint tie-break: costs at most angle x overlap length (<= 1 here)
            assert d <= dref + angle * 1.0 + 1e-13, (angle, d, dref)


def test_segment_segment_parallel_side_by_side_midpoint():
    p0, p1 = v3(0, 0, 0), v3(2, 0, 0)
    # overlap of the projections is x in [1, 2]: midpoint x = 1.5
    s, t, d = _ss_dist(p0, p1, v3(1, 1, 0), v3(4, 1, 0))
    assert (s, t) == pytest.approx((0.75, 1.0 / 6.0), abs=EXACT)
    assert d == pytest.approx(1.0, abs=EXACT)
    # reversed second segment: same point, t measured from the other end
    s, t, d = _ss_dist(p0, p1, v3(4, 1, 0), v3(1, 1, 0))
    assert (s, t) == pytest.approx((0.75, 5.0 / 6.0), abs=EXACT)
    # second segment covers the first: overlap is the whole first segment
    s, t, d = _ss_dist(p0, p1, v3(-1, 0, 1), v3(3, 0, 1))
    assert (s, t) == pytest.approx((0.5, 0.5), abs=EXACT)
    # first covers second
    s, t, d = _ss_dist(p0, p1, v3(0.5, 0.3, 0.4), v3(1.0, 0.3, 0.4))
    assert (s, t) == pytest.approx((0.375, 0.5), abs=EXACT)
    assert d == pytest.approx(0.5, abs=EXACT)


def test_segment_segment_parallel_midpoint_survives_rotation():
    """Rounding from a rotation/translation must not break the parallel tie."""
    rng = np.random.default_rng(RNG_SEED + 2)
    for _ in range(50):
        R = random_rotation(rng)
        off = rng.uniform(-10, 10, 3)
        pts = [R @ x + off for x in (v3(0, 0, 0), v3(2, 0, 0), v3(1, 0.1, 0), v3(4, 0.1, 0))]
        s, t, d = _ss_dist(*pts)
        # exact answer (0.75, 1/6); rounding of |coords| ~ 10 gives ~1e-15 errors, and the
        # parameter formulas divide by lengths ~1: 1e-12 is a wide margin
        assert (s, t) == pytest.approx((0.75, 1.0 / 6.0), abs=1e-12)
        assert d == pytest.approx(0.1, abs=1e-12)


def test_segment_segment_collinear():
    p0, p1 = v3(0, 0, 0), v3(2, 0, 0)
    # overlapping: overlap x in [1, 2]
    s, t, d = _ss_dist(p0, p1, v3(1, 0, 0), v3(5, 0, 0))
    assert (s, t, d) == pytest.approx((0.75, 0.125, 0.0), abs=EXACT)
    # identical segments: the middle
    s, t, d = _ss_dist(p0, p1, p0, p1)
    assert (s, t, d) == pytest.approx((0.5, 0.5, 0.0), abs=EXACT)
    # disjoint, after the end: nearest endpoints p1 and q0
    s, t, d = _ss_dist(p0, p1, v3(3, 0, 0), v3(5, 0, 0))
    assert (s, t, d) == pytest.approx((1.0, 0.0, 1.0), abs=EXACT)
    s, t, d = _ss_dist(p0, p1, v3(5, 0, 0), v3(3, 0, 0))
    assert (s, t, d) == pytest.approx((1.0, 1.0, 1.0), abs=EXACT)
    # disjoint, before the start
    s, t, d = _ss_dist(p0, p1, v3(-3, 0, 0), v3(-1, 0, 0))
    assert (s, t, d) == pytest.approx((0.0, 1.0, 1.0), abs=EXACT)
    # parallel but offset and disjoint: nearest endpoints
    s, t, d = _ss_dist(p0, p1, v3(3, 1, 0), v3(5, 1, 0))
    assert (s, t, d) == pytest.approx((1.0, 0.0, math.sqrt(2.0)), abs=EXACT)
    # touching at one point: the shared endpoint
    s, t, d = _ss_dist(p0, p1, v3(2, 0, 0), v3(3, 0, 0))
    assert (s, t, d) == pytest.approx((1.0, 0.0, 0.0), abs=EXACT)


def test_segment_segment_crossing_axes():
    s, t, d = _ss_dist(v3(-1, 0, 0), v3(1, 0, 0), v3(0, -1, 0), v3(0, 1, 0))
    assert (s, t, d) == (0.5, 0.5, 0.0)  # exact in binary
    # T junction: crossing at an endpoint of one segment
    s, t, d = _ss_dist(v3(-1, 0, 0), v3(1, 0, 0), v3(0, 0, 0), v3(0, 1, 0))
    assert (s, t, d) == (0.5, 0.0, 0.0)
    # generic crossing at a chosen point
    rng = np.random.default_rng(RNG_SEED + 3)
    for _ in range(50):
        x = rng.uniform(-1, 1, 3)
        d1, d2 = rng.normal(size=(2, 3))
        s0, t0 = rng.uniform(0.05, 0.95, 2)
        p0, p1 = x - s0 * d1, x + (1 - s0) * d1
        q0, q1 = x - t0 * d2, x + (1 - t0) * d2
        s, t, d = _ss_dist(p0, p1, q0, q1)
        # crossing point recovered to rounding; conditioning 1/sin(angle) ~ up to 1e2 here
        assert (s, t) == pytest.approx((s0, t0), abs=1e-10)
        assert d <= 1e-14  # rounding of coordinates of size ~1


def test_segment_segment_degenerate():
    p0, p1 = v3(0, 0, 0), v3(2, 0, 0)
    c = v3(0.5, 1.0, 0.0)
    # zero-length first segment: a point, s = 0, t = projection
    s, t, d = _ss_dist(c, c, p0, p1)
    assert (s, t, d) == pytest.approx((0.0, 0.25, 1.0), abs=EXACT)
    s, t, d = _ss_dist(p0, p1, c, c)
    assert (s, t, d) == pytest.approx((0.25, 0.0, 1.0), abs=EXACT)
    s, t, d = _ss_dist(c, c, p1, p1)
    assert (s, t) == (0.0, 0.0)
    assert d == pytest.approx(math.hypot(1.5, 1.0), abs=EXACT)
    # both points coincide
    assert geo.segment_segment_closest(c, c, c, c) == (0.0, 0.0)
    # a segment far below resolution of the other one behaves as a point
    tiny = c + v3(1e-20, 0, 0)
    s, t, d = _ss_dist(c, tiny, p0, p1)
    assert s == 0.0 and d == pytest.approx(1.0, abs=EXACT)


def test_segment_segment_never_nan():
    rng = np.random.default_rng(RNG_SEED + 4)
    for scale in (1e-150, 1e-100, 1e-20, 1.0, 1e20, 1e100, 1e140):
        for _ in range(20):
            p0, p1, q0, q1 = rng.normal(size=(4, 3)) * scale
            cases = [
                (p0, p1, q0, q1),
                (p0, p0, q0, q1),
                (p0, p0, q0, q0),
                (p0, p1, p0, p1),  # identical
                (p0, p1, p1, p0),  # reversed identical
                (p0, p1, p0 + (p1 - p0) * 1e-300, p1),
                (p0, p0 + 1e-300, q0, q1),  # denormal-size direction
            ]
            for args in cases:
                s, t = geo.segment_segment_closest(*args)
                check_param(s)
                check_param(t)


# ------------------------------------------------------------------------------------------
# point - triangle
# ------------------------------------------------------------------------------------------
def _pt_dist(p, a, b, c):
    u, v, w = geo.point_triangle_closest(p, a, b, c)
    check_bary(u, v, w)
    return u, v, w, float(np.linalg.norm(tri_pt(a, b, c, u, v, w) - p))


def test_point_triangle_random_vs_bruteforce():
    rng = np.random.default_rng(RNG_SEED + 5)
    for k in range(300):
        a, b, c = rng.uniform(-1, 1, size=(3, 3))
        p = rng.uniform(-1.5, 1.5, 3)
        if k % 2:  # half the points near the plane, over or near the face
            p = tri_pt(a, b, c, *rng.dirichlet([1, 1, 1]) * 1.2 - 0.0667) + 0.05 * rng.normal(size=3)
        u, v, w, d = _pt_dist(p, a, b, c)
        dref = ref_seg_tri(p, p, a, b, c, ns=1)
        # SLSQP solves this QP to ~1e-13 in distance (measured 2e-14); wrong-region or
        # projection errors are >= 1e-4 here
        assert abs(d - dref) <= 1e-9, (k, d, dref)


def test_point_triangle_regions():
    cases = [
        (v3(0.2, 0.3, 5.0), (0.5, 0.2, 0.3), 5.0),  # face
        (v3(0.2, 0.3, -2.0), (0.5, 0.2, 0.3), 2.0),  # face, below
        (v3(0.2, 0.3, 0.0), (0.5, 0.2, 0.3), 0.0),  # in the face
        (v3(-1.0, -1.0, 2.0), (1.0, 0.0, 0.0), 6 ** 0.5),  # vertex a
        (v3(2.0, -0.5, 1.0), (0.0, 1.0, 0.0), 1.5),  # vertex b
        (v3(-0.3, 2.0, 1.0), (0.0, 0.0, 1.0), math.sqrt(0.09 + 1 + 1)),  # vertex c
        (v3(0.5, -1.0, 1.0), (0.5, 0.5, 0.0), math.sqrt(2.0)),  # edge ab
        (v3(-1.0, 0.4, 3.0), (0.6, 0.0, 0.4), math.sqrt(10.0)),  # edge ac
        (v3(1.0, 1.0, 2.0), (0.0, 0.5, 0.5), math.sqrt(4.5)),  # edge bc
        (v3(1.0, 0.0, 7.0), (0.0, 1.0, 0.0), 7.0),  # exactly above vertex b
        (v3(0.5, 0.0, 1.0), (0.5, 0.5, 0.0), 1.0),  # exactly above edge ab
    ]
    for p, bary, dist in cases:
        u, v, w, d = _pt_dist(p, A, B, C)
        # hand-computed answers; the arithmetic is exact up to a couple of roundings
        assert (u, v, w) == pytest.approx(bary, abs=EXACT), p
        assert d == pytest.approx(dist, abs=1e-14), p  # EXACT, plus sqrt of values up to 10
    # vertex order does not matter for the point found
    p = v3(1.0, 1.0, 2.0)
    u, v, w, d = _pt_dist(p, C, A, B)
    assert tri_pt(C, A, B, u, v, w) == pytest.approx(v3(0.5, 0.5, 0.0), abs=EXACT)


def test_point_triangle_degenerate():
    # collinear vertices: the longest edge is a-c
    a, b, c = v3(0, 0, 0), v3(1, 0, 0), v3(3, 0, 0)
    u, v, w, d = _pt_dist(v3(2, 1, 0), a, b, c)
    assert (u, v, w) == pytest.approx((1 / 3, 0.0, 2 / 3), abs=EXACT)
    assert d == pytest.approx(1.0, abs=EXACT)
    u, v, w, d = _pt_dist(v3(5, 0, 1), a, b, c)
    assert d == pytest.approx(math.sqrt(5.0), abs=EXACT)
    # two coincident vertices
    a, b, c = v3(0, 0, 0), v3(0, 0, 0), v3(0, 0, 2)
    u, v, w, d = _pt_dist(v3(1, 0, 1), a, b, c)
    assert d == pytest.approx(1.0, abs=EXACT)
    # three coincident vertices: a point
    u, v, w, d = _pt_dist(v3(1, 2, 2), a, a, a)
    assert (u, v, w) == (1.0, 0.0, 0.0) and d == pytest.approx(3.0, abs=EXACT)
    # sliver of relative area 1e-20: distances to the segment [0,1] on x
    a, b, c = v3(0, 0, 0), v3(1, 0, 0), v3(0.5, 1e-20, 0)
    for p, dist in [(v3(0.5, 0.0, 1.0), 1.0), (v3(2.0, 0.0, 0.0), 1.0), (v3(0.3, -0.4, 0), 0.4)]:
        u, v, w, d = _pt_dist(p, a, b, c)
        # the shape differs from its longest edge by 1e-20; distances are O(1)
        assert d == pytest.approx(dist, abs=EXACT), p


@pytest.mark.parametrize("height", [1e-30, 1e-20, 1e-12, 1e-10, 1e-9, 1e-6, 1e-3])
def test_point_triangle_slivers_random(height):
    """Thin triangles on both sides of the degeneracy threshold (height 1e-10 x edge)."""
    rng = np.random.default_rng(RNG_SEED + 6)
    for _ in range(25):
        R = random_rotation(rng)
        off = rng.uniform(-1, 1, 3)
        a, b, c = (R @ x + off for x in (v3(0, 0, 0), v3(1, 0, 0), v3(rng.uniform(-0.2, 1.2), height, 0)))
        p = R @ (v3(rng.uniform(-0.5, 1.5), rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3))) + off
        u, v, w, d = _pt_dist(p, a, b, c)
        # Every point of the triangle is within `height` of its boundary (the union of the
        # edges, closed forms), and every point of the boundary is within `height` of the
        # longest edge used for degenerate triangles; 1e-12 absorbs coordinate rounding.
        dshape = min(ref_point_segment(p, a, b), ref_point_segment(p, a, c), ref_point_segment(p, b, c))
        assert d <= dshape + height + 1e-12
        assert d >= dshape - height - 1e-12
        dref = ref_seg_tri(p, p, a, b, c, ns=1)
        # SLSQP on a thin triangle (nearly singular QP) stalls at up to ~1e-9 (measured 7e-10
        # at height 1e-9), plus the longest-edge fallback's `height`
        assert abs(d - dref) <= 1e-8 + height, (height, d, dref)


# ------------------------------------------------------------------------------------------
# segment - triangle
# ------------------------------------------------------------------------------------------
def _st(p0, p1, a, b, c):
    s, u, v, w, dist = geo.segment_triangle_closest(p0, p1, a, b, c)
    check_param(s)
    check_bary(u, v, w)
    d = float(np.linalg.norm(seg_pt(p0, p1, s) - tri_pt(a, b, c, u, v, w)))
    # returned distance agrees with the returned points (0.0 exactly on crossing): the two
    # evaluations round differently, by a few ulps of the largest coordinate
    size = max(1.0, *(float(np.abs(x).max()) for x in (p0, p1, a, b, c)))
    assert abs(dist - d) <= 1e-14 * size, (dist, d)
    return s, u, v, w, dist


def test_segment_triangle_random_vs_bruteforce():
    rng = np.random.default_rng(RNG_SEED + 7)
    zero = 0
    for k in range(200):
        a, b, c = rng.uniform(-1, 1, size=(3, 3))
        p0, p1 = rng.uniform(-1.5, 1.5, size=(2, 3))
        if k % 4 == 1:  # short segments near the face
            m = tri_pt(a, b, c, *rng.dirichlet([1, 1, 1]))
            p0 = m + 0.1 * rng.normal(size=3)
            p1 = p0 + 0.2 * rng.normal(size=3)
        s, u, v, w, d = _st(p0, p1, a, b, c)
        zero += d == 0.0
        dref = ref_seg_tri(p0, p1, a, b, c)
        # SLSQP stops at squared distance ~1e-16 (ftol), i.e. distance ~1e-8 (measured 7e-9)
        # when the true distance is 0; elsewhere it is good to ~1e-14 (measured 2e-15).
        # Misclassified candidates cost >= 1e-4 here.
        assert abs(d - dref) <= (1e-7 if d == 0.0 else 1e-9), (k, d, dref)
    assert zero >= 10  # the sample really contains crossing segments


def test_segment_triangle_piercing():
    s, u, v, w, d = _st(v3(0.2, 0.3, 1.0), v3(0.2, 0.3, -3.0), A, B, C)
    assert (s, u, v, w, d) == pytest.approx((0.25, 0.5, 0.2, 0.3, 0.0), abs=EXACT)
    assert d == 0.0
    # oblique
    x = v3(0.1, 0.6, 0.0)
    dirn = v3(0.3, -0.2, 0.7)
    s, u, v, w, d = _st(x - 0.3 * dirn, x + 0.7 * dirn, A, B, C)
    assert (s, u, v, w) == pytest.approx((0.3, 0.3, 0.1, 0.6), abs=EXACT)
    assert d == 0.0
    # ending exactly on the face
    s, u, v, w, d = _st(v3(0.2, 0.3, 1.0), v3(0.2, 0.3, 0.0), A, B, C)
    assert (s, d) == (1.0, 0.0)


def test_segment_triangle_flat_on_face_midpoint():
    # segment x in [0.1, 0.9] at y = 0.2, z = 0.5: the part over the triangle is x in
    # [0.1, 0.8], its midpoint x = 0.45 -> s = 0.35 / 0.8
    for z in (0.5, -0.5, 0.0):
        s, u, v, w, d = _st(v3(0.1, 0.2, z), v3(0.9, 0.2, z), A, B, C)
        assert s == pytest.approx(0.4375, abs=EXACT)
        assert (u, v, w) == pytest.approx((0.35, 0.45, 0.2), abs=EXACT)
        assert d == pytest.approx(abs(z), abs=EXACT)
    # crossing the whole triangle: inside part x in [0, 0.8] of x in [-1, 2]
    s, u, v, w, d = _st(v3(-1, 0.2, 0.5), v3(2, 0.2, 0.5), A, B, C)
    assert s == pytest.approx(1.4 / 3.0, abs=EXACT)
    assert (u, v, w) == pytest.approx((0.4, 0.4, 0.2), abs=EXACT)
    # fully inside: the middle of the segment
    s, u, v, w, d = _st(v3(0.1, 0.1, 0.5), v3(0.3, 0.1, 0.5), A, B, C)
    assert s == pytest.approx(0.5, abs=EXACT)
    # reversed direction: same point
    s, u, v, w, d = _st(v3(0.9, 0.2, 0.5), v3(0.1, 0.2, 0.5), A, B, C)
    assert s == pytest.approx(1 - 0.4375, abs=EXACT)
    assert (u, v, w) == pytest.approx((0.35, 0.45, 0.2), abs=EXACT)


def test_segment_triangle_flat_other_directions():
    # along y at x = 0.1: inside part y in [0, 0.9] of y in [-0.2, 1.2]
    s, u, v, w, d = _st(v3(0.1, -0.2, 0.5), v3(0.1, 1.2, 0.5), A, B, C)
    assert s == pytest.approx(0.65 / 1.4, abs=EXACT)
    assert (u, v, w, d) == pytest.approx((0.45, 0.1, 0.45, 0.5), abs=EXACT)
    # diagonal (-0.2,-0.1) + t (1,1): x >= 0 -> t >= 0.2, x + y <= 1 -> t <= 0.65
    s, u, v, w, d = _st(v3(-0.2, -0.1, -0.25), v3(0.8, 0.9, -0.25), A, B, C)
    assert s == pytest.approx(0.425, abs=EXACT)
    assert (u, v, w, d) == pytest.approx((0.45, 0.225, 0.325, 0.25), abs=EXACT)


def test_segment_triangle_flat_random_midpoint():
    """Random segments parallel to random triangles: midpoint of the part over the face."""
    rng = np.random.default_rng(RNG_SEED + 12)
    g = np.linspace(0.0, 1.0, 20001)
    checked = 0
    for _ in range(60):
        a, b, c = rng.uniform(-1, 1, size=(3, 3))
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        h = rng.uniform(-0.3, 0.3)
        e1 = (b - a) / np.linalg.norm(b - a)
        e2 = np.cross(n, e1)
        p0 = a + rng.uniform(-0.5, 1.0) * e1 + rng.uniform(-0.5, 1.0) * e2 + h * n
        ang = rng.uniform(0, 2 * np.pi)
        p1 = p0 + rng.uniform(0.3, 2.0) * (math.cos(ang) * e1 + math.sin(ang) * e2)
        # brute force: barycentrics of the projections of 20001 points of the segment
        P = p0 + g[:, None] * (p1 - p0)
        # in-plane barycentrics by the 2x2 normal equations (Cramer), no BLAS call
        e, f = b - a, c - a
        ee, ef, ff = e @ e, e @ f, f @ f
        re, rf = (P - a) @ e, (P - a) @ f
        det = ee * ff - ef * ef
        vb = (ff * re - ef * rf) / det
        wb = (ee * rf - ef * re) / det
        inside = (vb >= 0) & (wb >= 0) & (vb + wb <= 1)
        if not inside.any():
            continue
        checked += 1
        idx = np.flatnonzero(inside)  # one interval (the triangle is convex)
        s_mid = 0.5 * (g[idx[0]] + g[idx[-1]])
        s, u, v, w, d = _st(p0, p1, a, b, c)
        # the sampled interval ends are within one spacing (5e-5) of the true ones
        assert s == pytest.approx(s_mid, abs=5e-5)
        # the contact point is straight below P(s): distance |h|, up to rounding of O(1)
        # coordinates through a normalised normal (~1e-15); 1e-13 is the margin
        assert d == pytest.approx(abs(h), abs=1e-13)
    assert checked >= 10  # a fair share of random draws overlap the face (17 of 60)


def test_segment_triangle_flat_survives_rotation():
    rng = np.random.default_rng(RNG_SEED + 8)
    for _ in range(50):
        R = random_rotation(rng)
        off = rng.uniform(-10, 10, 3)
        a, b, c, p0, p1 = (R @ x + off for x in (A, B, C, v3(0.1, 0.2, 0.05), v3(0.9, 0.2, 0.05)))
        s, u, v, w, d = _st(p0, p1, a, b, c)
        # rotation rounding (~1e-15 at |coords| ~ 10) tilts the segment by ~1e-14 rad,
        # far under the parallel threshold; parameters follow to ~1e-13
        assert s == pytest.approx(0.4375, abs=1e-12)
        assert (u, v, w) == pytest.approx((0.35, 0.45, 0.2), abs=1e-12)
        assert d == pytest.approx(0.05, abs=1e-12)


def test_segment_triangle_parallel_to_edge_outside():
    # beside edge ab, in the plane and above it: the overlap with ab is x in [0, 0.5]
    for z in (0.0, 1.0):
        s, u, v, w, d = _st(v3(-0.5, -1, z), v3(0.5, -1, z), A, B, C)
        assert s == pytest.approx(0.75, abs=EXACT)
        assert (u, v, w) == pytest.approx((0.75, 0.25, 0.0), abs=EXACT)
        assert d == pytest.approx(math.hypot(1.0, z), abs=EXACT)


def test_segment_triangle_endpoint_and_edge_cases():
    # perpendicular above the face, not reaching it: lower endpoint
    s, u, v, w, d = _st(v3(0.2, 0.2, 3.0), v3(0.2, 0.2, 1.0), A, B, C)
    assert (s, u, v, w, d) == pytest.approx((1.0, 0.6, 0.2, 0.2, 1.0), abs=EXACT)
    # vertical segment beside edge ab, crossing the plane outside: edge contact
    s, u, v, w, d = _st(v3(0.5, -1, 1), v3(0.5, -1, -1), A, B, C)
    assert (s, u, v, w, d) == pytest.approx((0.5, 0.5, 0.5, 0.0, 1.0), abs=EXACT)
    # skew segment over vertex c
    s, u, v, w, d = _st(v3(-1, 1.5, 0.0), v3(1, 1.5, 0.0), A, B, C)
    assert (s, u, v, w, d) == pytest.approx((0.5, 0.0, 0.0, 1.0, 0.5), abs=EXACT)
    # zero-length segment: the point answer, s = 0
    s, u, v, w, d = _st(v3(0.2, 0.3, 2.0), v3(0.2, 0.3, 2.0), A, B, C)
    assert (s, u, v, w, d) == pytest.approx((0.0, 0.5, 0.2, 0.3, 2.0), abs=EXACT)


def test_segment_triangle_degenerate_triangles():
    a, b, c = v3(0, 0, 0), v3(1, 0, 0), v3(3, 0, 0)  # collinear, longest edge a-c
    s, u, v, w, d = _st(v3(2, 1, 1), v3(2, 1, -1), a, b, c)
    assert (s, d) == pytest.approx((0.5, 1.0), abs=EXACT)
    assert tri_pt(a, b, c, u, v, w) == pytest.approx(v3(2, 0, 0), abs=EXACT)
    # lying parallel beside the collinear "triangle": midpoint of the overlap x in [1, 3]
    s, u, v, w, d = _st(v3(1, 1, 0), v3(5, 1, 0), a, b, c)
    assert (s, d) == pytest.approx((0.25, 1.0), abs=EXACT)
    # all vertices coincide
    s, u, v, w, d = _st(v3(-1, 1, 0), v3(1, 1, 0), a, a, a)
    assert (s, d) == pytest.approx((0.5, 1.0), abs=EXACT)
    # sliver with relative area 1e-20
    a, b, c = v3(0, 0, 0), v3(1, 0, 0), v3(0.5, 1e-20, 0)
    s, u, v, w, d = _st(v3(0.25, -1, 1), v3(0.25, 1, 1), a, b, c)
    # the sliver is within 1e-20 of the segment [0,1] on x: distance 1 at x = 0.25
    assert (s, d) == pytest.approx((0.5, 1.0), abs=EXACT)
    s, u, v, w, d = _st(v3(0.3, -1, 0), v3(0.3, 1, 0), a, b, c)
    assert d <= EXACT  # crossing the sliver: zero up to rounding of O(1) coordinates


@pytest.mark.parametrize("height", [1e-20, 1e-11, 1e-9, 1e-6])
def test_segment_triangle_slivers_random(height):
    rng = np.random.default_rng(RNG_SEED + 9)
    for _ in range(15):
        R = random_rotation(rng)
        off = rng.uniform(-1, 1, 3)
        a, b, c = (R @ x + off for x in (v3(0, 0, 0), v3(1, 0, 0), v3(rng.uniform(-0.2, 1.2), height, 0)))
        p0, p1 = (R @ x + off for x in rng.uniform(-1, 1.5, size=(2, 3)))
        s, u, v, w, d = _st(p0, p1, a, b, c)
        dref = min(ref_seg_seg(p0, p1, a, b), ref_seg_seg(p0, p1, a, c), ref_seg_seg(p0, p1, b, c))
        # vs the union of the edges (SLSQP, good to ~1e-14 away from parallel valleys):
        # equal up to `height`, the distance of any triangle point to the boundary and of
        # the boundary to the longest edge; 1e-9 covers the reference
        assert d <= dref + height + 1e-9
        assert d >= dref - height - 1e-9


def test_segment_triangle_never_nan():
    rng = np.random.default_rng(RNG_SEED + 10)
    for scale in (1e-150, 1e-20, 1.0, 1e20, 1e140):
        for _ in range(20):
            p0, p1, a, b, c = rng.normal(size=(5, 3)) * scale
            cases = [
                (p0, p1, a, b, c),
                (p0, p0, a, b, c),
                (p0, p1, a, a, c),
                (p0, p1, a, a, a),
                (a, b, a, b, c),  # along an edge
                (a, a + (b - a) * 1e-300, a, b, c),
                (p0, p1, a, b, a + (b - a) * 0.5 + (c - a) * 1e-18),  # sliver
            ]
            for args in cases:
                s, u, v, w, d = geo.segment_triangle_closest(*args)
                check_param(s)
                check_bary(u, v, w)
                assert math.isfinite(d) and d >= 0.0
            for args in [(p0, a, b, c), (p0, a, a, c), (p0, a, a, a), (a, a, b, c)]:
                check_bary(*geo.point_triangle_closest(*args))


# ------------------------------------------------------------------------------------------
# unit independence
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("scale", [2.0**-140, 2.0**-20, 2.0**60, 2.0**140])
def test_scale_invariance(scale):
    """Scaling all input by a power of two is exact, so every answer must be bit-identical
    (all tolerances are relative) and distances scale exactly."""
    rng = np.random.default_rng(RNG_SEED + 13)
    for k in range(40):
        p0, p1, q0, q1, a = rng.uniform(-1, 1, size=(5, 3))
        if k % 4 == 1:  # parallel segments / flat on the face
            q1 = q0 + 0.5 * (p1 - p0)
            a = p0 + (q0 - p0) * 0.3
        if k % 4 == 2:  # zero-length segment, degenerate triangle
            p1 = p0.copy()
            a = q0 + 2.0 * (q1 - q0)
        sc = [x * scale for x in (p0, p1, q0, q1, a)]
        assert geo.segment_segment_closest(*sc[:4]) == geo.segment_segment_closest(p0, p1, q0, q1)
        assert geo.point_triangle_closest(*sc[:4]) == geo.point_triangle_closest(p0, p1, q0, q1)
        assert geo.segment_point_closest(*sc[:3]) == geo.segment_point_closest(p0, p1, q0)
        r1 = geo.segment_triangle_closest(p0, p1, q0, q1, a)
        r2 = geo.segment_triangle_closest(*sc)
        assert r2[:4] == r1[:4] and r2[4] == r1[4] * scale


# ------------------------------------------------------------------------------------------
# allocation free
# ------------------------------------------------------------------------------------------
@numba.njit
def _drive(x, n):
    acc = 0.0
    m = x.shape[0] - 4
    for k in range(n):
        i = k % m
        s, t = geo.segment_segment_closest(x[i], x[i + 1], x[i + 2], x[i + 3])
        u, v, w = geo.point_triangle_closest(x[i], x[i + 1], x[i + 2], x[i + 3])
        s2, u2, v2, w2, d2 = geo.segment_triangle_closest(x[i], x[i + 1], x[i + 2], x[i + 3], x[i + 4])
        acc += s + t + u + v + w + s2 + u2 + d2
        acc += geo.segment_point_closest(x[i], x[i + 1], x[i + 2]) + geo.dot3(x[i], x[i + 1])
    return acc


def test_no_allocation_in_hot_loop():
    from numba.core.runtime import _nrt_python, rtsys

    x = np.random.default_rng(RNG_SEED + 11).uniform(-1, 1, size=(64, 3))
    _drive(x, 1)  # compile
    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        s0 = rtsys.get_allocation_stats()
        _drive(x, 10)
        s1 = rtsys.get_allocation_stats()
        _drive(x, 10_000)
        s2 = rtsys.get_allocation_stats()
    finally:
        if not was_on:
            _nrt_python.memsys_disable_stats()
    few = s1.alloc - s0.alloc
    many = s2.alloc - s1.alloc
    # per-call overhead (argument boxing) is constant; any per-iteration allocation would
    # make the 10 000-iteration call allocate >= 9 990 more than the 10-iteration one
    assert many == few, (few, many)


_SOURCE_RUN = r"""
import importlib.util, sys
import numpy as np
spec = importlib.util.spec_from_file_location("geometry_source", sys.argv[1])
geo = importlib.util.module_from_spec(spec)
spec.loader.exec_module(geo)
P = np.load(sys.argv[2])
out = [geo.segment_triangle_closest(*p) + geo.segment_segment_closest(*p[:4])
       + geo.point_triangle_closest(p[0], p[2], p[3], p[4]) for p in P]
np.save(sys.argv[3], np.array(out, dtype=np.float64))
"""


def _awkward_inputs(n, rng):
    """Segment-triangle inputs (p0, p1, a, b, c) near the routines' branch points: points,
    near-points, degenerate triangles, segments parallel to an edge or to the plane, ends on
    a vertex or an edge, crossings, and plain random ones."""
    P = rng.normal(size=(n, 5, 3)) * 0.05
    for i in range(n):
        p = P[i]
        m = i % 8
        if m == 0:
            p[1] = p[0]
        elif m == 1:
            p[1] = p[0] + rng.normal(size=3) * 1e-12
        elif m == 2:
            p[4] = p[2] + (p[3] - p[2]) * 0.5
        elif m == 3:
            p[1] = p[0] + (p[3] - p[2])
        elif m == 4:
            p[1] = p[0] + np.cross(np.cross(p[3] - p[2], p[4] - p[2]), rng.normal(size=3))
        elif m == 5:
            p[0] = p[2]
        elif m == 6:
            p[0] = 0.5 * (p[2] + p[3])
            p[1] = p[0] + rng.normal(size=3) * 0.01
    return P


def test_compiled_routines_equal_their_python_source_bit_for_bit(tmp_path):
    """The compiled closest-point routines (their inner steps inlined into one another,
    ``_jit_inline``) give the very bits the Python source gives, run by the interpreter with
    numba's JIT off (IEEE double, one rounding per operation): a fastmath flag, a fused
    multiply-add or any reordering of the inlined arithmetic would change some of these 1,600
    awkward cases by an ulp, and then the wedge curve, which is chaotic at one ulp (the
    bristle-body search and the bristle-bristle contacts call these routines)."""
    import os
    import subprocess
    import sys

    P = _awkward_inputs(1600, np.random.default_rng(RNG_SEED + 7))
    np.save(tmp_path / "inputs.npy", P)
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    path = pathlib.Path(geo.__file__)
    subprocess.run([sys.executable, "-c", _SOURCE_RUN, str(path), str(tmp_path / "inputs.npy"),
                    str(tmp_path / "source.npy")], env=env, check=True, timeout=120)
    want = np.load(tmp_path / "source.npy")
    got = np.array([geo.segment_triangle_closest(*p) + geo.segment_segment_closest(*p[:4])
                    + geo.point_triangle_closest(p[0], p[2], p[3], p[4]) for p in P])
    assert got.shape == want.shape
    # bit for bit (NaN-free inputs; -0.0 and 0.0 told apart through the bit patterns)
    assert np.array_equal(got.view(np.int64), want.view(np.int64))
