"""What a run records: the channels a scene asks for (``run.channels``), the static datasets
written once, and each frame's values from the current state."""
from __future__ import annotations

import numpy as np

from engine.assembly.system import System
from engine.stepping.observables import (CONTROLLER_CHANNELS, RELEASE_CHANNELS, actuator_wrench,
                          bending_moments, controller_record, energies, mount_torques,
                          root_reactions)
from engine.io.recorder import state_channels, state_frame
from engine.state import ACC_N_BB, ACC_N_BODY, ACC_N_BODYBODY

def run_channels(system: System) -> tuple[dict, dict]:
    """The recorded channels ``{name: (per-frame shape, dtype)}`` and the static datasets
    ``{name: array}`` of this system's scene."""
    sc = system.scene
    want = set(sc.run.channels)
    ch: dict[str, tuple] = {"time": ((), "f8")}
    static: dict[str, np.ndarray] = {}
    N = system.n_nodes
    if "nodes" in want and N:
        ch["nodes/positions"] = ((N, 3), "f8")
        static["nodes/radius"] = system.nodes.rad
        static["bristles/first_node"] = system.bristle_first_node
        static["bristles/brush"] = system.bristle_brush
        static["bonds/nodes"] = np.stack([system.bonds.i, system.bonds.j], axis=1)
    if "bodies" in want:
        controlled = _controlled_bodies(system)
        for k, name in enumerate(system.body_names):
            for key, n in (("position", 3), ("orientation", 4), ("velocity", 3),
                           ("angular_velocity", 3), ("contact_force", 3),
                           ("contact_torque", 3), ("total_force", 3), ("total_torque", 3)):
                ch[f"bodies/{name}/{key}"] = ((n,), "f8")
            if k in controlled:
                ch[f"bodies/{name}/actuator_force"] = ((3,), "f8")
                ch[f"bodies/{name}/actuator_torque"] = ((3,), "f8")
            sl = slice(*_tri_range(system, k))
            tris = system.bodies.tris[sl]
            v0 = tris.min() if len(tris) else 0
            v1 = tris.max() + 1 if len(tris) else 0
            static[f"bodies/{name}/vertices"] = system.bodies.verts[v0:v1]
            static[f"bodies/{name}/triangles"] = tris - v0
    if "root_force" in want:
        for b in system.brushes:
            ch[f"brushes/{b.name}/root_force"] = ((3,), "f8")
            ch[f"brushes/{b.name}/root_torque"] = ((3,), "f8")
            if b.mount >= 0:  # the load's moment about the mount's centre of mass
                ch[f"brushes/{b.name}/mount_torque"] = ((3,), "f8")
    if "energy" in want:
        for key in ("kinetic", "bond", "contact", "gravity", "dissipated", "external_work",
                    "total"):
            ch[f"energy/{key}"] = ((), "f8")
    if "contacts" in want:
        for key in ("bristle_bristle", "bristle_body", "body_body"):
            ch[f"contacts/{key}"] = ((), "i8")
    for c in sc.controllers:  # always recorded: a controller's record is small
        for key, shape in CONTROLLER_CHANNELS:
            ch[f"controllers/{c.name}/{key}"] = (shape, "f8")
        if c.release_below is not None or c.release_below_fraction is not None:  # only then: results without it stay as they were
            for key, shape in RELEASE_CHANNELS:
                ch[f"controllers/{c.name}/{key}"] = (shape, "f8")
    if "bending" in want and system.bonds.i.shape[0]:
        ch["bonds/bending_moment"] = ((system.bonds.i.shape[0],), "f4")
        static.setdefault("bonds/nodes", np.stack([system.bonds.i, system.bonds.j], axis=1))
    extra_ch, extra_static = state_channels(system)  # velocities, spins, mass properties
    ch.update(extra_ch)
    static.update(extra_static)
    return ch, static


def _controlled_bodies(system: System) -> set[int]:
    """Indices of the bodies a controller acts on."""
    idx = system.mission.ctl_index
    return {int(idx[c, 0]) for c in range(idx.shape[0])}


def _tri_range(system: System, k: int) -> tuple[int, int]:
    counts = [len(g.triangles) for g in system.body_geometry]
    start = sum(counts[:k])
    return start, start + counts[k]


def run_frame(system: System, channels: dict) -> dict:
    """One frame: the current value of each channel in ``channels``."""
    fr: dict = {"time": system.time}
    if "nodes/positions" in channels:
        fr["nodes/positions"] = system.nodes.x
    bd = system.bodies
    for k, name in enumerate(system.body_names):
        key = f"bodies/{name}/position"
        if key in channels:
            fr[key] = bd.pos[k]
            fr[f"bodies/{name}/orientation"] = bd.q[k]
            fr[f"bodies/{name}/velocity"] = bd.v[k]
            fr[f"bodies/{name}/angular_velocity"] = bd.w[k]
            # contacts alone; the total adds mounted brushes' roots, orbit (gravity gradient,
            # Hill frame), external loads and controllers (uniform gravity is not in it)
            fr[f"bodies/{name}/contact_force"] = bd.f_contact[k]
            fr[f"bodies/{name}/contact_torque"] = bd.tq_contact[k]
            fr[f"bodies/{name}/total_force"] = bd.f[k]
            fr[f"bodies/{name}/total_torque"] = bd.tq[k]
            if f"bodies/{name}/actuator_force" in channels:
                af, at = actuator_wrench(system, k)
                fr[f"bodies/{name}/actuator_force"] = af
                fr[f"bodies/{name}/actuator_torque"] = at
    if any(k.startswith("brushes/") for k in channels):
        reactions = root_reactions(system)
        for name, (f, t) in reactions.items():
            fr[f"brushes/{name}/root_force"] = f
            fr[f"brushes/{name}/root_torque"] = t
        for name, t in mount_torques(system, reactions).items():
            fr[f"brushes/{name}/mount_torque"] = t
    if "energy/total" in channels:
        for key, val in energies(system).items():
            fr[f"energy/{key}"] = val
    if "contacts/bristle_bristle" in channels:
        fr["contacts/bristle_bristle"] = int(system.acc[ACC_N_BB])
        fr["contacts/bristle_body"] = int(system.acc[ACC_N_BODY])
        fr["contacts/body_body"] = int(system.acc[ACC_N_BODYBODY])
    if "bonds/bending_moment" in channels:
        fr["bonds/bending_moment"] = bending_moments(system).astype(np.float32)
    for c, ctl in enumerate(system.scene.controllers):
        for key, val in controller_record(system, c).items():
            fr[f"controllers/{ctl.name}/{key}"] = val
    fr.update(state_frame(system, channels))
    return fr
