"""What a scene will cost, from the scene alone: bristles, nodes, triangles, an estimate of
the timestep and so of the steps, recorded frames, memory and result-file size.

Nothing is allocated in proportion to the scene: the timestep comes from one representative
bristle per brush (``n_nodes`` nodes, the build's own Gershgorin bound of
:mod:`engine.assembly.timestep`), with every node charged the most contacts the build could give it
(four neighbouring bristles, every colliding body). That bound is at least the build's, so
the estimated dt is at most the build's (more steps, never fewer), within a small factor on
the presets (``tests/engine/test_estimate.py``). It ignores the build's cap on dt from fast
bodies (tunnelling), which can only lower dt further. Imports numpy only (no numba, no
trimesh): the job server and the CLI's ``validate`` call it before anything is built::

    cost = engine.estimate(scene)
    cost.n_nodes, cost.steps, cost.memory_bytes, cost.as_dict()
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Optional

from engine.model.spec import Scene
from engine.state import tangential_ratio

# The peak memory of a process that builds and runs the scene: a fixed part and a part per
# node. Measured (ru_maxrss, kernels loaded from the cache) on 100 x 100 x 8 box-pressed
# brushes and larger (tests/engine/test_build_memory.py): ~230 MB for the interpreter,
# numpy, scipy, h5py and the loaded kernels, plus ~1.2 KB per node for the build (state,
# bonds, the build's bounded checks) and the run; 2 KB per node leaves room for contact
# lists that grow in deep contact and the recorder's buffers. A first run that compiles
# the kernels (an empty numba cache: a fresh installation) holds LLVM's memory on top of
# the built arrays: for 80,000 nodes it peaked at 1.11 GB against 0.41 GB with the cache
# warm (51ae462, the bonds' SIMD blocks among the kernels; 626 MB before them), so the
# fixed part covers that compile (1.23 GB estimated there)
BYTES_PER_NODE = 2_000
BYTES_PER_TRIANGLE = 400   # vertices, normals, pseudo-normals and the triangle grid
BYTES_FIXED = 1024 * 2**20  # the interpreter, the libraries, the kernels (compiled or loaded)
# recorded bytes per node and frame of each per-node channel, as docs/results.md lays them
# out: nodes/positions (N, 3) f8; nodes/velocities and angular_velocities (N, 3) f8 each;
# bonds/bending_moment one f4 per bond (fewer bonds than nodes). The other channels
# (contacts: three counts) are per frame, brush or body and small
_CHANNEL_NODE_BYTES = {"nodes": 3 * 8, "node_velocities": 6 * 8, "bending": 4}
MAX_BRISTLE_CONTACTS = 4   # as engine.assembly.timestep.BRISTLE_CONTACTS_PER_NODE


@dataclass(frozen=True)
class Cost:
    """The size of a scene and of its run. ``dt`` is the estimate (or the scene's own),
    ``steps`` the steps to ``duration``, ``frames`` the recorded frames; ``memory_bytes``
    an upper bound on the peak memory of a process that builds and runs the scene
    (``tests/engine/test_build_memory.py``), ``result_bytes`` the result file (uncompressed);
    ``node_steps = n_nodes * steps`` (what the run's wall time grows with)."""

    n_bristles: int
    n_nodes: int
    n_triangles: Optional[int]  # None: a mesh file whose size is not known here
    dt: float
    dt_given: bool
    duration: float
    steps: float
    frames: float
    dt_bound: float         # the stability limit (stability_bound): a given dt above it fails
    dt_limited_by: str      # what sets dt_bound
    node_steps: float
    memory_bytes: float
    result_bytes: float

    def as_dict(self) -> dict:
        return asdict(self)

    def summary(self) -> str:
        tri = "?" if self.n_triangles is None else f"{self.n_triangles}"
        s = lambda n: "" if n == 1 else "s"  # noqa: E731  ("1 bristle")
        return (f"{self.n_bristles} bristle{s(self.n_bristles)}, {self.n_nodes} "
                f"node{s(self.n_nodes)}, {tri} triangles; dt "
                f"{'(given) ' if self.dt_given else '~ '}{self.dt:.3g} s -> {self.steps:.3g} "
                f"steps, {self.frames:.3g} frames; memory ~ {self.memory_bytes / 2**20:.0f} "
                f"MiB, result ~ {self.result_bytes / 2**20:.0f} MiB")


def shape_triangles(shape, mesh_triangles=None) -> Optional[int]:
    """Triangles of a body shape (``mesh_triangles(file)``: how many a mesh file has, or
    None if unknown)."""
    kind = shape.type
    if kind == "box":
        return 12
    if kind == "sphere":
        return 20 * 4 ** int(shape.subdivisions)
    if kind == "cylinder":
        return 4 * int(shape.sections)
    if kind == "wedge":
        return 8
    if kind == "mesh":
        return mesh_triangles(shape.file) if mesh_triangles is not None else None
    return None


def _bristle_omega2(scene: Scene, brush) -> float:
    """The largest Gershgorin bound of omega^2 over one bristle of ``brush``, every node
    charged the most contacts it could have."""
    import numpy as np

    from engine.assembly.element import frustum_bond_stiffness, node_masses
    from engine.assembly.timestep import equalizing_scales, node_bounds

    mat = scene.materials[brush.material]
    E, rho = mat.youngs_modulus, mat.density
    G = E / (2.0 * (1.0 + mat.poisson_ratio))
    n = brush.n_nodes
    r_node = brush.root_radius + (brush.tip_radius - brush.root_radius) * np.linspace(0, 1, n)
    seg = brush.bristle_length / (n - 1)
    r0, r1 = r_node[:-1], r_node[1:]
    m, inertia = node_masses(rho, r_node, seg)
    kn, ks, kb, ksb, kt = frustum_bond_stiffness(E, G, r0, r1, seg)
    bi, bj = np.arange(n - 1), np.arange(1, n)
    free = np.ones(n, bool)
    free[0] = False  # the root is clamped
    partners = min(MAX_BRISTLE_CONTACTS, brush.n_bristles - 1)
    k_body = np.zeros(n)
    kt_body = 0.0
    for body in scene.bodies:
        if not body.collide:
            continue
        Eb = scene.materials[body.material].youngs_modulus
        sides = 1.0 if body.motion.type in ("fixed", "kinematic") and getattr(
            body.motion, "after", None) != "free" else 2.0
        k_body = k_body + sides * 2.0 * Eb * E * r_node / (Eb + E)
        pair = scene.pair(brush.material, body.material)
        kt_body = max(kt_body, tangential_ratio(pair.tangential_ratio,
                                                math.tan(pair.friction_angle)))
    own = scene.pair(brush.material, brush.material)
    info = dict(node_mass=m, node_inertia=inertia, node_radius=r_node,
                node_E=np.full(n, E), node_free=free,
                node_bristle_contacts=np.full(n, float(partners)), node_k_body=k_body,
                kt_ratio_bristle=tangential_ratio(own.tangential_ratio,
                                                  math.tan(own.friction_angle)),
                kt_ratio_body=kt_body,
                bond_arrays=(bi, bj, kn, ks, kb, ksb, kt, np.full(n - 1, seg)))
    if scene.environment.inertia_scaling == "equalize":
        ms, is_ = equalizing_scales(info)
        info["node_mass"] = m * ms
        info["node_inertia"] = inertia * is_
    w2_t, w2_r, _ = node_bounds(info)
    return float(max(w2_t.max(), w2_r.max()))


def stability_bound(scene: Scene) -> tuple[float, str]:
    """The estimated stability limit of the timestep, ``2 / omega_max`` without
    ``run.dt_safety`` (at most the build's ``dt_stable``), and what sets it; ``inf`` when
    nothing moves elastically. Whatever ``run.dt`` is: a given dt above it is unstable."""
    bounds = [(_bristle_omega2(scene, b), b.name) for b in scene.brushes]
    omega2, name = max(bounds, default=(0.0, ""))
    if not omega2 > 0 or not math.isfinite(omega2):
        return math.inf, "nothing moves elastically"
    return 2.0 / math.sqrt(omega2), f"the bristles of brush {name!r} (bonds and contacts)"


def estimate_dt(scene: Scene) -> float:
    """The automatic timestep the build would choose, estimated from one bristle per brush
    (at most the build's; ``run.dt`` when the scene gives it)."""
    from engine.assembly.timestep import controller_cap

    if scene.run.dt is not None:
        return float(scene.run.dt)
    bound, _ = stability_bound(scene)
    if not math.isfinite(bound):
        dt = float(scene.run.record_interval)  # nothing moves elastically
    else:
        dt = scene.run.dt_safety * bound
    cap = controller_cap(scene.controllers)
    return min(dt, cap[0]) if cap is not None else dt


def _ceil(x: float) -> float:
    return float(math.ceil(x)) if math.isfinite(x) else math.inf


def _floor(x: float) -> float:
    return float(math.floor(x)) if math.isfinite(x) else math.inf


def estimate(scene: Scene, mesh_triangles=None) -> Cost:
    """The cost of ``scene`` (a validated :class:`engine.Scene`), computed in microseconds
    whatever the scene's size. ``mesh_triangles(file) -> int | None`` counts a mesh file's
    triangles (the job server knows them for uploaded meshes)."""
    n_bristles = sum(b.rows * b.columns for b in scene.brushes)
    n_nodes = sum(b.rows * b.columns * b.n_nodes for b in scene.brushes)
    tris = [shape_triangles(body.shape, mesh_triangles) for body in scene.bodies]
    n_triangles = None if any(t is None for t in tris) else int(sum(tris))
    dt = estimate_dt(scene)
    dt_bound, dt_limited_by = stability_bound(scene)
    duration = float(scene.run.duration)
    steps = _ceil(duration / dt) if dt > 0 else math.inf
    frames = _floor(duration / scene.run.record_interval) + 1
    node_bytes = sum(_CHANNEL_NODE_BYTES.get(c, 0) for c in scene.run.channels)
    result_bytes = float(frames) * (n_nodes * node_bytes + 200 * (1 + len(scene.bodies)))
    memory = BYTES_FIXED + n_nodes * BYTES_PER_NODE + (n_triangles or 0) * BYTES_PER_TRIANGLE
    return Cost(n_bristles=n_bristles, n_nodes=n_nodes, n_triangles=n_triangles, dt=dt,
                dt_given=scene.run.dt is not None, duration=duration, steps=float(steps),
                frames=float(frames), dt_bound=dt_bound, dt_limited_by=dt_limited_by,
                node_steps=float(n_nodes) * steps if n_nodes else 0.0,
                memory_bytes=float(memory), result_bytes=result_bytes)
