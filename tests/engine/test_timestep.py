"""The automatic timestep counts only the contacts a node can actually have
(engine/assembly/timestep.py and the reach analysis of engine/assembly/contacts.py)."""
from __future__ import annotations

import copy
import importlib

import numpy as np

import pytest

import engine

STEEL = {"youngs_modulus": 200e9, "poisson_ratio": 0.3, "density": 7640.0}


def _rods(columns: int, pitch: float = 0.2, length: float = 0.09, n_nodes: int = 10,
          bodies=(), brushes=None) -> dict:
    """Steel rods (1.42 mm diameter) clamped at z = 0 along +z, ``pitch`` apart along x."""
    brush = {"name": "rods", "material": "steel", "rows": 1, "columns": columns,
             "pitch": [pitch, pitch], "bristle_length": length, "root_radius": 0.00071,
             "tip_radius": 0.00071, "n_nodes": n_nodes}
    return {"schema_version": 1, "name": "rods", "materials": {"steel": STEEL},
            "brushes": brushes or [brush], "bodies": list(bodies),
            "environment": {"gravity": [0.0, 0.0, 0.0]},
            "run": {"duration": 1e-3, "record_interval": 1e-4}}


def _dt(scene: dict) -> engine.System:
    return engine.build(engine.parse_scene(scene))


def _far_plate() -> dict:
    """A fixed steel plate 1 m above the rods: no rod can reach it."""
    return {"name": "plate", "material": "steel", "shape": {"type": "box",
                                                           "size": [0.05, 0.05, 0.01]},
            "pose": {"position": [0.0, 0.0, 1.0]}, "motion": {"type": "fixed"}}


def _on_one_base(xs) -> dict:
    """One-rod brushes at ``xs`` on one moving (kinematic, non-colliding, turning) base."""
    one = _rods(1)["brushes"][0]
    brushes = [dict(copy.deepcopy(one), name=f"b{i}", mount="base",
                    base={"position": [x, 0.0, 0.0]}) for i, x in enumerate(xs)]
    base = {"name": "base", "material": "steel", "collide": False,
            "shape": {"type": "box", "size": [0.3, 0.02, 0.01]},
            "pose": {"position": [0.0, 0.0, -0.005]},
            "motion": {"type": "kinematic", "profile": {"kind": "constant",
                                                        "velocity": [0.0, 0.0, 0.0],
                                                        "angular_velocity": [0.0, 0.0, 1.0]}}}
    return _rods(len(xs), brushes=brushes, bodies=[base])


@pytest.mark.parametrize("scene", ["apart", "far body", "one moving base"])
def test_rods_that_cannot_meet_get_the_dt_of_one_rod(scene):
    """Two 90 mm steel rods 0.2 m apart can never touch (each stays within 90 mm of its root,
    fixed or on one rigid base), nor reach a plate 1 m away: their dt must be one rod's (the
    same arrays, so equal to round-off). Catches a contact term put on every node (the flat
    budget of 4 bristle + 1 body contacts made dt several times smaller) and the old rule
    that any two brushes on a moving body may meet."""
    if scene == "one moving base":
        one = _dt(_on_one_base([-0.1]))
        two = _dt(_on_one_base([-0.1, 0.1]))
    else:
        bodies = [_far_plate()] if scene == "far body" else []
        one = _dt(_rods(1))
        two = _dt(_rods(2, bodies=bodies))
    assert "contacts" not in two.dt_limited_by
    assert two.dt_stable == pytest.approx(one.dt_stable, rel=1e-12)  # identical bond arrays


def test_bristles_that_can_touch_keep_the_contact_term():
    """Rods 5 mm apart can touch (the reach spheres overlap): the contact term must stay and
    make dt smaller than one rod's (a steel contact k = E r = 1.4e8 N/m is stiffer than the
    rod's bonds). Catches a reach test that drops contacts that can happen."""
    one = _dt(_rods(1))
    two = _dt(_rods(2, pitch=0.005))
    assert "contacts" in two.dt_limited_by
    assert two.dt_stable < 0.8 * one.dt_stable  # contacts at least 1.5x the bonds' omega^2


def test_a_body_in_reach_adds_its_contact_term():
    """A fixed plate 20 mm above the 90 mm rods' tips is in reach of the outer nodes only:
    the contact term must appear (dt smaller than without the plate). Catches a body
    region that misses the body (e.g. a wrong centre or radius)."""
    plate = _far_plate()
    plate["pose"]["position"] = [0.0, 0.0, 0.09 + 0.02 + 0.005]
    near = _dt(_rods(1, bodies=[plate]))
    alone = _dt(_rods(1))
    assert "contacts" in near.dt_limited_by
    assert near.dt_stable < 0.8 * alone.dt_stable


def _forces(system, x, q):
    """Force and torque on every node at positions ``x`` and orientations ``q`` (nodes at
    rest), through the step loop itself: one step of a negligible dt."""
    from engine.stepping.loop import _advance

    nd = system.nodes
    nd.x[:] = x
    nd.q[:] = q
    nd.v[:] = 0.0
    nd.w[:] = 0.0
    dt = system.dt
    system.dt = 1e-30
    try:
        _advance(system, 1)
    finally:
        system.dt = dt
    return nd.f.copy(), nd.t.copy()


def test_the_bound_is_above_the_highest_frequency_of_the_linearised_bristle():
    """The Gershgorin bound against the exact highest frequency of one tapered silicone
    bristle (6 nodes, 1.0 -> 0.5 mm): the stiffness matrix is assembled by central
    differences of the step loop's own forces (translations and small rotations of every free
    node), and sqrt(max eig(M^-1 K)) must not exceed omega of ``dt_stable = 2 / omega``.
    It must also not be loose by more than Gershgorin's usual factor (< 4 here: the bound
    sums the absolute entries of each row, which for a chain is at most about twice the
    largest eigenvalue; measured 1.14). Bugs caught (each injected, each failed): the
    rotation rows' diagonal without the shear part ``12EI/L^3 * L^2/4`` (bound 13,209 against
    the true 14,815 rad/s), rotation left out of the bound (12,769), and a stiffness counted
    several times over (a needlessly small dt)."""
    from engine.kernels.rotations import qexp, qmul

    scene = _rods(1, n_nodes=6, length=0.033)
    scene["materials"] = {"silicone": {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48,
                                       "density": 1700.0}}
    b = scene["brushes"][0]
    b.update(material="silicone", root_radius=0.001, tip_radius=0.0005)
    system = _dt(scene)
    nd = system.nodes
    free = np.flatnonzero(nd.inv_mass > 0)
    x0, q0 = nd.x.copy(), nd.q.copy()
    n = len(free)
    K = np.zeros((6 * n, 6 * n))
    h_x, h_r = 1e-9, 1e-7
    for col, (node, kind, axis) in enumerate((node, kind, axis) for node in free
                                             for kind in (0, 1) for axis in range(3)):
        out = []
        for sign in (1.0, -1.0):
            x, q = x0.copy(), q0.copy()
            if kind == 0:
                x[node, axis] += sign * h_x
            else:
                e = np.zeros(3)
                e[axis] = sign * h_r
                q[node] = qmul(*qexp(*e), *q0[node])
            f, t = _forces(system, x, q)
            out.append(np.concatenate([np.concatenate([f[m], t[m]]) for m in free]))
        K[:, col] = -(out[0] - out[1]) / (2 * (h_x if kind == 0 else h_r))
    mass = np.concatenate([[nd.mass[m]] * 3 + [nd.inertia[m]] * 3 for m in free])
    s = 1.0 / np.sqrt(mass)
    A = s[:, None] * K * s[None, :]
    omega_true = float(np.sqrt(np.linalg.eigvalsh(0.5 * (A + A.T)).max()))
    omega_bound = 2.0 / system.dt_stable
    assert omega_true <= omega_bound * (1 + 1e-6), (omega_true, omega_bound)
    assert omega_bound < 4.0 * omega_true, (omega_true, omega_bound)


@pytest.mark.parametrize("levels", [3, 0])
@pytest.mark.parametrize("cap", [4, 10_000])
def test_partner_counts_agree_on_every_path(monkeypatch, levels, cap):
    """Catches an off-by-radius, a self-count, a wrong cap or an index mix-up in the three
    ways the build counts the bristles that can reach a node (all pairs for small brushes;
    the nearest roots per tip reach; chunks of listed pairs when every tip has its own
    reach, ``levels = 0``): each must give the count of a plain double loop over roots and
    nodes, capped at ``cap`` (uncapped with 10,000)."""
    build_mod = importlib.import_module("engine.assembly.contacts")

    rng = np.random.default_rng(3)
    n_roots, n_nodes = 300, 1200
    roots = rng.uniform(-1.0, 1.0, (n_roots, 3))
    reach_tip = (rng.choice(rng.uniform(0.05, 0.3, levels), n_roots) if levels
                 else rng.uniform(0.05, 0.3, n_roots))
    owner = np.arange(n_roots) * 2          # bristle indices, sorted, not 0..n-1
    node_owner = np.sort(owner[rng.integers(0, n_roots, n_nodes)])
    own = np.searchsorted(owner, node_owner)
    reach = rng.uniform(0.02, 0.4, n_nodes)
    expected = np.array([min(cap, sum(1 for c in range(n_roots)
                                      if owner[c] != node_owner[n]
                                      and np.linalg.norm(roots[c] - roots[own[n]])
                                      <= reach[n] + reach_tip[c])) for n in range(n_nodes)])
    # a real test: counts from 0 to above the cap of 4
    assert expected.min() == 0 and expected.max() >= 5 if cap > 4 else expected.max() == 4
    brute = build_mod._count_within(roots, reach_tip, owner, reach, node_owner, cap)
    monkeypatch.setattr(build_mod, "_BRUTE_PAIRS", 0)
    monkeypatch.setattr(build_mod, "_PAIR_BUDGET", 500)   # many chunks
    tree = build_mod._count_within(roots, reach_tip, owner, reach, node_owner, cap)
    np.testing.assert_array_equal(brute, expected)
    np.testing.assert_array_equal(tree, expected)
