"""What a detumble run did, from its result file (``brush-studio study detumble``).

Every quantity comes from the recorded channels (docs/results.md) and the run's own scene:

* the target's angular velocity ``w`` (relative to the world frame: the Hill frame with an
  orbit) and its angular momentum ``L = R I_p R^T (w + Omega)`` (inertial, world components;
  ``engine.io.results`` computes it), ``|w|(t)``;
* the time to detumble: the first frame from which ``|w|`` stays below ``threshold`` times its
  initial value to the end of the run (``None`` if it does not);
* peak loads: on the target its recorded ``contact_force`` / ``contact_torque`` (about its
  centre of mass; with the gravity-gradient torque, which is orders smaller); on the chaser
  the brushes' load, ``-root_force`` summed over the brushes mounted on it and the largest
  ``-root_torque`` (each about its own brush base);
* the chaser's Delta-v (integral of |F|/m of its thrusters), angular impulse and attitude
  error, from the controller's channels;
* the peak bending stress of the bristles, ``sigma = M r / I = 4 M / (pi r^3)`` (a solid
  circular section, ``r`` the bond's mean radius) from ``bonds/bending_moment``, against the
  bristle material's stress limit.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import numpy as np

from .chaser_loads import brush_load_on_body, peak_magnitude, wheel_momentum

TARGET = "target"
CHASER = "chaser"
CONTROLLER = "chaser_control"
#: s: the chaser thrusters' specific impulse unless told (a hydrazine monopropellant class)
DEFAULT_ISP = 220.0


def detumble_time(time: np.ndarray, speed: np.ndarray, threshold: float) -> Optional[float]:
    """The first time from which ``speed`` stays below ``threshold * speed[0]`` until the
    end; ``None`` if the last frame is not below it."""
    time = np.asarray(time, float)
    speed = np.asarray(speed, float)
    if len(time) == 0:
        return None
    above = np.flatnonzero(speed >= threshold * speed[0])
    first = int(above[-1]) + 1 if above.size else 0
    return float(time[first]) if first < len(time) else None


def bending_stress(moment: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Outer-fibre bending stress of a solid circular section, Pa: 4 M / (pi r^3)."""
    return 4.0 * np.asarray(moment, float) / (math.pi * np.asarray(radius, float) ** 3)


def peak_bending_stress(res) -> np.ndarray:
    """Per frame, the largest bending stress over the bonds, Pa, from an open result file
    (channel groups ``bending`` and ``nodes``: the moments and the node radii); NaN per frame
    without them. A bond's radius is the mean of its two nodes' (its midpoint's, where the
    moment is taken)."""
    if "bonds/bending_moment" not in res.channels() or "nodes/radius" not in res.statics():
        return np.full(res.n_frames, np.nan)
    bonds = np.asarray(res.static("bonds/nodes"))
    radius = np.asarray(res.static("nodes/radius"))
    r_bond = 0.5 * (radius[bonds[:, 0]] + radius[bonds[:, 1]])
    moment = np.asarray(res.series("bonds/bending_moment"), float)
    return bending_stress(moment, r_bond[None, :]).max(axis=1)


def bristle_bending_stress(res) -> np.ndarray | None:
    """(frames, bristles): per frame, each bristle's largest bending stress over its bonds,
    Pa (the fatigue history, :mod:`studio.studies.fatigue`); None without the channels."""
    from .fatigue import bond_bristles, bristle_series

    if "bonds/bending_moment" not in res.channels() or "nodes/radius" not in res.statics():
        return None
    bonds = np.asarray(res.static("bonds/nodes"))
    radius = np.asarray(res.static("nodes/radius"))
    first = np.asarray(res.static("bristles/first_node"))[:-1]  # (n_bristles + 1,): offsets
    r_bond = 0.5 * (radius[bonds[:, 0]] + radius[bonds[:, 1]])
    stress = bending_stress(np.asarray(res.series("bonds/bending_moment"), float),
                            r_bond[None, :])
    return bristle_series(stress, bond_bristles(bonds[:, 0], first), len(first))


def read_detumble(h5_path: Path) -> dict:
    """The series of a detumble run (time, target w and L, loads, controller channels,
    bending stress) as arrays, and the scene facts they need."""
    import engine

    with engine.open_result(h5_path) as res:
        scene = res.scene
        t = np.asarray(res.time)
        d = {"time": t, "status": res.status}
        body = f"bodies/{TARGET}"
        d["omega"] = np.asarray(res.series(f"{body}/angular_velocity"))
        d["target_force"] = np.asarray(res.series(f"{body}/contact_force"))
        d["target_torque"] = np.asarray(res.series(f"{body}/contact_torque"))
        d["angular_momentum"] = np.asarray(res.body_angular_momentum(TARGET))
        mounted = [b for b in scene.brushes if b.mount == CHASER]
        d["chaser_mass"] = float(res.static(f"bodies/{CHASER}/mass"))
        for who in (TARGET, CHASER):
            d[f"{who}_position"] = np.asarray(res.series(f"bodies/{who}/position"))
            d[f"{who}_velocity"] = np.asarray(res.series(f"bodies/{who}/velocity"))
        if mounted:
            # the brushes' load on the chaser: their forces add; about the chaser's centre
            # of mass their torques add too (issue 25 item 6)
            d["chaser_force"], torque_com = brush_load_on_body(res, CHASER)
            if torque_com is not None:
                d["chaser_torque_com"] = torque_com
            torques = [np.asarray(res.series(f"brushes/{b.name}/root_torque"))
                       for b in mounted]
            d["chaser_torque"] = np.stack(torques)[
                np.argmax(np.stack([np.linalg.norm(t, axis=1) for t in torques]), axis=0),
                np.arange(len(t))]
        else:
            # a reduced brush (a patch on the chaser, issue 25 item 4): the chaser's own
            # recorded contact force and torque (about its centre of mass) are its load
            d["chaser_force"] = np.asarray(res.series(f"bodies/{CHASER}/contact_force"))
            d["chaser_torque"] = np.asarray(res.series(f"bodies/{CHASER}/contact_torque"))
            d["chaser_torque_com"] = d["chaser_torque"]
        ctl = f"controllers/{CONTROLLER}"
        for key in ("delta_v", "angular_impulse_total", "attitude_error", "position_error",
                    "applied_force"):
            d[key] = np.asarray(res.series(f"{ctl}/{key}"))
        for key in ("samples", "saturated_force_samples", "saturated_torque_samples",
                    "angular_impulse", "released", "release_time"):
            if f"{ctl}/{key}" in res.channels():   # results written before issue 25 lack them
                d[key] = np.asarray(res.series(f"{ctl}/{key}"))
        c = next(c for c in scene.controllers if c.name == CONTROLLER)
        d["hold_offset"] = np.asarray(c.position, float)
        d["n_contacts"] = np.asarray(res.series(
            "contacts/bristle_body" if mounted else "contacts/body_body"))
        d["peak_stress"] = peak_bending_stress(res)
        d["bristle_stress"] = bristle_bending_stress(res)
        d["material"] = mounted[0].material if mounted else "(reduced brush)"
        orbit = scene.environment.orbit
        d["mean_motion"] = orbit.n if orbit is not None else 0.0
    return d


def analyse(d: dict, threshold: float, stress_limit: float, *, isp: float = DEFAULT_ISP,
            drift_time: float = 3600.0, sn_curve: str | None = None) -> dict:
    """The run's summary (JSON-able) from :func:`read_detumble`'s arrays; with the bristles'
    stress histories, their fatigue figures (``sn_curve``: the S–N points,
    :func:`studio.studies.fatigue.parse_sn_curve`)."""
    t = d["time"]
    speed = np.linalg.norm(d["omega"], axis=1)
    L = np.linalg.norm(d["angular_momentum"], axis=1)
    t_d = detumble_time(t, speed, threshold)
    peak = lambda a: float(np.linalg.norm(a, axis=1).max()) if len(a) else 0.0  # noqa: E731
    att = np.linalg.norm(d["attitude_error"], axis=1)
    in_contact = d["n_contacts"] > 0
    first_contact = float(t[np.argmax(in_contact)]) if in_contact.any() else None
    stress = float(np.nanmax(d["peak_stress"])) if np.isfinite(d["peak_stress"]).any() \
        else None
    out = {
        "omega0": float(speed[0]) if len(t) else None,
        "omega_end": float(speed[-1]) if len(t) else None,
        "angular_momentum0": float(L[0]) if len(t) else None,
        "angular_momentum_end": float(L[-1]) if len(t) else None,
        "threshold": threshold, "detumble_time": t_d, "detumbled": t_d is not None,
        "first_contact": first_contact, "end_time": float(t[-1]) if len(t) else 0.0,
        "peak_target_force": peak(d["target_force"]),
        "peak_target_torque": peak(d["target_torque"]),
        "peak_chaser_force": peak(d["chaser_force"]),
        "peak_chaser_torque": peak(d["chaser_torque"]),
        "delta_v": float(d["delta_v"][-1]) if len(t) else 0.0,
        "angular_impulse": float(d["angular_impulse_total"][-1]) if len(t) else 0.0,
        "peak_attitude_error": float(att.max()) if len(t) else 0.0,
        "peak_thrust": float(np.abs(d["applied_force"]).max()) if len(t) else 0.0,
        "peak_bending_stress": stress, "stress_limit": stress_limit,
        "stress_ratio": (stress / stress_limit) if stress is not None else None,
        "material": d["material"]}
    out.update(controller_honesty(d))
    out.update(designer_figures(d, isp=isp, drift_time=drift_time))
    out.update(fatigue_figures(d, sn_curve))
    return out


def fatigue_figures(d: dict, sn_curve: str | None = None) -> dict:
    """The run's fatigue figures (the worst bristle's cycles, amplitude, Miner damage and
    runs to failure: :func:`studio.studies.fatigue.fatigue`); the per-bristle lists stay
    in ``d["fatigue"]`` for the per-bristle table."""
    from .fatigue import fatigue, parse_sn_curve

    keys = ("fatigue_cycles_max", "fatigue_amplitude_max", "fatigue_damage_max",
            "runs_to_failure", "sn_extrapolated")
    if d.get("bristle_stress") is None:
        return dict.fromkeys(keys)
    f = fatigue(d["bristle_stress"], parse_sn_curve(sn_curve) if sn_curve else None)
    d["fatigue"] = f
    return {k: f[k] for k in keys}


def controller_honesty(d: dict) -> dict:
    """What the controller really did (issue 25 item 5): per body axis the fraction of its
    samples at which the thrust and the torque command were clipped; the time in contact
    (frames with a bristle-body contact, times the frame interval); the hold shortfall: how
    far the chaser sat outside its commanded hold point along the approach axis (the held
    offset's direction), median over the frames in contact, so the interference reached is
    the commanded one minus it."""
    t = d["time"]
    out = {"thrust_saturation": None, "torque_saturation": None}
    if "samples" in d and len(t) and d["samples"][-1] > 0:
        n = float(d["samples"][-1])
        out["thrust_saturation"] = [float(v) / n for v in d["saturated_force_samples"][-1]]
        out["torque_saturation"] = [float(v) / n for v in d["saturated_torque_samples"][-1]]
    in_contact = d["n_contacts"] > 0
    dt_frame = np.diff(t, append=t[-1]) if len(t) else t
    out["time_in_contact"] = float(np.sum(dt_frame[in_contact])) if len(t) else 0.0
    axis = d["hold_offset"] / max(float(np.linalg.norm(d["hold_offset"])), 1e-300)
    # position_error = hold point - chaser (relative to the target): -e.axis is how far the
    # chaser sits outside the hold point
    shortfall = -(d["position_error"] @ axis)
    out["hold_shortfall_in_contact"] = (float(np.median(shortfall[in_contact]))
                                        if in_contact.any() else None)
    return out


G0 = 9.80665  # m/s^2, standard gravity (the definition of Isp in seconds)


def propellant_mass(mass: float, delta_v: float, isp: float) -> float:
    """Propellant (kg) a chaser of wet mass ``mass`` burns for ``delta_v`` at specific
    impulse ``isp`` (s): the rocket equation, m (1 - exp(-dv / (Isp g0)))."""
    return mass * (1.0 - math.exp(-delta_v / (isp * G0)))


def designer_figures(d: dict, *, isp: float = DEFAULT_ISP, drift_time: float = 3600.0) -> dict:
    """The mission designer's figures of a run (issue 25 item 6):

    * ``peak_chaser_torque_com`` / ``sliding_chaser_torque_com``: the brush's moment on the
      chaser about its centre of mass (what its attitude control must hold), peak and median
      over the frames in contact (``None`` for results without the ``mount_torque`` channel);
    * ``delta_v_gimballed`` (integral of |F|/m, the controller's channel) and
      ``delta_v_per_axis`` (integral of |Fx|+|Fy|+|Fz| over m, body-axis thrusters, from the
      recorded applied force by the trapezoid rule over frames) and the propellant mass of
      each at ``isp`` (s);
    * ``wheel_momentum``: the largest |angular impulse| of the controller's torque over the
      run (N m s), the momentum its wheels store if they provide it;
    * the debris (target) at the end of the run (after a release if there was one): its
      speed in the Hill frame ``debris_speed`` (what the pushing gave it), its velocity
      relative to the chaser ``debris_dv``, and its free Clohessy-Wiltshire drift
      over ``drift_time`` from its last recorded state with the chaser held (station
      keeping) at its last position: ``min_separation`` (centre-to-centre, m) and when.
    """
    t = d["time"]
    out = {}
    in_contact = d["n_contacts"] > 0
    if "chaser_torque_com" in d and len(t):
        tq = np.linalg.norm(d["chaser_torque_com"], axis=1)
        out["peak_chaser_torque_com"] = peak_magnitude(d["chaser_torque_com"])
        out["sliding_chaser_torque_com"] = (float(np.median(tq[in_contact]))
                                            if in_contact.any() else 0.0)
    else:
        out["peak_chaser_torque_com"] = out["sliding_chaser_torque_com"] = None
    m = d["chaser_mass"]
    dv_g = float(d["delta_v"][-1]) if len(t) else 0.0
    thrust = np.sum(np.abs(d["applied_force"]), axis=1)
    dv_a = float(np.trapezoid(thrust, t) / m) if len(t) > 1 else 0.0
    out.update(delta_v_gimballed=dv_g, delta_v_per_axis=dv_a, isp=isp,
               propellant_gimballed=propellant_mass(m, dv_g, isp),
               propellant_per_axis=propellant_mass(m, dv_a, isp))
    out["wheel_momentum"] = (wheel_momentum(d["angular_impulse"])
                             if "angular_impulse" in d and len(t) else None)
    if len(t):
        rel = d[f"{TARGET}_velocity"][-1] - d[f"{CHASER}_velocity"][-1]
        out["debris_dv"] = float(np.linalg.norm(rel))
        out["debris_speed"] = float(np.linalg.norm(d[f"{TARGET}_velocity"][-1]))
        dist, when = cw_min_separation(d["mean_motion"], d[f"{TARGET}_position"][-1],
                                       d[f"{TARGET}_velocity"][-1],
                                       d[f"{CHASER}_position"][-1], drift_time)
        out.update(drift_time=drift_time, min_separation=dist, min_separation_after=when)
    return out


def cw_drift(n: float, pos, vel, times) -> np.ndarray:
    """Positions (len(times), 3) of a free point in the Hill frame after each time, from
    ``pos``, ``vel``: the closed-form Clohessy-Wiltshire solution (straight line if n = 0)."""
    pos = np.asarray(pos, float)
    vel = np.asarray(vel, float)
    times = np.asarray(times, float)
    if n == 0.0:
        return pos + times[:, None] * vel
    from engine.kernels.orbit import cw_flow

    state = np.concatenate([pos, vel])
    return np.array([cw_flow(n, float(tau), state)[:3] for tau in times])


def cw_min_separation(n, pos, vel, held, drift_time, samples: int = 2000):
    """Smallest distance (m) between a point drifting freely (CW) from ``pos``, ``vel`` and a
    point held at ``held``, over ``drift_time`` s (sampled ``samples`` times), and when."""
    times = np.linspace(0.0, drift_time, samples + 1)
    dist = np.linalg.norm(cw_drift(n, pos, vel, times) - np.asarray(held, float), axis=1)
    i = int(np.argmin(dist))
    return float(dist[i]), float(times[i])


def plot_omega(path: Path, runs: list[tuple[str, dict]], threshold: float) -> None:
    """|w|(t) of the target of every run (one line each) into ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.5))
    for label, d in runs:
        speed = np.degrees(np.linalg.norm(d["omega"], axis=1))
        line, = ax.plot(d["time"], speed, lw=1, label=label)
        if len(speed):  # each run's own threshold: a fraction of its own initial spin
            ax.axhline(threshold * speed[0], color=line.get_color(), ls=":", lw=0.8)
    if runs:
        ax.plot([], [], color="k", ls=":", lw=0.8,
                label=f"threshold ({threshold:g} x the run's initial |ω|, its colour)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("target |ω| [deg/s]")
    ax.set_title("Detumble: the target's angular speed (relative to the Hill frame)",
                 fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
