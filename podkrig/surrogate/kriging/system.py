"""The kriging system at given hyperparameters: pairwise data of the training points, the
factorisation of the correlation (or projected variogram) matrix, and the objectives that choose
the hyperparameters — the concentrated log-likelihood and the closed-form leave-one-out error —
with their analytic gradients; and the lean system of all samples after a subset fit
(:func:`factor_exponential`: no pairwise arrays, no :math:`R^{-1}`, the factor in place). :class:`~podkrig.surrogate.kriging.ordinary.OrdinaryKriging`
drives them; nothing here holds fitted state.
"""

from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

from podkrig.surrogate.kriging import _kernels
from podkrig.surrogate.kriging.variogram import EXPONENTIAL

RCOND_MIN = 1e-12  # smallest admissible reciprocal condition number of the kriging matrix
FAIL = 1e10  # objective value returned where the (generalised) covariance matrix is singular


class SingularSystemError(ValueError):
    """Internal: a factorisation failed at some hyperparameters (caught by the optimiser)."""


@dataclass
class Pairs:
    """Pairwise data of the training points shared by every output: ``i < j`` pairs only."""

    n: int
    iu: tuple
    A: np.ndarray  # (n_pairs, d) |x_i - x_j| per dimension
    logA: np.ndarray | None = None  # (n_pairs, d) log|x_i - x_j|, 0 where the difference is 0
    powers: dict | None = None  # beta -> (n_pairs, d) |x_i - x_j| ** beta

    def power(self, beta):
        if beta not in self.powers:
            if len(self.powers) > 8:
                self.powers.clear()
            self.powers[beta] = _kernels.abs_power(self.A, beta)
        return self.powers[beta]


@dataclass
class _State:
    """Factorised kriging system of one output at given hyperparameters."""

    L: np.ndarray  # Cholesky factor: of R (exponential) or of Z^T K Z (power)
    Q: np.ndarray  # (n, n) projected precision, bordered-system inverse block
    Kinv_like: np.ndarray  # R^-1 (exponential) or Q (power): d log det / dK
    alpha: np.ndarray  # Q y
    mu: float
    sigma2: float
    logdet: float
    m: int  # degrees of freedom of sigma2: n (exponential) or n - 1 (power)
    q1: np.ndarray
    c0: float
    K: np.ndarray


def _symmetrize_lower(M):
    """Full symmetric matrix from the lower triangle of ``M`` (LAPACK ``potri`` output)."""
    iu = np.triu_indices(M.shape[0], 1)
    M[iu] = M.T[iu]
    return M


def _check_rcond(L, anorm, what):
    """Treat a numerically singular matrix (1-norm reciprocal condition < RCOND_MIN) as singular.

    Without this guard the likelihood, evaluated through a Cholesky factor that barely exists,
    is dominated by rounding and the optimiser walks to ranges whose weights are noise.
    """
    rcond, info = lapack.dpocon(L, anorm, uplo="L")
    if info != 0 or not rcond > RCOND_MIN:
        raise SingularSystemError(f"{what} ill-conditioned (reciprocal condition number {rcond:.2g})")


def factor(Svals, pairs, kind, nugget, y):
    """Build, factorise and solve the kriging system for reduced distances ``Svals`` on the pairs.

    Notes
    -----
    With the bordered matrix :math:`M = [[K, 1], [1^T, 0]]` of ordinary kriging, the block
    :math:`Q` of :math:`M^{-1}` is :math:`Z (Z^T K Z)^{-1} Z^T` for any orthonormal basis :math:`Z`
    of :math:`1^\\perp`; for a positive definite :math:`K = R` it equals
    :math:`R^{-1} - R^{-1} 1 1^T R^{-1} / (1^T R^{-1} 1)`. The exponential family uses the Cholesky
    factor of :math:`R`; the power model (only conditionally positive definite) that of
    :math:`Z^T K Z`, with :math:`Z` from a Householder reflection.
    """
    n = pairs.n
    i, j = pairs.iu
    K = np.empty((n, n))
    off = np.exp(-Svals) if kind == EXPONENTIAL else -Svals
    K[i, j] = off
    K[j, i] = off
    if kind == EXPONENTIAL:
        # (10 + n) eps on the diagonal as in DACE: rounding-level regularisation only
        np.fill_diagonal(K, 1.0 + nugget + (10 + n) * np.finfo(float).eps)
        L, info = lapack.dpotrf(K, lower=1, clean=1)
        if info != 0:
            raise SingularSystemError(f"correlation matrix not positive definite (pivot {info})")
        _check_rcond(L, np.abs(K).sum(axis=0).max(), "correlation matrix")
        Rinv, info = lapack.dpotri(L, lower=1)
        if info != 0:
            raise SingularSystemError(f"correlation matrix singular (pivot {info})")
        Rinv = _symmetrize_lower(Rinv)
        r1 = Rinv.sum(axis=1)
        s = r1.sum()
        if not s > 0:
            raise SingularSystemError("1^T R^-1 1 <= 0: correlation matrix numerically singular")
        Q = Rinv - np.outer(r1, r1) / s
        q1 = r1 / s  # 1/n - Q K 1/n, simplified
        c0 = 1.0 / s
        Kinv_like, m = Rinv, n
    else:
        scale = np.abs(off).max() if off.size else 1.0
        np.fill_diagonal(K, nugget + (10 + n) * np.finfo(float).eps * scale)
        v = np.ones(n)
        v[0] += np.sqrt(n)
        c = 2.0 / (v @ v)
        Kv = K @ v
        HKH = K - c * np.outer(v, Kv) - c * np.outer(Kv, v) + c * c * (v @ Kv) * np.outer(v, v)
        L, info = lapack.dpotrf(HKH[1:, 1:], lower=1, clean=1)
        if info != 0:
            raise SingularSystemError(f"projected variogram matrix not positive definite (pivot {info})")
        _check_rcond(L, np.abs(HKH[1:, 1:]).sum(axis=0).max(), "projected variogram matrix")
        Ainv, info = lapack.dpotri(L, lower=1)
        if info != 0:
            raise SingularSystemError(f"projected variogram matrix singular (pivot {info})")
        B = np.zeros((n, n))
        B[1:, 1:] = _symmetrize_lower(Ainv)
        HB = B - c * np.outer(v, v @ B)
        Q = HB - c * np.outer(HB @ v, v)
        Q = 0.5 * (Q + Q.T)
        b = K.sum(axis=1) / n
        q1 = 1.0 / n - Q @ b
        c0 = float(b @ q1)
        Kinv_like, m = Q, n - 1
    alpha = Q @ y
    mu = float(np.mean(y - K @ alpha))
    sigma2 = max(float(y @ alpha), 0.0) / m
    logdet = 2.0 * float(np.sum(np.log(np.diag(L))))
    return _State(L, Q, Kinv_like, alpha, mu, sigma2, logdet, m, q1, c0, K)


class Objective:
    """Criterion and its analytic gradient for one output over ``params = [log a_1..log a_d, (beta)]``."""

    def __init__(self, pairs, y, kind, nugget, criterion, beta):
        self.pairs, self.y, self.kind, self.nugget = pairs, y, kind, nugget
        self.criterion, self.beta = criterion, beta  # beta: float, or None when fitted
        self.yscale = max(float(np.sum((y - y.mean()) ** 2)), np.finfo(float).tiny)

    def split(self, params):
        d = self.pairs.A.shape[1]
        psi = params[:d]
        beta = self.beta if self.beta is not None else float(params[d])
        return psi, beta

    def state(self, params):
        psi, beta = self.split(params)
        theta = np.exp(-beta * psi)
        P = self.pairs.power(beta) if self.beta is not None else _kernels.abs_power(self.pairs.A, beta)
        return factor(P @ theta, self.pairs, self.kind, self.nugget, self.y), P, theta, psi, beta

    def value(self, st):
        if self.criterion == "ml":
            # concentrated likelihood (Sacks et al. 1989): -2 log L = m log sigma2 + log det + const
            return st.m * np.log(max(st.sigma2, 1e-300)) + st.logdet
        e = st.alpha / np.diag(st.Q)  # Dubrule (1983): LOO residuals y_i - yhat_{-i}(x_i)
        return float(e @ e) / self.yscale

    def __call__(self, params):
        try:
            st, P, theta, psi, beta = self.state(params)
        except SingularSystemError:
            return FAIL, np.zeros_like(params)
        f = self.value(st)
        # dF = sum_ij G_ij dK_ij for symmetric dK
        if self.criterion == "ml":
            G = st.Kinv_like - np.outer(st.alpha, st.alpha) / max(st.sigma2, 1e-300)
        else:
            dq = np.diag(st.Q)
            e = st.alpha / dq
            v, w = e / dq, e * e / dq
            Qv = st.Q @ v
            G = 2.0 * (st.Q * w) @ st.Q - np.outer(Qv, st.alpha) - np.outer(st.alpha, Qv)
            G /= self.yscale
        i, j = self.pairs.iu
        H = 2.0 * G[i, j]  # two symmetric entries per pair
        if self.kind == EXPONENTIAL:
            H = H * st.K[i, j]  # dK/dS = -R (exponential); -1 (power)
        # dS/dpsi_k = -beta theta_k P_k  ->  dK/dpsi_k = +beta theta_k P_k (times R for exponential)
        g_psi = beta * theta * (H @ P)
        if self.beta is not None:
            return f, g_psi
        # dS/dbeta = sum_k theta_k P_k (log|dx_k| - psi_k)
        g_beta = -float(H @ ((P * (self.pairs.logA - psi)) @ theta))
        return f, np.append(g_psi, g_beta)


def factor_exponential(X, y, ranges, beta, nugget, out, use_numba=None):
    """One output's system of all samples (exponential family), factorised into ``out``.

    Parameters
    ----------
    X : ndarray of shape (n, d)
        Training inputs, unit cube.
    y : ndarray of shape (n,)
    ranges : ndarray of shape (d,)
    beta : float
    nugget : float
        Relative to the sill.
    use_numba : bool or None
        As in :class:`~podkrig.surrogate.kriging.OrdinaryKriging`.
    out : ndarray of shape (n, n), C order
        Receives the lower Cholesky factor :math:`L` of :math:`R` (:func:`correlation_factor`).

    Returns
    -------
    alpha, mu, sigma2, q1, c0, diag_Q, logdet
        With :math:`r = R^{-1} 1`, :math:`s = 1^T r`: :math:`\\hat\\mu = r^T y / s`,
        :math:`\\alpha = Q y = R^{-1} y - r \\hat\\mu`, :math:`\\hat\\sigma^2 = y^T \\alpha / n`,
        :math:`q_1 = r / s`, :math:`c_0 = 1 / s`, and
        :math:`Q_{ii} = (R^{-1})_{ii} - r_i^2 / s` from the triangular inverse,
        :math:`(R^{-1})_{ii} = \\sum_k (L^{-1})_{ki}^2` (for the leave-one-out residuals);
        the same quantities as :func:`factor` without
        forming :math:`R^{-1}` or :math:`Q` (one :math:`n \\times n` temporary).
    """
    n = len(y)
    U = correlation_factor(X, ranges, beta, nugget, out, use_numba)
    W, info = lapack.dpotrs(U, np.column_stack([np.ones(n), y]), lower=0)
    if info != 0:
        raise SingularSystemError(f"triangular solve failed (info {info})")
    r1, Rinv_y = W[:, 0], W[:, 1]
    s = float(r1.sum())
    if not s > 0:
        raise SingularSystemError("1^T R^-1 1 <= 0: correlation matrix numerically singular")
    mu = float(r1 @ y) / s
    alpha = Rinv_y - r1 * mu
    Uinv, info = lapack.dtrtri(U, lower=0)  # U^-1 = (L^-1)^T, a copy
    if info != 0:
        raise SingularSystemError(f"correlation factor singular (pivot {info})")
    diag_Rinv = np.einsum("ik,ik->i", Uinv, Uinv)
    del Uinv
    dq = diag_Rinv - r1 * r1 / s
    logdet = 2.0 * float(np.sum(np.log(np.diagonal(U))))
    return alpha, mu, max(float(y @ alpha), 0.0) / n, r1 / s, 1.0 / s, dq, logdet

def correlation_factor(X, ranges, beta, nugget, out, use_numba=None):
    """Cholesky factor of the correlation matrix of ``X`` at ``ranges``, ``beta``, in place.

    The matrix :math:`R_{ij} = e^{-s(x_i, x_j)}` comes from the prediction kernel
    (:func:`~podkrig.surrogate.kriging._kernels.predict_mean_and_covariance`, deterministic
    whatever the number of threads) with the diagonal of the exact fit,
    :math:`1 + \\eta + (10 + n)\\varepsilon`; LAPACK ``dpotrf`` factorises it in ``out``
    (C order, ``(n, n)``), which then holds the lower factor :math:`L` (zero above the
    diagonal). Returns the upper factor :math:`U = L^T` as a Fortran-order view of ``out``.

    Raises
    ------
    SingularSystemError
        Not positive definite, or reciprocal condition number below ``RCOND_MIN``.
    """
    n = X.shape[0]
    theta = np.asarray(ranges, dtype=float)[None, :] ** (-beta)
    K = _kernels.predict_mean_and_covariance(X, X, theta, np.array([beta]), EXPONENTIAL, np.zeros((1, n)),
                                             np.zeros(1), use_numba)[1]
    out[...] = K[0]
    del K
    np.fill_diagonal(out, 1.0 + float(nugget) + (10 + n) * np.finfo(float).eps)
    anorm = float(out.sum(axis=0).max())  # 1-norm: every correlation is >= 0
    U, info = lapack.dpotrf(out.T, lower=0, overwrite_a=1, clean=1)
    if not np.shares_memory(U, out):  # scipy copied after all: keep the factor in out
        out[...] = U.T
        U = out.T
    if info != 0:
        raise SingularSystemError(f"correlation matrix not positive definite (pivot {info})")
    rcond, info = lapack.dpocon(U, anorm, uplo="U")
    if info != 0 or not rcond > RCOND_MIN:
        raise SingularSystemError(f"correlation matrix ill-conditioned (reciprocal condition number {rcond:.2g})")
    return U
