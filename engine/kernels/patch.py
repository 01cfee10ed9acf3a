"""The reduced brush as a contact element (issue 25 item 2): a compliant patch carried by a
body, the brush's footprint at its tip plane, that touches every other colliding closed mesh
with the fitted reduced law of ``engine.model.reduced_law``.

The patch (an a x b rectangle, body frame) is sampled by a grid of points, each carrying its
cell's area ``A_i``. A point inside another body's closed mesh has the interference ``d_i``
(its distance to that body's closest surface point, found as for mesh-mesh contact:
``body_contacts.closest_triangle`` within ``reach`` and the feature's pseudo-normal for the
inside test) and the rate ``dd_i = -v_rel . n`` (n the outward surface normal there, v_rel
the velocity of the patch's material point relative to the other body's). Per point:

* normal force = the law's force per unit area times the point's area::

      F_i = (A_i / A_law) k d_i^p (u(dd_i) + c dd_i),   clipped at 0,

  ``A_law`` the footprint the law was fitted on, so a flat contact of the law's whole
  footprint gives exactly the fitted ``k d^p (u + c dd)``; a larger footprint carries
  proportionally more (the brush is taken as uniform);
* friction opposing the point's slip ``v_i`` (the tangential part of v_rel)::

      F_t,i = mu (F_n / 1 N)^q tanh(|v_i| / v_s) F_i,

  with ``mu_eff`` taken at the patch's total normal force ``F_n = sum F_i`` (the law is
  fitted on whole-patch loads) and each point's own slip speed. The law's torsional moment
  is then not a separate term: it follows from the friction's distribution over the points;
  for a flat contact spinning fast against ``v_s`` it is ``mu_eff F_n r_t``, ``r_t`` the
  mean distance of the footprint's points from its centre (``reduced_law.torsion_radius``,
  tests/engine/test_patch.py checks it).

Each point's force acts on the patch's body at the point and its opposite on the other
body at the same point (action = reaction at one point: linear and angular momentum are
conserved to round-off). Energy: the stored (elastic) energy of a point is ``(A_i / A_law)
k d_i^(p+1) / (p+1)`` (the loading branch at zero rate); what the law's force does beyond
that elastic force, ``(F_i - (A_i / A_law) k d_i^p) dd_i`` (rate damping and the unloading
branch), and the friction's ``|F_t,i| |v_i|`` are booked as dissipated, per step times dt,
so that the scene's energy books close to the step's O(dt) accuracy.

Out of range: each step in contact counts, per patch, whether the largest interference, the
largest |rate| or the largest slip speed over the touching points lies beyond the law's
fitted ``ranges``; the run summary reports the counts and the largest values (never silent).
"""
from __future__ import annotations

import math

from numba import njit

from .bodies import push_body
from .body_contacts import closest_triangle, feature_normal
from .rotations import qrot, qrot_inv

V_REG = 1e-3   # m/s: engine.model.reduced_law.V_REG (the loading/unloading switch's width)
F_REF = 1.0    # N: engine.model.reduced_law.F_REF

# par columns (per patch)
P_K, P_P, P_C, P_ETA, P_MU, P_Q, P_VS, P_RT = 0, 1, 2, 3, 4, 5, 6, 7
P_D_HI, P_DD_LO, P_DD_HI, P_V_HI = 8, 9, 10, 11
P_REACH, P_RADIUS, P_CX, P_CY, P_CZ = 12, 13, 14, 15, 16
N_PAR = 17
# state columns (per patch): steps in contact, steps with d / dd / v out of range, largest
# d, |dd|, v seen, total normal force at the last step, energy dissipated so far
S_STEPS, S_OUT_D, S_OUT_DD, S_OUT_V, S_MAX_D, S_MAX_DD, S_MAX_V, S_FN, S_DISS = range(9)
N_STATE = 9
HIT = 12  # per touching point: i, d, n (3), arm from the patch body (3), from the other (3), F


@njit(cache=True)
def patch_contacts(bd, pa, dt):
    """Every patch against every body it may touch (``pa.pair[p, t]``); forces into
    ``bd.f``/``bd.tq``. Returns (touching points, stored energy, energy dissipated over this
    step); ``dt = 0`` books nothing (the initial force evaluation)."""
    bpos, bq, bv, bw = bd.pos, bd.q, bd.v, bd.w
    bound_r = bd.bound_r
    verts, tris, tnormal, tedge, pnormal = bd.verts, bd.tris, bd.tnormal, bd.tedge, bd.pnormal
    grid_origin, grid_cell, grid_dims = bd.grid_origin, bd.grid_cell, bd.grid_dims
    grid_base, grid_start, grid_tris = bd.grid_base, bd.grid_start, bd.grid_tris
    bf, btq = bd.f, bd.tq
    hits, scratch = pa.hits, pa.scratch
    count = 0
    stored = 0.0
    dissipated = 0.0
    nk = bpos.shape[0]
    for p in range(pa.body.shape[0]):
        s = pa.body[p]
        par = pa.par[p]
        k, pw, c, eta = par[P_K], par[P_P], par[P_C], par[P_ETA]
        mu, qexp_, v_s = par[P_MU], par[P_Q], par[P_VS]
        reach = par[P_REACH]
        sw, sx, sy, sz = bq[s, 0], bq[s, 1], bq[s, 2], bq[s, 3]
        cx, cy, cz = qrot(sw, sx, sy, sz, par[P_CX], par[P_CY], par[P_CZ])
        st = pa.state[p]
        st[S_FN] = 0.0
        n = 0
        for t in range(nk):
            if not pa.pair[p, t]:
                continue
            dx = bpos[s, 0] + cx - bpos[t, 0]
            dy = bpos[s, 1] + cy - bpos[t, 1]
            dz = bpos[s, 2] + cz - bpos[t, 2]
            lim = par[P_RADIUS] + bound_r[t] + reach
            if dx * dx + dy * dy + dz * dz >= lim * lim:
                continue
            tw, tx, ty, tz = bq[t, 0], bq[t, 1], bq[t, 2], bq[t, 3]
            reach2 = (bound_r[t] + reach) ** 2
            for i in range(pa.start[p], pa.start[p + 1]):
                rsx, rsy, rsz = qrot(sw, sx, sy, sz, pa.pts[i, 0], pa.pts[i, 1], pa.pts[i, 2])
                ex = bpos[s, 0] + rsx - bpos[t, 0]
                ey = bpos[s, 1] + rsy - bpos[t, 1]
                ez = bpos[s, 2] + rsz - bpos[t, 2]
                if ex * ex + ey * ey + ez * ez > reach2:
                    continue
                scratch[0], scratch[1], scratch[2] = qrot_inv(tw, tx, ty, tz, ex, ey, ez)
                tri, _s, u, v, w, d = closest_triangle(t, scratch, scratch, reach, verts, tris,
                                                       tnormal, tedge, grid_origin, grid_cell,
                                                       grid_dims, grid_base, grid_start,
                                                       grid_tris)
                if tri < 0 or d <= 0.0:
                    continue
                va = verts[tris[tri, 0]]
                vb = verts[tris[tri, 1]]
                vc = verts[tris[tri, 2]]
                px = u * va[0] + v * vb[0] + w * vc[0]
                py = u * va[1] + v * vb[1] + w * vc[1]
                pz = u * va[2] + v * vb[2] + w * vc[2]
                fnx, fny, fnz = feature_normal(tri, u, v, w, pnormal)
                if ((scratch[0] - px) * fnx + (scratch[1] - py) * fny
                        + (scratch[2] - pz) * fnz) >= 0.0:
                    continue  # outside
                nx, ny, nz = qrot(tw, tx, ty, tz, (px - scratch[0]) / d,
                                  (py - scratch[1]) / d, (pz - scratch[2]) / d)
                row = hits[n]
                row[0] = i
                row[1] = d
                row[2] = nx
                row[3] = ny
                row[4] = nz
                row[5] = rsx
                row[6] = rsy
                row[7] = rsz
                row[8] = ex
                row[9] = ey
                row[10] = ez
                row[11] = t
                n += 1
        if n == 0:
            continue
        # normal forces first: mu_eff needs the patch's total
        fn_total = 0.0
        diss = 0.0
        d_max = 0.0
        dd_max = 0.0
        v_max = 0.0
        for h in range(n):
            row = hits[h]
            i = int(row[0])
            t = int(row[11])
            d = row[1]
            vx, vy, vz = _relative_velocity(bv, bw, s, t, row)
            vn = vx * row[2] + vy * row[3] + vz * row[4]
            dd = -vn
            el = pa.w[i] * k * d ** pw
            ld = 1.0 - (1.0 - eta) * 0.5 * (1.0 - math.tanh(dd / V_REG))
            fn = max(el * (ld + c * dd), 0.0)
            row[1] = fn          # the row now holds the force; d is not needed again
            fn_total += fn
            stored += el * d / (pw + 1.0)
            diss += (fn - el) * dd * dt
            d_max = max(d_max, d)
            dd_max = max(dd_max, abs(dd))
            # slip speed, for the range check
            tx_ = vx - vn * row[2]
            ty_ = vy - vn * row[3]
            tz_ = vz - vn * row[4]
            v_max = max(v_max, math.sqrt(tx_ * tx_ + ty_ * ty_ + tz_ * tz_))
        mu_fn = mu * (max(fn_total, 1e-12) / F_REF) ** qexp_ if mu > 0.0 else 0.0
        for h in range(n):
            row = hits[h]
            t = int(row[11])
            fn = row[1]
            nx, ny, nz = row[2], row[3], row[4]
            vx, vy, vz = _relative_velocity(bv, bw, s, t, row)
            vn = vx * nx + vy * ny + vz * nz
            tx_ = vx - vn * nx
            ty_ = vy - vn * ny
            tz_ = vz - vn * nz
            vt = math.sqrt(tx_ * tx_ + ty_ * ty_ + tz_ * tz_)
            Fx = fn * nx
            Fy = fn * ny
            Fz = fn * nz
            if mu_fn > 0.0 and vt > 0.0:
                ft = mu_fn * math.tanh(vt / v_s) * fn
                Fx -= ft * tx_ / vt
                Fy -= ft * ty_ / vt
                Fz -= ft * tz_ / vt
                diss += ft * vt * dt
            push_body(bf, btq, s, row[5], row[6], row[7], Fx, Fy, Fz)
            push_body(bf, btq, t, row[8], row[9], row[10], -Fx, -Fy, -Fz)
        count += n
        dissipated += diss
        st[S_FN] = fn_total
        st[S_DISS] += diss
        if dt > 0.0:
            st[S_STEPS] += 1
            if d_max > par[P_D_HI]:
                st[S_OUT_D] += 1
            if dd_max > max(abs(par[P_DD_LO]), abs(par[P_DD_HI])):
                st[S_OUT_DD] += 1
            if v_max > par[P_V_HI]:
                st[S_OUT_V] += 1
            st[S_MAX_D] = max(st[S_MAX_D], d_max)
            st[S_MAX_DD] = max(st[S_MAX_DD], dd_max)
            st[S_MAX_V] = max(st[S_MAX_V], v_max)
    return count, stored, dissipated


@njit(cache=True, inline="always")
def _relative_velocity(bv, bw, s, t, row):
    """Velocity of body s's material point at the hit relative to body t's (world)."""
    rsx, rsy, rsz = row[5], row[6], row[7]
    ex, ey, ez = row[8], row[9], row[10]
    vx = (bv[s, 0] + bw[s, 1] * rsz - bw[s, 2] * rsy) - (bv[t, 0] + bw[t, 1] * ez
                                                         - bw[t, 2] * ey)
    vy = (bv[s, 1] + bw[s, 2] * rsx - bw[s, 0] * rsz) - (bv[t, 1] + bw[t, 2] * ex
                                                         - bw[t, 0] * ez)
    vz = (bv[s, 2] + bw[s, 0] * rsy - bw[s, 1] * rsx) - (bv[t, 2] + bw[t, 0] * ey
                                                         - bw[t, 1] * ex)
    return vx, vy, vz
