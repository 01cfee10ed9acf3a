"""One docking of ``study docking`` on a worker: run the scene, then its figures.

Figures: the peak contact force and torque (about its centre of mass) on the target; the
relative speed along the approach axis at the end (positive: the craft separate; the
rebound ratio is it over the closing speed) and whether they are still in contact there
(a soft capture when their relative speed is also below ``capture_fraction`` of the closing
speed); the closest gap between the chaser's docking face and the target's hull (its
vertices); the total linear momentum before and after (it must not change: no external
force acts).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


#: a docking ends in soft capture when, at the end, the craft still touch and their relative
#: speed is below this fraction of the closing speed
CAPTURE_FRACTION = 0.1


def hull_gap(face_x: float, chaser_pos, chaser_q, target_pos, target_q, vertices) -> np.ndarray:
    """Per frame, the distance from the chaser's docking face (its body-frame plane
    x = ``face_x``) to the target's nearest vertex, along the face's normal: negative once a
    vertex is behind the face (the hulls meet)."""
    from engine.model.layout import quat_to_matrix

    Rc = quat_to_matrix(chaser_q)                       # (F, 3, 3)
    Rt = quat_to_matrix(target_q)
    world = target_pos[:, None, :] + np.einsum("fij,vj->fvi", Rt, vertices)
    local = np.einsum("fji,fvj->fvi", Rc, world - chaser_pos[:, None, :])   # Rc^T (w - c)
    return local[:, :, 0].min(axis=1) - face_x


def analyse(t, chaser_vel, target_vel, force, torque, gap, touching, *, p_start,
            p_end) -> dict:
    v_rel = target_vel[:, 0] - chaser_vel[:, 0]        # + separating, - closing
    closing = float(-v_rel[0])
    end_speed = float(v_rel[-1])
    in_contact = bool(touching[-1])
    peak_f = np.linalg.norm(force, axis=1)
    peak_t = np.linalg.norm(torque, axis=1)
    first = np.nonzero(touching)[0]
    return {
        "closing_speed": closing,
        "separation_speed": end_speed,
        "rebound_ratio": end_speed / closing if closing > 0 else float("nan"),
        "in_contact_at_end": in_contact,
        "soft_capture": bool(in_contact and abs(end_speed) < CAPTURE_FRACTION * closing),
        "peak_force": float(peak_f.max()),
        "peak_torque": float(peak_t.max()),
        "first_contact": float(t[first[0]]) if len(first) else None,
        "contact_time": float(np.count_nonzero(touching) * (t[1] - t[0])) if len(t) > 1 else 0.0,
        "min_hull_gap": float(gap.min()),
        "hulls_met": bool(gap.min() <= 0.0),
        "momentum_change": float(np.linalg.norm(p_end - p_start)
                                 / max(np.linalg.norm(p_start), 1e-300)),
    }


def docking_task(scene, h5_path: Path, params: dict) -> dict:
    """Dask task (``studio.studies.runner``): one docking, with or without the brush."""
    import engine

    from ..runner import run_counting_momentum

    system, result, p_start, p_end = run_counting_momentum(scene, h5_path)
    chaser = next(b for b in scene.bodies if b.name == "chaser")
    face_x = float(chaser.shape.size[0]) / 2
    with engine.open_result(h5_path) as res:
        t = res.time
        cv = res.series("bodies/chaser/velocity")
        tv = res.series("bodies/target/velocity")
        force = res.series("bodies/target/contact_force")
        torque = res.series("bodies/target/contact_torque")
        gap = hull_gap(face_x, res.series("bodies/chaser/position"),
                       res.series("bodies/chaser/orientation"),
                       res.series("bodies/target/position"),
                       res.series("bodies/target/orientation"),
                       res.static("bodies/target/vertices"))
        w_end = res.series("bodies/target/angular_velocity")[-1]
    touching = np.linalg.norm(force, axis=1) > 0.0
    out = analyse(t, cv, tv, force, torque, gap, touching, p_start=p_start, p_end=p_end)
    out["target_spin_end"] = float(np.linalg.norm(w_end))
    out.update(status=result.status, dt=system.dt, steps=result.summary.get("steps"),
               wall_s=result.summary.get("wall_s"), n_nodes=system.n_nodes)
    return out
