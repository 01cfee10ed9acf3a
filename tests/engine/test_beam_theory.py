"""engine.analysis.beam_theory: the clamped-free roots against the characteristic equation solved
independently (scipy's brentq on cos(b) cosh(b) + 1 with sign-change brackets), and the
frequencies against the textbook numbers of the seed's steel rod."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from engine.analysis import beam_theory


def _brentq_roots(n_modes: int) -> list[float]:
    # f = cos cosh + 1 changes sign between consecutive multiples of pi (plus the first
    # interval (pi/2, pi)): cos is -1 at odd multiples, +1 at even ones, and cosh >= 1
    f = lambda b: math.cos(b) * math.cosh(b) + 1.0  # noqa: E731
    edges = [0.5 * math.pi] + [n * math.pi for n in range(1, n_modes + 1)]
    return [brentq(f, a, b, xtol=1e-15, rtol=1e-15) for a, b in zip(edges, edges[1:])]


def test_roots_solve_the_clamped_free_equation():
    n_modes = 8
    roots = beam_theory.cantilever_beta_l(n_modes)
    # 1e-13 relative: both are converged to round-off (Newton to 4e-16, brentq to 1e-15);
    # a wrong bracket or a Newton step jumping to the neighbouring root errs by ~pi
    np.testing.assert_allclose(roots, _brentq_roots(n_modes), rtol=1e-13)


def test_roots_are_the_textbook_values():
    # Blevins, Formulas for natural frequency and mode shape, table 8-1 (four decimals):
    # a wrong equation (cos cosh = +1, the free-free / clamped-clamped one: 4.7300, ...)
    # fails here
    np.testing.assert_allclose(beam_theory.cantilever_beta_l(4),
                               [1.8751, 4.6941, 7.8548, 10.9955], atol=5e-5)
    # and they tend to (n - 1/2) pi (the 1/cosh term vanishes): 1e-9 at n = 12
    assert beam_theory.cantilever_beta_l(12)[-1] == pytest.approx(11.5 * math.pi, abs=1e-9)


def test_no_modes_is_an_error():
    with pytest.raises(ValueError, match="n_modes"):
        beam_theory.cantilever_beta_l(0)


def test_seed_rod_frequencies():
    # seed table 4.1 steel rod (L 0.4 m, d 1.42 mm, E 200 GPa, rho 7640): the brief's
    # 6.353, 39.81, 111.47 Hz to its four significant figures (1e-3); a factor 2 pi
    # (rad/s for Hz) or a missing square on beta L fails by far more
    r = 1.42e-3 / 2
    f = beam_theory.cantilever_frequencies(0.4, 200e9, beam_theory.circle_second_moment(r),
                                           7640.0, beam_theory.circle_area(r), 3)
    np.testing.assert_allclose(f, [6.353, 39.81, 111.47], rtol=1e-3)
    # the circular-section shorthand is the same formula (round-off only)
    for mode in (1, 2, 3):
        assert beam_theory.rod_frequency(mode, 0.4, 200e9, r, 7640.0) == pytest.approx(
            f[mode - 1], rel=1e-14)


def test_frequency_scales_as_the_dimensional_analysis_says():
    # f ~ sqrt(E / rho) r / L^2 for a circular rod (I / A = r^2 / 4): doubling r doubles f,
    # doubling L quarters it, quadrupling E doubles it (round-off only)
    base = beam_theory.rod_frequency(1, 0.1, 1e9, 1e-3, 1000.0)
    assert beam_theory.rod_frequency(1, 0.1, 1e9, 2e-3, 1000.0) == pytest.approx(2 * base,
                                                                                 rel=1e-13)
    assert beam_theory.rod_frequency(1, 0.2, 1e9, 1e-3, 1000.0) == pytest.approx(base / 4,
                                                                                 rel=1e-13)
    assert beam_theory.rod_frequency(1, 0.1, 4e9, 1e-3, 1000.0) == pytest.approx(2 * base,
                                                                                 rel=1e-13)
