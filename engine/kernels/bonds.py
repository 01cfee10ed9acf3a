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

Forces and torques are the exact gradient of the bond's energy (see ``_law``).

For small rotations the shear spring at the midpoint plus the bending spring on the relative
rotation give exactly the Euler-Bernoulli beam element's stiffness matrix (the midpoint shear
force ``12EI/L^3 [(y_j - y_i) - L/2 (theta_i + theta_j)]`` and the node moment
``L/2 F + EI/L (theta_i - theta_j)``), so a uniform cantilever under a tip load is exact at
any resolution. A tapered (frustum) bond's 2 x 2 stiffness in (shear, relative rotation) is
the inverse of the frustum's exact flexibility, which has a coupling term: with it a tapered
cantilever under end loads is exact too, and the axial and twist springs are the frustum's
exact compliances. Forces on both nodes are equal and opposite and torques are consistent,
so linear and angular momentum are conserved to round-off.

The bonds are evaluated in blocks, in passes that the compiler turns into SIMD loops: the
block's bonds' node states and constants are gathered into rows of one scratch array
(``_gather``), then each pass runs over the block's bonds reading and writing whole rows
(``_relative_rotation``, ``_law``, ``_damping``), and only the relative
rotation's angle, which calls libm's ``atan2``, has a scalar pass (``_angle``). Every
number is the one the per-bond evaluation computed, operation for operation: IEEE sums,
products, quotients and square roots round the same in a vector lane, each branch of the
per-bond form is a select of the same two values, nothing is reassociated or fused (no
fastmath), and a node sums its bonds' actions in the same order. A division that a branch
would have skipped may now divide by zero in a lane whose result is not selected, so the
passes compile with numpy's error model (no exception for it). On the wedge's 20 mm state
a bond cost 69 ns in the per-bond form and 37 ns blocked (``benchmarks/bond_kernel.py``).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .rotations import qlog_factor, qmul, qrot, qrot_inv


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


BLOCK = 128          # nodes (bond_node_forces) or bonds (bond_forces) per block
_ST = 2 * BLOCK + 8  # scratch row length: a block's bonds, its nodes' next bonds and the
                     # previous bonds that are not among them (on a bristle's chain, the
                     # first node's alone); not a power of two, or the rows' same entries
                     # fall into one cache set and evict each other (2 * BLOCK doubled the
                     # damped bonds' cost)

# scratch rows (each _ST long): gathered inputs ...
_QIW, _QIX, _QIY, _QIZ, _QJW, _QJX, _QJY, _QJZ = 0, 1, 2, 3, 4, 5, 6, 7
_R0, _R1, _R2 = 8, 9, 10                   # x_j - x_i
_KN, _KS, _KB, _KSB, _KT, _L0 = 11, 12, 13, 14, 15, 16
_DV0, _DV1, _DV2 = 17, 18, 19              # v_j - v_i        (damped only)
_WI0, _WI1, _WI2, _WJ0, _WJ1, _WJ2 = 20, 21, 22, 23, 24, 25
_CN, _CS, _CB, _CT = 26, 27, 28, 29
# ... intermediates ...
_RW, _RX, _RY, _RZ, _VN, _VN2, _FL = 30, 31, 32, 33, 34, 35, 36
_MW, _MX, _MY, _MZ = 37, 38, 39, 40       # the midpoint frame
# ... and results: force on i, torques on i and j, energy, bending moment, dissipation
_FX, _FY, _FZ, _TIX, _TIY, _TIZ, _TJX, _TJY, _TJZ = 41, 42, 43, 44, 45, 46, 47, 48, 49
_EN, _BEND, _DISS = 50, 51, 52
_ROWS = 53


@njit(cache=True, parallel=True)
def bond_forces(x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct,
                bf, bti, btj, benergy, bdiss, bbend, damped, want_energy, dt):
    """Per-bond force on node i (``bf``; node j gets ``-bf``) and torques on i and j.

    Writes elastic energy (``benergy``), dissipated energy of this step (``bdiss``) and the
    bending-moment magnitude (``bbend``) when ``want_energy``. The step loop uses the fused
    ``bond_node_forces``; this per-bond form serves energy evaluations outside it.
    """
    nb = bi.shape[0]
    nblk = (nb + BLOCK - 1) // BLOCK
    if nb >= PARALLEL_MIN_BONDS:
        for c in prange(nblk):
            _bond_block(c * BLOCK, min(nb, (c + 1) * BLOCK), x, v, q, w, bi, bj, kn, ks, kb,
                        ksb, kt, L0, cn, cs, cb, ct, bf, bti, btj, benergy, bdiss, bbend,
                        damped, want_energy, dt)
    else:
        for c in range(nblk):
            _bond_block(c * BLOCK, min(nb, (c + 1) * BLOCK), x, v, q, w, bi, bj, kn, ks, kb,
                        ksb, kt, L0, cn, cs, cb, ct, bf, bti, btj, benergy, bdiss, bbend,
                        damped, want_energy, dt)


@njit(cache=True)
def _bond_block(b0, b1, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct,
                bf, bti, btj, benergy, bdiss, bbend, damped, want_energy, dt):
    """Bonds b0 .. b1 - 1 of :func:`bond_forces`."""
    W = np.empty(_ROWS * _ST)
    lst = np.empty(_ST, np.int64)
    m = b1 - b0
    for k in range(m):
        lst[k] = b0 + k
    _evaluate(W, lst, m, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct,
              damped, want_energy, dt)
    for k in range(m):
        b = b0 + k
        bf[b, 0] = W[_FX * _ST + k]
        bf[b, 1] = W[_FY * _ST + k]
        bf[b, 2] = W[_FZ * _ST + k]
        bti[b, 0] = W[_TIX * _ST + k]
        bti[b, 1] = W[_TIY * _ST + k]
        bti[b, 2] = W[_TIZ * _ST + k]
        btj[b, 0] = W[_TJX * _ST + k]
        btj[b, 1] = W[_TJY * _ST + k]
        btj[b, 2] = W[_TJZ * _ST + k]
    _write_energies(W, lst, m, benergy, bdiss, bbend, damped and want_energy, want_energy)


@njit(cache=True, parallel=True)
def bond_node_forces(nd, bn, damped, want_diss, want_energy, dt):
    """Set each node's force and torque to the sum of its (at most two) bonds' actions, in one
    pass over nodes, without per-bond arrays.

    Nodes are taken in chunks, and a chunk in blocks of ``BLOCK`` nodes; within a block each
    bond is evaluated once, as the next bond of its node i, and its action on node j is
    carried to j where j is in the block; a previous bond found nowhere else in the block
    (the block's first node's) is evaluated again (nothing is shared between chunks, so
    chunks run in parallel race-free).
    The sums are taken in the same order as a per-node gather of ``bond_forces``' per-bond
    actions, so the result equals it exactly. This is the first force stage of a step: it
    overwrites ``f`` and ``t``. The dissipation (written when ``want_diss``: every step of a
    damped run that books its energy) and the energies and bending moments (when
    ``want_energy``: the step the caller reads them) are written by the evaluation as a next
    bond only.
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


@njit(cache=True)
def _bond_chunk(n0, n1, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, bond_prev,
                bond_next, f, t, benergy, bdiss, bbend, damped, want_diss, want_energy, dt):
    """Nodes n0 .. n1 - 1 of :func:`bond_node_forces`, block by block."""
    W = np.empty(_ROWS * _ST)
    lst = np.empty(_ST, np.int64)
    nslot = np.empty(BLOCK, np.int64)
    pslot = np.empty(BLOCK, np.int64)
    for a in range(n0, n1, BLOCK):
        a1 = min(n1, a + BLOCK)
        # the block's bonds: each node's next bond (slots 0 .. own - 1, in node order), then
        # any node's previous bond that is not the node before's next bond (the block's
        # first node's, evaluated again: nothing is shared between blocks)
        m = 0
        for k in range(a, a1):
            nslot[k - a] = -1
            if bond_next[k] >= 0:
                nslot[k - a] = m
                lst[m] = bond_next[k]
                m += 1
        own = m
        for k in range(a, a1):
            pslot[k - a] = -1
            bp = bond_prev[k]
            if bp >= 0:
                if k > a and bond_next[k - 1] == bp:
                    pslot[k - a] = nslot[k - a - 1]
                else:
                    pslot[k - a] = m
                    lst[m] = bp
                    m += 1
        _evaluate(W, lst, m, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct,
                  damped, want_energy, dt)
        for k in range(a, a1):
            fx = 0.0
            fy = 0.0
            fz = 0.0
            tx = 0.0
            ty = 0.0
            tz = 0.0
            s = nslot[k - a]
            if s >= 0:
                fx += W[_FX * _ST + s]
                fy += W[_FY * _ST + s]
                fz += W[_FZ * _ST + s]
                tx += W[_TIX * _ST + s]
                ty += W[_TIY * _ST + s]
                tz += W[_TIZ * _ST + s]
            s = pslot[k - a]
            if s >= 0:
                fx -= W[_FX * _ST + s]
                fy -= W[_FY * _ST + s]
                fz -= W[_FZ * _ST + s]
                tx += W[_TJX * _ST + s]
                ty += W[_TJY * _ST + s]
                tz += W[_TJZ * _ST + s]
            f[k, 0] = fx
            f[k, 1] = fy
            f[k, 2] = fz
            t[k, 0] = tx
            t[k, 1] = ty
            t[k, 2] = tz
        # energies of the next bonds only (a previous bond's are its own node's to write)
        _write_energies(W, lst, own, benergy, bdiss, bbend, damped and want_diss,
                        want_energy)


@njit(cache=True)
def _evaluate(W, lst, m, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, damped,
              want_energy, dt):
    """The bonds ``lst[:m]``: their forces and torques (and dissipation, energy and bending
    moment where asked) into the result rows of ``W``."""
    _gather(W, lst, m, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, damped)
    _relative_rotation(W, m)
    _angle(W, m)
    _law(W, m, want_energy)
    if damped:
        _damping(W, m, dt)


@njit(cache=True)
def _write_energies(W, lst, m, benergy, bdiss, bbend, want_diss, want_energy):
    """The dissipation, energies and bending moments of the bonds ``lst[:m]`` from ``W``
    into the bonds' arrays, those asked for."""
    for s in range(m):
        b = lst[s]
        if want_diss:
            bdiss[b] = W[_DISS * _ST + s]
        if want_energy:
            benergy[b] = W[_EN * _ST + s]
            bbend[b] = W[_BEND * _ST + s]


@njit(cache=True)
def _gather(W, lst, m, x, v, q, w, bi, bj, kn, ks, kb, ksb, kt, L0, cn, cs, cb, ct, damped):
    """The node states and constants of the bonds ``lst[:m]`` into the input rows of ``W``
    (the one pass with the bonds' index arrays)."""
    for s in range(m):
        b = lst[s]
        i = bi[b]
        j = bj[b]
        for c in range(4):
            W[(_QIW + c) * _ST + s] = q[i, c]
            W[(_QJW + c) * _ST + s] = q[j, c]
        for c in range(3):
            W[(_R0 + c) * _ST + s] = x[j, c] - x[i, c]
        W[_KN * _ST + s] = kn[b]
        W[_KS * _ST + s] = ks[b]
        W[_KB * _ST + s] = kb[b]
        W[_KSB * _ST + s] = ksb[b]
        W[_KT * _ST + s] = kt[b]
        W[_L0 * _ST + s] = L0[b]
        if damped:
            for c in range(3):
                W[(_DV0 + c) * _ST + s] = v[j, c] - v[i, c]
                W[(_WI0 + c) * _ST + s] = w[i, c]
                W[(_WJ0 + c) * _ST + s] = w[j, c]
            W[_CN * _ST + s] = cn[b]
            W[_CS * _ST + s] = cs[b]
            W[_CB * _ST + s] = cb[b]
            W[_CT * _ST + s] = ct[b]


@njit(cache=True, error_model="numpy")
def _relative_rotation(W, m):
    """r = q_i^* q_j, taken with r_w >= 0, its vector part's squared norm and norm."""
    for s in range(m):
        rw, rx, ry, rz = qmul(W[_QIW * _ST + s], -W[_QIX * _ST + s], -W[_QIY * _ST + s],
                              -W[_QIZ * _ST + s], W[_QJW * _ST + s], W[_QJX * _ST + s],
                              W[_QJY * _ST + s], W[_QJZ * _ST + s])
        neg = rw < 0.0
        rw = -rw if neg else rw
        rx = -rx if neg else rx
        ry = -ry if neg else ry
        rz = -rz if neg else rz
        vn2 = rx * rx + ry * ry + rz * rz
        W[_RW * _ST + s] = rw
        W[_RX * _ST + s] = rx
        W[_RY * _ST + s] = ry
        W[_RZ * _ST + s] = rz
        W[_VN * _ST + s] = math.sqrt(vn2)
        W[_VN2 * _ST + s] = vn2


@njit(cache=True)
def _angle(W, m):
    """phi = log(r) = fl r_vec (``rotations.qlog_factor``); the one pass with a libm call
    (atan2), so scalar."""
    for s in range(m):
        W[_FL * _ST + s] = qlog_factor(W[_VN * _ST + s], W[_RW * _ST + s])


@njit(cache=True, error_model="numpy")
def _law(W, m, want_energy):
    """Force on node i and torques on i and j of each bond (undamped), the midpoint frame,
    and where ``want_energy`` each bond's elastic energy and bending moment |m_xy|.
    U = 1/2 kn (|r| - L0)^2 + 1/2 ks (d_x^2 + d_y^2) + ksb (d_x phi_y - d_y phi_x)
    + 1/2 (kb (phi_x^2 + phi_y^2) + kt phi_z^2), with d = R_m^T r the bond vector in the
    midpoint frame R_m = R_i exp(phi / 2) and phi = log(q_i^* q_j). Forces and torques are its
    exact gradient (the rotation derivatives use the SO(3) Jacobians of phi and of phi / 2),
    so undamped bristles conserve energy for any rotation; the torques sum to r x F, so
    angular momentum is conserved too."""
    for s in range(m):
        qiw = W[_QIW * _ST + s]
        qix = W[_QIX * _ST + s]
        qiy = W[_QIY * _ST + s]
        qiz = W[_QIZ * _ST + s]
        qjw = W[_QJW * _ST + s]
        qjx = W[_QJX * _ST + s]
        qjy = W[_QJY * _ST + s]
        qjz = W[_QJZ * _ST + s]
        rw = W[_RW * _ST + s]
        rx = W[_RX * _ST + s]
        ry = W[_RY * _ST + s]
        rz = W[_RZ * _ST + s]
        vn = W[_VN * _ST + s]
        vn2 = W[_VN2 * _ST + s]
        fl = W[_FL * _ST + s]
        kn = W[_KN * _ST + s]
        ks = W[_KS * _ST + s]
        kb = W[_KB * _ST + s]
        ksb = W[_KSB * _ST + s]
        kt = W[_KT * _ST + s]
        r0 = W[_R0 * _ST + s]
        r1 = W[_R1 * _ST + s]
        r2 = W[_R2 * _ST + s]
        px = fl * rx
        py = fl * ry
        pz = fl * rz
        # exp(phi / 2) = sqrt(r): (1 + rw, r_vec) normalised (half-angle formula; rw >= 0);
        # below 1e-8 rad the series of rotations.qexp, which needs no square root
        small = vn2 < 1e-16
        hn = 1.0 / math.sqrt((1.0 + rw) * (1.0 + rw) + vn2)
        hw = 1.0 - vn2 / 8.0 if small else (1.0 + rw) * hn
        hx = 0.5 * rx if small else rx * hn
        hy = 0.5 * ry if small else ry * hn
        hz = 0.5 * rz if small else rz * hn
        mw, mx, my, mz = qmul(qiw, qix, qiy, qiz, hw, hx, hy, hz)
        length = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        dx, dy, dz = qrot_inv(mw, mx, my, mz, r0, r1, r2)
        ez = length - W[_L0 * _ST + s]
        # axial force along the chord (independent of the node rotations)
        fa = kn * ez / length
        fa = fa if length > 0.0 else 0.0
        Fx = fa * r0
        Fy = fa * r1
        Fz = fa * r2
        # shear force and midpoint moment: the gradients of U in d and phi (with the taper's
        # coupling ksb (d_x phi_y - d_y phi_x), zero for a uniform bond)
        sfx = ks * dx + ksb * py
        sfy = ks * dy - ksb * px
        mlx = kb * px - ksb * dy
        mly = kb * py + ksb * dx
        mlz = kt * pz
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
        # (1/th^2 - (1 + cos th) / (2 th sin th), and (1 + cos th) / sin th = cot(th / 2))
        th2 = px * px + py * py + pz * pz
        c_inv = (1.0 / 12.0 + th2 / 720.0 if th2 < 1e-8
                 else 1.0 / th2 - rw / (2.0 * math.sqrt(th2) * vn))
        h2 = 0.25 * th2
        inr = 1.0 / math.sqrt(rw * rw + vn2)
        sn = vn * inr      # sin(|phi| / 2)
        cs_ = rw * inr     # cos(|phi| / 2)
        hth = math.sqrt(h2)
        a1 = 0.5 - h2 / 24.0 if h2 < 1e-8 else sn * sn / ((1.0 + cs_) * h2)
        a2 = 1.0 / 6.0 - h2 / 120.0 if h2 < 1e-8 else (hth - sn) / (h2 * hth)
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
        W[_FX * _ST + s] = Fx
        W[_FY * _ST + s] = Fy
        W[_FZ * _ST + s] = Fz
        W[_TIX * _ST + s] = tgx + tjx
        W[_TIY * _ST + s] = tgy + tjy
        W[_TIZ * _ST + s] = tgz + tjz
        W[_TJX * _ST + s] = tix
        W[_TJY * _ST + s] = tiy
        W[_TJZ * _ST + s] = tiz
        W[_MW * _ST + s] = mw
        W[_MX * _ST + s] = mx
        W[_MY * _ST + s] = my
        W[_MZ * _ST + s] = mz
        if want_energy:
            W[_EN * _ST + s] = (0.5 * (kn * ez * ez + ks * (dx * dx + dy * dy)
                                       + kb * (px * px + py * py) + kt * pz * pz)
                                + ksb * (dx * py - dy * px))
            W[_BEND * _ST + s] = math.sqrt(mlx * mlx + mly * mly)


@njit(cache=True, error_model="numpy")
def _damping(W, m, dt):
    """Viscous damping on the strain rates in the co-rotating midpoint frame, added to the
    results of :func:`_law`, and the energy it dissipates over ``dt``."""
    for s in range(m):
        mw = W[_MW * _ST + s]
        mx = W[_MX * _ST + s]
        my = W[_MY * _ST + s]
        mz = W[_MZ * _ST + s]
        r0 = W[_R0 * _ST + s]
        r1 = W[_R1 * _ST + s]
        r2 = W[_R2 * _ST + s]
        wi0 = W[_WI0 * _ST + s]
        wi1 = W[_WI1 * _ST + s]
        wi2 = W[_WI2 * _ST + s]
        wj0 = W[_WJ0 * _ST + s]
        wj1 = W[_WJ1 * _ST + s]
        wj2 = W[_WJ2 * _ST + s]
        cn = W[_CN * _ST + s]
        cs = W[_CS * _ST + s]
        cb = W[_CB * _ST + s]
        ct = W[_CT * _ST + s]
        wmx = 0.5 * (wi0 + wj0)
        wmy = 0.5 * (wi1 + wj1)
        wmz = 0.5 * (wi2 + wj2)
        vx = W[_DV0 * _ST + s] - (wmy * r2 - wmz * r1)
        vy = W[_DV1 * _ST + s] - (wmz * r0 - wmx * r2)
        vz = W[_DV2 * _ST + s] - (wmx * r1 - wmy * r0)
        lvx, lvy, lvz = qrot_inv(mw, mx, my, mz, vx, vy, vz)
        ox, oy, oz = qrot_inv(mw, mx, my, mz, wj0 - wi0, wj1 - wi1, wj2 - wi2)
        dfx, dfy, dfz = qrot(mw, mx, my, mz, cs * lvx, cs * lvy, cn * lvz)
        dmx, dmy, dmz = qrot(mw, mx, my, mz, cb * ox, cb * oy, ct * oz)
        W[_FX * _ST + s] += dfx
        W[_FY * _ST + s] += dfy
        W[_FZ * _ST + s] += dfz
        hx_ = 0.5 * (r1 * dfz - r2 * dfy)
        hy_ = 0.5 * (r2 * dfx - r0 * dfz)
        hz_ = 0.5 * (r0 * dfy - r1 * dfx)
        W[_TIX * _ST + s] += dmx + hx_
        W[_TIY * _ST + s] += dmy + hy_
        W[_TIZ * _ST + s] += dmz + hz_
        W[_TJX * _ST + s] += -dmx + hx_
        W[_TJY * _ST + s] += -dmy + hy_
        W[_TJZ * _ST + s] += -dmz + hz_
        W[_DISS * _ST + s] = dt * (cs * (lvx * lvx + lvy * lvy) + cn * lvz * lvz
                                   + cb * (ox * ox + oy * oy) + ct * oz * oz)


@njit(cache=True, inline="always")
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
