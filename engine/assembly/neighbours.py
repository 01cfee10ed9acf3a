"""The neighbour lists' Python side: their skin, allocation, growth on an overflow, and first
fill at build time. What keeps them valid while the system steps (the half-skin test, the
rebuild, the overflow codes) is compiled: ``engine.kernels.neighbours``.

A list starts with :data:`INITIAL_LIST_CAPACITY` rows; when a rebuild finds more entries
than fit, the kernel changes nothing and returns ``OVERFLOW_PAIRS`` or ``OVERFLOW_BODY`` with
the count needed, and :func:`grow_on_overflow` replaces that list by a larger one holding
the same entries and history; the caller then steps again (``engine.stepping.loop``) or
rebuilds again (:func:`fill`).
"""
from __future__ import annotations

import numpy as np

from engine.kernels.body_contacts import BSLOT
from engine.kernels.contact_law import HISTORY_COLUMNS
from engine.kernels.contacts import NSLOT
from engine.kernels.neighbours import rebuild_lists
from engine.state import LIMIT_SKIN, OK, OVERFLOW_BODY, OVERFLOW_PAIRS, BodyList, PairList

INITIAL_LIST_CAPACITY = 16   # rows at first; grow_on_overflow enlarges them


def list_skin(verlet_skin: float | None, r_min: float) -> float:
    """The skin, m: the scene's ``run.verlet_skin``, else the smallest node radius (else
    1 mm, for a scene without bristles)."""
    return verlet_skin if verlet_skin is not None else (r_min or 1e-3)


def pair_list(cap: int, history: bool) -> PairList:
    """Segment pairs (capacity ``cap``) with ``NSLOT`` contact slots each; contact history
    (the kept tangential force, the energy released on letting go, the dashpot force:
    ``contact_law.contact_with_history``) only where there is friction, damping or adhesion,
    else no rows."""
    c = cap * NSLOT
    h = c if history else 0
    return PairList(a=np.zeros(cap, np.int64), b=np.zeros(cap, np.int64),
                    ft=np.zeros((h, HISTORY_COLUMNS)),
                    active=np.zeros(c, np.int8), fc=np.zeros((c, 3)), cp=np.zeros((c, 3)),
                    s=np.zeros(c), t=np.zeros(c), energy=np.zeros(c), diss=np.zeros(c),
                    ratio=np.zeros(c), n=np.zeros(2, np.int64), a2=np.zeros(cap, np.int64),
                    b2=np.zeros(cap, np.int64), ft2=np.zeros((h, HISTORY_COLUMNS)),
                    xf=np.zeros((c, 4, 3)))


def body_list(cap: int, history: bool) -> BodyList:
    """(segment, body) candidates (capacity ``cap``) with ``BSLOT`` contact slots each;
    history as in :func:`pair_list`."""
    c = cap * BSLOT
    h = c if history else 0
    return BodyList(s=np.zeros(cap, np.int64), b=np.zeros(cap, np.int64),
                    ft=np.zeros((h, HISTORY_COLUMNS)),
                    active=np.zeros(c, np.int8), fc=np.zeros((c, 3)), cp=np.zeros((c, 3)),
                    par=np.zeros(c), energy=np.zeros(c), diss=np.zeros(c),
                    ratio=np.zeros(c), local=np.zeros((cap, 2, 3)), n=np.zeros(2, np.int64),
                    s2=np.zeros(cap, np.int64), b2=np.zeros(cap, np.int64),
                    ft2=np.zeros((h, HISTORY_COLUMNS)), xf=np.zeros((c, 4, 3)),
                    deep=np.zeros(cap, np.int8), deep2=np.zeros(cap, np.int8),
                    face=np.full(cap, -1, np.int64))


def allocate(history_bristle: bool, history_body: bool) -> tuple[PairList, BodyList]:
    """Both lists, empty, at the initial capacity; with history rows where asked."""
    return (pair_list(INITIAL_LIST_CAPACITY, history_bristle),
            body_list(INITIAL_LIST_CAPACITY, history_body))


def _grown_pairs(old: PairList) -> PairList:
    new = pair_list(_capacity(old), old.ft.shape[0] > 0)
    n = int(old.n[0])
    new.a[:n] = old.a[:n]
    new.b[:n] = old.b[:n]
    if old.ft.shape[0] > 0:
        new.ft[:n * NSLOT] = old.ft[:n * NSLOT]
    new.n[0] = n
    return new


def _grown_body(old: BodyList) -> BodyList:
    new = body_list(_capacity(old), old.ft.shape[0] > 0)
    n = int(old.n[0])
    new.s[:n] = old.s[:n]
    new.b[:n] = old.b[:n]
    new.deep[:n] = old.deep[:n]
    if old.ft.shape[0] > 0:
        new.ft[:n * BSLOT] = old.ft[:n * BSLOT]
    new.n[0] = n
    return new


def _capacity(old) -> int:
    """Room for the entries the overflowing rebuild found (``n[1]``), and half as many more."""
    return int(int(old.n[1]) * 1.5) + 64


def grow_on_overflow(system, code: int) -> bool:
    """On an overflow ``code`` of the compiled rebuild, replace that list of ``system`` (a
    built ``System``) by a larger one with the same entries and history, and return True;
    on any other code return False."""
    if code == OVERFLOW_PAIRS:
        system.pairs = _grown_pairs(system.pairs)
        return True
    if code == OVERFLOW_BODY:
        system.body_pairs = _grown_body(system.body_pairs)
        return True
    return False


def fill(system) -> None:
    """Build the lists of a new ``system`` from its initial positions, growing them until
    they hold every entry."""
    while True:
        code = rebuild_lists(system.nodes, system.bonds, system.bodies, system.pairs,
                             system.body_pairs, system.flags, system.limits[LIMIT_SKIN])
        if code == OK:
            return
        if not grow_on_overflow(system, code):
            raise RuntimeError(f"neighbour-list rebuild returned code {code}")
