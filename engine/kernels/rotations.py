"""Quaternion and small-vector kernels (numba, allocation-free, scalars in and out); their
numpy versions for build time and the studio are in :mod:`engine.model.layout`.

Quaternions are ``[w, x, y, z]`` and rotate local coordinates into world coordinates.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def qmul(aw, ax, ay, az, bw, bx, by, bz):
    """Hamilton product a*b."""
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@njit(cache=True, inline="always")
def qrot(w, x, y, z, vx, vy, vz):
    """Rotate vector v by unit quaternion q (q v q*)."""
    # t = 2 q_vec x v ; v' = v + w t + q_vec x t
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


@njit(cache=True, inline="always")
def qrot_inv(w, x, y, z, vx, vy, vz):
    """Rotate vector v by the inverse of unit quaternion q (q* v q)."""
    return qrot(w, -x, -y, -z, vx, vy, vz)


@njit(cache=True, inline="always")
def qexp(rx, ry, rz):
    """Unit quaternion of the rotation vector r (axis * angle)."""
    a2 = rx * rx + ry * ry + rz * rz
    if a2 < 1e-16:
        # Taylor series, exact to machine precision for |r| < 1e-8
        return (1.0 - a2 / 8.0, 0.5 * rx, 0.5 * ry, 0.5 * rz)
    a = math.sqrt(a2)
    s = math.sin(0.5 * a) / a
    return (math.cos(0.5 * a), s * rx, s * ry, s * rz)


@njit(cache=True, inline="always")
def qlog(w, x, y, z):
    """Rotation vector (axis * angle, angle in [0, pi]) of unit quaternion q."""
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    f = qlog_factor(math.sqrt(x * x + y * y + z * z), w)
    return (f * x, f * y, f * z)


@njit(cache=True, inline="always")
def qlog_factor(vn, w):
    """f of log(q) = f q_vec for a unit quaternion with w >= 0 and |q_vec| = vn:
    2 atan2(vn, w) / vn, and 2 below vn = 1e-12 (the limit, without dividing by ~0)."""
    if vn < 1e-12:
        return 2.0
    return 2.0 * math.atan2(vn, w) / vn


@njit(cache=True, inline="always")
def qnormalize(w, x, y, z):
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return (w / n, x / n, y / n, z / n)


@njit(cache=True, inline="always")
def cross(ax, ay, az, bx, by, bz):
    return (ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx)


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternion [w,x,y,z] (w >= 0) of a proper rotation matrix (numpy)."""
    if np.array_equal(m, np.eye(3)):  # the common case, without importing scipy.spatial
        return np.array([1.0, 0.0, 0.0, 0.0])
    from scipy.spatial.transform import Rotation
    x, y, z, w = Rotation.from_matrix(m).as_quat()
    q = np.array([w, x, y, z])
    return q if w >= 0 else -q
