"""Spectral peaks of a recorded signal: the one estimator of the rod study, the convergence
study's ``spectral_peak`` quantity, the verification tests and the benchmarks.

The estimate, in three steps:

1. :func:`power_spectrum`: the one-sided power spectral density (unit^2/Hz) of the leading
   uniformly sampled part of the record, mean removed, under a 4-term Blackman-Harris window
   (side lobes below -92 dB, so a weak higher mode is not hidden under the leakage of the
   first; main lobe +-4 bins of the record), zero-padded to ``padding`` times its length;
2. :func:`spectral_peaks`: local maxima that are the largest sample within
   ``+-max(relative_width f, 4 / duration)`` (the main lobe's half width, so that a side lobe
   never counts, nor a second maximum on a lobe's flank), above ``4 / duration`` (out of the
   zero-frequency lobe) and above ``floor`` times the largest;
3. each peak's frequency refined by a parabola through the log-PSD at its bin and the two
   neighbours (for a pure tone within ~1e-5 Hz over a 2 s record: ``tests/engine/
   test_spectrum.py``).

numpy only (scipy's window on first use); nothing of the engine's model.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

#: half width of the Blackman-Harris main lobe, in bins of the (unpadded) record: 4 / duration
LOBE_BINS = 4.0


def uniform_part(time: np.ndarray, *signals: np.ndarray):
    """The leading uniformly sampled part of a recording (a run records its last frame at
    the end time, usually off the regular grid): ``(time, *signals)`` cut there."""
    time = np.asarray(time, float)
    steps = np.diff(time)
    if steps.size == 0:
        return (time, *signals)
    dt = float(np.median(steps))
    off = np.flatnonzero(np.abs(steps - dt) > 1e-6 * dt)
    n = int(off[0]) + 1 if off.size else len(time)
    return (time[:n], *(np.asarray(s)[:n] for s in signals))


def power_spectrum(time: np.ndarray, signal: np.ndarray, padding: int = 8
                   ) -> tuple[np.ndarray, np.ndarray]:
    """``(frequency, psd)``: one-sided power spectral density (unit^2/Hz) of the uniformly
    sampled part of ``signal``, mean removed, 4-term Blackman-Harris window, zero-padded to
    the power of two at or above ``padding`` times its length."""
    from scipy.signal.windows import blackmanharris

    time, signal = uniform_part(time, signal)
    if len(time) < 16:
        raise ValueError(f"{len(time)} samples: too few for a spectrum")
    dt = float(time[1] - time[0])
    window = blackmanharris(len(signal), sym=False)
    x = (np.asarray(signal, float) - np.mean(signal)) * window
    n_fft = 1 << int(math.ceil(math.log2(padding * len(x))))
    spec = np.fft.rfft(x, n_fft)
    psd = (np.abs(spec) ** 2) * 2.0 * dt / float(np.sum(window ** 2))
    psd[0] *= 0.5
    return np.fft.rfftfreq(n_fft, dt), psd


def spectral_peaks(freq: np.ndarray, psd: np.ndarray, duration: float, *,
                   max_peaks: int = 8, floor: float = 1e-9, relative_width: float = 0.2
                   ) -> list[dict]:
    """Peaks of a PSD from :func:`power_spectrum` of a record ``duration`` long (see the
    module's docstring): the ``max_peaks`` largest, sorted by frequency,
    ``[{"frequency_hz", "psd"}]``."""
    from scipy.signal import find_peaks

    freq = np.asarray(freq, float)
    psd = np.asarray(psd, float)
    df = float(freq[1] - freq[0])
    top = float(psd.max()) if psd.size else 0.0
    if top <= 0:
        return []
    lobe = LOBE_BINS / duration
    idx, _ = find_peaks(psd)
    out = []
    for i in idx:
        f = freq[i]
        half = max(relative_width * f, lobe)
        if f < lobe or psd[i] < floor * top:
            continue
        sel = (freq >= f - half) & (freq <= f + half)
        if psd[i] < psd[sel].max():
            continue
        a, b, c = np.log(np.maximum(psd[i - 1:i + 2], 1e-300))
        den = a - 2.0 * b + c
        shift = 0.5 * (a - c) / den if den != 0 else 0.0
        out.append({"frequency_hz": float(f + shift * df), "psd": float(psd[i])})
    out.sort(key=lambda p: -p["psd"])
    return sorted(out[:max_peaks], key=lambda p: p["frequency_hz"])


def peak_frequencies(time: np.ndarray, signal: np.ndarray, n_peaks: int) -> np.ndarray:
    """Frequencies (Hz, ascending) of the ``n_peaks`` largest spectral peaks of a recorded
    signal (:func:`power_spectrum` then :func:`spectral_peaks`); ValueError when the
    spectrum has fewer."""
    time, signal = uniform_part(time, signal)
    freq, psd = power_spectrum(time, signal)
    duration = len(time) * float(time[1] - time[0])
    peaks = spectral_peaks(freq, psd, duration, max_peaks=n_peaks)
    if len(peaks) < n_peaks:
        raise ValueError(
            f"the spectrum has {len(peaks)} peak(s), {n_peaks} needed (a peak must lie above "
            f"{LOBE_BINS / duration:.3g} Hz, {LOBE_BINS:g} periods in the {duration:.3g} s "
            "record, and stand out of the larger peaks' skirts: record longer)")
    return np.array([p["frequency_hz"] for p in peaks])


def match_modes(peaks: Sequence[dict], analytic: Sequence[float], window: float = 0.2
                ) -> list[dict]:
    """For each analytic frequency, the largest peak within ``window`` (relative) of it:
    ``[{"mode", "analytic_hz", "measured_hz", "rel_error", "psd"}]`` (measured None when
    no peak is there)."""
    out = []
    for n, fa in enumerate(analytic, start=1):
        near = [p for p in peaks if abs(p["frequency_hz"] - fa) <= window * fa]
        best = max(near, key=lambda p: p["psd"]) if near else None
        out.append({"mode": n, "analytic_hz": fa,
                    "measured_hz": best["frequency_hz"] if best else None,
                    "rel_error": (best["frequency_hz"] / fa - 1.0) if best else None,
                    "psd": best["psd"] if best else None})
    return out
