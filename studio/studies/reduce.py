"""``brush-studio study reduce``: fit the reduced brush law (engine.model.reduced_law) to short DEM
runs of a brush design against a flat target surface, and validate it on held-out DEM runs
(issue 25 items 1 and 3).

The brush is a preset's first brush (default the detumble presets' brush), its base fixed in
the world with the bristles along +z; the target is a plate of the preset's target material
(the contact pair between it and the bristles is the preset's) whose lower face starts
``GAP`` above the undeformed tips. Runs (each one Dask task, short):

* presses (fit): the plate, moved kinematically, goes down at a constant ``rate`` to a
  ``depth`` of interference and back up: (d, dd, F_n) samples of both branches;
* slides (fit): pressed to a ``depth`` slowly, the plate slides along x at a constant
  ``speed``: (F_n, v, F_t) samples of the steady slide;
* impacts (held out, never fitted): a free plate hits the brush off-centre at a normal speed,
  some with a tangential speed or a spin about the normal.

The normal law is fitted on the presses, the tangential law on the slides
(``studio.studies.reduce_fit``: scipy least squares, 95 % intervals). Each impact is then
replayed with the fitted law by a rigid-body integration of the plate (scipy ``solve_ivp``:
force at the patch centre, friction against the slip of the plate's point there, torsion
against its spin; the plate's tilt during the short contact is neglected) and compared with
its DEM run: peak normal force, normal Delta-v, Delta-omega, dissipated energy, the force
history's RMS error. Outputs (``-o DIR``): ``law.json`` (the law file a scene references),
``validation.json`` (per impact: DEM, reduced, relative errors), ``reduce_summary.json``,
``outcomes.json``, ``runs/``.
"""
from __future__ import annotations

import fcntl
import json
import math
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Literal, Optional

import numpy as np

from . import api
from pydantic import Field

from .options import StudyOptions

GAP = 0.002                 # m: the plate's face above the undeformed tips at the start
PLATE_T = 0.02              # m: plate thickness
IMPACT_MASS = 5.0           # kg: the free plate of the held-out impacts
IMPACT_OFFSET = 0.05        # m: the plate's centre off the patch centre along x (a lever)
PLATE = "plate"


# ----------------------------------------------------------------------------- scenes
SLIDE_AXES = {"x": (1.0, 0.0), "y": (0.0, 1.0)}


def _design(preset: str, rows=None, columns=None, n_nodes=None, slide_axis="y",
            length_mm=None, diameter_mm=None) -> dict:
    """The brush (fixed base at the origin, bristles along +z), materials, contact pairs
    and the target material of ``preset``; the slide axis in the base plane (``x``: along
    the brush's columns, ``y``: across its rows). ``length_mm`` and ``diameter_mm`` (root;
    the tip keeps its ratio) change the bristles as ``study detumble``'s design sweep does."""
    from studio import presets

    scene = json.loads(presets.load_preset_or_file(preset).to_json())
    if not scene["brushes"]:
        raise ValueError(f"--preset {preset!r}: has no brush")
    brush = dict(scene["brushes"][0])
    brush.update(name="brush", base={"position": [0, 0, 0], "orientation": [1, 0, 0, 0]})
    brush.pop("mount", None)
    for key, value in (("rows", rows), ("columns", columns), ("n_nodes", n_nodes)):
        if value is not None:
            brush[key] = int(value)
    resize_bristles(brush, length_mm, diameter_mm)
    bodies = [b for b in scene["bodies"] if b.get("collide", True)]
    target_material = next((b["material"] for b in bodies if b["name"] == "target"),
                           bodies[0]["material"] if bodies else brush["material"])
    return {"brush": brush, "materials": scene["materials"],
            "contact_pairs": scene.get("contact_pairs", []),
            "target_material": target_material, "slide_axis": SLIDE_AXES[slide_axis]}


def detumble_contact(scene: dict) -> dict:
    """Where a detumble scene (the layout of ``static_presets/detumble_presets.py``) loads
    its first chaser brush: at the held offset, the tip plane's centre, the target's surface
    velocity there relative to the chaser (its spin times the lever; the chaser is held
    still) in the brush's base frame (``slip_direction``, the unit vector in the base plane,
    and ``slip_speed``, m/s) and the held interference (m: how far the undeformed tip plane
    lies inside the target's surface along the bristles). What ``study reduce`` must cover
    to fit a law for that scene (tests/studies/test_reduce_scenes.py)."""
    from engine.model.layout import quat_to_matrix

    target = next(b for b in scene["bodies"] if b["name"] == "target")
    chaser = next(b for b in scene["bodies"] if b["name"] == "chaser")
    ctl = next(c for c in scene["controllers"] if c["body"] == "chaser")
    brush = next(b for b in scene["brushes"] if b.get("mount") == "chaser")
    r_chaser = quat_to_matrix(np.asarray((chaser.get("pose") or {}).get("orientation")
                                         or [1, 0, 0, 0], float))
    r_base = r_chaser @ quat_to_matrix(np.asarray(brush["base"]["orientation"], float))
    centre = np.asarray((target.get("pose") or {}).get("position") or [0, 0, 0], float)
    com = centre + np.asarray((target.get("mass_properties") or {}).get("center_of_mass")
                              or [0, 0, 0], float)
    held = com + np.asarray(ctl["position"], float)      # the controller holds off the COM
    tip = held + r_chaser @ np.asarray(brush["base"]["position"], float) \
        + r_base @ [0.0, 0.0, tip_plane(brush)]
    v = np.cross(np.asarray(target["angular_velocity"], float), tip - com)
    v_base = r_base.T @ v
    speed = float(np.hypot(v_base[0], v_base[1]))
    shape = target["shape"]
    axis = r_base[:, 2]                                     # bristles, base -> tips
    if shape["type"] == "cylinder":                         # side: the radial distance
        rel = tip - centre
        depth = shape["radius"] - float(np.hypot(rel[0], rel[1]))
    else:                                                   # box: the face the tips meet
        half = np.asarray(shape["size"], float) / 2
        j = int(np.argmax(np.abs(axis)))
        depth = float(half[j] - abs((tip - centre)[j]))
    return {"slip_speed": speed,
            "slip_direction": [float(v_base[0] / speed), float(v_base[1] / speed)]
            if speed > 0 else [0.0, 0.0],
            "interference": depth}


def resize_bristles(brush: dict, length_mm=None, diameter_mm=None) -> None:
    """A brush design's bristles ``length_mm`` long with a ``diameter_mm`` root (the tip
    keeping its ratio to the root), in place on the brush dict; None keeps the value. The
    one rule ``study reduce`` and ``study detumble``'s design sweep share."""
    if length_mm is not None:
        brush["bristle_length"] = float(length_mm) * 1e-3
    if diameter_mm is not None:
        ratio = brush["tip_radius"] / brush["root_radius"]
        brush["root_radius"] = 0.5 * float(diameter_mm) * 1e-3
        brush["tip_radius"] = brush["root_radius"] * ratio


def patch_size(brush: dict) -> tuple[float, float]:
    """The brush footprint a x b (m): its grid's extent plus one tip diameter."""
    a = (brush["columns"] - 1) * brush["pitch"][0] + 2 * brush["tip_radius"]
    b = (brush["rows"] - 1) * brush["pitch"][1] + 2 * brush["tip_radius"]
    return a, b


def tip_plane(brush: dict) -> float:
    return brush["bristle_length"] + brush["tip_radius"]


def _plate(design: dict, travel: float) -> dict:
    """A plate that covers the footprint over a ``travel`` along the slide axis."""
    a, b = patch_size(design["brush"])
    ex, ey = design["slide_axis"]
    return {"type": "box", "size": [a + 2 * abs(ex) * travel + 0.04,
                                    b + 2 * abs(ey) * travel + 0.04, PLATE_T]}


def _sliding_path(design, times, depths, speed):
    """Waypoints of the plate: its face ``depths`` (m) below the tip plane at ``times``
    (negative: above), sliding at ``speed`` along the slide axis all the while (so the
    bristles meet the face leaning the way the surface moves, as under a spinning target,
    instead of being pressed end-on: straight columns pressed along their axis buckle, see
    the module docstring)."""
    z0 = tip_plane(design["brush"]) + PLATE_T / 2
    ex, ey = design["slide_axis"]
    pos = [[float(speed * t * ex), float(speed * t * ey), float(z0 - d)]
           for t, d in zip(times, depths)]
    return [float(t) for t in times], pos


def _scene(design, name, plate_body, duration, record_interval) -> dict:
    return {"name": name, "description": f"study reduce: {name}",
            "materials": design["materials"], "contact_pairs": design["contact_pairs"],
            "brushes": [design["brush"]], "bodies": [plate_body],
            "run": {"duration": duration, "record_interval": record_interval,
                    "channels": ["bodies", "energy", "contacts"]}}


def _kinematic_plate(design, times, positions, travel) -> dict:
    return {"name": PLATE, "material": design["target_material"],
            "shape": _plate(design, travel), "pose": {"position": positions[0]},
            "motion": {"type": "kinematic", "profile": {
                "kind": "waypoints", "times": times, "positions": positions}}}


def press_scene(design, depth, rate, speed=0.0) -> dict:
    """The plate down at ``rate`` from ``GAP`` above the tips to ``depth`` and back up,
    sliding at ``speed`` along the slide axis (0: an end-on press)."""
    t1 = (GAP + depth) / rate
    ts = np.linspace(0.0, 2 * t1, 33)
    ds = depth - (GAP + depth) * np.abs(ts - t1) / t1
    times, pos = _sliding_path(design, ts, ds, speed)
    body = _kinematic_plate(design, times, pos, speed * 2 * t1)
    name = f"press_d{depth * 1e3:g}_r{rate * 1e3:g}" + (f"_v{speed * 1e3:g}" if speed else "")
    return _scene(design, name, body, 2 * t1, min(t1 / 60, 0.005))


SLIDE_TIME = 0.5     # s of slide at the held depth
APPROACH_RATE = 0.02  # m/s


def slide_scene(design, depth, speed) -> dict:
    """The plate sliding at ``speed`` along the slide axis from the start, pressed slowly
    (``APPROACH_RATE``) to ``depth``, then held there for ``SLIDE_TIME``."""
    t1 = (GAP + depth) / APPROACH_RATE
    ts = np.concatenate([np.linspace(0.0, t1, 17), np.linspace(t1, t1 + SLIDE_TIME, 11)[1:]])
    ds = np.minimum(-GAP + APPROACH_RATE * ts, depth)
    times, pos = _sliding_path(design, ts, ds, speed)
    body = _kinematic_plate(design, times, pos, speed * (t1 + SLIDE_TIME))
    return _scene(design, f"slide_d{depth * 1e3:g}_v{speed * 1e3:g}", body,
                  t1 + SLIDE_TIME, 0.005)


def box_inertia(m, size):
    a, b, c = size
    return [m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12]


def impact_scene(design, vn, vt=0.0, spin=0.0, duration=None) -> dict:
    z0 = tip_plane(design["brush"]) + GAP + PLATE_T / 2
    ex, ey = design["slide_axis"]
    shape = _plate(design, 0.0)
    shape["size"][0] += 2 * IMPACT_OFFSET
    I = box_inertia(IMPACT_MASS, shape["size"])
    body = {"name": PLATE, "material": design["target_material"], "shape": shape,
            "pose": {"position": [IMPACT_OFFSET, 0, z0]}, "motion": {"type": "free"},
            "mass_properties": {"mass": IMPACT_MASS,
                                "inertia": [[I[0], 0, 0], [0, I[1], 0], [0, 0, I[2]]]},
            "velocity": [vt * ex, vt * ey, -vn], "angular_velocity": [0.0, 0.0, spin]}
    if duration is None:
        duration = GAP / vn + 0.6
    return _scene(design, f"impact_v{vn * 1e3:g}_t{vt * 1e3:g}_w{spin:g}", body, duration,
                  0.002)


# ----------------------------------------------------------------------------- task
def _series(h5_path):
    import engine

    with engine.open_result(h5_path) as res:
        out = {"time": np.asarray(res.time)}
        for key in ("position", "velocity", "angular_velocity", "contact_force",
                    "contact_torque"):
            out[key] = np.asarray(res.series(f"bodies/{PLATE}/{key}"))
        out["dissipated"] = np.asarray(res.series("energy/dissipated"))
    return out


def reduce_task(scene, h5_path: Path, params: dict) -> dict:
    """Dask task: run one DEM scene; return its samples (presses, slides) or its impact
    figures (JSON-able)."""
    import engine

    result = engine.run(engine.build(scene), output=h5_path, cancel=api.cancel_requested)
    api.check_cancel()
    s = _series(h5_path)
    zt = params["tip_plane"]
    face = s["position"][:, 2] - PLATE_T / 2
    d = zt - face
    out = {"status": result.status if result.status in ("completed", "stopped") else "failed",
           "wall_s": result.summary.get("wall_s")}
    kind = params["kind"]
    axis = np.array([*params.get("slide_axis", (1.0, 0.0)), 0.0])
    speed = params.get("speed", 0.0)
    if kind in ("press", "check"):
        out.update(d=d.tolist(), dd=(-s["velocity"][:, 2]).tolist(),
                   fn=s["contact_force"][:, 2].tolist(), time=s["time"].tolist())
    if kind == "check":
        axis_v = s["velocity"] @ axis
        out.update(v=axis_v.tolist(), ft=(-s["contact_force"] @ axis).tolist())
    if kind in ("press", "slide") and speed > 0:
        # the samples of steady sliding in contact: the tangential law's (F_n, v, F_t)
        v = s["velocity"] @ axis
        steady = (np.abs(v - speed) < 0.02 * speed) & (d > 0)
        out.update(slide_fn=s["contact_force"][steady, 2].tolist(), slide_v=v[steady].tolist(),
                   slide_ft=(-s["contact_force"][steady] @ axis).tolist(),
                   slide_d=d[steady].tolist())
    if kind == "impact":
        out.update(impact_figures(s["time"], s["velocity"], s["angular_velocity"],
                                  s["contact_force"][:, 2]))
    return out


def impact_figures(t, v, w, fn) -> dict:
    """Delta-v, Delta-omega, peak F_n, dissipated kinetic energy and the F_n history of a
    free plate's impact (the plate of :func:`impact_scene`)."""
    return {"dv": (v[-1] - v[0]).tolist(), "dw": (w[-1] - w[0]).tolist(),
            "peak_fn": float(np.max(fn)), "time": t.tolist(), "fn": fn.tolist(),
            "v0": v[0].tolist(), "w0": w[0].tolist(), "v_end": v[-1].tolist(),
            "w_end": w[-1].tolist()}


# ----------------------------------------------------------------------------- reduced replay
def replay_impact(law: dict, design: dict, scene: dict) -> dict:
    """The impact of ``scene`` replayed with the reduced law (module docstring)."""
    from scipy.integrate import solve_ivp

    from engine.model.reduced_law import friction_coefficient, normal_force, torsion_radius

    par = law["parameters"]
    a, b = law["patch"]["size"]
    rt = torsion_radius(a, b)
    body = scene["bodies"][0]
    m = body["mass_properties"]["mass"]
    I = np.array([body["mass_properties"]["inertia"][i][i] for i in range(3)])
    zt = tip_plane(design["brush"])
    y0 = np.concatenate([body["pose"]["position"], body["velocity"],
                         body["angular_velocity"]])
    T = scene["run"]["duration"]

    def loads(y):
        c, v, w = y[:3], y[3:6], y[6:9]
        r = np.array([-c[0], -c[1], -PLATE_T / 2])      # COM -> patch centre on the face
        u = v + np.cross(w, r)
        d = zt - (c[2] - PLATE_T / 2)
        fn = float(normal_force(d, -u[2], par["k"], par["p"], par["c"], par["eta"]))
        s = math.hypot(u[0], u[1])
        F = np.array([0.0, 0.0, fn])
        M = np.zeros(3)
        if fn > 0:
            if s > 0:
                mu = float(friction_coefficient(fn, s, par["mu"], par["q"], par["v_s"]))
                F[:2] = -mu * fn * u[:2] / s
            ws = abs(w[2]) * rt
            if ws > 0:
                mu_t = float(friction_coefficient(fn, ws, par["mu"], par["q"], par["v_s"]))
                M[2] = -math.copysign(mu_t * fn * rt, w[2])
        return F, np.cross(r, F) + M

    def rhs(t, y):
        F, tau = loads(y)
        return np.concatenate([y[3:6], F / m, tau / I])

    sol = solve_ivp(rhs, (0.0, T), y0, method="LSODA", rtol=1e-8, atol=1e-10,
                    max_step=5e-4, dense_output=True)
    ts = np.linspace(0.0, T, max(int(T / 0.002), 2) + 1)
    ys = sol.sol(ts)
    fn = np.array([loads(ys[:, i])[0][2] for i in range(ts.size)])
    return impact_figures(ts, ys[3:6].T, ys[6:9].T, fn)


def kinetic(m, I, v, w) -> float:
    return 0.5 * m * float(np.dot(v, v)) + 0.5 * float(np.dot(I, np.square(w)))


def compare(dem: dict, red: dict, scene: dict) -> dict:
    """Relative errors of the reduced replay against the DEM impact."""
    body = scene["bodies"][0]
    m = body["mass_properties"]["mass"]
    I = np.array([body["mass_properties"]["inertia"][i][i] for i in range(3)])
    e = {}
    for name, x in (("dem", dem), ("reduced", red)):
        e[name] = {"peak_fn": x["peak_fn"], "dv_normal": x["dv"][2], "dw": x["dw"],
                   "dissipated": kinetic(m, I, x["v0"], x["w0"])
                   - kinetic(m, I, x["v_end"], x["w_end"])}
    rel = lambda a, b: abs(a - b) / max(abs(b), 1e-300)  # noqa: E731
    dwd, dwr = np.asarray(e["dem"]["dw"]), np.asarray(e["reduced"]["dw"])
    e["errors"] = {"peak_fn": rel(e["reduced"]["peak_fn"], e["dem"]["peak_fn"]),
                   "dv_normal": rel(e["reduced"]["dv_normal"], e["dem"]["dv_normal"]),
                   "dw": float(np.linalg.norm(dwr - dwd) / max(np.linalg.norm(dwd), 1e-300)),
                   "dissipated": rel(e["reduced"]["dissipated"], e["dem"]["dissipated"])}
    fd = np.interp(red["time"], dem["time"], dem["fn"])
    e["errors"]["force_history_rms"] = float(np.sqrt(np.mean((np.asarray(red["fn"]) - fd)
                                                             ** 2)) / max(dem["peak_fn"],
                                                                          1e-300))
    return e


def check_sliding_press(law: dict, dem: dict) -> dict:
    """A held-out sliding press (kinematic: the law's forces follow from the plate's path)
    against its DEM run, over its samples from the law's ``fit_from`` interference on: the
    peak normal force and the tangential impulse (the integral of F_t over time: what turns
    a target's spin, the analogue of a contact's Delta-omega), DEM, reduced, relative
    errors."""
    from engine.model.reduced_law import friction_coefficient, normal_force

    par = law["parameters"]
    t, d, dd = (np.asarray(dem[k], float) for k in ("time", "d", "dd"))
    fn, v, ft = (np.asarray(dem[k], float) for k in ("fn", "v", "ft"))
    m = d >= law.get("fit_from", 0.0)
    if m.sum() < 2:
        raise ValueError("held-out sliding press: no samples past fit_from")
    fn_r = normal_force(d, dd, par["k"], par["p"], par["c"], par["eta"])
    ft_r = friction_coefficient(fn_r, np.abs(v), par["mu"], par["q"], par["v_s"]) * fn_r
    # the window's samples are one contiguous stretch (the face goes below fit_from once)
    tm = t[m]

    def impulse(f):
        return float(np.sum(0.5 * (f[m][1:] + f[m][:-1]) * np.diff(tm)))

    rel = lambda a, b: (a - b) / abs(b)  # noqa: E731
    out = {"window": [float(tm[0]), float(tm[-1])],
           "dem": {"peak_fn": float(fn[m].max()), "tangential_impulse": impulse(ft),
                   "normal_impulse": impulse(fn)},
           "reduced": {"peak_fn": float(fn_r[m].max()), "tangential_impulse": impulse(ft_r),
                       "normal_impulse": impulse(fn_r)}}
    out["errors"] = {k: rel(out["reduced"][k], out["dem"][k]) for k in out["dem"]}
    return out


# ----------------------------------------------------------------------------- study
def _floats(text, what: str, scale: float) -> list:
    from .study_command import number_list

    values = ([float(v) for v in text] if isinstance(text, list) else
              number_list(text, float, f"{what} {text!r}: expected comma-separated numbers"))
    if not values or any(not math.isfinite(v) or v <= 0 for v in values):
        raise ValueError(f"{what} {text!r}: numbers > 0")
    return [v * scale for v in values]


def build_specs(options: "Options", design: dict):
    from .runner import RunSpec

    zt = tip_plane(design["brush"])
    axis = list(design["slide_axis"])
    task = "studio.studies.reduce:reduce_task"
    specs = []
    press_speed = options.press_speed * 1e-3
    if press_speed < 0 or not math.isfinite(press_speed):
        raise ValueError(f"--press-speed {options.press_speed!r}: a number >= 0")
    for depth in _floats(options.depths, "--depths", 1e-3):
        for rate in _floats(options.rates, "--rates", 1e-3):
            sc = press_scene(design, depth, rate, press_speed)
            specs.append(RunSpec(sc["name"], sc, {"kind": "press", "depth": depth,
                                                  "rate": rate, "speed": press_speed,
                                                  "slide_axis": axis, "tip_plane": zt},
                                 task))
    for depth in _floats(options.slide_depths, "--slide-depths", 1e-3):
        for speed in _floats(options.speeds, "--speeds", 1e-3):
            sc = slide_scene(design, depth, speed)
            specs.append(RunSpec(sc["name"], sc, {"kind": "slide", "depth": depth,
                                                  "speed": speed, "slide_axis": axis,
                                                  "tip_plane": zt}, task))
    check = [options.check_depth * 1e-3, options.check_rate * 1e-3, options.check_speed * 1e-3]
    if all(v > 0 for v in check):
        sc = press_scene(design, *check)
        sc["name"] = "check_" + sc["name"]
        specs.append(RunSpec(sc["name"], sc, {"kind": "check", "depth": check[0],
                                              "rate": check[1], "speed": check[2],
                                              "slide_axis": axis, "tip_plane": zt}, task))
    vt = options.impact_tangential * 1e-3
    for vn in _floats(options.impact_speeds, "--impact-speeds", 1e-3):
        for t_speed, spin in ((0.0, 0.0), (vt, 0.0), (0.0, options.impact_spin)):
            if (t_speed, spin) != (0.0, 0.0) and vn != max(
                    _floats(options.impact_speeds, "--impact-speeds", 1e-3)):
                continue   # the oblique and spinning impacts at the fastest speed only
            sc = impact_scene(design, vn, t_speed, spin)
            specs.append(RunSpec(sc["name"], sc, {"kind": "impact", "vn": vn, "vt": t_speed,
                                                  "spin": spin, "tip_plane": zt}, task))
    return specs


def fit_digest(options: "Options", design: dict) -> str:
    """A hash of what a law is fitted from: every run's digest (scene, parameters, task) and
    ``--fit-from``. A law file that carries it (``law.json``'s ``fit_digest``) was fitted
    from these runs: ``study detumble`` reuses it rather than fitting again."""
    import hashlib

    text = json.dumps({"runs": sorted(s.digest() for s in build_specs(options, design)),
                       "fit_from": options.fit_from}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def fit_law(outcomes, design: dict, fit_from: float = 0.0) -> dict:
    """The law dict (engine.model.reduced_law) fitted to the press and slide outcomes'
    samples with an interference of at least ``fit_from`` (m)."""
    from .reduce_fit import fit_normal, fit_tangent

    presses = [o.summary for o in outcomes if o.ok and o.params["kind"] == "press"]
    # every steady sliding sample: the slides' and those of presses made while sliding
    slides = [o.summary for o in outcomes if o.ok and "slide_fn" in o.summary]
    cat = lambda runs, k: np.concatenate([np.asarray(r[k], float) for r in runs])  # noqa
    d, dd, fn = cat(presses, "d"), cat(presses, "dd"), cat(presses, "fn")
    keep = d >= fit_from
    d, dd, fn = d[keep], dd[keep], fn[keep]
    normal = fit_normal(d, dd, fn)
    # friction opposes the slip: a sample whose tangential force does not (F_t <= 0) is the
    # other regime of the brush, its bristles leaning ahead as columns that push the plate
    # along (seen at first touch and in slides pressed steeply: the approach over the slide
    # speed above ~1/4), which the law's form does not hold
    ft = cat(slides, "slide_ft")
    keep = (cat(slides, "slide_d") >= fit_from) & (ft > 0)
    pushed = int(np.sum((cat(slides, "slide_d") >= fit_from) & (ft <= 0)))
    sv = cat(slides, "slide_v")[keep]
    tangent = fit_tangent(cat(slides, "slide_fn")[keep], sv, ft[keep])
    contact = d > 0
    params = {k: normal[k]["value"] for k in ("k", "p", "c", "eta")}
    params.update({k: tangent[k]["value"] for k in ("mu", "q", "v_s")})
    return {"form": "F_n = k d^p (u(dd) + c dd); F_t = mu (F_n/1 N)^q tanh(v/v_s) F_n; "
                    "M = mu_eff(F_n, w r_t) F_n r_t (engine.model.reduced_law)",
            "parameters": params,
            "intervals": {k: v for k, v in {**normal, **tangent}.items()
                          if isinstance(v, dict)},
            "fit_rms": {"normal_N": normal["rms"], "tangent_N": tangent["rms"]},
            "ranges": {"interference": [float(d[contact].min()), float(d[contact].max())],
                       "rate": [float(dd[contact].min()), float(dd[contact].max())],
                       "slip_speed": [float(sv.min()), float(sv.max())],
                       "normal_force": [0.0, float(fn.max())]},
            "patch": {"size": list(patch_size(design["brush"])), "normal": [0, 0, 1]},
            "brush": {k: design["brush"][k] for k in ("material", "rows", "columns", "pitch",
                                                       "bristle_length", "root_radius",
                                                       "tip_radius", "n_nodes")},
            "target_material": design["target_material"],
            "slide_axis": list(design["slide_axis"]), "fit_from": fit_from,
            "samples_left_out": {"pushing_not_friction": pushed},
            "v_s_floor": tangent["v_s_floor"],
            "fit_notes": [tangent["v_s_at_floor"]] if "v_s_at_floor" in tangent else []}


_LIST = list[float]


class Options(StudyOptions):
    """``brush-studio study reduce``."""

    preset: str = Field("detumble_upper_stage",
                        description="the scene whose first brush, materials and target "
                                    "material are used (default detumble_upper_stage)",
                        json_schema_extra={"metavar": "NAME_OR_FILE", "scene": True})
    depths: _LIST = Field([20.0, 35.0], min_length=1, description="press depths",
                          json_schema_extra={"unit": "mm"})
    rates: _LIST = Field([10.0, 20.0], min_length=1, description="press rates",
                         json_schema_extra={"unit": "mm/s"})
    slide_depths: _LIST = Field([10.0, 30.0], min_length=1,
                                description="slide interferences (the normal load of a slide)",
                                json_schema_extra={"unit": "mm"})
    speeds: _LIST = Field([80.0, 120.0], min_length=1, description="slide speeds",
                          json_schema_extra={"unit": "mm/s"})
    press_speed: float = Field(100.0, ge=0,
                               description="slide speed of the presses (0: end-on presses, "
                                           "which buckle straight bristles)",
                               json_schema_extra={"metavar": "MM_PER_S", "unit": "mm/s"})
    fit_from: float = Field(10.0, ge=0,
                            description="interference below which samples are left out of "
                                        "the fit (the first touch of straight bristles, "
                                        "end-on: a buckling snap the law's form cannot "
                                        "follow)", json_schema_extra={"metavar": "MM",
                                                                     "unit": "mm"})
    slide_axis: Literal["x", "y"] = Field("y", description="the direction the plate slides "
                                          "in the brush's base plane: x along its columns, "
                                          "y across its rows (default y: the detumble "
                                          "presets' target surface moves across the rows)")
    check_depth: float = Field(27.0, ge=0, description="held-out sliding press (never "
                               "fitted, compared with the law): depth; 0 leaves it out",
                               json_schema_extra={"metavar": "MM", "unit": "mm"})
    check_rate: float = Field(15.0, ge=0, description="held-out sliding press: rate",
                              json_schema_extra={"metavar": "MM_PER_S", "unit": "mm/s"})
    check_speed: float = Field(100.0, ge=0, description="held-out sliding press: slide speed",
                               json_schema_extra={"metavar": "MM_PER_S", "unit": "mm/s"})
    impact_speeds: _LIST = Field([30.0, 100.0], min_length=1,
                                 description="held-out impact normal speeds",
                                 json_schema_extra={"unit": "mm/s"})
    impact_tangential: float = Field(100.0, ge=0,
                                     description="tangential speed of the oblique held-out "
                                                 "impact",
                                     json_schema_extra={"metavar": "MM_PER_S", "unit": "mm/s"})
    impact_spin: float = Field(0.5, ge=0, description="spin about the normal of the spinning "
                                                      "held-out impact",
                               json_schema_extra={"metavar": "RAD_PER_S", "unit": "rad/s"})
    rows: Optional[int] = Field(None, ge=1, description="brush rows (default: the preset's)")
    columns: Optional[int] = Field(None, ge=1, description="bristles per row (default: the "
                                                           "preset's)")
    n_nodes: Optional[int] = Field(None, ge=2, le=4096,
                                   description="nodes per bristle (default: the preset's)",
                                   json_schema_extra={"flags": ["--nodes", "--n-nodes"],
                                                      "metavar": "N"})
    length: Optional[float] = Field(None, gt=0, description="bristle length (default: the "
                                                            "preset's)",
                                    json_schema_extra={"metavar": "MM", "unit": "mm"})
    diameter: Optional[float] = Field(None, gt=0,
                                      description="bristle root diameter, the tip keeping its "
                                                  "ratio (default: the preset's)",
                                      json_schema_extra={"metavar": "MM", "unit": "mm"})


def design_of(options: Options) -> dict:
    """The brush design ``options`` fit a law for (:func:`_design`)."""
    return _design(options.preset, options.rows, options.columns, options.n_nodes,
                   options.slide_axis, options.length, options.diameter)


class LawFitError(RuntimeError):
    """A brush design's law could not be fitted; the message says why and names the folder
    of its runs."""


def fitted_law(path: Path, digest: str) -> Optional[dict]:
    """The law at ``path`` if it was fitted from the runs of ``digest``, else None."""
    from engine.model.reduced_law import load_law

    try:
        law = load_law(path)
    except (OSError, ValueError):
        return None
    return law if law.get("fit_digest") == digest else None


@contextmanager
def _locked(folder: Path):
    """Hold ``folder``'s lock: one process fits a design's law, the others wait for it."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def fit_or_reuse(options: "Options", folder: Path,
                 on_fit: Optional[Callable[[], None]] = None) -> tuple[dict, bool]:
    """The law of ``options``' brush design in ``folder``: the ``law.json`` there when it was
    fitted from the same runs (its ``fit_digest``), else fitted now by this study into
    ``folder`` (``on_fit`` called first: a long fit announced). Under the folder's lock, so
    concurrent callers for one design fit it once and the others reuse it. Returns (law,
    reused); LawFitError when the fit fails, ValueError/KeyError/OSError when the design
    cannot be read."""
    folder = Path(folder)
    digest = fit_digest(options, design_of(options))
    with _locked(folder):
        law = fitted_law(folder / "law.json", digest)
        if law is not None:
            return law, True
        if on_fit is not None:
            on_fit()
        try:
            code = _run_study(options, folder)
        except (api.StudyInputError, ValueError) as exc:    # a fit with too few samples, ...
            raise LawFitError(f"its fit failed ({exc}; {folder})") from None
        law = fitted_law(folder / "law.json", digest) if code == 0 else None
        if law is None:
            raise LawFitError(f"its study reduce failed (exit {code}; the failed runs in "
                              f"{folder}/outcomes.json)")
        return law, False


def add_parser(study_subparsers) -> None:
    from .study_command import set_command

    p = study_subparsers.add_parser(
        "reduce", help="fit a reduced brush law (a compliant patch) to short DEM runs",
        description="Fit the reduced brush law (a compliant patch: Hunt-Crossley-like normal "
                    "force, load- and speed-dependent friction, torsion from the patch size) "
                    "to short DEM presses and slides of a preset's brush against a flat "
                    "plate, with 95 % confidence intervals, and validate it on held-out DEM "
                    "impacts (peak force, Delta-v, Delta-omega, dissipated energy). Writes "
                    "law.json and validation.json. See docs/mission.md.")
    set_command(p, run, Options, default_output="study-reduce")


def _run_study(options: Options, out: Path) -> int:
    from engine.model.reduced_law import save_law

    from .run_files import write_json_atomic
    from .study_command import report_failures, run_study

    problem = None
    design = None
    try:
        design = design_of(options)
        build_specs(options, design)      # checks the number lists
    except (ValueError, KeyError, OSError) as exc:
        problem = str(exc)
    code, outcomes = run_study(lambda: build_specs(options, design), out, options,
                               desc="reduce runs", problem=problem)
    if code is not None:
        return code
    failed = report_failures(outcomes)
    if failed:
        return failed
    law = fit_law(outcomes, design, options.fit_from * 1e-3)
    rows = []
    specs = {s.run_id: s for s in build_specs(options, design)}
    for o in outcomes:
        if o.params["kind"] != "impact":
            continue
        scene = specs[o.run_id].scene
        red = replay_impact(law, design, scene)
        cmp_ = compare(o.summary, red, scene)
        rows.append({"run_id": o.run_id, **{k: o.params[k] for k in ("vn", "vt", "spin")},
                     **cmp_})
    law["validation"] = [{"run_id": r["run_id"], **r["errors"]} for r in rows]
    checks = [{"run_id": o.run_id, **{k: o.params[k] for k in ("depth", "rate", "speed")},
               **check_sliding_press(law, o.summary)}
              for o in outcomes if o.params["kind"] == "check"]
    law["validation_sliding"] = [{"run_id": c["run_id"], **c["errors"]} for c in checks]
    law["fit_digest"] = fit_digest(options, design)
    save_law(out / "law.json", law)
    write_json_atomic(out / "validation.json", {"impacts": rows, "sliding": checks})
    write_json_atomic(out / "reduce_summary.json",
                      {"law": law, "runs": [{"run_id": o.run_id, "params": o.params,
                                             "wall_s": o.wall_s} for o in outcomes]})
    par, ci = law["parameters"], law["intervals"]
    print("Reduced law (95 % intervals):")
    for k in ("k", "p", "c", "eta", "mu", "q", "v_s"):
        print(f"  {k:4s} = {par[k]:.4g}  [{ci[k]['ci95'][0]:.4g}, {ci[k]['ci95'][1]:.4g}]")
    for note in law["fit_notes"]:
        print(f"  note: {note}")
    print("Held-out impacts (relative errors, reduced vs DEM):")
    print(f"  {'run':34s} {'peak Fn':>8s} {'dv_n':>7s} {'dw':>7s} {'E diss':>7s} "
          f"{'F(t) rms':>8s}")
    for r in rows:
        e = r["errors"]
        print(f"  {r['run_id']:34s} {e['peak_fn']:8.1%} {e['dv_normal']:7.1%} {e['dw']:7.1%} "
              f"{e['dissipated']:7.1%} {e['force_history_rms']:8.1%}")
    for c in checks:
        dm, rd, e = c["dem"], c["reduced"], c["errors"]
        print(f"Held-out sliding press {c['run_id']} (from {law['fit_from'] * 1e3:g} mm): "
              f"peak F_n {dm['peak_fn']:.3g} / {rd['peak_fn']:.3g} N ({e['peak_fn']:+.1%}), "
              f"tangential impulse {dm['tangential_impulse']:.3g} / "
              f"{rd['tangential_impulse']:.3g} N s ({e['tangential_impulse']:+.1%}), "
              f"normal impulse ({e['normal_impulse']:+.1%}) (DEM / reduced)")
    print(f"Wrote {out}/law.json, validation.json, reduce_summary.json")
    return 0


run = api.study_run("reduce", _run_study)
