"""The Cundall-Strack contact law (seed eqs. 3.5-3.9), shared by every contact type
(bristle-bristle, bristle-body, body-body, mesh-mesh).

Normal: linear spring ``k_n * overlap`` plus an optional viscous term from a coefficient of
restitution, the sum clipped at zero (never attractive). Tangential: an incremental spring
kept per contact across steps (contact history), rotated into the current tangent plane each
step, capped by Coulomb's ``|F_t| <= mu F_n`` on the total normal force F_n (spring + dashpot,
clipped; seed eq. 3.8, mu = tan(phi)). :func:`contact_force` states the law and its energy
exactly. An optional cohesive term (:func:`adhesion`, a pull-off force per contact) is added
along the normal; without it (pull-off 0, the default) the law is the one above, bit for bit.
"""
from __future__ import annotations

import math

from numba import njit

# values of a contact's ``friction`` switch: engine.state.Friction, as plain ints
from ..state import NO_FRICTION, SLIP_EACH_STEP, SLIP_FROZEN  # noqa: F401


def clipped_restitution(zeta: float) -> float:
    """Restitution of a linear spring-dashpot (damping ratio ``zeta``) whose force is never
    attractive, as in :func:`contact_force`: the contact ends when ``k x + c v`` reaches zero,
    before the overlap does, so the rebound is faster than the classical ``exp(-zeta pi /
    sqrt(1 - zeta^2))``. Closed form of the free response ``x'' + 2 zeta x' + x = 0``,
    ``x(0) = 0``, ``x'(0) = 1``, stopped where ``x + 2 zeta x' = 0``."""
    z = float(zeta)
    if z <= 0.0:
        return 1.0
    if z < 1.0:
        wd = math.sqrt(1.0 - z * z)
        u = math.atan2(2.0 * z * wd, 2.0 * z * z - 1.0)
        return -math.exp(-z * u / wd) * (math.cos(u) - z / wd * math.sin(u))
    if z == 1.0:
        return math.exp(-2.0)  # the limit of both branches
    s = math.sqrt(z * z - 1.0)
    t = math.atanh(2.0 * z * s / (2.0 * z * z - 1.0)) / s
    return -math.exp(-z * t) * (math.cosh(s * t) - z / s * math.sinh(s * t))


def restitution_damping_ratio(e: float) -> float:
    """Damping ratio that makes the non-attractive spring-dashpot of :func:`contact_force`
    rebound with restitution ``e`` (v_out / v_in), by bisection of
    :func:`clipped_restitution`, which decreases from 1 at zeta = 0 towards 0."""
    if e >= 1.0:
        return 0.0
    lo, hi = 0.0, 1.0
    while clipped_restitution(hi) > e:
        lo, hi = hi, 2.0 * hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if clipped_restitution(mid) > e:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-14 * hi:
            break
    return 0.5 * (lo + hi)


@njit(cache=True, inline="always")
def normal_stiffness(E1, l1, E2, l2):
    """k_n = 2 E1 l1 E2 l2 / (E1 l1 + E2 l2): two springs in series (seed eqs. 3.5-3.6) with
    characteristic lengths l_i = 2 r_i (DESIGN §3), so that equal materials give k_n = E r."""
    a = E1 * l1
    b = E2 * l2
    return 2.0 * a * b / (a + b)


@njit(cache=True, inline="always")
def contact_force(nx, ny, nz, overlap, vx, vy, vz, kn, kt, mu, zeta, meff,
                  ftx, fty, ftz, friction, dt, fd_prev):
    """Force on side A of a contact whose normal n points from B to A.

    ``v`` is the velocity of A's contact point relative to B's. ``ft`` is the tangential
    force kept from the last step (ignored unless ``friction``); ``fd_prev`` the dashpot's
    normal force of the last step (0 for a contact that starts). Returns
    ``(Fx, Fy, Fz, ftx, fty, ftz, fd, dissipated, stored, released)``: the total force on A,
    the new tangential force and dashpot force to keep, the energy dissipated this step, the
    elastic energy stored, and the energy the contact releases if it lets go at the next
    step (``clear_history``).

    The law (seed eqs. 3.5-3.9), exactly as computed here:

    * normal: ``F_n = max(k_n overlap - c v_n, 0)`` with ``c = 2 zeta sqrt(k_n m_eff)``
      (zeta = 0 without damping): spring plus dashpot, clipped at zero, never attractive;
    * tangential: the kept force turned into the current tangent plane (same magnitude),
      then the trial ``F_t* = F_t,old - k_t v_t dt`` (v_t: the tangential part of v);
      Coulomb's cap on the TOTAL normal force, ``|F_t| <= mu F_n`` (seed eq. 3.8): the
      applied force is the trial returned to the cone, ``F_t = F_t* min(1, mu F_n / |F_t*|)``,
      so friction vanishes whenever the normal force does (the dashpot's clipped rebound);
    * dissipated: the dashpot's work over the step, the trapezoid
      ``-(f_d,prev + f_d) / 2 v_n dt``, plus the slip work
      ``(F_t,old + F_t) . (F_t* - F_t) / (2 k_t)``: the work the tangential force does over
      the step (its mean over the step times the displacement, as the leapfrog's kicks apply
      it) less the change of the spring's energy ``|F_t|^2 / (2 k_t)``, so the energy books
      close; zero while the contact sticks;
    * stored: ``k_n overlap^2 / 2 + |F_t|^2 / (2 k_t)``;
    * released: ``|F_t|^2 / (2 k_t) - f_d v_n dt / 2``, the tangential spring's energy and
      the first half of the coming step's dashpot work (with this step's velocity), booked
      if the contact lets go then.

    Why the trapezoid (second order): ``v`` is the leapfrog's half-step velocity
    v_{k-1/2}, the one that drifted the positions from x_{k-1} to x_k; the two half kicks
    around it give, for a mass m under forces F_{k-1} then F_k,
    ``m|v_k|^2/2 - m|v_{k-1}|^2/2 = (F_{k-1} + F_k)/2 . v_{k-1/2} dt
    + dt^2 (|F_k|^2 - |F_{k-1}|^2) / (8 m)``: the trapezoid is the step's work exactly,
    up to a term that telescopes (the books' error stays O(dt^2), it does not accumulate).
    The spring's trapezoid is exactly the change of ``k_n overlap^2 / 2``; the dashpot's
    must be booked the same way: ``-f_d v_n dt`` alone (the step's end force) misses
    ``(f_d,prev - f_d) v_n dt / 2`` per step, a first-order error of the books. (Both
    halves are booked along the current normal at the current contact point: the turn of
    these over a step leaves a remainder that scales with how fast they turn; the 5 x 5
    brush's damped books fall from 0.0078 % at dt to 0.0007 % at dt/4, test_energy_books.)

    With ``friction == SLIP_FROZEN`` the kept force is the trial force, never capped: the
    applied tangential force is the trial's return to Coulomb's cone, so within a
    quasi-static increment it depends on the net tangential displacement only, not on the
    path the relaxation took (a backward-Euler return mapping per increment); its slip is
    counted as dissipated when a ``SLIP_EACH_STEP`` step commits it.
    """
    fn = kn * overlap
    vn = vx * nx + vy * ny + vz * nz
    diss = 0.0
    if zeta > 0.0:
        c = 2.0 * zeta * math.sqrt(kn * meff)
        fd = -c * vn
        if fn + fd < 0.0:
            fd = -fn
        diss = -0.5 * (fd_prev + fd) * vn * dt
        fnt = fn + fd
    else:
        fd = 0.0
        diss = -0.5 * fd_prev * vn * dt
        fnt = fn
    Fx = fnt * nx
    Fy = fnt * ny
    Fz = fnt * nz
    stored = 0.5 * fn * overlap
    if friction and mu > 0.0:
        # rotate the kept tangential force into the current tangent plane, same magnitude
        old2 = ftx * ftx + fty * fty + ftz * ftz
        dn = ftx * nx + fty * ny + ftz * nz
        ftx -= dn * nx
        fty -= dn * ny
        ftz -= dn * nz
        new2 = ftx * ftx + fty * fty + ftz * ftz
        if new2 > 0.0 and old2 > 0.0:
            s = math.sqrt(old2 / new2)
            ftx *= s
            fty *= s
            ftz *= s
        gx = ftx
        gy = fty
        gz = ftz
        tvx = vx - vn * nx
        tvy = vy - vn * ny
        tvz = vz - vn * nz
        ftx -= kt * tvx * dt
        fty -= kt * tvy * dt
        ftz -= kt * tvz * dt
        cap = mu * fnt  # the total normal force (spring + dashpot, >= 0): seed eq. 3.8
        mag = math.sqrt(ftx * ftx + fty * fty + ftz * ftz)
        ax = ftx
        ay = fty
        az = ftz
        if mag > cap:
            # slip: the trial returned to Coulomb's cone (to zero where F_n = 0)
            s = cap / mag
            ax *= s
            ay *= s
            az *= s
            if friction != SLIP_FROZEN:
                # the slip work over the step (docstring), >= 0 for a step's slip
                diss += ((gx + ax) * (ftx - ax) + (gy + ay) * (fty - ay)
                         + (gz + az) * (ftz - az)) / (2.0 * kt)
                ftx = ax
                fty = ay
                ftz = az
        Fx += ax
        Fy += ay
        Fz += az
        spring = 0.5 * (ax * ax + ay * ay + az * az) / kt
        stored += spring
    else:
        ftx = 0.0
        fty = 0.0
        ftz = 0.0
        spring = 0.0
    released = spring - 0.5 * fd * vn * dt
    return Fx, Fy, Fz, ftx, fty, ftz, fd, diss, stored, released


@njit(cache=True, inline="always")
def smoothstep(u):
    """0 below 0, 1 above 1, 3u^2 - 2u^3 between: the weights that fade contacts in and out."""
    if u <= 0.0:
        return 0.0
    if u >= 1.0:
        return 1.0
    return u * u * (3.0 - 2.0 * u)


HISTORY_COLUMNS = 6  # per contact slot: kept tangential force (0-2), released energy (3),
                     # dashpot force (4), adhered flag (5); ``contact_with_history``


@njit(cache=True, inline="always")
def adhesion(fa, adhered, overlap, vn, dt):
    """The cohesive term of a contact with pull-off force ``fa`` (N, > 0), added to
    :func:`contact_force`'s normal force. ``adhered`` (0 or 1) is the contact's state kept
    from the last step, ``vn`` the normal relative velocity (> 0: separating, the overlap
    shrinks). Returns ``(f, adhered, dissipated, stored, released)``: the normal force to add
    (<= 0: attraction), the new state, and the energies as in ``contact_force``.

    The law, exactly as computed here (a hysteretic constant-force cohesion, acting only
    inside the overlap):

    * a contact starts non-adhered (loading: the plain law); it becomes adhered at its first
      step that unloads (``v_n > 0``) and stays so until it lets go (overlap <= 0, which
      ``clear_history`` forgets);
    * while adhered, the normal force is ``F_n = k_n overlap + f_d - f_a``: the attraction
      ``f_a`` is added to the plain law's spring and dashpot, whose sum stays clipped at
      zero, so the total is never below ``-f_a``: a contact holds against a pull of up to
      ``f_a`` (the pull-off force) and no more. Coulomb's cap stays on the spring and
      dashpot's force (``mu (F_n + f_a)``), so an adhered contact with no load has friction;
    * energy: adhered, the attraction is the force of the potential ``-f_a overlap``, which
      is booked in ``stored`` (negative: the well); turning adhered at an overlap delta
      costs ``f_a delta`` (the work the attraction would have returned on loading), booked
      as dissipated, exactly the trapezoid's ``f_a (delta_prev + delta) / 2`` with
      ``delta_prev = delta + v_n dt``; letting go releases ``-f_a (delta - v_n dt / 2)``
      (the step's trapezoid of a force that ends; negative or positive, O(f_a v dt)). A
      loading-unloading cycle to a peak overlap delta_max thus loses ``f_a delta_max``:
      the law never creates energy. A sphere (mass m, stiffness k_n, no damping) hitting at
      v leaves at ``sqrt(v (v - v_c))`` and is held when ``v < v_c = 2 f_a / sqrt(k_n m)``.
    """
    now = adhered
    dis = 0.0
    if adhered == 0 and vn > 0.0:
        now = 1
        dis = fa * (overlap + 0.5 * vn * dt)
    if now == 0:
        return 0.0, 0, dis, 0.0, 0.0
    return -fa, 1, dis, -fa * overlap, -fa * (overlap - 0.5 * vn * dt)


@njit(cache=True, inline="always")
def clear_history(ft, slot, friction, diss):
    """A contact slot that is not touching forgets its history: ``diss[slot]`` gets the
    energy it released (``ft[slot, 3]``, see ``contact_force``: the tangential spring's
    ``|F_t|^2 / (2 k_t)`` when last computed, which a contact handed over to a neighbouring
    segment, or dropped while its spring is loaded, releases as slip; and the dashpot's
    work over the step in which it let go, ``-f_d v_n dt / 2``: the trapezoid's half of the
    last force, its other half being zero; taken with the last step's velocity, an
    O(dt^2) error once per contact, not per step). A list without history (no friction,
    no damping) has no rows: nothing to release.

    Within a quasi-static increment (``SLIP_FROZEN``) the tangential spring is kept: it is
    the trial of the net tangential displacement since the last commit, and a contact that
    lets go during the increment's move and touches again in its relaxation keeps it (else
    its friction would follow only the slide since it touched again: the first millimetre
    of the wedge study, docs/accuracy.md). The commit's step forgets it, and books column 3,
    if the contact is still open then. The dashpot force is forgotten at once (a contact
    that touches again starts without it); its last half step stays in column 3, booked
    with the spring's energy at the commit, or lost if the contact touches again first
    (the books within an increment are not closed anyway: its slip is booked at the
    commit)."""
    if slot >= ft.shape[0]:
        diss[slot] = 0.0
    elif friction == SLIP_FROZEN:
        diss[slot] = 0.0
        ft[slot, 4] = 0.0
        ft[slot, 5] = 0.0
    else:
        diss[slot] = ft[slot, 3]
        for c in range(HISTORY_COLUMNS):
            ft[slot, c] = 0.0


@njit(cache=True, inline="always")
def contact_with_history(ft, slot, friction, nx, ny, nz, overlap, vx, vy, vz, kn, kt, mu,
                         zeta, meff, dt, fa):
    """``contact_force`` reading and updating the history kept in ``ft[slot]`` (columns
    0-2: the kept tangential force; 3: the energy ``clear_history`` books if the slot lets
    go; 4: the dashpot force of the last step; 5: the adhered state of :func:`adhesion`,
    with pull-off force ``fa``, 0 for none). A list keeps that history (one row per slot)
    where its contacts have friction, damping or adhesion; without rows (``ft.shape[0] ==
    0``) a contact starts afresh every step, which is exact when it has none. Returns (Fx,
    Fy, Fz, dissipated, stored, f_adhesion), the last the attraction applied (0 or -fa)."""
    kept = slot < ft.shape[0]
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    fd_prev = 0.0
    if kept:
        if friction:
            f0 = ft[slot, 0]
            f1 = ft[slot, 1]
            f2 = ft[slot, 2]
        fd_prev = ft[slot, 4]
    Fx, Fy, Fz, f0, f1, f2, fd, dis, sto, rel = contact_force(
        nx, ny, nz, overlap, vx, vy, vz, kn, kt, mu, zeta, meff, f0, f1, f2, friction, dt,
        fd_prev)
    fadh = 0.0
    if fa > 0.0 and kept:
        fadh, state, d_a, s_a, r_a = adhesion(fa, int(ft[slot, 5]), overlap,
                                               vx * nx + vy * ny + vz * nz, dt)
        ft[slot, 5] = state
        Fx += fadh * nx
        Fy += fadh * ny
        Fz += fadh * nz
        dis += d_a
        sto += s_a
        rel += r_a
    if kept:
        ft[slot, 0] = f0
        ft[slot, 1] = f1
        ft[slot, 2] = f2
        ft[slot, 3] = rel
        ft[slot, 4] = fd
    return Fx, Fy, Fz, dis, sto, fadh
