"""Sampled pose controllers on free bodies (a chaser's thrusters and wheels), and constant
external loads on free bodies. Spec: ``engine.model.spec.PoseController``; docs/mission.md.

Each controller samples its body's state when the step loop's time reaches its next sample
time (every ``sample_interval``), computes a PID command on the position and attitude
errors, expresses it in the body's mesh axes, clips each axis to the saturation, and holds
that body-axis force and torque until the next sample (zero-order hold; the thrusters turn
with the body in between).

Anti-windup (``P_ANTI_WINDUP``, spec ``anti_windup``): conditional integration ("clamping").
At each sample the loop's integral is first advanced by e h; if the resulting command
saturates some body axis and the integral's increment, in body axes, pushes that axis
further into its limit (same sign as the clipped command), the increment is rejected and the
command recomputed with the old integral. The integral thus stops growing while the actuator
cannot deliver more, and a saturated loop comes out of saturation without the overshoot of
a wound-up integrator; while unsaturated it is the plain PID. Each sample also counts, per
body axis, whether the force and the torque command were clipped (``S_SAT_F``, ``S_SAT_T``):
the saturation fraction is that count over ``S_SAMPLES``.

Release rule (``release_below``, or ``release_below_fraction`` of the reference's |omega|
at the first sample): at the first sample where the
reference body's angular speed |omega| is below the threshold, the controller latches
"released" and from that sample on aims at the target position plus ``release_offset``
(world axes): the chaser backs off and its brush lets go of the target. Every step it adds the held force and torque to the body and
accumulates the impulse, the Delta-v (integral of |F| / m) and the angular impulse.

Arrays (built by ``engine.build``): ``ci`` (C, 2) int64: controlled body, reference body or
-1; ``cp`` (C, P_SIZE) parameters; ``cs`` (C, S_SIZE) state (layout below: the recorder reads
the same slots).
"""
from __future__ import annotations

import math

from numba import njit

from .rotations import qmul, qrot, qrot_inv

# parameter slots
P_KP, P_KD, P_KI = 0, 1, 2          # position loop
P_KPA, P_KDA, P_KIA = 3, 4, 5       # attitude loop
P_INTERVAL = 6
P_MAXF = 7                           # 3: per body axis
P_MAXT = 10                          # 3
P_DB_POS = 13
P_DB_ATT = 14
P_TARGET = 15                        # 3: position, or offset from the reference's centre
P_QTARGET = 18                       # 4: target orientation of the mesh axes
P_QBM = 22                           # 4: principal frame -> mesh axes (q_mesh = q_body q_bm)
P_RELEASE_BELOW = 26                 # rad/s: release once |omega_reference| < this; 0 = never
P_RELEASE_OFFSET = 27                # 3: added to the target position once released (m)
P_ANTI_WINDUP = 30                   # 1: conditional integration (below); 0: plain integral
P_RELEASE_FRACTION = 31              # release once |omega_ref| < this x its first-sample value
P_SIZE = 32

# state slots
S_NEXT = 0
S_CMD_F = 1        # 3: commanded force, body (mesh) axes, before saturation
S_APP_F = 4        # 3: applied force, body axes
S_CMD_T = 7        # 3
S_APP_T = 10       # 3
S_INT_POS = 13     # 3: integral of the position error (m s)
S_INT_ATT = 16     # 3: integral of the attitude error (rad s)
S_IMPULSE = 19     # 3: integral of the applied force, world axes (N s)
S_ANG_IMPULSE = 22  # 3: integral of the applied torque, world axes (N m s)
S_DELTA_V = 25     # integral of |F| / m (m/s)
S_ANG_IMPULSE_ABS = 26  # integral of |torque| (N m s)
S_ERR_POS = 27     # 3: position error at the last sample, world axes (m)
S_ERR_ATT = 30     # 3: attitude error (rotation vector) at the last sample, world axes (rad)
S_SAMPLES = 33
S_RELEASED = 34    # 0 holding, 1 released (latched)
S_RELEASE_TIME = 35  # time of the sample that released (s); -1 until then (engine.build)
S_SAT_F = 36       # 3: samples at which each body axis's force command was clipped
S_SAT_T = 39       # 3: the same for the torque
S_REF_SPIN0 = 42   # the reference's |omega| at the first sample (rad/s); 0 without one
S_SIZE = 43


@njit(cache=True, inline="always")
def _clip(x, limit):
    if x > limit:
        return limit
    if x < -limit:
        return -limit
    return x


@njit(cache=True)
def _pid_axis3(c, cp, cs, mw, mx, my, mz, kp_slot, ki_slot, int_slot, max_slot,
               ex, ey, ez, dx, dy, dz, h):
    """One loop's PID command (world axes): kp e + d + ki (I + e h), with I advanced by e h
    unless anti-windup rejects the increment (module docstring). ``d`` is the derivative
    term, already scaled."""
    kp = cp[c, kp_slot]
    ki = cp[c, ki_slot]
    ix = cs[c, int_slot] + ex * h
    iy = cs[c, int_slot + 1] + ey * h
    iz = cs[c, int_slot + 2] + ez * h
    ux = kp * ex + dx + ki * ix
    uy = kp * ey + dy + ki * iy
    uz = kp * ez + dz + ki * iz
    if cp[c, P_ANTI_WINDUP] != 0.0 and ki != 0.0:
        bx, by, bz = qrot_inv(mw, mx, my, mz, ux, uy, uz)
        gx, gy, gz = qrot_inv(mw, mx, my, mz, ki * ex * h, ki * ey * h, ki * ez * h)
        reject = ((abs(bx) > cp[c, max_slot] and gx * bx > 0.0)
                  or (abs(by) > cp[c, max_slot + 1] and gy * by > 0.0)
                  or (abs(bz) > cp[c, max_slot + 2] and gz * bz > 0.0))
        if reject:
            ix -= ex * h
            iy -= ey * h
            iz -= ez * h
            ux = kp * ex + dx + ki * ix
            uy = kp * ey + dy + ki * iy
            uz = kp * ez + dz + ki * iz
    cs[c, int_slot] = ix
    cs[c, int_slot + 1] = iy
    cs[c, int_slot + 2] = iz
    return ux, uy, uz


@njit(cache=True)
def _sample(c, ci, cp, cs, pos, q, v, w, mass, time):
    k = ci[c, 0]
    r = ci[c, 1]
    h = cp[c, P_INTERVAL]
    # ---- release rule: latch once the reference's spin is below the threshold
    if r >= 0:
        spin = math.sqrt(w[r, 0] * w[r, 0] + w[r, 1] * w[r, 1] + w[r, 2] * w[r, 2])
        if cs[c, S_SAMPLES] == 0.0:
            cs[c, S_REF_SPIN0] = spin
        below = cp[c, P_RELEASE_BELOW]
        if cp[c, P_RELEASE_FRACTION] > 0.0:
            below = cp[c, P_RELEASE_FRACTION] * cs[c, S_REF_SPIN0]
        if cs[c, S_RELEASED] == 0.0 and below > 0.0 and spin < below:
            cs[c, S_RELEASED] = 1.0
            cs[c, S_RELEASE_TIME] = time
    # the body's mesh axes (the thrusters' and wheels' axes)
    mw, mx, my, mz = qmul(q[k, 0], q[k, 1], q[k, 2], q[k, 3], cp[c, P_QBM], cp[c, P_QBM + 1],
                          cp[c, P_QBM + 2], cp[c, P_QBM + 3])
    # ---- position loop (world axes)
    tx0 = cp[c, P_TARGET]
    ty0 = cp[c, P_TARGET + 1]
    tz0 = cp[c, P_TARGET + 2]
    if cs[c, S_RELEASED] != 0.0:
        tx0 += cp[c, P_RELEASE_OFFSET]
        ty0 += cp[c, P_RELEASE_OFFSET + 1]
        tz0 += cp[c, P_RELEASE_OFFSET + 2]
    ex = tx0 - pos[k, 0]
    ey = ty0 - pos[k, 1]
    ez = tz0 - pos[k, 2]
    dvx = -v[k, 0]
    dvy = -v[k, 1]
    dvz = -v[k, 2]
    if r >= 0:
        ex += pos[r, 0]
        ey += pos[r, 1]
        ez += pos[r, 2]
        dvx += v[r, 0]
        dvy += v[r, 1]
        dvz += v[r, 2]
    cs[c, S_ERR_POS] = ex
    cs[c, S_ERR_POS + 1] = ey
    cs[c, S_ERR_POS + 2] = ez
    fx = fy = fz = 0.0
    if math.sqrt(ex * ex + ey * ey + ez * ez) > cp[c, P_DB_POS]:
        fx, fy, fz = _pid_axis3(c, cp, cs, mw, mx, my, mz, P_KP, P_KI, S_INT_POS, P_MAXF,
                                ex, ey, ez, cp[c, P_KD] * dvx, cp[c, P_KD] * dvy,
                                cp[c, P_KD] * dvz, h)
    # ---- attitude loop: rotation vector of q_target q_mesh^-1 (world axes)
    ew, exq, eyq, ezq = qmul(cp[c, P_QTARGET], cp[c, P_QTARGET + 1], cp[c, P_QTARGET + 2],
                             cp[c, P_QTARGET + 3], mw, -mx, -my, -mz)
    if ew < 0.0:
        ew, exq, eyq, ezq = -ew, -exq, -eyq, -ezq
    sn = math.sqrt(exq * exq + eyq * eyq + ezq * ezq)
    if sn > 0.0:
        ang = 2.0 * math.atan2(sn, ew)
        ax = ang * exq / sn
        ay = ang * eyq / sn
        az = ang * ezq / sn
    else:
        ang = 0.0
        ax = ay = az = 0.0
    cs[c, S_ERR_ATT] = ax
    cs[c, S_ERR_ATT + 1] = ay
    cs[c, S_ERR_ATT + 2] = az
    tx = ty = tz = 0.0
    if ang > cp[c, P_DB_ATT]:
        tx, ty, tz = _pid_axis3(c, cp, cs, mw, mx, my, mz, P_KPA, P_KIA, S_INT_ATT, P_MAXT,
                                ax, ay, az, -cp[c, P_KDA] * w[k, 0],
                                -cp[c, P_KDA] * w[k, 1], -cp[c, P_KDA] * w[k, 2], h)
    # ---- into the body's mesh axes, saturate per axis
    bfx, bfy, bfz = qrot_inv(mw, mx, my, mz, fx, fy, fz)
    btx, bty, btz = qrot_inv(mw, mx, my, mz, tx, ty, tz)
    cs[c, S_CMD_F] = bfx
    cs[c, S_CMD_F + 1] = bfy
    cs[c, S_CMD_F + 2] = bfz
    cs[c, S_CMD_T] = btx
    cs[c, S_CMD_T + 1] = bty
    cs[c, S_CMD_T + 2] = btz
    for a in range(3):
        if abs(cs[c, S_CMD_F + a]) > cp[c, P_MAXF + a]:
            cs[c, S_SAT_F + a] += 1.0
        if abs(cs[c, S_CMD_T + a]) > cp[c, P_MAXT + a]:
            cs[c, S_SAT_T + a] += 1.0
    cs[c, S_APP_F] = _clip(bfx, cp[c, P_MAXF])
    cs[c, S_APP_F + 1] = _clip(bfy, cp[c, P_MAXF + 1])
    cs[c, S_APP_F + 2] = _clip(bfz, cp[c, P_MAXF + 2])
    cs[c, S_APP_T] = _clip(btx, cp[c, P_MAXT])
    cs[c, S_APP_T + 1] = _clip(bty, cp[c, P_MAXT + 1])
    cs[c, S_APP_T + 2] = _clip(btz, cp[c, P_MAXT + 2])
    cs[c, S_SAMPLES] += 1.0


@njit(cache=True)
def apply_controllers(ci, cp, cs, pos, q, v, w, mass, f, tq, time, dt):
    """Sample the controllers whose time has come, then add every controller's held force
    and torque to its body. Returns their work over this step (F.v + T.w) dt."""
    work = 0.0
    for c in range(ci.shape[0]):
        if time >= cs[c, S_NEXT] - 1e-9 * dt:
            _sample(c, ci, cp, cs, pos, q, v, w, mass, time)
            while cs[c, S_NEXT] <= time + 1e-9 * dt:
                cs[c, S_NEXT] += cp[c, P_INTERVAL]
        k = ci[c, 0]
        mw, mx, my, mz = qmul(q[k, 0], q[k, 1], q[k, 2], q[k, 3], cp[c, P_QBM],
                              cp[c, P_QBM + 1], cp[c, P_QBM + 2], cp[c, P_QBM + 3])
        fx, fy, fz = qrot(mw, mx, my, mz, cs[c, S_APP_F], cs[c, S_APP_F + 1],
                          cs[c, S_APP_F + 2])
        tx, ty, tz = qrot(mw, mx, my, mz, cs[c, S_APP_T], cs[c, S_APP_T + 1],
                          cs[c, S_APP_T + 2])
        f[k, 0] += fx
        f[k, 1] += fy
        f[k, 2] += fz
        tq[k, 0] += tx
        tq[k, 1] += ty
        tq[k, 2] += tz
        cs[c, S_IMPULSE] += fx * dt
        cs[c, S_IMPULSE + 1] += fy * dt
        cs[c, S_IMPULSE + 2] += fz * dt
        cs[c, S_ANG_IMPULSE] += tx * dt
        cs[c, S_ANG_IMPULSE + 1] += ty * dt
        cs[c, S_ANG_IMPULSE + 2] += tz * dt
        cs[c, S_DELTA_V] += math.sqrt(fx * fx + fy * fy + fz * fz) * dt / mass[k]
        cs[c, S_ANG_IMPULSE_ABS] += math.sqrt(tx * tx + ty * ty + tz * tz) * dt
        work += (fx * v[k, 0] + fy * v[k, 1] + fz * v[k, 2]
                 + tx * w[k, 0] + ty * w[k, 1] + tz * w[k, 2]) * dt
    return work


@njit(cache=True)
def apply_external(ext, motion, v, w, f, tq, dt):
    """Constant external force and torque (world axes) on free bodies; returns their work."""
    work = 0.0
    for k in range(ext.shape[0]):
        if motion[k] != 3:  # FREE
            continue
        for a in range(3):
            f[k, a] += ext[k, a]
            tq[k, a] += ext[k, 3 + a]
            work += (ext[k, a] * v[k, a] + ext[k, 3 + a] * w[k, a]) * dt
    return work
