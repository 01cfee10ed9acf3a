"""Euler-Bernoulli beam theory in closed form: the one source of the cantilever's bending
frequencies for the engine (the quasi-static check spacing), the studies (rod, convergence),
the benchmarks and the verification tests.

Pure ``math``: no numba, no scipy, nothing from the rest of the engine, so that importing it
costs nothing and a test using it as an oracle compares the engine with textbook physics,
not with the engine's own model. All quantities are SI.
"""
from __future__ import annotations

import math

import numpy as np


# ------------------------------------------------------------------------------ sections
def circle_area(radius: float) -> float:
    """Area of a solid circular section, pi r^2."""
    return math.pi * radius ** 2


def circle_second_moment(radius: float) -> float:
    """Second moment of area of a solid circular section about a diameter, pi r^4 / 4."""
    return math.pi * radius ** 4 / 4.0


# ------------------------------------------------------------------------------ frequencies
def _clamped_free_root(n: int) -> float:
    """The n-th root (n >= 1) of cos(b) cosh(b) = -1, by Newton's method on the equivalent,
    well-scaled g(b) = cos(b) + 1 / cosh(b) (cosh > 0: same roots; g stays O(1) where
    cos cosh grows like e^b). The root lies within 0.31 of (n - 1/2) pi and tends to it."""
    b = 1.9 if n == 1 else (n - 0.5) * math.pi
    for _ in range(60):
        g = math.cos(b) + 1.0 / math.cosh(b)
        dg = -math.sin(b) - math.tanh(b) / math.cosh(b)
        step = g / dg
        b -= step
        if abs(step) < 4e-16 * b:
            break
    return b


def cantilever_beta_l(n_modes: int = 3) -> np.ndarray:
    """The first ``n_modes`` roots beta_n L of the clamped-free frequency equation
    cos(beta L) cosh(beta L) = -1: 1.8751, 4.6941, 7.8548, 10.9955, ..."""
    if n_modes < 1:
        raise ValueError(f"n_modes must be at least 1, not {n_modes}")
    return np.array([_clamped_free_root(n) for n in range(1, n_modes + 1)])


def cantilever_frequencies(length: float, youngs_modulus: float, second_moment: float,
                           density: float, area: float, n_modes: int = 3) -> np.ndarray:
    """Bending natural frequencies (Hz) of a uniform Euler-Bernoulli cantilever,
    f_n = (beta_n L)^2 / (2 pi) sqrt(E I / (rho A L^4))."""
    bl = cantilever_beta_l(n_modes)
    return bl ** 2 / (2.0 * math.pi) * math.sqrt(
        youngs_modulus * second_moment / (density * area * length ** 4))


def rod_frequency(mode: int, length: float, youngs_modulus: float, radius: float,
                  density: float) -> float:
    """Bending frequency (Hz) of mode ``mode`` (1-based) of a uniform cantilever of solid
    circular section of ``radius``."""
    return float(cantilever_frequencies(length, youngs_modulus, circle_second_moment(radius),
                                        density, circle_area(radius), mode)[mode - 1])
