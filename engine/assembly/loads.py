"""Build, loads and the mission: forces on bristle nodes (``Loads``), and the mission layer
(``Mission``: the orbit, the controllers of engine.kernels.control, constant external loads on
bodies)."""
from __future__ import annotations

import numpy as np

from engine.errors import SceneError
from engine.model.layout import quat_conj
from engine.model.spec import Scene
from engine.state import Loads, Mission


def build_loads(scene: Scene, brushes: list, inv_mass: np.ndarray) -> Loads:
    """The scene's node loads: each load's force on its node of each listed bristle, with its
    amplitude profile. A load on a root node is refused (roots are clamped)."""
    load_nodes, load_of, lforce, lstart, ltimes, lvalues, lfreq, lphase = \
        [], [], [], [0], [], [], [], []
    brush_by_name = {b.name: i for i, b in enumerate(brushes)}
    for li, ldef in enumerate(scene.loads):
        info = brushes[brush_by_name[ldef.brush]]
        idx = range(info.n_bristles) if ldef.bristles == "all" else ldef.bristles
        node_in = ldef.node % info.n_nodes
        for b in idx:
            n_glob = info.first_node + b * info.n_nodes + node_in
            if inv_mass[n_glob] == 0:
                raise SceneError.single(f"loads.{li}.node", ldef.node,
                                        "a load on a root node does nothing: roots are clamped")
            load_nodes.append(n_glob)
            load_of.append(li)
        lforce.append(ldef.force)
        ltimes.extend(ldef.profile.times)
        lvalues.extend(ldef.profile.values)
        lstart.append(len(ltimes))
        lfreq.append(ldef.profile.frequency)
        lphase.append(ldef.profile.phase)
    NL = len(scene.loads)
    return Loads(node=np.asarray(load_nodes, np.int64), load=np.asarray(load_of, np.int64),
                 force=np.asarray(lforce, float).reshape(NL, 3),
                 start=np.asarray(lstart, np.int64), times=np.asarray(ltimes or [0.0], float),
                 values=np.asarray(lvalues or [0.0], float), frequency=np.asarray(lfreq, float),
                 phase=np.asarray(lphase, float), amp=np.zeros(NL))


def build_mission(scene: Scene, orbit_n: float, body_names: list[str],
                  shape_to_body: list) -> Mission:
    """The mission layer's arrays: orbit, controllers (engine.kernels.control), external loads."""
    from engine.kernels import control as C
    orbit = scene.environment.orbit
    orbit_arr = np.array([orbit_n, 1.0 if (orbit is not None and orbit.gravity_gradient)
                          else 0.0])
    nc = len(scene.controllers)
    ci = np.full((max(nc, 1), 2), -1, np.int64)
    cp = np.zeros((max(nc, 1), C.P_SIZE))
    cs = np.zeros((max(nc, 1), C.S_SIZE))
    for i, c in enumerate(scene.controllers):
        ci[i, 0] = body_names.index(c.body)
        ci[i, 1] = body_names.index(c.reference) if c.reference is not None else -1
        g, a = c.position_gains, c.attitude_gains
        cp[i, [C.P_KP, C.P_KD, C.P_KI]] = g.proportional, g.derivative, g.integral
        cp[i, [C.P_KPA, C.P_KDA, C.P_KIA]] = a.proportional, a.derivative, a.integral
        cp[i, C.P_INTERVAL] = c.sample_interval
        cp[i, C.P_MAXF:C.P_MAXF + 3] = c.max_force if c.max_force is not None else np.inf
        cp[i, C.P_MAXT:C.P_MAXT + 3] = c.max_torque if c.max_torque is not None else np.inf
        cp[i, C.P_DB_POS] = c.position_deadband
        cp[i, C.P_DB_ATT] = c.attitude_deadband
        cp[i, C.P_TARGET:C.P_TARGET + 3] = c.position
        cp[i, C.P_QTARGET:C.P_QTARGET + 4] = c.orientation
        cp[i, C.P_RELEASE_BELOW] = c.release_below if c.release_below is not None else 0.0
        cp[i, C.P_RELEASE_OFFSET:C.P_RELEASE_OFFSET + 3] = c.release_offset
        cp[i, C.P_RELEASE_FRACTION] = c.release_below_fraction or 0.0
        cp[i, C.P_ANTI_WINDUP] = 1.0 if c.anti_windup else 0.0
        cs[i, C.S_RELEASE_TIME] = -1.0   # not released (finite: results stay finite)
        # q_body = q_pose q_p (principal -> shape): the mesh axes are q_body q_p^-1
        cp[i, C.P_QBM:C.P_QBM + 4] = quat_conj(np.asarray(shape_to_body[ci[i, 0]], float))
    ext = np.zeros((len(scene.bodies), 6))
    for k, b in enumerate(scene.bodies):
        ext[k, :3] = b.external_force
        ext[k, 3:] = b.external_torque
    return Mission(orbit=orbit_arr, ctl_index=ci, ctl_par=cp, ctl_state=cs, external=ext)
