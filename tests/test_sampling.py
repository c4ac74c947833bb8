"""Sampling designs: shapes, bounds, seeding, the power-of-two warning, Sobol' continuation."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from podkrig.offline.sampling import METHODS, is_power_of_two, latin_hypercube, sample, sobol, uniform


@pytest.mark.parametrize("method", METHODS)
def test_shape_bounds_repeatability(method):
    U = sample(method, 64, 3, seed=5)
    assert U.shape == (64, 3)
    assert np.all((U >= 0) & (U < 1))
    assert_array_equal(sample(method, 64, 3, seed=5), U)  # same seed, same design
    assert not np.array_equal(sample(method, 64, 3, seed=6), U)


def test_sobol_warns_when_not_power_of_two():
    with pytest.warns(UserWarning, match="Sobol' design of 10 points: balance properties need a power of two"):
        sobol(10, 2, seed=0)
    with pytest.warns(UserWarning, match="of 24 points"):
        sample("sobol", 8, 2, seed=0, skip=16)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sobol(16, 2, seed=0)
        sample("sobol", 16, 2, seed=0, skip=16)


def test_sobol_continues_the_same_sequence():
    """Samples n..n+k of an append are those of one long draw, bit for bit."""
    full = sobol(64, 4, seed=11)
    assert_array_equal(np.vstack([sobol(16, 4, seed=11), sobol(16, 4, seed=11, skip=16),
                                  sobol(32, 4, seed=11, skip=32)]), full)


def test_sobol_is_balanced():
    # every elementary interval of length 1/n holds one point per coordinate (a (0, m, 1)-net)
    U = sobol(32, 3, seed=2)
    for j in range(3):
        assert_array_equal(np.sort(np.floor(U[:, j] * 32)), np.arange(32))


def test_latin_hypercube_strata():
    U = latin_hypercube(20, 3, seed=4)
    for j in range(3):
        assert_array_equal(np.sort(np.floor(U[:, j] * 20)), np.arange(20))


def test_uniform_is_default_rng():
    assert_array_equal(uniform(5, 2, seed=3), np.random.default_rng(3).random((5, 2)))


def test_errors():
    with pytest.raises(ValueError, match=r"sampling method must be one of \('sobol', 'lhs', 'random'\); got 'halton'"):
        sample("halton", 4, 2, seed=0)
    with pytest.raises(ValueError, match="a 'lhs' design of 8 points cannot be extended"):
        sample("lhs", 4, 2, seed=0, skip=8)
    with pytest.raises(ValueError, match="n must be >= 1; got 0"):
        sobol(0, 2, seed=0)
    with pytest.raises(ValueError, match="seed must be >= 0; got -1"):
        uniform(4, 2, seed=-1)
    with pytest.raises(TypeError, match="seed must be an integer; got 1.5"):
        latin_hypercube(4, 2, seed=1.5)


def test_is_power_of_two():
    assert [k for k in range(20) if is_power_of_two(k)] == [1, 2, 4, 8, 16]
