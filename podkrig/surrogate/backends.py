"""Selectable regressors of the POD coefficients, behind the one estimator interface of the surrogate.

:class:`~podkrig.surrogate.PODKriging` fits one of these to the POD coefficients of the snapshots
(inputs in the unit cube, ``(n_samples, n_dims)``; outputs ``(n_samples, n_modes)``), so that a
user can compare them on their own data with the same held-out report and invert with any of them:

- ``"podkrig"``: :class:`~podkrig.surrogate.kriging.OrdinaryKriging`, ours (default);
- ``"smt-krg"``: SMT's ``KRG`` (ordinary kriging, constant trend), one model per POD mode [1]_;
- ``"smt-kpls"``: SMT's ``KPLS`` (kriging with partial-least-squares reduced correlation
  hyperparameters), one model per POD mode [2]_;
- ``"sklearn-gpr"``: scikit-learn's ``GaussianProcessRegressor`` with a constant × anisotropic
  Matérn kernel and normalised outputs, one model per POD mode.

Every backend has ``fit(X, Y)``, ``predict(X, return_std=False)`` (means and standard deviations,
``(n_pred, n_outputs)``, output units), ``get_params()``, ``to_arrays()`` and the class method
``from_arrays(arrays, attrs, params)``. Persistence stores the training data and the fitted
hyperparameters, never a pickle: loading refits each model at those hyperparameters without
optimising (SMT's ``hyper_opt="NoOp"``, scikit-learn's ``optimizer=None``), which reproduces the
predictions to rounding with the same library version (bitwise in the tests with numpy 2.4; a few
1e-13 relative for scikit-learn with numpy 1.26); a different library version is warned about.

References
----------
.. [1] M. A. Bouhlel, J. T. Hwang, N. Bartoli, R. Lafage, J. Morlier, J. R. R. A. Martins, "A
   Python surrogate modeling framework with derivatives", Advances in Engineering Software 135,
   102662, 2019.
.. [2] M. A. Bouhlel, N. Bartoli, A. Otsmane, J. Morlier, "Improving kriging surrogates of
   high-dimensional design models by partial least squares dimension reduction", Structural and
   Multidisciplinary Optimization 53(5), 935–952, 2016.
"""

import importlib.metadata
import json
import warnings

import numpy as np

from podkrig import __version__
from podkrig.parallel import one_blas_thread
from podkrig.exceptions import NotFittedError
from podkrig.surrogate.kriging import FitMethod, OrdinaryKriging

_SMT_NUGGET = 100.0 * float(np.finfo(float).eps)  # SMT's own default jitter


class _PerModeBackend:
    """One model of an external library per output column; subclasses define the library calls."""

    backend = None  # registry name
    library = None  # distribution name, for the recorded version

    def get_params(self, deep=True):
        """Settings as a dict (scikit-learn convention)."""
        return {k: getattr(self, k) for k in self._PARAMS}

    def _check_fitted(self):
        if not hasattr(self, "hyper_"):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit(X, Y) before predict")

    @staticmethod
    def _check_xy(X, Y):
        X = np.array(X, dtype=float, copy=True)
        Y = np.array(Y, dtype=float, copy=True)
        if X.ndim != 2:
            raise ValueError(f"X must have shape (n_samples, n_dims); got shape {X.shape}")
        y_1d = Y.ndim == 1
        Y = Y.reshape(len(Y), -1) if y_1d else Y
        if Y.ndim != 2 or Y.shape[0] != X.shape[0]:
            raise ValueError(f"Y must have shape ({X.shape[0]},) or ({X.shape[0]}, n_outputs); got {Y.shape}")
        if len(X) < 3:
            raise ValueError(f"a kriging backend needs at least 3 samples; got {len(X)}")
        if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
            raise ValueError("X and Y must be finite; found NaN or inf (drop failed FE runs first)")
        return X, Y, y_1d

    def fit(self, X, Y):
        """Fit one model per output column.

        With ``fit_subset = m`` and more than ``m`` samples, each model's hyperparameters are
        fitted on ``m`` samples drawn at random without replacement (seed ``random_state``), and
        the model of all samples is then built at them without optimising (the library's own
        fixed-hyperparameter path, as at load); ``fit_method_`` records the choice.

        Parameters
        ----------
        X : array_like of shape (n_samples, n_dims)
            Training inputs (the unit cube in :class:`~podkrig.surrogate.PODKriging`).
        Y : array_like of shape (n_samples,) or (n_samples, n_outputs)
            Training outputs, any units.

        Returns
        -------
        self
        """
        self._check_settings()
        fs = self.fit_subset
        if not (fs is None or (isinstance(fs, (int, np.integer)) and not isinstance(fs, bool) and fs >= 3)):
            raise ValueError(f"fit_subset must be None or an integer >= 3; got {fs!r}")
        X, Y, self._y_1d = self._check_xy(X, Y)
        n = len(X)
        idx = (np.sort(np.random.default_rng(int(self.random_state)).choice(n, int(fs), replace=False))
               if fs is not None and n > fs else None)
        with one_blas_thread(), warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)  # library deprecation notes, not the user's
            if idx is None:
                fitted = [self._fit_one(X, Y[:, j]) for j in range(Y.shape[1])]
            else:
                hyper = [self._fit_one(X[idx], Y[idx, j])[1] for j in range(Y.shape[1])]
                fitted = [(self._rebuild_one(X, Y[:, j], h), h) for j, h in enumerate(hyper)]
        self.fit_method_ = (FitMethod("exact", n, n) if idx is None
                            else FitMethod("subset", n, len(idx), int(self.random_state)))
        self._models = [m for m, _ in fitted]
        self.hyper_ = np.array([h for _, h in fitted], dtype=float)
        self.X_, self.Y_ = X, Y
        self.n_features_in_, self.n_outputs_ = X.shape[1], Y.shape[1]
        return self

    def predict(self, X, return_std=False):
        """Means (and standard deviations) at new inputs, ``(n_pred, n_outputs)``, output units.

        Returns ``(n_pred,)`` arrays for 1-D training outputs. Leaves the estimator unchanged.
        """
        self._check_fitted()
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.n_features_in_:
            raise ValueError(f"X must have shape (n_pred, {self.n_features_in_}); got {X.shape}")
        with one_blas_thread():
            parts = [self._predict_one(m, X, return_std) for m in self._models]
        mean = np.column_stack([p[0] for p in parts])
        if not return_std:
            return mean[:, 0] if self._y_1d else mean
        std = np.column_stack([p[1] for p in parts])
        return (mean[:, 0], std[:, 0]) if self._y_1d else (mean, std)

    # ------------------------------------------------------------------ persistence
    @classmethod
    def library_version(cls):
        return importlib.metadata.version(cls.library)

    def to_arrays(self):
        """Training data and fitted hyperparameters, ``(arrays, attrs)``; no pickle.

        ``arrays``: ``X`` ``(n, d)``, ``Y`` ``(n, n_outputs)``, ``hyper`` ``(n_outputs, n_hyper)``
        (the library's own hyperparameter vector per model); ``attrs``: ``y_1d``, ``library``,
        ``library_version``.
        """
        self._check_fitted()
        return ({"X": self.X_, "Y": self.Y_, "hyper": self.hyper_},
                {"y_1d": bool(self._y_1d), "library": self.library, "library_version": self.library_version(),
                 "fit_method": json.dumps(self.fit_method_.to_dict())})

    @classmethod
    def from_arrays(cls, arrays, attrs, params):
        """Refit every model at the stored hyperparameters without optimising.

        Warns
        -----
        UserWarning
            When the installed library version differs from the one that fitted the models
            (predictions may then differ slightly).
        """
        est = cls(**params)
        est._check_settings()
        saved = str(attrs.get("library_version", "?"))
        if saved != cls.library_version():
            warnings.warn(f"surrogate backend {est.backend!r} was fitted with {cls.library} {saved}; "
                          f"{cls.library_version()} is installed: predictions may differ slightly",
                          UserWarning, stacklevel=3)
        X, Y = np.asarray(arrays["X"][...], float), np.asarray(arrays["Y"][...], float)
        hyper = np.asarray(arrays["hyper"][...], float)
        with one_blas_thread(), warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            est._models = [est._rebuild_one(X, Y[:, j], hyper[j]) for j in range(Y.shape[1])]
        est.hyper_, est.X_, est.Y_ = hyper, X, Y
        est.fit_method_ = (FitMethod.from_dict(json.loads(attrs["fit_method"])) if "fit_method" in attrs
                           else FitMethod("exact", len(X), len(X)))
        est._y_1d = bool(attrs["y_1d"])
        est.n_features_in_, est.n_outputs_ = X.shape[1], Y.shape[1]
        return est

    def describe(self):
        """One line for reports: backend, settings and library version."""
        settings = ", ".join(f"{k} {v}" for k, v in self.get_params().items())
        return f"{self.backend} ({self.library} {self.library_version()}): {settings}"


class SMTKriging(_PerModeBackend):
    """SMT's KRG or KPLS, one model per output column.

    Parameters
    ----------
    method : {"krg", "kpls"}
        ``KRG`` (one correlation length per input) or ``KPLS`` (``n_comp`` PLS directions).
    corr : {"squar_exp", "abs_exp", "pow_exp", "matern52", "matern32"}, default "squar_exp"
        SMT's correlation function (``KPLS``: the first three only).
    n_comp : int, default 2
        PLS components of ``KPLS`` (at most the number of inputs).
    n_start : int, default 5
        Starting points of SMT's hyperparameter optimiser (SMT's own default is 10).
    nugget : float, default 2.22e-14
        SMT's jitter on the correlation matrix (its default, ``100 eps``).
    random_state : int, default 41
        Seed of SMT's multistart (SMT's default) and of the subset draw.
    fit_subset : int or None, default None
        Fit the hyperparameters on this many random samples, then build the model of all
        samples at them (see ``fit``); None: SMT's own fit on all samples.

    Attributes
    ----------
    hyper_ : ndarray of shape (n_outputs, n_theta)
        SMT's ``optimal_theta`` per output (``n_theta`` = n_dims for KRG, ``n_comp`` for KPLS).
    """

    library = "smt"
    _PARAMS = ("method", "corr", "n_comp", "n_start", "nugget", "random_state", "fit_subset")

    def __init__(self, method="krg", corr="squar_exp", n_comp=2, n_start=5, nugget=_SMT_NUGGET, random_state=41,
                 fit_subset=None):
        self.method, self.corr, self.n_comp = method, corr, n_comp
        self.n_start, self.nugget, self.random_state = n_start, nugget, random_state
        self.fit_subset = fit_subset

    @property
    def backend(self):
        return f"smt-{self.method}"

    def _check_settings(self):
        if self.method not in ("krg", "kpls"):
            raise ValueError(f"method must be 'krg' or 'kpls'; got {self.method!r}")
        allowed = ("squar_exp", "abs_exp", "pow_exp") + (("matern52", "matern32") if self.method == "krg" else ())
        if self.corr not in allowed:
            raise ValueError(f"corr of smt-{self.method} must be one of {allowed}; got {self.corr!r}")
        for name, least in (("n_comp", 1), ("n_start", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < least:
                raise ValueError(f"{name} must be an integer >= {least}; got {v!r}")
        if not (np.isfinite(self.nugget) and self.nugget > 0):
            raise ValueError(f"nugget must be a finite number > 0; got {self.nugget!r}")

    def _model(self, **options):
        # SMT imports in ~1-3 s (11 s measured with the machine under load 14): only when used
        from smt.surrogate_models import KPLS, KRG

        common = {"corr": self.corr, "nugget": float(self.nugget), "print_global": False,
                  "seed": int(self.random_state)}
        if self.method == "kpls":
            return KPLS(n_comp=int(self.n_comp), **common, **options)
        return KRG(**common, **options)

    def _check_kpls(self, X):
        if self.method == "kpls" and self.n_comp > X.shape[1]:
            raise ValueError(f"n_comp = {self.n_comp} PLS components of smt-kpls exceed the {X.shape[1]} inputs")

    def _fit_one(self, X, y):
        self._check_kpls(X)
        model = self._model(n_start=int(self.n_start))
        model.set_training_values(X, y)
        model.train()
        return model, np.asarray(model.optimal_theta, dtype=float)

    def _rebuild_one(self, X, y, hyper):
        # SMT's log-scale optimum can sit an ulp outside its own theta bounds (20.000000000000004),
        # and SMT replaces an out-of-bounds theta0 by a random one: widen the bounds to hold it
        lo, hi = self._model().options["theta_bounds"]
        model = self._model(theta0=list(hyper), hyper_opt="NoOp", n_start=1,
                            theta_bounds=[min(lo, float(hyper.min())), max(hi, float(hyper.max()))])
        model.set_training_values(X, y)
        model.train()
        return model

    @staticmethod
    def _predict_one(model, X, return_std):
        mean = model.predict_values(X)[:, 0]
        if not return_std:
            return (mean,)
        return mean, np.sqrt(np.maximum(model.predict_variances(X)[:, 0], 0.0))


class SklearnGPR(_PerModeBackend):
    """scikit-learn's ``GaussianProcessRegressor``, one model per output column.

    Kernel :math:`c \\, \\mathrm{Matern}_\\nu(\\ell_1..\\ell_d)` on normalised outputs
    (``normalize_y=True``); the constant :math:`c` in [1e-3, 1e3], the lengths in [1e-2, 1e3]
    (unit-cube units), started at 0.5.

    Parameters
    ----------
    nu : {0.5, 1.5, 2.5, inf}, default 2.5
        Smoothness of the Matérn kernel (inf: squared exponential). The elastic responses are very
        smooth: 0.5 (the exponential kernel) is 13x less accurate than ours in ``BENCHMARKS.md``.
    alpha : float, default 1e-10
        Jitter added to the diagonal, normalised output units².
    n_restarts_optimizer : int, default 2
        Extra random starts of the L-BFGS-B fit of the log-hyperparameters.
    random_state : int, default 0
        Seed of the restarts and of the subset draw.
    fit_subset : int or None, default None
        Fit the kernel on this many random samples, then the regressor of all samples at it
        (see ``fit``); None: scikit-learn's own fit on all samples.

    Attributes
    ----------
    hyper_ : ndarray of shape (n_outputs, 1 + n_dims)
        The fitted kernel's ``theta`` (log of the constant and the lengths) per output.
    """

    backend = "sklearn-gpr"
    library = "scikit-learn"
    _PARAMS = ("nu", "alpha", "n_restarts_optimizer", "random_state", "fit_subset")
    _NU = (0.5, 1.5, 2.5, float("inf"))

    def __init__(self, nu=2.5, alpha=1e-10, n_restarts_optimizer=2, random_state=0, fit_subset=None):
        self.nu, self.alpha = nu, alpha
        self.n_restarts_optimizer, self.random_state = n_restarts_optimizer, random_state
        self.fit_subset = fit_subset

    def _check_settings(self):
        if self.nu not in self._NU:
            raise ValueError(f"nu must be one of {self._NU}; got {self.nu!r}")
        if not (np.isfinite(self.alpha) and self.alpha > 0):
            raise ValueError(f"alpha must be a finite number > 0; got {self.alpha!r}")
        n = self.n_restarts_optimizer
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise ValueError(f"n_restarts_optimizer must be an integer >= 0; got {n!r}")

    def _regressor(self, d, theta=None):
        # scikit-learn's gaussian_process imports in ~1-2 s (8 s measured under load 14): only when used
        from sklearn.gaussian_process import GaussianProcessRegressor
        from sklearn.gaussian_process.kernels import ConstantKernel, Matern

        kernel = ConstantKernel(1.0, (1e-3, 1e3)) * Matern(np.full(d, 0.5), (1e-2, 1e3), nu=float(self.nu))
        if theta is not None:
            return GaussianProcessRegressor(kernel.clone_with_theta(theta), alpha=float(self.alpha),
                                            optimizer=None, normalize_y=True)
        return GaussianProcessRegressor(kernel, alpha=float(self.alpha), normalize_y=True,
                                        n_restarts_optimizer=int(self.n_restarts_optimizer),
                                        random_state=int(self.random_state))

    def _fit_one(self, X, y):
        with warnings.catch_warnings():
            # a length at its upper bound (1e3 in the unit cube) means "flat along that input": fine
            warnings.filterwarnings("ignore", message=".*close to the specified upper bound")
            gp = self._regressor(X.shape[1]).fit(X, y)
        return gp, np.asarray(gp.kernel_.theta, dtype=float)

    def _rebuild_one(self, X, y, hyper):
        return self._regressor(X.shape[1], hyper).fit(X, y)

    @staticmethod
    def _predict_one(model, X, return_std):
        return model.predict(X, return_std=True) if return_std else (model.predict(X),)


BACKENDS = {
    "podkrig": lambda **kw: OrdinaryKriging(**kw),
    "smt-krg": lambda **kw: SMTKriging(method="krg", **kw),
    "smt-kpls": lambda **kw: SMTKriging(method="kpls", **kw),
    "sklearn-gpr": lambda **kw: SklearnGPR(**kw),
}


def make_backend(name, **settings):
    """A new, unfitted estimator of backend ``name`` with ``settings`` (its keyword arguments).

    Raises
    ------
    ValueError
        Unknown backend (the message lists the choices) or a setting the backend does not have.
    """
    if name not in BACKENDS:
        raise ValueError(f"surrogate backend must be one of {', '.join(BACKENDS)}; got {name!r}")
    try:
        return BACKENDS[name](**settings)
    except TypeError as e:
        raise ValueError(f"backend {name!r} does not take these settings: {sorted(settings)} ({e})") from None


def backend_name(estimator):
    """Registry name of a backend estimator (``"podkrig"`` for :class:`OrdinaryKriging`)."""
    if isinstance(estimator, OrdinaryKriging):
        return "podkrig"
    if isinstance(estimator, _PerModeBackend):
        return estimator.backend
    raise TypeError(f"not a surrogate backend: {type(estimator).__name__}; choose one of {', '.join(BACKENDS)}")


def backend_version(estimator):
    """Version of the library behind ``estimator`` (podkrig's own for ours)."""
    return __version__ if isinstance(estimator, OrdinaryKriging) else estimator.library_version()


def backend_from_arrays(name, arrays, attrs, params):
    """Rebuild a fitted estimator of backend ``name`` from its ``to_arrays`` output."""
    if name not in BACKENDS:
        raise ValueError(f"unknown surrogate backend {name!r}; this podkrig knows {', '.join(BACKENDS)}")
    cls = {"podkrig": OrdinaryKriging, "sklearn-gpr": SklearnGPR}.get(name, SMTKriging)
    return cls.from_arrays(arrays, attrs, params)
