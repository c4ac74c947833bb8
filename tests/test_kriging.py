"""Ordinary kriging: interpolation, analytic gradients, closed-form LOO, agreement with
scikit-learn GPR, numba/NumPy kernel agreement, and errors with remedies."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import approx_fprime

from podkrig.exceptions import NotFittedError
from podkrig.surrogate.kriging import OrdinaryKriging, covariance, semivariogram
from podkrig.surrogate.kriging.system import Objective, Pairs


def _f(X):
    return np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1] ** 2 + 0.3 * X[:, 2], np.exp(-X[:, 0] * X[:, 1])])


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    X = rng.random((25, 3))
    return X, _f(X), rng.random((40, 3))


@pytest.mark.parametrize("kw", [{"beta": 1.5}, {"beta": "fit"}, {"variogram": "power", "beta": 1.2},
                                {"beta": 1.8, "criterion": "loo"}])
def test_interpolates_training_points(data, kw):
    X, Y, _ = data
    ok = OrdinaryKriging(**kw).fit(X, Y)
    mean, std = ok.predict(X, return_std=True)
    # exact interpolator; the residual is rounding amplified by the condition number of the
    # correlation matrix, which may reach 1e12 (RCOND_MIN) when beta is fitted close to 2
    assert_allclose(mean, Y, rtol=0, atol=1e-5)
    # the variance at a training point is a difference of O(1) terms: rounding ~1e-12 relative
    assert np.all(std <= 1e-5 * np.sqrt(ok.sigma2_))
    assert ok.ranges_.shape == (2, 3) and ok.beta_.shape == (2,)


@pytest.mark.parametrize("kind", [0, 1])
@pytest.mark.parametrize("criterion", ["ml", "loo"])
@pytest.mark.parametrize("beta", [1.5, None])
def test_analytic_gradient_matches_finite_differences(data, kind, criterion, beta):
    X, Y, _ = data
    n = len(X)
    i, j = np.triu_indices(n, 1)
    A = np.abs(X[i] - X[j])
    logA = np.log(A)
    obj = Objective(Pairs(n, (i, j), A, logA, {}), Y[:, 0], kind, 0.0, criterion, beta)
    p = np.log([0.4, 0.7, 1.3])
    if beta is None:
        p = np.append(p, 1.3)
    _, g = obj(p)
    g_fd = approx_fprime(p, lambda q: obj(q)[0], 1e-6)
    # forward differences with step 1e-6: agreement to ~1e-5 relative
    assert_allclose(g, g_fd, rtol=1e-4, atol=1e-5 * np.max(np.abs(g)))


@pytest.mark.parametrize("variogram, beta", [("exponential", 1.8), ("exponential", 1.0), ("power", 1.5)])
def test_closed_form_loo_equals_refits(data, variogram, beta):
    X, Y, _ = data
    y = Y[:, 0]
    ok = OrdinaryKriging(variogram=variogram, beta=beta).fit(X, y)
    fixed = OrdinaryKriging(variogram=variogram, beta=beta, ranges=ok.ranges_[0], optimizer=None)
    brute = [y[k] - fixed.fit(np.delete(X, k, 0), np.delete(y, k)).predict(X[k : k + 1])[0] for k in range(len(X))]
    # the same linear algebra in two orders: rounding of the (ill-conditioned) kriging solves
    assert_allclose(ok.loo_residuals_[:, 0], brute, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("beta", [1.0, 2.0])
def test_agrees_with_sklearn_gpr(beta):
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Matern

    rng = np.random.default_rng(1)
    X = rng.random((20, 1))
    y = np.sin(5 * X[:, 0]) + 2.0
    Xp = rng.random((15, 1))
    a = 0.3 if beta == 1.0 else 0.1  # a Gaussian of range 0.3 on 20 points is numerically singular
    ok = OrdinaryKriging(beta=beta, ranges=a, optimizer=None).fit(X, y)
    mean, std = ok.predict(Xp, return_std=True)
    s2 = ok.sigma2_[0]
    # beta = 1: exp(-|h|/a) = Matern(nu=0.5, length_scale=a); beta = 2: exp(-(h/a)^2) = RBF(a/sqrt(2))
    base = Matern(a, "fixed", nu=0.5) if beta == 1.0 else RBF(a / np.sqrt(2), "fixed")
    # ordinary kriging = the GP with known mean mu (the GLS estimate) plus the variance of
    # estimating mu, sigma^2 (1 - 1^T R^-1 r)^2 / (1^T R^-1 1), computed here with sklearn's kernel
    kernel = ConstantKernel(s2, "fixed") * base
    gp = GaussianProcessRegressor(kernel, alpha=1e-14, optimizer=None).fit(X, y - ok.mu_[0])
    m_gp, s_gp = gp.predict(Xp, return_std=True)
    R = base(X)
    r = base(Xp, X)
    Rinv_1 = np.linalg.solve(R, np.ones(len(X)))
    var = s_gp**2 + s2 * (1.0 - r @ Rinv_1) ** 2 / Rinv_1.sum()
    # independent code (sklearn's Cholesky with alpha = 1e-14 jitter, numpy solve): agreement
    # limited by the conditioning of R (~1e8 for the Gaussian)
    assert_allclose(mean, m_gp + ok.mu_[0], rtol=1e-6, atol=1e-7)
    assert_allclose(std, np.sqrt(var), rtol=1e-5, atol=1e-7 * np.sqrt(s2))


@pytest.mark.parametrize("kw", [{"beta": 1.2}, {"beta": 1.5}, {"beta": 2.0}, {"beta": "fit"},
                                {"beta": "fit-shared"}, {"variogram": "power", "beta": 1.3}])
def test_numba_and_numpy_kernels_agree(data, kw):
    X, Y, Xp = data
    a = OrdinaryKriging(**kw, use_numba=True).fit(X, Y)
    b = OrdinaryKriging(**kw, use_numba=False).fit(X, Y)
    ma, sa = a.predict(Xp, return_std=True)
    mb, sb = b.predict(Xp, return_std=True)
    # the numba kernel's polynomial exp is accurate to ~1e-14 relative, amplified by the kriging
    # weights (up to ~1e6 times the outputs for a Gaussian near the conditioning limit)
    assert_allclose(ma, mb, rtol=1e-7, atol=1e-8)
    assert_allclose(sa, sb, rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("kw", [{"beta": "fit"}, {"variogram": "power", "beta": 1.3}])
def test_variance_paths_agree_and_mean_is_the_same_with_or_without_std(data, monkeypatch, kw):
    from podkrig.surrogate.kriging import ordinary

    X, Y, Xp = data
    ok = OrdinaryKriging(**kw).fit(X, Y)
    mean_only = ok.predict(Xp)
    mean, std = ok.predict(Xp, return_std=True)
    # one kernel pass gives means and cross-covariances: the means are bitwise those of predict
    assert np.array_equal(mean, mean_only)
    assert np.array_equal(np.sqrt(ok.predict_variance(Xp)), std)
    # the explicit L^-1 (dtrmm) against triangular solves, and blocks of 3 points against one
    # block: the same formula in another order, rounding ~1e-13 of sigma^2
    monkeypatch.setattr(ordinary, "EXPLICIT_INVERSE_BYTES", 0)
    monkeypatch.setattr(ordinary, "VARIANCE_BLOCK_BYTES", 3 * 8 * len(X) * Y.shape[1])
    solved = OrdinaryKriging(**kw).fit(X, Y)
    if ok.kind_ == 0:
        assert ok._L_inverse is not None and solved._L_inverse is None
    m2, s2 = solved.predict(Xp, return_std=True)
    assert np.array_equal(m2, mean)
    assert_allclose(s2**2, std**2, rtol=0, atol=1e-12 * ok.sigma2_.max())
    # a single point, and an empty batch
    assert_allclose(ok.predict(Xp[:1], return_std=True)[1] ** 2, std[:1] ** 2, rtol=0, atol=1e-12 * ok.sigma2_.max())
    assert ok.predict(Xp[:0], return_std=True)[1].shape == (0, Y.shape[1])


def _dense_ordinary_variance(X, Xp, ranges, beta, nugget):
    """σ²/σ̂² of ordinary kriging from the whole bordered system [[R, 1], [1ᵀ, 0]] solved densely
    (np.linalg.solve): 1 - λᵀr - μ with [R 1; 1ᵀ 0][λ; μ] = [r; 1], R with the fit's diagonal."""
    n = len(X)
    corr = lambda A, B: np.exp(-np.sum(np.abs(A[:, None, :] - B[None, :, :]) ** beta / np.asarray(ranges) ** beta,
                                       axis=-1))
    R = corr(X, X)
    np.fill_diagonal(R, 1.0 + nugget + (10 + n) * np.finfo(float).eps)
    A = np.block([[R, np.ones((n, 1))], [np.ones((1, n)), np.zeros((1, 1))]])
    rhs = np.vstack([corr(X, Xp), np.ones((1, len(Xp)))])
    return 1.0 - np.einsum("ip,ip->p", np.linalg.solve(A, rhs), rhs)


@pytest.mark.parametrize("explicit_inverse", [True, False])
@pytest.mark.parametrize("n, d, beta, nugget", [(12, 2, 1.0, 0.0), (80, 6, 1.5, 0.0), (300, 8, 1.9, 1e-8),
                                                (300, 6, 2.0, 1e-3)])
def test_variance_is_the_dense_ordinary_kriging_formula(monkeypatch, explicit_inverse, n, d, beta, nugget):
    """The Cholesky form of the variance (stored L^-1 product, or triangular solves) against the
    bordered ordinary-kriging system solved densely, on random designs and ranges, with and without
    a nugget; at the training points the variance vanishes without a nugget and is at the
    nugget's level (relative to the sill) with one. Defects: a lost trend term (1 - wᵀk)² c0, the sill or
    the nugget in the wrong place, the factor of another output, a point's row mixed into another's."""
    from podkrig.surrogate.kriging import ordinary

    monkeypatch.setattr(ordinary, "EXPLICIT_INVERSE_BYTES", 2**40 if explicit_inverse else 0)
    rng = np.random.default_rng(n + d)
    X, Xp = rng.random((n, d)), rng.random((50, d))
    ranges = rng.uniform(0.3, 1.5, size=(2, d))
    Y = np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1], X @ rng.random(d)])
    ok = OrdinaryKriging(beta=beta, ranges=ranges, nugget=nugget, optimizer=None).fit(X, Y)
    assert (ok._L_inverse is not None) == explicit_inverse
    var = ok.predict_variance(Xp)
    at_data = ok.predict_variance(X) / ok.sigma2_
    for j in range(2):
        dense = _dense_ordinary_variance(X, Xp, ranges[j], beta, nugget)
        # both sides are 1 - (a sum of O(1) terms); the bordered system's condition number (up to
        # ~1e9 for the Gaussian at n = 300) costs the dense solve its last digits: 1e-9 of the sill
        assert_allclose(var[:, j] / ok.sigma2_[j], dense, rtol=1e-8, atol=1e-9)
        # at a training point the variance is the nugget's share, less what the neighbours tell
        # (0.85-1 of it here), plus the fit's diagonal (10 + n) eps = 7e-14 and rounding
        assert np.all(at_data[:, j] <= nugget + 1e-12) and np.all(at_data[:, j] >= 0.5 * nugget)


def test_outputs_with_the_same_factor_share_one_triangular_product(monkeypatch):
    """Outputs at equal hyperparameters have bitwise-equal Cholesky factors: the O(n²) part of
    their variances is computed once per block and they keep one L^-1 between them; each variance
    is that of the output fitted alone. An output at other ranges keeps its own. Defects: sharing
    across different ranges or exponents, the sill of the first output given to the others."""
    from podkrig.surrogate.kriging import ordinary

    rng = np.random.default_rng(3)
    X, Xp = rng.random((60, 4)), rng.random((30, 4))
    Y = np.column_stack([np.sin(3 * X[:, 0]), X[:, 1] ** 2, 10 * X[:, 2] * X[:, 3], X[:, 0] - X[:, 3]])
    ranges = np.array([[0.5, 0.7, 0.9, 1.1]] * 3 + [[0.6, 0.7, 0.9, 1.1]])
    ok = OrdinaryKriging(beta=1.7, ranges=ranges, optimizer=None).fit(X, Y)
    assert list(ok._shared) == [0, 0, 0, 3] and sorted(ok._L_inverse) == [0, 3]
    calls = []
    real = ordinary.dtrmm
    monkeypatch.setattr(ordinary, "dtrmm", lambda *a, **k: calls.append(1) or real(*a, **k))
    mean, std = ok.predict(Xp, return_std=True)
    assert len(calls) == 2
    for j in range(4):
        alone = OrdinaryKriging(beta=1.7, ranges=ranges[j], optimizer=None).fit(X, Y[:, j])
        m, s = alone.predict(Xp, return_std=True)
        assert_allclose(mean[:, j], m, rtol=1e-13, atol=1e-13 * np.abs(Y[:, j]).max())
        assert_allclose(std[:, j], s, rtol=1e-10)


def test_fit_shared_uses_the_first_outputs_exponent_for_all(data):
    X, Y, _ = data
    assert Y.shape[1] > 1
    shared = OrdinaryKriging(beta="fit-shared").fit(X, Y)
    first = OrdinaryKriging(beta="fit").fit(X, Y[:, :1])
    assert np.all(shared.beta_ == shared.beta_[0])
    # L-BFGS-B stopping tolerance: the two fits reach the same optimum to ~1e-9
    assert_allclose(shared.beta_[0], first.beta_[0], rtol=1e-6)
    # the other outputs' ranges are fitted at that exponent: same as a fixed-beta fit (warm starts
    # differ between the two runs, so only to the optimiser's tolerance)
    fixed = OrdinaryKriging(beta=float(shared.beta_[0])).fit(X, Y[:, 1:])
    assert_allclose(shared.ranges_[1:], fixed.ranges_, rtol=1e-3)


def test_variance_is_positive_and_grows_away_from_data(data):
    X, Y, _ = data
    ok = OrdinaryKriging(beta=1.5).fit(X, Y[:, 0])
    near = X[:1] + 1e-3
    far = np.array([[0.999, 0.001, 0.999]])
    assert ok.predict(far, return_std=True)[1][0] > ok.predict(near, return_std=True)[1][0] > 0


def test_duplicates_are_refused_with_remedy(data):
    X, Y, _ = data
    Xd = np.vstack([X, X[3]])
    Yd = np.vstack([Y, Y[3]])
    with pytest.raises(ValueError, match=r"rows \[3, 25\].*remove duplicates or set a nugget"):
        OrdinaryKriging().fit(Xd, Yd)
    ok = OrdinaryKriging(beta=1.5, nugget=1e-6).fit(Xd, Yd)
    assert np.all(np.isfinite(ok.predict(X)))


@pytest.mark.parametrize(
    "kw, message",
    [
        ({"beta": 2.5}, "0 < beta <= 2"),
        ({"variogram": "power", "beta": 2.0}, "0 < beta < 2"),
        ({"beta": "auto"}, "\\(0, 2\\], 'fit' or 'fit-shared'"),
        ({"variogram": "spherical"}, "variogram must be one of"),
        ({"criterion": "aic"}, "criterion must be one of"),
        ({"nugget": -1.0}, "nugget must be"),
        ({"ranges": [0.1, 0.2]}, "ranges .*number or have shape"),
    ],
)
def test_setting_errors(data, kw, message):
    X, Y, _ = data
    with pytest.raises(ValueError, match=message):
        OrdinaryKriging(**kw).fit(X, Y)


def test_input_errors(data):
    X, Y, _ = data
    with pytest.raises(ValueError, match="unit cube"):
        OrdinaryKriging().fit(X * 10, Y)
    with pytest.raises(NotFittedError, match="not fitted"):
        OrdinaryKriging().predict(X)
    ok = OrdinaryKriging(beta=1.5).fit(X, Y)
    with pytest.raises(ValueError, match=r"shape \(n_pred, 3\)"):
        ok.predict(X[:, :2])


def test_semivariogram_shapes():
    h = np.array([0.0, 0.5, 1.0, 100.0])
    g = semivariogram(h, "exponential", beta=1.0, sill=2.0, range_=1.0)
    assert_allclose(g, [0.0, 2 * (1 - np.exp(-0.5)), 2 * (1 - np.exp(-1)), 2.0], rtol=1e-12, atol=0)
    assert_allclose(semivariogram(h, "power", beta=1.5), h**1.5, rtol=1e-12, atol=0)


def test_vectorised_log_kernel_matches_numpy():
    """The branch-free log of the prediction kernel against numpy over 30 decades and at 0."""
    from podkrig.surrogate.kriging import _kernels

    if _kernels.njit is None:
        pytest.skip("numba not installed")
    rng = np.random.default_rng(5)
    XtT = np.vstack([10.0 ** rng.uniform(-15, 1, 500), rng.uniform(0, 1, 500), np.zeros(500)])
    xp = np.array([0.0, 0.3, 0.0])
    Lg = np.empty_like(XtT)
    _kernels._fill_logs(Lg, np.empty(500), xp, XtT)
    expected = np.log(np.abs(xp[:2, None] - XtT[:2]))
    # series truncated at z^23 (< 1e-19) plus rounding of a dozen operations
    assert np.all(np.abs(Lg[:2] - expected) <= 4e-15 * np.maximum(1.0, np.abs(expected)))
    assert np.all(Lg[2] < -700)  # |dx| = 0: a large negative number, clamped by the callers


# exponents of the kernel tests: fitted ones just below 2 (one group around the base 2, per-output
# polynomials), one shared exponent near 2 (polynomial folded into the powers), the fast exponents,
# generic ones (base exp(beta log|dx|)) and a mixture that needs several groups
KERNEL_BETAS = {
    "fitted near 2": [1.99991, 1.99985, 1.9992, 1.995, 2.0, 1.97],
    "shared near 2": [1.9999145] * 4,
    "fast": [2.0, 1.5, 1.0, 2.0],
    "generic": [1.8, 1.8, 1.8],
    "mixed": [1.2, 1.8, 1.5, 0.6, 1.79, 1.999],
    # within 1e-9 of a fast base: a polynomial of degree 1, folded (one exponent) or per output;
    # the only plans whose need for logarithms rests on a 2-term polynomial alone
    "folded, degree 1": [2.0 - 1e-9] * 3,
    "per output, degree 1": [2.0, 1.5 - 1e-9, 1.5],
}


def _kernel_case(betas, seed=0, n=60, d=4, low=0.0, high=1.0):
    rng = np.random.default_rng(seed)
    beta = np.asarray(betas, float)
    ranges = rng.uniform(0.4, 3.0, (len(beta), d))
    return (rng.uniform(low, high, (300, d)), rng.random((n, d)), ranges ** -beta[:, None], beta,
            rng.random((len(beta), n)), rng.standard_normal(len(beta)))


@pytest.mark.parametrize("case", sorted(KERNEL_BETAS))
@pytest.mark.parametrize("box", [(0.0, 1.0), (-1.0, 2.0)])
def test_mean_kernel_equals_the_direct_formula(case, box):
    """The grouped numba kernel (base exponent, Taylor polynomial of the exponent difference)
    against the literal NumPy formula, inside the unit cube and extrapolating (|dx| up to 3)."""
    from podkrig.surrogate.kriging import _kernels

    if _kernels.njit is None:
        pytest.skip("numba not installed")
    Xp, Xt, theta, beta, alpha, mu = _kernel_case(KERNEL_BETAS[case], low=box[0], high=box[1])
    for kind in (0, 1):
        got = _kernels.predict_mean(Xp, Xt, theta, beta, kind, alpha, mu, use_numba=True)
        ref = _kernels.predict_mean_numpy(Xp, Xt, theta, beta, kind, alpha, mu)
        # positive weights: no cancellation, so the relative error of the sums is that of the
        # kernel entries. The expansion keeps the reduced distance s within 2^-53 (absolute) of the
        # exact one; a generic base exp(beta log|dx|) is good to ~1e-14 relative, the polynomial
        # exp(-s) to 7e-15, so exp(-s) to ~1e-14 * (1 + s) with s < 10 here; the clamp at exp(-40)
        # (4e-18 standing for 0) adds an absolute floor of 1e-16 per weight
        assert_allclose(got - mu, ref - mu, rtol=1e-13, atol=1e-16 * alpha.sum(axis=1).max())
    for kind in (0, 1):
        mean, K = _kernels.predict_mean_and_covariance(Xp, Xt, theta, beta, kind, alpha, mu, use_numba=True)
        assert np.array_equal(mean, _kernels.predict_mean(Xp, Xt, theta, beta, kind, alpha, mu, use_numba=True))
        for j in range(len(beta)):
            ref = _kernels.cross_covariance_numpy(Xp, Xt, theta[j], beta[j], kind)
            # kind 1 is -s itself: the 2^-53 absolute bound of the expansion times the sizes of s
            assert_allclose(K[j], ref, rtol=1e-13, atol=1e-16 if kind == 0 else 1e-15 * np.abs(ref).max())


@pytest.mark.parametrize("d", range(1, 12))
@pytest.mark.parametrize("case", ["shared near 2", "generic", "per output, degree 1"])
def test_mean_kernel_equals_the_direct_formula_in_every_dimension(case, d):
    """The correlation rows of an output at its group's powers sum the last 4, 6 or 8
    dimensions, take the exponential and the weights in one loop, the leading ones two at a time,
    over rows of powers padded with zeros: every width and padding (d = 1 … 11, even and odd)
    against the literal NumPy formula, with the tolerances of the test above; the means with and
    without the covariance rows are bitwise equal, and "per output, degree 1" mixes them with
    outputs of their own polynomial in one group. Defects: a padded row or a skipped dimension (d = 5, 7, 9, 11), the
    sum of the leading passes dropped (d > 8), a row not stored for the variance."""
    from podkrig.surrogate.kriging import _kernels

    if _kernels.njit is None:
        pytest.skip("numba not installed")
    Xp, Xt, theta, beta, alpha, mu = _kernel_case(KERNEL_BETAS[case], seed=d, d=d)
    got = _kernels.predict_mean(Xp, Xt, theta, beta, 0, alpha, mu, use_numba=True)
    ref = _kernels.predict_mean_numpy(Xp, Xt, theta, beta, 0, alpha, mu)
    assert_allclose(got - mu, ref - mu, rtol=1e-13, atol=1e-16 * alpha.sum(axis=1).max())
    mean, K = _kernels.predict_mean_and_covariance(Xp, Xt, theta, beta, 0, alpha, mu, use_numba=True)
    assert np.array_equal(mean, got)
    for j in range(len(beta)):
        assert_allclose(K[j], _kernels.cross_covariance_numpy(Xp, Xt, theta[j], beta[j], 0), rtol=1e-13, atol=1e-16)


def test_plan_groups_outputs_around_a_fast_base():
    from podkrig.surrogate.kriging._kernels import NQ, plan

    theta = np.ones((6, 4))
    fitted = plan(theta, np.array(KERNEL_BETAS["fitted near 2"]))
    # a group with base 2 (no transcendental power) whose polynomials grow with the distance to 2
    # (exactly 2 needs none); 1.97 would need more than degree 6: its own group, generic base
    assert fitted["g_code"].tolist() == [3, 0] and fitted["g_base"].tolist() == [2.0, 1.97]
    assert fitted["g_start"].tolist() == [0, 5, 6]
    nq = dict(zip(fitted["order"].tolist(), fitted["nq"].tolist()))
    assert nq[4] == 1 and nq[0] <= nq[1] <= nq[2] <= nq[3] <= NQ and nq[5] == 1
    shared = plan(theta[:4], np.array(KERNEL_BETAS["shared near 2"]))
    assert shared["g_code"].tolist() == [3] and shared["g_nfold"][0] > 1 and np.all(shared["nq"] == 1)
    generic = plan(theta[:3], np.array(KERNEL_BETAS["generic"]))
    assert generic["g_code"].tolist() == [0] and not np.any(generic["nq"] > 1)
    fixed = plan(theta[:2], np.array([2.0, 2.0]))
    assert not fixed["need_logs"]  # Gaussian: no logarithm at all


def test_kernels_are_deterministic_across_thread_counts_and_chunks():
    """Each prediction point is computed by one thread in a fixed order: the serial entry point
    and the parallel one on 2 threads (several chunk sizes) give bitwise equal results."""
    numba = pytest.importorskip("numba")
    from podkrig.surrogate.kriging import _kernels

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one numba thread only")
    Xp, Xt, theta, beta, alpha, mu = _kernel_case(KERNEL_BETAS["mixed"])
    Xp = np.random.default_rng(1).random((1001, 4))
    out = {t: _kernels.predict_mean(Xp, Xt, theta, beta, 0, alpha, mu, use_numba=True, threads=t) for t in (1, 2)}
    np.testing.assert_array_equal(out[1], out[2])
    cov = {t: _kernels.predict_mean_and_covariance(Xp, Xt, theta, beta, 0, alpha, mu, use_numba=True, threads=t)
           for t in (1, 2)}
    np.testing.assert_array_equal(cov[1][0], out[1])
    np.testing.assert_array_equal(cov[1][1], cov[2][1])
    XtT = np.ascontiguousarray(Xt.T)
    pl = _kernels.plan(theta, beta)
    args = (Xp, XtT, pl["theta"], pl["coef"], pl["nq"], pl["g_start"], pl["g_code"], pl["g_base"], pl["g_fold"],
            pl["g_nfold"], pl["need_logs"], 0, np.ascontiguousarray(alpha[pl["order"]]), mu[pl["order"]])
    for chunk in (1, 7, 32, 2000):  # chunks of one point, uneven, default, one chunk for all
        got, K = np.empty_like(out[1]), np.empty((len(beta),) + Xp.shape[:1] + Xt.shape[:1])
        _kernels._predict_mean_parallel(*args, got, K, True, chunk)
        np.testing.assert_array_equal(K, cov[1][1][pl["order"]])


def test_semivariogram_defaults_range_nugget_and_beta_check():
    """Defaults: exponential family, β = 1.5, unit sill and range, no nugget; γ(h) = γ(|h|); the
    nugget is a jump at 0⁺ only; the exponent is checked against the chosen model."""
    h = np.array([-2.0, 0.0, 0.5])
    assert_allclose(semivariogram(h), [1 - np.exp(-(2.0**1.5)), 0.0, 1 - np.exp(-(0.5**1.5))], rtol=1e-12, atol=0)
    g = semivariogram(h, beta=1.2, sill=3.0, range_=2.0, nugget=0.1)
    assert_allclose(g, [3.0 * (1 - np.exp(-1.0) + 0.1), 0.0, 3.0 * (1 - np.exp(-(0.25**1.2)) + 0.1)], rtol=1e-12, atol=0)
    with pytest.raises(ValueError, match="0 < beta < 2"):
        semivariogram(h, "power", beta=2.0)


def test_covariance_is_a_per_dimension_sum_inside_the_exponent():
    """s(x, x') = Σ_k (|x_k − x'_k| / a_k)^β by hand; exponential family e^{−s}, power model −s."""
    X1 = np.array([[0.0, 0.0], [0.3, 0.4]])
    X2 = np.array([[0.3, 0.4], [0.1, 1.0], [0.0, 0.0]])
    ranges, beta = np.array([0.5, 2.0]), 1.5
    s01 = (0.3 / 0.5) ** 1.5 + (0.4 / 2.0) ** 1.5
    s_11 = (0.2 / 0.5) ** 1.5 + (0.6 / 2.0) ** 1.5
    S = np.array([[s01, (0.1 / 0.5) ** 1.5 + (1.0 / 2.0) ** 1.5, 0.0], [0.0, s_11, s01]])
    assert_allclose(covariance(X1, X2, ranges, beta), np.exp(-S), rtol=1e-12, atol=0)
    assert_allclose(covariance(X1, X2, ranges, beta, "power"), -S, rtol=1e-12, atol=0)
    with pytest.raises(ValueError, match="variogram must be one of"):
        covariance(X1, X2, ranges, beta, "spherical")
