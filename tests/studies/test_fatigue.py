"""Bristle fatigue (studio.studies.fatigue): rainflow counts and Miner's damage against
closed forms on synthetic stress histories."""
from __future__ import annotations

import math

import numpy as np
import pytest

from studio.studies.fatigue import (bond_bristles, bristle_series, fatigue, parse_sn_curve,
                                    rainflow_cycles)


def test_a_cosine_history_is_n_cycles_of_its_amplitude():
    # 7 periods of A cos(2 pi t) + mean, from peak to peak: by definition 7 cycles of
    # amplitude A (ASTM E1049 counts them as 14 half cycles); exact up to the sampling of
    # the peaks, which the grid hits exactly here
    A, n = 2.0e6, 7
    t = np.linspace(0.0, n, n * 200 + 1)
    amp, count = rainflow_cycles(A * np.cos(2 * np.pi * t) + 3.0e6)
    assert count.sum() == pytest.approx(n, abs=1e-12)
    assert np.allclose(amp, A, rtol=1e-12)


def test_miner_damage_is_the_basquin_closed_form():
    # the curve through (5 MPa, 1e4) and (2 MPa, 1e6): N = 1e4 (S / 5 MPa)^-m with
    # m = ln(100) / ln(2.5); 7 cycles at 3 MPa give D = 7 / N(3 MPa)
    curve = parse_sn_curve("2:1e6, 5:1e4")
    m = math.log(100) / math.log(2.5)
    n_3 = 1e4 * (3.0 / 5.0) ** -m
    n_fail, extrapolated = curve.cycles_to_failure([3.0e6, 1.0e6, 10.0e6, 0.0])
    assert n_fail[0] == pytest.approx(n_3, rel=1e-12)
    assert list(extrapolated) == [False, True, True, False]
    assert n_fail[3] == math.inf       # no stress, no damage
    t = np.linspace(0.0, 7, 7 * 200 + 1)
    history = 1.5e6 * (1 - np.cos(2 * np.pi * t))        # 0 .. 3 MPa: amplitude 1.5 MPa
    f = fatigue(history[:, None], curve)
    n_15 = 1e4 * (1.5 / 5.0) ** -m                         # extrapolated along 2..5 MPa
    assert f["fatigue_damage_max"] == pytest.approx(7 / n_15, rel=1e-9)
    assert f["runs_to_failure"] == pytest.approx(n_15 / 7, rel=1e-9)
    assert f["sn_extrapolated"] is True
    assert f["fatigue_cycles_max"] == pytest.approx(7.0)


def test_ripples_below_the_floor_are_not_counted_but_damage_everything():
    # one big cycle and 50 ripples of 0.1 % of its amplitude: cycles counts the big one
    # (two half cycles here), the damage adds the ripples' (tiny) share
    t = np.linspace(0.0, 1.0, 5001)
    big = 2e6 * np.sin(np.pi * t) ** 2
    history = big + 2e3 * np.sin(2 * np.pi * 50 * t)
    f = fatigue(history[:, None], parse_sn_curve("5:1e4,1:1e7"))
    assert f["fatigue_cycles_max"] == pytest.approx(1.0)
    only_big = fatigue(big[:, None], parse_sn_curve("5:1e4,1:1e7"))
    assert f["fatigue_damage_max"] > only_big["fatigue_damage_max"]


def test_bristle_series_takes_each_bristles_largest_bond():
    first_node = np.array([0, 4, 8])            # 3 bristles of 4 nodes: 3 bonds each
    bond_first = np.array([0, 1, 2, 4, 5, 6, 8, 9, 10])
    owner = bond_bristles(bond_first, first_node)
    assert list(owner) == [0, 0, 0, 1, 1, 1, 2, 2, 2]
    stress = np.arange(18, dtype=float).reshape(2, 9)
    assert bristle_series(stress, owner, 3).tolist() == [[2, 5, 8], [11, 14, 17]]


@pytest.mark.parametrize("text, what", [
    ("5:1e4", "at least two"), ("5-1e4,2:1e6", "not STRESS_MPA:CYCLES"),
    ("5:1e6,2:1e4", "lower stress"), ("0:1e4,2:1e6", "> 0 MPa"), ("5:1e4,5:1e6", "lower")])
def test_bad_sn_curves_are_refused_with_the_reason(text, what):
    with pytest.raises(ValueError, match=what):
        parse_sn_curve(text)
