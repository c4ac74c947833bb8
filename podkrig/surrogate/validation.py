"""Errors of a POD-kriging surrogate: held-out FE runs, closed-form leave-one-out, coverage.

Conventions: snapshots ``Y`` of shape ``(n_samples, ...)`` (flattened to ``(n, n_outputs)``), mm;
parameters ``X`` ``(n, n_params)`` in physical units. Relative errors are per sample,
:math:`\\|\\hat y - y\\| / \\|y\\|` over all outputs of the snapshot (dimensionless).

Error split (thesis ch. 4, "sources of error"): with :math:`P` the projection onto the affine POD
space, :math:`y - \\hat y = (y - P y) + (P y - \\hat y)`; the first term (POD truncation) is
orthogonal to the basis and the second lies in it, so
:math:`\\|y - \\hat y\\|^2 = \\|y - Py\\|^2 + \\|Py - \\hat y\\|^2` exactly.

Example
-------
>>> import numpy as np
>>> from podkrig.surrogate import PODKriging
>>> def snapshots(X):                     # (n, 3 loads, 3 sensors), a smooth stand-in for FE runs
...     return np.stack([np.outer([1, 2, 3], [a, b ** 2, a * b]) for a, b in X])
>>> rng = np.random.default_rng(0)
>>> X, X_test = rng.uniform(1, 2, size=(30, 2)), rng.uniform(1.1, 1.9, size=(8, 2))
>>> surrogate = PODKriging().fit(X, snapshots(X))
>>> rep = held_out_errors(surrogate, X_test, snapshots(X_test))
>>> bool(rep.summary()["rel_error"]["median"] < 1e-3)
True
"""

import logging
from dataclasses import dataclass, field

import numpy as np

from podkrig.display import Displayed
from podkrig.surrogate.kriging import DEFAULT_BETA, OrdinaryKriging
from podkrig.surrogate.podkriging import LAYOUTS, PODKriging

logger = logging.getLogger(__name__)


def relative_errors(Y_pred, Y_true):
    """Per-sample relative error :math:`\\|\\hat y - y\\| / \\|y\\|`.

    Parameters
    ----------
    Y_pred, Y_true : array_like of shape (n_samples, ...)
        Same shape, output units.

    Returns
    -------
    ndarray of shape (n_samples,)
        Dimensionless; ``inf`` for a zero snapshot with a nonzero error.
    """
    Y_pred, Y_true = np.asarray(Y_pred, float), np.asarray(Y_true, float)
    if Y_pred.shape != Y_true.shape:
        raise ValueError(f"predicted and true snapshots differ in shape: {Y_pred.shape} vs {Y_true.shape}")
    n = len(Y_true)
    err = np.linalg.norm((Y_pred - Y_true).reshape(n, -1), axis=1)
    norm = np.linalg.norm(Y_true.reshape(n, -1), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(err == 0, 0.0, err / norm)


def coverage(Y_pred, Y_true, Y_std, k=2.0):
    """Share of outputs whose error lies within ``k`` predictive standard deviations.

    Parameters
    ----------
    Y_pred, Y_true, Y_std : array_like, same shape
        Predictions, true values and predictive standard deviations, output units.
    k : float, default 2
        Half-width of the interval in standard deviations; :math:`|\\hat y - y| \\le k \\sigma`
        counts as covered (the edge included). For a Gaussian predictive error with honest
        :math:`\\sigma`, ``k = 2`` covers 95.45 %.

    Returns
    -------
    float
        In [0, 1].
    """
    Y_pred, Y_true, Y_std = (np.asarray(a, float) for a in (Y_pred, Y_true, Y_std))
    if not Y_pred.shape == Y_true.shape == Y_std.shape or Y_pred.size == 0:
        raise ValueError(f"predictions, true values and standard deviations must have one non-empty shape; got "
                         f"{Y_pred.shape}, {Y_true.shape}, {Y_std.shape}")
    return float(np.mean(np.abs(Y_pred - Y_true) <= k * Y_std))


def summarize(errors):
    """``{"median", "p95", "max", "mean"}`` of per-sample errors (floats)."""
    e = np.asarray(errors, float)
    return {"median": float(np.median(e)), "p95": float(np.percentile(e, 95)), "max": float(np.max(e)),
            "mean": float(np.mean(e))}


@dataclass(frozen=True, eq=False, repr=False)
class HeldOutReport(Displayed):
    """Errors of a surrogate on held-out FE runs.

    Attributes
    ----------
    rel_error : ndarray of shape (n_held_out,)
        :math:`\\|\\hat y - y\\| / \\|y\\|` per held-out sample (per unit, the largest).
    pod_error : ndarray of shape (n_held_out,)
        POD truncation part :math:`\\|y - P y\\| / \\|y\\|`.
    interp_error : ndarray of shape (n_held_out,)
        Interpolation part :math:`\\|P y - \\hat y\\| / \\|y\\|`.
    coverage_2sigma : float
        Share of all held-out outputs with :math:`|\\hat y - y| \\le 2 \\sigma`.
    X : ndarray of shape (n_held_out, n_params)
    Y_true, Y_pred, Y_std : ndarray of shape (n_held_out, n_outputs)
        mm (output units).
    n_train, n_modes : int
    loo_error : ndarray of shape (n_train,) or None
        Closed-form leave-one-out relative errors of the training snapshots.
    units : tuple of str
        The unit of each output (``n_outputs``); outputs of different units are never added:
        ``rel_error``, ``pod_error`` and ``interp_error`` are the largest of the per-unit relative
        errors of a sample, and :meth:`summary` gives the errors per unit.
    sensors : dict
        Unit to the names of its sensors (empty when the surrogate does not name them).
    """

    rel_error: np.ndarray
    pod_error: np.ndarray
    interp_error: np.ndarray
    coverage_2sigma: float
    X: np.ndarray
    Y_true: np.ndarray
    Y_pred: np.ndarray
    Y_std: np.ndarray
    n_train: int
    n_modes: int
    loo_error: np.ndarray | None = None
    extra: dict = field(default_factory=dict)
    units: tuple = ()
    sensors: dict = field(default_factory=dict)

    def by_unit(self):
        """Errors per unit, each ``{median, p95, max, mean}`` over the held-out runs: ``rel_error``
        :math:`\\|\\hat y_u - y_u\\| / \\|y_u\\|`, ``peak_error`` (the error relative to the peak
        of the curve) :math:`\\max|\\hat y_u - y_u| / \\max|y_u|`, ``peak_value_error``
        :math:`|\\max|\\hat y_u| - \\max|y_u|| / \\max|y_u|` (e.g. the peak load) over the outputs
        :math:`u` of one unit; ``rms_abs_error`` and ``max_abs_error`` over all of them, in that unit;
        ``sensors``: their names when known.

        Returns
        -------
        dict of str to dict
        """
        units = np.asarray(self.units if len(self.units) else ("",) * self.Y_true.shape[1])
        out = {}
        for unit in dict.fromkeys(units.tolist()):
            cols = units == unit
            t, p = self.Y_true[:, cols], self.Y_pred[:, cols]
            d = p - t
            peak = np.abs(t).max(axis=1)
            peak = np.where(peak > 0, peak, np.inf)
            out[unit] = {"rel_error": summarize(relative_errors(p, t)),
                         "peak_error": summarize(np.abs(d).max(axis=1) / peak),
                         "peak_value_error": summarize(np.abs(np.abs(p).max(axis=1) - np.abs(t).max(axis=1)) / peak),
                         "rms_abs_error": float(np.sqrt(np.mean(d**2))), "max_abs_error": float(np.max(np.abs(d)))}
            if unit in self.sensors:
                out[unit]["sensors"] = list(self.sensors[unit])
        return out

    @property
    def n_held_out(self):
        return len(self.rel_error)

    def summary(self):
        """JSON-able dict: ``n_train``, ``n_held_out``, ``n_modes``, ``rel_error``, ``pod_error``,
        ``interp_error``, ``loo_error`` (each ``{median, p95, max, mean}``), ``coverage_2sigma``, and
        for podkrig's own kriging ``fit`` (:meth:`~podkrig.surrogate.kriging.FitMethod.to_dict`: exact
        or subset fit, subset size and seed) with ``fit_description``, then ``by_unit`` (:meth:`by_unit`)."""
        out = {
            "n_train": int(self.n_train),
            "n_held_out": int(self.n_held_out),
            "n_modes": int(self.n_modes),
            "rel_error": summarize(self.rel_error),
            "pod_error": summarize(self.pod_error),
            "interp_error": summarize(self.interp_error),
            "coverage_2sigma": float(self.coverage_2sigma),
        }
        if self.loo_error is not None:
            out["loo_error"] = summarize(self.loo_error)
        out.update(self.extra)
        out["by_unit"] = self.by_unit()
        return out

    _ARRAYS = ("rel_error", "pod_error", "interp_error", "X", "Y_true", "Y_pred", "Y_std")

    def to_dict(self):
        """Every field, arrays as nested lists (JSON-able; :meth:`from_dict` reads it back).
        :meth:`summary` is the short form shown in reports."""
        d = {name: np.asarray(getattr(self, name)).tolist() for name in self._ARRAYS}
        d.update(coverage_2sigma=float(self.coverage_2sigma), n_train=int(self.n_train), n_modes=int(self.n_modes),
                 loo_error=None if self.loo_error is None else np.asarray(self.loo_error).tolist(),
                 extra=dict(self.extra), units=list(self.units), sensors={k: list(v) for k, v in self.sensors.items()})
        return d

    @classmethod
    def from_dict(cls, d):
        arrays = {name: np.asarray(d[name], dtype=float) for name in cls._ARRAYS}
        loo = None if d.get("loo_error") is None else np.asarray(d["loo_error"], dtype=float)
        return cls(coverage_2sigma=float(d["coverage_2sigma"]), n_train=int(d["n_train"]), n_modes=int(d["n_modes"]),
                   loo_error=loo, extra=dict(d.get("extra", {})), units=tuple(d.get("units", ())),
                   sensors={k: tuple(v) for k, v in d.get("sensors", {}).items()}, **arrays)


def held_out_errors(surrogate, X, Y, *, with_loo=True):
    """Compare a fitted :class:`~podkrig.surrogate.PODKriging` with held-out FE snapshots.

    Parameters
    ----------
    surrogate : PODKriging
        Fitted.
    X : array_like of shape (n_held_out, n_params)
        Physical units, inside the trained box.
    Y : array_like of shape (n_held_out, ...)
        FE snapshots with the training snapshots' shape, mm.
    with_loo : bool, default True
        Also compute the closed-form leave-one-out errors of the training snapshots.

    Returns
    -------
    HeldOutReport
    """
    X = np.asarray(X, float)
    Y = np.asarray(Y, float)
    if Y.shape[1:] != tuple(surrogate.output_shape_):
        raise ValueError(
            f"held-out snapshots have shape {Y.shape[1:]} per sample, the surrogate predicts "
            f"{tuple(surrogate.output_shape_)}; use held-out runs of the same scenario and output"
        )
    if len(X) != len(Y) or len(X) == 0:
        raise ValueError(f"need as many held-out parameter vectors as snapshots (>= 1); got {len(X)} and {len(Y)}")
    Yf = Y.reshape(len(Y), -1)
    pred, std = surrogate.predict(X, return_std=True)
    proj = surrogate.project(Yf)
    prov = getattr(surrogate, "provenance_", {})
    level_units = [u or prov.get("reading_unit", "mm") for u in getattr(surrogate, "units_", ("",))]
    units = np.asarray(level_units * (Yf.shape[1] // len(level_units)))
    names = prov.get("sensor_names") if prov.get("output", "readings") == "readings" else None
    sensors = {}
    if names is not None and len(names) == len(level_units):
        for name, unit in zip(names, level_units):
            sensors.setdefault(unit, []).append(name)
    rel, pod, interp = (np.zeros(len(Yf)) for _ in range(3))
    for unit in dict.fromkeys(units.tolist()):  # never add outputs of different units: the worst unit
        cols = units == unit
        norm = np.linalg.norm(Yf[:, cols], axis=1)
        norm = np.where(norm > 0, norm, np.inf)
        rel = np.maximum(rel, relative_errors(pred[:, cols], Yf[:, cols]))
        pod = np.maximum(pod, np.linalg.norm(Yf[:, cols] - proj[:, cols], axis=1) / norm)
        interp = np.maximum(interp, np.linalg.norm(proj[:, cols] - pred[:, cols], axis=1) / norm)
    covered = coverage(pred, Yf, std)
    loo = loo_errors(surrogate) if with_loo else None
    logger.info("held-out: %d samples, median relative error %.3g, coverage %.3f", len(X), np.median(rel), covered)
    fit = getattr(surrogate.kriging_, "fit_method_", None)  # podkrig's own backend: how it was trained
    extra = {"fit": fit.to_dict(), "fit_description": fit.describe()} if fit is not None else {}
    return HeldOutReport(rel, pod, interp, covered, X, Yf, pred, std, len(surrogate.X_),
                         surrogate.pod_.n_modes_, loo, extra, tuple(units.tolist()),
                         {k: tuple(v) for k, v in sensors.items()})


def loo_errors(surrogate):
    """Closed-form leave-one-out relative errors of the training snapshots (Dubrule 1983).

    The kriging of each POD coefficient is left out one sample at a time in closed form, at fixed
    hyperparameters and with the POD basis of all training samples; the error of snapshot
    :math:`i` is :math:`\\| \\sum_k e_{ik} \\varphi_k + (y_i - P y_i) \\| / \\|y_i\\|` with the
    kriging LOO residuals :math:`e_{ik}`.

    Returns
    -------
    ndarray of shape (n_train,), or None
        None for a backend without closed-form leave-one-out residuals (SMT, scikit-learn).
    """
    if not hasattr(surrogate.kriging_, "loo_residuals_"):
        return None
    E = surrogate.kriging_.loo_residuals_  # (n, n_modes): a_ik - a_hat_{-i}(x_i)
    # the truncation residual y_i - P y_i is orthogonal to the basis: Pythagoras
    err = np.sqrt(np.sum(E * E, axis=1) + surrogate.train_residual_norm_**2)
    return err / np.where(surrogate.train_norm_ > 0, surrogate.train_norm_, np.inf)


def compare_settings(X, Y, X_held, Y_held, settings, space=None, pod=None):
    """Held-out relative errors of several kriging settings on the same snapshots (thesis Fig. 4.4).

    Parameters
    ----------
    X, Y : training parameters ``(n, n_params)`` and snapshots ``(n, ...)``
    X_held, Y_held : held-out parameters and snapshots
    settings : sequence of dict
        Keyword arguments of :class:`~podkrig.surrogate.kriging.OrdinaryKriging`, e.g.
        ``[{"variogram": "exponential", "beta": 1.2}, ...]``.
    space : ParameterSpace, optional
    pod : POD, optional

    Returns
    -------
    dict
        Label (e.g. ``"exponential, beta=1.2"``) to ndarray of shape (n_held_out,) of relative errors.
    """
    out = {}
    for s in settings:
        sur = PODKriging(pod=pod, kriging=OrdinaryKriging(**s), space=space).fit(X, Y)
        label = f"{s.get('variogram', 'exponential')}, beta={s.get('beta', DEFAULT_BETA)}"
        out[label] = relative_errors(sur.predict(X_held), np.asarray(Y_held).reshape(len(Y_held), -1))
    return out


def compare_layouts(surrogate, X, Y, X_held, Y_held):
    """Held-out errors per unit of a surrogate in each POD layout (one POD stacked over the control
    levels, a POD + kriging per level; thesis §4.3.3) on the same training snapshots, with the
    surrogate's own templates, scaling, units and space.

    The surrogate stands for its own layout when it was trained on ``X`` (one fit more, of the
    other layout); otherwise both layouts are fitted on ``X, Y``.

    Parameters
    ----------
    surrogate : PODKriging
        Fitted (its settings are reused; it is not modified).
    X, Y : training parameters ``(n, n_params)`` and snapshots ``(n, n_levels, ...)``
    X_held, Y_held : held-out parameters and snapshots

    Returns
    -------
    dict
        Layout (``"stacked"``, ``"per_level"``) to ``{"n_modes": int, "by_unit":``
        :meth:`HeldOutReport.by_unit` ``}``.
    """
    out = {}
    trained_on_X = np.array_equal(surrogate.X_, np.asarray(X, dtype=float))
    for layout in LAYOUTS:
        if layout == surrogate.layout and trained_on_X:
            sur = surrogate
        else:
            sur = PODKriging(pod=surrogate.pod, kriging=surrogate.kriging, space=surrogate.space, layout=layout,
                             scaling=surrogate.scaling).fit(X, Y, surrogate.units_)
            sur.provenance_.update({k: surrogate.provenance_[k] for k in ("sensor_names", "output", "reading_unit")
                                    if k in surrogate.provenance_})
        rep = held_out_errors(sur, X_held, Y_held, with_loo=False)
        out[layout] = {"n_modes": int(sur.n_modes_), "by_unit": rep.by_unit()}
    return out
