"""Build: turn a validated scene into flat arrays, and switch on only the stages it needs.

``build(scene) -> System``. The System owns the compiled state (``engine.state`` bundles), the
list of assembled stages (the ``Flags`` that switch the step loop's branches, named by
``engine.state.STAGE_TABLE``), the timestep and the element that limits it, and the names that map
array indices back to brushes, bristles, nodes and bodies.

:func:`build` reads as the data flow; each part has its builder: materials (here), bodies
(``engine.assembly.bodies``), bristles, bonds and roots (``engine.assembly.bristles``, with the rest
layout of ``engine.model.layout``), what can touch what (``engine.assembly.contacts``), node loads and
the mission (``engine.assembly.loads``), the timestep (``engine.assembly.timestep.choose_dt``), the
flags and stages (here), and the neighbour lists (``engine.assembly.neighbours``).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from engine.assembly import neighbours, overlap
from engine.kernels.bodies import FIXED
from engine.assembly.bodies import BodyPart, build_bodies, start_on_profiles
from engine.assembly.bristles import BristlePart, BrushInfo, build_bristles, start_with_mounts
from engine.assembly.contacts import ContactNeeds, contact_needs, max_body_speed, timestep_inputs
from engine.assembly.loads import build_loads, build_mission
from engine.assembly.patches import build_patches, timestep_entries
from engine.kernels.contact_law import restitution_damping_ratio
from engine.errors import SceneError
from engine.model.layout import quat_to_matrix
from engine.kernels.mesh_contact import initial_overlap
from engine.model.spec import Scene
from engine.state import (ACC_SIZE, ACC_STEPS, ACC_TIME, LIMIT_BODY_STEP, LIMIT_LOCAL_DAMPING,
                    LIMIT_NODE_STEP, LIMIT_OVERLAP, LIMIT_SKIN, LIMITS_SIZE, PRESCRIBED_FIELDS,
                    STAGES, STATE_ARRAYS, STATE_FIELDS, Bodies, BodyList, Bonds, Flags, Loads,
                    Mission, Nodes, PairList, Roots, Tables, assembled_stages)
from engine.assembly.timestep import MAX_BODY_STEP_RATIO, choose_dt, equalizing_scales

MAX_OVERLAP_RATIO = 0.5      # contact overlap / radius that counts as a blow-up
MAX_NODE_STEP_RATIO = 0.5    # node displacement per step / its radius
# MAX_BODY_STEP_RATIO (engine.assembly.timestep): body surface displacement per step / smallest
# bristle radius
CHECK_EVERY = 16
TIME_EVERY = 64


@dataclass
class System:
    """A scene compiled for the step loop. ``run`` advances it; it can be run again to
    continue from where it stopped."""

    scene: Scene
    nodes: Nodes
    bonds: Bonds
    roots: Roots
    bodies: Bodies
    pairs: PairList
    body_pairs: BodyList
    loads: Loads
    tables: Tables
    flags: Flags
    acc: np.ndarray
    err: np.ndarray
    stage_time: np.ndarray
    limits: np.ndarray
    dt: float
    dt_limited_by: str
    dt_stable: float
    stages: list[str]
    brushes: list[BrushInfo]
    body_names: list[str]
    bristle_first_node: np.ndarray   # (n_bristles + 1,)
    bristle_brush: np.ndarray        # (n_bristles,)
    node_bristle: np.ndarray
    warnings: list[str] = field(default_factory=list)
    body_geometry: list = field(default_factory=list)
    body_frame_offset: list = field(default_factory=list)  # quaternion shape->body per body
    prescribed_motions: list = field(default_factory=list)  # changes by prescribe_motion
    mission: Optional[Mission] = None   # orbit, controllers, external body loads
    patches: Optional[object] = None    # reduced brushes (engine.state.Patches)
    patch_info: list = field(default_factory=list)  # per patch (engine.assembly.patches)

    @property
    def controller_names(self) -> list[str]:
        return [c.name for c in self.scene.controllers]

    @property
    def time(self) -> float:
        return float(self.acc[ACC_TIME])

    @property
    def steps(self) -> int:
        return int(self.acc[ACC_STEPS])

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.x.shape[0])

    @property
    def n_bristles(self) -> int:
        return int(self.bristle_brush.shape[0])

    def node_label(self, n: int) -> str:
        b = int(self.node_bristle[n])
        if b < 0:
            return f"node {n}"
        brush = self.brushes[int(self.bristle_brush[b])]
        return (f"brush {brush.name!r} bristle {b - brush.first_bristle} node "
                f"{n - int(self.bristle_first_node[b])}")

    def segment_label(self, s: int) -> str:
        return self.node_label(int(self.bonds.i[s])).replace(" node ", " segment ")

    # ---- model and state (engine.state.STATE_FIELDS): snapshots and branches
    def save_state(self) -> "StateSnapshot":
        """A copy of this system's state (the arrays a run writes, the prescribed motions):
        :meth:`restore_state` puts it back, so a study can run on from one state several
        times. Costs a copy of the state arrays only; the model is not copied."""
        bundles = {}
        for name, fields in _state_fields():
            bundle = getattr(self, name)
            if bundle is not None:
                bundles[name] = {f: getattr(bundle, f).copy() for f in fields}
        return StateSnapshot(bundles=bundles,
                             arrays={a: getattr(self, a).copy() for a in STATE_ARRAYS},
                             prescribed_motions=[dict(m) for m in self.prescribed_motions])

    def restore_state(self, snapshot: "StateSnapshot") -> None:
        """Put back the state ``snapshot`` (:meth:`save_state` of this system or of a
        :meth:`branch` of it) holds: a run then goes on exactly (bit for bit) as it went on
        from the saved moment. Arrays are copied in place where they have the saved shape
        (a neighbour list that grew since, or a profile that ``prescribe_motion`` replaced,
        gets a copy of the saved one), so nothing is compiled again. The snapshot stays
        valid: it can be restored again."""
        fixed = [(n, f) for n, fields in STATE_FIELDS.items() if n not in _RESIZED
                 for f in fields if n in snapshot.bundles]
        if set(snapshot.bundles) != {n for n, _ in _state_fields() if getattr(self, n)
                                     is not None} or any(
                getattr(getattr(self, n), f).shape != snapshot.bundles[n][f].shape
                for n, f in fixed):
            raise ValueError("restore_state: the snapshot is of another system (its state "
                             "arrays have other shapes)")
        for name, saved in snapshot.bundles.items():
            bundle = getattr(self, name)
            replaced = {}
            for f, a in saved.items():
                mine = getattr(bundle, f)
                if mine.shape == a.shape:
                    mine[...] = a
                else:
                    replaced[f] = a.copy()
            if replaced:
                setattr(self, name, bundle._replace(**replaced))
        for a, saved in snapshot.arrays.items():
            getattr(self, a)[...] = saved
        self.prescribed_motions = [dict(m) for m in snapshot.prescribed_motions]

    def branch(self) -> "System":
        """A new system at this system's state that shares its model arrays (never written
        by a run) and owns copies of its state: running, restoring or prescribing motions
        on the branch leaves this system as it is, and the reverse."""
        child = dataclasses.replace(self, warnings=list(self.warnings),
                                    prescribed_motions=[dict(m) for m in
                                                        self.prescribed_motions])
        for name, fields in _state_fields():
            bundle = getattr(self, name)
            if bundle is not None:
                setattr(child, name, bundle._replace(
                    **{f: getattr(bundle, f).copy() for f in fields}))
        for a in STATE_ARRAYS:
            setattr(child, a, getattr(self, a).copy())
        return child


# bundles whose arrays a system may replace by larger ones (a neighbour list's growth)
_RESIZED = ("pairs", "body_pairs")


def _state_fields():
    """``(System attribute, fields)`` of every bundle field a snapshot holds: the state
    (``engine.state.STATE_FIELDS``) and what ``prescribe_motion`` changes."""
    for name in STATE_FIELDS.keys() | PRESCRIBED_FIELDS.keys():
        fields = tuple(STATE_FIELDS.get(name, ())) + tuple(PRESCRIBED_FIELDS.get(name, ()))
        if fields:
            yield name, fields


@dataclass(frozen=True)
class StateSnapshot:
    """A system's state at one moment (:meth:`System.save_state`): copies of the arrays a
    run writes (``engine.state.STATE_FIELDS`` and ``STATE_ARRAYS``) and of the prescribed
    motions (``PRESCRIBED_FIELDS``, ``System.prescribed_motions``)."""

    bundles: dict             # System attribute -> {field: array}
    arrays: dict              # "acc", "err", "stage_time" -> array
    prescribed_motions: list

    @property
    def time(self) -> float:
        return float(self.arrays["acc"][ACC_TIME])

    @property
    def steps(self) -> int:
        return int(self.arrays["acc"][ACC_STEPS])

    @property
    def nbytes(self) -> int:
        """The bytes of its arrays."""
        return (sum(a.nbytes for fields in self.bundles.values() for a in fields.values())
                + sum(a.nbytes for a in self.arrays.values()))


# ----------------------------------------------------------------------------- build
def build(scene: Scene) -> System:
    """Compile a validated scene. Raises SceneError for problems only the build can see
    (unreadable meshes, a dt override above the stability limit is only warned about)."""
    if not isinstance(scene, Scene):
        raise SceneError.single("(scene)", type(scene).__name__,
                                "build() takes an engine.Scene (see engine.load_scene)")
    warnings: list[str] = []
    tables, mat_index = build_materials(scene)
    orbit = scene.environment.orbit
    orbit_n = orbit.n if orbit is not None else 0.0
    body_part = build_bodies(scene, mat_index, orbit_n, warnings)
    # roots are placed on their mounts at the bodies' poses, then kinematic bodies start
    # on their profiles
    bristles = build_bristles(scene, mat_index, body_part.names, body_part.bodies)
    placed_pos, placed_q = body_part.bodies.pos.copy(), body_part.bodies.q.copy()
    start_on_profiles(body_part.bodies)
    start_with_mounts(bristles, body_part.bodies, placed_pos, placed_q)
    _check_initial_overlap(scene, bristles, body_part, warnings)
    needs = contact_needs(scene, bristles, body_part, tables, warnings)
    patches, patch_info = build_patches(scene, body_part.bodies, body_part.names)
    node_free = bristles.nodes.inv_mass > 0
    loads = build_loads(scene, bristles.brushes, bristles.nodes.inv_mass)
    dt, dt_stable, limited_by = _timestep(scene, bristles, body_part, tables, needs, warnings,
                                          patch_info)
    flags = build_flags(scene, bristles, body_part.bodies, tables, needs, node_free, loads)
    flags = flags._replace(patches=bool(patch_info) and bool(patches.pair.any()))
    r_min = float(bristles.nodes.rad.min()) if bristles.nodes.rad.size else 0.0
    skin = neighbours.list_skin(scene.run.verlet_skin, r_min)
    mission = build_mission(scene, orbit_n, body_part.names, body_part.shape_to_body)
    stages = assembled_stages(flags)
    # the step loop's limits (engine.state.LIMIT_*)
    limits = np.zeros(LIMITS_SIZE)
    limits[LIMIT_OVERLAP] = MAX_OVERLAP_RATIO
    limits[LIMIT_NODE_STEP] = MAX_NODE_STEP_RATIO
    limits[LIMIT_BODY_STEP] = MAX_BODY_STEP_RATIO * (r_min if bristles.nodes.rad.size else 1.0)
    limits[LIMIT_SKIN] = skin
    limits[LIMIT_LOCAL_DAMPING] = scene.environment.local_damping
    if needs.mesh_mesh:
        _check_mesh_overlap(body_part, warnings)
    pairs, body_pairs = neighbours.allocate(needs.history_bristle, needs.history_body)
    system = System(scene=scene, nodes=bristles.nodes, bonds=bristles.bonds,
                    roots=bristles.roots, bodies=body_part.bodies,
                    pairs=pairs, body_pairs=body_pairs,
                    loads=loads, tables=tables,
                    flags=flags, acc=np.zeros(ACC_SIZE), err=np.zeros(4),
                    stage_time=np.zeros(len(STAGES)), limits=limits, dt=dt,
                    dt_limited_by=limited_by, dt_stable=dt_stable, stages=stages,
                    brushes=bristles.brushes, body_names=body_part.names,
                    bristle_first_node=bristles.bristle_first,
                    bristle_brush=bristles.bristle_brush, node_bristle=bristles.node_bristle,
                    warnings=warnings, body_geometry=body_part.geometry,
                    body_frame_offset=body_part.shape_to_body, mission=mission,
                    patches=patches, patch_info=patch_info)
    if needs.bristle_bristle or needs.bristle_body:
        neighbours.fill(system)
    return system


# ----------------------------------------------------------------------------- builders
def build_materials(scene: Scene) -> tuple[Tables, dict]:
    """The material tables (Young's moduli; per material pair the friction coefficient, the
    tangential stiffness ratio, the damping ratio of the restitution and the pull-off force)
    and gravity, with
    each material's index."""
    mat_names = list(scene.materials)
    mat_index = {m: i for i, m in enumerate(mat_names)}
    M = len(mat_names)
    E_tab = np.array([scene.materials[m].youngs_modulus for m in mat_names], float)
    mu = np.zeros((M, M))
    ktr = np.full((M, M), 0.25)
    zeta = np.zeros((M, M))
    adhesion = np.zeros((M, M))
    for a in range(M):
        for b in range(M):
            pair = scene.pair(mat_names[a], mat_names[b])
            mu[a, b] = math.tan(pair.friction_angle)
            ktr[a, b] = pair.tangential_ratio
            zeta[a, b] = restitution_damping_ratio(pair.restitution)
            adhesion[a, b] = pair.adhesion_force
    gravity = np.asarray(scene.environment.gravity, float)
    return (Tables(E=E_tab, mu=mu, kt=ktr, zeta=zeta, gravity=gravity, adhesion=adhesion),
            mat_index)


def _check_initial_overlap(scene: Scene, bristles: BristlePart, body_part: BodyPart,
                           warnings: list) -> None:
    """Warn about bristles that start inside a body (``engine.assembly.overlap``)."""
    bonds, geoms, bodies = bristles.bonds, body_part.geometry, body_part.bodies
    overlap.check_build(scene, bristles.nodes.x, bristles.nodes.rad,
                        np.stack([bonds.i, bonds.j], 1), bristles.node_bristle,
                        bristles.bristle_brush,
                        [(b.name, b.first_bristle, b.mount) for b in bristles.brushes],
                        [bodies.pos[k] + geoms[k].vertices
                         @ quat_to_matrix(np.asarray(scene.bodies[k].pose.orientation, float)).T
                         for k in range(len(geoms))], [g.triangles for g in geoms],
                        [bool(g.watertight) for g in geoms], bodies.collide, warnings)


def _check_mesh_overlap(body_part: BodyPart, warnings: list) -> None:
    """Refuse mesh bodies that start deeply interpenetrated; warn about shallow overlaps."""
    touching, depth = initial_overlap(body_part.bodies)
    if depth > MAX_OVERLAP_RATIO:
        raise SceneError.single("bodies", body_part.names, (
            f"two mesh bodies start interpenetrating ({depth:.3g} x the contact point "
            f"length deep, limit {MAX_OVERLAP_RATIO}): move them apart, or list one in "
            f"the other's no_contact_with"))
    if touching:
        warnings.append(f"{touching} mesh-mesh contact point(s) start inside another "
                        f"body (at most {depth:.3g} x the contact point length deep)")


def _timestep(scene: Scene, bristles: BristlePart, body_part: BodyPart, tables: Tables,
              needs: ContactNeeds, warnings: list,
              patch_info: list = ()) -> tuple[float, float, str]:
    """``(dt, dt_stable, limited_by)`` of ``engine.assembly.timestep.choose_dt``, after scaling the
    node masses and inertias when the scene asks to equalize them (quasi-static runs)."""
    nodes = bristles.nodes
    N = nodes.x.shape[0]
    r_min = float(nodes.rad.min()) if N else 0.0
    sysinfo = timestep_inputs(bristles, body_part, tables, needs)
    # reduced brushes: their stiffness on both bodies of each pair, as other contacts
    sysinfo["bodies"] = list(sysinfo["bodies"]) + timestep_entries(
        list(patch_info), body_part.bodies, body_part.names)
    if scene.environment.inertia_scaling == "equalize" and N:
        mass_scale, inertia_scale = equalizing_scales(sysinfo)
        nodes.inv_mass[:] /= mass_scale          # the weight (nodes.mass) stays physical
        nodes.inertia[:] *= inertia_scale
        nodes.inv_inertia[:] /= inertia_scale
        sysinfo["node_mass"] = sysinfo["node_mass"] * mass_scale
        sysinfo["node_inertia"] = sysinfo["node_inertia"] * inertia_scale
    body_speed = None
    if N and (needs.bristle_body or needs.body_body):
        speed, fastest = max_body_speed(body_part.bodies, body_part.bodies.collide)
        body_speed = (speed, body_part.names[fastest] if fastest >= 0 else "")
    return choose_dt(sysinfo, scene.run, r_min, body_speed, warnings,
                     local_damping=scene.environment.local_damping,
                     controllers=scene.controllers)


def build_flags(scene: Scene, bristles: BristlePart, bodies: Bodies, tables: Tables,
                needs: ContactNeeds, node_free: np.ndarray, loads: Loads) -> Flags:
    """The step loop's switches: which forces and checks a step computes."""
    rigid = bool(np.any(bodies.motion != FIXED))
    return Flags(bonds=bristles.bonds.i.shape[0] > 0,
                 bond_damping=bool(np.any(bristles.bonds.cn > 0)
                                   or np.any(bristles.bonds.cb > 0)),
                 bristle_bristle=needs.bristle_bristle, bristle_body=needs.bristle_body,
                 body_body=needs.body_body, mesh_mesh=needs.mesh_mesh,
                 # plain ints in Flags (engine.state.SLIP_EACH_STEP and the like)
                 friction_bristle=int(needs.friction_bristle),
                 friction_body=int(needs.friction_body),
                 friction_body_body=int(needs.friction_body_body),
                 rigid_bodies=rigid, mounted_roots=bool(np.any(bristles.roots.body >= 0)),
                 gravity=bool(np.any(tables.gravity != 0)) and (bool(node_free.any()) or rigid),
                 loads=len(scene.loads) > 0 and len(loads.node) > 0,
                 local_damping=scene.environment.local_damping > 0,
                 track_energy="energy" in list(scene.run.channels),
                 check_every=CHECK_EVERY, time_every=TIME_EVERY,
                 orbit=(scene.environment.orbit.n if scene.environment.orbit is not None
                        else 0.0) != 0.0,
                 controllers=len(scene.controllers) > 0,
                 external_loads=any(any(b.external_force) or any(b.external_torque)
                                    for b in scene.bodies),
                 patches=False)  # set by build once the patches are built
