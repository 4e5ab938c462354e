"""Anderson acceleration of a fixed-point iteration.

The numpy and CasADi updates agree, and on a linear contraction it finds
the fixed point in far fewer steps.
"""

import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError

from ocp.mpc.acceleration import anderson_function, anderson_numpy


@pytest.mark.parametrize("filled", [0, 1, 2, 4])
def test_casadi_update_equals_numpy_update(filled):
    rng = np.random.default_rng(filled)
    n, m = 9, 3
    g, z = rng.normal(size=n), rng.normal(size=n)
    Gh, Fh = rng.normal(size=(n, m + 1)), rng.normal(size=(n, m + 1))
    valid = np.r_[np.zeros(m + 1 - filled), np.ones(filled)][-(m + 1):]
    a = anderson_numpy(g, z, Gh, Fh, valid)
    b = [np.array(v) for v in anderson_function(n, m)(g, z, Gh, Fh, valid)]
    for x, y in zip(a, b):
        np.testing.assert_allclose(np.reshape(y, np.shape(x)), x,
                                   atol=1e-12, rtol=0)
    if filled == 0:      # no history: the plain step
        np.testing.assert_array_equal(a[0], g)


def _iterate(M, b, memory, tol=1e-10, max_iter=500):
    n = b.size
    z = np.zeros(n)
    Gh, Fh, v = np.zeros((n, memory + 1)), np.zeros((n, memory + 1)), \
        np.zeros(memory + 1)
    for i in range(1, max_iter + 1):
        g = M @ z + b
        if np.abs(g - z).max() < tol:
            return g, i
        if memory:
            z, Gh, Fh, v = anderson_numpy(g, z, Gh, Fh, v)
        else:
            z = g
    return z, max_iter


def test_anderson_finds_a_linear_maps_fixed_point_faster():
    rng = np.random.default_rng(7)
    n = 30
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    # a contraction with a slow mode (0.9) and a few faster ones
    eig = np.r_[0.9, 0.8, 0.5, 0.3 * rng.random(n - 3)]
    M, b = Q @ np.diag(eig) @ Q.T, rng.normal(size=n)
    z_star = np.linalg.solve(np.eye(n) - M, b)
    z0, n0 = _iterate(M, b, 0)
    z3, n3 = _iterate(M, b, 3)
    assert n0 > 200 and n3 < 0.25 * n0
    np.testing.assert_allclose(z0, z_star, atol=1e-8)
    np.testing.assert_allclose(z3, z_star, atol=1e-8)


def test_memory_below_one_is_refused():
    with pytest.raises(InvalidValueError, match="memory"):
        anderson_function(3, 0)
