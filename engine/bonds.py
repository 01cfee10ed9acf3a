"""Bristle bonds: the beam-like interaction between consecutive nodes of a bristle.

Each bond carries the stiffnesses of seed eq. 3.1: normal ``E A / L``, shear ``12 E I / L^3``,
bending ``E I / L`` and twisting ``G J / L``. They act in a co-rotational frame at the bond's
midpoint (the node frames' mean rotation), so rotations may be large while strains stay small:

* ``d = R_m^T (x_j - x_i)``: axial strain ``d_z - L0`` and shear displacement ``(d_x, d_y)``;
* ``phi = log(q_i^* q_j)``: bending (x, y) and twist (z) rotation vector.

For small rotations the shear spring at the midpoint plus the bending spring on the relative
rotation give exactly the Euler-Bernoulli beam element's stiffness matrix (the midpoint shear
force ``12EI/L^3 [(y_j - y_i) - L/2 (theta_i + theta_j)]`` and the node moment
``L/2 F + EI/L (theta_i - theta_j)``), so a cantilever under a tip load is exact at any
resolution. Forces on both nodes are equal and opposite and torques are consistent, so linear
and angular momentum are conserved to round-off.
"""
from __future__ import annotations

import math

from numba import njit, prange

from .rotations import qexp, qlog, qmul, qrot, qrot_inv


PARALLEL_MIN = 4096  # below this many items a loop runs serially: no thread-pool latency


@njit(cache=True, parallel=True)
def bond_forces(x, v, q, w, bi, bj, kn, ks, kb, kt, L0, cn, cs, cb, ct,
                bf, bti, btj, benergy, bdiss, bbend, damped, want_energy, dt):
    """Per-bond force on node i (``bf``; node j gets ``-bf``) and torques on i and j.

    Writes elastic energy (``benergy``), dissipated energy of this step (``bdiss``) and the
    bending-moment magnitude (``bbend``) when ``want_energy``.
    """
    nb = bi.shape[0]
    if nb >= PARALLEL_MIN:
        for b in prange(nb):
            _bond(b, x, v, q, w, bi, bj, kn, ks, kb, kt, L0, cn, cs, cb, ct, bf, bti, btj,
                  benergy, bdiss, bbend, damped, want_energy, dt)
    else:
        for b in range(nb):
            _bond(b, x, v, q, w, bi, bj, kn, ks, kb, kt, L0, cn, cs, cb, ct, bf, bti, btj,
                  benergy, bdiss, bbend, damped, want_energy, dt)


@njit(cache=True, inline="always")
def _bond(b, x, v, q, w, bi, bj, kn, ks, kb, kt, L0, cn, cs, cb, ct,
          bf, bti, btj, benergy, bdiss, bbend, damped, want_energy, dt):
    if True:
        i = bi[b]
        j = bj[b]
        # relative rotation of j with respect to i, in i's frame
        rw, rx, ry, rz = qmul(q[i, 0], -q[i, 1], -q[i, 2], -q[i, 3],
                              q[j, 0], q[j, 1], q[j, 2], q[j, 3])
        px, py, pz = qlog(rw, rx, ry, rz)
        hw, hx, hy, hz = qexp(0.5 * px, 0.5 * py, 0.5 * pz)
        mw, mx, my, mz = qmul(q[i, 0], q[i, 1], q[i, 2], q[i, 3], hw, hx, hy, hz)
        r0 = x[j, 0] - x[i, 0]
        r1 = x[j, 1] - x[i, 1]
        r2 = x[j, 2] - x[i, 2]
        dx, dy, dz = qrot_inv(mw, mx, my, mz, r0, r1, r2)
        ez = dz - L0[b]
        flx = ks[b] * dx
        fly = ks[b] * dy
        flz = kn[b] * ez
        mlx = kb[b] * px
        mly = kb[b] * py
        mlz = kt[b] * pz
        if damped:
            # relative velocity of j w.r.t. i in the co-rotating midpoint frame
            wmx = 0.5 * (w[i, 0] + w[j, 0])
            wmy = 0.5 * (w[i, 1] + w[j, 1])
            wmz = 0.5 * (w[i, 2] + w[j, 2])
            vx = v[j, 0] - v[i, 0] - (wmy * r2 - wmz * r1)
            vy = v[j, 1] - v[i, 1] - (wmz * r0 - wmx * r2)
            vz = v[j, 2] - v[i, 2] - (wmx * r1 - wmy * r0)
            lvx, lvy, lvz = qrot_inv(mw, mx, my, mz, vx, vy, vz)
            ox, oy, oz = qrot_inv(mw, mx, my, mz, w[j, 0] - w[i, 0], w[j, 1] - w[i, 1],
                                  w[j, 2] - w[i, 2])
            flx += cs[b] * lvx
            fly += cs[b] * lvy
            flz += cn[b] * lvz
            mlx += cb[b] * ox
            mly += cb[b] * oy
            mlz += ct[b] * oz
            if want_energy:
                bdiss[b] = dt * (cs[b] * (lvx * lvx + lvy * lvy) + cn[b] * lvz * lvz
                                 + cb[b] * (ox * ox + oy * oy) + ct[b] * oz * oz)
        Fx, Fy, Fz = qrot(mw, mx, my, mz, flx, fly, flz)
        Mx, My, Mz = qrot(mw, mx, my, mz, mlx, mly, mlz)
        bf[b, 0] = Fx
        bf[b, 1] = Fy
        bf[b, 2] = Fz
        # moment of the midpoint force about each node: (r/2) x F, same for both nodes
        hx_ = 0.5 * (r1 * Fz - r2 * Fy)
        hy_ = 0.5 * (r2 * Fx - r0 * Fz)
        hz_ = 0.5 * (r0 * Fy - r1 * Fx)
        bti[b, 0] = Mx + hx_
        bti[b, 1] = My + hy_
        bti[b, 2] = Mz + hz_
        btj[b, 0] = -Mx + hx_
        btj[b, 1] = -My + hy_
        btj[b, 2] = -Mz + hz_
        if want_energy:
            benergy[b] = 0.5 * (kn[b] * ez * ez + ks[b] * (dx * dx + dy * dy)
                                + kb[b] * (px * px + py * py) + kt[b] * pz * pz)
            bbend[b] = kb[b] * math.sqrt(px * px + py * py)


@njit(cache=True, parallel=True)
def gather_bond_forces(bond_prev, bond_next, bf, bti, btj, f, t):
    """Set each node's force and torque to the sum of its (at most two) bonds' actions.

    This is the first force stage of a step: it overwrites ``f`` and ``t``.
    """
    n = f.shape[0]
    if n >= PARALLEL_MIN:
        for k in prange(n):
            _gather(k, bond_prev, bond_next, bf, bti, btj, f, t)
    else:
        for k in range(n):
            _gather(k, bond_prev, bond_next, bf, bti, btj, f, t)


@njit(cache=True, inline="always")
def _gather(k, bond_prev, bond_next, bf, bti, btj, f, t):
    if True:
        fx = 0.0
        fy = 0.0
        fz = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        b = bond_next[k]
        if b >= 0:
            fx += bf[b, 0]
            fy += bf[b, 1]
            fz += bf[b, 2]
            tx += bti[b, 0]
            ty += bti[b, 1]
            tz += bti[b, 2]
        b = bond_prev[k]
        if b >= 0:
            fx -= bf[b, 0]
            fy -= bf[b, 1]
            fz -= bf[b, 2]
            tx += btj[b, 0]
            ty += btj[b, 1]
            tz += btj[b, 2]
        f[k, 0] = fx
        f[k, 1] = fy
        f[k, 2] = fz
        t[k, 0] = tx
        t[k, 1] = ty
        t[k, 2] = tz
