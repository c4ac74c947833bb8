"""Sampling designs: shapes, bounds, seeding, the power-of-two warning, Sobol' continuation."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from scipy.spatial.distance import pdist

from podkrig._qmc import scrambled_sobol
from podkrig.ga.operators import initial_population
from podkrig.offline.sampling import (
    METHODS,
    is_power_of_two,
    latin_hypercube,
    sample,
    sobol,
    uniform,
)


@pytest.mark.parametrize("method", METHODS)
def test_shape_bounds_repeatability(method):
    U = sample(method, 64, 3, seed=5)
    assert U.shape == (64, 3)
    assert np.all((U >= 0) & (U < 1))
    assert_array_equal(sample(method, 64, 3, seed=5), U)  # same seed, same design
    assert not np.array_equal(sample(method, 64, 3, seed=6), U)


def test_sobol_warns_when_not_power_of_two():
    with pytest.warns(UserWarning, match="of 10 points.*power of two"):
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
    with pytest.raises(ValueError, match=r"\('sobol', 'lhs', 'lhs-ese', 'random'\); got 'halton'"):
        sample("halton", 4, 2, seed=0)
    with pytest.raises(ValueError, match="'lhs' design of 8 points"):
        sample("lhs", 4, 2, seed=0, skip=8)
    with pytest.raises(ValueError, match="n must be >= 1.*got 0"):
        sobol(0, 2, seed=0)
    with pytest.raises(ValueError, match="seed must be >= 0.*got -1"):
        uniform(4, 2, seed=-1)
    with pytest.raises(TypeError, match="seed must be an integer.*got 1.5"):
        latin_hypercube(4, 2, seed=1.5)


def test_is_power_of_two():
    assert [k for k in range(20) if is_power_of_two(k)] == [1, 2, 4, 8, 16]


def test_lhs_ese_is_a_latin_hypercube_that_fills_space_better():
    """SMT's ESE keeps one point per stratum and lowers the phi_p criterion it optimises
    (p = 10, Jin et al. 2005) below that of every plain Latin hypercube of seeds 0-4."""
    def phi_p(U, p=10):
        return float(np.sum(pdist(U) ** -p) ** (1 / p))

    U = sample("lhs-ese", 20, 3, seed=1)
    for j in range(3):
        assert_array_equal(np.sort(np.floor(U[:, j] * 20)), np.arange(20))
    assert phi_p(U) < min(phi_p(latin_hypercube(20, 3, seed=s)) for s in range(5))
    with pytest.raises(ValueError, match="'lhs-ese' design of 8 points"):
        sample("lhs-ese", 4, 2, seed=0, skip=8)


def test_one_sobol_sequence_on_every_scipy_version():
    """The designs, the GA's initial population and the integer-seeded screens draw the same points
    on every scipy that pyproject allows (values recorded with scipy 1.17; the test also runs in a
    scipy 1.12 environment, where qmc.Sobol takes ``seed=`` instead of ``rng=``)."""
    assert_array_equal(sobol(4, 2, seed=0), [[0.40994958858937025, 0.9641202185302973],
                                             [0.7219116594642401, 0.10752477683126926],
                                             [0.9048664066940546, 0.5285515235736966],
                                             [0.21716429200023413, 0.41444470454007387]])
    assert_array_equal(scrambled_sobol(4, 2, 5), [[0.6313518090173602, 0.2368540344759822],
                                                  [0.26858777832239866, 0.7618419313803315],
                                                  [0.24232526123523712, 0.4772229678928852],
                                                  [0.8571077436208725, 0.5215023290365934]])
    # the GA's Sobol' population is the design of the same Generator seed (first 6 of 8 points)
    assert_array_equal(initial_population(6, 3, method="sobol", rng=np.random.default_rng(3)),
                       sobol(8, 3, seed=3)[:6])
