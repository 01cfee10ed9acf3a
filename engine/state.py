"""The compiled state: flat structure-of-arrays bundles handed to the numba step loop.

Each bundle is a namedtuple of numpy arrays (numba passes them by reference, so kernels
update the arrays in place). ``build`` creates them; nothing else allocates them.
"""
from __future__ import annotations

from collections import namedtuple

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
    "verts", "tris", "tnormal", "pnormal", "grid_origin", "grid_cell", "grid_dims", "grid_base", "grid_start",
    "grid_tris", "ft_bb", "scratch", "scratch2",
    # mesh-mesh contacts (engine.mesh_contact): first contact point of each body (K + 1),
    # the points (body frames), per-pair point stiffness (K, K; 0 = the pair does not touch)
    # and length, tangential history per (point, other body)
    "point_start", "points", "mesh_kn", "mesh_len", "ft_mesh"])

PairList = namedtuple("PairList", [
    "a", "b", "ft", "active", "fc", "cp", "s", "t", "energy", "diss", "ratio", "n",
    "a2", "b2", "ft2", "xf"])

BodyList = namedtuple("BodyList", [
    "s", "b", "ft", "active", "fc", "cp", "par", "energy", "diss", "ratio", "local", "n",
    "s2", "b2", "ft2", "xf", "deep", "deep2"])

Loads = namedtuple("Loads", [
    "node", "load", "force", "start", "times", "values", "frequency", "phase", "amp"])

Tables = namedtuple("Tables", ["E", "mu", "kt", "zeta", "gravity"])

# the mission layer: ``orbit`` = [mean motion n (rad/s), gravity gradient on (1) or off (0)];
# controllers (engine.control: ``ctl_index`` (C, 2), ``ctl_par``, ``ctl_state``); ``external``
# (K, 6): constant force and torque on free bodies, world axes
Mission = namedtuple("Mission", ["orbit", "ctl_index", "ctl_par", "ctl_state", "external"])

Flags = namedtuple("Flags", [
    "bonds", "bond_damping", "bristle_bristle", "bristle_body", "body_body",
    "friction_bristle", "friction_body", "friction_body_body", "rigid_bodies",
    "mounted_roots", "gravity", "loads", "local_damping", "track_energy", "check_every",
    "time_every", "orbit", "controllers", "external_loads"])

# accumulators (float64 array ``acc``)
ACC_HINGE_DISS = 0   # must stay 0: bodies_half_kick writes acc[0]
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

# stage timing slots
STAGES = ("integrate", "neighbour_list", "bonds", "bristle_bristle", "bristle_body",
          "body_body", "external_forces", "checks")

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
