"""Propagation of an identification: response variability over the region of equivalence (RVC).

RVC (response variability of calibration/validation models, thesis ch. 5 and 7) is the spread of
a model's predictions over the members of a region of equivalence: per output, the mean, the
coefficient of variation std/|mean|, (max − min)/|mean| and quantiles of the distribution drawn
(default the 5 % and 95 % quantiles, a 90 % band). A small CV for a validation model means the
calibration pins down what that other test would show.

The distribution is that of the model's *surrogate* over the region's members (the RVC of
validation models, thesis ch. 5 and 7; the kriging variance is not added). A validation model
that can fail — a nonlinear FE run that stops early, or whose load has no maximum within the
control range (still rising, or its peak in the last control interval), so no capacity — is also
run on its FE model at a seeded subsample of the same members (``fe_runs``): :class:`ValidationRuns` counts the runs that
failed (the failed share of the validation runs over the region) and compares the FE outputs of
the others with the surrogate's at the same members. The capacity of a specimen is the peak load
``F_peak`` (kN) and its control displacement ``d_peak`` (mm) of a scenario with the option
``peak_readings``; they are outputs like any other and are named without a load level
(``"F_peak"``: the same at every level).

Examples
--------
A region uniform on [0, 1] pushed through ``y = 10 + 2 a``: the band is the image of the
quantiles of ``a``.

>>> import numpy as np
>>> from podkrig.online.region import Region
>>> from podkrig.parameters import Parameter, ParameterSpace
>>> class Line:
...     space = ParameterSpace((Parameter("a", 0.0, 1.0),))
...     sensor_names, sensor_units, load_levels = ("y",), {"y": "kN"}, np.array([1.0])
...     def predict(self, X, return_std=False):
...         Y = 10 + 2 * np.asarray(X)
...         return (Y, 0 * Y) if return_std else Y
>>> a = np.linspace(0, 1, 10001)[:, None]
>>> region = Region("likelihood-ratio", 0.95, a, np.zeros(len(a)), 1.0, {"a": (0.0, 1.0)}, ("a",), ("-",),
...                 len(a), 0.0, {})
>>> out = rvc(region, Line(), outputs=["y"])
>>> out.outputs, out.units, [round(float(q), 3) for q in out.quantiles[:, 0]]
(('y',), ('kN',), [10.1, 11.9])
"""

import logging
import math
from dataclasses import dataclass

import numpy as np

from podkrig.display import Displayed
from podkrig.offline.failures import without_peak

logger = logging.getLogger(__name__)

__all__ = ["QUANTILES", "RVCModel", "RVCResult", "ValidationRuns", "output_columns", "rvc", "run_validation"]

#: default quantile levels of an RVC: the 5 % and 95 % quantiles (a 90 % band)
QUANTILES = (0.05, 0.95)


@dataclass(frozen=True)
class RVCModel:
    """A validation model for :func:`rvc` inside :func:`~podkrig.online.calibrate.calibrate`.

    Attributes
    ----------
    model : object
        A batched model (``space``, ``sensor_names``, ``load_levels``, ``predict``), e.g. a
        :class:`~podkrig.online.problem.SurrogateModel` of the validation scenario.
    outputs : sequence of str or None
        Reported outputs (``"SENSOR@LOAD"``, or ``"SENSOR"`` for the last level; None: every sensor
        at the last level).
    fixed : dict of str to float or None
        Values of the model's parameters the calibration neither identifies nor fixes.
    scenario : fe.Scenario or None
        The FE model of the validation scenario, for the ``fe_runs`` validation runs.
    fe_runs : int
        FE runs of ``scenario`` at a seeded subsample of the region's members
        (:func:`run_validation`; 0: none).
    quantiles : tuple of float
        Quantile levels of the distribution reported, in (0, 1).
    """

    model: object
    outputs: tuple | None = None
    fixed: dict | None = None
    scenario: object = None
    fe_runs: int = 0
    quantiles: tuple = QUANTILES


@dataclass(frozen=True, eq=False, repr=False)
class ValidationRuns(Displayed):
    """FE runs of a validation model at members of the region of equivalence.

    A run *failed* when it stopped early (its status is not ``"converged"``: a budget exhausted,
    no convergence, or an FE error) or when it finished without a load maximum (``no_peak``: its
    peak in the last control interval, :func:`~podkrig.offline.failures.without_peak`; no
    capacity).

    Attributes
    ----------
    names : tuple of str
        The region's parameters, in the columns of ``parameters``.
    parameters : ndarray of shape (n_runs, n_free)
        The members run, in their units.
    status : tuple of str
        Per run: ``"converged"``, the solver's status of a run that stopped early
        (``"budget_exhausted"``, ``"not_converged"``) or ``"error"`` (the FE run raised).
    no_peak : ndarray of shape (n_runs,), bool
        Finished runs without a load maximum (their peak in the last control interval).
    fe : ndarray of shape (n_runs, n_outputs)
        The FE values of the RVC's outputs (NaN where a run did not reach them), their units.
    surrogate : ndarray of shape (n_runs, n_outputs)
        The model's (surrogate's) prediction at the same members.
    messages : tuple of str
        Why each run failed ("" for those that did not).
    """

    names: tuple
    parameters: np.ndarray
    status: tuple
    no_peak: np.ndarray
    fe: np.ndarray
    surrogate: np.ndarray
    messages: tuple

    @property
    def n_runs(self):
        return len(self.status)

    @property
    def stopped(self):
        """ndarray of shape (n_runs,), bool: the runs that stopped early."""
        return np.array([s != "converged" for s in self.status], dtype=bool)

    @property
    def failed(self):
        """ndarray of shape (n_runs,), bool: stopped early or without a load maximum."""
        return self.stopped | self.no_peak

    @property
    def failed_share(self):
        """Share of the runs that failed (-), NaN without runs."""
        return float(self.failed.mean()) if self.n_runs else math.nan

    def relative_difference(self):
        """|FE − surrogate| / |FE| per run and output over the runs that did not fail, ndarray of
        shape (n_ok, n_outputs) (-)."""
        ok = ~self.failed
        fe = self.fe[ok]
        return np.abs(fe - self.surrogate[ok]) / np.maximum(np.abs(fe), 1e-300)

    def _repr_lines(self):
        return [f"ValidationRuns: {self.n_runs} FE runs at region members, {int(self.failed.sum())} failed "
                f"({int(self.stopped.sum())} stopped early, {int(self.no_peak.sum())} without a load maximum)"]

    def to_dict(self):
        """``names``, ``parameters``, ``status``, ``no_peak``, ``fe``, ``surrogate`` (NaN as None),
        ``messages``, and the counts ``n_runs``, ``n_failed``, ``n_stopped``, ``n_no_peak`` and
        ``failed_share``."""
        return {"names": list(self.names), "parameters": self.parameters.tolist(), "status": list(self.status),
                "no_peak": self.no_peak.tolist(), "fe": _nan_to_none(self.fe),
                "surrogate": _nan_to_none(self.surrogate),
                "messages": list(self.messages), "n_runs": self.n_runs, "n_failed": int(self.failed.sum()),
                "n_stopped": int(self.stopped.sum()), "n_no_peak": int(self.no_peak.sum()),
                "failed_share": None if not self.n_runs else self.failed_share}

    @classmethod
    def from_dict(cls, d):
        n_free = len(d["names"])
        return cls(tuple(d["names"]), np.asarray(d["parameters"], dtype=float).reshape(-1, n_free),
                   tuple(d["status"]), np.asarray(d["no_peak"], dtype=bool), _none_to_nan(d["fe"]),
                   _none_to_nan(d["surrogate"]), tuple(d["messages"]))


def _nan_to_none(a):
    return [[None if not math.isfinite(v) else v for v in row] for row in np.asarray(a, dtype=float).tolist()]


def _none_to_nan(rows):
    return np.array([[math.nan if v is None else v for v in row] for row in rows], dtype=float)


@dataclass(frozen=True, eq=False, repr=False)
class RVCResult(Displayed):
    """Spread of a model's outputs over a region of equivalence.

    Attributes
    ----------
    outputs : tuple of str
        Output names ``"SENSOR@LOAD"`` (``"SENSOR"``: at the last level).
    mean, std, min, max : ndarray of shape (n_outputs,)
        Over the region members, in each output's unit.
    cv : ndarray of shape (n_outputs,)
        std / |mean| (-).
    range_ratio : ndarray of shape (n_outputs,)
        (max − min) / |mean| (-).
    n_samples : int
        Region members used.
    units : tuple of str
        The unit of each output (mm, kN, ...).
    quantile_levels : tuple of float
        Levels ``q_k`` in (0, 1) of :attr:`quantiles`.
    quantiles : ndarray of shape (n_levels, n_outputs)
        The ``q_k`` quantile of each output over the members (linear interpolation between order
        statistics, :func:`numpy.quantile`), in its unit.
    runs : ValidationRuns or None
        FE runs at a subsample of the members, with the failed share (a validation model with
        ``fe_runs``).
    values : ndarray of shape (n_samples, n_outputs) or None
        The outputs at each member (for figures; not part of :meth:`to_dict`).
    """

    outputs: tuple
    mean: np.ndarray
    std: np.ndarray
    cv: np.ndarray
    range_ratio: np.ndarray
    min: np.ndarray
    max: np.ndarray
    n_samples: int
    units: tuple
    quantile_levels: tuple
    quantiles: np.ndarray
    runs: ValidationRuns | None = None
    values: np.ndarray | None = None

    @property
    def failed_share(self):
        """Share of the FE validation runs at region members that failed (-), None without runs."""
        return None if self.runs is None or not self.runs.n_runs else self.runs.failed_share

    def to_dict(self):
        """``outputs``, ``units``, ``mean``, ``std``, ``cv``, ``range_ratio``, ``min``, ``max`` (lists
        aligned with ``outputs``), ``quantile_levels``, ``quantiles`` (one list per level),
        ``n_samples``, ``failed_share`` and ``runs`` (:meth:`ValidationRuns.to_dict`, or None)."""
        return {"outputs": list(self.outputs), "units": list(self.units), "mean": self.mean.tolist(),
                "std": self.std.tolist(), "cv": self.cv.tolist(), "range_ratio": self.range_ratio.tolist(),
                "min": self.min.tolist(), "max": self.max.tolist(), "quantile_levels": list(self.quantile_levels),
                "quantiles": self.quantiles.tolist(), "n_samples": self.n_samples,
                "failed_share": self.failed_share, "runs": None if self.runs is None else self.runs.to_dict()}

    @classmethod
    def from_dict(cls, d, *, values=None):
        arrays = [np.asarray(d[k], dtype=float) for k in ("mean", "std", "cv", "range_ratio", "min", "max")]
        levels = tuple(float(q) for q in d["quantile_levels"])
        quantiles = np.asarray(d["quantiles"], dtype=float).reshape(len(levels), len(d["outputs"]))
        return cls(tuple(d["outputs"]), *arrays, int(d["n_samples"]), tuple(d["units"]), levels, quantiles,
                   None if d["runs"] is None else ValidationRuns.from_dict(d["runs"]),
                   None if values is None else np.asarray(values))


def _check_quantiles(quantiles):
    levels = tuple(float(q) for q in quantiles)
    if not levels or not all(0.0 < q < 1.0 for q in levels) or list(levels) != sorted(set(levels)):
        raise ValueError(f"RVC quantiles must be distinct levels in (0, 1), ascending, e.g. [0.05, 0.95]; "
                         f"got {list(quantiles)}")
    return levels


def output_columns(model, outputs):
    """``(names, columns)``: the outputs asked for (default every sensor at the last level) and their
    columns in the flattened readings (level-major, C order) of ``model`` (anything with
    ``sensor_names`` and ``load_levels``: a surrogate model or an FE scenario).

    Raises
    ------
    ValueError
        An output the model does not have (``F_peak``, ``d_peak``: a scenario without the option
        ``peak_readings``).
    """
    levels = np.asarray(model.load_levels, dtype=float)
    all_names = [f"{s}@{level:g}" for level in levels for s in model.sensor_names]
    if outputs is None:
        outputs = [f"{s}@{levels[-1]:g}" for s in model.sensor_names]
    # a bare sensor name is that sensor at the last level (a peak reading is the same at every level)
    full = [o if "@" in o else f"{o}@{levels[-1]:g}" for o in outputs]
    unknown = [o for o, f in zip(outputs, full) if f not in all_names]
    if unknown:
        hint = ("; F_peak and d_peak need the scenario option peak_readings = true"
                if any(o.split("@")[0] in ("F_peak", "d_peak") for o in unknown) else "")
        raise ValueError(f"unknown RVC output(s) {unknown}; outputs are SENSOR@LOAD (or SENSOR at the last level), "
                         f"e.g. {all_names[:3]}{hint}")
    return list(outputs), [all_names.index(f) for f in full]


def _members(region, model, fixed, max_samples, rng):
    """The region's members (a seeded subset of at most ``max_samples``) as full parameter rows of
    the model's space, ``(n, n_params)``, and the subset's rows in ``region.samples``."""
    fixed = dict(fixed or {})
    names = list(model.space.names)
    missing = [n for n in names if n not in region.names and n not in fixed]
    if missing:
        raise ValueError(f"RVC model needs values for {missing} (not calibrated): pass them as fixed")
    rows = np.arange(len(region.samples))
    if len(rows) > max_samples:
        rows = np.sort(np.random.default_rng(rng).choice(len(rows), max_samples, replace=False))
    X = region.samples[rows]
    full = np.empty((len(X), len(names)))
    for j, n in enumerate(names):
        full[:, j] = X[:, region.names.index(n)] if n in region.names else fixed[n]
    return full, rows


def rvc(region, model, *, fixed=None, outputs=None, max_samples=20000, rng=0, quantiles=QUANTILES, scenario=None,
        fe_runs=0):
    """Response variability of a (calibration or validation) model over a region of equivalence.

    Parameters
    ----------
    region : Region
    model : object
        A batched model (``space``, ``sensor_names``, ``load_levels``, ``predict``; optionally
        ``sensor_units``, default mm) whose space contains the region's parameters; its other
        parameters take the values in ``fixed``.
    fixed : dict of str to float, optional
    outputs : sequence of str, optional
        Output names ``"SENSOR@LOAD"``, or ``"SENSOR"`` at the last level (default: every sensor
        at the last load level).
    max_samples : int
        Region members used (a seeded random subset when there are more).
    rng : int
        Seed of the subsets (members used, members run on FE).
    quantiles : sequence of float
        Quantile levels in (0, 1), ascending (default the 5 % and 95 % quantiles).
    scenario : fe.Scenario, optional
        The model's FE scenario, for ``fe_runs``.
    fe_runs : int
        FE runs of ``scenario`` at a seeded subsample of the members used (at most all of them):
        :func:`run_validation`, the failed share of the validation runs.

    Returns
    -------
    RVCResult

    Raises
    ------
    ValueError
        A parameter of the model neither in the region nor ``fixed``; an unknown output;
        quantile levels outside (0, 1); ``fe_runs`` without a scenario.
    """
    levels = _check_quantiles(quantiles)
    if fe_runs and scenario is None:
        raise ValueError(f"fe_runs = {fe_runs} needs the validation model's FE scenario (scenario=...)")
    full, rows = _members(region, model, fixed, max_samples, rng)
    outputs, idx = output_columns(model, outputs)
    Y, _ = model.predict(full, return_std=True)
    Y = Y[:, idx]
    mean = Y.mean(axis=0)
    std = Y.std(axis=0, ddof=1) if len(Y) > 1 else np.zeros_like(mean)
    scale = np.maximum(np.abs(mean), 1e-300)
    units = getattr(model, "sensor_units", None) or {}
    unit = tuple(units.get(o.split("@")[0], "mm") for o in outputs)
    runs = None
    if fe_runs:
        pick = np.sort(np.random.default_rng([rng, 1]).choice(len(full), min(fe_runs, len(full)), replace=False))
        runs = run_validation(scenario, list(model.space.names), full[pick], idx, Y[pick],
                              region.names, region.samples[rows[pick]])
    return RVCResult(tuple(outputs), mean, std, std / scale, (Y.max(axis=0) - Y.min(axis=0)) / scale, Y.min(axis=0),
                     Y.max(axis=0), int(len(Y)), unit, levels, np.quantile(Y, levels, axis=0), runs, Y)


def run_validation(scenario, names, X, columns, predicted, region_names, members):
    """FE runs of a validation scenario at region members: :class:`ValidationRuns`.

    Parameters
    ----------
    scenario : fe.Scenario
    names : sequence of str
        The parameters of the columns of ``X``.
    X : ndarray of shape (n_runs, n_params)
        Full parameter rows, in their units.
    columns : sequence of int
        The outputs' columns in the flattened readings (level-major, C order).
    predicted : ndarray of shape (n_runs, n_outputs)
        The surrogate's outputs at the same rows.
    region_names : tuple of str
    members : ndarray of shape (n_runs, n_free)
        The region's members run (recorded in :attr:`ValidationRuns.parameters`).

    Returns
    -------
    ValidationRuns
    """
    levels = np.asarray(scenario.load_levels, dtype=float)
    status, no_peak, fe, messages = [], [], np.full(predicted.shape, np.nan), []
    for k, row in enumerate(X):
        try:
            response = scenario.run(dict(zip(names, map(float, row))))
        except Exception as e:  # noqa: BLE001 - an FE failure is a failed validation run, as in the offline stage
            status.append("error")
            no_peak.append(False)
            messages.append(f"{type(e).__name__}: {e}")
            logger.info("validation run %d of %d at a region member: %s", k + 1, len(X), messages[-1])
            continue
        fe[k] = response.readings.ravel()[list(columns)]
        state = getattr(response, "status", "converged")
        status.append(state)
        # no load maximum: the peak of a finished curve in its last control interval
        peak = getattr(response, "peak_displacement", math.nan)
        flat = state == "converged" and math.isfinite(peak) and bool(without_peak(peak, levels))
        no_peak.append(flat)
        if state != "converged":
            limit = f": {response.limit}" if getattr(response, "limit", "") else ""
            messages.append(f"{state}{limit}, reached {response.reached:.6g} {scenario.load_unit}")
        else:
            messages.append(f"no load maximum: the peak at {peak:.4g} {scenario.load_unit} is in the last control "
                            "interval" if flat else "")
        logger.info("validation run %d of %d at a region member: %s", k + 1, len(X), messages[-1] or "a load maximum")
    return ValidationRuns(tuple(region_names), np.asarray(members, dtype=float), tuple(status),
                          np.asarray(no_peak, dtype=bool), fe, np.asarray(predicted, dtype=float), tuple(messages))
