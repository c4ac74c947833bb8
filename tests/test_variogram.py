"""The variogram helpers (:mod:`podkrig.surrogate.kriging.variogram`) in double precision for any
numeric input (issue 12: mutation testing)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig.surrogate.kriging import covariance, semivariogram


def test_integer_ranges_and_exponent_give_the_gaussian_correlation():
    """Ranges (1, 2) and β = 2 given as integers: s = (0.5/1)² + (1/2)² = 0.5, R = e^{-0.5} (rtol
    1e-14). Integer arrays cannot be raised to a negative integer power in numpy, so the ranges must
    be converted to float first."""
    assert_allclose(covariance([[0.0, 0.0]], [[0.5, 1.0]], [1, 2], 2), [[np.exp(-0.5)]], rtol=1e-14)
    assert_allclose(covariance([[0.0, 0.0]], [[0.5, 1.0]], [1, 2], 2, "power"), [[-0.5]], rtol=1e-14)


def test_single_precision_ranges_and_lags_are_used_in_double_precision():
    """float32 ranges (as read from a float32 store) and float32 lags give the float64 result of the
    same numbers (rtol 1e-14; single-precision arithmetic would differ by ~1e-8)."""
    X1 = np.array([[0.1, 0.7], [0.9, 0.2]])
    X2 = np.array([[0.35, 0.05], [0.6, 0.95], [0.0, 0.4]])
    ranges = np.array([0.3, 0.7], dtype=np.float32)
    assert_allclose(covariance(X1, X2, ranges, 1.3), covariance(X1, X2, ranges.astype(float), 1.3), rtol=1e-14)
    h = np.array([0.1, 0.3, 0.7, 2.9], dtype=np.float32)
    for variogram in ("exponential", "power"):
        g = semivariogram(h, variogram, beta=1.3, sill=3.0, range_=0.7)
        assert g.dtype == np.float64
        assert_allclose(g, semivariogram(h.astype(float), variogram, beta=1.3, sill=3.0, range_=0.7), rtol=1e-14)


def test_exponent_range_of_each_model():
    """The exponential family takes 0 < β ≤ 2 and the power model 0 < β < 2 (open at 0 for both): β = 1
    gives the linear power variogram γ(h) = s·|h|/a (hand values at h = 0.5, 2 with a = 2, s = 3) and
    the exponential one 1 − e^{−|h|/a}; β = 0 (a flat γ, no spatial structure) and a non-number are
    refused with the allowed range."""
    h = np.array([0.5, 2.0])
    assert_allclose(semivariogram(h, "power", beta=1.0, sill=3.0, range_=2.0), [0.75, 3.0], rtol=1e-14)
    assert_allclose(semivariogram(h, "exponential", beta=1, range_=2.0), 1 - np.exp(-h / 2.0), rtol=1e-14)
    assert_allclose(semivariogram(h, "power", beta=0.2), h**0.2, rtol=1e-14)
    with pytest.raises(ValueError, match=r"exponential family .*0 < beta <= 2.*got 0"):
        semivariogram(h, "exponential", beta=0.0)
    with pytest.raises(ValueError, match=r"power model .*0 < beta < 2.*got 0"):
        semivariogram(h, "power", beta=0.0)
    with pytest.raises(ValueError, match=r"beta .*\(0, 2\] or 'fit'; got 'steep'"):
        semivariogram(h, beta="steep")
    with pytest.raises(ValueError, match=r"beta .*\(0, 2\] or 'fit'; got None"):
        semivariogram(h, beta=None)
