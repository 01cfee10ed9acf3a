"""Closed-form and independently computed references for the physics verification tests.

Nothing here uses the engine's model: every function is the textbook solution of a continuum
problem (Euler-Bernoulli beam, inextensible elastica), evaluated with scipy, so that a test
compares the engine with physics rather than with itself. The sections and the cantilever's
bending frequencies come from :mod:`engine.analysis.beam_theory`, the one source the studies and
benchmarks use too: pure ``math`` that imports nothing else of the engine (its roots are
tested against brentq in ``test_beam_theory.py``). All quantities are SI.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.integrate import quad, solve_bvp
from scipy.optimize import brentq

# sections and Euler-Bernoulli frequencies: the shared closed forms, re-exported
from engine.analysis.beam_theory import (  # noqa: F401
    cantilever_beta_l, cantilever_frequencies, circle_area, circle_second_moment)


# ------------------------------------------------------------------------------ statics
def cantilever_tip_deflection(force: float, length: float, youngs_modulus: float,
                              second_moment: float) -> float:
    """Tip deflection of a uniform Euler-Bernoulli cantilever under a transverse tip force,
    ``P L^3 / (3 E I)`` (small deflection, no shear)."""
    return force * length ** 3 / (3.0 * youngs_modulus * second_moment)


def tapered_cantilever_tip_deflection(force: float, length: float, youngs_modulus: float,
                                      second_moment: Callable[[float], float]) -> float:
    """Tip deflection of a non-uniform Euler-Bernoulli cantilever (clamped at x = 0) under a
    transverse tip force P, by the unit-load (Castigliano) integral

        delta = P * integral_0^L (L - x)^2 / (E I(x)) dx,

    with ``second_moment(x)`` the section's I at distance x from the clamp, evaluated by
    adaptive Gauss-Kronrod quadrature (scipy ``quad``) to ~1e-12 relative."""
    value, abserr = quad(lambda x: (length - x) ** 2 / (youngs_modulus * second_moment(x)),
                         0.0, length, epsabs=0.0, epsrel=1e-12, limit=200)
    assert abserr <= 1e-10 * abs(value), "quadrature of the tapered-beam integral failed"
    return force * value


def conical_second_moment(root_radius: float, tip_radius: float,
                          length: float) -> Callable[[float], float]:
    """I(x) of a solid cone frustum whose radius tapers linearly from ``root_radius`` at
    x = 0 to ``tip_radius`` at x = ``length``."""

    def second_moment(x: float) -> float:
        return circle_second_moment(root_radius + (tip_radius - root_radius) * x / length)

    return second_moment


# ------------------------------------------------------------------------------ elastica
def elastica_tip(load_parameter: float, tol: float = 1e-10) -> tuple[float, float, float]:
    """Large deflection of an inextensible, unshearable cantilever (clamped horizontally at
    the origin) under a dead vertical tip load: the elastica.

    With arc length s in [0, 1] (units of L), theta the slope angle measured downwards and
    ``load_parameter`` alpha = P L^2 / (E I), the bending moment M(s) = P (x_tip - x(s)) gives

        theta'' = -alpha cos(theta),  theta(0) = 0,  theta'(1) = 0,
        x' = cos(theta), y' = sin(theta),  x(0) = y(0) = 0,

    solved as one boundary-value problem with scipy ``solve_bvp`` (the linear solution
    theta = alpha (s - s^2/2) as the first guess, with continuation in alpha for large loads).

    Returns ``(x_tip / L, y_tip / L, theta_tip)``: the tip's horizontal position and its
    downward deflection, both relative to L, and the tip slope (rad).
    """
    s = np.linspace(0.0, 1.0, 201)
    guess = None
    # continuation: the Newton iteration of solve_bvp converges from the linear guess only
    # for moderate alpha, so large loads are reached in steps
    steps = max(1, int(math.ceil(load_parameter / 2.0)))
    for a in np.linspace(load_parameter / steps, load_parameter, steps):
        if guess is None:
            th = a * (s - 0.5 * s ** 2)
            guess = np.vstack([th, a * (1.0 - s), np.cumsum(np.cos(th)) / len(s),
                               np.cumsum(np.sin(th)) / len(s)])

        def rhs(_s, y, a=a):
            return np.vstack([y[1], -a * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])])

        def bc(ya, yb):
            return np.array([ya[0], yb[1], ya[2], ya[3]])

        sol = solve_bvp(rhs, bc, s, guess, tol=tol, max_nodes=100_000)
        if not sol.success:
            raise RuntimeError(f"elastica BVP did not converge at alpha = {a}: {sol.message}")
        s = sol.x
        guess = sol.y
    return float(sol.y[2, -1]), float(sol.y[3, -1]), float(sol.y[0, -1])


def elastica_tip_quadrature(load_parameter: float) -> tuple[float, float, float]:
    """The same elastica as :func:`elastica_tip`, by its first integral instead of a BVP
    solver (an independent check of the BVP reference).

    Multiplying theta'' = -alpha cos(theta) by theta' and integrating with theta'(1) = 0 gives
    theta'^2 = 2 alpha (sin(theta_0) - sin(theta)), theta_0 the tip slope. Then

        sqrt(alpha) = int_0^theta0 d(theta) / sqrt(2 (sin theta0 - sin theta)),
        x_tip / L = sqrt(2 sin(theta0) / alpha),
        y_tip / L = int_0^theta0 sin(theta) d(theta) / sqrt(2 alpha (sin theta0 - sin theta)).

    theta_0 is found with brentq; the 1/sqrt endpoint singularity is integrated exactly with
    quad's algebraic weight. Valid for tip slopes below ~1.5 rad (alpha up to ~10)."""

    def smooth(theta, theta0):
        # sqrt((theta0 - theta) / (sin theta0 - sin theta)), finite at theta -> theta0:
        # sin a - sin b = 2 cos((a + b)/2) sin((a - b)/2), so the ratio is h / sin(h) / cos(m)
        h = 0.5 * (theta0 - theta)
        m = 0.5 * (theta0 + theta)
        sinc = 1.0 if h < 1e-8 else h / math.sin(h)
        return math.sqrt(sinc / math.cos(m))

    def length_integral(theta0, numerator):
        val, _ = quad(lambda t: numerator(t) * smooth(t, theta0) / math.sqrt(2.0), 0.0, theta0,
                      weight="alg", wvar=(0.0, -0.5), epsabs=0.0, epsrel=1e-13, limit=200)
        return val

    root_alpha = math.sqrt(load_parameter)
    # the length integral diverges (logarithmically) as theta0 -> pi/2; 1e-3 short of it, it
    # equals sqrt(alpha) for alpha ~ 20, beyond the range of use
    theta0 = brentq(lambda t0: length_integral(t0, lambda t: 1.0) - root_alpha,
                    1e-9, math.pi / 2 - 1e-3, xtol=1e-15, rtol=1e-15)
    x_tip = math.sqrt(2.0 * math.sin(theta0) / load_parameter)
    y_tip = length_integral(theta0, math.sin) / root_alpha
    return x_tip, y_tip, theta0


# ------------------------------------------------------------------------------ contacts
def restitution_damping_ratio(restitution: float) -> float:
    """Damping ratio zeta of a linear spring-dashpot whose free (attractive-allowed) contact
    rebounds with coefficient e: e = exp(-zeta pi / sqrt(1 - zeta^2)) solved for zeta."""
    le = math.log(restitution)
    return -le / math.sqrt(math.pi ** 2 + le * le)


def nonattractive_dashpot_restitution(damping_ratio: float) -> float:
    """Rebound speed ratio of a mass hitting a wall through a linear spring-dashpot whose
    force is never attractive, F = max(0, k x + c x'), c = 2 zeta sqrt(k m).

    In units m = k = 1 and unit impact speed, x'' = -(x + 2 zeta x') from x = 0, x' = 1
    until the force k x + c x' falls to zero (after which it stays clipped at zero and the
    mass leaves at constant speed), integrated with scipy ``solve_ivp`` (DOP853, rtol 1e-12).
    Returns |x'| at that instant."""
    from scipy.integrate import solve_ivp

    def force(_t, y):
        return y[0] + 2.0 * damping_ratio * y[1]

    force.terminal = True
    force.direction = -1
    sol = solve_ivp(lambda _t, y: [y[1], -(y[0] + 2.0 * damping_ratio * y[1])],
                    (0.0, 4.0 * math.pi), [0.0, 1.0], method="DOP853", events=force,
                    rtol=1e-12, atol=1e-14)
    assert sol.t_events[0].size == 1, "the contact did not end"
    return float(-sol.y_events[0][0][1])


# ------------------------------------------------------------------------------ hinge
def hinge_spin_down(omega0: float, k1: float, k2: float, t: np.ndarray) -> np.ndarray:
    """Closed-form solution of d(omega)/dt = -k1 omega - k2 sign(omega) from omega0 > 0:
    omega = (omega0 + k2/k1) exp(-k1 t) - k2/k1 until it reaches zero at
    t* = ln(1 + k1 omega0 / k2) / k1, and zero after (k1 -> 0: omega0 - k2 t)."""
    t = np.asarray(t, float)
    if k1 > 0.0:
        a = k2 / k1
        w = (omega0 + a) * np.exp(-k1 * t) - a
    else:
        w = omega0 - k2 * t
    return np.maximum(w, 0.0)


# ------------------------------------------------------------------------------ orbits
def clohessy_wiltshire(n: float, t: float, r0, v0) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form solution of the Clohessy-Wiltshire equations (Hill frame: x radial,
    y along-track, z orbit normal; x'' = 3n^2 x + 2n y', y'' = -2n x', z'' = -n^2 z), as in
    Vallado, *Fundamentals of Astrodynamics*, eq. 6-66: position and velocity at t."""
    x0, y0, z0 = r0
    u0, w0, s0 = v0  # x', y', z' at 0
    c, s = math.cos(n * t), math.sin(n * t)
    x = (4 - 3 * c) * x0 + s / n * u0 + 2 / n * (1 - c) * w0
    y = 6 * (s - n * t) * x0 + y0 - 2 / n * (1 - c) * u0 + (4 * s - 3 * n * t) / n * w0
    z = c * z0 + s / n * s0
    u = 3 * n * s * x0 + c * u0 + 2 * s * w0
    w = -6 * n * (1 - c) * x0 - 2 * s * u0 + (4 * c - 3) * w0
    sz = -n * s * z0 + c * s0
    return np.array([x, y, z]), np.array([u, w, sz])
