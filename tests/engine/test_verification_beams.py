"""Physics verification of one bristle as a beam: the engine against continuum references.

A single bristle (one brush, rows = columns = 1) is turned by its base so that it lies along
+x from the origin: a horizontal cantilever clamped at its root. References come from
``analytic.py`` (closed forms and scipy solutions of the continuum problems; nothing there
uses the engine):

* small tip load on the steel rod of seed table 4.1 vs ``P L^3 / (3 E I)``;
* small tip load on the conical silicone bristle vs the tapered-beam integral at the
  resolutions studies use and from 2 to 33 nodes (the frustum element is exact), and its
  twist under a tip torque vs the frustum's torsional compliance;
* large deflection under a dead vertical tip load vs the elastica (scipy ``solve_bvp``);
* the first three bending frequencies of the steel rod vs Euler-Bernoulli, from the spectrum
  of a free vibration after a short tip impulse;
* the automatic timestep: below the safety fraction of the stability limit, and that limit
  below the true highest frequency of the discrete system.

Static cases reach equilibrium by dynamic relaxation (Cundall local damping) and check that
the tip has stopped moving before comparing. Every run writes to pytest's ``tmp_path``.
"""
from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

import engine
from engine.analysis.spectrum import peak_frequencies

import analytic  # tests/engine is on sys.path (pytest's rootdir-relative import of this file)

# base orientation turning the bristle's local +z onto world +x (rotation of pi/2 about +y)
ALONG_X = (math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0)

# seed table 4.1: the steel rod
STEEL = dict(youngs_modulus=200e9, poisson_ratio=0.3, density=7640.0)
ROD_LENGTH = 0.4
ROD_RADIUS = 1.42e-3 / 2

# the conical silicone bristle
SILICONE = dict(youngs_modulus=2.7e6, poisson_ratio=0.48, density=1700.0)
CONE_LENGTH = 0.033
CONE_ROOT_RADIUS = 1.0e-3
CONE_TIP_RADIUS = 0.5e-3

# A static run counts as settled when the tip moved less than this fraction of the reference
# deflection over the last 20 % of the run: 10x below the tightest tolerance (1 %), so the
# unfinished relaxation cannot decide a comparison.
SETTLED = 1e-3


# ------------------------------------------------------------------------------ helpers
def cantilever_scene(*, n_nodes: int, length: float, root_radius: float, tip_radius: float,
                     material: dict, tip_force: float, profile: dict, duration: float,
                     record_interval: float, local_damping: float) -> engine.Scene:
    """A horizontal cantilever along +x clamped at the origin, with a vertical dead load
    ``(0, 0, -tip_force) * profile(t)`` on its tip node; no gravity."""
    return engine.parse_scene({
        "name": "cantilever",
        "materials": {"rod": material},
        "brushes": [{"name": "rod", "material": "rod", "rows": 1, "columns": 1,
                     "bristle_length": length, "root_radius": root_radius,
                     "tip_radius": tip_radius, "n_nodes": n_nodes,
                     "base": {"orientation": ALONG_X}}],
        "loads": [{"brush": "rod", "node": -1, "force": [0.0, 0.0, -tip_force],
                   "profile": profile}],
        "environment": {"gravity": [0.0, 0.0, 0.0], "local_damping": local_damping},
        "run": {"duration": duration, "record_interval": record_interval,
                "channels": ["nodes"]},
    })


def run_tip(scene: engine.Scene, output: Path) -> tuple[engine.System, np.ndarray, np.ndarray]:
    """Build and run ``scene`` into the result file ``output``; return the system, the frame
    times and the tip positions (frames, 3)."""
    system = engine.build(scene)
    result = engine.run(system, output=output)
    assert result.status == "completed", result.summary
    with engine.open_result(result.path) as res:
        time = np.asarray(res.time)
        tip = np.asarray(res.series("nodes/positions")[:, -1, :])
    return system, time, tip


def assert_settled(time: np.ndarray, value: np.ndarray, scale: float) -> None:
    """The recorded quantity moved less than SETTLED * scale over the last 20 % of the run."""
    tail = time >= 0.8 * time[-1]
    drift = float(np.ptp(value[tail]))
    assert drift < SETTLED * scale, (
        f"not yet in equilibrium: the tip still moves by {drift / scale:.2e} of the "
        f"reference over the last 20 % of the run")


def quasi_static(ramp: float = 0.1) -> dict:
    """Load amplitude: a linear ramp from 0 to 1 over ``ramp`` seconds, then held."""
    return {"times": [0.0, ramp], "values": [0.0, 1.0]}


def observed_order(n_nodes: list[int], errors: list[float]) -> np.ndarray:
    """Convergence order between successive resolutions, with h = L / (n_nodes - 1)."""
    h = 1.0 / (np.asarray(n_nodes, float) - 1.0)
    e = np.abs(np.asarray(errors, float))
    return np.log(e[:-1] / e[1:]) / np.log(h[:-1] / h[1:])


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """One folder for the runs that several tests share (through the lru_caches below)."""
    return tmp_path_factory.mktemp("beam_runs")


# ------------------------------------------------------------------------------ 1. steel rod
def test_steel_rod_small_tip_load_matches_euler_bernoulli(tmp_path):
    n_nodes = 21
    force = 1e-3  # N: tip deflection 0.13 % of L, so geometric non-linearity is ~1e-6
    I = analytic.circle_second_moment(ROD_RADIUS)
    ref = analytic.cantilever_tip_deflection(force, ROD_LENGTH, STEEL["youngs_modulus"], I)
    scene = cantilever_scene(n_nodes=n_nodes, length=ROD_LENGTH, root_radius=ROD_RADIUS,
                             tip_radius=ROD_RADIUS, material=STEEL, tip_force=force,
                             profile=quasi_static(), duration=1.0, record_interval=0.05,
                             local_damping=0.7)
    _, time, tip = run_tip(scene, tmp_path / "run.h5")
    assert_settled(time, tip[:, 2], ref)
    deflection = -tip[-1, 2]
    # 1 %: the bond model reproduces the Euler-Bernoulli element exactly for a uniform rod,
    # so only the relaxation remainder (< 1e-3, checked above) and (delta/L)^2 ~ 2e-6 are
    # left; a wrong shear or bending spring (a factor in 12EI/L^3 or EI/L) errs by >= 25 %.
    assert deflection == pytest.approx(ref, rel=0.01)
    # the tip moves along the load only: no spurious axial or out-of-plane motion
    assert abs(tip[-1, 1]) < 1e-9 * ROD_LENGTH
    assert tip[-1, 0] == pytest.approx(ROD_LENGTH, rel=1e-5)


# ------------------------------------------------------------------------------ 2. cone
def _cone_reference_compliance() -> float:
    I = analytic.conical_second_moment(CONE_ROOT_RADIUS, CONE_TIP_RADIUS, CONE_LENGTH)
    return analytic.tapered_cantilever_tip_deflection(1.0, CONE_LENGTH,
                                                      SILICONE["youngs_modulus"], I)


@functools.lru_cache(maxsize=None)
def cone_tip_error(n_nodes: int, run_dir: Path) -> float:
    """Relative error of the conical bristle's small-load tip deflection at ``n_nodes``
    (positive: the model is more compliant than the tapered beam). Cached: several tests
    share the runs."""
    compliance = _cone_reference_compliance()
    force = 1e-3 * CONE_LENGTH / compliance  # N: tip deflection 0.1 % of L
    ref = force * compliance
    scene = cantilever_scene(n_nodes=n_nodes, length=CONE_LENGTH, root_radius=CONE_ROOT_RADIUS,
                             tip_radius=CONE_TIP_RADIUS, material=SILICONE, tip_force=force,
                             profile=quasi_static(ramp=0.05), duration=1.0,
                             record_interval=0.05, local_damping=0.7)
    _, time, tip = run_tip(scene, run_dir / f"cone_{n_nodes}.h5")
    assert_settled(time, tip[:, 2], ref)
    return float(-tip[-1, 2] / ref - 1.0)


def test_conical_bristle_tip_stiffness_matches_tapered_beam(run_dir):
    """The resolutions studies run at (5 and 9 nodes) give the tapered beam's tip deflection.
    Catches the per-segment compliance-equivalent I_eff without the frustum's shear-bending
    coupling (the element before: +6.0 % at 5 nodes, +1.45 % at 9), the coupling with the
    wrong sign (+12 % at 5 nodes) or twice as large (+4.5 %) (linear solves of the chain)."""
    errors = {n: cone_tip_error(n, run_dir) for n in (5, 9)}
    # 0.2 %: the frustum element is exact for end loads at any resolution, so only the
    # relaxation remainder (< 0.1 %, SETTLED) and (delta/L)^2 ~ 1e-6 are left (measured
    # -1e-6 at both); the targets were 1 % at 5 nodes and 0.2 % at 9
    assert all(abs(e) < 0.002 for e in errors.values()), errors


@pytest.mark.slow
def test_conical_bristle_is_exact_at_every_resolution(run_dir):
    """From 3 nodes (two frustums) to 33 the tip deflection is the tapered beam's: the error
    does not shrink with resolution because there is none to shrink (the compliance-
    equivalent element before erred by +27 % at 3 nodes and +0.36 % at 17)."""
    errors = [cone_tip_error(n, run_dir) for n in (3, 17, 33)]
    # 0.2 %: as above, the relaxation remainder
    assert all(abs(e) < 0.002 for e in errors), errors


def test_conical_bristle_twist_reaction_torque_is_exact_frustum_compliance(tmp_path):
    """A conical bristle (9 nodes) twisted into the static shape of a tip torque T, node
    angles theta(x) = T int_0^x ds / (G J(s)) with J = pi r^4 / 2, holds exactly T at its
    base with every interior node in equilibrium. Catches a twist spring that is not the
    frustum's exact compliance (J at the segment's mean radius: +0.35 % in the root bond
    here; the mean of its end values: +0.97 %) or J = I (a factor 2)."""
    n_nodes, theta = 9, 1e-3
    E, nu = SILICONE["youngs_modulus"], SILICONE["poisson_ratio"]
    G = E / (2.0 * (1.0 + nu))

    def radius(s):
        return CONE_ROOT_RADIUS + (CONE_TIP_RADIUS - CONE_ROOT_RADIUS) * s / CONE_LENGTH

    def compliance(a, b):  # int_a^b ds / (G J(s))
        return quad(lambda s: 1.0 / (G * 2.0 * analytic.circle_second_moment(radius(s))),
                    a, b, epsabs=0.0, epsrel=1e-13)[0]

    torque = theta / compliance(0.0, CONE_LENGTH)
    x = np.linspace(0.0, CONE_LENGTH, n_nodes)
    angles = torque * np.array([compliance(0.0, s) for s in x])
    scene = engine.parse_scene({
        "materials": {"rod": SILICONE},
        "brushes": [{"name": "rod", "material": "rod", "bristle_length": CONE_LENGTH,
                     "root_radius": CONE_ROOT_RADIUS, "tip_radius": CONE_TIP_RADIUS,
                     "n_nodes": n_nodes}],
        "environment": {"gravity": [0.0, 0.0, 0.0]},
        "run": {"duration": 1.0, "record_interval": 0.01, "channels": ["root_force"]}})
    system = engine.build(scene)
    q = system.nodes.q  # the bristle stands along +z: twist each node about +z
    q[:, :] = 0.0
    q[:, 0] = np.cos(0.5 * angles)
    q[:, 3] = np.sin(0.5 * angles)
    result = engine.run(system, until=system.dt, output=tmp_path / "twist.h5")
    with engine.open_result(result.path) as res:
        root_torque = np.asarray(res.series("brushes/rod/root_torque"))[-1]
    # 1e-6: one step from rest moves only the tip node (nothing else is out of balance);
    # theta^2 terms of the rotation algebra are ~1e-7 of T
    assert root_torque[2] == pytest.approx(-torque, rel=1e-6)
    # the nodes between root and tip-1 stay in equilibrium; the tip, the one node out of
    # balance, turns during that first step (its forces are applied from t = 0), so its
    # neighbour feels the turn and is left out
    assert np.max(np.abs(system.nodes.t[1:-2, 2])) < 1e-6 * torque


# ------------------------------------------------------------------------------ 3. elastica
ELASTICA_LOAD = 2.0  # alpha = P L^2 / (E I): tip deflection 49 % of L, tip slope 45 deg


@functools.lru_cache(maxsize=None)
def elastica_tip_error(n_nodes: int, run_dir: Path, load_parameter: float = ELASTICA_LOAD):
    """(x error, y error) of the steel rod's tip under a dead vertical tip load of
    ``load_parameter`` E I / L^2, relative to L, against the elastica."""
    E = STEEL["youngs_modulus"]
    I = analytic.circle_second_moment(ROD_RADIUS)
    force = load_parameter * E * I / ROD_LENGTH ** 2
    x_ref, y_ref, _ = analytic.elastica_tip(load_parameter)
    scene = cantilever_scene(n_nodes=n_nodes, length=ROD_LENGTH, root_radius=ROD_RADIUS,
                             tip_radius=ROD_RADIUS, material=STEEL, tip_force=force,
                             profile=quasi_static(ramp=0.2), duration=1.0,
                             record_interval=0.05, local_damping=0.7)
    _, time, tip = run_tip(scene, run_dir / f"elastica_{n_nodes}_{load_parameter}.h5")
    assert_settled(time, tip[:, 2], y_ref * ROD_LENGTH)
    assert_settled(time, tip[:, 0], y_ref * ROD_LENGTH)
    return tip[-1, 0] / ROD_LENGTH - x_ref, -tip[-1, 2] / ROD_LENGTH - y_ref


def test_elastica_reference_is_consistent():
    """The BVP reference against its first-integral form and Bisshopp & Drucker (1945):
    alpha = 1 gives a vertical tip deflection of 0.30172 L and a horizontal one of 0.05643 L."""
    x_bvp, y_bvp, t_bvp = analytic.elastica_tip(ELASTICA_LOAD)
    x_q, y_q, t_q = analytic.elastica_tip_quadrature(ELASTICA_LOAD)
    # 1e-8: both are solved to ~1e-10; a wrong sign or factor in either differs by >> 1e-3
    assert (x_bvp, y_bvp, t_bvp) == pytest.approx((x_q, y_q, t_q), abs=1e-8)
    x1, y1, _ = analytic.elastica_tip(1.0)
    # 5e-5: the published table gives five decimals
    assert y1 == pytest.approx(0.30172, abs=5e-5)
    assert 1.0 - x1 == pytest.approx(0.05643, abs=5e-5)
    assert y_bvp >= 0.3  # the test below is a large deflection indeed


def test_large_deflection_matches_elastica(run_dir):
    # 11 nodes: inside the tolerance by a factor ~60 (error ~0.03 / (n-1)^2 of L)
    ex, ey = elastica_tip_error(11, run_dir)
    # 2 % of L on both tip coordinates: the co-rotational bond is exact for rigid rotations,
    # so what remains is the O(h^2) discretisation of the curved rod (3e-4 L at 11 nodes)
    assert abs(ex) < 0.02 and abs(ey) < 0.02, f"tip error ({ex:+.2e}, {ey:+.2e}) L"


def test_large_deflection_converges_at_second_order(run_dir):
    ladder = [5, 9, 17]
    errors = [elastica_tip_error(n, run_dir) for n in ladder]
    order_y = observed_order(ladder, [e[1] for e in errors])
    order_x = observed_order(ladder, [e[0] for e in errors])
    # 1.8-2.3: chord-based discretisation of the elastica is O(h^2) (measured 2.07, 2.01 on
    # y and 1.96, 1.98 on x); a formulation error in large rotations would stall at a constant
    # error (order 0)
    assert np.all((order_y > 1.8) & (order_y < 2.3)), (errors, order_y)
    assert np.all((order_x > 1.8) & (order_x < 2.3)), (errors, order_x)


@pytest.mark.slow
def test_large_deflection_fine_resolution(run_dir):
    ex, ey = elastica_tip_error(41, run_dir)
    # 1e-4 L: second order from 3e-4 L at 11 nodes predicts ~2e-5 L at 41 nodes
    assert abs(ex) < 1e-4 and abs(ey) < 1e-4, (ex, ey)


def test_coarse_loaded_cantilever_is_stable_or_stops_clearly(tmp_path):
    """Three nodes under the large load: DESIGN §6 allows either a stable run or a clear stop.

    Under load the co-rotational bond's axial spring adds a rotational stiffness ~ k_n d_x^2
    (d_x: the shear reading of a bond in its midpoint frame, whose rotation changes the axial
    reading d_z by -d_x dphi) that the at-rest timestep bound does not include. It grows like
    (P h^3 / E I)^2 E A / h, so on coarse, slender, stiff rods under large loads it exceeds the
    dt_safety margin: here omega_max rises from 6.0e4 to 3.2e5 rad/s at equilibrium, beyond
    the 1.34e5 rad/s that dt_safety 0.5 tolerates. Finer chains (5 nodes and up) are stable."""
    E = STEEL["youngs_modulus"]
    I = analytic.circle_second_moment(ROD_RADIUS)
    force = ELASTICA_LOAD * E * I / ROD_LENGTH ** 2
    scene = cantilever_scene(n_nodes=3, length=ROD_LENGTH, root_radius=ROD_RADIUS,
                             tip_radius=ROD_RADIUS, material=STEEL, tip_force=force,
                             profile=quasi_static(ramp=0.2), duration=1.0,
                             record_interval=0.05, local_damping=0.7)
    system = engine.build(scene)
    try:
        engine.run(system, output=tmp_path / "run.h5")
    except engine.InstabilityError as exc:
        message = str(exc)
        assert "dt_safety" in message and "node" in message, message
        return
    x_ref, y_ref, _ = analytic.elastica_tip(ELASTICA_LOAD)
    tip = system.nodes.x[-1]
    # 2 % of L as above; three nodes err by ~1 % of L (run with dt_safety 0.1)
    assert tip[0] / ROD_LENGTH == pytest.approx(x_ref, abs=0.02)
    assert -tip[2] / ROD_LENGTH == pytest.approx(y_ref, abs=0.02)


# ------------------------------------------------------------------------------ 4. frequencies
def test_steel_rod_bending_frequencies(tmp_path):
    # 16 nodes: the coarsest chain whose third mode is inside 2 % (11 nodes: -2.6 %)
    n_nodes = 16
    E, rho = STEEL["youngs_modulus"], STEEL["density"]
    I = analytic.circle_second_moment(ROD_RADIUS)
    A = analytic.circle_area(ROD_RADIUS)
    ref = analytic.cantilever_frequencies(ROD_LENGTH, E, I, rho, A, n_modes=3)
    assert ref == pytest.approx([6.353, 39.81, 111.47], rel=1e-3)  # the brief's numbers
    # a 2 ms triangular tip pulse of 0.1 N peak (impulse 1e-4 N s): its spectrum sinc^2(f 1ms)
    # falls by only 4 % at 111 Hz, and the tip swings ~2.5 mm (0.6 % of L: linear regime)
    pulse = {"times": [0.0, 0.001, 0.002], "values": [0.0, 1.0, 0.0]}
    scene = cantilever_scene(n_nodes=n_nodes, length=ROD_LENGTH, root_radius=ROD_RADIUS,
                             tip_radius=ROD_RADIUS, material=STEEL, tip_force=0.1,
                             profile=pulse, duration=2.0, record_interval=1e-3,
                             local_damping=0.0)
    _, time, tip = run_tip(scene, tmp_path / "run.h5")
    free = time > 0.002
    measured = peak_frequencies(time[free], tip[free, 2], 3)
    # 2 %: lumped node masses lower every frequency by O(h^2) (at 16 nodes: -0.20 %, -0.71 %,
    # -1.16 %); the spectral estimate itself is good to ~1e-4 over 2 s (12 periods of mode 1;
    # tests/engine/test_spectrum.py)
    np.testing.assert_allclose(measured, ref, rtol=0.02)
    # lumped mass errs low, never high
    assert np.all(measured < ref)


# ------------------------------------------------------------------------------ 5. timestep
def discrete_highest_frequency(system: engine.System) -> float:
    """Highest angular frequency (rad/s) of the linearised, straight, unloaded bristle exactly
    as the engine discretises it: lumped node masses and inertias, and per bond the axial
    spring k_n, the twist spring k_t, and in each bending plane the midpoint shear spring k_s
    with the bending spring k_b (element matrix of bonds.py). Root clamped."""
    nodes, bonds = system.nodes, system.bonds
    free = nodes.inv_mass > 0
    n = nodes.mass.shape[0]
    omega2 = 0.0
    # axial and twist chains: 1 DOF per node
    for k, inertia in ((bonds.kn, nodes.mass), (bonds.kt, nodes.inertia)):
        K = np.zeros((n, n))
        for b in range(len(bonds.i)):
            i, j = bonds.i[b], bonds.j[b]
            K[np.ix_([i, j], [i, j])] += k[b] * np.array([[1.0, -1.0], [-1.0, 1.0]])
        s = 1.0 / np.sqrt(inertia[free])
        omega2 = max(omega2, np.linalg.eigvalsh(K[np.ix_(free, free)] * np.outer(s, s)).max())
    # bending plane: DOFs (u, theta) per node
    K = np.zeros((2 * n, 2 * n))
    for b in range(len(bonds.i)):
        i, j = bonds.i[b], bonds.j[b]
        ks, kb, ksb, h = bonds.ks[b], bonds.kb[b], bonds.ksb[b], bonds.L0[b]
        # energy 1/2 ks d^2 + ksb d phi + 1/2 kb phi^2 with d = g . u, phi = p . u
        g = np.array([-1.0, -h / 2, 1.0, -h / 2])
        p = np.array([0.0, -1.0, 0.0, 1.0])
        ke = ks * np.outer(g, g) + ksb * (np.outer(g, p) + np.outer(p, g)) + kb * np.outer(p, p)
        idx = [2 * i, 2 * i + 1, 2 * j, 2 * j + 1]
        K[np.ix_(idx, idx)] += ke
    m = np.empty(2 * n)
    m[0::2], m[1::2] = nodes.mass, nodes.inertia
    keep = np.repeat(free, 2)
    s = 1.0 / np.sqrt(m[keep])
    omega2 = max(omega2, np.linalg.eigvalsh(K[np.ix_(keep, keep)] * np.outer(s, s)).max())
    return math.sqrt(omega2)


@pytest.mark.parametrize("case", ["steel_rod", "silicone_cone"])
def test_automatic_timestep_is_below_the_stability_limit(case):
    if case == "steel_rod":
        geometry = dict(length=ROD_LENGTH, root_radius=ROD_RADIUS, tip_radius=ROD_RADIUS,
                        material=STEEL, n_nodes=21)
    else:
        geometry = dict(length=CONE_LENGTH, root_radius=CONE_ROOT_RADIUS,
                        tip_radius=CONE_TIP_RADIUS, material=SILICONE, n_nodes=16)
    scene = cantilever_scene(**geometry, tip_force=1e-3, profile=quasi_static(),
                             duration=1.0, record_interval=0.01, local_damping=0.0)
    system = engine.build(scene)
    safety = scene.run.dt_safety
    # dt is the safety fraction of the limit (1e-12: one rounding of the product)
    assert 0 < system.dt <= safety * system.dt_stable * (1 + 1e-12)
    assert system.dt == pytest.approx(safety * system.dt_stable, rel=1e-12)
    label = system.dt_limited_by
    assert isinstance(label, str) and "brush 'rod'" in label and "node" in label, label
    assert ("translation" in label) or ("rotation" in label), label
    # the limit is a true stability limit of leapfrog (2 / omega_max) for the unloaded chain:
    # dt_stable <= 2 / omega_max, equality allowed to rounding (1e-12)
    omega_max = discrete_highest_frequency(system)
    assert system.dt_stable <= 2.0 / omega_max * (1 + 1e-12)
    # ...and not wastefully small: within 2x of it (a looser bound would double every run;
    # measured 1.06 for the steel rod, 1.32 for the cone)
    assert system.dt_stable >= 0.5 * 2.0 / omega_max
