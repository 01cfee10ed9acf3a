"""Bristle bonds: the beam-like interaction between consecutive nodes of a bristle.

Each bond carries the stiffnesses of seed eq. 3.1: normal ``E A / L``, shear ``12 E I / L^3``,
bending ``E I / L`` and twisting ``G J / L``, and, for a tapered bond, a shear-bending
coupling ``ksb`` (``build_bristles.frustum_bond_stiffness``). They act in a co-rotational
frame at the bond's midpoint (the node frames' mean rotation), so rotations may be large while
strains stay small:

* axial strain: the chord length ``|x_j - x_i| - L0``;
* shear displacement: ``(d_x, d_y)`` of ``d = R_m^T (x_j - x_i)``, the bond vector in the
  midpoint frame;
* ``phi = log(q_i^* q_j)``: bending (x, y) and twist (z) rotation vector.

Forces and torques are the exact gradient of the bond's energy (see ``_bond_eval``).

For small rotations the shear spring at the midpoint plus the bending spring on the relative
rotation give exactly the Euler-Bernoulli beam element's stiffness matrix (the midpoint shear
force ``12EI/L^3 [(y_j - y_i) - L/2 (theta_i + theta_j)]`` and the node moment
``L/2 F + EI/L (theta_i - theta_j)``), so a uniform cantilever under a tip load is exact at
any resolution. A tapered (frustum) bond's 2 x 2 stiffness in (shear, relative rotation) is
the inverse of the frustum's exact flexibility, which has a coupling term: with it a tapered
cantilever under end loads is exact too, and the axial and twist springs are the frustum's
exact compliances. Forces on both nodes are equal and opposite and torques are consistent,
so linear and angular momentum are conserved to round-off.
"""
from __future__ import annotations

import math

from numba import njit, prange

from .rotations import qmul, qrot, qrot_inv


# Below PARALLEL_MIN items a loop runs serially: no thread-pool latency. So each parallel
# kernel (nodes_kick_drift, nodes_kick, nodes_kick_drift_cw, bond_forces, bond_node_forces,
# bristle_bristle_narrow, bristle_body_narrow) holds its loop twice, a ``prange`` and a
# ``range`` over the same per-item function; numba cannot choose between them at run time in
# one loop. Both are needed (benchmarks/prange_latency.py, a 3-column half kick, CPU us per
# call, on the shared 2-core test machine): 16 items 1.0 serial / 2.5 prange with 1 thread,
# 1.0 / 18.4 with 2 (the idle worker spins); 512 items 4.5 / 44 with 2; 4096 items 19 / 26;
# 65536 items 194 / 232 (the serial loop of a big scene leaves the second core idle).
# A prange pays once a call holds some tens of microseconds of work, so the threshold is
# counted in items of each kernel's own cost: PARALLEL_MIN for the light per-node kernels
# (a few ns a node) and the pairs; PARALLEL_MIN_BONDS nodes for the bonds (about 0.1 us a
# node); PARALLEL_MIN_CANDIDATES for the bristle-body candidates (about 1 us each), which
# with the old common 4096 stayed serial on every brush below 4096 bristles and took half a
# box-pressed step on one core while the other waited (benchmarks/threads.py). A kernel
# cannot ask numba for its thread count and stay cached, so with one thread (a study's
# workers) a prange loop runs on that one thread, about 1.5 us a call more than the serial
# twin: from 256 candidates (some 250 us of work) that is under 1 %.
PARALLEL_MIN = 4096
PARALLEL_MIN_BONDS = 1024
PARALLEL_MIN_CANDIDATES = 256
NODE_CHUNK = 512     # nodes per parallel task of ``bond_node_forces``


@njit(cache=True, parallel=True)
def bond_forces(x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct,
                bf, bti, btj, benergy, bdiss, bbend, damped, want_energy, dt):
    """Per-bond force on node i (``bf``; node j gets ``-bf``) and torques on i and j.

    Writes elastic energy (``benergy``), dissipated energy of this step (``bdiss``) and the
    bending-moment magnitude (``bbend``) when ``want_energy``. The step loop uses the fused
    ``bond_node_forces``; this per-bond form serves energy evaluations outside it.
    """
    nb = bi.shape[0]
    if nb >= PARALLEL_MIN_BONDS:
        for b in prange(nb):
            _bond(b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, bf, bti, btj,
                  benergy, bdiss, bbend, damped, want_energy, dt)
    else:
        for b in range(nb):
            _bond(b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, bf, bti, btj,
                  benergy, bdiss, bbend, damped, want_energy, dt)


@njit(cache=True, inline="always")
def _bond(b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct,
          bf, bti, btj, benergy, bdiss, bbend, damped, want_energy, dt):
    Fx, Fy, Fz, Tix, Tiy, Tiz, Tjx, Tjy, Tjz = _bond_eval(
        b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, benergy, bdiss, bbend,
        damped, want_energy, want_energy, dt)
    bf[b, 0] = Fx
    bf[b, 1] = Fy
    bf[b, 2] = Fz
    bti[b, 0] = Tix
    bti[b, 1] = Tiy
    bti[b, 2] = Tiz
    btj[b, 0] = Tjx
    btj[b, 1] = Tjy
    btj[b, 2] = Tjz


@njit(cache=True, parallel=True)
def bond_node_forces(nd, bn, damped, want_diss, want_energy, dt):
    """Set each node's force and torque to the sum of its (at most two) bonds' actions, in one
    pass over nodes, without per-bond arrays.

    Nodes are taken in chunks; within a chunk each bond is evaluated once, as the next bond
    of its node i, and its action on node j is carried to j (the node after i on the
    bristle). A chunk's first node re-evaluates its previous bond (nothing is shared between
    chunks, so chunks run in parallel race-free). The sums are taken in the same order as
    a per-node gather of ``bond_forces``' per-bond actions, so the result equals it exactly. This
    is the first force stage of a step: it overwrites ``f`` and ``t``. The dissipation
    (written when ``want_diss``: every step of a damped run that books its energy) and the
    energies and bending moments (when ``want_energy``: the step the caller reads them) are
    written by the evaluation as a next bond only.
    """
    x, v, q, w, f, t = nd.x, nd.v, nd.q, nd.w, nd.f, nd.t
    bond_prev, bond_next = nd.bond_prev, nd.bond_next
    bi, bj, kn, ks, kb, ksb, kt, L0 = bn.i, bn.j, bn.kn, bn.ks, bn.kb, bn.ksb, bn.kt, bn.L0
    cn, cs, cb, ct = bn.cn, bn.cs, bn.cb, bn.ct
    benergy, bdiss, bbend = bn.energy, bn.diss, bn.bend
    n = f.shape[0]
    if n >= PARALLEL_MIN_BONDS:
        nchunk = (n + NODE_CHUNK - 1) // NODE_CHUNK
        for c in prange(nchunk):
            _bond_chunk(c * NODE_CHUNK, min(n, (c + 1) * NODE_CHUNK), x, v, q, w, bi, bj, kn,
                        ks, kb, ksb, kt, L0, cn, cs, cb, ct, bond_prev, bond_next, f, t, benergy,
                        bdiss, bbend, damped, want_diss, want_energy, dt)
    else:
        _bond_chunk(0, n, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, bond_prev,
                    bond_next, f, t, benergy, bdiss, bbend, damped, want_diss, want_energy, dt)


@njit(cache=True, inline="always")
def _bond_chunk(n0, n1, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, bond_prev,
                bond_next, f, t, benergy, bdiss, bbend, damped, want_diss, want_energy, dt):
    last = -1          # the bond evaluated as the previous node's next bond ...
    cFx = 0.0          # ... its force on node i and its torque on node j
    cFy = 0.0
    cFz = 0.0
    cTx = 0.0
    cTy = 0.0
    cTz = 0.0
    for k in range(n0, n1):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        bn_ = bond_next[k]
        nFx = 0.0
        nFy = 0.0
        nFz = 0.0
        nTx = 0.0
        nTy = 0.0
        nTz = 0.0
        if bn_ >= 0:
            nFx, nFy, nFz, Tix, Tiy, Tiz, nTx, nTy, nTz = _bond_eval(
                bn_, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, benergy, bdiss,
                bbend, damped, want_diss, want_energy, dt)
            fx += nFx
            fy += nFy
            fz += nFz
            tx += Tix
            ty += Tiy
            tz += Tiz
        bp = bond_prev[k]
        if bp >= 0:
            if bp != last:
                cFx, cFy, cFz, _x, _y, _z, cTx, cTy, cTz = _bond_eval(
                    bp, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, benergy,
                    bdiss, bbend, damped, False, False, dt)
            fx -= cFx
            fy -= cFy
            fz -= cFz
            tx += cTx
            ty += cTy
            tz += cTz
        f[k, 0] = fx
        f[k, 1] = fy
        f[k, 2] = fz
        t[k, 0] = tx
        t[k, 1] = ty
        t[k, 2] = tz
        last = bn_
        cFx = nFx
        cFy = nFy
        cFz = nFz
        cTx = nTx
        cTy = nTy
        cTz = nTz


@njit(cache=True, inline="always")
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(cache=True, inline="always")
def _bond_eval(b, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct,
               benergy, bdiss, bbend, damped, want_diss, want_energy, dt):
    """One bond: returns the force on node i (node j gets its negative) and the torques on
    i and j. Energy U = 1/2 kn (|r| - L0)^2 + 1/2 ks (d_x^2 + d_y^2)
    + ksb (d_x phi_y - d_y phi_x) + 1/2 (kb (phi_x^2 + phi_y^2) + kt phi_z^2), with
    d = R_m^T r the bond vector in the
    midpoint frame R_m = R_i exp(phi / 2) and phi = log(q_i^* q_j). Forces and torques are its
    exact gradient (the rotation derivatives use the SO(3) Jacobians of phi and of phi / 2),
    so undamped bristles conserve energy for any rotation; the torques sum to r x F, so
    angular momentum is conserved too. Writes the damping's dissipation of this step
    (``bdiss``) when ``want_diss``, the elastic energy and bending moment when
    ``want_energy``."""
    i = bi[b]
    j = bj[b]
    qiw, qix, qiy, qiz = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    qjw, qjx, qjy, qjz = q[j, 0], q[j, 1], q[j, 2], q[j, 3]
    rw, rx, ry, rz = qmul(qiw, -qix, -qiy, -qiz, qjw, qjx, qjy, qjz)
    # phi = log(r) as in rotations.qlog; r = (cos(|phi|/2), sin(|phi|/2) phi/|phi|) also
    # gives every sine and cosine below without calling sin or cos
    if rw < 0.0:
        rw, rx, ry, rz = -rw, -rx, -ry, -rz
    vn2 = rx * rx + ry * ry + rz * rz
    vn = math.sqrt(vn2)
    if vn < 1e-12:
        px, py, pz = 2.0 * rx, 2.0 * ry, 2.0 * rz
    else:
        fl = 2.0 * math.atan2(vn, rw) / vn
        px, py, pz = fl * rx, fl * ry, fl * rz
    # exp(phi / 2) = sqrt(r): (1 + rw, r_vec) normalised (half-angle formula; rw >= 0);
    # below 1e-8 rad the series of rotations.qexp, which needs no square root
    if vn2 < 1e-16:
        hw = 1.0 - vn2 / 8.0
        hx = 0.5 * rx
        hy = 0.5 * ry
        hz = 0.5 * rz
    else:
        hn = 1.0 / math.sqrt((1.0 + rw) * (1.0 + rw) + vn2)
        hw = (1.0 + rw) * hn
        hx = rx * hn
        hy = ry * hn
        hz = rz * hn
    mw, mx, my, mz = qmul(qiw, qix, qiy, qiz, hw, hx, hy, hz)
    r0 = x[j, 0] - x[i, 0]
    r1 = x[j, 1] - x[i, 1]
    r2 = x[j, 2] - x[i, 2]
    length = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    dx, dy, dz = qrot_inv(mw, mx, my, mz, r0, r1, r2)
    ez = length - L0[b]
    # axial force along the chord (independent of the node rotations)
    fa = kn[b] * ez / length if length > 0.0 else 0.0
    Fx = fa * r0
    Fy = fa * r1
    Fz = fa * r2
    # shear force and midpoint moment: the gradients of U in d and phi (with the taper's
    # coupling ksb (d_x phi_y - d_y phi_x), zero for a uniform bond)
    sfx = ks[b] * dx + ksb[b] * py
    sfy = ks[b] * dy - ksb[b] * px
    mlx = kb[b] * px - ksb[b] * dy
    mly = kb[b] * py + ksb[b] * dx
    mlz = kt[b] * pz
    gx, gy, gz = _cross(dx, dy, dz, sfx, sfy, 0.0)   # d x f_shear, midpoint frame
    sx, sy, sz = qrot(mw, mx, my, mz, sfx, sfy, 0.0)
    Fx += sx
    Fy += sy
    Fz += sz
    # rotation derivatives: tau_i = R_m g + R_j Jl^-1(phi) [m - 1/2 Jl(phi/2) g],
    #                       tau_j = R_i Jr^-1(phi) [1/2 Jl(phi/2) g - m]
    # coefficients of the SO(3) Jacobians of a rotation vector with squared angle th2:
    # c_inv for J^-1 = I -+ 1/2 W + c_inv W^2 (of phi) and a1, a2 for J = I +- a1 W + a2 W^2
    # (of phi / 2); Taylor series at small angles, else the sines and cosines from r
    th2 = px * px + py * py + pz * pz
    if th2 < 1e-8:
        c_inv = 1.0 / 12.0 + th2 / 720.0
    else:
        # 1/th^2 - (1 + cos th) / (2 th sin th), and (1 + cos th) / sin th = cot(th / 2)
        c_inv = 1.0 / th2 - rw / (2.0 * math.sqrt(th2) * vn)
    h2 = 0.25 * th2
    if h2 < 1e-8:
        a1 = 0.5 - h2 / 24.0
        a2 = 1.0 / 6.0 - h2 / 120.0
    else:
        inr = 1.0 / math.sqrt(rw * rw + vn2)
        sn = vn * inr      # sin(|phi| / 2)
        cs_ = rw * inr     # cos(|phi| / 2)
        hth = math.sqrt(h2)
        a1 = sn * sn / ((1.0 + cs_) * h2)   # (1 - cos) / h2 without cancellation
        a2 = (hth - sn) / (h2 * hth)
    hpx = 0.5 * px
    hpy = 0.5 * py
    hpz = 0.5 * pz
    ux, uy, uz = _cross(hpx, hpy, hpz, gx, gy, gz)
    uux, uuy, uuz = _cross(hpx, hpy, hpz, ux, uy, uz)
    jgx = 0.5 * (gx + a1 * ux + a2 * uux)   # 1/2 Jl(phi/2) g
    jgy = 0.5 * (gy + a1 * uy + a2 * uuy)
    jgz = 0.5 * (gz + a1 * uz + a2 * uuz)
    ax_ = mlx - jgx
    ay_ = mly - jgy
    az_ = mlz - jgz
    # Jl^-1(phi) a = a - 1/2 phi x a + c phi x (phi x a)
    cx1, cy1, cz1 = _cross(px, py, pz, ax_, ay_, az_)
    cx2, cy2, cz2 = _cross(px, py, pz, cx1, cy1, cz1)
    lx = ax_ - 0.5 * cx1 + c_inv * cx2
    ly = ay_ - 0.5 * cy1 + c_inv * cy2
    lz = az_ - 0.5 * cz1 + c_inv * cz2
    # Jr^-1(phi) (-a) = -(a + 1/2 phi x a + c phi x (phi x a))
    kx = -(ax_ + 0.5 * cx1 + c_inv * cx2)
    ky = -(ay_ + 0.5 * cy1 + c_inv * cy2)
    kz = -(az_ + 0.5 * cz1 + c_inv * cz2)
    tgx, tgy, tgz = qrot(mw, mx, my, mz, gx, gy, gz)
    tjx, tjy, tjz = qrot(qjw, qjx, qjy, qjz, lx, ly, lz)
    tix, tiy, tiz = qrot(qiw, qix, qiy, qiz, kx, ky, kz)
    Tix = tgx + tjx
    Tiy = tgy + tjy
    Tiz = tgz + tjz
    Tjx = tix
    Tjy = tiy
    Tjz = tiz
    if damped:
        # viscous damping on the strain rates in the co-rotating midpoint frame
        wmx = 0.5 * (w[i, 0] + w[j, 0])
        wmy = 0.5 * (w[i, 1] + w[j, 1])
        wmz = 0.5 * (w[i, 2] + w[j, 2])
        vx = v[j, 0] - v[i, 0] - (wmy * r2 - wmz * r1)
        vy = v[j, 1] - v[i, 1] - (wmz * r0 - wmx * r2)
        vz = v[j, 2] - v[i, 2] - (wmx * r1 - wmy * r0)
        lvx, lvy, lvz = qrot_inv(mw, mx, my, mz, vx, vy, vz)
        ox, oy, oz = qrot_inv(mw, mx, my, mz, w[j, 0] - w[i, 0], w[j, 1] - w[i, 1],
                              w[j, 2] - w[i, 2])
        dfx, dfy, dfz = qrot(mw, mx, my, mz, cs[b] * lvx, cs[b] * lvy, cn[b] * lvz)
        dmx, dmy, dmz = qrot(mw, mx, my, mz, cb[b] * ox, cb[b] * oy, ct[b] * oz)
        Fx += dfx
        Fy += dfy
        Fz += dfz
        hx_ = 0.5 * (r1 * dfz - r2 * dfy)
        hy_ = 0.5 * (r2 * dfx - r0 * dfz)
        hz_ = 0.5 * (r0 * dfy - r1 * dfx)
        Tix += dmx + hx_
        Tiy += dmy + hy_
        Tiz += dmz + hz_
        Tjx += -dmx + hx_
        Tjy += -dmy + hy_
        Tjz += -dmz + hz_
        if want_diss:
            bdiss[b] = dt * (cs[b] * (lvx * lvx + lvy * lvy) + cn[b] * lvz * lvz
                             + cb[b] * (ox * ox + oy * oy) + ct[b] * oz * oz)
    if want_energy:
        benergy[b] = (0.5 * (kn[b] * ez * ez + ks[b] * (dx * dx + dy * dy)
                             + kb[b] * (px * px + py * py) + kt[b] * pz * pz)
                      + ksb[b] * (dx * py - dy * px))
        bbend[b] = math.sqrt(mlx * mlx + mly * mly)
    return Fx, Fy, Fz, Tix, Tiy, Tiz, Tjx, Tjy, Tjz
