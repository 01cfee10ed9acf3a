"""One shot of ``study trap`` on a worker: run the scene, then the figures of the shot.

Figures (SI): the depth reached (how far the bead's centre went below the tip plane, its
largest value); whether it is ``arrested`` (its speed at the end below ``ARREST_FRACTION`` of
the impact speed) and the time to arrest (from the first contact to the first frame after
which it stays so); whether it touches the brush at the end; and how the shot ended:

* ``trapped``: at the end its centre lies inside the brush's envelope (below the tip plane
  plus its radius, above the roots' plane, within the footprint) and it touches the brush
  (held: adhered, or wedged) or is arrested;
* ``loose``: inside the envelope, neither touching nor arrested (in flight between bristles
  at the end: not counted as trapped);
* ``rebounded`` (out through the tip plane; the rebound speed is its speed at the end),
  ``passed`` (through the roots' plane: a backing plate would take the hit) or ``escaped``
  (out of the footprint's side).

Why not a speed threshold alone: a bead held on a bristle swings with it (the seed's 33 mm
silicone bristle's first mode is about 8 Hz), at speeds that can exceed a few % of a slow
impact. The run lasts 2.5 crossings of the brush at the impact speed.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

#: arrested: at the end the bead moves slower than this fraction of its impact speed
ARREST_FRACTION = 0.05


def analyse(t, pos, vel, force, *, radius, tip_z, root_z, half_width) -> dict:
    """The figures of one shot from its recorded series: ``pos``/``vel`` the bead's centre
    and velocity (F, 3), ``force`` its contact force (F, 3); ``tip_z``, ``root_z`` the tip
    and roots' planes, ``half_width`` the brush footprint's half width (centred on x = y =
    0)."""
    speed = np.linalg.norm(vel, axis=1)
    v0 = float(speed[0])
    slow = speed < ARREST_FRACTION * v0
    end = pos[-1]
    inside_z = root_z < end[2] < tip_z + radius
    inside_xy = bool(np.all(np.abs(end[:2]) <= half_width + radius))
    touching = np.linalg.norm(force, axis=1) > 0.0
    first = np.nonzero(touching)[0]
    t_contact = float(t[first[0]]) if len(first) else None
    # the first frame from which the bead stays slow
    t_arrest = None
    if slow[-1]:
        fast = np.nonzero(~slow)[0]
        k = int(fast[-1]) + 1 if len(fast) else 0
        if t_contact is not None:
            t_arrest = float(t[k] - t_contact)
    if inside_z and inside_xy:
        outcome = "trapped" if (touching[-1] or slow[-1]) else "loose"
    elif end[2] <= root_z:
        outcome = "passed"
    elif not inside_xy:
        outcome = "escaped"
    else:
        outcome = "rebounded"
    return {
        "impact_speed": v0,
        "trapped": outcome == "trapped",
        "outcome": outcome,
        "depth": max(0.0, float(tip_z - pos[:, 2].min())),
        "arrested": bool(slow[-1]),
        "time_to_arrest": t_arrest,
        "first_contact": t_contact,
        "rebound_speed": float(speed[-1]) if outcome == "rebounded" else 0.0,
        "end_speed": float(speed[-1]),
        "touching_at_end": bool(touching[-1]),
    }


def trap_task(scene, h5_path: Path, params: dict) -> dict:
    """Dask task (``studio.studies.runner``): one bead fired into the brush."""
    import engine

    from ..runner import run_counting_momentum

    system, result, _, _ = run_counting_momentum(scene, h5_path)
    bead = next(b for b in scene.bodies if b.name == "bead")
    with engine.open_result(h5_path) as res:
        t = res.time
        pos = res.series("bodies/bead/position")
        vel = res.series("bodies/bead/velocity")
        force = res.series("bodies/bead/contact_force")
    out = analyse(t, pos, vel, force, radius=float(bead.shape.radius),
                  tip_z=float(params["tip_z"]), root_z=float(params["root_z"]),
                  half_width=float(params["half_width"]))
    out.update(status=result.status, dt=system.dt, steps=result.summary.get("steps"),
               wall_s=result.summary.get("wall_s"), n_nodes=system.n_nodes)
    return out
