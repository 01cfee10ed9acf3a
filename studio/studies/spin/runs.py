"""The brush dynamic test of seed 4.3 (``brush-studio study spin``): its scenes, the analysis
of a run and the run's task (:func:`spin_task`; the study is :mod:`studio.studies.spin.study`).

A rigid foam cube (20, 40 or 60 mm) spins about a fixed horizontal axis (world y, through its
centre) with the external dissipation of seed eq. 4.6 and hits a fixed 17 x 5 silicone brush
whose bristles point at it (the presets ``spin_cube_20/40/60``; their descriptions give every
assumption). The brush takes six configurations (seed figs. 4.24-4.25, numbered as the
presets do):

====  ===========  =============  ==========================================
cfg   brush        level          horizontal position of the bristle tips
====  ===========  =============  ==========================================
1     horizontal   axis (z = 0)   P1: on the face plane, x = a/2
2     horizontal   axis (z = 0)   P2: halfway to the edge, x = a (1 + sqrt 2)/4
3     horizontal   top face       P1
4     horizontal   top face       P2
5     vertical     axis           P1
6     vertical     axis           P2
====  ===========  =============  ==========================================

("horizontal": the 17-bristle rows run along the axis, y; "vertical": along z.)

Per run: omega(t) of the cube; the contact intervals, detected from the magnitude of the
contact force on the cube (above a fraction of its largest value); the change of omega per
contact against the contact's duration (seed fig. 4.40); the time the cube comes to rest (|omega| below 5 % of
its initial spin from then on).
A further set of runs repeats one cube and configuration with random bristle tips (Gaussian,
variance 4e-10 m^2, several seeds) against the perfect brush (seed fig. 4.41).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Optional

import numpy as np

from studio.studies import api

CUBES_MM = (20, 40, 60)
CONFIGS = {  # config -> (brush orientation, level, horizontal position)
    1: ("horizontal", "axis", "P1"),
    2: ("horizontal", "axis", "P2"),
    3: ("horizontal", "top", "P1"),
    4: ("horizontal", "top", "P2"),
    5: ("vertical", "axis", "P1"),
    6: ("vertical", "axis", "P2"),
}
REST_FRACTION = 0.05       # the cube is at rest once |omega| stays below this fraction of
#                            its initial spin (it may still rock a little in the brush)
REST_HOLD = 0.3            # s: ... for at least this long (a run ends after that)
STOP_SPEED = 1e-5          # rad/s: the runs' stop condition (see spin_scene)
CONTACT_FRACTION = 0.02    # contact = |F| above this fraction of the run's largest |F|
SEED_TIP_VARIANCE = 4e-10  # m^2 (seed 4.3.5)
# the quaternion turning the brush's local +z (bristle direction) onto world -x, local x
# onto world +z (as in the presets)
Q_Z_TO_MINUS_X = [math.cos(-math.pi / 4), 0.0, math.sin(-math.pi / 4), 0.0]


def config_label(config: int) -> str:
    o, lvl, pos = CONFIGS[config]
    return f"{config}: {o}, {'axis level' if lvl == 'axis' else 'top-face level'}, {pos}"


# ----------------------------------------------------------------------------- scenes
def spin_scene(cube_mm: int, config: int, *, n_nodes: Optional[int] = None,
               omega0: Optional[float] = None, duration: Optional[float] = None,
               tip_variance: float = 0.0, seed: int = 0,
               grid: Optional[tuple[int, int]] = None,
               k1: Optional[float] = None, k2: Optional[float] = None,
               record_interval: Optional[float] = None) -> dict:
    """The scene (dict) of one cube size and brush configuration, from the preset
    ``spin_cube_<cube_mm>`` (configuration 1), moved to ``config``. Overrides: nodes per
    bristle, initial spin (rad/s), duration (s), tip randomness (variance m^2, seed), the
    grid ``(bristles along the long side, along the short side)`` (default 17 x 5), the
    hinge's k1 (1/s) and k2 (rad/s^2), the record interval."""
    from studio import presets

    if config not in CONFIGS:
        raise ValueError(f"config {config!r}: one of {sorted(CONFIGS)}")
    scene = json.loads(presets.load_preset(f"spin_cube_{int(cube_mm)}").to_json())
    cube = next(b for b in scene["bodies"] if b["name"] == "cube")
    a = float(cube["shape"]["size"][0])
    brush = scene["brushes"][0]
    orientation, level, position = CONFIGS[config]
    long_side, short_side = grid if grid else (max(brush["rows"], brush["columns"]),
                                               min(brush["rows"], brush["columns"]))
    # rows stack along base y = world y; a row (columns) runs along base x = world z
    if orientation == "horizontal":
        brush["rows"], brush["columns"] = long_side, short_side
    else:
        brush["rows"], brush["columns"] = short_side, long_side
    tips = a / 2 if position == "P1" else a * (1 + math.sqrt(2)) / 4
    x_base = tips + brush["bristle_length"] + brush["tip_radius"]
    z_base = 0.0 if level == "axis" else a / 2
    brush["base"] = {"position": [x_base, 0.0, z_base], "orientation": Q_Z_TO_MINUS_X}
    if n_nodes is not None:
        brush["n_nodes"] = int(n_nodes)
    brush["tip_variance"] = float(tip_variance)
    brush["seed"] = int(seed)
    if omega0 is not None:
        cube["angular_velocity"] = [0.0, float(omega0), 0.0]
    if k1 is not None:
        cube["motion"]["k1"] = float(k1)
    if k2 is not None:
        cube["motion"]["k2"] = float(k2)
    if duration is not None:
        scene["run"]["duration"] = float(duration)
    if record_interval is not None:
        scene["run"]["record_interval"] = float(record_interval)
    scene["run"]["channels"] = ["bodies", "contacts", "energy"]
    # The presets stop below 0.05 rad/s, but a cube pushed back by the brush passes through
    # zero speed at every turning point, and a record falling there ends the run while the
    # brush still drives it (seen: the 40 mm cube, configuration 1, stopped at 0.49 s in
    # contact). Here the engine stops only at exact rest (the hinge's k2 term, seed eq. 4.6,
    # sets omega to zero once nothing drives it); a cube caught and rocking in the brush is
    # stopped by the study's RestMonitor, and ``rest_time`` says when it stopped turning.
    scene["run"]["stop"] = {"quantity": "body_angular_speed", "body": "cube",
                            "value": STOP_SPEED, "min_time": 0.2}
    scene["name"] = f"spin_cube_{int(cube_mm)}_config_{config}"
    scene["description"] = (
        f"Study 'spin': the {cube_mm} mm cube with the brush in configuration "
        f"{config_label(config)} (tips at x = {tips * 1e3:.2f} mm, brush centre at z = "
        f"{z_base * 1e3:.1f} mm), {brush['rows']} x {brush['columns']} bristles, "
        f"{brush['n_nodes']} nodes each, tip variance {tip_variance:g} m^2 (seed {seed}). "
        f"Built from the preset spin_cube_{cube_mm}: " + scene["description"])
    return scene


# ----------------------------------------------------------------------------- analysis
def contact_intervals(time: np.ndarray, force: np.ndarray, omega: np.ndarray, *,
                      fraction: float = CONTACT_FRACTION, floor: float = 1e-9,
                      max_gap: int = 1) -> list[dict]:
    """Contacts of the cube with the brush from the magnitude of the contact force on it.

    A frame is "in contact" when |F| exceeds ``fraction`` of the run's largest |F| (and
    ``floor`` N); runs of such frames separated by at most ``max_gap`` quiet frames are one
    contact. For each: start and end time (first and last frame in contact), duration,
    omega just before (the frame before the start) and just after (the frame after the
    end), ``delta_omega = after - before``, and the peak force."""
    time = np.asarray(time, float)
    mag = np.asarray(force, float)
    if mag.ndim == 2:
        mag = np.linalg.norm(mag, axis=1)
    omega = np.asarray(omega, float)
    if not len(mag) or mag.max() <= floor:
        return []
    on = mag > max(fraction * float(mag.max()), floor)
    idx = np.flatnonzero(on)
    groups = []
    start = prev = int(idx[0])
    for i in idx[1:]:
        i = int(i)
        if i - prev > max_gap + 1:
            groups.append((start, prev))
            start = i
        prev = i
    groups.append((start, prev))
    out = []
    n = len(time)
    for s, e in groups:
        b, a = max(s - 1, 0), min(e + 1, n - 1)
        out.append({"t_start": float(time[s]), "t_end": float(time[e]),
                    # the frames in contact stand for their record intervals
                    "duration": float(time[e + 1] - time[s]) if e + 1 < n
                    else float(time[e] - time[s]),
                    "omega_before": float(omega[b]), "omega_after": float(omega[a]),
                    "delta_omega": float(omega[a] - omega[b]),
                    "peak_force": float(mag[s:e + 1].max())})
    return out


def turned_angle(time: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """The angle turned since the first frame (trapezoidal integral of omega), rad."""
    time = np.asarray(time, float)
    omega = np.asarray(omega, float)
    if len(time) < 2:
        return np.zeros(len(time))
    steps = np.diff(time) * 0.5 * (omega[1:] + omega[:-1])
    return np.concatenate([[0.0], np.cumsum(steps)])


def rest_time(time: np.ndarray, omega: np.ndarray, *, fraction: float = REST_FRACTION,
              hold: float = REST_HOLD, stopped: bool = False) -> Optional[float]:
    """When the cube came to rest (its spin-down time): the first frame from which |omega|
    stays below ``fraction`` of the initial |omega| until the end of the run, provided that
    lasts ``hold`` seconds. (Not "omega = 0": a cube caught by the brush keeps rocking in it
    while the bristles vibrate, and the undamped bristles take long to calm down; nor "no
    longer turning": a cube that cannot push a corner through the brush rocks fast in its
    well without turning.) A run ended by the scene's stop condition (``stopped``: omega
    exactly 0 under the hinge's friction) needs no hold. ``None`` when it still turns."""
    time = np.asarray(time, float)
    omega = np.abs(np.asarray(omega, float))
    if len(time) < 2:
        return None
    fast = np.flatnonzero(omega >= fraction * omega[0])
    first = int(fast[-1]) + 1 if fast.size else 0
    if first >= len(time):
        return None
    if not stopped and time[-1] - time[first] < hold - 1e-9:
        return None
    return float(time[first])


class RestMonitor:
    """``cancel`` callable for ``engine.run``: True once the run's own result file shows
    |omega| below ``REST_FRACTION`` of ``omega0`` for the last ``REST_HOLD`` seconds
    (checked at most every ``every_s`` wall seconds). So a study stops each run once the
    cube has spun down, instead of simulating a rocking cube to the end (the engine's stop
    conditions look at one instant only)."""

    def __init__(self, h5_path: Path, axis, omega0: float, body: str = "cube",
                 min_time: float = 0.2, every_s: float = 1.0):
        self.h5_path, self.body, self.min_time, self.every_s = Path(h5_path), body, min_time, every_s
        self.axis = np.asarray(axis, float) / np.linalg.norm(axis)
        self.limit = REST_FRACTION * abs(float(omega0))
        self.last = 0.0
        self.fired = False

    def __call__(self) -> bool:
        import time as _time

        import engine

        now = _time.monotonic()
        if self.fired or now - self.last < self.every_s:
            return self.fired
        self.last = now
        try:
            with engine.open_result(self.h5_path) as res:
                n = res.n_frames
                if n < 3:
                    return False
                t_end = float(res.frame("time", n - 1))
                if t_end < self.min_time + REST_HOLD:
                    return False
                dt = float(res.frame("time", n - 1) - res.frame("time", n - 2))
                k = min(n, int(math.ceil(REST_HOLD / max(dt, 1e-12))) + 2)
                frames = slice(n - k, n)
                t = np.asarray(res.series("time", frames))
                w = np.asarray(res.series(f"bodies/{self.body}/angular_velocity", frames))
        except Exception:  # not readable right now: look again later
            return False
        speed = np.abs(w @ self.axis)
        self.fired = bool(t[-1] - t[0] >= REST_HOLD and speed.max() < self.limit)
        return self.fired


def read_spin(h5_path: Path, body: str = "cube") -> dict:
    """omega(t) about the hinge axis, the contact force and torque on the cube, and the
    cube's hinge data, from a run's result file."""
    import engine

    with engine.open_result(h5_path) as res:
        scene = res.scene
        spec = next(b for b in scene.bodies if b.name == body)
        axis = np.asarray(spec.motion.axis, float)
        axis /= np.linalg.norm(axis)
        time = np.asarray(res.time)
        w = np.asarray(res.series(f"bodies/{body}/angular_velocity"))
        f = np.asarray(res.series(f"bodies/{body}/contact_force"))
        tq = np.asarray(res.series(f"bodies/{body}/contact_torque"))
        status = res.status
    return {"time": time, "omega": w @ axis, "force": f, "torque_axis": tq @ axis,
            "status": status, "k2": float(spec.motion.k2)}


def analyse(data: dict) -> dict:
    """Contacts, rest time and what they say, from :func:`read_spin`'s dict."""
    t, om = data["time"], data["omega"]
    contacts = contact_intervals(t, data["force"], om)
    rest = rest_time(t, om, stopped=data["status"] == "stopped")
    deltas = [c["delta_omega"] for c in contacts]
    return {"omega0": float(om[0]) if len(om) else None,
            "omega_end": float(om[-1]) if len(om) else None,
            "rest_time": rest, "at_rest": rest is not None,
            "n_contacts": len(contacts), "contacts": contacts,
            "delta_omega_spread": float(np.ptp(deltas)) if len(deltas) > 1 else 0.0,
            "end_time": float(t[-1]) if len(t) else 0.0,
            # the last frame still pressed by the brush (the stop caught a turning point)?
            "last_contact_torque": float(data["torque_axis"][-1]) if len(t) else 0.0}


# ----------------------------------------------------------------------------- task
def spin_task(scene, h5_path: Path, params: dict) -> dict:
    """Dask task: run one spin scene until the cube rests (or ``run.duration``), then its
    contacts and rest time (JSON-able). A run ended by :class:`RestMonitor` is closed by
    the engine as ``cancelled``; this task reports it as ``stopped`` (``stopped_by``
    says why)."""
    import engine

    system = engine.build(scene)
    cube = next(b for b in scene.bodies if b.name == "cube")
    axis = np.asarray(cube.motion.axis, float)
    monitor = RestMonitor(h5_path, axis, float(np.dot(cube.angular_velocity, axis)
                                               / np.linalg.norm(axis)))
    result = engine.run(system, output=h5_path,
                        cancel=lambda: monitor() or api.cancel_requested())
    api.check_cancel()  # a cancel of the study running this in-process
    data = read_spin(h5_path)
    status, stopped_by = result.status, None
    if result.status == "stopped":
        stopped_by = f"the scene's stop condition (|omega| < {STOP_SPEED:g} rad/s)"
    elif result.status == "cancelled" and monitor.fired:
        status = "stopped"
        stopped_by = (f"the study: |omega| below {REST_FRACTION:g} of its initial value "
                      f"for {REST_HOLD:g} s")
    data["status"] = status
    out = analyse(data)
    out.update(status=status, stopped_by=stopped_by, dt=system.dt,
               wall_s=result.summary.get("wall_s"), steps=result.summary.get("steps"),
               n_nodes=system.n_nodes)
    return out
