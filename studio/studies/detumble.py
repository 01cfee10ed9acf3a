"""``brush-studio study detumble``: a chaser holds its brush against a tumbling target in
orbit until the target's spin is gone (issue 15, item 4).

Scenes come from a detumble preset (``detumble_upper_stage``, ``detumble_box_satellite``;
their descriptions give every assumption, ``static_presets/detumble_presets.py`` the layout:
free ``target``, free ``chaser`` carrying ``brush``, controller ``chaser_control`` holding
the chaser at an offset from the target's centre). The study sweeps, as a grid:

* target size: a scale factor on the target's shape (its density kept: mass x s^3, inertia
  x s^5, centre of mass x s); the chaser's held offset and start move with the surface;
* spin rate (deg/s) about the preset's spin axis;
* brush design: bristle length (mm) and root diameter (mm; the tip keeps its ratio); the
  chaser's held offset moves with the length, so the held tip interference is kept.

Per run (``detumble_analysis``): the target's |w|(t) and angular momentum, the time to
detumble (|w| below ``threshold`` of its initial value to the end), peak contact force and
torque on the target and on the chaser (the brush's load), the chaser's Delta-v, angular
impulse and attitude error, and the bristles' peak bending stress against the stress limit.

Outputs (``-o DIR``): ``detumble_summary.json`` (every run's numbers and parameters),
``detumble_summary.csv``, ``omega.png`` (|w| against time, one line per run),
``outcomes.json``; ``runs/`` one result file per run. Every run is one Dask task
(``studio.studies.runner.run_many``).

``--fidelity reduced`` runs the brush as a patch with a fitted law (:func:`reduced_scene`):
the law of ``--law``, or, without it, each brush design's own (:func:`fit_laws`: ``study
reduce`` with its defaults into ``laws/<design id>/``, reused by a re-run), and beside each
scenario a DEM spot check of its first ``--spot-check-s`` seconds, compared in two windows
(:func:`spot_check`: the whole of it, and after the first touch).
"""
from __future__ import annotations

import csv
import itertools
import json
import math
from pathlib import Path
from typing import Annotated, Literal, Optional

import numpy as np

from pydantic import Field

from . import api
from .options import StudyOptions
from .detumble_analysis import (CHASER, CONTROLLER, DEFAULT_ISP, TARGET, analyse, plot_omega,
                                read_detumble)

PRESETS = ("detumble_upper_stage", "detumble_box_satellite")
#: bending stress limits of the bristle materials, Pa (the scene model has no strength):
#: silicone rubber tears at 5-11 MPa in tension; the low end, as a conservative limit
STRESS_LIMITS = {"silicone": 5e6}
DEG = math.pi / 180.0


# ----------------------------------------------------------------------------- scenes
def _target_extent(target: dict, axis: np.ndarray) -> float:
    """The target's largest extent from its centre of mass along ``axis`` (world), m."""
    from engine.model.meshes import body_geometry
    from engine.model.layout import quat_to_matrix
    from engine.model.spec import Body

    body = Body.model_validate(target)
    geo = body_geometry(body)
    R = quat_to_matrix(np.asarray(body.pose.orientation, float))
    return float(np.max((geo.vertices @ R.T) @ axis))


def _scale_shape(shape: dict, s: float) -> dict:
    shape = dict(shape)
    for key in ("size",):
        if key in shape:
            shape[key] = [v * s for v in shape[key]]
    for key in ("radius", "height", "length"):
        if key in shape:
            shape[key] = shape[key] * s
    if shape.get("type") == "mesh":
        shape["scale"] = shape.get("scale", 1.0) * s
    return shape


def chaser_parts(scene: dict, where: str):
    """(target, chaser, controller, brushes mounted on the chaser) of a detumble scene dict;
    SceneError when it is not one."""
    bodies = {b["name"]: b for b in scene["bodies"]}
    ctl = next((c for c in scene["controllers"] if c["name"] == CONTROLLER), None)
    mounted = [b for b in scene["brushes"] if b.get("mount") == CHASER]
    if TARGET not in bodies or CHASER not in bodies or ctl is None or not mounted:
        from engine import SceneError
        raise SceneError.single("(scene)", where,
                                f"not a detumble scene: it needs bodies {TARGET!r} and "
                                f"{CHASER!r}, a brush mounted on {CHASER!r} and the "
                                f"controller {CONTROLLER!r}")
    return bodies[TARGET], bodies[CHASER], ctl, mounted


def tip_reach(scene: dict) -> float:
    """How far the chaser's first brush reaches towards the target from the chaser, along
    the held offset's axis, m: the bristles' length projected on that axis plus the tip's
    radius (a sphere's). A design that changes it moves the held offset by the difference
    (:func:`keep_interference`), so the held tip interference stays the preset's."""
    from engine.model.layout import quat_to_matrix

    _, chaser, ctl, mounted = chaser_parts(scene, "(scene)")
    brush = mounted[0]
    axis = np.asarray(ctl["position"], float)
    axis = axis / np.linalg.norm(axis)
    along = quat_to_matrix(np.asarray(chaser["pose"].get("orientation", (1, 0, 0, 0)), float)) \
        @ quat_to_matrix(np.asarray(brush["base"]["orientation"], float)) @ [0.0, 0.0, 1.0]
    return brush["bristle_length"] * abs(float(along @ axis)) + brush["tip_radius"]


def keep_interference(scene: dict, reach_before: float) -> None:
    """Move the chaser's held offset and start (in place) by the change of
    :func:`tip_reach` from ``reach_before``: a longer bristle is held farther off."""
    _, chaser, ctl, _ = chaser_parts(scene, "(scene)")
    hold = np.asarray(ctl["position"], float)
    axis = hold / np.linalg.norm(hold)
    shift = tip_reach(scene) - reach_before
    ctl["position"] = list(hold + shift * axis)
    chaser["pose"]["position"] = list(np.asarray(chaser["pose"]["position"], float)
                                      + shift * axis)


def detumble_scene(preset, *, size: float = 1.0, spin_deg: Optional[float] = None,
                   length_mm: Optional[float] = None, diameter_mm: Optional[float] = None,
                   n_nodes: Optional[int] = None, rows: Optional[int] = None,
                   columns: Optional[int] = None, duration: Optional[float] = None,
                   record_interval: Optional[float] = None, tilt_deg: float = 0.0,
                   tumble: float = 0.0, offset: float = 0.0) -> dict:
    """The scene (dict) of one run: the preset with the target scaled by ``size``, spinning
    at ``spin_deg`` deg/s about its preset axis, bristles ``length_mm`` long with a
    ``diameter_mm`` root; ``n_nodes``, ``rows`` / ``columns``, ``duration`` and
    ``record_interval`` override the preset's resolution (a reduced run)."""
    if isinstance(preset, dict):
        scene = json.loads(json.dumps(preset))
        preset = scene.get("name", "scene")
    else:
        from studio import presets

        scene = json.loads(presets.load_preset_or_file(preset).to_json())
    target, chaser, ctl, mounted = chaser_parts(scene, preset)
    brush = mounted[0]   # the presets' brushes share one design
    offset_hold = np.asarray(ctl["position"], float)
    axis = offset_hold / np.linalg.norm(offset_hold)
    shift = 0.0
    if size != 1.0:
        before = _target_extent(target, axis)
        target["shape"] = _scale_shape(target["shape"], size)
        mp = target["mass_properties"]
        if mp.get("density") is None:  # mass and inertia given: scale them
            mp["mass"] *= size ** 3
            mp["inertia"] = [[v * size ** 5 for v in row] for row in mp["inertia"]]
            if mp.get("center_of_mass") is not None:
                mp["center_of_mass"] = [v * size for v in mp["center_of_mass"]]
        shift += _target_extent(target, axis) - before
    w_preset = np.asarray(target["angular_velocity"], float)
    if spin_deg is not None:
        target["angular_velocity"] = list(w_preset / np.linalg.norm(w_preset) * spin_deg * DEG)
        stop = scene["run"].get("stop")
        if stop and stop.get("body") == TARGET:  # the preset's stop is relative to its spin
            stop["value"] *= spin_deg * DEG / float(np.linalg.norm(w_preset))
    w_now = np.asarray(target["angular_velocity"], float)
    e = np.cross(w_now, axis)
    e = e / np.linalg.norm(e) if np.linalg.norm(e) > 0 else np.cross(axis, [0.0, 0.0, 1.0])
    if tilt_deg or tumble:
        from scipy.spatial.transform import Rotation

        wn = float(np.linalg.norm(w_now))
        w_new = Rotation.from_rotvec(math.radians(tilt_deg) * e).apply(w_now) + tumble * wn * e
        target["angular_velocity"] = list(w_new / np.linalg.norm(w_new) * wn)
    # a longer bristle reaches farther along the approach axis by its projection on it
    from .reduce import resize_bristles

    reach = tip_reach(scene)
    for b in mounted:
        resize_bristles(b, length_mm, diameter_mm)
    shift += tip_reach(scene) - reach
    ctl["position"] = list(offset_hold + shift * axis + offset * e)
    chaser["pose"]["position"] = list(np.asarray(chaser["pose"]["position"], float)
                                      + shift * axis + offset * e)
    for key, value in (("n_nodes", n_nodes), ("rows", rows), ("columns", columns)):
        if value is not None:
            for b in mounted:
                b[key] = int(value)
    if duration is not None:
        scene["run"]["duration"] = float(duration)
    if record_interval is not None:
        scene["run"]["record_interval"] = float(record_interval)
    scene["name"] = f"{preset}_study"
    scene["description"] = (
        f"Study 'detumble': the preset {preset} with the target scaled x{size:g}, spinning at "
        f"{np.linalg.norm(target['angular_velocity']) / DEG:g} deg/s, bristles "
        f"{brush['bristle_length'] * 1e3:g} mm, root diameter "
        f"{2 * brush['root_radius'] * 1e3:g} mm, {brush['rows']} x {brush['columns']}, "
        f"{brush['n_nodes']} nodes each"
        + (f", spin axis tilted {tilt_deg:g} deg" if tilt_deg else "")
        + (f", tumbling ({tumble:g} x |w| across)" if tumble else "")
        + (f", held {offset * 1e3:g} mm off-centre" if offset else "") + ". "
        + scene["description"])
    return scene


# ----------------------------------------------------------------------------- reduced
FIDELITIES = ("dem", "reduced")
#: frames of a reduced run, s (default): an hour-long run keeps 3 600 (each frame is flushed
#: to disk, about 30 ms on the shared test machine: at 0.1 s the recording took 20 times the
#: physics)
REDUCED_RECORD_INTERVAL = 1.0
SPOT_MARGIN = 0.1            # s: the DEM spot check runs this much past its window
#: channels of a reduced run: no bristles, so no nodes, root forces nor bending
REDUCED_CHANNELS = ["bodies", "energy", "contacts"]


def spot_scene(scene: dict, spot_s: float) -> dict:
    """The DEM spot check's scene of a detumble scene dict: its first ``spot_s`` seconds (a
    little past, :data:`SPOT_MARGIN`, so both runs' windows end there), with no stop rule."""
    dem = json.loads(json.dumps(scene))
    dem["run"]["duration"] = min(spot_s + SPOT_MARGIN, dem["run"]["duration"])
    dem["run"].pop("stop", None)
    return dem


def reduced_scene(scene: dict, law: dict) -> dict:
    """``scene`` (a detumble scene dict, :func:`detumble_scene`) with the chaser's brushes
    replaced by one reduced brush (issue 25 item 4): a patch (``engine.kernels.patch``) of the
    brush's footprint (``reduce.patch_size``: the root grid's extent plus one tip diameter)
    on the chaser, its tip plane where the undeformed tips end (``bristle_length +
    tip_radius`` along the base's +z, the brush's base pose), so the held offset gives the
    same interference as the DEM brush. The law goes into the scene inline. A law fitted on
    a brush with fewer bristles (``law.brush``) is taken per bristle: its footprint is
    restated to the full brush's area times its bristle share, so the full brush carries
    ``bristles / law bristles`` times its force at a depth, and its friction coefficient is
    taken at the law's brush's share of the load (``mu`` times that share to the power
    ``q``; both recorded in the inline law's ``patch.size_restated``)."""
    from engine.model.reduced_law import check_law
    from .reduce import patch_size

    scene = json.loads(json.dumps(scene))
    law = json.loads(json.dumps(check_law(dict(law))))
    mounted = [b for b in scene["brushes"] if b.get("mount") == CHASER]
    brush = mounted[0]
    a, b = patch_size(brush)
    n_full = brush["rows"] * brush["columns"] * len(mounted)
    lb = law.get("brush") or {}
    if lb.get("rows") and lb.get("columns"):
        n_law = int(lb["rows"]) * int(lb["columns"])
        a_law, b_law = (float(v) for v in law["patch"]["size"])
        want = a * b * len(mounted) * n_law / n_full
        f = math.sqrt(want / (a_law * b_law))
        law["patch"]["size_restated"] = {
            "from": [a_law, b_law], "why": f"per bristle: the law's {n_law} bristles carry "
                                          f"the share {n_law}/{n_full} of this footprint"}
        law["patch"]["size"] = [a_law * f, b_law * f]
        # mu_eff = mu (F_n / 1 N)^q is the law's at ITS brush's load; the element takes it
        # at the whole patch's, n_full / n_law times larger: per bristle, mu (s F_n)^q with
        # s = n_law / n_full, i.e. mu s^q at the whole patch's load
        par = law["parameters"]
        share = n_law / n_full
        law["patch"]["size_restated"]["mu"] = {
            "from": float(par["mu"]), "why": f"mu_eff per bristle: mu x ({n_law}/{n_full})^q"}
        par["mu"] = float(par["mu"]) * share ** float(par["q"])
    tip = brush["bristle_length"] + brush["tip_radius"]
    patches = []
    for i, br in enumerate(mounted):
        base = br["base"]
        from engine.model.layout import quat_to_matrix

        R = quat_to_matrix(np.asarray(base["orientation"], float))
        pos = np.asarray(base["position"], float) + R @ [0.0, 0.0, tip]
        patches.append({"name": f"reduced_{br['name']}", "law": law,
                        "pose": {"position": list(pos), "orientation": list(base["orientation"])},
                        "size": [a, b]})
    scene["brushes"] = [b for b in scene["brushes"] if b.get("mount") != CHASER]
    chaser = next(b for b in scene["bodies"] if b["name"] == CHASER)
    chaser["patches"] = patches
    scene["run"]["channels"] = list(REDUCED_CHANNELS)
    scene["name"] = scene["name"] + "_reduced"
    scene["description"] = ("Reduced brush (issue 25): the chaser's brush replaced by a "
                            "compliant patch with a fitted law (engine.kernels.patch). "
                            + scene["description"])
    return scene


#: s after the DEM brush's first contact that the spot check's second window starts: the
#: straight bristles' end-on spike, which the law leaves out (docs/mission.md), is over by
#: then. In the upper stage's 10 s spot check (frames every 20 ms) the spike (27.7 N against
#: the 3.6 N of the steady slide) lasted until 0.35 s after the first contact: from 0.4 s
#: on, |F| stays below the steady slide's largest value and the torque opposes the spin;
#: 0.5 s leaves a frame's margin at the reduced run's coarser frames' interpolation
SETTLE_S = 0.5


def window_figures(d: dict, t_end: float, t_start: float = 0.0) -> dict:
    """Over [t_start, t_end] of a run (:func:`detumble_analysis.read_detumble`'s arrays):
    the change of the target's spin along its initial spin axis (rad/s), the mean torque on
    it along that axis (N m: the change of its angular momentum over the window, the contact
    torque's impulse, over the window's length; the gravity-gradient torque is orders
    smaller), the peaks of its recorded contact torque along the axis and of its contact
    force |F| (at the frames and at the window's ends) and the time of first contact in the
    window. Runs of different steps record at different times: values at the window's ends
    are linearly interpolated between the frames around them."""
    t = np.asarray(d["time"], float)
    t_end = min(float(t_end), float(t[-1]))
    t_start = min(max(float(t_start), float(t[0])), t_end)
    inside = (t > t_start) & (t < t_end)

    def series(a):   # the frames inside, with both ends interpolated
        a = np.asarray(a, float)
        at = lambda x: np.array([np.interp(x, t, a[:, i]) for i in range(a.shape[1])])  # noqa
        return np.vstack([at(t_start), a[inside], at(t_end)])

    w_all = np.asarray(d["omega"], float)
    axis = w_all[0] / max(float(np.linalg.norm(w_all[0])), 1e-300)   # the initial spin axis
    w = series(w_all)
    tq = series(d["target_torque"]) @ axis
    force = np.linalg.norm(series(d["target_force"]), axis=1)
    L = series(d["angular_momentum"])
    span = (t >= t_start) & (t <= t_end)
    contact = np.asarray(d["n_contacts"])[span] > 0
    return {"window_s": float(t_end - t_start), "start_s": float(t_start),
            "end_s": float(t_end), "delta_omega": float((w[-1] - w[0]) @ axis),
            "mean_torque": float((L[-1] - L[0]) @ axis / max(t_end - t_start, 1e-300)),
            "peak_torque": float(np.abs(tq).max()), "peak_force": float(force.max()),
            "first_contact": (float(t[span][np.argmax(contact)]) if contact.any()
                              else None)}


SPOT_KEYS = ("delta_omega", "mean_torque", "peak_torque", "peak_force")


def spot_check_errors(dem: dict, reduced: dict) -> dict:
    """Relative errors of the reduced run against the DEM spot check over the same window:
    (reduced - DEM) / |DEM| of Delta-omega, mean and peak torque and peak force."""
    out = {}
    for key in SPOT_KEYS:
        ref = dem.get(key)
        val = reduced.get(key)
        out[key] = (float((val - ref) / abs(ref)) if ref not in (None, 0.0) and val is not None
                    else None)
    return out


def spot_check(dem: dict, reduced: dict, window_s: float, settle_s: float = SETTLE_S) -> dict:
    """The reduced run against its DEM spot check (both :func:`read_detumble`'s arrays) in
    two windows: the whole spot check [0, window_s] (``dem``, ``reduced``,
    ``relative_error``) and ``after_touch``, from the DEM brush's first contact plus
    ``settle_s`` to the window's end (the law leaves the first touch out: there it is not
    expected to agree; ``None``, with ``after_touch_why``, when the DEM brush touched too
    late to leave such a window)."""
    whole_d, whole_r = window_figures(dem, window_s), window_figures(reduced, window_s)
    out = {"dem": whole_d, "reduced": whole_r,
           "relative_error": spot_check_errors(whole_d, whole_r), "after_touch": None}
    touch = whole_d["first_contact"]
    start = None if touch is None else touch + settle_s
    if start is None or start >= whole_d["end_s"]:
        out["after_touch_why"] = (
            "the DEM brush did not touch in the spot check" if touch is None else
            f"the DEM brush first touched at {touch:.3g} s: {settle_s:g} s later is past "
            f"the window's end ({whole_d['end_s']:g} s); a longer --spot-check-s")
        return out
    a_d, a_r = window_figures(dem, window_s, start), window_figures(reduced, window_s, start)
    out["after_touch"] = {"first_contact": touch, "settle_s": settle_s, "dem": a_d,
                          "reduced": a_r, "relative_error": spot_check_errors(a_d, a_r)}
    return out


# ----------------------------------------------------------------------------- task
def detumble_task(scene, h5_path: Path, params: dict) -> dict:
    """Dask task: run one detumble scene and summarise it (JSON-able)."""
    import engine

    from .contact_peak import ContactForcePeak

    if params.get("law_error"):       # the design's law could not be fitted
        raise RuntimeError(params["law_error"])
    system = engine.build(scene)
    # the largest single bristle contact on the target (a DEM brush: a reduced one has none)
    dem_brush = any(b.mount == CHASER for b in scene.brushes)
    peak = (ContactForcePeak(system, list(system.body_names).index(TARGET))
            if dem_brush else None)
    result = engine.run(system, output=h5_path, cancel=api.cancel_requested, observer=peak)
    api.check_cancel()
    data = read_detumble(h5_path)
    out = analyse(data, params["threshold"], params["stress_limit"],
                  isp=params.get("isp", DEFAULT_ISP), drift_time=params.get("drift_time", 3600.0),
                  sn_curve=params.get("sn_curve"))
    out.update(pressure_figures(system, out["peak_target_force"],
                                peak.peak if peak is not None else None))
    if "fatigue" in data:
        write_fatigue_table(Path(h5_path).with_suffix(".fatigue.csv"), data["fatigue"])
    s = result.summary
    if s.get("patches"):
        out["patches"] = s["patches"]
        out["warnings"] = [w for w in s.get("warnings", []) if w.startswith("patch ")]
    out["fidelity"] = params.get("fidelity", "dem")
    wall = s.get("wall_s") or 0.0
    out.update(status=result.status if result.status in ("completed", "stopped")
               else "failed", dt=system.dt, wall_s=wall, steps=s.get("steps"),
               n_nodes=system.n_nodes,
               node_steps_per_s=(s.get("steps") or 0) * system.n_nodes / wall if wall else None)
    return out


def footprint_area(system) -> float:
    """The area the chaser's brushes press on, m^2, of a built scene (``engine.System``):
    each mounted brush's footprint (``reduce.patch_size``: its grid's extent plus one tip
    diameter), or each reduced patch's size as the build resolved it (:func:`reduced_scene`
    gives it that footprint)."""
    from .reduce import patch_size

    mounted = [b for b in system.scene.brushes if b.mount == CHASER]
    if mounted:
        return float(sum(math.prod(patch_size(b.model_dump())) for b in mounted))
    return float(sum(p["size"][0] * p["size"][1] for p in system.patch_info
                     if p["body"] == CHASER))


def pressure_figures(system, peak_force: float,
                     peak_contact_force: Optional[float]) -> dict:
    """Contact pressure on the target (issue 25 item 6): ``peak_footprint_pressure``, the
    largest push on the target over the brush footprint (a mean; both fidelities), and, for
    a DEM brush, ``peak_contact_force`` (the largest single bristle contact, at the recorded
    frames) and ``peak_contact_pressure``, that force over the tip's cross-section pi r_tip^2
    (a nominal pressure, as the design search reports it). A reduced brush has no single
    contacts: those two are None."""
    from .contact_peak import footprint_pressure, nominal_pressure

    area = footprint_area(system)
    out = {"footprint_area": area,
           "peak_footprint_pressure": footprint_pressure(peak_force, area) if area else None,
           "peak_contact_force": None, "peak_contact_pressure": None}
    if peak_contact_force is not None:
        r_tip = min(b.tip_radius for b in system.scene.brushes if b.mount == CHASER)
        out.update(peak_contact_force=float(peak_contact_force),
                   peak_contact_pressure=nominal_pressure(peak_contact_force, r_tip))
    return out


def write_fatigue_table(path: Path, f: dict) -> None:
    """One row per bristle: counted stress cycles, largest amplitude (MPa) and, with an S–N
    curve, Miner's damage of the run."""
    import csv

    damage = f.get("bristle_damage")
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["bristle", "cycles", "amplitude_max_mpa"]
                   + (["miner_damage"] if damage is not None else []))
        for b, (n, a) in enumerate(zip(f["bristle_cycles"], f["bristle_amplitude"])):
            w.writerow([b, f"{n:g}", f"{a / 1e6:.6g}"]
                       + ([f"{damage[b]:.6g}"] if damage is not None else []))


# ----------------------------------------------------------------------------- study
def build_specs(options: "Options", grid: dict):
    from .runner import RunSpec

    specs = []
    for size, spin, length, diameter, tilt, tumble, off in itertools.product(
            grid["sizes"], grid["spins"], grid["lengths"], grid["diameters"], grid["tilts"],
            grid["tumbles"], grid["offsets"]):
        params = {"preset": options.preset, "size": size, "spin_deg": spin,
                  "tilt_deg": tilt, "tumble": tumble, "offset": off,
                  "length_mm": length, "diameter_mm": diameter,
                  "threshold": options.threshold, "isp": options.isp,
                  "drift_time": options.drift_time, "sn_curve": options.sn_curve,
                  "stress_limit": grid["stress_limit"]}
        run_id = "_".join(_tag(k, v) for k, v in (
            ("size", size), ("spin", spin), ("len", length), ("dia", diameter)))
        run_id += "".join(f"_{k}{v:g}" for k, v in (
            ("tilt", tilt), ("tumble", tumble), ("off", off)) if v)
        scene = detumble_scene(
            options.preset, size=size, spin_deg=spin, length_mm=length,
            diameter_mm=diameter, n_nodes=options.n_nodes, rows=options.rows,
            columns=options.columns, duration=options.duration,
            record_interval=options.record_interval, tilt_deg=tilt,
            tumble=tumble, offset=off)
        task = "studio.studies.detumble:detumble_task"
        law = grid["law"]
        if options.fidelity == "reduced" and grid.get("laws") is not None:
            params["law_design"] = design_id(options, length, diameter)
            law = grid["laws"][params["law_design"]]
        if isinstance(law, str):     # its design's fit failed: the run fails saying why
            params.update(fidelity="reduced", law_error=law)
            specs.append(RunSpec(run_id=run_id, scene=scene, params=params, task=task))
            continue
        if options.fidelity == "reduced":
            spot = options.spot_check_s
            params.update(fidelity="reduced", spot_check_s=spot or None)
            if spot:
                # the DEM spot check: the same scenario's first seconds with the brush
                specs.append(RunSpec(run_id=run_id + "_dem_spot", scene=spot_scene(scene, spot),
                                     params=dict(params, fidelity="dem", spot_of=run_id),
                                     task=task))
            scene = reduced_scene(scene, law)
            if options.record_interval is None:
                scene["run"]["record_interval"] = REDUCED_RECORD_INTERVAL
        specs.append(RunSpec(run_id=run_id, scene=scene, params=params, task=task))
    return specs


def _tag(key: str, value: Optional[float]) -> str:
    """``len20`` for a swept value, ``lenp`` for the preset's own (None): run and design
    ids."""
    return f"{key}{'p' if value is None else f'{value:g}'}"


LAWS_DIR = "laws"   # OUT/laws/<design id>/: study reduce's outputs for each brush design


def design_id(options: "Options", length: Optional[float], diameter: Optional[float]) -> str:
    """The name of a brush design of the sweep (``len20_diap``: 'p' for the preset's value;
    ``--rows``, ``--columns`` and ``--nodes`` appended when given): the runs of one design
    share one fitted law, whatever the target's size, spin and the tolerance sweeps."""
    name = "_".join(_tag(k, v) for k, v in (("len", length), ("dia", diameter)))
    return name + "".join(f"_{k}{v}" for k, v in (
        ("rows", options.rows), ("cols", options.columns), ("nodes", options.n_nodes))
        if v is not None)


def design_ids(options: "Options", grid: dict) -> dict:
    """{design id: (length mm, diameter mm)} of the sweep (None: the preset's value)."""
    return {design_id(options, L, D): (L, D)
            for L, D in itertools.product(grid["lengths"], grid["diameters"])}


def reduce_options(options: "Options", length: Optional[float],
                   diameter: Optional[float]):
    """``study reduce``'s options (its defaults: the protocol of the detumble's regime) for
    one brush design of the sweep, with this study's execution options."""
    from . import reduce

    return reduce.Options(preset=options.preset, rows=options.rows, columns=options.columns,
                          n_nodes=options.n_nodes, length=length, diameter=diameter,
                          scheduler=options.scheduler, workers=options.workers,
                          no_progress=options.no_progress)


def fit_laws(options: "Options", grid: dict, out: Path) -> dict:
    """``--fidelity reduced`` without ``--law``: each brush design's law, fitted by ``study
    reduce`` (its runs, fit and validation, through the same runner) into
    ``out/laws/<design id>/``, or the one already there when it was fitted from the same
    runs (``law.json``'s ``fit_digest``: a re-run reuses it, not refits it). Returns
    {design id: law dict, or the message of why it could not be fitted}."""
    from . import reduce

    laws = {}
    for did, (length, diameter) in design_ids(options, grid).items():
        folder = out / LAWS_DIR / did
        what = f"no reduced law for brush design {did}"
        try:
            law, reused = reduce.fit_or_reuse(
                reduce_options(options, length, diameter), folder,
                on_fit=lambda: print(f"law of brush design {did}: study reduce into {folder}"))
        except (reduce.LawFitError, ValueError, KeyError, OSError) as exc:
            laws[did] = f"{what}: {exc}"
            continue
        if reused:
            print(f"law of brush design {did}: {folder}/law.json (fitted before: reused)")
        laws[did] = law
    return laws


def write_outputs(out_dir: Path, outcomes, threshold: float) -> dict:
    """detumble_summary.json / .csv and omega.png from the finished runs."""
    from .run_files import write_json_atomic

    out_dir = Path(out_dir)
    ok = [o for o in outcomes if o.ok]
    rows = []
    for o in outcomes:
        row = {"run_id": o.run_id, "status": o.status, "error": o.error}
        row.update(o.params)
        row.update(o.summary if o.ok else {})
        row["status"] = o.status
        rows.append(row)
    write_json_atomic(out_dir / "detumble_summary.json", {"runs": rows})
    keys = sorted({k for r in rows for k in r})
    with (out_dir / "detumble_summary.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    plot_omega(out_dir / "omega.png", [(o.run_id, read_detumble(o.h5)) for o in ok],
               threshold)
    return {"runs": rows}


def _floats(text, what: str) -> list:
    if text is None or (isinstance(text, list) and not text):
        return [None]
    if isinstance(text, list):  # checked by the options model
        return [float(v) for v in text]
    from .study_command import number_list

    values = number_list(text, float, f"{what} {text!r}: expected comma-separated numbers")
    if not values or any(not math.isfinite(v) or v <= 0 for v in values):
        raise ValueError(f"{what} {text!r}: numbers > 0")
    return values


def _signed(values, what: str) -> list:
    """Finite numbers of any sign (a list checked by the options model, or text)."""
    if isinstance(values, list):
        if not values:
            return [0.0]
        return [float(v) for v in values]
    from .study_command import number_list

    out = number_list(values, float, f"{what} {values!r}: expected comma-separated numbers")
    if not out or any(not math.isfinite(v) for v in out):
        raise ValueError(f"{what} {values!r}: finite numbers")
    return out


_POSITIVE_LIST = list[Annotated[float, Field(gt=0, allow_inf_nan=False)]]


class Options(StudyOptions):
    """``brush-studio study detumble`` (``None`` or an empty list: the preset's value)."""

    preset: str = Field("detumble_upper_stage",
                        description="the detumble scene: " + " or ".join(PRESETS)
                        + " (default detumble_upper_stage), or a scene file with the same "
                          "layout", json_schema_extra={"metavar": "NAME_OR_FILE",
                                                       "scene": True})
    sizes: _POSITIVE_LIST = Field([1.0], min_length=1,
                                  description="target scale factors (default 1)")
    spins: _POSITIVE_LIST = Field(default_factory=list,
                                  description="initial spin rates, deg/s (default: the "
                                              "preset's)",
                                  json_schema_extra={"metavar": "DEG_PER_S",
                                                     "unit": "deg/s"})
    lengths: _POSITIVE_LIST = Field(default_factory=list,
                                    description="bristle lengths, mm (default: the preset's)",
                                    json_schema_extra={"metavar": "MM", "unit": "mm"})
    diameters: _POSITIVE_LIST = Field(default_factory=list,
                                      description="bristle root diameters, mm (default: the "
                                                  "preset's)",
                                      json_schema_extra={"metavar": "MM", "unit": "mm"})
    threshold: float = Field(0.05, gt=0, lt=1,
                             description="detumbled once |omega| stays below this fraction "
                                         "of its initial value (default 0.05)")
    stress_limit: Optional[float] = Field(
        None, gt=0, description="bristle bending stress limit, Pa (default: "
        + ", ".join(f"{k} {v:g}" for k, v in STRESS_LIMITS.items()) + ")",
        json_schema_extra={"metavar": "PA", "unit": "Pa"})
    n_nodes: Optional[int] = Field(None, ge=2, le=4096,
                                   description="nodes per bristle (default: the preset's)",
                                   json_schema_extra={"flags": ["--nodes", "--n-nodes"],
                                                      "metavar": "N"})
    rows: Optional[int] = Field(None, ge=1, description="brush rows (default: preset's)")
    columns: Optional[int] = Field(None, ge=1,
                                   description="bristles per row (default: the preset's)")
    duration: Optional[float] = Field(None, gt=0,
                                      description="simulated time per run at most (default: "
                                                  "the preset's; a run stops earlier once "
                                                  "the target is detumbled)",
                                      json_schema_extra={"metavar": "S", "unit": "s"})
    record_interval: Optional[float] = Field(None, gt=0,
                                             description="time between recorded frames, s",
                                             json_schema_extra={"metavar": "S", "unit": "s"})
    tilts: list[float] = Field([0.0], min_length=1,
                               description="tolerance sweep: spin-axis tilts toward the brush "
                                           "normal (default 0)",
                               json_schema_extra={"metavar": "DEG", "unit": "deg"})
    tumbles: list[float] = Field([0.0], min_length=1,
                                 description="tolerance sweep: a transverse spin component, as "
                                             "a fraction of |omega| (a tumbling, non-principal "
                                             "spin; default 0)",
                                 json_schema_extra={"metavar": "FRACTION"})
    offsets: list[float] = Field([0.0], min_length=1,
                                 description="tolerance sweep: the hold point moved across the "
                                             "surface's motion (default 0)",
                                 json_schema_extra={"metavar": "M", "unit": "m"})
    isp: float = Field(DEFAULT_ISP, gt=0,
                       description=f"specific impulse of the chaser's thrusters (default "
                                   f"{DEFAULT_ISP:g}, a hydrazine monopropellant class): the "
                                   "propellant figures, "
                                   "for per-axis and gimballed thrusters",
                       json_schema_extra={"metavar": "S", "unit": "s"})
    sn_curve: Optional[str] = Field(
        None, description="S-N points of the bristle material, stress amplitude MPa : cycles "
                          "to failure, e.g. 5:1e4,2:1e6 (at least two; log-log interpolation, "
                          "extrapolation flagged): each run's Miner damage of its worst "
                          "bristle and the runs it survives. No default: no material data "
                          "is invented",
        json_schema_extra={"metavar": "MPA:CYCLES,..."})
    fidelity: Literal["dem", "reduced"] = Field(
        "dem", description="dem: the bristles (DEM); reduced: the brush replaced by a "
                           "compliant patch with a fitted law (--law, or fitted here), at "
                           "the rigid-body time step, for hour-long runs (docs/mission.md)")
    law: Optional[str] = Field(None, description="with --fidelity reduced: the reduced law "
                                                 "file (law.json of brush-studio study "
                                                 "reduce) for every run; without it each "
                                                 "brush design of the sweep gets its own, "
                                                 "fitted by study reduce's defaults into "
                                                 "OUTPUT/laws/DESIGN/ (reused by a re-run)",
                               json_schema_extra={"metavar": "FILE"})
    spot_check_s: float = Field(5.0, ge=0,
                                description="with --fidelity reduced: the first seconds of "
                                            "each scenario also run with the DEM brush, and "
                                            "the reduced run's Delta-omega, force and torque "
                                            "compared over them and over their part after "
                                            "the first touch (0: none; default 5)",
                                json_schema_extra={"metavar": "S", "unit": "s"})
    drift_time: float = Field(3600.0, gt=0,
                              description="how long the debris's free CW drift after the run "
                                          "is followed for the minimum chaser-debris distance "
                                          "(default 3600)",
                              json_schema_extra={"metavar": "S", "unit": "s"})


def add_parser(study_subparsers) -> None:
    from .study_command import set_command

    p = study_subparsers.add_parser(
        "detumble", help="a chaser's brush detumbles a spinning target in orbit",
        description="A chaser holds its brush against a spinning target (a detumble preset) "
                    "until the target's spin is gone: |omega|(t), angular momentum, time to "
                    "detumble, peak loads on target and chaser, the chaser's Delta-v and "
                    "attitude error, peak bristle bending stress against the limit; swept "
                    "over target size, spin rate and brush design. See docs/mission.md.")
    set_command(p, run, Options, default_output="study-detumble")


def _grid(options: Options) -> dict:
    """The swept values, checked; ValueError names the bad option."""
    import engine
    from studio import presets

    grid = {"sizes": _floats(options.sizes, "--sizes"),
            "spins": _floats(options.spins, "--spins"),
            "lengths": _floats(options.lengths, "--lengths"),
            "diameters": _floats(options.diameters, "--diameters"),
            "tilts": _signed(options.tilts, "--tilts"),
            "tumbles": _signed(options.tumbles, "--tumbles"),
            "offsets": _signed(options.offsets, "--offsets")}
    try:
        scene = presets.load_preset_or_file(options.preset)
    except (KeyError, OSError, engine.SceneError) as exc:
        raise ValueError(f"--preset {options.preset!r}: {exc}") from None
    brush = next((b for b in scene.brushes if b.mount == CHASER), None)
    if brush is None:
        raise ValueError(f"--preset {options.preset!r}: not a detumble scene (no brush "
                         f"mounted on {CHASER!r}; presets: {list(PRESETS)})")
    material = brush.material
    limit = options.stress_limit if options.stress_limit is not None \
        else STRESS_LIMITS.get(material)
    if limit is None:
        raise ValueError(f"--stress-limit: no default for bristle material {material!r}; "
                         f"give it in Pa")
    grid["stress_limit"] = float(limit)
    if options.sn_curve:
        from .fatigue import parse_sn_curve

        parse_sn_curve(options.sn_curve)  # ValueError naming what is wrong, before any run
    grid["law"] = None
    grid["laws"] = None      # without --law: each design's, fitted by _run_study
    if options.fidelity == "reduced" and options.law:
        from engine.model.reduced_law import load_law
        try:
            grid["law"] = load_law(options.law)
        except (OSError, ValueError) as exc:
            raise ValueError(f"--law {options.law!r}: {exc}") from None
    return grid


def _run_study(options: Options, out: Path) -> int:
    from .study_command import report_failures, run_study

    problem = None
    grid = None
    try:
        grid = _grid(options)
    except ValueError as exc:
        problem = str(exc)
    if problem is None and options.fidelity == "reduced" and not options.law:
        from engine.io.output_paths import OutputPathError, check_output_dir

        from .api import StudyInputError
        try:
            check_output_dir(out, "-o/--output")
        except OutputPathError as exc:
            raise StudyInputError(str(exc)) from None
        grid["laws"] = fit_laws(options, grid, out)
    code, outcomes = run_study(lambda: build_specs(options, grid), out, options,
                               desc="detumble runs", problem=problem)
    if code is not None:
        return code
    outcomes = _attach_spot_checks(outcomes)
    summary = write_outputs(out, outcomes, options.threshold)
    print(f"{'run':36s} {'w0 deg/s':>8s} {'detumbled':>10s} {'F target':>9s} "
          f"{'dv m/s':>8s} {'stress/limit':>12s} {'thrust sat':>10s} {'contact s':>9s}")
    for r in summary["runs"]:
        if r["status"] not in ("completed", "stopped"):
            continue
        td = f"{r['detumble_time']:.2f} s" if r["detumble_time"] is not None else "no"
        ratio = f"{r['stress_ratio']:.3f}" if r["stress_ratio"] is not None else "-"
        print(f"{r['run_id']:36s} {r['omega0'] / DEG:8.3g} {td:>10s} "
              f"{r['peak_target_force']:8.3g}N {r['delta_v']:8.3g} {ratio:>12s} "
              f"{_max_fraction(r.get('thrust_saturation')):>10s} "
              f"{r.get('time_in_contact', 0.0):9.3g}")
    for r in summary["runs"]:
        sc = r.get("spot_check")
        if sc:
            print(f"spot check {r['run_id']}, DEM / reduced, "
                  + _window_line(sc, "whole window"))
            after = sc.get("after_touch")
            print(f"spot check {r['run_id']}, DEM / reduced, "
                  + (_window_line(after, f"after the first touch ({after['first_contact']:.2f}"
                                         f" s + {after['settle_s']:g} s)")
                     if after else f"after the first touch: none ({sc['after_touch_why']})"))
        for w in r.get("warnings") or []:
            print(f"warning {r['run_id']}: {w}")
    print(f"Wrote {out}/detumble_summary.json, detumble_summary.csv, omega.png")
    return report_failures(outcomes)


def _attach_spot_checks(outcomes):
    """Fold each DEM spot-check run into the reduced run it checks (its summary gets
    ``spot_check``: :func:`spot_check` of their result files, the whole window and the part
    after the first touch); the spot runs themselves leave the list (a failed one stays, to
    be reported)."""
    by_id = {o.run_id: o for o in outcomes}
    keep = []
    for o in outcomes:
        of = o.params.get("spot_of")
        if of is None:
            keep.append(o)
            continue
        main = by_id.get(of)
        if not o.ok:
            keep.append(o)
            continue
        if main is not None and main.ok:
            check = spot_check(read_detumble(o.h5), read_detumble(main.h5),
                               float(main.params["spot_check_s"]))
            main.summary["spot_check"] = dict(check, dem_wall_s=o.summary.get("wall_s"))
    return keep


def _window_line(check: dict, what: str) -> str:
    """One spot-check window as a printed line: DEM / reduced and the relative error."""
    d, r, e = check["dem"], check["reduced"], check["relative_error"]
    fmt = lambda v: "-" if v is None else f"{100 * v:+.1f} %"  # noqa: E731
    return (f"{d['start_s']:.2f}-{d['end_s']:.2f} s {what}: delta-omega "
            f"{d['delta_omega']:.3g} / {r['delta_omega']:.3g} rad/s ({fmt(e['delta_omega'])}), "
            f"peak force {d['peak_force']:.3g} / {r['peak_force']:.3g} N "
            f"({fmt(e['peak_force'])}), mean torque {d['mean_torque']:.3g} / "
            f"{r['mean_torque']:.3g} N m ({fmt(e['mean_torque'])}), peak torque "
            f"({fmt(e['peak_torque'])})")


def _max_fraction(fractions) -> str:
    """The largest per-axis saturation fraction as a percentage ('-' without a record)."""
    return f"{100 * max(fractions):.0f} %" if fractions else "-"


run = api.study_run("detumble", _run_study)
