"""The kriging system at given hyperparameters (issue 12): the factorisations against dense closed
forms (bordered-matrix inverse, generalised least squares), the objectives against explicit
leave-one-out refits, their analytic gradients against finite differences, and the lean system of
all samples against the full one. Small systems (n = 9): fast and well conditioned."""


import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.linalg import null_space

from podkrig.surrogate.kriging import OrdinaryKriging, system
from podkrig.surrogate.kriging._kernels import EXPONENTIAL, POWER
from podkrig.surrogate.kriging.system import (FAIL, Objective, Pairs, SingularSystemError, correlation_factor, factor,
                                              factor_exponential)

X = np.array([[0.1, 0.2], [0.8, 0.1], [0.4, 0.9], [0.55, 0.45], [0.9, 0.7], [0.2, 0.6], [0.7, 0.35],
              [0.3, 0.05], [0.05, 0.95]])
Y = np.sin(3 * X[:, 0]) + X[:, 1] ** 2
EPS_DIAG = (10 + len(X)) * np.finfo(float).eps


def _pairs(X, with_log=True):
    i, j = np.triu_indices(len(X), 1)
    A = np.abs(X[i] - X[j])
    logA = np.where(A > 0, np.log(np.where(A > 0, A, 1.0)), 0.0) if with_log else None
    return Pairs(len(X), (i, j), A, logA, {})


def _dense(X, ranges, beta, kind, nugget=0.0):
    """The dense kriging matrix: correlations exp(-s) (exponential) or variogram -s (power), with
    s = sum_k |dx_k / a_k|^beta and the documented diagonals."""
    s = (np.abs(X[:, None, :] - X[None, :, :]) ** beta * np.asarray(ranges, float) ** -beta).sum(axis=2)
    n = len(X)
    if kind == EXPONENTIAL:
        K = np.exp(-s)
        np.fill_diagonal(K, 1.0 + nugget + EPS_DIAG)
    else:
        K = -s
        np.fill_diagonal(K, nugget + EPS_DIAG * np.abs(s).max())
    return K


def _bordered_inverse(K):
    n = len(K)
    M = np.block([[K, np.ones((n, 1))], [np.ones((1, n)), np.zeros((1, 1))]])
    return np.linalg.inv(M)


@pytest.mark.parametrize("kind, beta", [(EXPONENTIAL, 1.7), (EXPONENTIAL, 1.0), (POWER, 1.5)])
def test_factor_matches_the_bordered_system(kind, beta):
    """Q, q1 and c0 are the blocks of the inverse of the bordered matrix [[K, 1], [1^T, 0]]
    (Q, q1 and -c0); alpha = Q y; mu is the generalised least-squares mean; sigma2 = y^T Q y / m with
    m = n (exponential) or n - 1 (power); logdet is log det R, or log det Z^T K Z over an
    orthonormal basis Z of 1-perp. The defect guarded is a wrong block, sign or degree of freedom.
    Dense inverses of a 10 x 10 system with condition ~1e3: 1e-9."""
    ranges = np.array([0.4, 0.7])
    pairs = _pairs(X)
    theta = ranges ** -beta
    st = factor(pairs.power(beta) @ theta, pairs, kind, 0.0, Y)
    K = _dense(X, ranges, beta, kind)
    assert_allclose(st.K, K, rtol=1e-13, atol=1e-15)
    Minv = _bordered_inverse(K)
    n = len(X)
    assert_allclose(st.Q, Minv[:n, :n], rtol=1e-9, atol=1e-9 * np.abs(Minv).max())
    assert_allclose(st.q1, Minv[:n, n], rtol=1e-9, atol=1e-12)
    assert st.c0 == pytest.approx(-Minv[n, n], rel=1e-9)
    assert_allclose(st.alpha, Minv[:n, :n] @ Y, rtol=1e-8, atol=1e-10 * np.abs(st.alpha).max())
    assert st.mu == pytest.approx(Minv[n, :n] @ Y, rel=1e-9)
    m = n if kind == EXPONENTIAL else n - 1
    assert st.m == m
    assert st.sigma2 == pytest.approx(Y @ Minv[:n, :n] @ Y / m, rel=1e-9)
    if kind == EXPONENTIAL:
        assert st.logdet == pytest.approx(np.linalg.slogdet(K)[1], rel=1e-10)
        assert_allclose(st.Kinv_like, np.linalg.inv(K), rtol=1e-9)
        assert_allclose(st.L @ st.L.T, K, rtol=1e-12, atol=1e-14)
    else:
        Z = null_space(np.ones((1, n)))
        assert st.logdet == pytest.approx(np.linalg.slogdet(Z.T @ K @ Z)[1], rel=1e-10)
        assert_allclose(st.Kinv_like, st.Q, rtol=0)
    assert_allclose(st.Q, st.Q.T, rtol=0, atol=0)


def test_nugget_raises_the_diagonal():
    """A nugget eta adds eta to the correlation diagonal (relative to the sill), nothing else."""
    pairs = _pairs(X)
    theta = np.array([0.4, 0.7]) ** -1.5
    st = factor(pairs.power(1.5) @ theta, pairs, EXPONENTIAL, 0.25, Y)
    assert_allclose(st.K, _dense(X, [0.4, 0.7], 1.5, EXPONENTIAL, nugget=0.25), rtol=1e-13)


@pytest.mark.parametrize("kind", [EXPONENTIAL, POWER])
def test_duplicate_points_are_a_singular_system(kind):
    """Two coincident samples without a nugget make the system singular: SingularSystemError (a
    ValueError) naming the matrix (correlation or projected variogram) and its condition number, not
    weights made of rounding noise."""
    Xd = np.vstack([X, X[3]])
    pairs = _pairs(Xd)
    what = "correlation matrix" if kind == EXPONENTIAL else "projected variogram matrix"
    with pytest.raises(SingularSystemError, match=rf"^{what} ill-conditioned \(reciprocal condition number"):
        factor(pairs.power(1.5) @ np.array([4.0, 2.0]), pairs, kind, 0.0, np.append(Y, Y[3]))


def test_ill_conditioned_but_factorisable_system_is_refused():
    """Gaussian correlations (beta 2) at long ranges: Cholesky succeeds but the reciprocal condition
    number (1-norm, LAPACK dpocon on the lower factor) is below RCOND_MIN = 1e-12: refused with the
    number in the message (ranges 100 and 17); at ranges 8.5 (rcond 6.4e-12) the system is accepted.
    The defects guarded are a condition estimate read from the wrong triangle of the factor (only
    its diagonal: ~8e-12 at ranges 17, let through) and a norm other than the 1-norm (all entries:
    ranges 8.5 refused). Margins of 6x to 9x on each side of the limit."""
    pairs = _pairs(X)
    with pytest.raises(SingularSystemError, match=r"correlation matrix ill-conditioned \(reciprocal condition"):
        factor(pairs.power(2.0) @ np.array([1e-4, 1e-4]), pairs, EXPONENTIAL, 0.0, Y)
    # ranges 17: rcond ~9e-14 from the whole factor, while its diagonal alone (an estimate from
    # the wrong triangle) would suggest ~8e-12 and let the system through
    with pytest.raises(SingularSystemError, match=r"correlation matrix ill-conditioned"):
        factor(pairs.power(2.0) @ np.array([17.0, 17.0]) ** -2.0, pairs, EXPONENTIAL, 0.0, Y)
    # ranges 8.5: rcond 6.4e-12 with the 1-norm (largest column sum) -- just above the limit, so the
    # system is accepted, in the full and the lean path (a norm of all entries, 9x larger, would refuse it)
    st = factor(pairs.power(2.0) @ np.array([8.5, 8.5]) ** -2.0, pairs, EXPONENTIAL, 0.0, Y)
    assert np.isfinite(st.sigma2)
    factor_exponential(X, Y, np.array([8.5, 8.5]), 2.0, 0.0, np.empty((len(X), len(X))))
    assert system.RCOND_MIN == 1e-12


def _explicit_loo(K, y):
    """Residuals y_i - yhat_{-i}(x_i) of ordinary kriging refitted without sample i (bordered
    system of the other n - 1 samples)."""
    n = len(y)
    e = np.empty(n)
    for i in range(n):
        keep = np.arange(n) != i
        Minv = _bordered_inverse(K[np.ix_(keep, keep)])
        w = Minv[:n - 1, :n - 1] @ K[keep, i] + Minv[:n - 1, n - 1]
        e[i] = y[i] - w @ y[keep]
    return e


@pytest.mark.parametrize("kind, beta", [(EXPONENTIAL, 1.7), (POWER, 1.5)])
def test_objective_values_are_the_likelihood_and_the_explicit_leave_one_out_error(kind, beta):
    """"ml": m log sigma2 + log det (concentrated -2 log-likelihood up to a constant); "loo": the
    sum of squared leave-one-out residuals of explicit refits (Dubrule's closed form must equal
    them) over sum (y - ybar)^2. Dense algebra: 1e-8."""
    psi = np.log([0.4, 0.7])
    pairs = _pairs(X)
    ml = Objective(pairs, Y, kind, 0.0, "ml", beta)
    st = ml.state(psi)[0]
    assert ml.value(st) == pytest.approx(st.m * np.log(st.sigma2) + st.logdet, rel=1e-14)
    loo = Objective(pairs, Y, kind, 0.0, "loo", beta)
    e = _explicit_loo(_dense(X, np.exp(psi), beta, kind), Y)
    assert loo.value(st) == pytest.approx(e @ e / np.sum((Y - Y.mean()) ** 2), rel=1e-8)
    assert loo(psi)[0] == pytest.approx(loo.value(st), rel=1e-14)


@pytest.mark.parametrize("criterion", ["ml", "loo"])
@pytest.mark.parametrize("kind, beta", [(EXPONENTIAL, 1.7), (EXPONENTIAL, None), (POWER, 1.5), (POWER, None)])
def test_gradients_match_finite_differences(criterion, kind, beta):
    """The analytic gradient over [log a_1, log a_2, (beta)] equals central differences of the
    value (step 1e-5: truncation ~1e-10, rounding ~1e-11 of values of order 1-10): 1e-6 relative
    plus 1e-7 absolute. Fitted beta (None) checks the exponent's derivative, with its log|dx|."""
    pairs = _pairs(X)
    obj = Objective(pairs, Y, kind, 0.0, criterion, beta)
    params = np.log([0.4, 0.7]) if beta is not None else np.array([np.log(0.4), np.log(0.7), 1.6])
    f, g = obj(params)
    assert g.shape == params.shape
    h = 1e-5
    fd = np.array([(obj(params + h * ek)[0] - obj(params - h * ek)[0]) / (2 * h) for ek in np.eye(len(params))])
    assert_allclose(g, fd, rtol=1e-6, atol=1e-7)
    assert np.all(np.abs(g) > 1e-4)  # a real slope, not a vanishing one


def test_objective_at_a_singular_point_returns_the_penalty():
    """Where the system is singular the objective returns FAIL = 1e10 and a zero gradient (the
    optimiser backs off) instead of raising."""
    obj = Objective(_pairs(X), Y, EXPONENTIAL, 0.0, "ml", 2.0)
    f, g = obj(np.log([100.0, 100.0]))
    assert f == FAIL == 1e10
    assert_allclose(g, [0.0, 0.0], atol=0)


def test_objective_split_and_scale():
    """params = [log ranges, (beta)]: beta from the params only when it is fitted; the loo scale is
    sum (y - ybar)^2, floored at the smallest float for a constant output."""
    pairs = _pairs(X)
    assert Objective(pairs, Y, EXPONENTIAL, 0.0, "ml", 1.3).split(np.array([0.1, 0.2]))[1] == 1.3
    psi, beta = Objective(pairs, Y, EXPONENTIAL, 0.0, "ml", None).split(np.array([0.1, 0.2, 1.9]))
    assert beta == 1.9
    assert_allclose(psi, [0.1, 0.2], rtol=0)
    assert Objective(pairs, Y, EXPONENTIAL, 0.0, "loo", 1.3).yscale == pytest.approx(np.sum((Y - Y.mean()) ** 2))
    assert Objective(pairs, np.full(9, 2.0), EXPONENTIAL, 0.0, "loo", 1.3).yscale == np.finfo(float).tiny


def test_pairs_power_caches_and_bounds_its_cache():
    """|dx|^beta per pair, computed once per beta; the cache is emptied when it holds more than 8
    exponents (memory of a long beta fit stays bounded)."""
    pairs = _pairs(X)
    first = pairs.power(1.5)
    assert_allclose(first, pairs.A ** 1.5, rtol=1e-14)
    assert pairs.power(1.5) is first
    for b in np.linspace(1.0, 1.4, 8):
        pairs.power(float(b))
    assert len(pairs.powers) == 9 and pairs.power(1.5) is first
    pairs.power(1.95)
    assert set(pairs.powers) == {1.95}


@pytest.mark.parametrize("nugget", [0.0, 1e-3])
def test_lean_system_of_all_samples_equals_the_full_one(nugget):
    """factor_exponential (no R^-1, no Q) gives the full factor's alpha, mu, sigma2, q1, c0, diagonal
    of Q and log det; ``out`` holds the lower Cholesky factor (zero above the diagonal) and the
    returned U = L^T is a view of it. Same algebra, other rounding order: 1e-9."""
    ranges, beta = np.array([0.4, 0.7]), 1.7
    pairs = _pairs(X)
    st = factor(pairs.power(beta) @ ranges ** -beta, pairs, EXPONENTIAL, nugget, Y)
    out = np.empty((len(X), len(X)))
    alpha, mu, sigma2, q1, c0, dq, logdet = factor_exponential(X, Y, ranges, beta, nugget, out)
    assert_allclose(alpha, st.alpha, rtol=1e-9, atol=1e-9 * np.abs(st.alpha).max())
    assert mu == pytest.approx(st.mu, rel=1e-9)
    assert sigma2 == pytest.approx(st.sigma2, rel=1e-9)
    assert_allclose(q1, st.q1, rtol=1e-9)
    assert c0 == pytest.approx(st.c0, rel=1e-9)
    assert_allclose(dq, np.diag(st.Q), rtol=1e-9)
    assert logdet == pytest.approx(st.logdet, rel=1e-9)
    assert_allclose(np.triu(out, 1), 0.0, atol=0)
    assert_allclose(out @ out.T, st.K, rtol=1e-12, atol=1e-14)
    U = correlation_factor(X, ranges, beta, nugget, out)
    assert np.shares_memory(U, out)
    assert_allclose(U, out.T, rtol=0)


def test_lean_system_refuses_an_ill_conditioned_matrix():
    """The lean path applies the same RCOND_MIN guard as the full one."""
    out = np.empty((len(X), len(X)))
    with pytest.raises(SingularSystemError, match=r"ill-conditioned \(reciprocal condition number"):
        factor_exponential(X, Y, np.array([100.0, 100.0]), 2.0, 0.0, out)
    with pytest.raises(SingularSystemError, match="not positive definite|ill-conditioned"):
        correlation_factor(np.vstack([X, X[:1]]), np.array([0.4, 0.7]), 1.7, 0.0, np.empty((10, 10)))


@pytest.mark.parametrize("kind", [EXPONENTIAL, POWER])
def test_scaling_the_data_scales_the_fit(kind):
    """Outputs times c = 1e-3 (e.g. m instead of mm): the weights Q, q1, c0 and log det do not
    change, alpha and mu scale by c and sigma2 by c^2, both in the full and (exponential) in the
    lean system; the defect guarded is a floor on the process variance that is not scale-free.
    Exact up to rounding: 1e-10."""
    c = 1e-3
    pairs = _pairs(X)
    S = pairs.power(1.5) @ np.array([0.4, 0.7]) ** -1.5
    st, small = factor(S, pairs, kind, 0.0, Y), factor(S, pairs, kind, 0.0, c * Y)
    assert_allclose(small.alpha, c * st.alpha, rtol=1e-10)
    assert small.mu == pytest.approx(c * st.mu, rel=1e-10)
    assert small.sigma2 == pytest.approx(c * c * st.sigma2, rel=1e-10)
    assert (small.logdet, small.c0) == (st.logdet, st.c0)
    if kind == EXPONENTIAL:
        out = np.empty((len(X), len(X)))
        lean, lean_small = (factor_exponential(X, y, np.array([0.4, 0.7]), 1.5, 0.0, out) for y in (Y, c * Y))
        assert lean_small[2] == pytest.approx(c * c * lean[2], rel=1e-10)
        assert lean_small[2] == pytest.approx(small.sigma2, rel=1e-9)


def test_a_strong_nugget_gives_a_small_but_valid_system():
    """Two strongly correlated samples with nugget 0.5: R = [[1.5, r], [r, 1.5]] with r ~ 1, so
    1^T R^-1 1 = 2 / (1.5 + r) < 1 -- a valid system (only <= 0 is singular). mu is the mean of the
    two outputs (symmetry) and c0 = 1 / (1^T R^-1 1): rel 1e-12."""
    X2 = np.array([[0.5, 0.5], [0.5001, 0.5]])
    y2 = np.array([1.0, 3.0])
    pairs = _pairs(X2)
    S = pairs.power(2.0) @ np.array([1.0, 1.0])
    r = np.exp(-S[0])
    st = factor(S, pairs, EXPONENTIAL, 0.5, y2)
    s = 2.0 / (1.5 + r)  # the (10 + n) eps of the diagonal is below the tolerance
    assert s < 1
    assert st.c0 == pytest.approx(1 / s, rel=1e-12)
    assert st.mu == pytest.approx(2.0, rel=1e-12)
    out = np.empty((2, 2))
    alpha, mu, sigma2, q1, c0, dq, logdet = factor_exponential(X2, y2, np.array([1.0, 1.0]), 2.0, 0.5, out)
    assert (mu, c0) == (pytest.approx(2.0, rel=1e-12), pytest.approx(1 / s, rel=1e-12))


def test_an_indefinite_matrix_is_reported_with_its_pivot():
    """A matrix that is not positive definite at all (a negative nugget of -0.9 makes the
    correlation diagonal 0.1 under off-diagonal correlations up to ~0.9) fails the Cholesky
    factorisation: SingularSystemError naming the matrix and the failing pivot, in the full
    systems of both kinds and in the lean one (the optimiser catches it; OrdinaryKriging quotes it)."""
    pairs = _pairs(X)
    S = pairs.power(1.5) @ np.array([0.4, 0.7]) ** -1.5
    with pytest.raises(SingularSystemError, match=r"correlation matrix not positive definite.*pivot \d+"):
        factor(S, pairs, EXPONENTIAL, -0.9, Y)
    with pytest.raises(SingularSystemError, match=r"projected variogram matrix.*\(pivot \d+\)"):
        factor(S, pairs, POWER, -5.0, Y)
    with pytest.raises(SingularSystemError, match=r"correlation matrix not positive definite.*pivot \d+"):
        correlation_factor(
X, np.array([0.4, 0.7]), 1.5, -0.9, np.empty((len(X), len(X))))


class _FailingLapack:
    """scipy's LAPACK with one routine made to fail: it returns ``info`` (and, when given, its
    result replaced by ``result(a)``). Fault injection for branches a small well-conditioned system
    cannot reach on demand: a LAPACK failure after a successful, well-conditioned ``dpotrf``."""

    def __init__(self, lapack, name, info, result=None):
        self._lapack, self._name, self._info, self._result = lapack, name, info, result

    def __getattr__(self, attr):
        routine = getattr(self._lapack, attr)
        if attr != self._name:
            return routine

        def failing(*args, **kwargs):
            out, _ = routine(*args, **kwargs)
            return (out if self._result is None else self._result(out)), self._info

        return failing


@pytest.mark.parametrize("kind, routine, info, result, message", [
    (EXPONENTIAL, "dpotri", 4, None, ("correlation matrix", "pivot 4")),
    (EXPONENTIAL, "dpotri", 0, lambda a: -np.eye(len(a)), ("1^T R^-1 1 <= 0", "numerically singular")),
    (POWER, "dpotri", 3, None, ("projected variogram matrix", "pivot 3")),
])
def test_a_lapack_failure_after_the_factorisation_is_named(monkeypatch, kind, routine, info, result, message):
    """Full system: a failed inverse (info > 0) or a non-positive 1^T R^-1 1 raises
    SingularSystemError naming the matrix and the pivot, which OrdinaryKriging quotes to the user."""
    pairs = _pairs(X)
    S = pairs.power(1.5) @ np.array([0.4, 0.7]) ** -1.5
    monkeypatch.setattr(system, "lapack", _FailingLapack(system.lapack, routine, info, result))
    with pytest.raises(SingularSystemError) as raised:
        factor(S, pairs, kind, 0.0, Y)
    assert all(fragment in str(raised.value) for fragment in message), str(raised.value)
    variogram = "exponential" if kind == EXPONENTIAL else "power"
    with pytest.raises(ValueError, match=r"singular at ranges \(0\.4, 0\.7\) \(") as quoted:
        OrdinaryKriging(variogram, beta=1.5, ranges=[0.4, 0.7], optimizer=None).fit(X, Y)
    assert f"({raised.value})" in str(quoted.value)  # the cause quoted to the user


@pytest.mark.parametrize("routine, info, result, message", [
    ("dpotrs", 2, None, ("triangular solve", "info 2")),
    ("dpotrs", 0, lambda w: -np.abs(w), ("1^T R^-1 1 <= 0", "numerically singular")),
    ("dtrtri", 5, None, ("correlation factor", "pivot 5")),
])
def test_a_lapack_failure_in_the_lean_system_is_named(monkeypatch, routine, info, result, message):
    """Lean system of all samples: the same failures after a successful dpotrf, naming the step and
    LAPACK's info."""
    monkeypatch.setattr(system, "lapack", _FailingLapack(system.lapack, routine, info, result))
    with pytest.raises(SingularSystemError) as raised:
        factor_exponential(X, Y, np.array([0.4, 0.7]), 1.5, 0.0, np.empty((len(X), len(X))))
    assert all(fragment in str(raised.value) for fragment in message), str(raised.value)



def test_power_model_condition_uses_the_one_norm():
    """Two samples 4e-8 apart in the power model: the projected variogram matrix has a reciprocal
    condition number (1-norm, LAPACK dpocon) of 3.0e-12, above RCOND_MIN = 1e-12, so the system is
    accepted; estimated with the sum of all entries instead of the largest column sum it would read
    5.4e-13 and be refused. 1e-8 apart (4e-13) is refused. Margins about 2x either way."""
    def system_of(d):
        X2 = np.vstack([X, X[3] + [d, 0.0]])
        pairs = _pairs(X2)
        return pairs.power(1.5) @ np.array([0.4, 0.7]) ** -1.5, pairs, np.append(Y, Y[3])

    S, pairs, y = system_of(4e-8)
    factor(S, pairs, POWER, 0.0, y)  # accepted
    S, pairs, y = system_of(1e-8)
    with pytest.raises(SingularSystemError, match=r"^projected variogram matrix ill-conditioned"):
        factor(S, pairs, POWER, 0.0, y)
