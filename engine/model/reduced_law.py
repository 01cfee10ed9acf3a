"""The reduced brush law (issue 25): a brush's contact with a surface as one compliant patch.

Fitted from DEM runs by ``brush-studio study reduce`` (studio/studies/reduce.py), stored as
JSON (:func:`save_law` / :func:`load_law`), used by the patch contact element
(``engine.kernels.patch``). The stated form, with the patch's interference ``d`` (m: how far
the undeformed tip plane is pushed into the surface, > 0 in contact), its rate ``dd`` (m/s,
> 0 loading) and the tip-plane sliding speed ``v`` (m/s):

* normal force (Hunt-Crossley-like, with a quasi-static loading/unloading ratio)::

      F_n = k d^p (u(dd) + c dd),   u(dd) = 1 - (1 - eta) (1 - tanh(dd / V_REG)) / 2

  clipped at 0 (the patch pulls nothing): ``k`` (N/m^p), ``p``, ``c`` (s/m: rate
  damping), ``eta`` (unloading over loading force at zero rate, in (0, 1]);
* tangential force opposing the slip, regularised stick-slip::

      F_t = mu_eff(F_n, v) F_n,   mu_eff = mu (F_n / 1 N)^q tanh(v / v_s)

  ``mu``, ``q`` (load dependence), ``v_s`` (m/s: the slip speed at which the tips let go);
* torsional moment about the patch normal, from the patch's size (not fitted): the same
  friction spread uniformly over the footprint ``a x b``, ``M = mu_eff(F_n, w r_t) F_n r_t``
  with the torsional radius ``r_t`` = the mean distance of the rectangle's points from its
  centre (:func:`torsion_radius`), opposing the spin ``w`` about the normal.

The law file also holds the fitted ranges of ``d``, ``dd`` and ``v`` (a use outside them is
reported by the element's run summary), the parameters' 95 % confidence intervals and the
held-out validation errors.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

LAW_VERSION = 1
V_REG = 1e-3                 # m/s: width of the loading/unloading switch
NORMAL_PARAMS = ("k", "p", "c", "eta")
TANGENT_PARAMS = ("mu", "q", "v_s")
PARAMS = NORMAL_PARAMS + TANGENT_PARAMS
F_REF = 1.0                  # N: the load unit of mu_eff's power law


def loading_factor(dd, eta):
    """u(dd): 1 while loading, eta while unloading, smooth across |dd| ~ V_REG."""
    return 1.0 - (1.0 - eta) * 0.5 * (1.0 - np.tanh(np.asarray(dd, float) / V_REG))


def normal_force(d, dd, k, p, c, eta):
    """F_n (N) of the stated law; 0 where d <= 0."""
    d = np.asarray(d, float)
    dd = np.asarray(dd, float)
    dp = np.where(d > 0, np.abs(d), 0.0) ** p
    return np.maximum(k * dp * (loading_factor(dd, eta) + c * dd), 0.0)


def friction_coefficient(fn, v, mu, q, v_s):
    """mu_eff(F_n, v) of the stated law (v >= 0)."""
    fn = np.maximum(np.asarray(fn, float), 1e-12)
    return mu * (fn / F_REF) ** q * np.tanh(np.asarray(v, float) / v_s)


def torsion_radius(a: float, b: float, n: int = 200) -> float:
    """Mean distance from the centre of the points of an a x b rectangle (m), by the
    midpoint rule on an n x n grid (converged to < 1e-4 relative at n = 200)."""
    x = (np.arange(n) + 0.5) / n - 0.5
    X, Y = np.meshgrid(x * a, x * b)
    return float(np.mean(np.hypot(X, Y)))


def save_law(path, law: dict) -> None:
    """Write a law dict (``parameters``, ``ranges``, ``patch``...) as JSON."""
    law = dict(law, law_version=LAW_VERSION)
    check_law(law)
    Path(path).write_text(json.dumps(law, indent=2, sort_keys=True))


def check_law(law: dict) -> dict:
    """ValueError naming what is wrong with a law dict; the dict if it is usable."""
    if law.get("law_version") != LAW_VERSION:
        raise ValueError(f"law_version {law.get('law_version')!r}: this Brush Studio reads "
                         f"{LAW_VERSION}")
    par = law.get("parameters", {})
    missing = [k for k in PARAMS if k not in par]
    if missing:
        raise ValueError(f"law parameters missing: {missing}")
    for k in PARAMS:
        if not math.isfinite(float(par[k])):
            raise ValueError(f"law parameter {k} = {par[k]!r}: not finite")
    if par["k"] <= 0 or par["p"] <= 0 or not 0 < par["eta"] <= 1 or par["v_s"] <= 0 \
            or par["mu"] < 0:
        raise ValueError("law parameters out of their domain: k, p, v_s > 0, mu >= 0, "
                         "0 < eta <= 1")
    rng = law.get("ranges", {})
    for key in ("interference", "rate", "slip_speed"):
        lo_hi = rng.get(key)
        if lo_hi is None or len(lo_hi) != 2 or not lo_hi[0] <= lo_hi[1]:
            raise ValueError(f"law ranges.{key}: expected [low, high]")
    patch = law.get("patch", {})
    if len(patch.get("size", ())) != 2 or min(patch["size"]) <= 0:
        raise ValueError("law patch.size: expected [a, b] > 0 (m)")
    return law


def load_law(path) -> dict:
    """A law file's dict, checked (:func:`check_law`)."""
    return check_law(json.loads(Path(path).read_text()))


def parameter_vector(law: dict) -> np.ndarray:
    """The parameters in the element's order (PARAMS), then the torsional radius."""
    par = law["parameters"]
    a, b = law["patch"]["size"]
    return np.array([float(par[k]) for k in PARAMS] + [torsion_radius(a, b)])
