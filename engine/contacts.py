"""Bristle-bristle contacts: the Verlet neighbour list (built through a cell list, O(n)) and
the capsule-capsule narrow phase with the Cundall-Strack law.

A contact is between two segments (capsules) of *different* bristles. Where two segments of
one bristle meet at a joint, a contact whose closest point is exactly that joint is counted by
the segment after the joint only, so a touch at a joint is counted once.

The neighbour list keeps every segment pair whose bounding spheres are closer than the skin.
It is rebuilt (by the step loop) when some node has moved more than half the skin since the
last build; pairs that survive a rebuild keep their tangential history. Its capacity is fixed;
an overflow is reported to the caller, which grows the arrays and steps again.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .bonds import PARALLEL_MIN
from .contact_law import contact_force, normal_stiffness
from .geometry import segment_segment_closest


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


@njit(cache=True)
def build_pair_list(mid, bound, seg_bristle, skin, out_a, out_b):
    """All pairs (a < b) of segments of different bristles whose bounding spheres are closer
    than ``skin``, sorted by (a, b). Returns the number of pairs; if it exceeds the capacity
    of ``out_a`` nothing past the capacity is written and the caller must grow and retry."""
    ns = mid.shape[0]
    if ns == 0:
        return 0
    rmax = 0.0
    lo0 = mid[0, 0]
    lo1 = mid[0, 1]
    lo2 = mid[0, 2]
    hi0 = lo0
    hi1 = lo1
    hi2 = lo2
    for s in range(ns):
        rmax = max(rmax, bound[s])
        lo0 = min(lo0, mid[s, 0])
        lo1 = min(lo1, mid[s, 1])
        lo2 = min(lo2, mid[s, 2])
        hi0 = max(hi0, mid[s, 0])
        hi1 = max(hi1, mid[s, 1])
        hi2 = max(hi2, mid[s, 2])
    cell = 2.0 * rmax + skin
    # keep the grid at most ~2 cells per segment (and finite) however spread the scene is
    while True:
        d0 = int((hi0 - lo0) / cell) + 1
        d1 = int((hi1 - lo1) / cell) + 1
        d2 = int((hi2 - lo2) / cell) + 1
        if d0 * d1 * d2 <= 2 * ns + 64:
            break
        cell *= 1.26
    ncell = d0 * d1 * d2
    cid = np.empty(ns, np.int64)
    count = np.zeros(ncell + 1, np.int64)
    for s in range(ns):
        c0 = min(int((mid[s, 0] - lo0) / cell), d0 - 1)
        c1 = min(int((mid[s, 1] - lo1) / cell), d1 - 1)
        c2 = min(int((mid[s, 2] - lo2) / cell), d2 - 1)
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
                        if dx * dx + dy * dy + dz * dz < lim * lim:
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


@njit(cache=True)
def carry_history(old_a, old_b, old_ft, n_old, new_a, new_b, new_ft, n_new, ns):
    """Copy the tangential history of pairs present in both sorted lists (merge join)."""
    i = 0
    for k in range(n_new):
        key = new_a[k] * ns + new_b[k]
        while i < n_old and old_a[i] * ns + old_b[i] < key:
            i += 1
        if i < n_old and old_a[i] * ns + old_b[i] == key:
            new_ft[k, 0] = old_ft[i, 0]
            new_ft[k, 1] = old_ft[i, 1]
            new_ft[k, 2] = old_ft[i, 2]
        else:
            new_ft[k, 0] = 0.0
            new_ft[k, 1] = 0.0
            new_ft[k, 2] = 0.0


@njit(cache=True, parallel=True)
def bristle_bristle_narrow(x, v, w, rad, mass, bi, bj, seg_has_next, seg_material,
                           pa, pb, n_pairs, ft, friction,
                           E, mu_table, kt_table, zeta_table,
                           active, fc, cp, par_s, par_t, energy, diss, overlap_ratio, dt):
    """Capsule-capsule contacts for the first ``n_pairs`` listed pairs. Per pair, writes the
    force on segment ``pa`` (``fc``; ``pb`` gets ``-fc``), the contact point ``cp`` and the
    closest-point parameters; keeps the tangential history in ``ft``."""
    if n_pairs >= PARALLEL_MIN:
        for p in prange(n_pairs):
            _bristle_bristle_narrow_one(p, x, v, w, rad, mass, bi, bj, seg_has_next, seg_material, pa, pb, n_pairs, ft, friction, E, mu_table, kt_table, zeta_table, active, fc, cp, par_s, par_t, energy, diss, overlap_ratio, dt)
    else:
        for p in range(n_pairs):
            _bristle_bristle_narrow_one(p, x, v, w, rad, mass, bi, bj, seg_has_next, seg_material, pa, pb, n_pairs, ft, friction, E, mu_table, kt_table, zeta_table, active, fc, cp, par_s, par_t, energy, diss, overlap_ratio, dt)



@njit(cache=True)
def _bristle_bristle_narrow_one(p, x, v, w, rad, mass, bi, bj, seg_has_next, seg_material,
                           pa, pb, n_pairs, ft, friction,
                           E, mu_table, kt_table, zeta_table,
                           active, fc, cp, par_s, par_t, energy, diss, overlap_ratio, dt):
    a = pa[p]
    b = pb[p]
    i0 = bi[a]
    i1 = bj[a]
    j0 = bi[b]
    j1 = bj[b]
    active[p] = 0
    s, t = segment_segment_closest(x[i0], x[i1], x[j0], x[j1])
    if (s >= 1.0 and seg_has_next[a]) or (t >= 1.0 and seg_has_next[b]):
        if friction:
            ft[p, 0] = 0.0
            ft[p, 1] = 0.0
            ft[p, 2] = 0.0
        return
    ax = x[i0, 0] + s * (x[i1, 0] - x[i0, 0])
    ay = x[i0, 1] + s * (x[i1, 1] - x[i0, 1])
    az = x[i0, 2] + s * (x[i1, 2] - x[i0, 2])
    bx = x[j0, 0] + t * (x[j1, 0] - x[j0, 0])
    by = x[j0, 1] + t * (x[j1, 1] - x[j0, 1])
    bz = x[j0, 2] + t * (x[j1, 2] - x[j0, 2])
    ra = rad[i0] + s * (rad[i1] - rad[i0])
    rb = rad[j0] + t * (rad[j1] - rad[j0])
    dx = ax - bx
    dy = ay - by
    dz = az - bz
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    ov = ra + rb - d
    if ov <= 0.0:
        if friction:
            ft[p, 0] = 0.0
            ft[p, 1] = 0.0
            ft[p, 2] = 0.0
        return
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
    cx = ax - nx * h
    cy = ay - ny * h
    cz = az - nz * h
    wax = w[i0, 0] + s * (w[i1, 0] - w[i0, 0])
    way = w[i0, 1] + s * (w[i1, 1] - w[i0, 1])
    waz = w[i0, 2] + s * (w[i1, 2] - w[i0, 2])
    wbx = w[j0, 0] + t * (w[j1, 0] - w[j0, 0])
    wby = w[j0, 1] + t * (w[j1, 1] - w[j0, 1])
    wbz = w[j0, 2] + t * (w[j1, 2] - w[j0, 2])
    vax = v[i0, 0] + s * (v[i1, 0] - v[i0, 0]) + way * (cz - az) - waz * (cy - ay)
    vay = v[i0, 1] + s * (v[i1, 1] - v[i0, 1]) + waz * (cx - ax) - wax * (cz - az)
    vaz = v[i0, 2] + s * (v[i1, 2] - v[i0, 2]) + wax * (cy - ay) - way * (cx - ax)
    vbx = v[j0, 0] + t * (v[j1, 0] - v[j0, 0]) + wby * (cz - bz) - wbz * (cy - by)
    vby = v[j0, 1] + t * (v[j1, 1] - v[j0, 1]) + wbz * (cx - bx) - wbx * (cz - bz)
    vbz = v[j0, 2] + t * (v[j1, 2] - v[j0, 2]) + wbx * (cy - by) - wby * (cx - bx)
    ma = mass[i0] + s * (mass[i1] - mass[i0])
    mb = mass[j0] + t * (mass[j1] - mass[j0])
    m1 = seg_material[a]
    m2 = seg_material[b]
    kn = normal_stiffness(E[m1], ra, E[m2], rb)
    if friction:
        f0 = ft[p, 0]
        f1 = ft[p, 1]
        f2 = ft[p, 2]
    else:
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
    Fx, Fy, Fz, f0, f1, f2, dis, sto = contact_force(
        nx, ny, nz, ov, vax - vbx, vay - vby, vaz - vbz, kn, kt_table[m1, m2] * kn,
        mu_table[m1, m2], zeta_table[m1, m2], ma * mb / (ma + mb), f0, f1, f2,
        friction, dt)
    if friction:
        ft[p, 0] = f0
        ft[p, 1] = f1
        ft[p, 2] = f2
    active[p] = 1
    fc[p, 0] = Fx
    fc[p, 1] = Fy
    fc[p, 2] = Fz
    cp[p, 0] = cx
    cp[p, 1] = cy
    cp[p, 2] = cz
    par_s[p] = s
    par_t[p] = t
    energy[p] = sto
    diss[p] = dis
    overlap_ratio[p] = ov / min(ra, rb)


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
def scatter_bristle_bristle(x, f, t, bi, bj, pa, pb, n_pairs, active, fc, cp, par_s, par_t,
                            energy, diss, overlap_ratio, stats):
    """Add the pair forces to the nodes (serial: race-free). ``stats`` gets
    [count, stored energy, dissipated energy, max overlap ratio, pair index of the max]."""
    count = 0
    e_sto = 0.0
    e_dis = 0.0
    worst = 0.0
    worst_p = -1
    for p in range(n_pairs):
        if active[p] == 0:
            continue
        a = pa[p]
        b = pb[p]
        count += 1
        add_segment_force(x, f, t, bi[a], bj[a], par_s[p], fc[p, 0], fc[p, 1], fc[p, 2],
                          cp[p, 0], cp[p, 1], cp[p, 2])
        add_segment_force(x, f, t, bi[b], bj[b], par_t[p], -fc[p, 0], -fc[p, 1], -fc[p, 2],
                          cp[p, 0], cp[p, 1], cp[p, 2])
        e_sto += energy[p]
        e_dis += diss[p]
        if overlap_ratio[p] > worst:
            worst = overlap_ratio[p]
            worst_p = p
    stats[0] = count
    stats[1] = e_sto
    stats[2] = e_dis
    stats[3] = worst
    stats[4] = worst_p
