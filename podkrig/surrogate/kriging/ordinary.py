"""Ordinary kriging of several outputs, one set of hyperparameters per output column.

Conventions: inputs ``X`` of shape ``(n_samples, n_dims)`` in the unit cube (scale physical
parameters with :meth:`podkrig.parameters.ParameterSpace.to_unit`); outputs ``Y`` of shape
``(n_samples,)`` or ``(n_samples, n_outputs)``, e.g. the POD coefficients of the snapshots, in their
own units. Every output gets its own ranges (and exponent, with ``beta="fit"``), fitted
independently; they share the training points and the batched prediction kernel.

Example
-------
>>> import numpy as np
>>> from podkrig.surrogate.kriging import OrdinaryKriging
>>> rng = np.random.default_rng(0)
>>> X = rng.random((30, 2))
>>> Y = np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1], X[:, 0] * X[:, 1]])
>>> ok = OrdinaryKriging(beta=1.8).fit(X, Y)
>>> mean, std = ok.predict(X[:3], return_std=True)
>>> bool(np.allclose(mean, Y[:3], rtol=0, atol=1e-8)), bool(np.all(std < 1e-4))
(True, True)

Why one module of ~880 lines (half documentation): it is the estimator — settings, the
hyperparameter search per output, persistence and prediction — whose state must be read
together; the kriging system at given hyperparameters (also the lean one of all samples after a
subset fit) is :mod:`.system`, the kernels :mod:`._kernels`.
"""

import json
import logging
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
from scipy.linalg.blas import dtrmm
from scipy.optimize import minimize
from scipy.spatial.distance import pdist

from podkrig.parallel import one_blas_thread
from podkrig.exceptions import NotFittedError
from podkrig.surrogate.kriging import _kernels
from podkrig.surrogate.kriging.system import (
    FAIL,
    Objective,
    Pairs,
    SingularSystemError,
    correlation_factor,
    factor_exponential,
)
from podkrig.surrogate.kriging.variogram import (
    BETA_FIT_BOUNDS,
    EXPONENTIAL,
    check_beta,
    check_variogram,
)

logger = logging.getLogger(__name__)

DEFAULT_BETA = "fit-shared"  # why: see the ``beta`` parameter of OrdinaryKriging
CRITERIA = ("ml", "loo")
# why: L^-1 of every output is kept for the variance while it takes at most this much memory
# (6 outputs of 1 024 snapshots: 50 MB); beyond, triangular solves per output
EXPLICIT_INVERSE_BYTES = 64 * 2**20
# why: the (n_outputs, block, n) cross-covariances of one variance block stay this small; 8-64 MB
# changed the variance rate by < 15 % at n = 1 024 and 4 096 (4 outputs, one core): BLAS-bound
VARIANCE_BLOCK_BYTES = 16 * 2**20
# why (fit_subset="auto"): above this many samples the hyperparameters are fitted on a random
# subset of SUBSET_SIZE samples and the kriging system of all samples is factorised once per
# output at those hyperparameters. Measured in BENCHMARKS.md ("Training at scale", load
# 7-12 on 2 cores, CPU seconds): the exact fit costs O(n^3) per likelihood evaluation and ~100-300
# evaluations per output: 38 s at n = 512 (d = 8, 8 modes), 70 s at n = 1024 (FE, d = 5, 6 modes),
# tens of minutes at n = 2048. A subset of 512 matched or beat the exact fit on all 1024 FE
# samples (median 3.99e-4 against 4.46e-4, 14 s) where 256 lost 2.6x (1.17e-3); on the synthetic
# set at n = 2048, 512 gave 0.70 % against 0.84 % with 256. At n <= 512 the exact fit is
# affordable, and a subset of 256 was worse there (3.1 % against 2.2 %, synthetic).
EXACT_FIT_MAX_SAMPLES = 512
SUBSET_SIZE = 512
FIT_METHODS = ("exact", "subset")
# why: ranges fitted on a sparse subset can be too long for the denser full design (the correlation
# matrix of a smooth response reaches RCOND_MIN); they are shortened by this factor until the
# system of all samples is well conditioned, at most RANGE_SHRINK_STEPS times (0.8^30 = 1e-3)
RANGE_SHRINK = 0.8
RANGE_SHRINK_STEPS = 30


@dataclass(frozen=True)
class FitMethod:
    """How the hyperparameters of an :class:`OrdinaryKriging` were chosen (recorded in the file).

    Attributes
    ----------
    method : {"exact", "subset"}
        ``"exact"``: the criterion of all ``n_samples`` was optimised; ``"subset"``: the criterion
        of ``subset_size`` samples drawn at random without replacement (seed ``subset_seed``,
        ``numpy.random.default_rng``) was optimised, then the system of all samples factorised once.
    n_samples : int
        Training samples of the final kriging system.
    subset_size : int
        Samples of the hyperparameter fit (``n_samples`` for ``"exact"``).
    subset_seed : int or None
        Seed of the subset draw (None for ``"exact"``).
    range_scale : tuple of float
        Per output, the factor (a power of :data:`RANGE_SHRINK`, 1 mostly) applied to the
        subset's ranges to keep the system of all samples well conditioned; empty for ``"exact"``.
    """

    method: str
    n_samples: int
    subset_size: int
    subset_seed: int | None = None
    range_scale: tuple = ()

    def __post_init__(self):
        if self.method not in FIT_METHODS:
            raise ValueError(f"fit method must be one of {FIT_METHODS}; got {self.method!r}")
        object.__setattr__(self, "range_scale", tuple(float(v) for v in self.range_scale))

    def to_dict(self):
        """Plain-JSON form."""
        return {"method": self.method, "n_samples": int(self.n_samples), "subset_size": int(self.subset_size),
                "subset_seed": None if self.subset_seed is None else int(self.subset_seed),
                "range_scale": list(self.range_scale)}

    @classmethod
    def from_dict(cls, d):
        """Inverse of :meth:`to_dict`."""
        seed = d.get("subset_seed")
        return cls(str(d["method"]), int(d["n_samples"]), int(d["subset_size"]), None if seed is None else int(seed),
                   tuple(d.get("range_scale", ())))

    def describe(self):
        """One line for reports."""
        if self.method == "exact":
            return f"hyperparameters fitted on all {self.n_samples} samples (exact)"
        shrunk = sum(v < 1.0 for v in self.range_scale)
        return (f"hyperparameters fitted on a random subset of {self.subset_size} of the {self.n_samples} samples "
                f"(seed {self.subset_seed}), then one factorisation of all {self.n_samples}"
                + (f"; ranges of {shrunk} output(s) shortened (down to x{min(self.range_scale):.3g}) for conditioning"
                   if shrunk else ""))



@dataclass(frozen=True, eq=False)
class KrigingHyperparameters:
    """The fitted hyperparameters of an :class:`OrdinaryKriging`, one row per output (read-only).

    Attributes
    ----------
    variogram : {"exponential", "power"}
        Semivariogram model (:mod:`podkrig.surrogate.kriging.variogram`).
    nugget : float
        Nugget relative to the sill (exponential) or scale (power), dimensionless.
    ranges : ndarray of shape (n_outputs, n_dims)
        Correlation ranges :math:`a_k`, unit-cube units.
    beta : ndarray of shape (n_outputs,)
        Exponents :math:`\\beta` of the semivariogram.
    mu : ndarray of shape (n_outputs,)
        Generalised-least-squares mean :math:`\\hat\\mu`, output units.
    sigma2 : ndarray of shape (n_outputs,)
        Process variance (exponential) or variogram scale (power) :math:`\\hat\\sigma^2`,
        output units².
    """

    variogram: str
    nugget: float
    ranges: np.ndarray
    beta: np.ndarray
    mu: np.ndarray
    sigma2: np.ndarray

    def __post_init__(self):
        check_variogram(self.variogram)
        n_out = len(np.atleast_1d(self.beta))
        for name, ndim in (("ranges", 2), ("beta", 1), ("mu", 1), ("sigma2", 1)):
            a = np.array(getattr(self, name), dtype=float)  # a private copy, then frozen
            if a.ndim != ndim or a.shape[0] != n_out:
                raise ValueError(f"KrigingHyperparameters.{name} must have {ndim} dimension(s) and "
                                 f"{n_out} rows (one per output); got shape {a.shape}")
            a.flags.writeable = False
            object.__setattr__(self, name, a)
        object.__setattr__(self, "nugget", float(self.nugget))

    def __eq__(self, other):
        """Value equality: same variogram and nugget, bitwise equal arrays."""
        if not isinstance(other, KrigingHyperparameters):
            return NotImplemented
        return (self.variogram, self.nugget) == (other.variogram, other.nugget) and all(
            np.array_equal(getattr(self, k), getattr(other, k)) for k in ("ranges", "beta", "mu", "sigma2"))

    __hash__ = None  # mutable-looking arrays inside: not hashable

    @property
    def n_outputs(self):
        return len(self.beta)

    @property
    def theta(self):
        """:math:`a_k^{-\\beta}` per output, ndarray of shape (n_outputs, n_dims)."""
        return self.ranges ** (-self.beta[:, None])

    def to_dict(self):
        """Plain-JSON form (lists of floats)."""
        return {"variogram": self.variogram, "nugget": self.nugget, "ranges": self.ranges.tolist(),
                "beta": self.beta.tolist(), "mu": self.mu.tolist(), "sigma2": self.sigma2.tolist()}

    @classmethod
    def from_dict(cls, d):
        """Inverse of :meth:`to_dict`."""
        return cls(d["variogram"], d["nugget"], d["ranges"], d["beta"], d["mu"], d["sigma2"])


class OrdinaryKriging:
    """Ordinary kriging with exponential-family or power semivariograms, one fit per output.

    Parameters
    ----------
    variogram : {"exponential", "power"}, default "exponential"
        Semivariogram model, see :mod:`podkrig.surrogate.kriging.variogram`.
    beta : float, "fit" or "fit-shared", default "fit-shared"
        Exponent of the semivariogram (bounded to [0.2, 2] for the exponential family, [0.2, 1.95]
        for the power model when fitted): a fixed value (the thesis compares 1.2, 1.5 and 1.8);
        ``"fit"``, estimated per output together with its ranges; or ``"fit-shared"``, estimated
        on the first output (the dominant POD coefficient) and kept for the others, whose ranges
        alone are fitted (one exponent per surrogate, as in the thesis). The default is
        ``"fit-shared"``, the one default of the estimator, ``podkrig surrogate build`` and the
        study file, chosen from the held-out measurements in ``BENCHMARKS.md`` (diagonal
        compression test, 4 free parameters, 200 held-out runs, 24 readings): at n = 256 it ties
        per-mode ``"fit"`` in median relative error (1.81e-3 against 1.83e-3; p95 7.9e-3 against
        8.0e-3) and trains 4x faster (1.0-1.2 s against 4.1-4.9 s), and the region of
        equivalence (10⁶ mean predictions) takes 2.8 s against 5.1 s, because one block of powers
        serves every mode. Per-mode ``"fit"`` is slightly more accurate with few samples (median
        1.21e-2 against 1.24e-2 at n = 64, 5.20e-3 against 5.51e-3 at n = 128) and its variance a
        little more honest (90 % against 87 % of held-out outputs within ±2 sigma at n = 64): choose
        it for small designs when the predictive variance matters. Fixed exponents lose accuracy
        (1.8: 4.2e-3 at n = 256). Exponents 1, 1.5 and 2 need no transcendental function in the
        prediction kernel, and exponents within about 0.01 below 2 (as fitted here) one logarithm
        per training point and dimension for all outputs together (see
        :mod:`podkrig.surrogate.kriging._kernels` and ``BENCHMARKS.md``).
    ranges : float or array_like of shape (n_dims,) or (n_outputs, n_dims), default 0.5
        Correlation ranges :math:`a_k` in unit-cube units: the starting point of the optimiser, or
        the values used when ``optimizer=None``.
    nugget : float, default 0.0
        Nugget relative to the sill (added to the diagonal of the correlation matrix). 0 gives an
        exact interpolator; use a small positive value (e.g. 1e-8) for noisy or duplicated samples.
    criterion : {"ml", "loo"}, default "ml"
        Hyperparameters by maximum concentrated likelihood ([1]_; for the intrinsic power model,
        the likelihood of the n − 1 contrasts) or by the closed-form leave-one-out error [2]_.
        Either is searched on each output divided by its standard deviation: the fitted ranges
        and exponent do not depend on the output's unit.
    optimizer : "l-bfgs-b", callable or None, default "l-bfgs-b"
        Minimiser of the criterion over the log-ranges (and beta), run from every starting point
        (and for the polish of an exponent that ends near its upper bound).
        ``"l-bfgs-b"``: :func:`l_bfgs_b` (SciPy's L-BFGS-B with the analytic gradient, at most 200
        iterations). A callable ``optimizer(objective, x0, bounds) -> (x, f)``, as scikit-learn's
        ``GaussianProcessRegressor(optimizer=...)`` allows: ``objective(x)`` returns the criterion
        and its gradient ``(f, grad)`` at ``x`` (shape ``(n_params,)``; a singular system gives
        :data:`~podkrig.surrogate.kriging.system.FAIL` and a zero gradient), ``x0`` is the
        starting point and ``bounds`` a list of ``(lower, upper)`` per parameter; it returns the
        best point found and its criterion. ``None`` keeps ``ranges`` (no search). A callable is
        not written to a surrogate file (its name is); a loaded surrogate predicts but is not
        refitted with it.
    n_restarts : int, default 1
        Extra random starting points of the optimiser, on top of ``ranges`` and the previous
        output's optimum.
    range_bounds : tuple of float, default (0.01, 100.0)
        Bounds of the ranges during optimisation, unit-cube units.
    random_state : int, default 0
        Seed of the random restarts.
    use_numba : bool or None, default None
        Use the numba prediction kernels (None: unless ``PODKRIG_DISABLE_NUMBA=1``).
    fit_subset : "auto", int or None, default "auto"
        Training at scale. An integer ``m``: when there are more than ``m`` samples, the
        hyperparameters are fitted (by ``criterion``) on ``m`` samples drawn at random without
        replacement (seed ``random_state``), then the kriging system of *all* samples is built and
        factorised once per output at those hyperparameters (mean, variance, kriging weights and
        leave-one-out residuals of all samples). ``None``: always the exact fit on all samples.
        ``"auto"``: :data:`SUBSET_SIZE` above :data:`EXACT_FIT_MAX_SAMPLES` samples (with an
        optimizer), else exact. The choice is kept in ``fit_method_`` and in the surrogate file.

    Attributes
    ----------
    X_ : ndarray of shape (n_samples, n_dims)
        Training inputs (a copy).
    hyperparameters_ : KrigingHyperparameters
        The fitted hyperparameters (variogram, nugget, ranges, exponents, mean, variance) in one
        read-only value object; ``ranges_``, ``beta_``, ``mu_`` and ``sigma2_`` are views of it.
    alpha_ : ndarray of shape (n_outputs, n_samples)
        Kriging weights :math:`Q y`.
    L_ : ndarray of shape (n_outputs, m, m)
        Lower Cholesky factors (``m = n_samples`` for the exponential family, ``n_samples - 1`` for
        the power model, see ``factor``).
    Q_ : ndarray of shape (n_outputs, n_samples, n_samples)
        Projected precision (block of the inverse bordered kriging matrix), used for variances.
    loo_residuals_ : ndarray of shape (n_samples, n_outputs)
        Closed-form leave-one-out residuals :math:`y_i - \\hat y_{-i}(x_i)` at the fitted
        hyperparameters (Dubrule 1983).
    loo_variance_ : ndarray of shape (n_samples, n_outputs)
        Kriging variances of those leave-one-out predictions, output units².
    criterion_ : ndarray of shape (n_outputs,)
        Final criterion value per output (of all samples, at the final hyperparameters).
    fit_method_ : FitMethod
        Exact or subset fit, with the subset size and seed.
    subset_index_ : ndarray of shape (subset_size,)
        Rows of ``X_`` the hyperparameters were fitted on (all rows for the exact fit).

    Notes
    -----
    Predictor and variance of ordinary kriging [1]_, with the (generalised) covariance vector
    :math:`k(x)` and the bordered-system block :math:`Q`:

    .. math::

        \\hat y(x) = \\hat\\mu + k(x)^T Q y, \\qquad
        \\sigma^2_K(x) = \\hat\\sigma^2 \\left[k_0 + c_0 - 2 q_1^T k(x) - k(x)^T Q k(x)\\right],

    which for the exponential family reduces to Sacks et al.'s
    :math:`\\hat\\sigma^2 [1 - r^T R^{-1} r + (1 - 1^T R^{-1} r)^2 / 1^T R^{-1} 1]`. The concentrated
    likelihood is :math:`-2 \\log L = m \\log \\hat\\sigma^2 + \\log\\det R`,
    :math:`\\hat\\sigma^2 = y^T Q y / m`; the leave-one-out residuals are
    :math:`e_i = (Q y)_i / Q_{ii}`. Both gradients come from
    :math:`\\partial Q = -Q \\, \\partial K \\, Q`. With ``criterion="loo"`` the variance is
    calibrated on the leave-one-out residuals,
    :math:`\\hat\\sigma^2 = \\frac{1}{n} \\sum_i e_i^2 Q_{ii}`.

    Cost: ``fit`` forms and factorises one ``n × n`` matrix per objective evaluation
    (:math:`O(n^3)`; with a subset of ``m`` samples, :math:`O(m^3)` per evaluation plus one
    :math:`O(n^3)` factorisation and triangular inverse per output; the exponential family then keeps
    only the Cholesky factors, ``n²`` doubles per output, and the surrogate file stores the
    hyperparameters and weights, the factors being rebuilt at load); ``predict`` of the mean is :math:`O(n_{pred} \\, n \\, d)` per output without
    forming the cross-covariance matrix (one exponential per output and training point, plus one
    logarithm per training point and dimension for exponents other than 1, 1.5 and 2; numba
    threads split the prediction points, with results independent of their number);
    ``return_std`` forms it and costs :math:`O(n_{pred} n^2)` per output: :math:`n^2` flops per point
    for :math:`\\lVert L^{-1} k \\rVert^2`, at the BLAS rate (about 2 700 points per CPU second per
    output at n = 4 096 on one AVX-512 core), once for all outputs whose hyperparameters coincide.

    References
    ----------
    .. [1] J. Sacks, W. J. Welch, T. J. Mitchell, H. P. Wynn, "Design and analysis of computer
       experiments", Statistical Science 4(4), 409–423, 1989.
    .. [2] O. Dubrule, "Cross validation of kriging in a unique neighborhood", Mathematical
       Geology 15(6), 687–699, 1983.
    .. [3] The thesis, ch. 4 (ordinary kriging of POD coefficients).
    """

    def __init__(self, variogram="exponential", beta=DEFAULT_BETA, ranges=0.5, nugget=0.0, criterion="ml",
                 optimizer="l-bfgs-b", n_restarts=1, range_bounds=(1e-2, 1e2), random_state=0,
                 use_numba=None, fit_subset="auto"):
        self.variogram = variogram
        self.beta = beta
        self.ranges = ranges
        self.nugget = nugget
        self.criterion = criterion
        self.optimizer = optimizer
        self.n_restarts = n_restarts
        self.range_bounds = range_bounds
        self.random_state = random_state
        self.use_numba = use_numba
        self.fit_subset = fit_subset

    # ------------------------------------------------------------------ parameters
    def get_params(self, deep=True):
        """Hyperparameters as a dict (scikit-learn convention)."""
        return {k: getattr(self, k) for k in (
            "variogram", "beta", "ranges", "nugget", "criterion", "optimizer", "n_restarts",
            "range_bounds", "random_state", "use_numba", "fit_subset")}

    def set_params(self, **params):
        """Set hyperparameters; unknown names are an error."""
        valid = self.get_params()
        for k, v in params.items():
            if k not in valid:
                raise ValueError(f"unknown parameter {k!r} of OrdinaryKriging; valid: {sorted(valid)}")
            setattr(self, k, v)
        return self

    def _check_settings(self, d, n_out):
        kind = check_variogram(self.variogram)
        fit_beta = isinstance(self.beta, str)
        if fit_beta and self.beta not in ("fit", "fit-shared"):
            raise ValueError(f"beta must be a number in (0, 2], 'fit' or 'fit-shared'; got {self.beta!r}")
        beta = None if fit_beta else check_beta(self.beta, self.variogram)
        if self.criterion not in CRITERIA:
            raise ValueError(f"criterion must be one of {CRITERIA}; got {self.criterion!r}")
        if not (callable(self.optimizer) or self.optimizer in ("l-bfgs-b", None)):
            raise ValueError(f"optimizer must be 'l-bfgs-b', a callable or None; got {self.optimizer!r}")
        if fit_beta and self.optimizer is None:
            raise ValueError("beta='fit' needs an optimizer; give a fixed beta or optimizer='l-bfgs-b'")
        if not (np.isscalar(self.nugget) and np.isfinite(self.nugget) and self.nugget >= 0):
            raise ValueError(f"nugget must be a finite number >= 0; got {self.nugget!r}")
        lo, hi = (float(b) for b in self.range_bounds)
        if not 0 < lo < hi:
            raise ValueError(f"range_bounds must satisfy 0 < lower < upper; got {self.range_bounds!r}")
        if isinstance(self.n_restarts, bool) or not isinstance(self.n_restarts, (int, np.integer)) \
                or self.n_restarts < 0:
            raise ValueError(f"n_restarts must be an integer >= 0; got {self.n_restarts!r}")
        fs = self.fit_subset
        if not (fs is None or fs == "auto" or (isinstance(fs, (int, np.integer)) and not isinstance(fs, bool)
                                               and fs >= 3)):
            raise ValueError(f"fit_subset must be 'auto', None or an integer >= 3 (samples of the "
                             f"hyperparameter fit); got {fs!r}")
        r = np.asarray(self.ranges, dtype=float)
        if r.ndim == 0:
            r = np.full((n_out, d), float(r))
        elif r.shape == (d,):
            r = np.tile(r, (n_out, 1))
        elif r.shape != (n_out, d):
            raise ValueError(f"ranges must be a number or have shape ({d},) or ({n_out}, {d}); got {r.shape}")
        if not np.all(np.isfinite(r) & (r > 0)):
            raise ValueError(f"ranges must be finite and > 0; got {self.ranges!r}")
        return kind, beta, r, (lo, hi)

    # ------------------------------------------------------------------ fit
    def fit(self, X, Y):
        """Fit one kriging interpolant per output column.

        Parameters
        ----------
        X : array_like of shape (n_samples, n_dims)
            Training inputs in the unit cube.
        Y : array_like of shape (n_samples,) or (n_samples, n_outputs)
            Training outputs, any units.

        Returns
        -------
        self : OrdinaryKriging

        Raises
        ------
        ValueError
            Bad shapes or values, inputs outside the unit cube, duplicate samples with
            ``nugget=0``, or a singular kriging system at every starting point.
        """
        # one BLAS thread: the matrices are small (n <= a few thousand), and on a shared machine
        # a multi-threaded BLAS in many tiny calls is 20-60x slower than a single thread
        with one_blas_thread():
            return self._fit(X, Y)

    def _fit(self, X, Y):
        X = np.array(X, dtype=float, copy=True)
        Y = np.array(Y, dtype=float, copy=True)
        if X.ndim != 2:
            raise ValueError(f"X must have shape (n_samples, n_dims); got shape {X.shape}")
        self._y_1d = Y.ndim == 1
        Y = Y.reshape(len(Y), -1) if Y.ndim == 1 else Y
        if Y.ndim != 2 or Y.shape[0] != X.shape[0]:
            raise ValueError(f"Y must have shape ({X.shape[0]},) or ({X.shape[0]}, n_outputs); got {Y.shape}")
        n, d = X.shape
        if n < 3:
            raise ValueError(f"ordinary kriging needs at least 3 samples; got {n}")
        if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
            raise ValueError("X and Y must be finite; found NaN or inf (drop failed FE runs first)")
        if X.min() < -1e-9 or X.max() > 1 + 1e-9:
            raise ValueError(
                f"kriging inputs must lie in the unit cube; got values in [{X.min():g}, {X.max():g}]; "
                "scale them with ParameterSpace.to_unit (PODKriging does this for you)"
            )
        kind, beta, ranges0, (lo, hi) = self._check_settings(d, Y.shape[1])
        if self.nugget == 0:
            _check_duplicates(X)
        m = self._subset_size(n)
        if m is not None:
            return self._fit_subset(X, Y, m, kind)
        i, j = np.triu_indices(n, 1)
        A = np.abs(X[i] - X[j])
        logA = None
        if beta is None:  # log|Δx| for the exponent's gradient, 0 where a coordinate repeats
            logA = np.log(np.where(A > 0, A, 1.0))  # (there A^β log A = 0 anyway)
        pairs = Pairs(n, (i, j), A, logA, {})
        rng = np.random.default_rng(self.random_state)
        fit_beta = beta is None
        bfit_lo, bfit_hi = BETA_FIT_BOUNDS[self.variogram]
        bounds = [(np.log(lo), np.log(hi))] * d + ([(bfit_lo, bfit_hi)] if fit_beta else [])

        n_out = Y.shape[1]
        ranges, betas, mus, sigma2s = np.empty((n_out, d)), np.empty(n_out), np.empty(n_out), np.empty(n_out)
        self.alpha_ = np.empty((n_out, n))
        m = n if kind == EXPONENTIAL else n - 1
        self.L_ = np.empty((n_out, m, m))
        self.Q_ = np.empty((n_out, n, n))
        self.q1_ = np.empty((n_out, n))
        self.c0_ = np.empty(n_out)
        self.criterion_ = np.empty(n_out)
        self.loo_residuals_ = np.empty((n, n_out))
        self.loo_variance_ = np.empty((n, n_out))
        self.n_evaluations_ = np.zeros(n_out, dtype=int)
        optimize = l_bfgs_b if self.optimizer == "l-bfgs-b" else self.optimizer
        previous = None
        beta0 = 1.8 if kind == EXPONENTIAL else 1.5
        shared = self.beta == "fit-shared"
        for col in range(n_out):
            constant = _is_constant(Y[:, col])
            # the criterion is searched on the output divided by its standard deviation, and the
            # mean, weights and variance scaled back: -2 log L of c y is that of y plus m log c²,
            # a constant that L-BFGS-B's relative stopping test (ftol × |f|) does not ignore, so
            # without it the ranges and exponent fitted to c y differed from those of y (×7.3:
            # β 1.998 → 1.9997, σ up to 2.2× on a triplet surrogate's POD coefficients)
            scale = 1.0 if constant else float(np.std(Y[:, col]))
            y = Y[:, col] / scale
            if shared and col > 0:
                # "fit-shared": the exponent of the first (dominant) output serves every output
                beta, fit_beta, bounds = float(betas[0]), False, bounds[:d]
                previous = None if previous is None else previous[:d]
            obj = Objective(pairs, y, kind, float(self.nugget), self.criterion, beta)
            start = np.log(np.clip(ranges0[col], lo, hi))
            if fit_beta:
                start = np.append(start, beta0)
            if self.optimizer is None or constant:
                params = start
                try:
                    st = obj.state(params)[0]
                except SingularSystemError as e:
                    raise self._singular(X, col, params, d, e) from e
            else:
                starts = [start] + ([previous] if previous is not None else [])
                for _ in range(self.n_restarts):
                    s = rng.uniform(np.log(max(lo, 0.05)), np.log(min(hi, 5.0)), d)
                    starts.append(np.append(s, rng.uniform(bfit_lo, bfit_hi)) if fit_beta else s)
                best = None
                counted = _Counted(obj)
                for s in starts:
                    res = optimize(counted, s, bounds)
                    if res[1] < FAIL and (best is None or res[1] < best[1]):
                        best = res
                self.n_evaluations_[col] += counted.calls
                if best is None:
                    raise self._singular(X, col, start, d, None)
                params = np.asarray(best[0], dtype=float)
                if fit_beta and bfit_hi - params[-1] < 0.02:
                    # L-BFGS-B stops just short of an active upper bound: polish the ranges at the
                    # bound and keep it unless clearly worse (0.01 in -2 log L, or 0.1 % of the LOO
                    # error); an exact 2.0 also uses the fast kernel path
                    fixed = _Counted(Objective(pairs, y, kind, float(self.nugget), self.criterion, bfit_hi))
                    x, fun = (l_bfgs_b(fixed, params[:-1], bounds[:-1], maxiter=50) if optimize is l_bfgs_b
                              else optimize(fixed, params[:-1], bounds[:-1]))
                    self.n_evaluations_[col] += fixed.calls
                    tol = 0.01 if self.criterion == "ml" else 1e-3 * abs(best[1])
                    if fun <= best[1] + tol:
                        params = np.append(np.asarray(x, dtype=float), bfit_hi)
                previous = params
                st = obj.state(params)[0]
            psi, b = obj.split(params)
            ranges[col] = np.exp(psi)
            betas[col] = b
            mus[col] = st.mu * scale
            self.alpha_[col] = st.alpha * scale
            self.L_[col] = st.L
            self.Q_[col] = st.Q
            self.q1_[col] = st.q1
            self.c0_[col] = st.c0
            # the criterion of the output as given: -2 log L gains m log scale² (LOO is scale-free)
            self.criterion_[col] = obj.value(st) + (st.m * np.log(scale**2) if self.criterion == "ml" else 0.0)
            dq = np.diag(st.Q)
            e = st.alpha * scale / dq
            self.loo_residuals_[:, col] = e
            if constant:
                sigma2s[col] = 0.0
            elif self.criterion == "loo":
                sigma2s[col] = float(np.mean(e * e * dq))
            else:
                sigma2s[col] = st.sigma2 * scale**2
            self.loo_variance_[:, col] = sigma2s[col] / dq
        self.hyperparameters_ = KrigingHyperparameters(self.variogram, float(self.nugget), ranges, betas, mus, sigma2s)
        self.X_ = X
        self.n_features_in_ = d
        self.n_outputs_ = n_out
        self.kind_ = kind
        self.fit_method_ = FitMethod("exact", n, n)
        self.subset_index_ = np.arange(n)
        self._prepare_prediction()
        logger.info("kriging fitted: %d samples, %d dims, %d outputs, %d criterion evaluations",
                    n, d, n_out, int(self.n_evaluations_.sum()))
        return self

    def _subset_size(self, n):
        """Samples of the hyperparameter fit when it runs on a subset, else None (exact fit)."""
        fs = self.fit_subset
        if fs is None:
            return None
        if fs == "auto":
            return SUBSET_SIZE if n > EXACT_FIT_MAX_SAMPLES and self.optimizer is not None else None
        return int(fs) if n > int(fs) else None

    def _fit_subset(self, X, Y, m, kind):
        """Hyperparameters on ``m`` random samples, then the system of all samples at them.

        The subset fit is the exact fit of a copy of this estimator (same settings) on the rows
        ``subset_index_``; the final system is :meth:`_factor_all` of all rows.
        """
        n, d = X.shape
        idx = np.sort(np.random.default_rng(self.random_state).choice(n, m, replace=False))
        sub = type(self)(**{**self.get_params(), "fit_subset": None})._fit(X[idx], Y[idx])
        hp = sub.hyperparameters_
        self.n_evaluations_ = sub.n_evaluations_.copy()
        self.X_, self.kind_ = X, kind
        self.n_features_in_, self.n_outputs_ = d, Y.shape[1]
        self.fit_method_ = FitMethod("subset", n, m, int(self.random_state))
        self.subset_index_ = idx
        ranges, mus, sigma2s, scale = self._factor_all(X, Y, hp.ranges, hp.beta)
        self.fit_method_ = FitMethod("subset", n, m, int(self.random_state), tuple(scale))
        self.hyperparameters_ = KrigingHyperparameters(self.variogram, float(self.nugget), ranges, hp.beta,
                                                       mus, sigma2s)
        self._prepare_prediction()
        logger.info("kriging fitted: hyperparameters on %d of %d samples (%d criterion evaluations), one "
                    "factorisation of all %d per output; %d dims, %d outputs", m, n,
                    int(self.n_evaluations_.sum()), n, d, self.n_outputs_)
        return self

    def _factor_all(self, X, Y, ranges, betas):
        """The kriging system of all samples at fixed hyperparameters, output by output.

        Sets ``alpha_``, ``L_``, ``Q_``, ``q1_``, ``c0_``, ``criterion_``, ``loo_residuals_`` and
        ``loo_variance_`` as the exact fit does, and returns the final ranges ``(n_outputs, d)``,
        means and variances ``(n_outputs,)`` and the range scale per output. The exponential
        family never forms the pairwise arrays nor :math:`Q` (``Q_`` is empty,
        ``(n_outputs, 0, 0)``): see :func:`~podkrig.surrogate.kriging.system.factor_exponential`; where the correlation matrix of
        all samples is ill-conditioned the output's ranges are multiplied by
        :data:`RANGE_SHRINK` until it is not. The power model uses the exact fit's system
        (:func:`~podkrig.surrogate.kriging.system.factor`, memory :math:`O(n^2 d)`).
        """
        n, n_out = Y.shape
        kind, nugget = self.kind_, float(self.nugget)
        ranges = np.array(ranges, dtype=float)
        scale = np.ones(n_out)
        mus, sigma2s = np.empty(n_out), np.empty(n_out)
        self.alpha_, self.q1_ = np.empty((n_out, n)), np.empty((n_out, n))
        self.c0_, self.criterion_ = np.empty(n_out), np.empty(n_out)
        self.loo_residuals_, self.loo_variance_ = np.empty((n, n_out)), np.empty((n, n_out))
        if kind == EXPONENTIAL:
            self.L_, self.Q_ = np.empty((n_out, n, n)), np.empty((n_out, 0, 0))
            m_dof = n
        else:
            i, j = np.triu_indices(n, 1)
            pairs = Pairs(n, (i, j), np.abs(X[i] - X[j]), None, {})
            self.L_, self.Q_ = np.empty((n_out, n - 1, n - 1)), np.empty((n_out, n, n))
            m_dof = n - 1
        for col in range(n_out):
            y = Y[:, col]
            try:
                if kind == EXPONENTIAL:
                    for _ in range(RANGE_SHRINK_STEPS):
                        try:
                            alpha, mu, sigma2, q1, c0, dq, logdet = factor_exponential(
                                X, y, ranges[col] * scale[col], float(betas[col]), nugget, self.L_[col],
                                self.use_numba)
                            break
                        except SingularSystemError:
                            scale[col] *= RANGE_SHRINK
                    else:
                        raise SingularSystemError(f"still singular with the ranges shortened x{scale[col]:.2g}")
                    ranges[col] *= scale[col]
                    if scale[col] < 1.0:
                        logger.info("output %d: ranges shortened x%.3g for a well-conditioned system of %d samples",
                                    col, scale[col], n)
                else:
                    st = Objective(pairs, y, kind, nugget, self.criterion, float(betas[col])).state(np.log(ranges[col]))[0]
                    alpha, mu, sigma2, q1, c0, dq, logdet = st.alpha, st.mu, st.sigma2, st.q1, st.c0, np.diag(st.Q), st.logdet
                    self.L_[col], self.Q_[col] = st.L, st.Q
            except SingularSystemError as e:
                raise ValueError(
                    f"the kriging system of all {n} samples is singular for output {col} at the hyperparameters "
                    f"fitted on {self.fit_method_.subset_size} of them ({e}); set a small nugget (e.g. "
                    "nugget=1e-8) or fit on all samples (fit_subset=None)") from e
            e = alpha / dq
            self.alpha_[col], self.q1_[col], self.c0_[col] = alpha, q1, c0
            self.loo_residuals_[:, col] = e
            mus[col] = mu
            if _is_constant(y):
                sigma2s[col] = 0.0
            elif self.criterion == "loo":
                sigma2s[col] = float(np.mean(e * e * dq))
            else:
                sigma2s[col] = sigma2
            if self.criterion == "ml":
                self.criterion_[col] = m_dof * np.log(max(sigma2, 1e-300)) + logdet
            else:
                self.criterion_[col] = float(e @ e) / max(float(np.sum((y - y.mean()) ** 2)), np.finfo(float).tiny)
            self.loo_variance_[:, col] = sigma2s[col] / dq
        return ranges, mus, sigma2s, scale

    def _singular(self, X, col, params, d, cause):
        dist = pdist(X)
        k = int(np.argmin(dist))
        ranges = ", ".join(f"{v:.3g}" for v in np.exp(params[:d]))
        return ValueError(
            f"kriging system of output {col} is singular at ranges ({ranges}) "
            f"({cause or 'at every starting point'}); the closest samples are {dist[k]:.3g} apart "
            "(unit cube): remove duplicates or set a nugget (e.g. nugget=1e-8)"
        )

    # ------------------------------------------------------------------ predict
    def _check_fitted(self):
        if not hasattr(self, "hyperparameters_"):
            raise NotFittedError(
                "this OrdinaryKriging instance is not fitted yet; call fit(X, Y) before predict"
            )

    def _prepare_prediction(self):
        """Everything ``predict`` reuses, fixed by the fit: built here (at fit or load), never in
        ``predict``, which leaves the estimator untouched.

        - ``_theta``: :math:`a_k^{-\\beta}`, ``(n_outputs, n_dims)``;
        - ``_plan_unit``: the numba kernel's grouping of outputs for batches inside the unit cube
          (:func:`podkrig.surrogate.kriging._kernels.plan`, ~50 µs, as much as predicting a few points);
        - ``_ones_weights``: :math:`w_j = K_j^{-1} 1 = L_j^{-T} L_j^{-1} 1` per output (exponential
          family), ``(n_outputs, n)``;
        - ``_shared``: per output, the first output with a bitwise-equal Cholesky factor (equal
          ranges and exponent: fixed hyperparameters, or fitted ones that met), ``(n_outputs,)``;
          such outputs share one :math:`\\lVert L^{-1} k \\rVert^2` per point, the O(n²) part of
          the variance, so a POD of many modes at shared hyperparameters costs one mode's variance;
        - ``_L_inverse``: :math:`L_j^{-1}` per distinct factor, a dict output -> ``(n, n)`` when
          they take at most :data:`EXPLICIT_INVERSE_BYTES` (Fortran order, for ``dtrmm``; a triangular
          product is 2-3x faster than triangular solves for GA-sized batches; variances agree with the
          solves to ~1e-14 relative on the demo surrogate, see tests), else ``None``.
        """
        hp = self.hyperparameters_
        self._theta = hp.theta
        self._plan_unit = _kernels.plan(self._theta, hp.beta, 1.0)
        ones = np.ones(self.X_.shape[0])
        self._L_inverse = self._ones_weights = None
        self._shared = np.arange(self.n_outputs_)
        if self.kind_ == EXPONENTIAL:
            n = self.X_.shape[0]
            for j in range(1, self.n_outputs_):
                same = (i for i in range(j) if self._shared[i] == i and hp.beta[i] == hp.beta[j]
                        and np.array_equal(hp.ranges[i], hp.ranges[j]) and np.array_equal(self.L_[i], self.L_[j]))
                self._shared[j] = next(same, j)
            distinct = np.unique(self._shared)
            if len(distinct) * n * n * 8 <= EXPLICIT_INVERSE_BYTES:
                eye = np.eye(n)
                self._L_inverse = {int(j): np.asfortranarray(solve_triangular(self.L_[j], eye, lower=True,
                                                                              check_finite=False))
                                   for j in distinct}
            u = [solve_triangular(L, ones, lower=True, check_finite=False) for L in self.L_]
            self._ones_weights = np.stack([solve_triangular(L, uj, lower=True, trans="T", check_finite=False)
                                           for L, uj in zip(self.L_, u)])

    # read-only views of the fitted hyperparameters (the value object hyperparameters_ holds them)
    ranges_ = property(lambda self: self._fitted().ranges, doc="Fitted ranges, (n_outputs, n_dims).")
    beta_ = property(lambda self: self._fitted().beta, doc="Exponent per output, (n_outputs,).")
    mu_ = property(lambda self: self._fitted().mu, doc="Mean per output, (n_outputs,), output units.")
    sigma2_ = property(lambda self: self._fitted().sigma2, doc="Process variance per output, output units².")

    def _fitted(self):
        self._check_fitted()
        return self.hyperparameters_

    @property
    def theta_(self):
        """:math:`a_k^{-\\beta}` per output, ndarray of shape (n_outputs, n_dims)."""
        self._check_fitted()
        return self._theta

    # ------------------------------------------------------------------ persistence
    _ARRAYS = ("X_", "alpha_", "L_", "Q_", "q1_", "c0_", "criterion_", "loo_residuals_", "loo_variance_",
               "n_evaluations_")

    def to_arrays(self):
        """The fitted state as named arrays and scalar attributes (for HDF5, no pickle).

        Returns
        -------
        arrays : dict of str to ndarray
            ``X``, ``ranges``, ``beta``, ``mu``, ``sigma2``, ``alpha``, ``L``, ``Q``, ``q1``, ``c0``,
            ``criterion``, ``loo_residuals``, ``loo_variance``, ``n_evaluations`` (the names of
            surrogate files of schema 1), and ``subset_index``. A subset fit of the exponential
            family leaves out ``L`` and ``Q`` (``n²`` doubles per output: 4 GB for 8 modes of 8 192
            samples): :meth:`from_arrays` rebuilds the factors, bitwise as at the fit.
        attrs : dict of str to int, float, bool or str
            ``kind`` (kernel code), ``y_1d``, ``variogram``, ``nugget``, ``fit_method`` (JSON of
            :meth:`FitMethod.to_dict`).
        """
        self._check_fitted()
        hp = self.hyperparameters_
        arrays = {name.rstrip("_"): getattr(self, name) for name in self._ARRAYS}
        arrays.update(ranges=hp.ranges, beta=hp.beta, mu=hp.mu, sigma2=hp.sigma2, subset_index=self.subset_index_)
        if self._factors_rebuilt():
            del arrays["L"], arrays["Q"]
        attrs = {"kind": int(self.kind_), "y_1d": bool(self._y_1d), "variogram": hp.variogram,
                 "nugget": hp.nugget, "fit_method": json.dumps(self.fit_method_.to_dict())}
        return arrays, attrs

    def _factors_rebuilt(self):
        """Whether persistence leaves the factors out (subset fit, exponential family)."""
        return self.fit_method_.method == "subset" and self.kind_ == EXPONENTIAL

    @classmethod
    def from_arrays(cls, arrays, attrs, params):
        """Rebuild a fitted estimator from :meth:`to_arrays` output; predictions are bitwise identical.

        Parameters
        ----------
        arrays : mapping of str to array_like
            As returned by :meth:`to_arrays` (an HDF5 group works).
        attrs : mapping
            As returned by :meth:`to_arrays`; ``variogram`` and ``nugget`` may be missing (files of
            schema 1), then taken from ``params``.
        params : dict
            Settings, :meth:`get_params` of the fitted estimator.

        Raises
        ------
        KeyError, ValueError
            A missing array or inconsistent shapes.
        """
        ok = cls(**params)
        for name in cls._ARRAYS:
            if name.rstrip("_") in arrays:  # L and Q are absent after a subset fit
                setattr(ok, name, np.asarray(arrays[name.rstrip("_")][...]))
        variogram = str(attrs.get("variogram", ok.variogram))
        hp = ok.hyperparameters_ = KrigingHyperparameters(
            variogram, float(attrs.get("nugget", ok.nugget)),
            *(np.asarray(arrays[k][...], dtype=float) for k in ("ranges", "beta", "mu", "sigma2")))
        ok.kind_ = int(attrs["kind"])
        if ok.kind_ != check_variogram(variogram):
            raise ValueError(f"kernel code {ok.kind_} does not match the variogram {variogram!r}")
        ok._y_1d = bool(attrs["y_1d"])
        ok.n_outputs_ = ok.alpha_.shape[0]
        n = ok.X_.shape[0]
        ok.n_features_in_ = ok.X_.shape[1]
        # files written before the subset fit existed have no record: their fit was exact
        ok.fit_method_ = (FitMethod.from_dict(json.loads(attrs["fit_method"])) if "fit_method" in attrs
                          else FitMethod("exact", n, n))
        ok.subset_index_ = (np.asarray(arrays["subset_index"][...]) if "subset_index" in arrays else np.arange(n))
        if ok._factors_rebuilt():
            ok.L_, ok.Q_ = np.empty((ok.n_outputs_, n, n)), np.empty((ok.n_outputs_, 0, 0))
            with one_blas_thread():  # as at the fit: the same factor, bit for bit
                for col in range(ok.n_outputs_):
                    try:
                        correlation_factor(ok.X_, hp.ranges[col], float(hp.beta[col]), hp.nugget, ok.L_[col], ok.use_numba)
                    except SingularSystemError as e:
                        raise ValueError(f"stored hyperparameters of output {col} give a singular system ({e})") from e
        ok._prepare_prediction()
        return ok

    def predict(self, X, return_std=False):
        """Kriging mean (and standard deviation) at new inputs.

        Parameters
        ----------
        X : array_like of shape (n_pred, n_dims)
            Inputs in the unit cube.
        return_std : bool, default False
            Also return the kriging standard deviation.

        Returns
        -------
        mean : ndarray of shape (n_pred, n_outputs), or (n_pred,) for 1-D training outputs
        std : ndarray, same shape as ``mean``
            Only with ``return_std``; output units.

        Warns
        -----
        UserWarning
            When a variance is clearly negative (ill-conditioned system) and clipped to 0.
        """
        X = self._checked_points(X)
        hp = self.hyperparameters_
        if not return_std:
            mean = _kernels.predict_mean(X, self.X_, self._theta, hp.beta, self.kind_, self.alpha_, hp.mu,
                                         self.use_numba, plan_unit=self._plan_unit)
            return mean[:, 0] if self._y_1d else mean
        mean, var = self._mean_and_variance(X)
        std = np.sqrt(var)
        if self._y_1d:
            return mean[:, 0], std[:, 0]
        return mean, std

    def predict_variance(self, X):
        """Kriging variance, ndarray of shape (n_pred, n_outputs), output units² (clipped at 0).

        :math:`O(n_{pred} n^2)` per output, one BLAS thread (see :meth:`fit`); see
        :meth:`_mean_and_variance`.
        """
        return self._mean_and_variance(self._checked_points(X))[1]

    def _checked_points(self, X):
        self._check_fitted()
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.n_features_in_:
            raise ValueError(f"X must have shape (n_pred, {self.n_features_in_}); got {X.shape}")
        return X

    def _mean_and_variance(self, X):
        """Kriging means and variances ``(n_pred, n_outputs)`` each, from one kernel pass.

        The cross-covariances :math:`k_j(x)` of every output come from the same numba pass as the
        means (:func:`podkrig.surrogate.kriging._kernels.predict_mean_and_covariance`), in blocks
        of at most :data:`VARIANCE_BLOCK_BYTES`. Exponential family (Sacks et al. 1989, through
        the Cholesky factor :math:`K_j = L_j L_j^T`, better conditioned than the :math:`Q` form):

        .. math::

            \\sigma^2_j(x) = \\sigma^2_j \\left(1 - \\lVert L_j^{-1} k \\rVert^2
            + (1 - w_j^T k)^2 c_{0,j}\\right), \\qquad w_j = K_j^{-1} 1,

        with :math:`L_j^{-1}` applied as a stored explicit inverse (a triangular matrix product,
        BLAS ``dtrmm``; kept while all of them fit in :data:`EXPLICIT_INVERSE_BYTES`) or by
        triangular solves. Power variogram: :math:`\\sigma^2_j (c_{0,j} - 2 k^T q_{1,j} - k^T Q_j k)`.
        Variances clearly below zero (ill-conditioned system) warn and are clipped to 0.
        """
        hp = self.hyperparameters_
        n_pred, n = X.shape[0], self.X_.shape[0]
        mean = np.empty((n_pred, self.n_outputs_))
        var = np.empty((n_pred, self.n_outputs_))
        block = max(1, int(VARIANCE_BLOCK_BYTES // (8 * n * self.n_outputs_)))
        with one_blas_thread():
            for a in range(0, max(n_pred, 1), block):
                b = min(n_pred, a + block)
                mean[a:b], K = _kernels.predict_mean_and_covariance(
                    X[a:b], self.X_, self._theta, hp.beta, self.kind_, self.alpha_, hp.mu, self.use_numba,
                    plan_unit=self._plan_unit)
                var[a:b] = self._variance_from_covariance(K).T
        sigma2 = hp.sigma2
        scale = np.maximum(sigma2, np.finfo(float).tiny)
        if np.any(var < -1e-6 * scale):
            warnings.warn(
                f"kriging variance down to {var.min():.3g} < 0 (ill-conditioned system), clipped to 0; "
                "consider a small nugget", UserWarning, stacklevel=3,
            )
        return mean, np.maximum(var, 0.0)

    def _variance_from_covariance(self, K):
        """Unclipped variances ``(n_outputs, n_pred)`` from the cross-covariances ``K``
        ``(n_outputs, n_pred, n)``."""
        sigma2 = self.hyperparameters_.sigma2[:, None]
        if self.kind_ != EXPONENTIAL:
            quad = np.einsum("jpi,jpi->jp", np.matmul(K, self.Q_), K)
            return sigma2 * (self.c0_[:, None] - 2.0 * np.einsum("jpi,ji->jp", K, self.q1_) - quad)
        quad = np.empty(K.shape[:2])
        for j in range(self.n_outputs_):  # a handful of POD modes, each one BLAS-3 call
            if self._shared[j] != j:  # the same factor (and covariances) as an earlier output
                quad[j] = quad[self._shared[j]]
                continue
            if self._L_inverse is not None:  # triangular product: half the flops of a full one
                V = dtrmm(1.0, self._L_inverse[j], K[j].T, side=0, lower=1)
            else:
                V = solve_triangular(self.L_[j], K[j].T, lower=True, check_finite=False)
            quad[j] = np.einsum("ip,ip->p", V, V)
        trend = 1.0 - np.einsum("jpi,ji->jp", K, self._ones_weights)
        return sigma2 * (1.0 - quad + trend**2 * self.c0_[:, None])


def l_bfgs_b(objective, x0, bounds, maxiter=200):
    """The default ``optimizer`` of :class:`OrdinaryKriging`: SciPy's L-BFGS-B from ``x0``.

    Parameters
    ----------
    objective : callable
        ``objective(x) -> (f, grad)``, the criterion and its analytic gradient.
    x0 : ndarray of shape (n_params,)
        Starting point (log-ranges, then the exponent when it is fitted).
    bounds : list of (float, float)
        Lower and upper bound of each parameter.
    maxiter : int, default 200
        Iterations at most (the polish of an exponent at its upper bound uses 50).

    Returns
    -------
    x : ndarray of shape (n_params,)
        The point L-BFGS-B stops at.
    f : float
        The criterion there.
    """
    res = minimize(objective, x0, jac=True, method="L-BFGS-B", bounds=bounds, options={"maxiter": maxiter})
    return res.x, res.fun


class _Counted:
    """An objective that counts its evaluations (``n_evaluations_`` whatever the optimiser)."""

    def __init__(self, objective):
        self.objective, self.calls = objective, 0

    def __call__(self, x):
        self.calls += 1
        return self.objective(x)


def _is_constant(y):
    """Whether an output column is constant to rounding: its spread at most 1e-14 of its largest
    magnitude (relative, so that a common scale of the data does not change the answer)."""
    return bool(np.ptp(y) <= 1e-14 * float(np.max(np.abs(y))))


def _check_duplicates(X):
    """``ValueError`` naming the first pair of identical rows of ``X``."""
    _, index, counts = np.unique(X, axis=0, return_index=True, return_counts=True)
    if np.any(counts > 1):
        row = X[index[np.argmax(counts > 1)]]
        rows = np.flatnonzero(np.all(X == row, axis=1))
        raise ValueError(
            f"duplicate samples: rows {rows.tolist()} of X are identical ({row.tolist()}); "
            "the kriging system is singular: remove duplicates or set a nugget (e.g. nugget=1e-8)"
        )
