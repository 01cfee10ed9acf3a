"""Bristle-bristle contacts: the Verlet neighbour list (built through a cell list, O(n)) and
the capsule-capsule narrow phase with the Cundall-Strack law.

A contact is between two segments (capsules) of *different* bristles, at their closest
points. Only local minima of the distance between two bristles count: a closest point at a
joint is counted by the segment after the joint, and only if the segment before it does not
come closer; so a touch at a joint is counted once, and contacts hand over continuously from
segment to segment (which keeps the energy of undamped, frictionless contacts constant).

The neighbour list keeps every segment pair whose bounding spheres are closer than the skin
(:func:`build_pair_list`, the broad phase); when it is rebuilt, how the surviving pairs keep
their history and what happens on an overflow is ``engine.kernels.neighbours``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .bonds import PARALLEL_MIN
from .contact_law import clear_history, contact_with_history, normal_stiffness, smoothstep
from .jit import item_kernel
from .geometry import row3, segment_point_closest, segment_segment_closest


@njit(cache=True)
def segment_bounds(x, rad, bi, bj, mid, bound):
    """Midpoint and bounding-sphere radius of every segment."""
    for s in range(bi.shape[0]):
        i = bi[s]
        j = bj[s]
        lx = x[j, 0] - x[i, 0]
        ly = x[j, 1] - x[i, 1]
        lz = x[j, 2] - x[i, 2]
        mid[s, 0] = x[i, 0] + 0.5 * lx
        mid[s, 1] = x[i, 1] + 0.5 * ly
        mid[s, 2] = x[i, 2] + 0.5 * lz
        bound[s] = 0.5 * math.sqrt(lx * lx + ly * ly + lz * lz) + max(rad[i], rad[j])


@njit(cache=True, inline="always")
def _box_gap2(x, ia, ja, ib, jb):
    """Squared distance between the axis-aligned boxes of segments ia-ja and ib-jb: a lower
    bound of the squared distance between the segments (their closest points lie in the
    boxes). Side by side bristles are rejected by it without the segment-segment distance,
    which their bounding spheres (as long as the segments) let through."""
    g2 = 0.0
    for c in range(3):
        a0 = min(x[ia, c], x[ja, c])
        a1 = max(x[ia, c], x[ja, c])
        b0 = min(x[ib, c], x[jb, c])
        b1 = max(x[ib, c], x[jb, c])
        gap = max(b0 - a1, a0 - b1)
        if gap > 0.0:
            g2 += gap * gap
    return g2


@njit(cache=True)
def build_pair_list(mid, bound, seg_bristle, skin, out_a, out_b, x, bi, bj, seg_rmax):
    """All pairs (a < b) of segments of different bristles whose capsules (axis distance
    minus the largest radii) are closer than ``skin``, sorted by (a, b). Candidates come from
    a cell list over the segments' midpoints, its cells as long along each axis as the
    segments' boxes are; their bounding spheres, then their axes' boxes prefilter. No point
    of a segment moves further than its farthest node, so the list stays complete while
    every node has moved less than skin / 2. Returns the number of pairs; if it exceeds the
    capacity of ``out_a`` nothing past the capacity is written and the caller must grow
    and retry."""
    ns = mid.shape[0]
    if ns == 0:
        return 0
    # per axis, the largest half-extent of a segment's axis box plus its largest radius: two
    # segments within reach (their axes' boxes at most rmax_a + rmax_b + skin apart along
    # each axis, the box test below) have midpoints at most 2 h + skin apart along it, so a
    # cell that long holds every partner in the 27 cells around. Cells shaped by the
    # segments' boxes, not their bounding spheres: a brush's segments are long along the
    # bristles and thin across, and spheres made cubes that held several rows of bristles
    h0 = 0.0
    h1 = 0.0
    h2 = 0.0
    lo0 = mid[0, 0]
    lo1 = mid[0, 1]
    lo2 = mid[0, 2]
    hi0 = lo0
    hi1 = lo1
    hi2 = lo2
    for s in range(ns):
        i = bi[s]
        j = bj[s]
        r = seg_rmax[s]
        h0 = max(h0, 0.5 * abs(x[j, 0] - x[i, 0]) + r)
        h1 = max(h1, 0.5 * abs(x[j, 1] - x[i, 1]) + r)
        h2 = max(h2, 0.5 * abs(x[j, 2] - x[i, 2]) + r)
        lo0 = min(lo0, mid[s, 0])
        lo1 = min(lo1, mid[s, 1])
        lo2 = min(lo2, mid[s, 2])
        hi0 = max(hi0, mid[s, 0])
        hi1 = max(hi1, mid[s, 1])
        hi2 = max(hi2, mid[s, 2])
    # the margin covers the rounding of the midpoints and of the box test's own 1e-9
    cell0 = (2.0 * h0 + skin) * (1.0 + 1e-6)
    cell1 = (2.0 * h1 + skin) * (1.0 + 1e-6)
    cell2 = (2.0 * h2 + skin) * (1.0 + 1e-6)
    # keep the grid at most ~2 cells per segment (and finite) however spread the scene is
    while True:
        d0 = int((hi0 - lo0) / cell0) + 1
        d1 = int((hi1 - lo1) / cell1) + 1
        d2 = int((hi2 - lo2) / cell2) + 1
        if d0 * d1 * d2 <= 2 * ns + 64:
            break
        cell0 *= 1.26
        cell1 *= 1.26
        cell2 *= 1.26
    ncell = d0 * d1 * d2
    cid = np.empty(ns, np.int64)
    count = np.zeros(ncell + 1, np.int64)
    for s in range(ns):
        c0 = min(int((mid[s, 0] - lo0) / cell0), d0 - 1)
        c1 = min(int((mid[s, 1] - lo1) / cell1), d1 - 1)
        c2 = min(int((mid[s, 2] - lo2) / cell2), d2 - 1)
        c = (c0 * d1 + c1) * d2 + c2
        cid[s] = c
        count[c + 1] += 1
    for c in range(ncell):
        count[c + 1] += count[c]
    order = np.empty(ns, np.int64)
    fill = count[:-1].copy()
    for s in range(ns):
        order[fill[cid[s]]] = s
        fill[cid[s]] += 1
    cap = out_a.shape[0]
    n = 0
    keys = np.empty(cap, np.int64)
    for a in range(ns):
        c = cid[a]
        c2 = c % d2
        c1 = (c // d2) % d1
        c0 = c // (d1 * d2)
        for e0 in range(max(c0 - 1, 0), min(c0 + 2, d0)):
            for e1 in range(max(c1 - 1, 0), min(c1 + 2, d1)):
                for e2 in range(max(c2 - 1, 0), min(c2 + 2, d2)):
                    cc = (e0 * d1 + e1) * d2 + e2
                    for k in range(count[cc], count[cc + 1]):
                        b = order[k]
                        if b <= a or seg_bristle[b] == seg_bristle[a]:
                            continue
                        dx = mid[a, 0] - mid[b, 0]
                        dy = mid[a, 1] - mid[b, 1]
                        dz = mid[a, 2] - mid[b, 2]
                        lim = bound[a] + bound[b] + skin
                        if dx * dx + dy * dy + dz * dz >= lim * lim:
                            continue
                        ia = bi[a]
                        ja = bj[a]
                        ib = bi[b]
                        jb = bj[b]
                        lim = seg_rmax[a] + seg_rmax[b] + skin
                        if _box_gap2(x, ia, ja, ib, jb) > lim * lim * (1.0 + 1e-9):
                            continue  # the axes' boxes alone are farther apart than lim
                        s, t = segment_segment_closest(row3(x, ia), row3(x, ja), row3(x, ib), row3(x, jb))
                        ex = (x[ia, 0] + s * (x[ja, 0] - x[ia, 0])
                              - x[ib, 0] - t * (x[jb, 0] - x[ib, 0]))
                        ey = (x[ia, 1] + s * (x[ja, 1] - x[ia, 1])
                              - x[ib, 1] - t * (x[jb, 1] - x[ib, 1]))
                        ez = (x[ia, 2] + s * (x[ja, 2] - x[ia, 2])
                              - x[ib, 2] - t * (x[jb, 2] - x[ib, 2]))
                        if ex * ex + ey * ey + ez * ez < lim * lim:
                            if n < cap:
                                keys[n] = a * ns + b
                            n += 1
    if n > cap:
        return n
    srt = np.argsort(keys[:n])
    for k in range(n):
        key = keys[srt[k]]
        out_a[k] = key // ns
        out_b[k] = key % ns
    return n


NSLOT = 5  # contacts a segment pair can hold: 4 node-segment + 1 crossing
CROSS_SIN2_LO = 0.04   # sin^2 of the angle where crossing contacts start to count (0.2 rad)
CROSS_SIN2_HI = 0.10   # ... and count fully (0.32 rad)
CROSS_END = 0.25       # crossing contacts fade out over the last quarter of each segment


@njit(cache=True, parallel=True)
def bristle_bristle_narrow(nd, bn, pl, tb, friction, dt):
    """Contacts of the first ``n_pairs`` listed segment pairs, up to ``NSLOT`` per pair:

    * slots 0-3, node against segment: each node of one bristle against the other bristle's
      segment (the start node of each segment, and the tip node of the last one). The
      distance from a point to a segment is continuously differentiable, so the contact
      energy has no kinks and undamped contacts conserve energy; a closest point at a joint is
      counted once (by the segment after the joint, and only if it is a local minimum);
    * slot 4, crossing: segments that cross at an angle touch between their nodes; that
      contact is weighted smoothly to zero towards either segment's ends (where the node
      contacts take over) and towards parallel axes (where the closest point is ill-defined).

    Per slot: the force on the pair's first segment ``fc`` (the second gets ``-fc``), the
    contact point ``cp``, and the contact's parameters on both segments; tangential history
    per slot in ``ft``."""
    x, v, w, rad, mass = nd.x, nd.v, nd.w, nd.rad, nd.mass
    bond_prev, bond_next = nd.bond_prev, nd.bond_next
    bi, bj, seg_has_next, seg_material = bn.i, bn.j, bn.has_next, bn.material
    pa, pb, n_pairs, ft = pl.a, pl.b, pl.n[0], pl.ft
    E, mu_table, kt_table, zeta_table, adh_table = tb.E, tb.mu, tb.kt, tb.zeta, tb.adhesion
    active, fc, cp, par_s, par_t = pl.active, pl.fc, pl.cp, pl.s, pl.t
    energy, diss, overlap_ratio, xf = pl.energy, pl.diss, pl.ratio, pl.xf
    # the pair kernel's arrays in five tuples, not as 31 arguments: CPython 3.11 compiles a
    # call of more than 30 arguments as f(*args), and numba's call through that one tuple
    # costs about a microsecond (as bristle_body_narrow's candidate kernel measured)
    nodes = (x, v, w, rad, mass, bond_prev, bond_next)
    segs = (bi, bj, seg_has_next, seg_material)
    lst = (pa, pb, ft)
    tabs = (E, mu_table, kt_table, zeta_table, adh_table)
    out = (active, fc, cp, par_s, par_t, energy, diss, overlap_ratio, xf)
    if n_pairs >= PARALLEL_MIN:
        for p in prange(n_pairs):
            _pair(p, nodes, segs, lst, tabs, out, friction, dt)
    else:
        for p in range(n_pairs):
            _pair(p, nodes, segs, lst, tabs, out, friction, dt)


@njit(cache=True, inline="always")
def _pair(p, nodes, segs, lst, tabs, out, friction, dt):
    """One listed pair. Where the capsules are apart (axis distance at least both segments'
    largest radii) no slot can touch, since every slot's points lie on the axes: its slots
    are cleared here, in the loop, and only a pair within reach pays the call of
    ``_pair_contacts`` (some thirty arrays passed; on the wedge 20 mm in, three pairs in
    four are apart). Axes whose boxes are farther apart than that (with the pair list's
    margin) settle it without the segments' closest points."""
    x = nodes[0]
    rad = nodes[3]
    bi = segs[0]
    bj = segs[1]
    a = lst[0][p]
    b = lst[1][p]
    ia = bi[a]
    ja = bj[a]
    ib = bi[b]
    jb = bj[b]
    reach = max(rad[ia], rad[ja]) + max(rad[ib], rad[jb])
    apart = _box_gap2(x, ia, ja, ib, jb) > reach * reach * (1.0 + 1e-9)
    s0 = 0.0
    t0 = 0.0
    if not apart:
        s0, t0 = segment_segment_closest(row3(x, ia), row3(x, ja), row3(x, ib), row3(x, jb))
        gx = x[ia, 0] + s0 * (x[ja, 0] - x[ia, 0]) - x[ib, 0] - t0 * (x[jb, 0] - x[ib, 0])
        gy = x[ia, 1] + s0 * (x[ja, 1] - x[ia, 1]) - x[ib, 1] - t0 * (x[jb, 1] - x[ib, 1])
        gz = x[ia, 2] + s0 * (x[ja, 2] - x[ia, 2]) - x[ib, 2] - t0 * (x[jb, 2] - x[ib, 2])
        apart = gx * gx + gy * gy + gz * gz >= reach * reach
    if apart:
        active, diss, xf = out[0], out[6], out[8]
        ft = lst[2]
        base = p * NSLOT
        for k in range(NSLOT):
            active[base + k] = 0
            clear_history(ft, base + k, friction, diss)
        for r in range(4):
            for c in range(3):
                xf[base + 4, r, c] = 0.0
    else:
        _pair_contacts(p, nodes, segs, lst, tabs, out, friction, dt, s0, t0)


@item_kernel
def point_segment_max_overlap(x, rad, j0, j1, px, py, pz, t):
    """Refine t (start: the closest point of segment j0-j1 to p) to the maximum of
    rb(t) - |p - Q(t)| for a tapered segment (1-D Newton, clamped)."""
    dr = rad[j1] - rad[j0]
    if dr == 0.0:
        return t
    dx = x[j1, 0] - x[j0, 0]
    dy = x[j1, 1] - x[j0, 1]
    dz = x[j1, 2] - x[j0, 2]
    a = dx * dx + dy * dy + dz * dz
    for _ in range(4):
        rx = px - x[j0, 0] - t * dx
        ry = py - x[j0, 1] - t * dy
        rz = pz - x[j0, 2] - t * dz
        d = math.sqrt(rx * rx + ry * ry + rz * rz)
        if d <= 1e-300:
            return t
        rd = (rx * dx + ry * dy + rz * dz) / d
        g = dr + rd
        h = (a - rd * rd) / d
        if (t <= 0.0 and g < 0.0) or (t >= 1.0 and g > 0.0):
            return t
        if h > 1e-300:
            tn = min(max(t + g / h, 0.0), 1.0)
        else:
            tn = 1.0 if g > 0.0 else 0.0
        if abs(tn - t) < 1e-12:
            return tn
        t = tn
    return t


@njit(cache=True, inline="always")
def _point_overlap(x, rad, j0, j1, px, py, pz, reject=-math.inf):
    """Largest overlap rb(t) - |p - Q(t)| of a point with the tapered segment j0-j1
    (without the point's own radius), and its parameter. Where that overlap is surely at
    most ``reject`` (``max(rb) - min |p - Q|`` bounds it), the taper's refinement is skipped
    and the bound returned: a caller that only tests ``> reject`` gets the same answer."""
    t = segment_point_closest(row3(x, j0), row3(x, j1), (px, py, pz))
    if reject > -math.inf:
        qx = x[j0, 0] + t * (x[j1, 0] - x[j0, 0]) - px
        qy = x[j0, 1] + t * (x[j1, 1] - x[j0, 1]) - py
        qz = x[j0, 2] + t * (x[j1, 2] - x[j0, 2]) - pz
        bound = max(rad[j0], rad[j1]) - math.sqrt(qx * qx + qy * qy + qz * qz)
        if bound <= reject:
            return bound, t
    t = point_segment_max_overlap(x, rad, j0, j1, px, py, pz, t)
    qx = x[j0, 0] + t * (x[j1, 0] - x[j0, 0]) - px
    qy = x[j0, 1] + t * (x[j1, 1] - x[j0, 1]) - py
    qz = x[j0, 2] + t * (x[j1, 2] - x[j0, 2]) - pz
    return rad[j0] + t * (rad[j1] - rad[j0]) - math.sqrt(qx * qx + qy * qy + qz * qz), t


BEAT_MARGIN = 1e-9   # of a segment's radii: see best_of_neighbours


@item_kernel
def best_of_neighbours(x, rad, bi, bj, bond_prev, bond_next, seg, ov, px, py, pz):
    """A point touches a bristle where its overlap with the bristle's segments is a local
    maximum: keep segment ``seg`` only if its overlap ``ov`` beats the previous segment's
    and is at least the next one's. At a tie both give the same contact, so the contact
    hands over continuously, and a convex joint is counted once. A neighbour whose overlap
    bound (``_point_overlap``) lies ``BEAT_MARGIN`` of its radii below ``ov`` cannot beat it
    and skips the taper's refinement (the margin is far above the refined overlap's
    rounding, so every answer is the refined one's)."""
    pb = bond_prev[bi[seg]]
    if pb >= 0:
        j0 = bi[pb]
        j1 = bj[pb]
        o, _t = _point_overlap(x, rad, j0, j1, px, py, pz,
                               ov - BEAT_MARGIN * (rad[j0] + rad[j1]))
        if o >= ov:
            return False
    nb = bond_next[bj[seg]]
    if nb >= 0:
        j0 = bi[nb]
        j1 = bj[nb]
        o, _t = _point_overlap(x, rad, j0, j1, px, py, pz,
                               ov - BEAT_MARGIN * (rad[j0] + rad[j1]))
        if o > ov:
            return False
    return True


@njit(cache=True, inline="always")
def _dsmooth01(u):
    if u <= 0.0 or u >= 1.0:
        return 0.0
    return 6.0 * u * (1.0 - u)


@item_kernel
def crossing_weight_forces(x, rad, i0, i1, j0, j1, s, t, ov, kn, out, fa):
    """Extra nodal forces of a crossing contact, whose energy is U = w * 1/2 kn ov^2 with
    a weight w(angle, s, t) and ov = ra(s) + rb(t) - d: the applied force kn w ov n covers the
    distance term; this adds -1/2 kn ov^2 grad w - kn w ov (dra grad s + drb grad t), with
    grad s, grad t from differentiating the closest-point conditions (interior points, where
    w > 0). ``out`` (4, 3) gets the forces on nodes i0, i1, j0, j1, so U is conserved.
    An adhered contact (``contact_law.adhesion``, attraction ``fa`` at full weight, else 0)
    adds the potential ``-w fa ov``: U0 below is then 1/2 kn ov^2 - fa ov."""
    d1 = (x[i1, 0] - x[i0, 0], x[i1, 1] - x[i0, 1], x[i1, 2] - x[i0, 2])
    d2 = (x[j1, 0] - x[j0, 0], x[j1, 1] - x[j0, 1], x[j1, 2] - x[j0, 2])
    a11 = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    a22 = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]
    a12 = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
    r = (x[i0, 0] + s * d1[0] - x[j0, 0] - t * d2[0],
         x[i0, 1] + s * d1[1] - x[j0, 1] - t * d2[1],
         x[i0, 2] + s * d1[2] - x[j0, 2] - t * d2[2])
    sin2 = 1.0 - a12 * a12 / (a11 * a22)
    u_ang = (sin2 - CROSS_SIN2_LO) / (CROSS_SIN2_HI - CROSS_SIN2_LO)
    chi = smoothstep(u_ang)
    dchi = _dsmooth01(u_ang) / (CROSS_SIN2_HI - CROSS_SIN2_LO)
    ms = min(s, 1.0 - s)
    mt = min(t, 1.0 - t)
    ps = smoothstep(ms / CROSS_END)
    pt = smoothstep(mt / CROSS_END)
    dps = _dsmooth01(ms / CROSS_END) / CROSS_END * (1.0 if s < 0.5 else -1.0)
    dpt = _dsmooth01(mt / CROSS_END) / CROSS_END * (1.0 if t < 0.5 else -1.0)
    w = chi * ps * pt
    U0 = 0.5 * kn * ov * ov - fa * ov
    # dU/ds and dU/dt at fixed positions (the distance is stationary in s, t)
    cs_ = U0 * chi * dps * pt + (kn * w * ov - w * fa) * (rad[i1] - rad[i0])
    ct_ = U0 * chi * ps * dpt + (kn * w * ov - w * fa) * (rad[j1] - rad[j0])
    # grad of sin^2 w.r.t. d1 and d2
    f = -2.0 * a12 / (a11 * a22)
    det = a12 * a12 - a11 * a22
    for c in range(3):
        gd1 = f * (d2[c] - (a12 / a11) * d1[c])
        gd2 = f * (d1[c] - (a12 / a22) * d2[c])
        # closest-point conditions g1 = r.d1 = 0, g2 = r.d2 = 0: coefficients per node
        e1 = ((1.0 - s) * d1[c] - r[c], s * d1[c] + r[c], -(1.0 - t) * d1[c], -t * d1[c])
        e2 = ((1.0 - s) * d2[c], s * d2[c], -(1.0 - t) * d2[c] - r[c], r[c] - t * d2[c])
        ang = (-gd1, gd1, -gd2, gd2)
        for n in range(4):
            # [a11 -a12; a12 -a22] [ds dt] = -[e1 e2]
            ds = -(-a22 * e1[n] + a12 * e2[n]) / det
            dt_ = -(-a12 * e1[n] + a11 * e2[n]) / det
            grad = U0 * dchi * ps * pt * ang[n] + cs_ * ds + ct_ * dt_
            out[n, c] = -grad


@item_kernel
def _pair_contacts(p, nodes, segs, lst, tabs, out, friction, dt, s0, t0):
    """The slots of a pair whose capsules are within reach (``_pair``), ``(s0, t0)`` the
    closest points of its axes."""
    x, v, w, rad, mass, bond_prev, bond_next = nodes
    bi, bj, seg_has_next, seg_material = segs
    pa, pb, ft = lst
    E, mu_table, kt_table, zeta_table, adh_table = tabs
    active, fc, cp, par_s, par_t, energy, diss, overlap_ratio, xf = out
    a = pa[p]
    b = pb[p]
    base = p * NSLOT
    for k in range(NSLOT):
        slot = base + k
        diss[slot] = 0.0
        if k == 0 or k == 2:
            # a node of segment a against segment b
            if k == 2 and seg_has_next[a]:
                active[slot] = 0
                clear_history(ft, slot, friction, diss)
                continue
            first, second = a, b
            s = 0.0 if k == 0 else 1.0
        elif k == 1 or k == 3:
            if k == 3 and seg_has_next[b]:
                active[slot] = 0
                clear_history(ft, slot, friction, diss)
                continue
            first, second = b, a
            s = 0.0 if k == 1 else 1.0
        else:
            first, second = a, b
            s = 0.0
        i0 = bi[first]
        i1 = bj[first]
        j0 = bi[second]
        j1 = bj[second]
        weight = 1.0
        if k < 4:
            node = i0 if s == 0.0 else i1
            px_ = x[node, 0]
            py_ = x[node, 1]
            pz_ = x[node, 2]
            ovb, t = _point_overlap(x, rad, j0, j1, px_, py_, pz_, -rad[node])
            if ovb + rad[node] <= 0.0 or not best_of_neighbours(
                    x, rad, bi, bj, bond_prev, bond_next, second, ovb, px_, py_, pz_):
                active[slot] = 0
                clear_history(ft, slot, friction, diss)
                continue
            qx_ = x[j0, 0] + t * (x[j1, 0] - x[j0, 0])
            qy_ = x[j0, 1] + t * (x[j1, 1] - x[j0, 1])
            qz_ = x[j0, 2] + t * (x[j1, 2] - x[j0, 2])
        else:
            s = s0   # the axes' closest points, as _pair found them (first = a)
            t = t0
            d1x = x[i1, 0] - x[i0, 0]
            d1y = x[i1, 1] - x[i0, 1]
            d1z = x[i1, 2] - x[i0, 2]
            d2x = x[j1, 0] - x[j0, 0]
            d2y = x[j1, 1] - x[j0, 1]
            d2z = x[j1, 2] - x[j0, 2]
            cx_ = d1y * d2z - d1z * d2y
            cy_ = d1z * d2x - d1x * d2z
            cz_ = d1x * d2y - d1y * d2x
            n1 = d1x * d1x + d1y * d1y + d1z * d1z
            n2 = d2x * d2x + d2y * d2y + d2z * d2z
            sin2 = (cx_ * cx_ + cy_ * cy_ + cz_ * cz_) / (n1 * n2) if n1 * n2 > 0 else 0.0
            weight = (smoothstep((sin2 - CROSS_SIN2_LO) / (CROSS_SIN2_HI - CROSS_SIN2_LO))
                      * smoothstep(min(s, 1.0 - s) / CROSS_END)
                      * smoothstep(min(t, 1.0 - t) / CROSS_END))
            if weight <= 0.0:
                active[slot] = 0
                clear_history(ft, slot, friction, diss)
                for r in range(4):
                    for c in range(3):
                        xf[slot, r, c] = 0.0
                continue
            px_ = x[i0, 0] + s * d1x
            py_ = x[i0, 1] + s * d1y
            pz_ = x[i0, 2] + s * d1z
            qx_ = x[j0, 0] + t * d2x
            qy_ = x[j0, 1] + t * d2y
            qz_ = x[j0, 2] + t * d2z
        ra = rad[i0] + s * (rad[i1] - rad[i0])
        rb = rad[j0] + t * (rad[j1] - rad[j0])
        dx = px_ - qx_
        dy = py_ - qy_
        dz = pz_ - qz_
        d = math.sqrt(dx * dx + dy * dy + dz * dz)
        ov = ra + rb - d
        if ov <= 0.0:
            active[slot] = 0
            clear_history(ft, slot, friction, diss)
            continue
        if d > 1e-9 * (ra + rb):
            nx = dx / d
            ny = dy / d
            nz = dz / d
        else:
            # axes intersect: the normal is perpendicular to both axes (never NaN)
            ux = x[i1, 0] - x[i0, 0]
            uy = x[i1, 1] - x[i0, 1]
            uz = x[i1, 2] - x[i0, 2]
            wx = x[j1, 0] - x[j0, 0]
            wy = x[j1, 1] - x[j0, 1]
            wz = x[j1, 2] - x[j0, 2]
            nx = uy * wz - uz * wy
            ny = uz * wx - ux * wz
            nz = ux * wy - uy * wx
            nn = math.sqrt(nx * nx + ny * ny + nz * nz)
            if nn < 1e-30:
                # collinear axes: any direction perpendicular to the first axis
                if abs(ux) < 0.9 * math.sqrt(ux * ux + uy * uy + uz * uz):
                    nx, ny, nz = 0.0, -uz, uy
                else:
                    nx, ny, nz = uz, 0.0, -ux
                nn = math.sqrt(nx * nx + ny * ny + nz * nz)
            nx /= nn
            ny /= nn
            nz /= nn
        # contact point: the middle of the overlap along the normal
        h = ra - 0.5 * ov
        cx = px_ - nx * h
        cy = py_ - ny * h
        cz = pz_ - nz * h
        vax, vay, vaz = segment_point_velocity(v, w, i0, i1, s, px_, py_, pz_, cx, cy, cz)
        vbx, vby, vbz = segment_point_velocity(v, w, j0, j1, t, qx_, qy_, qz_, cx, cy, cz)
        ma = mass[i0] + s * (mass[i1] - mass[i0])
        mb = mass[j0] + t * (mass[j1] - mass[j0])
        m1 = seg_material[first]
        m2 = seg_material[second]
        kn = weight * normal_stiffness(E[m1], ra, E[m2], rb)
        Fx, Fy, Fz, dis, sto, fadh = contact_with_history(
            ft, slot, friction, nx, ny, nz, ov, vax - vbx, vay - vby, vaz - vbz, kn,
            kt_table[m1, m2] * kn, mu_table[m1, m2], zeta_table[m1, m2], ma * mb / (ma + mb),
            dt, weight * adh_table[m1, m2])
        active[slot] = 1
        if k == 4:
            # (the stored energy from the law is already w 1/2 kn ov^2 plus the tangential
            # spring's; overriding it by the normal part alone hid the spring's energy)
            crossing_weight_forces(x, rad, i0, i1, j0, j1, s, t, ov,
                                   normal_stiffness(E[m1], ra, E[m2], rb), xf[slot],
                                   adh_table[m1, m2] if fadh != 0.0 else 0.0)
        if first == a and not (k == 1 or k == 3):
            fc[slot, 0] = Fx
            fc[slot, 1] = Fy
            fc[slot, 2] = Fz
            par_s[slot] = s
            par_t[slot] = t
        else:
            # stored as the force on segment a at its parameter
            fc[slot, 0] = -Fx
            fc[slot, 1] = -Fy
            fc[slot, 2] = -Fz
            par_s[slot] = t
            par_t[slot] = s
        cp[slot, 0] = cx
        cp[slot, 1] = cy
        cp[slot, 2] = cz
        energy[slot] = sto
        diss[slot] = dis
        overlap_ratio[slot] = ov / min(ra, rb)


@njit(cache=True, inline="always")
def segment_point_velocity(v, w, i0, i1, s, px, py, pz, cx, cy, cz):
    """Velocity of the material point at c carried by segment i0-i1: the axis point at
    parameter s (p) moves with the interpolated node velocity, and c turns about it with the
    interpolated angular velocity."""
    wx = w[i0, 0] + s * (w[i1, 0] - w[i0, 0])
    wy = w[i0, 1] + s * (w[i1, 1] - w[i0, 1])
    wz = w[i0, 2] + s * (w[i1, 2] - w[i0, 2])
    return (v[i0, 0] + s * (v[i1, 0] - v[i0, 0]) + wy * (cz - pz) - wz * (cy - py),
            v[i0, 1] + s * (v[i1, 1] - v[i0, 1]) + wz * (cx - px) - wx * (cz - pz),
            v[i0, 2] + s * (v[i1, 2] - v[i0, 2]) + wx * (cy - py) - wy * (cx - px))


@njit(cache=True, inline="always")
def add_segment_force(x, f, t, i0, i1, s, Fx, Fy, Fz, cx, cy, cz):
    """Distribute a force acting at point c on the segment i0-i1 (axis parameter s) to its
    nodes, with the torque of its offset from the axis, so that the force and its moment
    about any point are preserved exactly."""
    px = x[i0, 0] + s * (x[i1, 0] - x[i0, 0])
    py = x[i0, 1] + s * (x[i1, 1] - x[i0, 1])
    pz = x[i0, 2] + s * (x[i1, 2] - x[i0, 2])
    rx = cx - px
    ry = cy - py
    rz = cz - pz
    tx = ry * Fz - rz * Fy
    ty = rz * Fx - rx * Fz
    tz = rx * Fy - ry * Fx
    u = 1.0 - s
    f[i0, 0] += u * Fx
    f[i0, 1] += u * Fy
    f[i0, 2] += u * Fz
    f[i1, 0] += s * Fx
    f[i1, 1] += s * Fy
    f[i1, 2] += s * Fz
    t[i0, 0] += u * tx
    t[i0, 1] += u * ty
    t[i0, 2] += u * tz
    t[i1, 0] += s * tx
    t[i1, 1] += s * ty
    t[i1, 2] += s * tz


@njit(cache=True)
def scatter_bristle_bristle(nd, bn, pl, stats):
    """Add the pair forces to the nodes (serial: race-free). ``stats`` gets
    [count, stored energy, dissipated energy, max overlap ratio, pair index of the max]."""
    x, f, t, bi, bj = nd.x, nd.f, nd.t, bn.i, bn.j
    pa, pb, n_pairs = pl.a, pl.b, pl.n[0]
    active, fc, cp, par_s, par_t = pl.active, pl.fc, pl.cp, pl.s, pl.t
    energy, diss, overlap_ratio, xf = pl.energy, pl.diss, pl.ratio, pl.xf
    count = 0
    e_sto = 0.0
    e_dis = 0.0
    worst = 0.0
    worst_p = -1
    for q in range(n_pairs * NSLOT):
        # an inactive slot's diss holds what its forgotten tangential spring released
        # (``clear_history``), an active one's the step's dashpot and slip work
        e_dis += diss[q]
        if active[q] == 0:
            continue
        p = q
        a = pa[q // NSLOT]
        b = pb[q // NSLOT]
        count += 1
        add_segment_force(x, f, t, bi[a], bj[a], par_s[p], fc[p, 0], fc[p, 1], fc[p, 2],
                          cp[p, 0], cp[p, 1], cp[p, 2])
        add_segment_force(x, f, t, bi[b], bj[b], par_t[p], -fc[p, 0], -fc[p, 1], -fc[p, 2],
                          cp[p, 0], cp[p, 1], cp[p, 2])
        if q % NSLOT == NSLOT - 1:
            for c in range(3):
                f[bi[a], c] += xf[q, 0, c]
                f[bj[a], c] += xf[q, 1, c]
                f[bi[b], c] += xf[q, 2, c]
                f[bj[b], c] += xf[q, 3, c]
        e_sto += energy[p]
        if overlap_ratio[p] > worst:
            worst = overlap_ratio[p]
            worst_p = p
    stats[0] = count
    stats[1] = e_sto
    stats[2] = e_dis
    stats[3] = worst
    stats[4] = worst_p // NSLOT if worst_p >= 0 else -1
