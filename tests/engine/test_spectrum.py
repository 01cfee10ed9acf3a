"""engine.analysis.spectrum, the one spectral-peak estimator, on closed forms: sums of sinusoids of
known frequencies and amplitudes."""
from __future__ import annotations

import math

import numpy as np
import pytest

from engine.analysis import spectrum


def _tones(t: np.ndarray, tones, rng) -> np.ndarray:
    return sum(a * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi)) for f, a in tones)


@pytest.mark.parametrize("duration, dt", [(2.0, 1e-3), (4.0, 1e-3), (1.0, 2e-4)])
def test_peaks_are_the_tones(duration, dt):
    # a strong first mode and two 100x / 1000x weaker higher ones, like a plucked cantilever
    rng = np.random.default_rng(7)
    t = np.arange(0.0, duration, dt)
    for _ in range(10):
        freqs = [rng.uniform(5, 9), rng.uniform(30, 50), rng.uniform(100, 130)]
        x = _tones(t, zip(freqs, (1.0, 1e-2, 1e-3)), rng)
        freq, psd = spectrum.power_spectrum(t, x)
        peaks = spectrum.spectral_peaks(freq, psd, duration)
        # exactly the three tones: no window side lobe counts as a peak (the convergence
        # study's former estimator, Hann with peaks 3 bins apart, reported the first tone's
        # side lobes at +-3.4 bins, -41 dB, as the second and third "modes" here)
        assert len(peaks) == 3
        # a hundredth of a bin (1 / duration): the parabola puts a lone tone within 1e-5 bins;
        # a weak tone on the -92 dB skirts of the 1000x stronger one moves by up to ~3e-3 bins
        got = [p["frequency_hz"] for p in peaks]
        np.testing.assert_allclose(got, freqs, rtol=0, atol=1e-2 / duration)
        # the shortcut the convergence study and the tests use gives the same numbers
        np.testing.assert_allclose(spectrum.peak_frequencies(t, x, 3), got, rtol=1e-12)


def test_psd_integrates_to_the_mean_square():
    # Parseval: a tone of amplitude A carries A^2 / 2; 2e-3: the window's power normalisation
    # is exact up to the incomplete periods under it (8e-4 here); a lost one-sided
    # factor 2, or a PSD per bin instead of per Hz, misses by 100 % or more
    t = np.arange(0.0, 2.0, 1e-3)
    amplitude = 0.3
    freq, psd = spectrum.power_spectrum(t, amplitude * np.sin(2 * math.pi * 7.3 * t) + 0.1)
    assert psd.sum() * (freq[1] - freq[0]) == pytest.approx(amplitude ** 2 / 2, rel=2e-3)


def test_a_maximum_on_a_larger_peaks_flank_is_no_peak():
    # two tones 2 Hz apart at 50 Hz (8 bins over 4 s: resolved by the window), within the
    # +-20 % of the larger one: reported as one peak, the larger; a plain local-maximum
    # search would report both
    t = np.arange(0.0, 4.0, 1e-3)
    x = np.sin(2 * math.pi * 50.0 * t) + 0.5 * np.sin(2 * math.pi * 52.0 * t + 1.0)
    freq, psd = spectrum.power_spectrum(t, x)
    peaks = spectrum.spectral_peaks(freq, psd, 4.0)
    assert [round(p["frequency_hz"], 1) for p in peaks] == [50.0]
    # without the relative width both are there (the window resolves them)
    both = spectrum.spectral_peaks(freq, psd, 4.0, relative_width=0.0)
    assert [round(p["frequency_hz"]) for p in both] == [50, 52]


def test_a_tone_inside_the_zero_frequency_lobe_is_no_peak():
    # 0.75 Hz over 4 s: 3 bins, inside the +-4-bin lobe of the removed mean
    t = np.arange(0.0, 4.0, 1e-3)
    x = np.sin(2 * math.pi * 0.75 * t) + 1e-2 * np.sin(2 * math.pi * 20.0 * t)
    freq, psd = spectrum.power_spectrum(t, x)
    assert [round(p["frequency_hz"]) for p in spectrum.spectral_peaks(freq, psd, 4.0)] == [20]


def test_the_off_grid_last_frame_is_dropped():
    # a run records its last frame at the end time, off the regular grid: appending one must
    # not change the estimate (1e-12: the same samples go into the same FFT)
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 2.0, 1e-3)
    x = _tones(t, [(6.3, 1.0), (39.8, 1e-2)], rng)
    ref = spectrum.peak_frequencies(t, x, 2)
    t_end = np.r_[t, t[-1] + 0.37e-3]
    got = spectrum.peak_frequencies(t_end, np.r_[x, 0.5], 2)
    np.testing.assert_allclose(got, ref, rtol=1e-12)


def test_asking_for_more_peaks_than_there_are_is_an_error():
    t = np.arange(0.0, 2.0, 1e-3)
    with pytest.raises(ValueError, match="1 peak"):
        spectrum.peak_frequencies(t, np.sin(2 * math.pi * 10.0 * t), 2)
    # a tone of fewer than 4 periods in the record is inside the zero-frequency lobe: the
    # message says how low a peak may lie (4 / 2 s = 2 Hz)
    with pytest.raises(ValueError, match="above 2 Hz"):
        spectrum.peak_frequencies(t, np.sin(2 * math.pi * 1.5 * t), 1)
    with pytest.raises(ValueError, match="too few"):
        spectrum.power_spectrum(t[:10], t[:10])


def test_modes_match_the_nearest_largest_peak():
    peaks = [{"frequency_hz": 6.2, "psd": 1.0}, {"frequency_hz": 38.0, "psd": 1e-3},
             {"frequency_hz": 41.0, "psd": 1e-2}]
    modes = spectrum.match_modes(peaks, [6.0, 40.0, 110.0])
    assert [m["measured_hz"] for m in modes] == [6.2, 41.0, None]
    assert modes[1]["rel_error"] == pytest.approx(41.0 / 40.0 - 1.0, rel=1e-12)
