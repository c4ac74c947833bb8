"""Batched cross-covariance kernels of the kriging predictor: numba kernels with NumPy twins.

Every kernel evaluates, for prediction points ``Xp`` ``(n_pred, d)`` and training points ``Xt``
``(n, d)`` (both in the unit cube), the reduced distance

.. math::

    s(x, x') = \\sum_{k=1}^{d} \\theta_k \\, |x_k - x'_k|^{\\beta}, \\qquad \\theta_k = a_k^{-\\beta},

and maps it to a (generalised) covariance: ``kind == 0`` (exponential family) gives the
correlation :math:`\\exp(-s)`; ``kind == 1`` (power variogram) gives the generalised covariance
:math:`-s` (the negated semivariogram).

The fused mean kernel never forms the ``(n_pred, n)`` matrix: per prediction point it builds the
``(d, n)`` block of powers :math:`|\\Delta_k|^\\beta` once and reuses it for every output that
shares the exponent (exponents 1, 1.5 and 2 need no transcendental call), or, for other exponents,
the block of :math:`\\log|\\Delta_k|` once for all outputs and
:math:`\\theta_k |\\Delta_k|^\\beta = \\exp(\\beta (\\log|\\Delta_k| - \\log a_k))` per output;
then it takes the dot product with the kriging weights. Its exponential is a
branch-free polynomial (``_exp_neg``: Taylor series of :math:`e^{-s/64}` raised to the power
64 by six squarings, relative error below 1e-14 for :math:`|s| \\le 40`; larger reduced distances
are clamped to 40, i.e. a correlation of 4e-18 stands for 0) because the
numba build has no vector math library, and a libm ``exp`` call per entry would keep the loop
scalar; the NumPy twin uses ``np.exp`` and the tests compare the two.

Set the environment variable ``PODKRIG_DISABLE_NUMBA=1`` (or pass ``use_numba=False`` to the
estimator) to use the NumPy twins only. First call of a numba kernel compiles it (a few seconds,
cached on disk afterwards).
"""

import math
import os

import numpy as np

EXPONENTIAL, POWER = 0, 1
_CHUNK = 512  # prediction points per block in the NumPy twins (bounds the (chunk, n, d) scratch)


def numba_enabled(use_numba=None):
    """Whether the numba kernels are used: ``use_numba`` if given, else not ``PODKRIG_DISABLE_NUMBA``."""
    if use_numba is not None:
        return bool(use_numba)
    return os.environ.get("PODKRIG_DISABLE_NUMBA", "").strip().lower() not in ("1", "true", "yes")


def abs_power(a, beta):
    """``|a| ** beta`` elementwise (NumPy), with the fast paths the kernels use; ``0 ** beta = 0``."""
    a = np.abs(a)
    if beta == 1.0:
        return a
    if beta == 2.0:
        return a * a
    if beta == 1.5:
        return a * np.sqrt(a)
    return a**beta


# ----------------------------------------------------------------------------- NumPy twins


def cross_covariance_numpy(Xp, Xt, theta, beta, kind):
    """``(n_pred, n)`` cross-covariance of one output (NumPy).

    Parameters
    ----------
    Xp : ndarray of shape (n_pred, d)
    Xt : ndarray of shape (n, d)
    theta : ndarray of shape (d,)
        Inverse ranges to the power beta, :math:`a_k^{-\\beta}`.
    beta : float
    kind : {0, 1}
        ``EXPONENTIAL`` or ``POWER``.
    """
    out = np.empty((Xp.shape[0], Xt.shape[0]))
    for c in range(0, Xp.shape[0], _CHUNK):
        S = abs_power(Xp[c : c + _CHUNK, None, :] - Xt[None, :, :], beta) @ theta
        out[c : c + _CHUNK] = np.exp(-S) if kind == EXPONENTIAL else -S
    return out


def predict_mean_numpy(Xp, Xt, theta, beta, kind, alpha, mu):
    """Kriging means of every output, ``(n_pred, n_outputs)`` (NumPy).

    Parameters
    ----------
    theta : ndarray of shape (n_outputs, d)
    beta : ndarray of shape (n_outputs,)
    kind : int
    alpha : ndarray of shape (n_outputs, n)
        Kriging weights :math:`Q y` per output.
    mu : ndarray of shape (n_outputs,)
    """
    n_out = theta.shape[0]
    out = np.empty((Xp.shape[0], n_out))
    for c in range(0, Xp.shape[0], _CHUNK):
        A = np.abs(Xp[c : c + _CHUNK, None, :] - Xt[None, :, :])
        last_beta, P = None, None
        for j in range(n_out):
            if beta[j] != last_beta:
                P, last_beta = abs_power(A, beta[j]), beta[j]
            S = P @ theta[j]
            K = np.exp(-S) if kind == EXPONENTIAL else -S
            out[c : c + _CHUNK, j] = K @ alpha[j] + mu[j]
    return out


# ----------------------------------------------------------------------------- numba kernels

try:  # numba is a core dependency; the guard only keeps the NumPy path usable without it
    from numba import njit, prange
except ImportError:  # pragma: no cover
    njit = None


if njit is not None:

    @njit(fastmath=True, inline="always", cache=True)
    def _exp_neg(s):
        # exp(-s) for -40 <= s <= 40 (callers clamp; exp(-40) = 4e-18 stands for "0"): Taylor
        # series of exp(-t), t = s / 64, |t| <= 0.625 (truncation 1e-18), then 6 squarings
        # (rounding grows to ~64 eps = 7e-15 relative). Pure arithmetic, so LLVM vectorises it.
        t = -s * (1.0 / 64.0)
        p = 1.0 / 20922789888000.0
        p = p * t + 1.0 / 1307674368000.0
        p = p * t + 1.0 / 87178291200.0
        p = p * t + 1.0 / 6227020800.0
        p = p * t + 1.0 / 479001600.0
        p = p * t + 1.0 / 39916800.0
        p = p * t + 1.0 / 3628800.0
        p = p * t + 1.0 / 362880.0
        p = p * t + 1.0 / 40320.0
        p = p * t + 1.0 / 5040.0
        p = p * t + 1.0 / 720.0
        p = p * t + 1.0 / 120.0
        p = p * t + 1.0 / 24.0
        p = p * t + 1.0 / 6.0
        p = p * t + 0.5
        p = p * t + 1.0
        p = p * t + 1.0
        p = p * p
        p = p * p
        p = p * p
        p = p * p
        p = p * p
        p = p * p
        return p

    @njit(fastmath=True, inline="always", cache=True)
    def _is_fast(beta):
        return beta == 1.0 or beta == 1.5 or beta == 2.0

    @njit(fastmath=True, inline="always", cache=True)
    def _fill_powers(P, xp, XtT, beta):
        # |x - x_i|^beta: the exponents 1, 1.5, 2 without a transcendental call; any other one
        # (shared by several outputs, so the block is reused) as exp(beta log|dx|)
        d, n = XtT.shape
        for k in range(d):
            x = xp[k]
            if beta == 1.0:
                for i in range(n):
                    P[k, i] = abs(x - XtT[k, i])
            elif beta == 2.0:
                for i in range(n):
                    a = x - XtT[k, i]
                    P[k, i] = a * a
            elif beta == 1.5:
                for i in range(n):
                    a = abs(x - XtT[k, i])
                    P[k, i] = a * math.sqrt(a)
            else:
                for i in range(n):
                    a = abs(x - XtT[k, i])
                    P[k, i] = a**beta

    @njit(fastmath=True, inline="always", cache=True)
    def _fill_logs(Lg, xp, XtT):
        # log|x - x_i|, shared by every output with a generic exponent. Branch-free so that LLVM
        # vectorises it (a libm log per entry would keep the loop scalar): split the IEEE-754 bits
        # into exponent e and mantissa m in [1, 2), fold m into [sqrt(1/2), sqrt(2)), then
        # log m = 2 atanh(z), z = (m - 1)/(m + 1), |z| <= 0.1716, by its odd series to z^23
        # (truncation < 1e-19). |dx| = 0 gives -1023 log 2 (about -709), which the callers clamp
        # like the -inf of log(0).
        d, n = XtT.shape
        for k in range(d):
            x = xp[k]
            row = Lg[k]
            for i in range(n):
                row[i] = abs(x - XtT[k, i])
            bits = row.view(np.int64)
            expo = np.empty(n)
            for i in range(n):
                b = bits[i]
                expo[i] = ((b >> 52) & 0x7FF) - 1023
                bits[i] = (b & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000  # mantissa, exponent 0
            for i in range(n):
                m = row[i]
                big = m > 1.4142135623730951
                m = m * 0.5 if big else m
                e = expo[i] + 1.0 if big else expo[i]
                z = (m - 1.0) / (m + 1.0)
                z2 = z * z
                q = 2.0 / 23.0
                q = q * z2 + 2.0 / 21.0
                q = q * z2 + 2.0 / 19.0
                q = q * z2 + 2.0 / 17.0
                q = q * z2 + 2.0 / 15.0
                q = q * z2 + 2.0 / 13.0
                q = q * z2 + 2.0 / 11.0
                q = q * z2 + 2.0 / 9.0
                q = q * z2 + 2.0 / 7.0
                q = q * z2 + 2.0 / 5.0
                q = q * z2 + 2.0 / 3.0
                q = q * z2 + 2.0
                row[i] = e * 0.6931471805599453 + z * q

    @njit(fastmath=True, inline="always", cache=True)
    def _powers_from_logs(P, Lg, beta):
        # |dx|^beta = exp(beta log|dx|) with the vectorisable exponential
        d, n = Lg.shape
        for k in range(d):
            for i in range(n):
                P[k, i] = _exp_neg(min(max(-beta * Lg[k, i], -40.0), 40.0))

    @njit(fastmath=True, inline="always", cache=True)
    def _reduced(S, P, Lg, theta_j, logr_j, beta, fast):
        # S_i = sum_k theta_k |dx_k|^beta = sum_k exp(beta (log|dx_k| - log a_k))
        d, n = P.shape
        if fast:
            th = theta_j[0]
            for i in range(n):
                S[i] = th * P[0, i]
            for k in range(1, d):
                th = theta_j[k]
                for i in range(n):
                    S[i] += th * P[k, i]
        else:
            for i in range(n):
                S[i] = 0.0
            for k in range(d):
                lr = logr_j[k]
                for i in range(n):
                    t = beta * (lr - Lg[k, i])
                    S[i] += _exp_neg(min(max(t, -40.0), 40.0))

    @njit(parallel=True, fastmath=True, cache=True)
    def _predict_mean_numba(Xp, XtT, theta, logr, beta, kind, alpha, mu, out):
        n_pred = Xp.shape[0]
        d, n = XtT.shape
        n_out = theta.shape[0]
        block = 32
        n_blocks = (n_pred + block - 1) // block
        for b in prange(n_blocks):
            P = np.empty((d, n))
            Lg = np.empty((d, n))
            S = np.empty(n)
            for p in range(b * block, min(n_pred, (b + 1) * block)):
                last_beta = -1.0
                have_logs = False
                fast = True
                for j in range(n_out):
                    if beta[j] != last_beta:
                        last_beta = beta[j]
                        # a block of powers pays off for a fast exponent or one shared with the
                        # next output (outputs come sorted by beta); otherwise logs, shared by all
                        exact = _is_fast(beta[j])
                        fast = exact or (j + 1 < n_out and beta[j + 1] == beta[j])
                        if exact:
                            _fill_powers(P, Xp[p], XtT, beta[j])
                        else:
                            if not have_logs:
                                _fill_logs(Lg, Xp[p], XtT)
                                have_logs = True
                            if fast:  # a generic exponent shared with the next output(s)
                                _powers_from_logs(P, Lg, beta[j])
                    _reduced(S, P, Lg, theta[j], logr[j], beta[j], fast)
                    acc = 0.0
                    if kind == 0:
                        for i in range(n):
                            acc += alpha[j, i] * _exp_neg(min(S[i], 40.0))
                    else:
                        for i in range(n):
                            acc -= alpha[j, i] * S[i]
                    out[p, j] = acc + mu[j]

    @njit(parallel=True, fastmath=True, cache=True)
    def _cross_covariance_numba(Xp, XtT, theta, logr, beta, kind, out):
        n_pred = Xp.shape[0]
        d, n = XtT.shape
        fast = _is_fast(beta)
        block = 32
        n_blocks = (n_pred + block - 1) // block
        for b in prange(n_blocks):
            P = np.empty((d, n))
            Lg = np.empty((d, n))
            S = np.empty(n)
            for p in range(b * block, min(n_pred, (b + 1) * block)):
                if fast:
                    _fill_powers(P, Xp[p], XtT, beta)
                else:
                    _fill_logs(Lg, Xp[p], XtT)
                _reduced(S, P, Lg, theta, logr, beta, fast)
                for i in range(n):
                    out[p, i] = _exp_neg(min(S[i], 40.0)) if kind == 0 else -S[i]


def predict_mean(Xp, Xt, theta, beta, kind, alpha, mu, use_numba=None):
    """Kriging means of every output, ``(n_pred, n_outputs)``; see :func:`predict_mean_numpy`.

    Outputs that share an exponent share one block of powers; order outputs by ``beta`` for speed.
    """
    Xp = np.ascontiguousarray(Xp, dtype=float)
    beta = np.ascontiguousarray(beta, dtype=float)
    if not numba_enabled(use_numba) or njit is None:
        return predict_mean_numpy(Xp, Xt, theta, beta, kind, alpha, mu)
    out = np.empty((Xp.shape[0], theta.shape[0]))
    theta = np.ascontiguousarray(theta, dtype=float)
    logr = -np.log(theta) / beta[:, None]  # log ranges
    _predict_mean_numba(
        Xp, np.ascontiguousarray(Xt.T), theta, logr, beta, int(kind),
        np.ascontiguousarray(alpha), np.ascontiguousarray(mu, dtype=float), out,
    )
    return out


def cross_covariance(Xp, Xt, theta, beta, kind, use_numba=None):
    """``(n_pred, n)`` cross-covariance of one output; see :func:`cross_covariance_numpy`."""
    Xp = np.ascontiguousarray(Xp, dtype=float)
    if not numba_enabled(use_numba) or njit is None:
        return cross_covariance_numpy(Xp, Xt, theta, float(beta), kind)
    out = np.empty((Xp.shape[0], Xt.shape[0]))
    theta = np.ascontiguousarray(theta, dtype=float)
    _cross_covariance_numba(Xp, np.ascontiguousarray(Xt.T), theta, -np.log(theta) / float(beta),
                            float(beta), int(kind), out)
    return out
