"""Batched cross-covariance kernels of the kriging predictor: numba kernels with NumPy twins.

Every kernel evaluates, for prediction points ``Xp`` ``(n_pred, d)`` and training points ``Xt``
``(n, d)`` (both in the unit cube), the reduced distance

.. math::

    s(x, x') = \\sum_{k=1}^{d} \\theta_k \\, |x_k - x'_k|^{\\beta}, \\qquad \\theta_k = a_k^{-\\beta},

and maps it to a (generalised) covariance: ``kind == 0`` (exponential family) gives the
correlation :math:`\\exp(-s)`; ``kind == 1`` (power variogram) gives the generalised covariance
:math:`-s` (the negated semivariogram). The NumPy twins evaluate these formulas literally and are
the reference of the tests.

Evaluation plan of the numba kernels (:func:`plan`)
----------------------------------------------------
The outputs are sorted by exponent (largest first) and grouped around a *base* exponent
:math:`\\beta_0`: one of the fast exponents 2, 1.5, 1 (powers :math:`\\Delta^2`,
:math:`|\\Delta|\\sqrt{|\\Delta|}`, :math:`|\\Delta|`, no transcendental call) when it lies at most
0.05 above the group's largest exponent, otherwise that exponent itself
(:math:`|\\Delta|^{\\beta_0} = \\exp(\\beta_0 \\log|\\Delta|)`). Output :math:`j` of the group uses

.. math::

    |\\Delta|^{\\beta_j} = |\\Delta|^{\\beta_0} \\, e^{\\varepsilon_j \\log|\\Delta|}
    \\approx |\\Delta|^{\\beta_0} \\sum_{m=0}^{M_j} \\frac{(\\varepsilon_j \\log|\\Delta|)^m}{m!},
    \\qquad \\varepsilon_j = \\beta_j - \\beta_0 \\le 0,

with the smallest degree :math:`M_j \\le 6` whose Lagrange remainder bound keeps the error of the
reduced distance below :math:`2^{-53}` (absolute) for every :math:`0 < \\Delta \\le \\Delta_{max}`:
for :math:`\\Delta \\le 1` the bound
:math:`\\theta_{max} e^{\\beta_j u} |\\varepsilon_j u|^{M+1} / (M+1)!`, :math:`u = \\log\\Delta`,
peaks at :math:`u = -(M+1)/\\beta_j`; for :math:`\\Delta > 1` (extrapolation) it grows with
:math:`\\Delta` and is taken at :math:`\\Delta_{max}`. The expansion is therefore exact to rounding,
not an approximation: its error is below that of the exponential itself. An output whose
exponent needs more terms opens a new group. When every output of a group has the same exponent
the polynomial is applied once to the block of powers.

Why: fitted exponents of the (very smooth) elastic responses end just below 2 (1.999..., where the
Gaussian correlation matrix reaches its conditioning limit), all different. The direct form costs
:math:`d` exponentials per output and training point (:math:`|\\Delta|^{\\beta_j}` for each
dimension); with base 2 and a polynomial of degree 3-5 it costs :math:`d` logarithms per training
point for all outputs together, plus a few multiply-adds per output. The exponent cannot simply be
rounded to 2: near the conditioning limit the terms of the kriging sums reach 1e7 times the
outputs, and predicting with 2 instead of 1.99991 moves the readings by 2.6 % (median). For the
same reason the kernels stay in float64.

Arithmetic: the exponential is a branch-free polynomial (``_exp_neg``: Taylor series of
:math:`e^{-s/64}` raised to the power 64 by six squarings, relative error below 1e-14 for
:math:`|s| \\le 40`; larger reduced distances are clamped to 40, i.e. a correlation of 4e-18 stands
for 0) and the logarithm works on the IEEE-754 bits without a division (``_fill_logs``) because the
numba build has no vector math library, and a libm call per entry would keep the loops scalar.

Threads (:mod:`podkrig.parallel`): a small batch (a GA population) runs on one thread, without
waking the pool; a large one is cut into chunks, several per thread, spread over
the numba threads (``prange``), never more threads than cores available. Each point is computed by
one thread in a fixed order, so results do not depend on the number of threads or the chunking,
and no ``(n_pred, n)`` matrix is formed for the mean.

Set the environment variable ``PODKRIG_DISABLE_NUMBA=1`` (or pass ``use_numba=False`` to the
estimator) to use the NumPy twins only. First call of a numba kernel compiles it (a few seconds,
cached on disk afterwards).
"""

import math
import os

import numpy as np

from podkrig import parallel

EXPONENTIAL, POWER = 0, 1
_CHUNK = 512  # prediction points per block in the NumPy twins (bounds the (chunk, n, d) scratch)
_FAST = ((2.0, 3), (1.5, 2), (1.0, 1))  # fast base exponents and their kernel codes (0: generic)
_SNAP = 0.05  # largest gap between a fast base exponent and the group's largest exponent
NQ = 7  # coefficients of the exponent polynomial at most (degree 6)
_TOL = 2.0**-53  # bound of the expansion error of the reduced distance (absolute)


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


# ----------------------------------------------------------------------------- evaluation plan


def _degree(theta_max, beta, base, log_dmax):
    """Smallest degree ``M < NQ`` of the Taylor polynomial of ``exp((beta - base) log|dx|)`` whose
    remainder keeps ``theta_max |dx|**base * remainder`` below ``_TOL`` for ``0 < |dx| <= e**log_dmax``;
    ``None`` if even degree ``NQ - 1`` does not."""
    a = base - beta
    if a == 0.0:
        return 0
    for M in range(NQ):
        q = M + 1
        bound = theta_max * (q * a / (math.e * beta)) ** q / math.factorial(q)  # peak for |dx| <= 1
        if log_dmax > 0.0:  # |dx| > 1 (extrapolation): increasing in |dx|
            bound = max(bound, theta_max * math.exp(base * log_dmax) * (a * log_dmax) ** q / math.factorial(q))
        if bound <= _TOL:
            return M
    return None


def _taylor(eps, M):
    """Coefficients ``eps**m / m!``, ``m = 0..M``, zero-padded to ``NQ``."""
    c = np.zeros(NQ)
    c[: M + 1] = [eps**m / math.factorial(m) for m in range(M + 1)]
    return c


def plan(theta, beta, delta_max=1.0):
    """Grouping of the outputs for the numba kernels (see the module notes).

    Parameters
    ----------
    theta : ndarray of shape (n_outputs, d)
        :math:`a_k^{-\\beta}` per output.
    beta : ndarray of shape (n_outputs,)
    delta_max : float
        Largest :math:`|x_k - x'_k|` of the batch (1 inside the unit cube; more when
        extrapolating).

    Returns
    -------
    dict
        ``order`` (outputs by decreasing exponent), and in that order: ``theta``, ``coef``
        ``(n_outputs, NQ)`` and ``nq`` ``(n_outputs,)`` (per-output polynomial), ``g_start``
        ``(n_groups + 1,)``, ``g_code`` (0 generic base, 1/2/3 for the base 1/1.5/2), ``g_base``,
        ``g_fold`` ``(n_groups, NQ)`` and ``g_nfold`` (polynomial applied to the block of powers),
        ``need_logs``.
    """
    theta = np.asarray(theta, dtype=float).reshape(len(beta), -1)
    beta = np.asarray(beta, dtype=float)
    n_out = len(beta)
    order = np.argsort(-beta, kind="stable")
    log_dmax = math.log(delta_max) if delta_max > 1.0 else 0.0
    thmax = theta.max(axis=1)
    coef, nq = np.zeros((n_out, NQ)), np.ones(n_out, dtype=np.int64)
    coef[:, 0] = 1.0
    g_start, g_code, g_base, g_fold, g_nfold = [0], [], [], [], []
    pos = 0
    while pos < n_out:
        b0 = float(beta[order[pos]])
        base, code = b0, 0
        for f, c in _FAST:
            if 0.0 <= f - b0 <= _SNAP and _degree(thmax[order[pos]], b0, f, log_dmax) is not None:
                base, code = f, c
                break
        start = pos
        degrees = []
        while pos < n_out:
            j = order[pos]
            M = _degree(thmax[j], float(beta[j]), base, log_dmax)
            if M is None:
                break
            degrees.append(M)
            pos += 1
        members = order[start:pos]
        if np.all(beta[members] == beta[members[0]]):  # one exponent: fold the polynomial into the powers
            g_fold.append(_taylor(float(beta[members[0]]) - base, degrees[0]))
            g_nfold.append(degrees[0] + 1)
        else:
            g_fold.append(_taylor(0.0, 0))
            g_nfold.append(1)
            for r, (j, M) in enumerate(zip(members, degrees)):
                coef[start + r] = _taylor(float(beta[j]) - base, M)
                nq[start + r] = M + 1
        g_start.append(pos)
        g_code.append(code)
        g_base.append(base)
    g_code = np.array(g_code, dtype=np.int64)
    g_nfold = np.array(g_nfold, dtype=np.int64)
    return {
        "order": order, "theta": np.ascontiguousarray(theta[order]), "coef": coef, "nq": nq,
        "g_start": np.array(g_start, dtype=np.int64), "g_code": g_code, "g_base": np.array(g_base),
        "g_fold": np.array(g_fold), "g_nfold": g_nfold,
        "need_logs": bool(np.any(g_code == 0) or np.any(g_nfold > 1) or np.any(nq > 1)),
    }


def _delta_max(Xp, Xt):
    """Largest coordinate difference between the two point sets."""
    if len(Xp) == 0:
        return 1.0
    return float(max(np.max(Xp.max(axis=0) - Xt.min(axis=0)), np.max(Xt.max(axis=0) - Xp.min(axis=0)), 0.0))


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
    def _fill_logs(Lg, E, xp, XtT):
        # Lg[k, i] = log|xp[k] - XtT[k, i]|; E is (n,) scratch. Branch-free and division-free so
        # that LLVM vectorises it (a libm log per entry would keep the loop scalar; a division
        # costs as much as the rest of the loop): split the IEEE-754 bits into exponent e and
        # mantissa m in [1, 2); scale m by 2^(-j/4), j = 0..4 chosen by comparisons, into
        # [2^(-1/8), 2^(1/8)); log(1 + f), |f| <= 0.0906, by its Taylor series to f^16 (truncation
        # < 2e-18). Error about 1e-16 absolute plus 2e-16 relative. |dx| = 0 gives about -709,
        # which the callers clamp like the -inf of log(0), or multiply by a zero power.
        d, n = XtT.shape
        for k in range(d):
            x = xp[k]
            row = Lg[k]
            for i in range(n):
                row[i] = abs(x - XtT[k, i])
            bits = row.view(np.int64)
            for i in range(n):
                b = bits[i]
                E[i] = ((b >> 52) & 0x7FF) - 1023
                bits[i] = (b & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000  # mantissa, exponent 0
            for i in range(n):
                m = row[i]
                e = E[i]
                c = 1.0
                if m > 1.0905077326652577:  # 2^(1/8)
                    c = 0.8408964152537145  # 2^(-1/4)
                    e += 0.25
                if m > 1.2968395546510096:  # 2^(3/8)
                    c = 0.7071067811865476
                    e += 0.25
                if m > 1.5422108254079407:  # 2^(5/8)
                    c = 0.5946035575013605
                    e += 0.25
                if m > 1.8340080864093424:  # 2^(7/8)
                    c = 0.5
                    e += 0.25
                f = m * c - 1.0
                q = -1.0 / 16.0
                q = q * f + 1.0 / 15.0
                q = q * f - 1.0 / 14.0
                q = q * f + 1.0 / 13.0
                q = q * f - 1.0 / 12.0
                q = q * f + 1.0 / 11.0
                q = q * f - 1.0 / 10.0
                q = q * f + 1.0 / 9.0
                q = q * f - 1.0 / 8.0
                q = q * f + 1.0 / 7.0
                q = q * f - 1.0 / 6.0
                q = q * f + 1.0 / 5.0
                q = q * f - 1.0 / 4.0
                q = q * f + 1.0 / 3.0
                q = q * f - 0.5
                q = q * f + 1.0
                row[i] = e * 0.6931471805599453 + f * q

    @njit(fastmath=True, inline="always", cache=True)
    def _fill_base(P, Lg, xp, XtT, code, base):
        # P[k, i] = |xp[k] - XtT[k, i]| ** base: codes 3, 2, 1 (base 2, 1.5, 1) without a
        # transcendental call; code 0 as exp(base log|dx|), clamped to [4e-18, 2e17]
        d, n = XtT.shape
        for k in range(d):
            x = xp[k]
            if code == 3:
                for i in range(n):
                    a = x - XtT[k, i]
                    P[k, i] = a * a
            elif code == 2:
                for i in range(n):
                    a = abs(x - XtT[k, i])
                    P[k, i] = a * math.sqrt(a)
            elif code == 1:
                for i in range(n):
                    P[k, i] = abs(x - XtT[k, i])
            else:
                for i in range(n):
                    P[k, i] = _exp_neg(min(max(-base * Lg[k, i], -40.0), 40.0))

    @njit(fastmath=True, inline="always", cache=True)
    def _poly_terms(P, Lg, k, c, nc, t, S, accumulate):
        # S[i] (+)= t * P[k, i] * sum_m c[m] Lg[k, i]**m, c[0] = 1, degree nc - 1 (<= 6). Branches
        # of fixed degree 0, 2, 4, 6 (zero-padded coefficients) keep each loop straight-line code
        # that LLVM vectorises.
        n = P.shape[1]
        if nc == 1:
            if accumulate:
                for i in range(n):
                    S[i] += t * P[k, i]
            else:
                for i in range(n):
                    S[i] = t * P[k, i]
        elif nc <= 3:
            c1, c2 = c[1], c[2]
            for i in range(n):
                x = Lg[k, i]
                v = t * P[k, i] * (1.0 + x * (c1 + x * c2))
                S[i] = S[i] + v if accumulate else v
        elif nc <= 5:
            c1, c2, c3, c4 = c[1], c[2], c[3], c[4]
            for i in range(n):
                x = Lg[k, i]
                v = t * P[k, i] * (1.0 + x * (c1 + x * (c2 + x * (c3 + x * c4))))
                S[i] = S[i] + v if accumulate else v
        else:
            c1, c2, c3, c4, c5, c6 = c[1], c[2], c[3], c[4], c[5], c[6]
            for i in range(n):
                x = Lg[k, i]
                v = t * P[k, i] * (1.0 + x * (c1 + x * (c2 + x * (c3 + x * (c4 + x * (c5 + x * c6))))))
                S[i] = S[i] + v if accumulate else v

    @njit(fastmath=True, inline="always", cache=True)
    def _group_powers(P, Lg, xp, XtT, code, base, fold, nfold):
        # block of |dx|^beta of a group: base powers, times the folded polynomial if any
        _fill_base(P, Lg, xp, XtT, code, base)
        if nfold > 1:
            for k in range(Lg.shape[0]):
                _poly_terms(P, Lg, k, fold, nfold, 1.0, P[k], False)

    @njit(fastmath=True, inline="always", cache=True)
    def _reduced(S, P, Lg, theta_j, coef_j, nq_j):
        # S_i = sum_k theta_k |dx_k|^beta_j (base power times the output's polynomial)
        for k in range(Lg.shape[0]):
            _poly_terms(P, Lg, k, coef_j, nq_j, theta_j[k], S, k > 0)

    @njit(fastmath=True, inline="always", cache=True)
    def _correlation_row(S, P, th, row, a):
        # row_i = exp(-sum_k th_k P[k, i]) and sum_i a_i row_i, for an output whose powers are
        # the group's (no polynomial of its own). P has _padded_rows(d) rows, those past
        # d = len(th) zeros. The sum over k runs in the order k = 0, 1, ... of _reduced, but its
        # last w = 4, 6 or 8 terms, the exponential, the row and the product with the weights
        # share one loop, and any leading terms (d > 8) go two at a time: S is stored once per two
        # leading dimensions instead of once per dimension, and the correlations are not read
        # back (the loop is bound by loads and stores otherwise: 1.3-1.7x fewer CPU seconds)
        d = th.shape[0]
        dp, n = P.shape
        w = dp if dp <= 8 else 8
        last = dp - w
        for k in range(0, last, 2):
            t0, t1 = th[k], th[k + 1]  # k + 1 < last <= d
            if k == 0:
                for i in range(n):
                    S[i] = t0 * P[0, i] + t1 * P[1, i]
            else:
                for i in range(n):
                    S[i] = S[i] + t0 * P[k, i] + t1 * P[k + 1, i]
        t0 = th[last] if last < d else 0.0
        t1 = th[last + 1] if last + 1 < d else 0.0
        t2 = th[last + 2] if last + 2 < d else 0.0
        t3 = th[last + 3] if last + 3 < d else 0.0
        acc = 0.0
        if w == 4:
            for i in range(n):
                r = _exp_neg(min(t0 * P[0, i] + t1 * P[1, i] + t2 * P[2, i] + t3 * P[3, i], 40.0))
                row[i] = r
                acc += a[i] * r
            return acc
        t4 = th[last + 4] if last + 4 < d else 0.0
        t5 = th[last + 5] if last + 5 < d else 0.0
        if w == 6:
            for i in range(n):
                r = _exp_neg(min(t0 * P[0, i] + t1 * P[1, i] + t2 * P[2, i] + t3 * P[3, i] + t4 * P[4, i]
                                 + t5 * P[5, i], 40.0))
                row[i] = r
                acc += a[i] * r
            return acc
        t6 = th[last + 6] if last + 6 < d else 0.0
        t7 = th[last + 7] if last + 7 < d else 0.0
        if last == 0:
            for i in range(n):
                r = _exp_neg(min(t0 * P[0, i] + t1 * P[1, i] + t2 * P[2, i] + t3 * P[3, i] + t4 * P[4, i]
                                 + t5 * P[5, i] + t6 * P[6, i] + t7 * P[7, i], 40.0))
                row[i] = r
                acc += a[i] * r
        else:
            for i in range(n):
                r = _exp_neg(min(S[i] + t0 * P[last, i] + t1 * P[last + 1, i] + t2 * P[last + 2, i]
                                 + t3 * P[last + 3, i] + t4 * P[last + 4, i] + t5 * P[last + 5, i]
                                 + t6 * P[last + 6, i] + t7 * P[last + 7, i], 40.0))
                row[i] = r
                acc += a[i] * r
        return acc

    @njit(fastmath=True, inline="always", cache=True)
    def _mean_rows(p0, p1, Xp, XtT, theta, coef, nq, g_start, g_code, g_base, g_fold, g_nfold,
                   need_logs, kind, alpha, mu, out, K, keep):
        # kriging means of the prediction points p0 <= p < p1, each in a fixed order; with
        # ``keep`` the covariance rows also go to K[j, p] (plan order), else to a scratch row:
        # the same loops on the same values, so the means are bitwise equal either way.
        d, n = XtT.shape
        # rows past d stay zero (_correlation_row): 4, 6 or 8 rows up to d = 8, d rounded up to even beyond
        P = np.zeros((4 if d <= 4 else 6 if d <= 6 else 8 if d <= 8 else d + d % 2, n))
        Lg = np.empty((d, n))
        S = np.empty(n)
        E = np.empty(n)
        R = np.empty(n)
        for p in range(p0, p1):
            if need_logs:
                _fill_logs(Lg, E, Xp[p], XtT)
            for g in range(g_code.shape[0]):
                _group_powers(P, Lg, Xp[p], XtT, g_code[g], g_base[g], g_fold[g], g_nfold[g])
                for j in range(g_start[g], g_start[g + 1]):
                    row = K[j, p] if keep else R
                    if kind == 0 and nq[j] == 1:
                        out[p, j] = _correlation_row(S, P, theta[j], row, alpha[j]) + mu[j]
                        continue
                    _reduced(S, P, Lg, theta[j], coef[j], nq[j])
                    if kind == 0:
                        for i in range(n):
                            row[i] = _exp_neg(min(S[i], 40.0))
                    else:
                        for i in range(n):
                            row[i] = -S[i]
                    acc = 0.0
                    for i in range(n):
                        acc += alpha[j, i] * row[i]
                    out[p, j] = acc + mu[j]

    # Entry points: the prediction points in chunks of ``chunk`` over the numba threads. On one
    # thread (small batches, see podkrig.parallel) the same compiled code runs without waking the
    # pool; a serial twin compiled apart would vectorise the fast-math sums differently and break
    # the bitwise independence of the thread count.

    @njit(parallel=True, fastmath=True, cache=True)
    def _predict_mean_parallel(Xp, XtT, theta, coef, nq, g_start, g_code, g_base, g_fold, g_nfold,
                               need_logs, kind, alpha, mu, out, K, keep, chunk):
        n_pred = Xp.shape[0]
        for b in prange((n_pred + chunk - 1) // chunk):
            _mean_rows(b * chunk, min(n_pred, (b + 1) * chunk), Xp, XtT, theta, coef, nq, g_start, g_code,
                       g_base, g_fold, g_nfold, need_logs, kind, alpha, mu, out, K, keep)


def _launch(kernel, work, n_pred, args, threads=None):
    """Run ``kernel(*args, chunk)`` on the threads :func:`podkrig.parallel.threads_for` gives for
    ``work`` units (``threads`` overrides it), in chunks of :func:`podkrig.parallel.chunk_size`."""
    threads = parallel.threads_for(work) if threads is None else int(threads)
    with parallel.numba_threads(threads):
        kernel(*args, max(1, n_pred) if threads <= 1 else parallel.chunk_size(n_pred, threads))


def predict_mean(Xp, Xt, theta, beta, kind, alpha, mu, use_numba=None, plan_unit=None, threads=None):
    """Kriging means of every output, ``(n_pred, n_outputs)``; see :func:`predict_mean_numpy`.

    The numba kernel follows :func:`plan` (outputs in any order). ``plan_unit``, the plan of these
    hyperparameters for batches inside the unit cube (``plan(theta, beta, 1.0)``), built once by
    the caller: it costs ~50 us, as much as predicting a few points. Batches reaching outside
    the unit cube get a plan of their own. Nothing passed in is modified. ``threads``: numba
    threads to use (default :func:`podkrig.parallel.threads_for` the batch: one for small batches).
    """
    return _mean_and_covariance(Xp, Xt, theta, beta, kind, alpha, mu, use_numba, plan_unit, threads, False)[0]


def predict_mean_and_covariance(Xp, Xt, theta, beta, kind, alpha, mu, use_numba=None, plan_unit=None,
                                threads=None):
    """Kriging means and the cross-covariances they are made of, in one pass.

    Returns
    -------
    mean : ndarray of shape (n_pred, n_outputs)
        Bitwise equal to :func:`predict_mean`.
    K : ndarray of shape (n_outputs, n_pred, n)
        Cross-covariance of each output (as :func:`cross_covariance_numpy`), for the kriging variance:
        one kernel call instead of one per output, and the reduced distances computed once.
    """
    return _mean_and_covariance(Xp, Xt, theta, beta, kind, alpha, mu, use_numba, plan_unit, threads, True)


def _mean_and_covariance(Xp, Xt, theta, beta, kind, alpha, mu, use_numba, plan_unit, threads, keep):
    Xp = np.ascontiguousarray(Xp, dtype=float)
    beta = np.ascontiguousarray(beta, dtype=float)
    if not numba_enabled(use_numba) or njit is None:
        mean = predict_mean_numpy(Xp, Xt, theta, beta, kind, alpha, mu)
        if not keep:
            return mean, None
        return mean, np.stack([cross_covariance_numpy(Xp, Xt, theta[j], float(beta[j]), kind)
                               for j in range(len(beta))])
    dmax = max(_delta_max(Xp, Xt), 1.0)
    pl = plan_unit if plan_unit is not None and dmax == 1.0 else plan(theta, beta, dmax)
    order = pl["order"]
    out = np.empty((Xp.shape[0], len(beta)))
    K = np.empty((len(beta), Xp.shape[0], Xt.shape[0]) if keep else (1, 1, 1))
    args = (
        Xp, np.ascontiguousarray(Xt.T), pl["theta"], pl["coef"], pl["nq"], pl["g_start"], pl["g_code"],
        pl["g_base"], pl["g_fold"], pl["g_nfold"], pl["need_logs"], int(kind),
        np.ascontiguousarray(np.asarray(alpha, dtype=float)[order]),
        np.ascontiguousarray(np.asarray(mu, dtype=float)[order]), out, K, keep,
    )
    _launch(_predict_mean_parallel, Xp.shape[0] * Xt.shape[0] * len(beta), Xp.shape[0], args,
            threads)
    result = np.empty_like(out)
    result[:, order] = out
    if not keep:
        return result, None
    K_out = np.empty_like(K)
    K_out[order] = K
    return result, K_out
