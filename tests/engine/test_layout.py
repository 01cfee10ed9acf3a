"""engine.model.layout's stacked helpers equal, bit for bit, the one-row numpy calls they replace
in build (``R @ v``, ``np.dot``, ``quat_from_two_vectors``, the numba ``qmul``): built node
positions and orientations must not change when the layout is computed for all bristles at
once. A helper that summed in another order (``einsum``, ``V @ R.T``) differs in the last bit
on some rows, which ``np.array_equal`` sees."""
from __future__ import annotations

import numpy as np

from engine.model import layout


def _rows(n=2000, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-4, 1, (n, 1))


def test_stacked_products_equal_one_row_products():
    v = _rows()
    q = np.random.default_rng(1).normal(size=4)
    R = layout.quat_to_matrix(q / np.linalg.norm(q))
    assert np.array_equal(layout.rotate_rows(R, v), np.array([R @ r for r in v]))
    assert np.array_equal(layout.rotate_rows(R.T, v), np.array([R.T @ r for r in v]))
    u = _rows(seed=2)
    assert np.array_equal(layout.row_dots(v, u), np.array([np.dot(a, b) for a, b in zip(v, u)]))


def test_quats_z_to_equals_quat_from_two_vectors():
    d = _rows()
    d[:7] = [(0, 0, -2.0), (0, 0, 3.0), (1e-9, 0, -1.0), (0, 0, 0), (1, 0, 0), (0, -1, 0),
             (-2, 0, 1)]  # along and against z, none, and zeros of either sign in q
    q = layout.quats_z_to(d)
    z = np.array([0.0, 0.0, 1.0])
    for k in range(len(d)):
        if k == 3:  # a zero row: the identity (quat_from_two_vectors has no direction)
            assert q[k].tolist() == [1.0, 0.0, 0.0, 0.0]
            continue
        one = layout.quat_from_two_vectors(z, d[k])
        assert np.array_equal(q[k], one) and np.array_equal(np.signbit(q[k]), np.signbit(one)), k
        # and it does what it says: +z turned onto the row's direction
        turned = layout.quat_to_matrix(q[k]) @ z
        unit = d[k] / np.linalg.norm(d[k])
        # rounding only; a direction within 1e-12 (in cos) of -z is taken as -z exactly, an
        # angle of up to sqrt(2e-12) = 1.4e-6 rad
        tol = 1e-12 if unit[2] > -1 + 1e-12 else 1.5e-6
        assert np.abs(turned - unit).max() < tol, k


def test_quat_mul_equals_the_kernel():
    from engine.kernels.rotations import qmul

    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(500, 4)), rng.normal(size=(500, 4))
    assert np.array_equal(layout.quat_mul(a, b), np.array([qmul(*x, *y) for x, y in zip(a, b)]))
    assert np.array_equal(layout.quat_mul(a[0], b), np.array([qmul(*a[0], *y) for y in b]))
