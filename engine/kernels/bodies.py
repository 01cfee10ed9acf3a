"""Rigid bodies: fixed, kinematic (prescribed), hinge (one fixed axis) and free (6 DOF).

Free bodies keep their angular momentum ``L`` (world frame) as state. The torque changes it in
the kicks; between kicks the torque-free rotation is integrated by the symplectic splitting of
Dullweber, Leimkuhler & McLachlan (J. Chem. Phys. 107, 1997): exact rotations about the
principal axes in the order 1-2-3-2-1. Each sub-rotation turns the body and counter-turns its
body-frame momentum, so ``L`` is conserved to round-off and the energy error stays bounded.

Hinge bodies rotate about a world-fixed axis through a fixed point with the external
dissipation of seed eq. 4.6, ``d(omega)/dt = -k1 omega - k2 sign(omega)``.

Kinematic bodies follow piecewise-cubic Hermite segments in position and constant angular
velocity per segment (``q(t) = exp(omega (t - t0)) q0``); see ``build_bodies.kinematic_segments``.
"""
from __future__ import annotations

import math

from numba import njit

from .orbit import cw_drift_body
from .jit import item_kernel
from .rotations import qexp, qmul, qnormalize, qrot, qrot_inv
from ..state import ACC_HINGE_DISS

FIXED = 0
KINEMATIC = 1
HINGE = 2
FREE = 3


@njit(cache=True, inline="always")
def push_body(bf, btq, k, rx, ry, rz, Fx, Fy, Fz):
    """Add the force F, applied at r from body k's centre of mass, to the body's force and
    torque (r x F) accumulators: the scatter of every contact force onto a body (a reaction
    is pushed as -F, which is bit-identical to subtracting F)."""
    bf[k, 0] += Fx
    bf[k, 1] += Fy
    bf[k, 2] += Fz
    btq[k, 0] += ry * Fz - rz * Fy
    btq[k, 1] += rz * Fx - rx * Fz
    btq[k, 2] += rx * Fy - ry * Fx


@item_kernel
def _free_rotate(q, L, Ip, k, h):
    """Torque-free rotation of body k over time h; q and the world momentum L[k] in place."""
    pw, px, py, pz = q[k, 0], q[k, 1], q[k, 2], q[k, 3]
    # body-frame angular momentum
    b0, b1, b2 = qrot_inv(pw, px, py, pz, L[k, 0], L[k, 1], L[k, 2])
    for axis, frac in ((0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5)):
        tau = h * frac
        if axis == 0:
            if Ip[k, 0] <= 0.0:
                continue
            a = tau * b0 / Ip[k, 0]
            ew, ex, ey, ez = qexp(a, 0.0, 0.0)
            c = math.cos(a)
            s = math.sin(a)
            b1, b2 = c * b1 + s * b2, -s * b1 + c * b2
        elif axis == 1:
            if Ip[k, 1] <= 0.0:
                continue
            a = tau * b1 / Ip[k, 1]
            ew, ex, ey, ez = qexp(0.0, a, 0.0)
            c = math.cos(a)
            s = math.sin(a)
            b2, b0 = c * b2 + s * b0, -s * b2 + c * b0
        else:
            if Ip[k, 2] <= 0.0:
                continue
            a = tau * b2 / Ip[k, 2]
            ew, ex, ey, ez = qexp(0.0, 0.0, a)
            c = math.cos(a)
            s = math.sin(a)
            b0, b1 = c * b0 + s * b1, -s * b0 + c * b1
        pw, px, py, pz = qmul(pw, px, py, pz, ew, ex, ey, ez)
    pw, px, py, pz = qnormalize(pw, px, py, pz)
    q[k, 0] = pw
    q[k, 1] = px
    q[k, 2] = py
    q[k, 3] = pz


@njit(cache=True, inline="always")
def _omega_from_L(q, L, Ip, w, k, frame_rate):
    """w = I^-1 L, less the rate of a frame turning about z (the Hill frame's n; 0 in an
    inertial frame), so that w is the angular velocity relative to the frame."""
    b0, b1, b2 = qrot_inv(q[k, 0], q[k, 1], q[k, 2], q[k, 3], L[k, 0], L[k, 1], L[k, 2])
    o0 = b0 / Ip[k, 0] if Ip[k, 0] > 0.0 else 0.0
    o1 = b1 / Ip[k, 1] if Ip[k, 1] > 0.0 else 0.0
    o2 = b2 / Ip[k, 2] if Ip[k, 2] > 0.0 else 0.0
    w[k, 0], w[k, 1], w[k, 2] = qrot(q[k, 0], q[k, 1], q[k, 2], q[k, 3], o0, o1, o2)
    if frame_rate != 0.0:
        w[k, 2] -= frame_rate


@item_kernel
def kinematic_state(k, time, seg_start, t0, t1, p0, p1, v0, v1, wseg, q0, cursor,
                    pos, v, q, w):
    """Set pose and velocity of kinematic body k at ``time``. Returns True once the profile
    has ended (the caller then holds or frees the body)."""
    first = seg_start[k]
    last = seg_start[k + 1] - 1
    c = cursor[k]
    if c < first:
        c = first
    while c < last and time > t1[c]:
        c += 1
    cursor[k] = c
    ended = False
    if time <= t0[first]:
        c = first
        tau = 0.0
        h = t1[c] - t0[c]
        moving = False
    elif time >= t1[last]:
        c = last
        tau = 1.0
        h = t1[c] - t0[c]
        moving = False
        ended = True
    else:
        h = t1[c] - t0[c]
        tau = (time - t0[c]) / h
        moving = True
    tau2 = tau * tau
    tau3 = tau2 * tau
    h00 = 2 * tau3 - 3 * tau2 + 1
    h10 = tau3 - 2 * tau2 + tau
    h01 = -2 * tau3 + 3 * tau2
    h11 = tau3 - tau2
    d00 = (6 * tau2 - 6 * tau) / h
    d10 = 3 * tau2 - 4 * tau + 1
    d01 = (-6 * tau2 + 6 * tau) / h
    d11 = 3 * tau2 - 2 * tau
    for a in range(3):
        pos[k, a] = h00 * p0[c, a] + h10 * h * v0[c, a] + h01 * p1[c, a] + h11 * h * v1[c, a]
        if moving:
            v[k, a] = d00 * p0[c, a] + d10 * v0[c, a] + d01 * p1[c, a] + d11 * v1[c, a]
            w[k, a] = wseg[c, a]
        else:
            v[k, a] = 0.0
            w[k, a] = 0.0
    el = tau * h
    ew, ex, ey, ez = qexp(wseg[c, 0] * el, wseg[c, 1] * el, wseg[c, 2] * el)
    q[k, 0], q[k, 1], q[k, 2], q[k, 3] = qmul(ew, ex, ey, ez, q0[c, 0], q0[c, 1], q0[c, 2],
                                              q0[c, 3])
    if ended:
        # velocity at release is the profile's final velocity
        for a in range(3):
            v[k, a] = v1[c, a]
            w[k, a] = wseg[c, a]
    return ended


@item_kernel
def bodies_half_kick(bd, tb, acc, dt, orbit_n):
    """Half a velocity kick of free and hinge bodies (``bd``, ``engine.state.Bodies``) from
    the forces of the last evaluation and gravity (``tb.gravity``). ``acc[ACC_HINGE_DISS]``
    accumulates the energy the hinge dissipation removes. ``orbit_n``: the mean motion of the
    Hill frame the scene lives in (0 = inertial; see engine.kernels.orbit)."""
    motion, pos, q, v, w, L, mass, Ip = bd.motion, bd.pos, bd.q, bd.v, bd.w, bd.L, bd.mass, bd.Ip
    f, tq, gravity = bd.f, bd.tq, tb.gravity
    hinge_axis, hinge_point, hinge_inertia = bd.hinge_axis, bd.hinge_point, bd.hinge_inertia
    hinge_k1, hinge_k2 = bd.hinge_k1, bd.hinge_k2
    h = 0.5 * dt
    for k in range(motion.shape[0]):
        m = motion[k]
        if m == FREE:
            for a in range(3):
                v[k, a] += h * (f[k, a] / mass[k] + gravity[a])
                L[k, a] += h * tq[k, a]
            _omega_from_L(q, L, Ip, w, k, orbit_n)
        elif m == HINGE:
            ax = hinge_axis[k, 0]
            ay = hinge_axis[k, 1]
            az = hinge_axis[k, 2]
            rx = pos[k, 0] - hinge_point[k, 0]
            ry = pos[k, 1] - hinge_point[k, 1]
            rz = pos[k, 2] - hinge_point[k, 2]
            Fx = f[k, 0] + mass[k] * gravity[0]
            Fy = f[k, 1] + mass[k] * gravity[1]
            Fz = f[k, 2] + mass[k] * gravity[2]
            torque = ((tq[k, 0] + ry * Fz - rz * Fy) * ax + (tq[k, 1] + rz * Fx - rx * Fz) * ay
                      + (tq[k, 2] + rx * Fy - ry * Fx) * az)
            om = w[k, 0] * ax + w[k, 1] * ay + w[k, 2] * az
            om += h * torque / hinge_inertia[k]
            # seed eq. 4.6, integrated exactly over the half step; never reverses omega
            before = om
            om *= math.exp(-hinge_k1[k] * h)
            red = hinge_k2[k] * h
            if abs(om) <= red:
                om = 0.0
            elif om > 0.0:
                om -= red
            else:
                om += red
            acc[ACC_HINGE_DISS] += 0.5 * hinge_inertia[k] * (before * before - om * om)
            w[k, 0] = om * ax
            w[k, 1] = om * ay
            w[k, 2] = om * az
            v[k, 0] = om * (ay * rz - az * ry)
            v[k, 1] = om * (az * rx - ax * rz)
            v[k, 2] = om * (ax * ry - ay * rx)


@item_kernel
def bodies_drift(bd, dt, time_new, orbit_n):
    """Advance the poses of the bodies ``bd`` (``engine.state.Bodies``) by dt (positions of
    free/hinge bodies; kinematic bodies are set to their profile at ``time_new``; a kinematic
    body whose profile ended and whose ``after`` is free becomes a free body). With
    ``orbit_n`` != 0 a free body's centre follows the exact Clohessy-Wiltshire flow and its
    momentum and orientation turn with the Hill frame (engine.kernels.orbit)."""
    motion, pos, q, v, w, L, Ip = bd.motion, bd.pos, bd.q, bd.v, bd.w, bd.L, bd.Ip
    hinge_axis, hinge_point, after_free = bd.hinge_axis, bd.hinge_point, bd.after_free
    seg_start, t0, t1, p0, p1 = bd.seg_start, bd.t0, bd.t1, bd.p0, bd.p1
    v0, v1, wseg, q0, cursor = bd.v0, bd.v1, bd.wseg, bd.q0, bd.cursor
    for k in range(motion.shape[0]):
        m = motion[k]
        if m == FREE:
            if orbit_n != 0.0:
                cw_drift_body(k, pos, v, L, q, dt, orbit_n)
            else:
                for a in range(3):
                    pos[k, a] += dt * v[k, a]
            _free_rotate(q, L, Ip, k, dt)
            _omega_from_L(q, L, Ip, w, k, orbit_n)
        elif m == HINGE:
            ax = hinge_axis[k, 0]
            ay = hinge_axis[k, 1]
            az = hinge_axis[k, 2]
            om = w[k, 0] * ax + w[k, 1] * ay + w[k, 2] * az
            ang = om * dt
            ew, ex, ey, ez = qexp(ang * ax, ang * ay, ang * az)
            rx, ry, rz = qrot(ew, ex, ey, ez, pos[k, 0] - hinge_point[k, 0],
                              pos[k, 1] - hinge_point[k, 1], pos[k, 2] - hinge_point[k, 2])
            pos[k, 0] = hinge_point[k, 0] + rx
            pos[k, 1] = hinge_point[k, 1] + ry
            pos[k, 2] = hinge_point[k, 2] + rz
            nw, nx, ny, nz = qmul(ew, ex, ey, ez, q[k, 0], q[k, 1], q[k, 2], q[k, 3])
            q[k, 0], q[k, 1], q[k, 2], q[k, 3] = qnormalize(nw, nx, ny, nz)
            v[k, 0] = om * (ay * rz - az * ry)
            v[k, 1] = om * (az * rx - ax * rz)
            v[k, 2] = om * (ax * ry - ay * rx)
        elif m == KINEMATIC:
            ended = kinematic_state(k, time_new, seg_start, t0, t1, p0, p1, v0, v1, wseg, q0,
                                    cursor, pos, v, q, w)
            if ended and after_free[k]:
                motion[k] = FREE
                # world angular momentum from the release angular velocity
                b0, b1, b2 = qrot_inv(q[k, 0], q[k, 1], q[k, 2], q[k, 3], w[k, 0], w[k, 1],
                                      w[k, 2] + orbit_n)
                L[k, 0], L[k, 1], L[k, 2] = qrot(q[k, 0], q[k, 1], q[k, 2], q[k, 3],
                                                 Ip[k, 0] * b0, Ip[k, 1] * b1, Ip[k, 2] * b2)
