"""Training at scale (issue 19): hyperparameters on a subset, one factorisation of all samples;
the recorded choice through save/load; the ±2σ coverage of the held-out report."""

from pathlib import Path

import h5py
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from podkrig.io.surrogate_file import load_surrogate, save_surrogate
from podkrig.offline.sampling import sobol, uniform
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.surrogate.kriging import FitMethod, OrdinaryKriging, ordinary
from podkrig.surrogate.pod import POD
from podkrig.surrogate.podkriging import PODKriging
from podkrig.surrogate.validation import coverage, held_out_errors

DATA = Path(__file__).parent / "data"


def _f(X):
    """Two smooth outputs of three inputs in the unit cube."""
    return np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1] ** 2 + 0.3 * X[:, 2], np.exp(-X[:, 0] * X[:, 1]) * X[:, 2]])


@pytest.fixture(scope="module")
def data():
    X = sobol(64, 3, seed=0)
    return X, _f(X), uniform(200, 3, seed=1)


@pytest.mark.parametrize("beta", [1.8, 2.0])
def test_full_factorisation_equals_the_exact_system_at_the_same_hyperparameters(data, beta):
    """With the exact fit's ranges imposed (optimizer None), the subset path's system of all samples
    (correlations from the numba kernel, dpotrs and the triangular inverse instead of R^-1 and Q)
    gives the exact path's mean, variance, weights and leave-one-out residuals. Both evaluate the same
    formulas in another rounding order; the near-singular Gaussian-like systems amplify rounding
    ~1e6-fold (BENCHMARKS.md), so 1e-6 of each quantity's scale bounds the difference; the
    leave-one-out residuals, ratios of weights to diagonal entries of Q, differ by up to 1e-5 of
    their scale at beta = 2 (rcond near RCOND_MIN = 1e-12): 1e-4."""
    X, Y, Xp = data
    exact = OrdinaryKriging(beta=beta, fit_subset=None).fit(X, Y)
    forced = OrdinaryKriging(beta=beta, ranges=exact.ranges_, optimizer=None, fit_subset=16).fit(X, Y)
    assert forced.fit_method_ == FitMethod("subset", 64, 16, 0, (1.0, 1.0))
    assert_array_equal(forced.ranges_, exact.ranges_)
    (m1, s1), (m2, s2) = exact.predict(Xp, return_std=True), forced.predict(Xp, return_std=True)
    assert_allclose(m2, m1, rtol=0, atol=1e-6 * np.abs(Y).max())
    # the variance is 1 - ||L^-1 k||^2 + ...: a difference of O(1) terms, its square root
    # magnifies an absolute rounding difference where sigma is small (3e-6 of the max at beta = 2)
    assert_allclose(s2, s1, rtol=0, atol=1e-5 * s1.max())
    # the GLS mean alone (r^T y / s here, mean(y - K alpha) there) moves with the conditioning
    # (2e-6 at beta = 2); the predictions it enters agree to 1e-6 above
    assert_allclose(forced.mu_, exact.mu_, rtol=0, atol=1e-5 * np.abs(Y).max())
    assert_allclose(forced.sigma2_, exact.sigma2_, rtol=1e-5)  # 1.3e-6 at beta = 2
    assert_allclose(forced.loo_residuals_, exact.loo_residuals_, rtol=0, atol=1e-4 * np.abs(exact.loo_residuals_).max())
    assert_allclose(forced.criterion_, exact.criterion_, rtol=0, atol=1e-3)  # n log sigma2: 64 x 1.3e-6
    assert forced.Q_.shape == (2, 0, 0) and forced.L_.shape == (2, 64, 64)


@pytest.mark.parametrize("variogram, beta, criterion", [("exponential", 1.5, "loo"), ("power", 1.5, "ml"),
                                                        ("power", 1.2, "loo")])
def test_subset_path_builds_the_exact_fits_system_for_every_variogram_and_criterion(data, variogram, beta, criterion):
    """The branches the exponential-ML test above leaves out: the power model (the exact fit's
    bordered system of n - 1 contrasts, ``Q`` kept), the leave-one-out criterion (variance
    calibrated on the LOO residuals, criterion = Σ e² / Σ (y - ȳ)²) and a constant output (variance
    0). At the same ranges the subset path must give the exact fit's weights, factors, Q, q1, c0,
    mean, variance, criterion and LOO residuals and variances: the same formulas on the same
    matrices, so 1e-9 of each quantity's scale (measured ≤ 1e-12; these exponents are far from the
    near-singular β = 2)."""
    X, Y, Xp = data
    Y = np.column_stack([Y, np.full(len(Y), 0.7)])  # a third, constant output
    settings = dict(variogram=variogram, beta=beta, criterion=criterion)
    exact = OrdinaryKriging(**settings, fit_subset=None).fit(X, Y)
    forced = OrdinaryKriging(**settings, ranges=exact.ranges_, optimizer=None, fit_subset=16).fit(X, Y)
    assert forced.fit_method_.method == "subset" and forced.fit_method_.range_scale == (1.0, 1.0, 1.0)
    names = ["alpha_", "q1_", "c0_", "mu_", "sigma2_", "criterion_", "loo_residuals_", "loo_variance_", "L_"]
    names += ["Q_"] if variogram == "power" else []
    for name in names:
        a, b = getattr(forced, name), getattr(exact, name)
        assert a.shape == b.shape, name
        if name == "criterion_" and criterion == "loo":
            # the constant output's LOO criterion is a ratio of rounding errors (Σ e² / Σ (y - ȳ)²,
            # both ~0): compared on the two varying outputs only
            a, b = a[:2], b[:2]
        assert_allclose(a, b, rtol=0, atol=1e-9 * max(np.abs(b).max(), 1.0), err_msg=name)
    assert forced.sigma2_[2] == 0.0 and np.all(forced.loo_variance_[:, 2] == 0.0)
    if criterion == "loo":  # the LOO-calibrated variance, by its closed form
        dq = forced.sigma2_[0] / forced.loo_variance_[:, 0]
        assert forced.sigma2_[0] == pytest.approx(np.mean(forced.loo_residuals_[:, 0] ** 2 * dq), rel=1e-12)
    (m1, s1), (m2, s2) = exact.predict(Xp, return_std=True), forced.predict(Xp, return_std=True)
    assert_allclose(m2, m1, rtol=0, atol=1e-9 * np.abs(Y).max())
    assert_allclose(s2, s1, rtol=0, atol=1e-7 * s1.max())


def test_subset_fit_predicts_within_the_exact_fits_error(data, monkeypatch):
    """The threshold lowered so that "auto" takes the subset path at n = 64 (32 samples for the
    hyperparameters): its held-out error stays within 2x the exact fit's (measured 1.0-1.6x here; the
    ranges of a 32-point fit are rougher estimates), and the two predictions differ by less than
    3x the exact fit's own RMS error."""
    X, Y, Xp = data
    Yp = _f(Xp)
    exact = OrdinaryKriging(fit_subset="auto").fit(X, Y)
    assert exact.fit_method_.method == "exact"
    monkeypatch.setattr(ordinary, "EXACT_FIT_MAX_SAMPLES", 40)
    monkeypatch.setattr(ordinary, "SUBSET_SIZE", 32)
    sub = OrdinaryKriging(fit_subset="auto").fit(X, Y)
    assert (sub.fit_method_.method, sub.fit_method_.subset_size, sub.fit_method_.subset_seed) == ("subset", 32, 0)
    assert len(np.unique(sub.subset_index_)) == 32 and sub.subset_index_.max() < 64
    rms_exact = np.sqrt(np.mean((exact.predict(Xp) - Yp) ** 2, axis=0))
    rms_sub = np.sqrt(np.mean((sub.predict(Xp) - Yp) ** 2, axis=0))
    assert np.all(rms_sub <= 2.0 * rms_exact)
    assert np.all(np.sqrt(np.mean((sub.predict(Xp) - exact.predict(Xp)) ** 2, axis=0)) <= 3.0 * rms_exact)
    # still an interpolator of all 64 samples, not only of the subset
    assert_allclose(sub.predict(X), Y, rtol=0, atol=1e-5)


def test_ranges_too_long_for_all_samples_are_shortened_and_recorded(caplog):
    """A very smooth response: the ranges fitted on 20 of 60 points make the 60-point Gaussian-like
    correlation matrix singular to working precision; the output's ranges are multiplied by
    RANGE_SHRINK until it is well conditioned, and the factor is recorded and logged, once for each
    output shortened and for no other."""
    rng = np.random.default_rng(0)
    X = rng.random((60, 3))
    # two smooth outputs and a rough one, whose short ranges need no shortening
    Y = np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1] ** 2, X[:, 0] * X[:, 2], np.cos(25 * X[:, 0] * X[:, 1])])
    with caplog.at_level("INFO", logger="podkrig.surrogate.kriging.ordinary"):
        sub = OrdinaryKriging(fit_subset=20).fit(X, Y)
    shortened = [r.args for r in caplog.records if "ranges shortened" in r.msg]  # (output, factor, samples)
    assert shortened == [(col, f, 60) for col, f in enumerate(sub.fit_method_.range_scale) if f < 1.0]
    alone = OrdinaryKriging(fit_subset=None).fit(X[sub.subset_index_], Y[sub.subset_index_])
    scale = np.array(sub.fit_method_.range_scale)
    assert np.any(scale < 1.0) and np.any(scale == 1.0)
    assert_allclose(np.log(scale) / np.log(ordinary.RANGE_SHRINK), np.round(np.log(scale) / np.log(ordinary.RANGE_SHRINK)),
                    atol=1e-9)  # whole numbers of shrink steps
    assert_allclose(sub.ranges_, alone.ranges_ * scale[:, None], rtol=1e-12)
    assert_array_equal(sub.beta_, alone.beta_)
    assert "shortened" in sub.fit_method_.describe()
    assert_allclose(sub.predict(X), Y, rtol=0, atol=1e-6)


def test_recorded_choice_round_trips_through_the_surrogate_file(tmp_path, monkeypatch):
    space = ParameterSpace((Parameter("E_b", 5000.0, 20000.0, unit="MPa"), Parameter("r_hj", 0.1, 1.0)))
    X = space.from_unit(sobol(64, 2, seed=0))
    Y = np.stack([np.outer([1.0, 2.0], [1e3 / X[:, 0], np.sin(2 * X[:, 1])][k]) for k in range(2)], axis=2)
    Y = np.moveaxis(Y, 1, 0)  # (64, 2 loads, 2 sensors)
    monkeypatch.setattr(ordinary, "EXACT_FIT_MAX_SAMPLES", 32)
    monkeypatch.setattr(ordinary, "SUBSET_SIZE", 32)
    sur = PODKriging(pod=POD(energy=1 - 1e-10), kriging=OrdinaryKriging(random_state=7), space=space).fit(X, Y)
    fm = sur.kriging_.fit_method_
    assert (fm.method, fm.n_samples, fm.subset_size, fm.subset_seed) == ("subset", 64, 32, 7)
    save_surrogate(sur, tmp_path / "s.h5")
    with h5py.File(tmp_path / "s.h5") as f:
        g = f["kriging"]
        assert "L" not in g and "Q" not in g  # rebuilt at load, not stored
        assert_array_equal(g["subset_index"][...], sur.kriging_.subset_index_)
    back = load_surrogate(tmp_path / "s.h5")
    assert back.kriging_.fit_method_ == fm
    assert_array_equal(back.kriging_.subset_index_, sur.kriging_.subset_index_)
    Xp = space.from_unit(uniform(30, 2, seed=3))
    for a, b in zip(sur.predict(Xp, return_std=True), back.predict(Xp, return_std=True)):
        assert_array_equal(a, b)  # the rebuilt factors are bitwise those of the fit
    rep = held_out_errors(back, Xp, np.moveaxis(np.stack(
        [np.outer([1.0, 2.0], [1e3 / Xp[:, 0], np.sin(2 * Xp[:, 1])][k]) for k in range(2)], axis=2), 1, 0))
    assert rep.summary()["fit"] == fm.to_dict()
    assert all(f in rep.summary()["fit_description"] for f in ("32 of the 64 samples", "seed 7"))


def test_files_without_a_record_were_fitted_exactly():
    sur = load_surrogate(DATA / "surrogate_v1.h5")
    n = len(sur.X_)
    assert sur.kriging_.fit_method_ == FitMethod("exact", n, n)
    assert_array_equal(sur.kriging_.subset_index_, np.arange(n))


def test_coverage_of_a_known_case():
    """Errors of 0, 1, 1.999, 2 (the edge counts), 2.001 and 3 sigma: 4 of 6 within ±2σ; with
    k = 1, 2 of 6. Gaussian errors with honest sigma: 95.45 % within ±2σ (2e5 draws: binomial
    standard error 4.7e-4, tolerance 5 of them)."""
    sigma = np.array([0.5, 2.0, 1.0, 4.0, 1.0, 0.1])
    err = np.array([0.0, 1.0, 1.999, 2.0, 2.001, 3.0]) * sigma
    truth = np.linspace(-1, 1, 6)
    assert coverage(truth + err, truth, sigma) == pytest.approx(4 / 6, abs=0)
    assert coverage(truth - err, truth, sigma, k=1.0) == pytest.approx(2 / 6, abs=0)
    rng = np.random.default_rng(0)
    s = rng.uniform(0.1, 3.0, 200_000)
    assert coverage(rng.normal(0.0, s), np.zeros_like(s), s) == pytest.approx(0.9545, abs=2.5e-3)
    with pytest.raises(ValueError, match="one non-empty shape"):
        coverage([1.0, 2.0], [1.0], [1.0, 1.0])


def test_sklearn_backend_fits_on_a_subset_and_keeps_the_record(data):
    """The peers' subset fit: hyperparameters of 24 random samples, the regressor of all 64 at
    them (an interpolator of all 64: jitter 1e-10 of the normalised outputs); the record and the
    predictions survive to_arrays/from_arrays."""
    from podkrig.surrogate.backends import SklearnGPR, make_backend

    X, Y, Xp = data
    gpr = make_backend("sklearn-gpr", fit_subset=24, n_restarts_optimizer=0).fit(X, Y)
    assert (gpr.fit_method_.method, gpr.fit_method_.n_samples, gpr.fit_method_.subset_size) == ("subset", 64, 24)
    assert_allclose(gpr.predict(X), Y, rtol=0, atol=1e-4 * np.abs(Y).max())
    back = SklearnGPR.from_arrays(*gpr.to_arrays(), gpr.get_params())
    assert back.fit_method_ == gpr.fit_method_
    assert_allclose(back.predict(Xp), gpr.predict(Xp), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="fit_subset .*None or an integer >= 3"):
        make_backend("sklearn-gpr", fit_subset="auto").fit(X, Y)


@pytest.mark.parametrize("bad", [2, True, "all", 1.5])
def test_fit_subset_setting_errors(data, bad):
    X, Y, _ = data
    with pytest.raises(ValueError, match="fit_subset .*'auto', None.*>= 3"):
        OrdinaryKriging(fit_subset=bad).fit(X, Y)
