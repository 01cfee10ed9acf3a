"""Relative orbital dynamics: the Clohessy-Wiltshire (Hill) equations about a circular
reference orbit of mean motion n, in the Hill frame (x radial outwards, y along-track,
z orbit normal; the frame turns at Omega = n z about the inertial frame):

    x'' = 3 n^2 x + 2 n y',    y'' = -2 n x',    z'' = -n^2 z.

How they are integrated. The step loop is a kick-drift-kick splitting of H = H_CW + V, where
V is the potential of the bonds and contacts (and H_CW the free CW Hamiltonian, quadratic in
the Hill coordinates and their canonical momenta p = v + Omega x r). The "drift" of every
free node and free body centre is the *exact* CW flow over dt (the closed-form state
transition matrix below), the kicks add the forces as before. Each sub-step is the exact
flow of a Hamiltonian piece, so the composition is symplectic and time-reversible: the
Jacobi integral ``C = |v|^2/2 - 3/2 n^2 x^2 + 1/2 n^2 z^2 + V/m`` stays bounded (its error
oscillates with O(dt^2) amplitude and does not drift), and a body with no force on it follows
the closed-form CW solution to round-off. A kick is the same whether written for v or for
p, because p - v = Omega x r does not change while r is held.

Attitude. A free body keeps its angular momentum L (inertial, in Hill-frame components) and
its orientation relative to the Hill frame. In the turning frame both turn by -n dt about z
each step (the frame's rotation), which commutes with the torque-free rotation; the angular
velocity the rest of the engine sees (contacts, mounted roots, records) is the one relative
to the Hill frame, ``w = I^-1 L - Omega``. A node (isotropic inertia) obeys
``w' = -Omega x w + torque / I`` in the frame: its spin turns by -n dt about z.

Gravity gradient (optional): torque ``3 n^2 x_hat x (I x_hat)`` on free and hinge bodies,
potential ``n^2/2 (tr I - 3 x_hat . I x_hat)``. Hinge bodies (an axis held in the Hill frame)
also get the tidal force ``m (3 n^2 x, 0, -n^2 z)`` on their centre and the frame's
centrifugal torque ``n^2 z_hat x (I z_hat)``; the Coriolis force does no work and so has no
moment about a fixed axis. Fixed and kinematic bodies and fixed roots
are held in the Hill frame.

With n = 0 none of this runs: the step loop takes its ordinary path (``Flags.orbit``).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .bonds import PARALLEL_MIN
from .rotations import qexp, qmul, qnormalize, qrot, qrot_inv

@njit(cache=True, inline="always")
def _one_minus_cos(th):
    s = math.sin(0.5 * th)
    return 2.0 * s * s


@njit(cache=True, inline="always")
def _sin_minus_arg(th):
    """sin(th) - th without cancellation for small th."""
    if abs(th) < 1e-2:
        t2 = th * th
        return -th * t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0)))
    return math.sin(th) - th


@njit(cache=True)
def cw_coefficients(n, tau):
    """The CW state transition matrix over tau as its 13 distinct entries (see cw_flow), a
    tuple: the step loop's kernels are compiled without reference counting
    (``engine.kernels.jit.item_kernel``), so an array made here would never be freed (two
    leaked per step with two free bodies in orbit)."""
    th = n * tau
    s = math.sin(th)
    c = math.cos(th)
    omc = _one_minus_cos(th)
    smt = _sin_minus_arg(th)
    return (1.0 + 3.0 * omc,          # x <- x        (4 - 3c)
            s / n,                    # x <- vx
            2.0 * omc / n,            # x <- vy
            6.0 * smt,                # y <- x        6 (s - th)
            (4.0 * smt + th) / n,     # y <- vy       (4 s - 3 th) / n
            c,                        # z <- z, vx <- vx, vz <- vz
            3.0 * n * s,              # vx <- x
            2.0 * s,                  # vx <- vy, -(vy <- vx)
            -6.0 * n * omc,           # vy <- x
            1.0 - 4.0 * omc,          # vy <- vy      (4c - 3)
            -n * s,                   # vz <- z
            s,                        # (s)
            th)


@njit(cache=True, inline="always")
def cw_apply(cf, x, y, z, vx, vy, vz):
    """The exact CW flow of one state by the coefficients of cw_coefficients."""
    nx = cf[0] * x + cf[1] * vx + cf[2] * vy
    ny = cf[3] * x + y - cf[2] * vx + cf[4] * vy
    nz = cf[5] * z + cf[1] * vz
    nvx = cf[6] * x + cf[5] * vx + cf[7] * vy
    nvy = cf[8] * x - cf[7] * vx + cf[9] * vy
    nvz = cf[10] * z + cf[5] * vz
    return nx, ny, nz, nvx, nvy, nvz


@njit(cache=True, inline="always")
def cw_apply_row(cf, pos, vel, k):
    """:func:`cw_apply` to row ``k`` of a position and a velocity array, in place."""
    (pos[k, 0], pos[k, 1], pos[k, 2], vel[k, 0], vel[k, 1], vel[k, 2]) = cw_apply(
        cf, pos[k, 0], pos[k, 1], pos[k, 2], vel[k, 0], vel[k, 1], vel[k, 2])


@njit(cache=True)
def cw_flow(n, tau, state):
    """Closed-form CW solution: the state (x, y, z, vx, vy, vz) after tau (a new array)."""
    cf = cw_coefficients(n, tau)
    r = cw_apply(cf, state[0], state[1], state[2], state[3], state[4], state[5])
    return np.array(r)


@njit(cache=True, inline="always")
def _turn_z(c, s, a0, a1):
    """Rotate (a0, a1) by the angle whose cos/sin are c, s about z."""
    return c * a0 - s * a1, s * a0 + c * a1


@njit(cache=True, inline="always")
def _kick_drift_cw(n_, x, v, q, w, f, t, inv_mass, inv_inertia, dt, cf, ch, sh):
    h = 0.5 * dt
    im = inv_mass[n_]
    if im == 0.0:
        return
    for a in range(3):
        v[n_, a] += h * f[n_, a] * im
    cw_apply_row(cf, x, v, n_)
    ii = inv_inertia[n_]
    w0 = w[n_, 0] + h * t[n_, 0] * ii
    w1 = w[n_, 1] + h * t[n_, 1] * ii
    w2 = w[n_, 2] + h * t[n_, 2] * ii
    # spin turns by -n dt about z (frame rotation), split around the orientation drift
    w0, w1 = _turn_z(ch, -sh, w0, w1)
    ew, ex, ey, ez = qexp(dt * w0, dt * w1, dt * w2)
    nw, nx, ny, nz = qmul(ew, ex, ey, ez, q[n_, 0], q[n_, 1], q[n_, 2], q[n_, 3])
    q[n_, 0], q[n_, 1], q[n_, 2], q[n_, 3] = qnormalize(nw, nx, ny, nz)
    w0, w1 = _turn_z(ch, -sh, w0, w1)
    w[n_, 0] = w0
    w[n_, 1] = w1
    w[n_, 2] = w2


@njit(cache=True, parallel=True)
def nodes_kick_drift_cw(x, v, q, w, f, t, inv_mass, inv_inertia, dt, n):
    """The nodes' half kick and drift in the Hill frame: the drift is the exact CW flow."""
    cf = cw_coefficients(n, dt)
    ch = math.cos(0.5 * n * dt)
    sh = math.sin(0.5 * n * dt)
    if x.shape[0] >= PARALLEL_MIN:
        for k in prange(x.shape[0]):
            _kick_drift_cw(k, x, v, q, w, f, t, inv_mass, inv_inertia, dt, cf, ch, sh)
    else:
        for k in range(x.shape[0]):
            _kick_drift_cw(k, x, v, q, w, f, t, inv_mass, inv_inertia, dt, cf, ch, sh)


@njit(cache=True)
def cw_drift_body(k, pos, v, L, q, dt, n):
    """Exact CW flow of body k's centre over dt and the frame's turn of its momentum and
    orientation (the torque-free rotation is done by the caller; the two commute)."""
    cf = cw_coefficients(n, dt)
    cw_apply_row(cf, pos, v, k)
    c = math.cos(n * dt)
    s = math.sin(n * dt)
    L[k, 0], L[k, 1] = _turn_z(c, -s, L[k, 0], L[k, 1])
    ew, ex, ey, ez = qexp(0.0, 0.0, -n * dt)
    nw, nx, ny, nz = qmul(ew, ex, ey, ez, q[k, 0], q[k, 1], q[k, 2], q[k, 3])
    q[k, 0], q[k, 1], q[k, 2], q[k, 3] = qnormalize(nw, nx, ny, nz)


@njit(cache=True, inline="always")
def _inertia_times_xhat(q, Ip, k):
    """I_world x_hat of body k (x_hat = radial unit vector of the Hill frame)."""
    b0, b1, b2 = qrot_inv(q[k, 0], q[k, 1], q[k, 2], q[k, 3], 1.0, 0.0, 0.0)
    return qrot(q[k, 0], q[k, 1], q[k, 2], q[k, 3], Ip[k, 0] * b0, Ip[k, 1] * b1,
                Ip[k, 2] * b2)


@njit(cache=True, inline="always")
def _inertia_times_zhat(q, Ip, k):
    b0, b1, b2 = qrot_inv(q[k, 0], q[k, 1], q[k, 2], q[k, 3], 0.0, 0.0, 1.0)
    return qrot(q[k, 0], q[k, 1], q[k, 2], q[k, 3], Ip[k, 0] * b0, Ip[k, 1] * b1,
                Ip[k, 2] * b2)


@njit(cache=True)
def orbit_body_forces(motion, pos, q, mass, Ip, f, tq, n, gravity_gradient):
    """Tidal force and the frame's centrifugal torque ``n^2 z_hat x (I z_hat)`` on hinge
    bodies (a free body has both inside its exact drift), and the gravity-gradient torque on
    free and hinge bodies."""
    n2 = n * n
    for k in range(motion.shape[0]):
        m = motion[k]
        if m == 2:  # HINGE
            f[k, 0] += mass[k] * 3.0 * n2 * pos[k, 0]
            f[k, 2] -= mass[k] * n2 * pos[k, 2]
            e0, e1, e2 = _inertia_times_zhat(q, Ip, k)
            tq[k, 0] -= n2 * e1
            tq[k, 1] += n2 * e0
        if gravity_gradient and (m == 2 or m == 3):
            d0, d1, d2 = _inertia_times_xhat(q, Ip, k)
            # 3 n^2 x_hat x (I x_hat), x_hat = (1, 0, 0)
            tq[k, 1] -= 3.0 * n2 * d2
            tq[k, 2] += 3.0 * n2 * d1


def orbit_energy_terms(n: float, gravity_gradient: bool, node_mass, node_x, motion, mass,
                       pos, R, Ip, L) -> np.ndarray:
    """The orbital part of the Jacobi integral (J) of F states, from arrays: ``node_mass``
    (N,) and ``node_x`` (F, N, 3) of the free nodes; per body ``motion`` (F, B) codes,
    ``mass`` (B,), ``pos`` (F, B, 3), ``R`` (F, B, 3, 3) principal frame -> world, ``Ip``
    (B, 3), ``L`` (F, B, 3) inertial angular momentum. Returns (F,). The terms: the tidal
    potential of free nodes and free / hinge bodies, -m (3/2 n^2 x^2 - 1/2 n^2 z^2); the
    frame term of a free body's rotational energy, -1/2 n L_z (with ``w`` relative to the
    frame the engine's kinetic energy 1/2 w.L plus this is 1/2 w_rel.I w_rel - 1/2
    Omega.I Omega plus a constant); the frame's centrifugal potential of a hinge body,
    -1/2 n^2 I_zz; with ``gravity_gradient`` the potential n^2/2 (tr I - 3 I_xx)."""
    FREE, HINGE = 3, 2  # engine.kernels.bodies' motion codes (bodies imports this module)
    n2 = n * n
    xs = np.asarray(node_x, float)
    e = -np.einsum("n,fn->f", np.asarray(node_mass, float),
                   1.5 * n2 * xs[..., 0] ** 2 - 0.5 * n2 * xs[..., 2] ** 2)
    motion = np.asarray(motion)
    free, hinge = motion == FREE, motion == HINGE
    moving = free | hinge
    pos = np.asarray(pos, float)
    tidal = np.asarray(mass, float)[None, :] * (1.5 * n2 * pos[..., 0] ** 2
                                                 - 0.5 * n2 * pos[..., 2] ** 2)
    e -= np.where(moving, tidal, 0.0).sum(axis=1)
    e -= np.where(free, 0.5 * n * np.asarray(L, float)[..., 2], 0.0).sum(axis=1)
    # world inertia entries I_aa = sum_k R[a, k]^2 Ip[k]
    Iw = np.einsum("fbak,bk->fba", np.asarray(R, float) ** 2, np.asarray(Ip, float))
    e -= np.where(hinge, 0.5 * n2 * Iw[..., 2], 0.0).sum(axis=1)
    if gravity_gradient:
        gg = 0.5 * n2 * (np.asarray(Ip, float).sum(axis=1)[None, :] - 3.0 * Iw[..., 0])
        e += np.where(moving, gg, 0.0).sum(axis=1)
    return e
