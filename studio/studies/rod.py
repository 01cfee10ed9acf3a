"""``brush-studio study rod``: bristle dynamics of seed 4.1 and the friction-damped frequency
response of seed fig. 4.6.

The steel rod of seed table 4.1 (E 200 GPa, nu 0.3, rho 7640 kg/m^3, L 0.4 m, d 1.42 mm) is
a horizontal cantilever. Three excitations (the presets ``rod_weight_release``,
``rod_tip_impulse``, ``rod_root_impulse``; their descriptions give every assumption):

* ``weight_release`` (seed 4.1.1, fig. 4.2): a 20 g weight's force on the tip, brought on
  slowly, then released; the rod vibrates freely for 4.5 s;
* ``tip_impulse`` (4.1.2, figs. 4.3-4.4): a triangular force pulse on the tip;
* ``root_impulse`` (4.1.3, fig. 4.5): the same pulse 0.0458 m from the root.

For each, the tip trajectory after the excitation and its power spectrum (one-sided PSD of
the vertical tip displacement, Blackman-Harris window), the spectral peaks in Hz and the
first three against the Euler-Bernoulli cantilever frequencies
``(beta_n L)^2 / (2 pi) sqrt(E I / (rho A L^4))``, ``beta_n L = 1.8751, 4.6941, 7.8548``.

``response`` (seed 4.1.4, fig. 4.6): the same rod lies on a flat plate under gravity, with
friction between them; a harmonic force ``F0 sin(2 pi f t)`` along the plate (horizontal,
transverse to the rod) acts on its tip. One run per drive frequency f; the steady-state tip
amplitude at f (the Fourier component over whole periods after a settling time) against f
is the frequency response. Friction takes energy out of every cycle of every mode, so the
response peaks near the first bending frequency and the higher-mode peaks are much lower.

Every simulation is one Dask task (``studio.studies.runner.run_many``); outputs in ``-o DIR``:
``peaks.json``; ``tip_<case>.csv`` (time, tip x, y, z); ``spectrum_<case>.csv`` (frequency,
PSD); ``frequency_response.csv``; ``rod.h5`` (all of those arrays); ``tip_trajectories.png``,
``spectra.png``, ``frequency_response.png``; ``outcomes.json``; ``runs/`` (one result file
per simulation).
"""
from __future__ import annotations

import copy
import csv
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from engine.beam_theory import rod_frequency
from engine.spectrum import (  # noqa: F401  (part of this study's API)
    match_modes, power_spectrum, spectral_peaks, uniform_part)

from . import api
from .api import ExecutionOptions, StudyResult

# seed table 4.1
ROD_LENGTH = 0.4
ROD_RADIUS = 1.42e-3 / 2
STEEL = {"youngs_modulus": 200e9, "poisson_ratio": 0.3, "density": 7640.0}
ROOT_IMPULSE_AT = 0.0458              # m from the root (seed 4.1.3)

CASES = ("weight_release", "tip_impulse", "root_impulse")
PRESETS = {c: f"rod_{c}" for c in CASES}
CASE_TITLES = {"weight_release": "weight release (seed fig. 4.2)",
               "tip_impulse": "impulse at the free end (fig. 4.4)",
               "root_impulse": "impulse at 0.0458 m from the root (fig. 4.5)"}

# plate material for the frequency response (PLA, as the presets' "pla")
PLA = {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1240.0}
DEFAULT_RESPONSE_FREQUENCIES = (2, 4, 5, 5.5, 6, 6.5, 7, 8, 10, 14, 20, 28, 34, 37, 39, 41,
                                43, 48, 60, 80, 100, 110, 115, 130)
DEFAULT_FRICTION_ANGLE_DEG = 17.0
DEFAULT_RESPONSE_FORCE = 0.005        # N, amplitude of the harmonic tip force (below the
#                                      friction threshold, so resonances stay bounded)


# ----------------------------------------------------------------------------- references
def cantilever_frequencies(length: float = ROD_LENGTH, radius: float = ROD_RADIUS,
                           youngs_modulus: float = STEEL["youngs_modulus"],
                           density: float = STEEL["density"], n_modes: int = 3) -> list[float]:
    """Euler-Bernoulli bending frequencies (Hz) of a uniform clamped-free rod:
    ``(beta_n L)^2 / (2 pi) sqrt(E I / (rho A L^4))`` (:mod:`engine.beam_theory`)."""
    return [rod_frequency(n, length, youngs_modulus, radius, density)
            for n in range(1, n_modes + 1)]


# ----------------------------------------------------------------------------- spectra
# power_spectrum (Blackman-Harris PSD), spectral_peaks, match_modes and uniform_part are the
# shared estimator of engine.spectrum, imported above


def drive_response(time: np.ndarray, signal: np.ndarray, frequency: float, start: float
                   ) -> dict:
    """Steady-state response to a drive at ``frequency`` (Hz) from ``start`` on: the
    amplitude and phase of the signal's Fourier component at that frequency over the
    largest whole number of periods (exact for a sinusoid sampled uniformly), and half the
    peak-to-peak swing over the same window."""
    time, signal = uniform_part(time, signal)
    period = 1.0 / frequency
    sel = time >= start
    t, y = time[sel], np.asarray(signal, float)[sel]
    if len(t) < 4:
        raise ValueError(f"no samples after t = {start:g} s")
    dt = float(t[1] - t[0])
    n_periods = int(math.floor((t[-1] - t[0] + dt) / period + 1e-9))
    if n_periods < 1:
        raise ValueError(f"less than one period of {frequency:g} Hz after t = {start:g} s")
    n = int(round(n_periods * period / dt))
    t, y = t[:n], y[:n]
    z = 2.0 / n * np.sum((y - y.mean()) * np.exp(-2j * math.pi * frequency * t))
    return {"amplitude": float(abs(z)), "phase": float(np.angle(z)),
            "half_peak_to_peak": float(0.5 * np.ptp(y)), "periods": n_periods,
            "mean": float(y.mean())}


# ----------------------------------------------------------------------------- scenes
def _preset_dict(name: str) -> dict:
    from studio import presets

    return json.loads(presets.load_preset(name).to_json())


def _excitation_end(scene: dict) -> float:
    """When the excitation of a rod preset is over (the last time of its load profile)."""
    return max(float(ld["profile"]["times"][-1]) for ld in scene["loads"])


def lever_loads(force: Sequence[float], profile: dict, n_nodes: int, at: float,
                length: float = ROD_LENGTH, brush: str = "brush") -> list[dict]:
    """A force at distance ``at`` from the root, shared between the two nodes around it by
    the lever rule (the statically equivalent pair: same resultant, same moment)."""
    h = length / (n_nodes - 1)
    s = at / h
    i = min(int(math.floor(s)), n_nodes - 2)
    w = s - i
    loads = []
    for node, share in ((i, 1.0 - w), (i + 1, w)):
        if share > 1e-12 and node > 0:  # the root node is clamped: its share goes to the base
            loads.append({"brush": brush, "node": node, "force": [share * f for f in force],
                          "profile": copy.deepcopy(profile)})
    return loads


def case_scene(case: str, *, n_nodes: Optional[int] = None,
               free_duration: Optional[float] = None,
               record_interval: Optional[float] = None) -> tuple[dict, float]:
    """The scene (dict) of one excitation case, from its preset, with optional overrides:
    nodes per rod, free-vibration time after the excitation, record interval. Returns
    ``(scene, analysis_start)``: the spectrum uses the frames from ``analysis_start`` on
    (after the release or the pulse)."""
    if case not in CASES:
        raise ValueError(f"case {case!r}: one of {CASES}")
    scene = _preset_dict(PRESETS[case])
    start = _excitation_end(scene)
    brush = scene["brushes"][0]
    if n_nodes is not None and n_nodes != brush["n_nodes"]:
        brush["n_nodes"] = int(n_nodes)
        if case == "root_impulse":
            ld = scene["loads"][0]
            scene["loads"] = lever_loads(ld["force"], ld["profile"], int(n_nodes),
                                         ROOT_IMPULSE_AT, brush["bristle_length"],
                                         brush["name"])
            scene["description"] += (f" Study override: {n_nodes} nodes; the pulse is shared "
                                     f"by the lever rule between the nodes around 0.0458 m.")
        else:
            scene["description"] += f" Study override: {n_nodes} nodes."
    if free_duration is not None:
        scene["run"]["duration"] = start + float(free_duration)
    if record_interval is not None:
        scene["run"]["record_interval"] = float(record_interval)
    scene["run"]["channels"] = ["nodes", "energy"]
    return scene, start


def response_scene(frequency: float, *, n_nodes: int = 16,
                   force: float = DEFAULT_RESPONSE_FORCE,
                   friction_angle: float = math.radians(DEFAULT_FRICTION_ANGLE_DEG),
                   settle_periods: float = 6.0, measure_periods: float = 6.0,
                   min_time: float = 0.5) -> tuple[dict, float]:
    """The seed fig. 4.6 set-up for one drive frequency: the rod along +x, clamped at the
    origin, lying on a fixed PLA plate (top face at z = -r, so the rod rests on it with
    zero initial overlap) under gravity, steel-PLA friction ``friction_angle``; a tip force
    ``force sin(2 pi f t)`` along +y (in the plate's plane, across the rod). Runs
    ``max(settle_periods / f, min_time)`` to settle, then ``max(measure_periods / f,
    min_time)`` to measure. Returns ``(scene, measure_start)``."""
    settle = max(settle_periods / frequency, min_time)
    measure = max(measure_periods / frequency, min_time)
    record = min(1e-3, 1.0 / (20.0 * frequency))
    r = ROD_RADIUS
    rod = _preset_dict(PRESETS["tip_impulse"])["brushes"][0]
    rod["n_nodes"] = int(n_nodes)
    scene = {
        "schema_version": 1,
        "name": f"rod_friction_response_{frequency:g}Hz",
        "description": (
            f"Seed 4.1.4, fig. 4.6: the steel rod of table 4.1 lying on a fixed PLA plate "
            f"under gravity (steel-PLA friction angle {math.degrees(friction_angle):.3g} deg, "
            f"an assumption: the seed gives none), driven at its tip by {force:g} N x "
            f"sin(2 pi {frequency:g} Hz t) along the plate, across the rod. Settle "
            f"{settle:.3g} s, then measure the steady tip amplitude over {measure:.3g} s."),
        "materials": {"steel": dict(STEEL), "pla": dict(PLA)},
        "contact_pairs": [{"materials": ["steel", "pla"], "friction_angle": friction_angle}],
        "brushes": [rod],
        "bodies": [{
            "name": "plate", "material": "pla",
            "shape": {"type": "box", "size": [ROD_LENGTH + 0.04, 0.12, 0.01]},
            "pose": {"position": [ROD_LENGTH / 2, 0.0, -r - 0.005]},
            "motion": {"type": "fixed"}}],
        "loads": [{"brush": rod["name"], "node": -1, "force": [0.0, force, 0.0],
                   "profile": {"frequency": float(frequency)}}],
        "environment": {"gravity": [0.0, 0.0, -9.81]},
        "run": {"duration": settle + measure, "record_interval": record,
                "channels": ["nodes", "energy", "contacts"]},
    }
    return scene, settle


# ----------------------------------------------------------------------------- tasks
def _run(scene, h5_path: Path):
    import engine

    system = engine.build(scene)
    result = engine.run(system, output=h5_path, cancel=api.cancel_requested)
    api.check_cancel()  # a cancel of the study running this in-process
    return system, result


def _tip(h5_path: Path) -> tuple[np.ndarray, np.ndarray]:
    import engine

    with engine.open_result(h5_path) as res:
        first = res.static("bristles/first_node")
        tip_node = int(first[1]) - 1
        time = np.asarray(res.time)
        tip = np.asarray(res.series("nodes/positions")[:, tip_node, :])
    return time, tip


def excitation_task(scene, h5_path: Path, params: dict) -> dict:
    """Dask task: run one excitation case, then its tip spectrum and peaks (JSON-able)."""
    system, result = _run(scene, h5_path)
    time, tip = _tip(h5_path)
    start = float(params["analysis_start"])
    sel = time >= start - 1e-12
    t, z = time[sel], tip[sel, 2]
    freq, psd = power_spectrum(t, z)
    duration = float(t[-1] - t[0])
    peaks = spectral_peaks(freq, psd, duration)
    brush = scene.brushes[0]
    E = scene.materials[brush.material].youngs_modulus
    rho = scene.materials[brush.material].density
    analytic = cantilever_frequencies(brush.bristle_length, brush.root_radius, E, rho)
    return {"status": result.status, "dt": system.dt, "wall_s": result.summary.get("wall_s"),
            "steps": result.summary.get("steps"), "n_nodes": brush.n_nodes,
            "analysis_start": start, "analysis_duration": duration,
            "peaks": peaks, "modes": match_modes(peaks, analytic),
            "tip_z_range": float(np.ptp(z))}


def response_task(scene, h5_path: Path, params: dict) -> dict:
    """Dask task: run one drive frequency, then the steady tip amplitude at it."""
    system, result = _run(scene, h5_path)
    time, tip = _tip(h5_path)
    resp = drive_response(time, tip[:, 1], float(params["frequency_hz"]),
                          float(params["measure_start"]))
    return dict(resp, status=result.status, dt=system.dt,
                wall_s=result.summary.get("wall_s"), steps=result.summary.get("steps"))


# ----------------------------------------------------------------------------- study
def build_specs(cases: Sequence[str], *, n_nodes: Optional[int], free_duration: Optional[float],
                record_interval: Optional[float], response_frequencies: Sequence[float],
                response_nodes: int, response_force: float, friction_angle: float,
                settle_periods: float, measure_periods: float, min_time: float):
    """The RunSpecs of the study: one per excitation case, one per drive frequency."""
    from .runner import RunSpec

    specs = []
    for case in cases:
        scene, start = case_scene(case, n_nodes=n_nodes, free_duration=free_duration,
                                  record_interval=record_interval)
        specs.append(RunSpec(run_id=case, scene=scene,
                             params={"case": case, "analysis_start": start},
                             task="studio.studies.rod:excitation_task"))
    for f in response_frequencies:
        scene, start = response_scene(f, n_nodes=response_nodes, force=response_force,
                                      friction_angle=friction_angle,
                                      settle_periods=settle_periods,
                                      measure_periods=measure_periods, min_time=min_time)
        specs.append(RunSpec(run_id=f"response_{f:g}Hz", scene=scene,
                             params={"case": "response", "frequency_hz": float(f),
                                     "measure_start": start, "force": response_force,
                                     "friction_angle": friction_angle},
                             task="studio.studies.rod:response_task"))
    return specs


def write_outputs(out_dir: Path, outcomes, analytic: Sequence[float]) -> dict:
    """peaks.json, CSVs, rod.h5 and PNGs from the finished runs; returns peaks.json's dict."""
    import h5py

    from .runner import jsonable, write_json_atomic

    out_dir = Path(out_dir)
    exc = [o for o in outcomes if o.params.get("case") in CASES and o.ok]
    resp = sorted((o for o in outcomes if o.params.get("case") == "response" and o.ok),
                  key=lambda o: o.params["frequency_hz"])
    peaks_doc = {
        "analytic_hz": list(analytic),
        "analytic": "Euler-Bernoulli cantilever (beta_n L)^2/(2 pi) sqrt(EI/(rho A L^4)), "
                    "beta_n L = 1.8751, 4.6941, 7.8548",
        "signal": "vertical tip displacement after the excitation; one-sided PSD, "
                  "Blackman-Harris window",
        "cases": {}}
    series = {}
    for o in exc:
        case = o.params["case"]
        time, tip = _tip(o.h5)
        start = float(o.params["analysis_start"])
        sel = time >= start - 1e-12
        freq, psd = power_spectrum(time[sel], tip[sel, 2])
        series[case] = (time, tip, freq, psd, start)
        peaks_doc["cases"][case] = {
            "title": CASE_TITLES[case], "peaks_hz": [p["frequency_hz"] for p in o.summary["peaks"]],
            "peaks": o.summary["peaks"], "modes": o.summary["modes"],
            "n_nodes": o.summary.get("n_nodes"), "dt": o.summary.get("dt"),
            "analysis_start": start, "analysis_duration": o.summary.get("analysis_duration"),
            "wall_s": o.wall_s}
        with (out_dir / f"tip_{case}.csv").open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["time", "tip_x", "tip_y", "tip_z"])
            w.writerows([f"{v:.9g}" for v in (t, *p)] for t, p in zip(time, tip))
        with (out_dir / f"spectrum_{case}.csv").open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["frequency_hz", "psd_m2_per_hz"])
            keep = freq <= 1000.0
            w.writerows([f"{a:.9g}", f"{b:.9g}"] for a, b in zip(freq[keep], psd[keep]))
    if resp:
        rows = [{"frequency_hz": o.params["frequency_hz"], "amplitude_m": o.summary["amplitude"],
                 "half_peak_to_peak_m": o.summary["half_peak_to_peak"],
                 "phase_rad": o.summary["phase"], "periods": o.summary["periods"],
                 "wall_s": o.wall_s} for o in resp]
        with (out_dir / "frequency_response.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        amp = np.array([r["amplitude_m"] for r in rows])
        fr = np.array([r["frequency_hz"] for r in rows])
        summary = {"force_n": resp[0].params["force"],
                   "friction_angle_deg": math.degrees(resp[0].params["friction_angle"]),
                   "frequencies_hz": fr.tolist(), "amplitude_m": amp.tolist()}
        # resonance peaks: local maxima of the swept amplitude standing out by 2 % of the
        # largest (an end counts when it is above its neighbour), and the largest below /
        # above midway between modes 1 and 2
        from scipy.signal import find_peaks

        idx, _ = find_peaks(np.r_[0.0, amp, 0.0], prominence=0.02 * float(amp.max()))
        is_max = np.zeros(len(amp), bool)
        is_max[idx - 1] = True
        summary["peaks_hz"] = fr[is_max].tolist()
        split = 0.5 * (analytic[0] + analytic[1])
        for name, sel in (("low", is_max & (fr < split)), ("high", is_max & (fr >= split))):
            if sel.any():
                i = int(np.flatnonzero(sel)[np.argmax(amp[sel])])
                summary[f"{name}_peak_hz"], summary[f"{name}_peak_m"] = float(fr[i]), float(amp[i])
            else:
                summary[f"{name}_peak_hz"] = summary[f"{name}_peak_m"] = None
        if summary["low_peak_m"] and summary["high_peak_m"] is not None:
            summary["high_to_low"] = summary["high_peak_m"] / summary["low_peak_m"]
        peaks_doc["frequency_response"] = summary
    write_json_atomic(out_dir / "peaks.json", peaks_doc)
    with h5py.File(out_dir / ".rod.h5.tmp", "w") as h:
        h.attrs["analytic_hz"] = np.asarray(analytic)
        h.attrs["peaks"] = json.dumps(jsonable(peaks_doc))
        for case, (time, tip, freq, psd, start) in series.items():
            g = h.create_group(case)
            g.create_dataset("time", data=time)
            g.create_dataset("tip", data=tip)
            g.create_dataset("frequency", data=freq)
            g.create_dataset("psd", data=psd)
            g.attrs["analysis_start"] = start
        if resp:
            g = h.create_group("frequency_response")
            g.create_dataset("frequency", data=fr)
            g.create_dataset("amplitude", data=amp)
    (out_dir / ".rod.h5.tmp").replace(out_dir / "rod.h5")
    _plot(out_dir, series, analytic, peaks_doc)
    return peaks_doc


def _plot(out_dir: Path, series: dict, analytic: Sequence[float], peaks_doc: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if series:
        n = len(series)
        fig, axes = plt.subplots(n, 1, figsize=(9, 2.6 * n), squeeze=False)
        for ax, (case, (time, tip, *_rest, start)) in zip(axes[:, 0], series.items()):
            ax.plot(time, tip[:, 2] * 1e3, lw=0.6)
            ax.axvline(start, color="0.5", ls=":", lw=1)
            ax.set_ylabel("tip z [mm]")
            ax.set_title(CASE_TITLES[case], fontsize=9)
            ax.grid(alpha=0.3)
        axes[-1, 0].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(out_dir / "tip_trajectories.png", dpi=120)
        plt.close(fig)
        fig, axes = plt.subplots(n, 1, figsize=(9, 2.8 * n), squeeze=False)
        for ax, (case, (_t, _tip, freq, psd, _s)) in zip(axes[:, 0], series.items()):
            keep = (freq > 0) & (freq <= 300)
            ax.semilogy(freq[keep], psd[keep], lw=0.8, label="DEM tip z")
            for k, fa in enumerate(analytic):
                ax.axvline(fa, color="tab:red", ls="--", lw=0.8,
                           label="Euler-Bernoulli" if k == 0 else None)
            for p in peaks_doc["cases"][case]["peaks"]:
                if p["frequency_hz"] <= 300:
                    ax.annotate(f"{p['frequency_hz']:.2f}", (p["frequency_hz"], p["psd"]),
                                fontsize=7, xytext=(3, 3), textcoords="offset points")
            ax.set_ylabel("PSD [m²/Hz]")
            ax.set_title(CASE_TITLES[case], fontsize=9)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8, loc="upper right")
        axes[-1, 0].set_xlabel("frequency [Hz]")
        fig.tight_layout()
        fig.savefig(out_dir / "spectra.png", dpi=120)
        plt.close(fig)
    fr = peaks_doc.get("frequency_response")
    if fr:
        fig, ax = plt.subplots(figsize=(8, 4.5))
        ax.plot(fr["frequencies_hz"], np.asarray(fr["amplitude_m"]) * 1e3, "o-", ms=4)
        for k, fa in enumerate(analytic):
            ax.axvline(fa, color="tab:red", ls="--", lw=0.8,
                       label="undamped cantilever modes" if k == 0 else None)
        ax.set_xscale("log")
        ax.set_xlabel("drive frequency [Hz]")
        ax.set_ylabel("steady tip amplitude [mm]")
        ax.set_title(f"Friction-damped frequency response (seed fig. 4.6): {fr['force_n']:g} N "
                     f"tip force, friction {fr['friction_angle_deg']:.3g}°", fontsize=9)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out_dir / "frequency_response.png", dpi=120)
        plt.close(fig)


# ----------------------------------------------------------------------------- CLI
def _floats(text: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"{text!r}: expected comma-separated numbers") from None
    return vals


@dataclass
class Options(ExecutionOptions):
    """``brush-studio study rod`` (``None``: the presets' value)."""

    cases: str = ",".join(CASES + ("response",))  # comma-separated subset
    preset: list = field(default_factory=list)     # rod presets (instead of cases)
    n_nodes: Optional[int] = None                  # nodes per rod, excitation cases
    free_duration: Optional[float] = None          # free vibration after the excitation, s
    record_interval: Optional[float] = None        # s
    frequencies: Optional[str] = None              # drive frequencies "F1,F2,...", Hz
    response_nodes: int = 16
    response_force: float = DEFAULT_RESPONSE_FORCE  # tip force amplitude, N
    friction_angle: float = DEFAULT_FRICTION_ANGLE_DEG  # rod-plate, degrees
    settle_periods: float = 6.0
    measure_periods: float = 6.0
    min_time: float = 0.5                          # least settling and measuring time, s


def add_parser(study_subparsers) -> None:
    from .preset_option import add_preset_option
    from .runner import add_common_options

    p = study_subparsers.add_parser(
        "rod", help="bristle dynamics (seed 4.1): tip spectra and the friction-damped "
                    "frequency response",
        description="The steel rod of seed 4.1: weight release, tip impulse and root impulse "
                    "(tip trajectory, power spectrum, peaks.json with the spectral peaks "
                    "against the Euler-Bernoulli frequencies), and the frequency response of "
                    "the rod lying on a plate with friction (seed fig. 4.6).")
    p.add_argument("--cases", default=",".join(CASES + ("response",)),
                   help="comma-separated subset of: " + ", ".join(CASES + ("response",)))
    add_preset_option(p, "rod", list(PRESETS.values()), "the excitation cases (--cases)")
    p.add_argument("--nodes", "--n-nodes", dest="n_nodes", type=int, default=None,
                   metavar="N", help="nodes per rod for the excitation cases (default: the presets', 36; "
                        "--n-nodes is the older spelling, deprecated)")
    p.add_argument("--free-duration", type=float, default=None, metavar="S",
                   help="free vibration recorded after the excitation (default: the "
                        "presets', 4.5 s)")
    p.add_argument("--record-interval", type=float, default=None, metavar="S",
                   help="record interval of the excitation cases (default: the presets')")
    p.add_argument("--frequencies", default=None, metavar="F1,F2,...",
                   help="drive frequencies of the response, Hz (default: 24 from 2 to 130)")
    p.add_argument("--response-nodes", type=int, default=16,
                   help="nodes per rod for the response runs (default 16)")
    p.add_argument("--response-force", type=float, default=DEFAULT_RESPONSE_FORCE,
                   metavar="N", help=f"tip force amplitude (default {DEFAULT_RESPONSE_FORCE})")
    p.add_argument("--friction-angle", type=float, default=DEFAULT_FRICTION_ANGLE_DEG,
                   metavar="DEG", help="rod-plate friction angle, degrees (default "
                                       f"{DEFAULT_FRICTION_ANGLE_DEG:g})")
    p.add_argument("--settle-periods", type=float, default=6.0,
                   help="drive periods to settle before measuring (default 6; at least "
                        "--min-time)")
    p.add_argument("--measure-periods", type=float, default=6.0,
                   help="drive periods measured (default 6; at least --min-time)")
    p.add_argument("--min-time", type=float, default=0.5, metavar="S",
                   help="least settling and measuring time, s (default 0.5)")
    add_common_options(p, default_output="study-rod")
    p.set_defaults(func=_cmd_rod)


def run(options: Options, out_dir, *, progress: Optional[api.ProgressFn] = None,
        cancel=None) -> StudyResult:
    """The rod study of ``options`` into ``out_dir``."""
    return api.run_body("rod", _run_study, options, out_dir, progress, cancel)


def _cmd_rod(args) -> int:
    return run(Options.from_args(args), args.output).exit_code


def _run_study(options: Options, out: Path) -> int:
    from .runner import check_common_options, failures_text, first_problem, run_study

    from .preset_option import PresetChoiceError, chosen

    problem = check_common_options(options)
    cases = [c.strip() for c in options.cases.split(",") if c.strip()]
    bad = [c for c in cases if c not in CASES + ("response",)]
    if bad:
        problem = f"--cases: unknown {bad}; choose from {CASES + ('response',)}"
    try:
        cases = chosen("rod", options.preset, {v: k for k, v in PRESETS.items()},
                       options.cases, Options.cases, "--cases") or cases
    except PresetChoiceError as exc:
        problem = problem or str(exc)
    try:
        freqs = (_floats(options.frequencies) if options.frequencies
                 else list(DEFAULT_RESPONSE_FREQUENCIES))
    except ValueError as exc:
        problem = f"--frequencies: {exc}"
        freqs = []
    checks = [(options.n_nodes is None or options.n_nodes >= 3, "--nodes must be >= 3"),
              (options.response_nodes >= 3, "--response-nodes must be >= 3"),
              (options.free_duration is None or options.free_duration > 0, "--free-duration must be > 0"),
              (options.record_interval is None or options.record_interval > 0,
               "--record-interval must be > 0"),
              (all(f > 0 for f in freqs), "--frequencies must be > 0"),
              (options.response_force > 0, "--response-force must be > 0"),
              (0 <= options.friction_angle < 90, "--friction-angle must be in [0, 90) degrees"),
              (options.settle_periods > 0 and options.measure_periods >= 1,
               "--settle-periods must be > 0 and --measure-periods >= 1"),
              (options.min_time >= 0, "--min-time must be >= 0")]
    problem = first_problem(problem, checks)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    code, outcomes = run_study(
        lambda: build_specs([c for c in cases if c in CASES], n_nodes=options.n_nodes,
                            free_duration=options.free_duration,
                            record_interval=options.record_interval,
                            response_frequencies=freqs if "response" in cases else [],
                            response_nodes=options.response_nodes,
                            response_force=options.response_force,
                            friction_angle=math.radians(options.friction_angle),
                            settle_periods=options.settle_periods,
                            measure_periods=options.measure_periods, min_time=options.min_time),
        out, options, desc="rod runs")
    if code is not None:
        return code
    analytic = cantilever_frequencies()
    doc = write_outputs(out, outcomes, analytic)
    print("Euler-Bernoulli: " + ", ".join(f"{f:.3f}" for f in analytic) + " Hz")
    for case, c in doc["cases"].items():
        modes = ", ".join(
            f"{m['measured_hz']:.3f} Hz ({m['rel_error']:+.2%})" if m["measured_hz"] else "-"
            for m in c["modes"])
        print(f"  {case:15s} modes 1-3: {modes}")
    fr = doc.get("frequency_response")
    if fr:
        peaks = ", ".join(f"{f:g}" for f in fr["peaks_hz"]) or "none"
        print(f"  friction response: largest {max(fr['amplitude_m']) * 1e3:.3g} mm; "
              f"response peaks at {peaks} Hz"
              + (f" (high/low peak ratio {fr['high_to_low']:.3f})" if fr.get("high_to_low")
                 is not None else " (no peak above the first mode's region)"))
    print(f"Wrote {out}/peaks.json, CSVs, rod.h5 and PNGs")
    failed = failures_text(outcomes)
    if failed:
        print("failed runs:\n" + failed, file=sys.stderr)
        return 1
    return 0
