"""Bristle dynamics of seed 4.1 and the friction-damped frequency
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

This module holds the rod, its references, scenes and run tasks
(:func:`excitation_task`, :func:`response_task`); the study is :mod:`studio.studies.rod.study`.
"""
from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from engine.analysis.beam_theory import rod_frequency
from engine.analysis.spectrum import (  # noqa: F401  (part of this study's API)
    match_modes, power_spectrum, spectral_peaks, uniform_part)

from studio.studies import api

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
    ``(beta_n L)^2 / (2 pi) sqrt(E I / (rho A L^4))`` (:mod:`engine.analysis.beam_theory`)."""
    return [rod_frequency(n, length, youngs_modulus, radius, density)
            for n in range(1, n_modes + 1)]


# ----------------------------------------------------------------------------- spectra
# power_spectrum (Blackman-Harris PSD), spectral_peaks, match_modes and uniform_part are the
# shared estimator of engine.analysis.spectrum, imported above


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


def tip_positions(h5_path: Path) -> tuple[np.ndarray, np.ndarray]:
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
    time, tip = tip_positions(h5_path)
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
    time, tip = tip_positions(h5_path)
    resp = drive_response(time, tip[:, 1], float(params["frequency_hz"]),
                          float(params["measure_start"]))
    return dict(resp, status=result.status, dt=system.dt,
                wall_s=result.summary.get("wall_s"), steps=result.summary.get("steps"))
