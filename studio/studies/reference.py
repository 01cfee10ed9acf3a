"""Closed-form references the studies share: Euler-Bernoulli bending frequencies of a
uniform clamped-free rod of circular section. One source for the rod study, the convergence
study's analytic reference and the benchmarks (the engine's tests keep their own,
independent oracle in ``tests/engine/analytic.py``)."""
from __future__ import annotations

import math

import numpy as np


def cantilever_beta_l(n_modes: int = 3) -> np.ndarray:
    """Roots beta_n L of the clamped-free frequency equation cos(bL) cosh(bL) = -1."""
    from scipy.optimize import brentq

    roots = []
    for n in range(1, n_modes + 1):
        centre = (n - 0.5) * math.pi
        roots.append(brentq(lambda b: math.cos(b) * math.cosh(b) + 1.0,
                            centre - 1.3 if n == 1 else centre - 0.35, centre + 0.35,
                            xtol=1e-14))
    return np.array(roots)


def cantilever_frequency(mode: int, length: float, youngs_modulus: float, radius: float,
                         density: float) -> float:
    """Euler-Bernoulli bending frequency (Hz) of mode ``mode`` (1-based) of a uniform
    cantilever of circular section: (beta_n L)^2 / (2 pi) sqrt(E I / (rho A L^4))."""
    bl = cantilever_beta_l(mode)[mode - 1]
    second_moment = math.pi * radius ** 4 / 4.0
    area = math.pi * radius ** 2
    return float(bl) ** 2 / (2.0 * math.pi) * math.sqrt(
        youngs_modulus * second_moment / (density * area * length ** 4))


def cantilever_frequencies(length: float, radius: float, youngs_modulus: float,
                           density: float, n_modes: int = 3) -> list[float]:
    """The first ``n_modes`` Euler-Bernoulli bending frequencies (Hz) of a uniform
    clamped-free rod of circular section."""
    return [cantilever_frequency(n, length, youngs_modulus, radius, density)
            for n in range(1, n_modes + 1)]
