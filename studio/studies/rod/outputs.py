"""The outputs of the rod study (seed 4.1) from its finished runs: ``peaks.json``;
``tip_<case>.csv`` (time, tip x, y, z); ``spectrum_<case>.csv`` (frequency, PSD);
``frequency_response.csv``; ``rod.h5`` (all of those arrays); ``tip_trajectories.png``,
``spectra.png``, ``frequency_response.png``."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Sequence

import numpy as np

from engine.jsonable import jsonable
from engine.analysis.spectrum import power_spectrum
from studio.studies.rod.runs import CASE_TITLES, CASES, tip_positions


def write_outputs(out_dir: Path, outcomes, analytic: Sequence[float]) -> dict:
    """peaks.json, CSVs, rod.h5 and PNGs from the finished runs; returns peaks.json's dict."""
    import h5py

    from studio.studies.run_files import write_json_atomic

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
        time, tip = tip_positions(o.h5)
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
