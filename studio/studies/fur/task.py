"""One impact of ``study fur`` on a worker: run the scene, then the figures of the impact.

The transmitted force is what reaches the plate (seed fig. 5.1): the plate's contact force
(projectile or wires touching it) minus the force the fur's base exerts on the roots (the
roots push the plate with its opposite). Its impulse is checked against the momentum the
moving parts lost: J_plate = -(P_end - P_0) of the sphere and the fur together, a
conservation law the recorded, sampled force must satisfy (``momentum_residual``); once the
fur has come to rest it is the projectile's momentum change alone
(``projectile_momentum_residual``: the fur's own momentum at the end is its difference).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np



def _trapezoid(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    if len(t) < 2:
        return np.zeros(f.shape[1:])
    return (0.5 * (f[1:] + f[:-1]) * np.diff(t)[:, None]).sum(axis=0)


def peak_wire_strain(positions: np.ndarray, radius: np.ndarray, n_nodes: int,
                     segment_length: float) -> float:
    """Largest bending strain r kappa of any wire at any frame, from the recorded node
    positions (F, n_bristles * n_nodes, 3): the discrete curvature at an interior node is
    the angle between its two segments over the rest segment length; ``radius`` the node
    radii (N,). Equal-length bristles, nodes root first (the fur's layout)."""
    if n_nodes < 3 or positions.size == 0:
        return 0.0
    F = positions.shape[0]
    p = positions.reshape(F, -1, n_nodes, 3)
    seg = np.diff(p, axis=2)
    seg /= np.linalg.norm(seg, axis=3, keepdims=True)
    cos = np.clip(np.einsum("fbsi,fbsi->fbs", seg[:, :, 1:], seg[:, :, :-1]), -1.0, 1.0)
    kappa = np.arccos(cos) / segment_length                  # (F, nb, n_nodes - 2)
    r = radius.reshape(-1, n_nodes)[:, 1:-1]
    return float((kappa * r[None]).max())


def analyse(t, f_plate, root, sphere_pos, sphere_vel, *, mass, radius, top, floor,
            p_start, p_end) -> dict:
    """The figures of one impact from its recorded series (SI): ``f_plate`` the plate's
    contact force, ``root`` the brush's root force (zeros without fur), ``top`` the height
    the projectile's penetration is measured from (fur tips or the plate), ``floor`` the
    height below which it has bottomed out (the fur's roots), ``p_start``/``p_end`` the total
    linear momentum of the moving parts before and after."""
    f = f_plate - root                              # force transmitted to the plate
    mag = np.linalg.norm(f, axis=1)
    peak = float(mag.max()) if len(mag) else 0.0
    impulse = _trapezoid(t, f)
    dp = p_end - p_start
    # conservation: the plate took what the moving parts lost
    residual = float(np.linalg.norm(impulse + dp) / max(np.linalg.norm(dp), 1e-300))
    dp_projectile = mass * (sphere_vel[-1] - sphere_vel[0])
    residual_projectile = float(np.linalg.norm(impulse + dp_projectile)
                                / max(np.linalg.norm(dp_projectile), 1e-300))
    v0 = sphere_vel[0]
    u = v0 / np.linalg.norm(v0)                     # incoming direction
    along = sphere_vel @ u
    touched = np.nonzero(mag > 1e-3 * peak)[0] if peak > 0 else np.array([], int)
    t_contact = float(t[touched[0]]) if len(touched) else None
    stopped = np.nonzero(along <= 0.0)[0]
    t_arrest = (float(t[stopped[0]] - t_contact)
                if len(stopped) and t_contact is not None else None)
    lowest = float((sphere_pos[:, 2] - radius).min())
    return {
        "peak_force": peak,
        "impulse": [float(x) for x in impulse],
        "impulse_magnitude": float(np.linalg.norm(impulse)),
        "momentum_change": [float(x) for x in dp],
        "momentum_residual": residual,
        "projectile_momentum_residual": residual_projectile,
        "time_to_arrest": t_arrest,
        "first_contact": t_contact,
        "penetration": max(0.0, top - lowest),
        "bottomed_out": bool(lowest <= floor),
        "rebound_speed": float(np.linalg.norm(sphere_vel[-1])),
        "incoming_speed": float(np.linalg.norm(v0)),
        "projectile_mass": mass,
    }


def fur_task(scene, h5_path: Path, params: dict) -> dict:
    """Dask task (``studio.studies.runner``): one impact, with fur or on the bare plate."""
    import engine

    from ..runner import run_counting_momentum

    system, result, p_start, p_end = run_counting_momentum(scene, h5_path)
    sphere = next(b for b in scene.bodies if b.name == "sphere")
    with engine.open_result(h5_path) as res:
        t = res.time
        f_plate = res.series("bodies/plate/contact_force")
        root = (res.series(f"brushes/{scene.brushes[0].name}/root_force") if scene.brushes
                else np.zeros_like(f_plate))
        pos = res.series("bodies/sphere/position")
        vel = res.series("bodies/sphere/velocity")
    out = analyse(t, f_plate, root, pos, vel, mass=float(sphere.mass_properties.mass),
                  radius=float(sphere.shape.radius), top=float(params["top"]),
                  floor=float(params["floor"]), p_start=p_start, p_end=p_end)
    if scene.brushes:
        b = scene.brushes[0]
        with engine.open_result(h5_path) as res:
            strain = peak_wire_strain(res.series("nodes/positions"), res.static("nodes/radius"),
                                      b.n_nodes, b.bristle_length / (b.n_nodes - 1))
        out["peak_wire_strain"] = strain
        E = scene.materials[b.material].youngs_modulus
        yield_strength = params.get("yield_strength")
        out["wire_yields"] = (bool(E * strain > yield_strength) if yield_strength else None)
    out.update(status=result.status, dt=system.dt, steps=result.summary.get("steps"),
               wall_s=result.summary.get("wall_s"), n_nodes=system.n_nodes)
    return out
