"""Least-squares fit of the reduced brush law (engine.model.reduced_law) to sampled contact data,
with 95 % confidence intervals from the Jacobian (``brush-studio study reduce``).

``fit_normal`` takes samples (interference d, rate dd, normal force F_n) from presses and
impacts; ``fit_tangent`` takes (F_n, slip speed v, tangential force F_t) from slides. Both
call ``scipy.optimize.least_squares`` (trust-region reflective, bounded). The covariance is
``s^2 (J^T J)^-1`` with ``s^2`` the residual variance (sum of squares over n - m), the
interval ``+- t(0.975, n - m) sigma`` (Student's t): the usual linearised intervals, valid
where the residuals are independent and the model is locally linear in its parameters.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import optimize, stats

from engine.model.reduced_law import (NORMAL_PARAMS, TANGENT_PARAMS, friction_coefficient,
                                normal_force)


def _intervals(res, names, scale) -> dict:
    n, m = res.fun.size, res.x.size
    J = res.jac / scale  # the residuals were scaled; undo for the variance
    dof = max(n - m, 1)
    s2 = float(np.sum((res.fun / scale) ** 2)) / dof
    try:
        cov = np.linalg.inv(J.T @ J) * s2
    except np.linalg.LinAlgError:
        cov = np.linalg.pinv(J.T @ J) * s2
    sigma = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    t = float(stats.t.ppf(0.975, dof))
    return {k: {"value": float(v), "sigma": float(sd), "ci95": [float(v - t * sd),
                                                                float(v + t * sd)]}
            for k, v, sd in zip(names, res.x, sigma)}


def fit_normal(d, dd, fn, *, guess=None) -> dict:
    """Fit k, p, c, eta of F_n = k d^p (u(dd) + c dd) to samples with d > 0. Residuals are
    scaled by the largest |F_n| (N) so the tolerances are relative. Returns
    {name: {value, sigma, ci95}} and 'rms' (N)."""
    d, dd, fn = (np.asarray(a, float) for a in (d, dd, fn))
    keep = d > 0
    d, dd, fn = d[keep], dd[keep], fn[keep]
    if d.size < 8:
        raise ValueError(f"{d.size} samples in contact: too few to fit the normal law")
    scale = max(float(np.abs(fn).max()), 1e-12)
    if guess is None:
        # a log-log line through the loading samples gives k and p
        load = (dd >= 0) & (fn > 0)
        if load.sum() >= 2:
            p0, lk = np.polyfit(np.log(d[load]), np.log(fn[load]), 1)
            guess = (float(np.exp(lk)), float(np.clip(p0, 0.1, 3.0)), 0.1, 0.8)
        else:
            guess = (scale / d.max(), 1.0, 0.1, 0.8)
    # k in log form keeps it positive and well scaled
    x0 = np.array([np.log(guess[0]), guess[1], guess[2], guess[3]])

    def resid(x):
        return (normal_force(d, dd, np.exp(x[0]), x[1], x[2], x[3]) - fn) / scale

    res = optimize.least_squares(resid, x0, bounds=([-50, 0.05, -50.0, 0.05],
                                                    [80, 4.0, 50.0, 1.0]),
                                 x_scale="jac", method="trf")
    out = _intervals(res, ("log_k",) + NORMAL_PARAMS[1:], 1.0)
    lk = out.pop("log_k")
    out = {"k": {"value": float(np.exp(lk["value"])), "sigma": float(np.exp(lk["value"])
                                                                      * lk["sigma"]),
                 "ci95": [float(np.exp(lk["ci95"][0])), float(np.exp(lk["ci95"][1]))]},
           **out}
    out["rms"] = float(np.sqrt(np.mean((res.fun * scale) ** 2)))
    out["n_samples"] = int(d.size)
    return out


V_S_MIN = 1e-6        # m/s: the smallest v_s a fit may give
V_S_RESOLVED = 0.01   # the samples resolve v_s while tanh(v_min / v_s) < 1 - this


def fit_tangent(fn, v, ft, *, guess=(0.5, 0.0, 0.01)) -> dict:
    """Fit mu, q, v_s of F_t = mu (F_n / 1 N)^q tanh(v / v_s) F_n to samples with F_n > 0
    (v >= 0 the slip speed, F_t >= 0 the force's magnitude along the slip)."""
    fn, v, ft = (np.asarray(a, float) for a in (fn, v, ft))
    keep = fn > 1e-3 * fn.max()
    fn, v, ft = fn[keep], np.abs(v[keep]), ft[keep]
    if fn.size < 6:
        raise ValueError(f"{fn.size} sliding samples: too few to fit the tangential law")
    scale = max(float(np.abs(ft).max()), 1e-12)
    # below v_floor, tanh(v / v_s) > 0.99 at every sample: the samples cannot tell such a
    # v_s from v_floor (1 % of the force), and a smaller one only stiffens the law (its
    # slope mu F_n / v_s sets the time step: a search's design fitted 1e-6 m/s from slides
    # at 80-120 mm/s and ran at 83 us steps instead of 0.1 s)
    v_floor = max(V_S_MIN, float(v.min()) / math.atanh(1.0 - V_S_RESOLVED))
    x0 = np.array([guess[0], guess[1], np.log(max(guess[2], 1.5 * v_floor))])

    def resid(x):
        return (friction_coefficient(fn, v, x[0], x[1], np.exp(x[2])) * fn - ft) / scale

    res = optimize.least_squares(resid, x0, bounds=([0.0, -1.0, np.log(v_floor)],
                                                    [5.0, 1.0, np.log(10.0)]),
                                 x_scale="jac", method="trf")
    out = _intervals(res, ("mu", "q", "log_v_s"), 1.0)
    lv = out.pop("log_v_s")
    out["v_s"] = {"value": float(np.exp(lv["value"])),
                  "sigma": float(np.exp(lv["value"]) * lv["sigma"]),
                  "ci95": [float(np.exp(lv["ci95"][0])), float(np.exp(lv["ci95"][1]))]}
    out["rms"] = float(np.sqrt(np.mean((res.fun * scale) ** 2)))
    out["n_samples"] = int(fn.size)
    out["v_s_floor"] = v_floor
    if out["v_s"]["value"] <= v_floor * (1.0 + 1e-6):
        out["v_s_at_floor"] = (f"v_s at its floor {v_floor:.3g} m/s: the slides "
                               f"(slips from {float(v.min()):.3g} m/s) do not resolve a "
                               f"smaller one; slower slides would")
    return out
