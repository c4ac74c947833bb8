"""POD-kriging surrogate on the coarse diagonal compression test: held-out accuracy, coverage,
error split, persistence, and the extrapolation guard."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig.io.surrogate_file import load_surrogate, save_surrogate
from podkrig.surrogate.kriging import OrdinaryKriging
from podkrig.parameters import ParameterSpace
from podkrig.surrogate.pod import POD
from podkrig.offline.sampling import sobol, uniform
from podkrig.surrogate.podkriging import PODKriging
from podkrig.surrogate.validation import held_out_errors, loo_errors, relative_errors

BOUNDS = {"kN_bj": (10, 1000, "log"), "kV_bj": (4, 400, "log"), "r_hj": (0.1, 1.0), "E_b": (5000, 20000)}


@pytest.fixture(scope="module")
def snapshots(coarse_diagonal):
    """64 Sobol' training runs and 200 random held-out runs, 4 free parameters (~2 s of FE)."""
    sc = coarse_diagonal
    space = ParameterSpace.from_scenario(sc, BOUNDS)
    X, Xh = space.from_unit(sobol(64, 4, seed=0)), space.from_unit(uniform(200, 4, seed=1))

    def run(X):
        return np.stack([sc.run(space.as_params(x)).readings for x in X])

    return space, X, run(X), Xh, run(Xh)


@pytest.fixture(scope="module")
def surrogate(snapshots):
    space, X, Y, _, _ = snapshots
    # per-mode exponents, as the accuracy and coverage figures below were measured; the default
    # "fit-shared" gives coverage ≈ 0.87 here (BENCHMARKS.md), too close to the bound below
    return PODKriging(kriging=OrdinaryKriging(beta="fit"), space=space).fit(X, Y)


def test_held_out_accuracy_and_coverage(surrogate, snapshots):
    _, _, _, Xh, Yh = snapshots
    rep = held_out_errors(surrogate, Xh, Yh)
    s = rep.summary()
    # measured (n = 64, beta fitted, 6 modes): median 1.18e-2, p95 4.6e-2, max 0.10; the bounds
    # leave ~1.7x margin for BLAS / optimiser differences across machines
    assert s["rel_error"]["median"] < 0.02
    assert s["rel_error"]["p95"] < 0.08
    assert s["n_modes"] == 6  # readings are linear in the load: 4 loads x 6 sensors have rank 6
    # measured coverage 0.90: the ML variance is slightly optimistic at n = 64
    assert abs(s["coverage_2sigma"] - 0.95) < 0.08
    # error split: the truncation residual is orthogonal to the POD space (Pythagoras)
    assert_allclose(rep.rel_error**2, rep.pod_error**2 + rep.interp_error**2, rtol=1e-9, atol=1e-20)
    assert s["loo_error"]["median"] < 0.03  # measured 1.45e-2


def test_loo_errors_match_refits(snapshots):
    space, X, Y, _, _ = snapshots
    X, Y = X[:20], Y[:20]
    sur = PODKriging(pod=POD(n_modes=3), kriging=OrdinaryKriging(beta=1.5), space=space).fit(X, Y)
    kr = sur.kriging_
    brute = []
    for k in range(len(X)):
        fixed = OrdinaryKriging(beta=1.5, ranges=kr.ranges_, optimizer=None)
        fixed.fit(np.delete(sur.U_, k, 0), np.delete(sur.pod_.transform(Y.reshape(20, -1)), k, 0))
        pred = sur.pod_.inverse_transform(fixed.predict(sur.U_[k : k + 1]))
        brute.append(relative_errors(pred, Y[k : k + 1].reshape(1, -1))[0])
    # same algebra in another order (rounding of the kriging solves)
    assert_allclose(loo_errors(sur), brute, rtol=1e-6, atol=1e-12)


def test_predictive_variance_includes_truncation(snapshots):
    space, X, Y, _, _ = snapshots
    sur = PODKriging(pod=POD(n_modes=2), kriging=OrdinaryKriging(beta=1.5), space=space).fit(X, Y)
    _, std = sur.predict(X, return_std=True)
    # at training points the kriging variance vanishes; what is left is the truncation part
    assert_allclose(std**2, np.broadcast_to(sur.residual_variance_, std.shape), rtol=1e-6, atol=1e-18)
    assert np.all(sur.residual_variance_ > 0)


def test_shapes(surrogate, snapshots):
    Xh = snapshots[3]
    assert surrogate.predict(Xh[:5]).shape == (5, 24)
    mean, std = surrogate.predict(Xh[:5], return_std=True, reshape=True)
    assert mean.shape == std.shape == (5, 4, 6)


def test_save_load_round_trip(surrogate, snapshots, tmp_path):
    _, _, _, Xh, _ = snapshots
    save_surrogate(surrogate, tmp_path / "s.h5")
    loaded = load_surrogate(tmp_path / "s.h5")
    a, sa = surrogate.predict(Xh, return_std=True)
    b, sb = loaded.predict(Xh, return_std=True)
    assert np.array_equal(a, b) and np.array_equal(sa, sb)  # same arrays, same kernels: bitwise
    assert loaded.space == surrogate.space and loaded.output_shape_ == (4, 6)
    assert loaded.provenance_["package_version"]
    assert_allclose(loo_errors(loaded), loo_errors(surrogate), rtol=0, atol=0)


def test_extrapolation_refused_or_warned(surrogate):
    x = np.array([[2000.0, 40.0, 0.5, 10000.0]])  # kN_bj above its bound 1000 N/mm³
    with pytest.raises(ValueError, match=r"kN_bj = 2000 N/mm³ .*\[10, 1000\].*extrapolate=True"):
        surrogate.predict(x)
    with pytest.warns(UserWarning, match="extrapolating"):
        y = surrogate.predict(x, extrapolate=True)
    assert np.all(np.isfinite(y))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        surrogate.predict(np.array([[1000.0, 4.0, 0.1, 5000.0]]))  # the box corners are inside


def test_bounds_of_training_data_without_space(snapshots):
    _, X, Y, Xh, _ = snapshots
    sur = PODKriging(kriging=OrdinaryKriging(beta=1.5)).fit(X, Y)
    assert_allclose(sur.lower_, X.min(axis=0), rtol=0, atol=0)
    inside = Xh[np.all((Xh >= X.min(axis=0)) & (Xh <= X.max(axis=0)), axis=1)]
    assert sur.predict(inside).shape == (len(inside), 24)
    with pytest.raises(ValueError, match="constant"):
        PODKriging().fit(np.column_stack([X[:, :3], np.ones(len(X))]), Y)


def test_predictions_equal_the_reference_path_and_ignore_the_thread_count(surrogate, snapshots):
    """The numba kernel (fitted exponents just below 2: base 2 and per-mode polynomials) against
    the literal NumPy formula, and bitwise the same with one or two numba threads."""
    numba = pytest.importorskip("numba")
    _, _, _, Xh, Yh = snapshots
    kr = surrogate.kriging_
    before, setting = numba.get_num_threads(), kr.use_numba
    try:
        kr.use_numba = False
        ref = surrogate.predict(Xh)
        kr.use_numba = True
        out = {}
        for t in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
            numba.set_num_threads(t)
            out[t] = surrogate.predict(Xh)
    finally:
        numba.set_num_threads(before)
        kr.use_numba = setting
    # rounding (~1e-16) amplified by the kriging weights, whose terms reach 1e7 times the
    # readings near the conditioning limit of the Gaussian (1.3e-8 of the readings measured at
    # n = 256): bound 1e-6, far below the held-out error of 1e-2
    assert_allclose(out[1], ref, rtol=1e-6, atol=1e-6 * np.abs(Yh).max())
    assert np.array_equal(out[1], out[max(out)])
