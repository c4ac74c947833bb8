"""Where in parameter space FE runs fail: the share of failed rows of a snapshot store and a
classifier of the failing region.

A nonlinear run that stops early (its step, iteration or CPU budget exhausted, or no convergence)
and any other failed FE run is a ``failed`` row of the store (:mod:`podkrig.offline.store`).
:func:`failure_report` counts them — per reason: the budget limit that ended a run, or
non-convergence — and fits :class:`FailureRegion`, a classifier of failure on the unit-cube
coordinates ``u`` of the design:

.. math::

    P(\\text{fail} \\mid u) = \\sigma(b + w^\\top (u - \\tfrac12)), \\qquad
    \\sigma(z) = 1 / (1 + e^{-z}),

by L2-regularised logistic regression (scikit-learn ``LogisticRegression``, ``C`` =
:data:`REGULARISATION`). Why this classifier, not a random forest or an SVC: a budget or a
convergence failure sets in where a strength or a fracture energy crosses a threshold, so over a
calibration box the failing region is close to a half-space in ``u``, which is exactly what a
linear classifier describes; its ``d + 1`` numbers are the whole model (stored as JSON in a
surrogate's provenance, evaluated by the inversion without scikit-learn or pickling), and each
weight ``w_j`` is the change of the log-odds of failure across parameter ``j``'s whole range —
directly comparable between parameters, with a sign that says towards which end runs fail.

The words (the share, the driving parameters, the region) are written by
:mod:`podkrig.reports.offline`; the inversion's warning near the region by
:func:`podkrig.online.findings.failure_findings`.

Examples
--------
>>> import numpy as np
>>> U = np.random.default_rng(0).random((200, 2))
>>> region = FailureRegion.fit(U, U[:, 1] > 0.7, ("ft", "GfI"))
>>> region.driving()[0], bool(region.probability([[0.5, 0.95]])[0] > 0.5)
('GfI', True)
"""

from dataclasses import dataclass

import numpy as np

from podkrig.display import Displayed
from podkrig.offline.store import FAILED, PENDING

__all__ = ["DRIVING_SHARE", "MIN_CLASS", "REGULARISATION", "FailureRegion", "FailureReport", "failure_report",
           "no_peak_rows", "without_peak"]

#: inverse L2 regularisation strength C of the logistic regression on unit-cube coordinates: weak
#: enough that a sharp boundary gets weights of tens (a transition ~0.1 of the range wide), strong
#: enough to keep the weights finite on separable data (-)
REGULARISATION = 100.0
#: a parameter drives failure when its weight is at least this share of the largest weight (-)
DRIVING_SHARE = 0.25
#: fewest failed and fewest finished runs for which a classifier is fitted
MIN_CLASS = 2


@dataclass(frozen=True)
class FailureRegion:
    """A fitted logistic classifier of failed FE runs over the unit cube of a design.

    Attributes
    ----------
    names : tuple of str
        Free parameters, in the order of the unit-cube coordinates, length ``d``.
    weights : tuple of float, length d
        ``w``: change of the log-odds of failure from the lower to the upper bound of each
        parameter's (scaled) range (-).
    intercept : float
        ``b``: log-odds of failure at the centre of the box (-).
    accuracy : float
        Share of the training runs the classifier puts on their own side (-).
    """

    names: tuple
    weights: tuple
    intercept: float
    accuracy: float

    @classmethod
    def fit(cls, U, failed, names):
        """Fit the classifier to runs at unit-cube points ``U`` (n, d) with outcome ``failed``
        (n,) bool; needs at least :data:`MIN_CLASS` runs of each outcome (ValueError otherwise)."""
        from sklearn.linear_model import LogisticRegression  # ~0.5 s of imports, only when runs failed

        U = np.asarray(U, dtype=float)
        failed = np.asarray(failed, dtype=bool)
        if U.ndim != 2 or U.shape != (len(failed), len(names)):
            raise ValueError(f"U must have shape ({len(failed)}, {len(names)}); got {U.shape}")
        if min(failed.sum(), (~failed).sum()) < MIN_CLASS:
            raise ValueError(f"a failure classifier needs at least {MIN_CLASS} failed and {MIN_CLASS} finished runs; "
                             f"got {int(failed.sum())} failed of {len(failed)}")
        clf = LogisticRegression(C=REGULARISATION).fit(U - 0.5, failed)
        accuracy = float(np.mean(clf.predict(U - 0.5) == failed))
        return cls(tuple(names), tuple(float(w) for w in clf.coef_[0]), float(clf.intercept_[0]), accuracy)

    def probability(self, U):
        """Predicted probability of failure at unit-cube points ``U`` (n, d), ndarray (n,)."""
        z = self.intercept + (np.atleast_2d(np.asarray(U, dtype=float)) - 0.5) @ np.asarray(self.weights)
        return 0.5 * (1.0 + np.tanh(0.5 * z))  # σ(z), without overflow

    def driving(self):
        """Parameters that drive failure (weight at least :data:`DRIVING_SHARE` of the largest),
        strongest first."""
        size = np.abs(np.asarray(self.weights))
        order = np.argsort(-size, kind="stable")
        return [self.names[j] for j in order if size[j] >= DRIVING_SHARE * size.max() and size[j] > 0]

    def direction(self, name):
        """``"high"`` when runs fail more towards the upper bound of ``name``, else ``"low"``."""
        return "high" if self.weights[self.names.index(name)] > 0 else "low"

    def to_dict(self):
        """JSON-able dict; :meth:`from_dict` reads it back."""
        return {"method": "logistic regression on unit-cube coordinates", "names": list(self.names),
                "weights": [float(w) for w in self.weights], "intercept": self.intercept, "accuracy": self.accuracy}

    @classmethod
    def from_dict(cls, d):
        """The classifier of :meth:`to_dict`'s dict ``d``."""
        return cls(tuple(d["names"]), tuple(float(w) for w in d["weights"]), float(d["intercept"]),
                   float(d["accuracy"]))


@dataclass(frozen=True, repr=False)
class FailureReport(Displayed):
    """Failed rows of a store: how many, why, and where.

    Attributes
    ----------
    n_run : int
        Rows run (done or failed).
    rows : tuple of int
        The failed rows.
    reasons : dict of str to int
        Failed rows per reason: the budget limit that ended a run that stopped early
        (``"steps"``, ``"iterations"``, ``"cpu"``, ``"wall"``), ``"not converged"``, or
        ``"error"`` (the FE run raised).
    region : FailureRegion or None
        None when fewer than :data:`MIN_CLASS` runs failed or finished.
    """

    n_run: int
    rows: tuple
    reasons: dict
    region: FailureRegion | None

    @property
    def n_failed(self):
        """Number of failed rows (int)."""
        return len(self.rows)

    @property
    def share(self):
        """Failed share of the rows run (-)."""
        return self.n_failed / self.n_run if self.n_run else 0.0

    def to_dict(self):
        """JSON-able dict with ``n_failed`` and ``share``; :meth:`from_dict` reads it back."""
        return {"n_run": self.n_run, "n_failed": self.n_failed, "share": self.share, "rows": list(self.rows),
                "reasons": dict(self.reasons), "region": None if self.region is None else self.region.to_dict()}

    @classmethod
    def from_dict(cls, d):
        """The report of :meth:`to_dict`'s dict ``d``."""
        return cls(int(d["n_run"]), tuple(int(i) for i in d["rows"]), dict(d["reasons"]),
                   None if d["region"] is None else FailureRegion.from_dict(d["region"]))


def failure_report(store):
    """The failed rows of an open :class:`~podkrig.offline.store.SnapshotStore`, their reasons and
    (with enough runs of each outcome) the classifier of where they fail."""
    status = store.status()
    ran = status != PENDING
    failed = status == FAILED
    partial = store.partial_rows()
    reasons = {}
    for row in np.flatnonzero(failed):
        info = partial.get(int(row))
        reason = "error" if info is None else info["limit"] or "not converged"
        reasons[reason] = reasons.get(reason, 0) + 1
    region = None
    if min(failed.sum(), (ran & ~failed).sum()) >= MIN_CLASS:
        U = store.parameters(physical=False, only_done=False)
        region = FailureRegion.fit(U[ran], failed[ran], store.space.names)
    return FailureReport(int(ran.sum()), tuple(int(i) for i in np.flatnonzero(failed)), reasons, region)


def without_peak(d_peak, load_levels):
    """Whether a curve whose peak load lies at the control displacement ``d_peak`` (mm) has no
    load maximum over the control levels ``load_levels`` (mm, ascending): its peak lies in the
    last control interval, beyond the last level but one — the load does not fall over a whole
    control interval after it (still rising at the end, or a plateau), so the run gives no
    capacity; a longer control range would tell.

    Parameters
    ----------
    d_peak : float or ndarray
    load_levels : sequence of float

    Returns
    -------
    bool or ndarray of bool
    """
    levels = np.asarray(load_levels, dtype=float)
    before_last = levels[-2] if len(levels) > 1 else 0.0
    return np.asarray(d_peak) > before_last * (1 + 1e-9)


def no_peak_rows(store):
    """Finished rows of an open store without a load maximum (:func:`without_peak`), so without
    a capacity (their ``F_peak`` is a lower bound), read from their ``d_peak`` reading (the
    control displacement at the peak, option ``peak_readings`` of a nonlinear scenario). A store
    without that reading has no capacity outputs: none.

    Returns
    -------
    tuple of int
        Store rows, ascending.
    """
    if "d_peak" not in store.sensor_names:
        return ()
    done = np.flatnonzero(store.done_mask())
    d_peak = store.readings(only_done=True)[:, -1, store.sensor_names.index("d_peak")]
    return tuple(int(i) for i in done[without_peak(d_peak, store.load_levels)])
