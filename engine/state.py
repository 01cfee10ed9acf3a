"""The compiled state: flat structure-of-arrays bundles handed to the numba step loop.

Each bundle is a namedtuple of numpy arrays (numba passes them by reference, so kernels
update the arrays in place). ``build`` creates them; nothing else allocates them.
"""
from __future__ import annotations

from collections import namedtuple
from enum import IntEnum

Nodes = namedtuple("Nodes", [
    "x", "v", "q", "w", "f", "t", "mass", "inv_mass", "inertia", "inv_inertia", "rad",
    "bond_prev", "bond_next", "x_build", "x0"])

Bonds = namedtuple("Bonds", [
    "i", "j", "kn", "ks", "kb", "ksb", "kt", "L0", "cn", "cs", "cb", "ct", "f", "ti", "tj",
    "energy", "diss", "bend", "has_next", "bristle", "material", "mount", "mid", "bound",
    "rmax"])

Roots = namedtuple("Roots", ["node", "body", "local_pos", "local_q"])

Bodies = namedtuple("Bodies", [
    "pos", "q", "v", "w", "L", "mass", "Ip", "motion", "f", "tq",
    "hinge_axis", "hinge_point", "hinge_inertia", "hinge_k1", "hinge_k2", "after_free",
    "seg_start", "t0", "t1", "p0", "p1", "v0", "v1", "wseg", "q0", "cursor",
    "sphere_r", "bound_r", "watertight", "material", "collide", "pos_build", "q_build", "pos0",
    "verts", "tris", "tnormal", "tedge", "pnormal", "grid_origin", "grid_cell", "grid_dims", "grid_base",
    "grid_start", "grid_side",
    "grid_tris",
    # per triangle: its body's index where the triangle's plane supports that body's mesh (no
    # vertex in front of it: a face of a convex body), else -1 (body_contacts.supported_face)
    "tsupport",
    "ft_bb", "scratch", "scratch2",
    # mesh-mesh contacts (engine.kernels.mesh_contact): first contact point of each body (K + 1),
    # the points (body frames), per-pair point stiffness (K, K; 0 = the pair does not touch)
    # and length, tangential history per (point, other body)
    "point_start", "points", "mesh_kn", "mesh_len", "ft_mesh",
    # the force and torque of the body's contacts alone (bristle-body, body-body, mesh-mesh)
    # at the last evaluation: ``f``/``tq`` also hold mounted roots, orbit, loads, controllers
    "f_contact", "tq_contact"])

PairList = namedtuple("PairList", [
    "a", "b", "ft", "active", "fc", "cp", "s", "t", "energy", "diss", "ratio", "n",
    "a2", "b2", "ft2", "xf"])

BodyList = namedtuple("BodyList", [
    "s", "b", "ft", "active", "fc", "cp", "par", "energy", "diss", "ratio", "local", "n",
    "s2", "b2", "ft2", "xf", "deep", "deep2",
    # per candidate: the triangle that settled its closest-feature queries last step, a hint
    # checked before use (body_contacts.supported_face); -1 after each rebuild
    "face"])

Loads = namedtuple("Loads", [
    "node", "load", "force", "start", "times", "values", "frequency", "phase", "amp"])

Tables = namedtuple("Tables", ["E", "mu", "kt", "zeta", "gravity", "adhesion"])

# the mission layer: ``orbit`` = [mean motion n (rad/s), gravity gradient on (1) or off (0)];
# controllers (engine.kernels.control: ``ctl_index`` (C, 2), ``ctl_par``, ``ctl_state``);
# ``external`` (K, 6): constant force and torque on free bodies, world axes
Mission = namedtuple("Mission", ["orbit", "ctl_index", "ctl_par", "ctl_state", "external"])

# reduced brushes (engine.kernels.patch): per patch its body, law parameters (``patch.P_*``),
# state (``patch.S_*``), which bodies it may touch (P, K); per sample point (body frame) its
# area over the law's footprint; ``start`` (P + 1) the first point of each patch; ``hits``
# and ``scratch`` working rows
Patches = namedtuple("Patches", ["body", "par", "state", "pair", "start", "pts", "w", "hits",
                                 "scratch"])

# ---- the state: what a run writes (MuJoCo's MjData); every other field is the model
# (MjModel), which ``engine.run`` never writes, so a branch of a system shares it
# (``System.save_state``/``restore_state``/``branch``). Keys are the ``System`` attributes
# holding the bundles; tests/engine/test_state_fields.py checks both ways that a run writes
# exactly these. The neighbour lists are state whole: a rebuild rewrites their entries and
# their build positions (``Nodes.x_build``, ``Bodies.pos_build``/``q_build``), and a growth
# replaces their arrays.
STATE_FIELDS = {
    "nodes": ("x", "v", "q", "w", "f", "t", "x_build"),
    # f, ti, tj: the per-bond actions, written by the energy evaluation at a run's start
    # (engine.stepping.loop._refresh_forces); mid and bound: each rebuild's segment bounds
    "bonds": ("f", "ti", "tj", "energy", "diss", "bend", "mid", "bound"),
    "roots": (),
    # motion: a kinematic body released as free when its profile ends; cursor: the
    # profile's current segment; scratch rows and the last evaluation's forces
    "bodies": ("pos", "q", "v", "w", "L", "motion", "f", "tq", "cursor", "ft_bb", "scratch",
               "scratch2", "pos_build", "q_build", "ft_mesh", "f_contact", "tq_contact"),
    "pairs": PairList._fields,
    "body_pairs": BodyList._fields,
    "loads": ("amp",),
    "tables": (),
    "mission": ("ctl_state",),
    "patches": ("state", "hits", "scratch"),
}
# the System's own state arrays: the accumulators (time, steps, energy books: ``ACC_*``), the
# failure report of the step loop (written only when a run fails) and the stage times
STATE_ARRAYS = ("acc", "err", "stage_time")
# what ``engine.prescribe_motion`` changes between runs (a run never does): the kinematic
# profiles (replaced arrays) and what a body does when its profile ends (written in place)
PRESCRIBED_FIELDS = {
    "bodies": ("seg_start", "t0", "t1", "p0", "p1", "v0", "v1", "wseg", "q0", "after_free"),
}


class Friction(IntEnum):
    """A contact kind's friction mode, ``Flags.friction_*`` (``engine.kernels.contact_law``
    applies it), as ``ContactNeeds`` (``engine.assembly.contacts``) decides it."""

    NONE = 0            # no tangential spring, no Coulomb cap
    SLIP_EACH_STEP = 1  # Coulomb's cap is applied to the kept spring every step (the dynamics)
    SLIP_FROZEN = 2     # the kept spring is the uncapped trial since the last commit: the force
                        # applied is capped, the slip is committed only by a SLIP_EACH_STEP
                        # step (quasi-static increments: engine.stepping.quasistatic)


# the same values as plain ints, as the kernels and ``Flags`` hold them (numba would type an
# IntEnum member as a type of its own and compile ``Flags`` anew)
NO_FRICTION = int(Friction.NONE)
SLIP_EACH_STEP = int(Friction.SLIP_EACH_STEP)
SLIP_FROZEN = int(Friction.SLIP_FROZEN)


def has_tangential_spring(friction_coefficient: float) -> bool:
    """A contact keeps a tangential spring (stiffness ``tangential_ratio`` k_n, with its
    history) only with friction, ``mu = tan(friction_angle) > 0`` (seed eq. 3.8: without
    friction the spring's cap ``mu F_n`` is zero)."""
    return friction_coefficient > 0.0


def tangential_ratio(ratio: float, friction_coefficient: float) -> float:
    """The tangential stiffness ratio a material pair acts with: ``ratio`` where it has a
    tangential spring (:func:`has_tangential_spring`), else 0."""
    return ratio if has_tangential_spring(friction_coefficient) else 0.0


def friction_mode(friction_coefficients) -> Friction:
    """The friction mode of a kind of contact, from the friction coefficients of the material
    pairs it can meet: ``SLIP_EACH_STEP`` where one has a tangential spring, else ``NONE``."""
    return (Friction.SLIP_EACH_STEP
            if any(has_tangential_spring(mu) for mu in friction_coefficients)
            else Friction.NONE)


Flags = namedtuple("Flags", [
    "bonds", "bond_damping", "bristle_bristle", "bristle_body", "body_body", "mesh_mesh",
    "friction_bristle", "friction_body", "friction_body_body", "rigid_bodies",
    "mounted_roots", "gravity", "loads", "local_damping", "track_energy", "check_every",
    "time_every", "orbit", "controllers", "external_loads", "patches"])

# the step loop's limits (float64 array ``System.limits``, built by ``engine.build``)
LIMIT_OVERLAP = 0        # largest contact overlap / node radius before InstabilityError
LIMIT_NODE_STEP = 1      # largest node displacement in one step / node radius
LIMIT_BODY_STEP = 2      # largest body displacement in one step, m
LIMIT_SKIN = 3           # the neighbour lists' skin, m
LIMIT_LOCAL_DAMPING = 4  # Cundall's local damping coefficient alpha
LIMITS_SIZE = 5

# accumulators (float64 array ``acc``)
ACC_HINGE_DISS = 0   # energy the hinges' dissipation removed (bodies_half_kick)
ACC_DISSIPATED = 1
ACC_WORK = 2
ACC_E_BB = 3
ACC_E_BODY = 4
ACC_E_BODYBODY = 5
ACC_N_BB = 6
ACC_N_BODY = 7
ACC_N_BODYBODY = 8
ACC_REBUILDS = 9
ACC_MAX_OVERLAP = 10
ACC_TIME = 11
ACC_STEPS = 12
ACC_TIMED_STEPS = 13
ACC_SIZE = 16

# ---- the step loop's stages: one vocabulary
# Timing slots: the step loop adds each timed part of a step to ``stage_time[SLOT_...]``
# (numba reads these module globals as compile-time constants).
SLOT_INTEGRATE = 0
SLOT_NEIGHBOUR_LIST = 1
SLOT_BONDS = 2
SLOT_BRISTLE_BRISTLE = 3
SLOT_BRISTLE_BODY = 4
SLOT_BODY_BODY = 5
SLOT_EXTERNAL = 6
SLOT_CHECKS = 7
# the slots' names, in slot order: the keys of the run summary's ``stages`` (wall seconds)
STAGES = ("integrate", "neighbour_list", "bonds", "bristle_bristle", "bristle_body",
          "body_body", "external_forces", "checks")
# slots whose work every step does, whatever the scene
ALWAYS_TIMED = (SLOT_INTEGRATE, SLOT_EXTERNAL, SLOT_CHECKS)

Stage = namedtuple("Stage", ["name", "slot", "needed", "what"])
Stage.__doc__ = """One computation stage: ``name`` as ``System.stages`` and the run summary's
``assembled`` list give it, the timing ``slot`` its time is counted in (None: inside another
stage's time), ``needed(flags)`` (assembled when true) and ``what`` it computes (docs/api.md's
table is this text)."""

_FRICTION = lambda f: bool(f.friction_bristle or f.friction_body or f.friction_body_body)

STAGE_TABLE = (
    Stage("bonds", SLOT_BONDS, lambda f: f.bonds,
          "beam bond forces and moments (axial, shear, bending, torsion)"),
    Stage("bond_damping", SLOT_BONDS, lambda f: f.bond_damping,
          "viscous damping inside the bonds"),
    Stage("neighbour_list", SLOT_NEIGHBOUR_LIST,
          lambda f: f.bristle_bristle or f.bristle_body,
          "Verlet lists of segment pairs and segment-body candidates, rebuilt when nodes "
          "have moved half the skin"),
    Stage("bristle_bristle_contacts", SLOT_BRISTLE_BRISTLE, lambda f: f.bristle_bristle,
          "contacts between bristle segments (only where two bristles can reach each other)"),
    Stage("bristle_body_contacts", SLOT_BRISTLE_BODY, lambda f: f.bristle_body,
          "contacts between bristle segments and colliding bodies"),
    Stage("body_body_contacts", SLOT_BODY_BODY, lambda f: f.body_body,
          "contacts between bodies, at least one of them free or hinged"),
    Stage("mesh_mesh_contacts", SLOT_BODY_BODY, lambda f: f.mesh_mesh,
          "the mesh-mesh part of body contacts: sample points of each hull against the other"),
    Stage("patch_contacts", SLOT_BODY_BODY, lambda f: f.patches,
          "reduced brushes: compliant patches with a fitted law against closed meshes"),
    Stage("tangential_history", None, _FRICTION,
          "Coulomb friction with tangential spring history in the contacts"),
    Stage("rigid_bodies", SLOT_INTEGRATE, lambda f: f.rigid_bodies,
          "motion of kinematic, hinged and free bodies"),
    Stage("mounted_roots", SLOT_INTEGRATE, lambda f: f.mounted_roots,
          "bristle roots carried by a body, their forces passed back to it"),
    Stage("gravity", SLOT_EXTERNAL, lambda f: f.gravity, "uniform gravity"),
    Stage("loads", SLOT_EXTERNAL, lambda f: f.loads, "node loads given in the scene"),
    Stage("local_damping", SLOT_EXTERNAL, lambda f: f.local_damping,
          "Cundall local (non-viscous) damping of the node forces"),
    Stage("energy_tracking", None, lambda f: f.track_energy,
          "energy bookkeeping: stored, dissipated and work done"),
    Stage("orbit", SLOT_EXTERNAL, lambda f: f.orbit,
          "Clohessy-Wiltshire relative orbital dynamics (and gravity-gradient torque)"),
    Stage("controllers", SLOT_EXTERNAL, lambda f: f.controllers,
          "pose controllers of controlled bodies"),
    Stage("external_body_loads", SLOT_EXTERNAL, lambda f: f.external_loads,
          "constant external force and torque on bodies"),
)


def assembled_stages(flags) -> list:
    """The names of the stages a system with these flags runs, in the table's order."""
    return [st.name for st in STAGE_TABLE if st.needed(flags)]


def timed_slots(stages) -> list:
    """The timing slots a run of these assembled stages reports, in slot order."""
    used = {st.slot for st in STAGE_TABLE if st.name in stages} | set(ALWAYS_TIMED)
    return [slot for slot in range(len(STAGES)) if slot in used]


def stages_markdown() -> str:
    """docs/api.md's table of stages (a test keeps the page equal to it)."""
    rows = ["| stage | timed in | what it computes |", "|---|---|---|"]
    for st in STAGE_TABLE:
        slot = f"`{STAGES[st.slot]}`" if st.slot is not None else "(within other stages)"
        rows.append(f"| `{st.name}` | {slot} | {st.what} |")
    return "\n".join(rows)


# failure codes returned by the step loop
OK = 0
OVERFLOW_PAIRS = 1
OVERFLOW_BODY = 2
FAIL_NONFINITE_NODE = 10
FAIL_NODE_SPEED = 11
FAIL_OVERLAP_BB = 12
FAIL_OVERLAP_BODY = 13
FAIL_BODY_SPEED = 14
FAIL_NONFINITE_BODY = 15
FAIL_OVERLAP_BODYBODY = 16
