"""The neighbour lists: which segment pairs (``PairList``) and which (segment, body)
candidates (``BodyList``) the narrow phases look at, in the manner of JAX-MD's neighbour list.

A list is built from the positions of one moment, which it keeps (``Nodes.x_build``,
``Bodies.pos_build``/``q_build``), with every entry closer than the skin; it stays valid
while no node or body has moved more than half the skin since (:func:`lists_stale`, from
:func:`predicted_displacement`; the step loop takes its nodes' part in its second half kick,
``stepper.nodes_kick_watch``), and is rebuilt then (:func:`rebuild_lists`), the contact
history of the entries that survive carried over (:func:`carry_history`). Its capacity is
fixed: a rebuild that finds more entries than fit changes nothing and returns an overflow
code (``engine.state.OVERFLOW_PAIRS``/``OVERFLOW_BODY``, the count needed in ``n[1]``), on
which the caller grows the list and steps again (``engine.assembly.neighbours``, which also
allocates the lists and fills them at build time).

The broad phases that find the entries are geometry of their contact kind and stay beside
it: ``contacts.build_pair_list`` (segment pairs, through a cell list) and
``body_contacts.build_body_candidates`` (segments against body surfaces).
"""
from __future__ import annotations

import math

from numba import njit

from .body_contacts import BSLOT, build_body_candidates
from .contacts import NSLOT, build_pair_list, segment_bounds
from .jit import item_kernel
from ..state import OK, OVERFLOW_BODY, OVERFLOW_PAIRS


@item_kernel
def predicted_displacement(nd, bd, dt):
    """Upper bound of how far any node and any body centre will be from where the
    neighbour lists were built, after the next drift: the nodes' part
    (:func:`node_displacement`) plus the bodies' (:func:`body_displacement`)."""
    return node_displacement(nd, dt) + body_displacement(bd, dt)


@item_kernel
def node_displacement(nd, dt):
    """The largest distance of a node from where the lists were built, after the next
    drift: its distance now plus ``dt`` times the speed the next half kick gives it."""
    worst = 0.0
    for n in range(nd.x.shape[0]):
        worst = node_displacement_one(n, nd.x, nd.x_build, nd.v, nd.f, nd.inv_mass, dt, worst)
    return worst


@njit(cache=True, inline="always")
def node_displacement_one(n, x, x_build, v, f, inv_mass, dt, worst):
    """``max(worst, node n's displacement)`` as :func:`node_displacement` takes it; the step
    loop's second half kick calls it on each node it has kicked
    (``stepper.nodes_kick_watch``), so the next step's check costs no pass of its own."""
    dx = x[n, 0] - x_build[n, 0]
    dy = x[n, 1] - x_build[n, 1]
    dz = x[n, 2] - x_build[n, 2]
    im = inv_mass[n]
    vx = v[n, 0] + 0.5 * dt * f[n, 0] * im
    vy = v[n, 1] + 0.5 * dt * f[n, 1] * im
    vz = v[n, 2] + 0.5 * dt * f[n, 2] * im
    a = dx * dx + dy * dy + dz * dz
    c = dt * dt * (vx * vx + vy * vy + vz * vz)
    # (sqrt(a) + sqrt(c))^2 <= 2 (a + c): most nodes are ruled out without a sqrt
    if 2.0 * (a + c) > worst * worst:
        d = math.sqrt(a) + dt * math.sqrt(vx * vx + vy * vy + vz * vz)
        if d > worst:
            worst = d
    return worst


@item_kernel
def body_displacement(bd, dt):
    """The largest distance a colliding body's surface may be from where the lists were
    built, after the next drift (its centre's move, plus its rotation times its reach)."""
    wb = 0.0
    for k in range(bd.pos.shape[0]):
        if not bd.collide[k]:
            continue
        dx = bd.pos[k, 0] - bd.pos_build[k, 0]
        dy = bd.pos[k, 1] - bd.pos_build[k, 1]
        dz = bd.pos[k, 2] - bd.pos_build[k, 2]
        sp = math.sqrt(bd.v[k, 0] ** 2 + bd.v[k, 1] ** 2 + bd.v[k, 2] ** 2)
        om = math.sqrt(bd.w[k, 0] ** 2 + bd.w[k, 1] ** 2 + bd.w[k, 2] ** 2)
        # rotation since the build: angle of q q_build^*, times the body's reach
        cw = abs(bd.q[k, 0] * bd.q_build[k, 0] + bd.q[k, 1] * bd.q_build[k, 1]
                 + bd.q[k, 2] * bd.q_build[k, 2] + bd.q[k, 3] * bd.q_build[k, 3])
        ang = 2.0 * math.acos(min(cw, 1.0))
        d = (math.sqrt(dx * dx + dy * dy + dz * dz) + ang * bd.bound_r[k]
             + 2.0 * dt * (sp + om * bd.bound_r[k]))
        if d > wb:
            wb = d
    return wb


@item_kernel
def lists_stale(nd, bd, dt, skin):
    """Whether the lists may miss a contact after the next drift: some node or body may then
    be more than half the skin from where the lists were built (two entries closing in on
    each other can then have crossed the skin between them)."""
    return predicted_displacement(nd, bd, dt) > 0.5 * skin


@njit(cache=True)
def rebuild_lists(nd, bn, bd, pl, bl, fl, skin):
    """Rebuild the neighbour lists from the current positions, keeping contact history.
    Returns OK or an overflow code (then nothing was changed)."""
    segment_bounds(nd.x, nd.rad, bn.i, bn.j, bn.mid, bn.bound)
    if fl.bristle_bristle:
        n_new = build_pair_list(bn.mid, bn.bound, bn.bristle, skin, pl.a2, pl.b2, nd.x, bn.i,
                                bn.j, bn.rmax)
        if n_new > pl.a2.shape[0]:
            pl.n[1] = n_new
            return OVERFLOW_PAIRS
    if fl.bristle_body:
        m_new = build_body_list(nd, bn, bd, bl, skin)
        if m_new > bl.s2.shape[0]:
            bl.n[1] = m_new
            return OVERFLOW_BODY
    if fl.bristle_bristle:
        if pl.ft.shape[0] > 0:  # a history (friction or damping)
            carry_history(pl.a, pl.b, pl.ft, pl.n[0], pl.a2, pl.b2, pl.ft2, n_new,
                          bn.i.shape[0], NSLOT)
            pl.ft[:n_new * NSLOT] = pl.ft2[:n_new * NSLOT]
        pl.a[:n_new] = pl.a2[:n_new]
        pl.b[:n_new] = pl.b2[:n_new]
        pl.n[0] = n_new
    if fl.bristle_body:
        if bl.ft.shape[0] > 0:
            carry_history(bl.s, bl.b, bl.ft, bl.n[0], bl.s2, bl.b2, bl.ft2, m_new,
                          bd.pos.shape[0], BSLOT)
            bl.ft[:m_new * BSLOT] = bl.ft2[:m_new * BSLOT]
        bl.s[:m_new] = bl.s2[:m_new]
        bl.b[:m_new] = bl.b2[:m_new]
        bl.deep[:m_new] = bl.deep2[:m_new]
        bl.face[:m_new] = -1
        bl.n[0] = m_new
    nd.x_build[:] = nd.x
    bd.pos_build[:] = bd.pos
    bd.q_build[:] = bd.q
    return OK


@njit(cache=True)
def build_body_list(nd, bn, bd, bl, skin):
    """The (segment, body) candidates from the current positions into the list's second
    rows (``bl.s2``, ``bl.b2``, ``bl.deep2``); returns their count (``build_body_candidates``)."""
    return build_body_candidates(bn.mid, bn.bound, bn.mount, bd.pos, bd.bound_r, bd.collide,
                                 skin, bl.s2, bl.b2, bl.deep2, nd.x, nd.rad, bn.i, bn.j,
                                 bn.rmax, bd.q, bd.sphere_r, bd.watertight, bd.verts, bd.tris,
                                 bd.tnormal, bd.tedge, bd.pnormal, bd.grid_origin,
                                 bd.grid_cell, bd.grid_dims, bd.grid_base, bd.grid_start,
                                 bd.grid_tris, bd.grid_side, bd.scratch2, bd.tsupport)


@njit(cache=True)
def carry_history(old_a, old_b, old_ft, n_old, new_a, new_b, new_ft, n_new, ns, nslot):
    """Copy the tangential history (``nslot`` rows per entry) of the entries present in both
    lists, sorted by the key ``a * ns + b`` (merge join); a new entry starts at zero. For the
    segment pairs (``nslot`` = NSLOT, ``ns`` segments) and the segment-body candidates
    (BSLOT, ``ns`` bodies)."""
    i = 0
    for k in range(n_new):
        key = new_a[k] * ns + new_b[k]
        while i < n_old and old_a[i] * ns + old_b[i] < key:
            i += 1
        found = i < n_old and old_a[i] * ns + old_b[i] == key
        for m in range(nslot):
            for c in range(new_ft.shape[1]):
                new_ft[k * nslot + m, c] = old_ft[i * nslot + m, c] if found else 0.0
