"""Build, contacts: which contacts a scene can have, worked out from where things can reach.

A node stays within its reach of its root (the arc length of the next node, stretched, plus
the bristle's largest radius) while roots keep their distances on a fixed or rigid base; a
body stays within a region over the run (fixed, hinged, or along its kinematic profile).
From these come the contact stages the scene needs (bristle-bristle only if two bristles can
meet, and so on), the contact history they keep (only where there is friction or damping),
the mesh-mesh pair tables, and the contact stiffness each node and each body must be stable
with (``engine.assembly.timestep``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.kernels.bodies import FIXED, FREE, HINGE, KINEMATIC
from engine.kernels.contact_law import HISTORY_COLUMNS
from engine.errors import SceneError
from engine.kernels.mesh_contact import mesh_contact_stiffness, pair_stiffness
from engine.assembly.timestep import BRISTLE_CONTACTS_PER_NODE
from engine.state import Friction, friction_mode, tangential_ratio


@dataclass
class ContactNeeds:
    """The contacts a scene can have, and whether they keep a contact history."""

    bristle_bristle: bool
    bristle_body: bool
    body_body: bool
    mesh_mesh: bool
    friction_bristle: Friction    # Friction.NONE or SLIP_EACH_STEP (engine.state.friction_mode)
    friction_body: Friction
    friction_body_body: Friction
    history_bristle: bool         # contact history kept: friction, damping (restitution < 1)
                                  # or adhesion
    history_body: bool
    history_body_body: bool
    node_partners: np.ndarray     # per node, how many other bristles can touch its segments
    bristle_materials: list[int]
    body_materials: list[int]     # of the colliding bodies
    spheres: list[int]            # colliding sphere bodies


def contact_needs(scene, bristles, body_part, tables, warnings: list) -> ContactNeeds:
    """Which contacts can happen. Fills the mesh-mesh pair tables of the bodies
    (``mesh_kn``, ``mesh_len``) and sizes their contact history (``ft_mesh``, replacing
    ``body_part.bodies``); warns about mesh pairs that cannot touch (not watertight); refuses
    a ``no_contact_with`` that names a sphere body."""
    bodies, body_names = body_part.bodies, body_part.names
    collide, motion, after_free = bodies.collide, bodies.motion, bodies.after_free
    sphere_r, watertight, bmat = bodies.sphere_r, bodies.watertight, bodies.material
    point_len = body_part.point_len
    E_tab, mu = tables.E, tables.mu
    x, rad = bristles.nodes.x, bristles.nodes.rad
    N, K = x.shape[0], len(body_names)
    mat_index = {m: i for i, m in enumerate(scene.materials)}
    bristle_mats = sorted({mat_index[b.material] for b in scene.brushes})
    body_mats = sorted({int(bmat[k]) for k in range(K) if collide[k]})
    node_partners = _bristle_partners(bristles.brushes, x, rad, bristles.node_bristle,
                                      bristles.bristle_first, len(bristles.bristle_brush),
                                      motion)
    bb_needed = bool(node_partners.any())
    bbody_needed = N > 0 and bool(collide.any())
    spheres = [k for k in range(K) if collide[k] and sphere_r[k] > 0]
    meshmesh_needed = False
    bodybody_needed = False
    for k1 in range(K):
        for k2 in range(k1 + 1, K):
            if not (collide[k1] and collide[k2]):
                continue
            if not any(motion[k] in (FREE, HINGE) or after_free[k] for k in (k1, k2)):
                continue
            excluded = (body_names[k2] in scene.bodies[k1].no_contact_with
                        or body_names[k1] in scene.bodies[k2].no_contact_with)
            if sphere_r[k1] <= 0 and sphere_r[k2] <= 0:
                if excluded:
                    continue
                if not (watertight[k1] and watertight[k2]):
                    warnings.append(f"bodies {body_names[k1]!r} and {body_names[k2]!r}: "
                                    f"mesh-mesh contact needs two closed (watertight) "
                                    f"meshes; this pair does not touch")
                    continue
                kn_pair = pair_stiffness(E_tab[bmat[k1]], point_len[k1], E_tab[bmat[k2]],
                                         point_len[k2])
                bodies.mesh_kn[k1, k2] = bodies.mesh_kn[k2, k1] = kn_pair
                bodies.mesh_len[k1, k2] = bodies.mesh_len[k2, k1] = min(point_len[k1],
                                                                        point_len[k2])
                meshmesh_needed = True
            elif excluded:
                raise SceneError.single(f"bodies.{k1}.no_contact_with", body_names[k2],
                                        "only pairs of mesh bodies can be excluded; a "
                                        "sphere body touches every colliding body")
            bodybody_needed = True
    # damping or adhesion: either needs a history (the dashpot force, the adhered state)
    zeta = tables.zeta + tables.adhesion
    any_pair = lambda table, m1, m2: any(table[a, b] > 0 for a in m1 for b in m2)  # noqa: E731
    friction = lambda needed, m1, m2: (  # noqa: E731
        friction_mode(mu[a, b] for a in m1 for b in m2) if needed else Friction.NONE)
    friction_bristle = friction(bb_needed, bristle_mats, bristle_mats)
    friction_body = friction(bbody_needed, bristle_mats, body_mats)
    friction_body_body = friction(bodybody_needed, body_mats, body_mats)
    needs = ContactNeeds(
        bristle_bristle=bb_needed, bristle_body=bbody_needed, body_body=bodybody_needed,
        mesh_mesh=meshmesh_needed, friction_bristle=friction_bristle,
        friction_body=friction_body, friction_body_body=friction_body_body,
        history_bristle=bool(friction_bristle) or (
            bb_needed and any_pair(zeta, bristle_mats, bristle_mats)),
        history_body=bool(friction_body) or (
            bbody_needed and any_pair(zeta, bristle_mats, body_mats)),
        history_body_body=bool(friction_body_body) or (
            bodybody_needed and any_pair(zeta, body_mats, body_mats)),
        node_partners=node_partners, bristle_materials=bristle_mats, body_materials=body_mats,
        spheres=spheres)
    if needs.mesh_mesh and needs.history_body_body:  # per (contact point, other body)
        body_part.bodies = bodies._replace(ft_mesh=np.zeros((int(bodies.point_start[-1]), K,
                                                             HISTORY_COLUMNS)))
    return needs


def timestep_inputs(bristles, body_part, tables, needs: ContactNeeds) -> dict:
    """The dict ``engine.assembly.timestep.automatic_dt`` takes: per node its mass, inertia, radius,
    modulus, the bristles and bodies that can touch it; per free or hinged colliding body the
    contact stiffness it can meet."""
    nodes, bonds = bristles.nodes, bristles.bonds
    bodies, body_names = body_part.bodies, body_part.names
    E_tab, mu, ktr = tables.E, tables.mu, tables.kt
    motion, after_free, collide = bodies.motion, bodies.after_free, bodies.collide
    sphere_r, bmat = bodies.sphere_r, bodies.material
    rad = nodes.rad
    N, K, B = rad.shape[0], len(body_names), bonds.i.shape[0]
    E_node = E_tab[bristles.node_material] if N else np.zeros(0)
    bodies_info = []
    E_br_max = float(E_node.max()) if N else 0.0
    r_max = float(rad.max()) if N else 0.0
    n_segments = max(B, 1)
    spheres = needs.spheres
    for k in range(K):
        if (motion[k] in (FREE, HINGE) or after_free[k]) and collide[k]:
            k_body = 0.0
            if needs.bristle_body and N:
                Ek = float(E_tab[bmat[k]])
                k_body += min(n_segments, 100) * 2.0 * E_br_max * Ek / (E_br_max + Ek) * r_max
            if needs.body_body and sphere_r[k] > 0:
                k_body += 2.0 * float(E_tab[bmat[k]]) * sphere_r[k] * 2
            elif needs.body_body and spheres:
                k_body += 2.0 * float(E_tab[bmat[k]]) * max(sphere_r[s] for s in spheres) * 2
            k_body += mesh_contact_stiffness(bodies, k)
            bodies_info.append((body_names[k], float(bodies.mass[k]), float(bodies.Ip[k].min()),
                                k_body, float(bodies.bound_r[k])))
    bristle_mats, body_mats = needs.bristle_materials, needs.body_materials
    kt_bb = max([tangential_ratio(ktr[a, b], mu[a, b]) for a in bristle_mats
                 for b in bristle_mats], default=0.0)
    kt_body = max([tangential_ratio(ktr[a, b], mu[a, b]) for a in bristle_mats
                   for b in body_mats], default=0.0)
    node_k_body = (_node_body_stiffness(bristles.brushes, bodies, nodes.x, rad, E_node,
                                        bristles.node_bristle, bristles.bristle_first, E_tab,
                                        after_free) if needs.bristle_body else np.zeros(N))
    nmass, ninertia = nodes.mass, nodes.inertia
    node_bristle, bristle_brush = bristles.node_bristle, bristles.bristle_brush
    bristle_first, brushes = bristles.bristle_first, bristles.brushes

    def label(n):
        b = int(node_bristle[n])
        brush = brushes[int(bristle_brush[b])]
        return (f"brush {brush.name!r} bristle {b - brush.first_bristle} node "
                f"{n - int(bristle_first[b])}")
    return dict(node_mass=np.where(nmass > 0, nmass, 1.0),
                node_inertia=np.where(ninertia > 0, ninertia, 1.0),
                node_radius=rad, node_E=E_node, node_free=nodes.inv_mass > 0,
                node_bristle_contacts=np.minimum(needs.node_partners, BRISTLE_CONTACTS_PER_NODE),
                node_k_body=node_k_body, kt_ratio_bristle=float(kt_bb),
                kt_ratio_body=float(kt_body),
                bond_arrays=(bonds.i, bonds.j, bonds.kn, bonds.ks, bonds.kb, bonds.ksb,
                             bonds.kt, bonds.L0),
                bodies=bodies_info, node_label=label)


def max_body_speed(bodies, collide) -> tuple[float, int]:
    """The largest surface speed |v| + |omega| r_bound any colliding body reaches: along its
    whole profile for a kinematic body (the Hermite velocity sampled densely), its initial
    state for free and hinge bodies. Returns (speed, body index)."""
    best, who = 0.0, -1
    tau = np.linspace(0.0, 1.0, 33)
    for k in range(len(bodies.mass)):
        if not collide[k]:
            continue
        if bodies.motion[k] == KINEMATIC:
            sp = 0.0
            for c in range(int(bodies.seg_start[k]), int(bodies.seg_start[k + 1])):
                h = bodies.t1[c] - bodies.t0[c]
                if h <= 0:
                    continue
                d00 = (6 * tau ** 2 - 6 * tau) / h
                d10 = 3 * tau ** 2 - 4 * tau + 1
                d11 = 3 * tau ** 2 - 2 * tau
                vel = (np.outer(d00, bodies.p0[c]) + np.outer(d10, bodies.v0[c])
                       - np.outer(d00, bodies.p1[c]) + np.outer(d11, bodies.v1[c]))
                sp = max(sp, float(np.linalg.norm(vel, axis=1).max())
                         + float(np.linalg.norm(bodies.wseg[c])) * bodies.bound_r[k])
        elif bodies.motion[k] == FIXED:
            continue
        else:
            sp = float(np.linalg.norm(bodies.v[k])
                       + np.linalg.norm(bodies.w[k]) * bodies.bound_r[k])
        if sp > best:
            best, who = sp, k
    return best, who


STRETCH_MARGIN = 0.05  # reach of a node: its arc length from the root x (1 + this)


def _node_reach(x, rad, nbristle, bristle_first):
    """Per node, the root of its bristle and how far from it any point of the node's segments
    can get: the arc length of the next node (bristles start straight), stretched by
    ``STRETCH_MARGIN``, plus the bristle's largest radius. Contacts on a segment act on both
    of its nodes (``contacts.add_segment_force``), hence the next node's arc length."""
    N = x.shape[0]
    first = np.asarray(bristle_first, np.int64)[nbristle]
    last = np.asarray(bristle_first, np.int64)[nbristle + 1] - 1
    root = x[first]
    far = x[np.minimum(np.arange(N) + 1, last)]
    r_max = np.zeros(len(bristle_first) - 1)
    np.maximum.at(r_max, nbristle, rad)
    reach = (1.0 + STRETCH_MARGIN) * np.linalg.norm(far - root, axis=1) + r_max[nbristle]
    return root, reach


def _roots_move(brushes, motion) -> np.ndarray:
    """Per brush: does its base move (mounted on a body that is not fixed)?"""
    return np.array([b.mount >= 0 and motion[b.mount] != FIXED for b in brushes], bool)


def _bristle_partners(brushes, x, rad, nbristle, bristle_first, n_bristle, motion,
                      cap=BRISTLE_CONTACTS_PER_NODE):
    """Per node, how many other bristles can touch its segments, counted up to ``cap`` (the
    most the timestep charges a node, ``engine.assembly.timestep.BRISTLE_CONTACTS_PER_NODE``). Bristles
    whose roots are fixed, or ride on one rigid base, keep their roots' distances, and a
    point of a bristle stays within its reach (``_node_reach``) of its root: node i of
    bristle b and bristle c can meet only if |root_b - root_c| <= reach_i + reach of c's
    tip. A bristle on a moving base can meet every bristle of the other bases.

    Counts only, never the pairs: memory stays a few arrays of the node count whatever the
    brush's density (``_count_within``)."""
    N = x.shape[0]
    count = np.zeros(N, np.int64)
    if n_bristle < 2:
        return count
    root, reach = _node_reach(x, rad, nbristle, bristle_first)
    bf = np.asarray(bristle_first, np.int64)
    tips = bf[1:] - 1
    moving = _roots_move(brushes, motion)
    brush_of = np.zeros(n_bristle, np.int64)
    for i, info in enumerate(brushes):
        brush_of[info.first_bristle:info.first_bristle + info.n_bristles] = i
    # a rigid frame per bristle: -1 for the world, else the moving mount body
    frame = np.array([brushes[b].mount if moving[b] else -1 for b in brush_of], np.int64)
    for f in np.unique(frame):
        members = np.flatnonzero(frame == f)
        nodes = np.flatnonzero(np.isin(nbristle, members))
        count[nodes] += _count_within(root[bf[members]], reach[tips[members]], members,
                                      reach[nodes], nbristle[nodes], cap)
        others = int(np.count_nonzero(frame != f))
        if others and (f >= 0 or np.any(frame >= 0)):
            # another base moves relative to this one: any bristle of it may come
            count[nodes] += others if f >= 0 else int(np.count_nonzero(frame >= 0))
    return np.minimum(count, cap)


_BRUTE_PAIRS = 1_000_000   # up to this many root-node pairs numpy compares all of them
_TIP_GROUPS = 16           # distinct tip reaches counted group by group (a tree each)
_PAIR_BUDGET = 1_000_000   # root-node pairs held at once by the general count


def _count_within(roots, reach_tip, owner, reach, node_owner, cap):
    """Per node, how many roots other than its own bristle's lie within ``reach +
    reach_tip`` of its root (``|root_c - root_own| <= reach_node + reach_tip_c``), counted
    up to ``cap``. ``roots``, ``reach_tip``: per bristle of ``owner`` (sorted bristle
    indices); ``reach``, ``node_owner``: per node. Small brushes compare every pair. Large
    ones use a k-d tree, never listing more than ``_PAIR_BUDGET`` pairs: when the tips have
    a few distinct reaches (every bristle of a brush alike), the ``cap + 1`` nearest roots of
    each reach level per bristle suffice (within one level the test is a radius); else
    (tip variance gives every bristle its own reach) bristle chunk by bristle chunk."""
    out = np.zeros(len(reach), np.int64)
    if not len(reach) or not len(roots):
        return out
    own = np.searchsorted(owner, node_owner)
    if roots.shape[0] * len(reach) <= _BRUTE_PAIRS:
        d = np.linalg.norm(roots[own][:, None, :] - roots[None, :, :], axis=2)
        hit = (d <= reach[:, None] + reach_tip[None, :]) & (owner[None, :]
                                                             != node_owner[:, None])
        return np.minimum(hit.sum(axis=1), cap).astype(np.int64)
    from scipy.spatial import cKDTree

    levels = np.unique(reach_tip)
    bristle_reach = np.zeros(len(roots))
    np.maximum.at(bristle_reach, own, reach)
    if len(levels) <= _TIP_GROUPS:
        k = min(cap + 1, len(roots))
        for level in levels:
            group = np.flatnonzero(reach_tip == level)
            tree = cKDTree(roots[group])
            kk = min(k, len(group))
            # distances to the kk nearest roots of this level, per bristle (inf beyond)
            d, _ = tree.query(roots, k=[*range(1, kk + 1)],
                              distance_upper_bound=float(bristle_reach.max() + level)
                              * (1 + 1e-12))
            dn = d[own]                                   # per node, sorted ascending
            within = (dn <= (reach + level)[:, None]).sum(axis=1)
            # the own root (distance 0) is one of them when the own tip is at this level
            out += within - (reach_tip[own] == level)
        return np.minimum(out, cap)
    tree = cKDTree(roots)
    r_max = bristle_reach + float(reach_tip.max())
    lengths = np.asarray(tree.query_ball_point(roots, r_max, return_length=True), np.int64)
    node_start = np.searchsorted(own, np.arange(len(roots) + 1))  # own is sorted
    start = 0
    while start < len(roots):
        stop = start + 1
        total = int(lengths[start])
        while stop < len(roots) and total + lengths[stop] <= _PAIR_BUDGET:
            total += int(lengths[stop])
            stop += 1
        lists = tree.query_ball_point(roots[start:stop], r_max[start:stop])
        sizes = np.fromiter((len(h) for h in lists), np.int64, stop - start)
        c = np.fromiter((i for h in lists for i in h), np.int64, int(sizes.sum()))
        b = np.repeat(np.arange(start, stop), sizes)
        keep = c != b
        b, c = b[keep], c[keep]
        slack = np.linalg.norm(roots[c] - roots[b], axis=1) - reach_tip[c]
        order = np.lexsort((slack, b))                   # per bristle, slack ascending
        b, slack = b[order], slack[order]
        first = np.searchsorted(b, np.arange(start, stop + 1))
        for j in range(start, stop):                     # per bristle: its nodes at once
            s_j = slack[first[j - start]:first[j - start + 1]]
            nodes = slice(node_start[j], node_start[j + 1])
            out[nodes] = np.searchsorted(s_j, reach[nodes], side="right")
        start = stop
    return np.minimum(out, cap)


def _body_regions(bodies, after_free):
    """Per body, capsules (a, b, radius) that contain its surface over the whole run, or None
    where its travel cannot be bounded (free bodies, kinematic ones freed at the end). A
    kinematic Hermite segment p(tau) = p0 + (p1 - p0) h01 + h (h10 v0 + h11 v1) stays within
    4/27 h (|v0| + |v1|) of [p0, p1] (|h10|, |h11| <= 4/27, 0 <= h01 <= 1)."""
    regions = []
    for k in range(bodies.pos.shape[0]):
        R = float(bodies.bound_r[k])
        m = bodies.motion[k]
        if m == FIXED:
            regions.append([(bodies.pos[k], bodies.pos[k], R)])
        elif m == HINGE:
            c = bodies.hinge_point[k]
            regions.append([(c, c, float(np.linalg.norm(bodies.pos[k] - c)) + R)])
        elif m == KINEMATIC and not after_free[k]:
            segs = range(bodies.seg_start[k], bodies.seg_start[k + 1])
            regions.append([(bodies.p0[c], bodies.p1[c], R + 4.0 / 27.0 * (
                bodies.t1[c] - bodies.t0[c]) * (np.linalg.norm(bodies.v0[c])
                                                 + np.linalg.norm(bodies.v1[c])))
                            for c in segs])
        else:
            regions.append(None)
    return regions


def _node_body_stiffness(brushes, bodies, x, rad, E_node, nbristle, bristle_first, E_tab,
                         after_free) -> np.ndarray:
    """Per node, the sum over the bodies that can touch it of the contact's normal stiffness
    ``2 E_b E_k r / (E_b + E_k)`` (seed eq. 3.6), doubled (a two-sided row) for bodies that
    move under forces. A body can touch a node if the node's reach around its root
    (``_node_reach``) meets the body's region (``_body_regions``); nodes of a brush on a moving
    base can touch every body but their own mount."""
    N = x.shape[0]
    out = np.zeros(N)
    root, reach = _node_reach(x, rad, nbristle, bristle_first)
    moving = _roots_move(brushes, bodies.motion)
    brush_of = np.zeros(N, np.int64)
    mount_of = np.zeros(N, np.int64)
    for i, info in enumerate(brushes):
        sl = slice(info.first_node, info.first_node + info.n_bristles * info.n_nodes)
        brush_of[sl] = i
        mount_of[sl] = info.mount
    node_moves = moving[brush_of]
    for k, region in enumerate(_body_regions(bodies, after_free)):
        if not bodies.collide[k]:
            continue
        if region is None:
            can = np.ones(N, bool)
        else:
            gap = np.full(N, np.inf)
            for a, b, R in region:
                ab = b - a
                L2 = float(ab @ ab)
                t = np.clip((root - a) @ ab / L2, 0.0, 1.0) if L2 > 0 else np.zeros(N)
                d = np.linalg.norm(root - (a + t[:, None] * ab), axis=1) - R
                gap = np.minimum(gap, d)
            can = (gap <= reach) | node_moves
        can &= mount_of != k
        Ek = float(E_tab[bodies.material[k]])
        two_sided = bodies.motion[k] in (FREE, HINGE) or after_free[k]
        out += np.where(can, (2.0 if two_sided else 1.0) * 2.0 * E_node * Ek / (E_node + Ek)
                        * rad, 0.0)
    return out
