"""The bristle-bristle neighbour list (``contacts.build_pair_list``): its cell-list broad
phase must find every pair of segments of different bristles whose capsules are within the
skin, each once, sorted, as the all-pairs search with the same distance test finds them."""
from __future__ import annotations

import numpy as np
import pytest

from engine.kernels.contacts import build_pair_list, segment_bounds
from engine.kernels.geometry import segment_segment_closest


def _chains(rng, n_bristles, n_nodes, spread, step):
    """Random bristles: chains of ``n_nodes`` nodes, each a random walk of ``step`` from a
    random root in a cube of side ``spread``; node radii 0.2 to 2 mm."""
    x = np.empty((n_bristles * n_nodes, 3))
    for b in range(n_bristles):
        p = rng.uniform(0.0, spread, 3)
        for k in range(n_nodes):
            x[b * n_nodes + k] = p
            p = p + rng.normal(size=3) * step
    rad = rng.uniform(2e-4, 2e-3, len(x))
    first = np.arange(n_bristles)[:, None] * n_nodes
    bi = (first + np.arange(n_nodes - 1)).ravel()
    bj = bi + 1
    return x, rad, bi, bj, np.repeat(np.arange(n_bristles), n_nodes - 1)


def _brush(rng, rows, cols, n_nodes, pitch, length, tilt):
    """A brush: rows x cols bristles on a square grid of ``pitch``, each a chain along z of
    ``length`` with lateral steps of ``tilt`` times the segment length (random signs), so
    that the segments' boxes are long along z and thin across, the cell list's shaped cells;
    node radii 0.4 to 0.6 of the pitch, so neighbours and next-but-one neighbours come near."""
    n_bristles = rows * cols
    x = np.empty((n_bristles * n_nodes, 3))
    seg = length / (n_nodes - 1)
    for b in range(n_bristles):
        p = np.array([(b % cols) * pitch, (b // cols) * pitch, 0.0])
        for k in range(n_nodes):
            x[b * n_nodes + k] = p
            p = p + np.array([*(rng.uniform(-tilt, tilt, 2) * seg), seg])
    rad = rng.uniform(0.4, 0.6, len(x)) * pitch
    first = np.arange(n_bristles)[:, None] * n_nodes
    bi = (first + np.arange(n_nodes - 1)).ravel()
    bj = bi + 1
    return x, rad, bi, bj, np.repeat(np.arange(n_bristles), n_nodes - 1)


@pytest.mark.parametrize("kind,n_bristles,spread,step", [
    ("chains", 60, 0.03, 0.006), ("chains", 200, 0.05, 0.004), ("chains", 40, 2.0, 0.01),
    # brushes (n_bristles rows and columns, spread the pitch, step the tilt): straight-ish
    # (cells much longer than wide), and bent far over (lateral steps up to 0.8 of a
    # segment: cells as wide as the tilted segments)
    ("brush", 12, 0.002, 0.05), ("brush", 12, 0.002, 0.8)])
def test_pair_list_finds_each_pair_within_the_skin_once(kind, n_bristles, spread, step):
    rng = np.random.default_rng(n_bristles + int(step * 1000))
    if kind == "chains":
        x, rad, bi, bj, bristle = _chains(rng, n_bristles, 6, spread, step)
    else:
        x, rad, bi, bj, bristle = _brush(rng, n_bristles, n_bristles, 6, spread, 0.04, step)
    skin = 1e-3 if kind == "chains" else 0.1 * spread
    ns = len(bi)
    mid, bound = np.empty((ns, 3)), np.empty(ns)
    segment_bounds(x, rad, bi, bj, mid, bound)
    rmax = np.maximum(rad[bi], rad[bj])
    cap = ns * ns
    out_a, out_b = np.zeros(cap, np.int64), np.zeros(cap, np.int64)
    n = build_pair_list(mid, bound, bristle, skin, out_a, out_b, x, bi, bj, rmax)
    want = []
    for a in range(ns):
        for b in range(a + 1, ns):
            if bristle[a] == bristle[b]:
                continue
            pa, qa, pb, qb = x[bi[a]], x[bj[a]], x[bi[b]], x[bj[b]]
            s, t = segment_segment_closest(pa, qa, pb, qb)
            # the gap vector and its square, term by term as the kernel writes them
            e = [pa[c] + s * (qa[c] - pa[c]) - pb[c] - t * (qb[c] - pb[c]) for c in range(3)]
            lim = rmax[a] + rmax[b] + skin
            if e[0] * e[0] + e[1] * e[1] + e[2] * e[2] < lim * lim:
                want.append((a, b))
    got = list(zip(out_a[:n].tolist(), out_b[:n].tolist()))
    assert got == want
    if spread < 1.0:
        assert n > 50  # a crowded scene: the list has something to find


def test_box_gap_never_exceeds_the_segments_distance():
    """The narrow phase calls a listed pair's capsules apart, without their closest points,
    where the axes' bounding boxes are farther apart than the two largest radii (with a
    1e-9 margin: ``contacts._pair``). That is sound only if the box gap is a lower bound of
    the axes' distance: checked against scipy's bounded minimisation of |P(s) - Q(t)|^2
    (convex in s, t) on random segment pairs from crossing to parallel, the gaps from
    touching to several lengths."""
    from scipy.optimize import minimize

    from engine.kernels.contacts import _box_gap2

    rng = np.random.default_rng(11)
    tight = 0
    for trial in range(400):
        p0 = rng.normal(size=3) * 1e-3
        d1 = rng.normal(size=3) * 5e-3
        d2 = d1 * rng.uniform(-1, 1) if trial % 4 == 0 else rng.normal(size=3) * 5e-3
        q0 = p0 + rng.normal(size=3) * 10.0 ** rng.uniform(-4, -2)
        x = np.array([p0, p0 + d1, q0, q0 + d2])

        def f(st):
            g = x[0] + st[0] * d1 - x[2] - st[1] * d2
            return g @ g

        best = min((minimize(f, s0, bounds=[(0, 1), (0, 1)], method="L-BFGS-B",
                             options={"ftol": 1e-15, "gtol": 1e-14})
                    for s0 in ([0.5, 0.5], [0.0, 1.0], [1.0, 0.0])), key=lambda r: r.fun)
        gap2 = _box_gap2(x, 0, 1, 2, 3)
        assert gap2 <= best.fun * (1 + 1e-9) + 1e-24, (trial, gap2, best.fun)
        tight += gap2 > 0.5 * best.fun
    assert tight > 40   # the bound is often close, so the test above can fail
