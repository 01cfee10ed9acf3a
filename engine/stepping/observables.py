"""What a built system's current state amounts to: energies, momenta, the reactions at the
brush roots, bending moments per bond and each controller's record.

Plain numpy over the ``System``'s arrays (the bond moments call the bond kernel once). The run
records these per frame (``engine.stepping.channels``); tests and studies call them on a live system.
"""
from __future__ import annotations

import numpy as np

from engine.kernels.bodies import FREE, HINGE
from engine.assembly.system import System
from engine.kernels.orbit import orbit_energy_terms
from engine.model.layout import quat_to_matrix
from engine.state import ACC_DISSIPATED, ACC_E_BB, ACC_E_BODY, ACC_E_BODYBODY, ACC_HINGE_DISS, ACC_WORK

#: per controller: (name, per-frame shape); forces and torques in the body's mesh axes,
#: impulses and errors in world axes (engine.kernels.control)
CONTROLLER_CHANNELS = (("commanded_force", (3,)), ("applied_force", (3,)),
                        ("commanded_torque", (3,)), ("applied_torque", (3,)),
                        ("impulse", (3,)), ("angular_impulse", (3,)), ("delta_v", ()),
                        ("angular_impulse_total", ()), ("position_error", (3,)),
                        ("attitude_error", (3,)), ("samples", ()),
                        ("saturated_force_samples", (3,)), ("saturated_torque_samples", (3,)))
#: (``samples`` counts the controller's samples, ``saturated_*_samples`` those at which each
#: body axis's command was clipped: their ratio is the saturation fraction)
#: added for a controller with a release rule (``release_below`` or ``_fraction``): 1 once released, and the
#: time of the releasing sample (-1 before)
RELEASE_CHANNELS = (("released", ()), ("release_time", ()))


def controller_record(system: System, c: int) -> dict[str, np.ndarray]:
    """Controller c's current record (CONTROLLER_CHANNELS, and RELEASE_CHANNELS for a
    controller with ``release_below``)."""
    from engine.kernels import control as C
    cs = system.mission.ctl_state[c]
    slots = {"commanded_force": C.S_CMD_F, "applied_force": C.S_APP_F,
             "commanded_torque": C.S_CMD_T, "applied_torque": C.S_APP_T,
             "impulse": C.S_IMPULSE, "angular_impulse": C.S_ANG_IMPULSE,
             "position_error": C.S_ERR_POS, "attitude_error": C.S_ERR_ATT}
    out = {k: cs[i:i + 3].copy() for k, i in slots.items()}
    out["delta_v"] = np.float64(cs[C.S_DELTA_V])
    out["angular_impulse_total"] = np.float64(cs[C.S_ANG_IMPULSE_ABS])
    out["samples"] = np.float64(cs[C.S_SAMPLES])
    out["saturated_force_samples"] = cs[C.S_SAT_F:C.S_SAT_F + 3].copy()
    out["saturated_torque_samples"] = cs[C.S_SAT_T:C.S_SAT_T + 3].copy()
    ctl = system.scene.controllers[c]
    if ctl.release_below is not None or ctl.release_below_fraction is not None:
        out["released"] = np.float64(cs[C.S_RELEASED])
        out["release_time"] = np.float64(cs[C.S_RELEASE_TIME])
    return out


def actuator_wrench(system: System, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The force and torque (world axes, N and N m) that body k's controllers applied at the
    last force evaluation: their held, clipped commands (``applied_force``/``applied_torque``,
    mesh axes) turned into the world as ``apply_controllers`` does. Zero without one."""
    from engine.kernels import control as C
    from engine.kernels.rotations import qmul, qrot
    force = np.zeros(3)
    torque = np.zeros(3)
    ms, q = system.mission, system.bodies.q
    for c in range(ms.ctl_index.shape[0]):
        if int(ms.ctl_index[c, 0]) != k:
            continue
        cp, cs = ms.ctl_par[c], ms.ctl_state[c]
        m = qmul(q[k, 0], q[k, 1], q[k, 2], q[k, 3], *cp[C.P_QBM:C.P_QBM + 4])
        force += qrot(*m, *cs[C.S_APP_F:C.S_APP_F + 3])
        torque += qrot(*m, *cs[C.S_APP_T:C.S_APP_T + 3])
    return force, torque


def energies(system: System) -> dict[str, float]:
    """Energies of the current state (J). Bond energy is that of the last force evaluation.
    ``dissipated`` and ``external_work`` are running books of the run; the step loop keeps
    the bond damping's and the local damping's share of ``dissipated`` only in a run that
    records the ``energy`` channel (``Flags.track_energy``), so read them from such a run."""
    nd, bd = system.nodes, system.bodies
    free = nd.inv_mass > 0
    kin = 0.5 * float(np.sum(nd.mass[free] * np.sum(nd.v[free] ** 2, axis=1)))
    kin += 0.5 * float(np.sum(nd.inertia[free] * np.sum(nd.w[free] ** 2, axis=1)))
    g = system.tables.gravity
    grav = -float(np.sum(nd.mass[free] * ((nd.x[free] - nd.x0[free]) @ g)))
    for k in range(bd.pos.shape[0]):
        if bd.motion[k] == FREE:
            kin += 0.5 * bd.mass[k] * float(bd.v[k] @ bd.v[k]) + 0.5 * float(bd.w[k] @ bd.L[k])
            grav -= bd.mass[k] * float((bd.pos[k] - bd.pos0[k]) @ g)
        elif bd.motion[k] == HINGE:
            om = float(bd.w[k] @ bd.hinge_axis[k])
            kin += 0.5 * bd.hinge_inertia[k] * om * om
            grav -= bd.mass[k] * float((bd.pos[k] - bd.pos0[k]) @ g)
    grav += orbit_energy(system)  # tidal (Clohessy-Wiltshire) potential; 0 without an orbit
    bond = float(system.bonds.energy.sum())
    contact = float(system.acc[ACC_E_BB] + system.acc[ACC_E_BODY] + system.acc[ACC_E_BODYBODY])
    diss = float(system.acc[ACC_HINGE_DISS] + system.acc[ACC_DISSIPATED])
    work = float(system.acc[ACC_WORK])
    return {"kinetic": kin, "bond": bond, "contact": contact, "gravity": grav,
            "dissipated": diss, "external_work": work, "total": kin + bond + contact + grav}


def angular_momentum(system: System, about=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Total angular momentum of free nodes and free/hinge bodies about a point."""
    nd, bd = system.nodes, system.bodies
    o = np.asarray(about, float)
    free = nd.inv_mass > 0
    Lt = np.sum(np.cross(nd.x[free] - o, nd.mass[free, None] * nd.v[free]), axis=0)
    Lt = Lt + np.sum(nd.inertia[free, None] * nd.w[free], axis=0)
    for k in range(bd.pos.shape[0]):
        if bd.motion[k] == FREE:
            Lt = Lt + np.cross(bd.pos[k] - o, bd.mass[k] * bd.v[k]) + bd.L[k]
    return Lt


def linear_momentum(system: System) -> np.ndarray:
    nd, bd = system.nodes, system.bodies
    free = nd.inv_mass > 0
    p = np.sum(nd.mass[free, None] * nd.v[free], axis=0)
    for k in range(bd.pos.shape[0]):
        if bd.motion[k] == FREE:
            p = p + bd.mass[k] * bd.v[k]
    return p


def root_reactions(system: System) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per brush: the total force the base exerts on the roots, and its moment about the
    base origin."""
    nd, rt, bd = system.nodes, system.roots, system.bodies
    out = {}
    for b in system.brushes:
        nodes = rt.node[b.root_index]
        f = nd.f[nodes]
        if b.mount >= 0:
            origin = bd.pos[b.mount] + quat_to_matrix(bd.q[b.mount]) @ b.base_local
        else:
            origin = b.base_position
        force = -f.sum(axis=0)
        torque = -(np.cross(nd.x[nodes] - origin, f).sum(axis=0) + nd.t[nodes].sum(axis=0))
        out[b.name] = (force, torque)
    return out


def mount_torques(system: System, reactions=None) -> dict[str, np.ndarray]:
    """Per brush mounted on a body: the moment of its roots' load on that body about the
    body's centre of mass (N m, world axes): what the body's attitude control sees (the
    ``root_torque`` is about the brush base). ``reactions``: :func:`root_reactions`' value,
    if already computed."""
    reactions = root_reactions(system) if reactions is None else reactions
    bd = system.bodies
    out = {}
    for b in system.brushes:
        if b.mount < 0:
            continue
        force, torque = reactions[b.name]
        origin = bd.pos[b.mount] + quat_to_matrix(bd.q[b.mount]) @ b.base_local
        # the load on the body is -force at the base with moment -torque about it
        out[b.name] = -(torque + np.cross(origin - bd.pos[b.mount], force))
    return out


def bending_moments(system: System) -> np.ndarray:
    """Bending moment magnitude per bond at its midpoint (N m), from the current state: the
    bond kernel's own value (the gradient of the bond energy in the bending rotation,
    ``|k_b phi + k_sb e_z x d|``, which includes a tapered bond's shear coupling)."""
    from engine.kernels.bonds import bond_forces
    nd, bn = system.nodes, system.bonds
    B = bn.i.shape[0]
    bend = np.zeros(B)
    bond_forces(nd.x, nd.v, nd.q, nd.w, bn.i, bn.j, bn.kn, bn.ks, bn.kb, bn.ksb, bn.kt, bn.L0,
                bn.cn, bn.cs, bn.cb, bn.ct, np.zeros((B, 3)), np.zeros((B, 3)),
                np.zeros((B, 3)), np.zeros(B), np.zeros(B), bend, False, True, system.dt)
    return bend


def orbit_energy(system) -> float:
    """The orbital part of the Jacobi integral of the current state (J):
    :func:`engine.kernels.orbit.orbit_energy_terms` of the live system."""
    n = float(system.mission.orbit[0])
    if n == 0.0:
        return 0.0
    nd, bd = system.nodes, system.bodies
    free = nd.inv_mass > 0
    B = bd.pos.shape[0]
    R = np.array([quat_to_matrix(bd.q[k]) for k in range(B)]).reshape(1, B, 3, 3)
    return float(orbit_energy_terms(
        n, system.mission.orbit[1] != 0.0, nd.mass[free], nd.x[free][None],
        bd.motion[None], bd.mass, bd.pos[None], R, bd.Ip, bd.L[None])[0])
