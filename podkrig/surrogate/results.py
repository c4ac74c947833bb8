"""Results of the surrogate stage: the fit, and its check on held-out FE runs.

:class:`SurrogateFitResult` and :class:`HeldOutResult` are what a study's ``surrogate`` and
``held_out_validation`` stages record in their manifests (``to_dict``) and what
``podkrig surrogate validate`` reports; the study report and the CLI's report read them back with
``from_dict`` and render them through :mod:`podkrig.reports.surrogate`.
:class:`ValidationModelResult` joins the two for a study's validation model (its store and its
surrogate).

Examples
--------
>>> fit = SurrogateFitResult(n_train=16, n_modes=6, retained_energy=0.99999999, backend="podkrig",
...                          beta=(1.8, 1.8), training_seconds=0.4)
>>> SurrogateFitResult.from_dict(fit.to_dict()) == fit
True
>>> sorted(fit.to_dict())
['backend', 'beta', 'n_modes', 'n_train', 'pod', 'retained_energy', 'scaling', 'training_seconds']
"""

from dataclasses import dataclass

import numpy as np

from podkrig.display import Displayed
from podkrig.offline.results import OfflineResult
from podkrig.surrogate.kriging import OrdinaryKriging

__all__ = ["HeldOutResult", "SurrogateFitResult", "ValidationModelResult"]


@dataclass(frozen=True, repr=False)
class SurrogateFitResult(Displayed):
    """A fitted surrogate in numbers.

    Attributes
    ----------
    n_train : int
        Training snapshots.
    n_modes : int
        Retained POD modes.
    retained_energy : float
        Share of the snapshots' energy the modes keep (-).
    backend : str
        Regressor of the POD coefficients (:data:`podkrig.surrogate.settings.BACKENDS`).
    beta : tuple of float or None
        Fitted semivariogram exponent per mode (-), for our kriging; else None.
    description : str or None
        The backend's own description of its fit, for another backend; else None.
    training_seconds : float or None
        Wall time of the fit, s (None: not recorded, a surrogate file of an older podkrig).
    dropped_rows : tuple of int
        Failed rows of the training store left out of the fit (``failed_rows="drop"``,
        :func:`~podkrig.surrogate.settings.fit_surrogate`).
    pod, scaling : str
        The POD layout (``"stacked"`` over the control levels or ``"per_level"``) and the scaling
        of the outputs (:class:`~podkrig.surrogate.PODKriging`).
    excluded_rows : tuple of int
        Finished rows left out of the fit, and ``excluded_why`` why (e.g. no load maximum, for a
        surrogate of capacity; :func:`~podkrig.surrogate.settings.fit_surrogate`).
    excluded_why : str
    """

    n_train: int
    n_modes: int
    retained_energy: float
    backend: str
    beta: tuple | None = None
    description: str | None = None
    training_seconds: float | None = None
    dropped_rows: tuple = ()
    pod: str = "stacked"
    scaling: str = "none"
    excluded_rows: tuple = ()
    excluded_why: str = ""

    @classmethod
    def from_surrogate(cls, sur):
        """The numbers of a fitted :class:`~podkrig.surrogate.PODKriging` (its training time from
        ``provenance_["training_seconds"]``)."""
        ours = isinstance(sur.kriging_, OrdinaryKriging)
        seconds = sur.provenance_.get("training_seconds")
        return cls(n_train=len(sur.X_), n_modes=int(sur.n_modes_), retained_energy=float(sur.pod_.retained_energy_),
                   backend=sur.backend_, beta=tuple(float(b) for b in sur.kriging_.beta_) if ours else None,
                   description=None if ours else sur.kriging_.describe(),
                   training_seconds=None if seconds is None else float(seconds),
                   dropped_rows=tuple(int(i) for i in sur.provenance_.get("dropped_rows", ())),
                   pod=sur.layout, scaling=sur.scaling,
                   excluded_rows=tuple(int(i) for i in sur.provenance_.get("excluded_rows", ())),
                   excluded_why=sur.provenance_.get("excluded_why", ""))

    def to_dict(self):
        """JSON-able dict (the study's ``surrogate`` manifest): ``beta`` for our kriging,
        ``description`` for another backend."""
        out = {"n_train": self.n_train, "n_modes": self.n_modes, "retained_energy": self.retained_energy,
               "backend": self.backend}
        if self.beta is not None:
            out["beta"] = list(self.beta)
        if self.description is not None:
            out["description"] = self.description
        out["training_seconds"] = self.training_seconds
        if self.dropped_rows:
            out["dropped_rows"] = list(self.dropped_rows)
        if self.excluded_rows:
            out.update(excluded_rows=list(self.excluded_rows), excluded_why=self.excluded_why)
        out.update(pod=self.pod, scaling=self.scaling)
        return out

    @classmethod
    def from_dict(cls, d):
        return cls(n_train=int(d["n_train"]), n_modes=int(d["n_modes"]), retained_energy=float(d["retained_energy"]),
                   backend=d.get("backend", "podkrig"),
                   beta=None if d.get("beta") is None else tuple(float(b) for b in d["beta"]),
                   description=d.get("description"),
                   training_seconds=None if d.get("training_seconds") is None else float(d["training_seconds"]),
                   dropped_rows=tuple(int(i) for i in d.get("dropped_rows", ())),
                   pod=d.get("pod", "stacked"), scaling=d.get("scaling", "none"),
                   excluded_rows=tuple(int(i) for i in d.get("excluded_rows", ())),
                   excluded_why=d.get("excluded_why", ""))


@dataclass(frozen=True, repr=False)
class HeldOutResult(Displayed):
    """A surrogate's errors on held-out FE runs: the summary of a
    :class:`~podkrig.surrogate.validation.HeldOutReport` and its absolute errors.

    Attributes
    ----------
    n_train, n_held_out, n_modes : int
    rel_error, pod_error, interp_error : dict
        ``{median, p95, max, mean}`` of the relative errors per held-out run (-): total, POD
        truncation and interpolation parts (:meth:`HeldOutReport.summary`).
    coverage_2sigma : float
        Share of held-out readings within ±2σ of the prediction (-).
    rms_abs_error_mm, max_abs_error_mm : float
        RMS and largest absolute error over every held-out reading in mm (a force in kN is not
        among them: see ``by_unit``), mm.
    by_unit : dict or None
        The errors per unit (:meth:`HeldOutReport.by_unit`); None in results written before.
    loo_error : dict or None
        Leave-one-out relative errors of the training snapshots (our kriging only).
    fit : dict or None
        How our kriging was trained (:meth:`~podkrig.surrogate.kriging.FitMethod.to_dict`).
    fit_description : str or None
        The same in words.
    backend : str or None
        The surrogate's backend (as ``podkrig surrogate validate`` reports it).
    held_out_store, held_out_content_hash : str or None
        The held-out store and its content hash (as ``podkrig surrogate validate`` reports them).
    layout : str or None
        The surrogate's POD layout (``"stacked"`` or ``"per_level"``), with ``layouts``.
    layouts : dict or None
        The held-out errors per unit of both POD layouts on the same training snapshots
        (:func:`~podkrig.surrogate.validation.compare_layouts`: layout → ``{n_modes, by_unit}``), when
        they were compared (a study's nonlinear test with more than one control level).
    """

    n_train: int
    n_held_out: int
    n_modes: int
    rel_error: dict
    pod_error: dict
    interp_error: dict
    coverage_2sigma: float
    rms_abs_error_mm: float
    max_abs_error_mm: float
    loo_error: dict | None = None
    fit: dict | None = None
    fit_description: str | None = None
    backend: str | None = None
    held_out_store: str | None = None
    held_out_content_hash: str | None = None
    by_unit: dict | None = None
    layout: str | None = None
    layouts: dict | None = None

    _OPTIONAL = ("loo_error", "fit", "fit_description", "held_out_store", "held_out_content_hash", "backend",
                 "by_unit", "layout", "layouts")

    @classmethod
    def from_report(cls, report, **provenance):
        """The result of a :class:`~podkrig.surrogate.validation.HeldOutReport` (``provenance``:
        ``backend``, ``held_out_store``, ``held_out_content_hash``, ``layout`` and ``layouts``)."""
        s = report.summary()
        units = np.asarray(report.units) if len(report.units) else None
        mm = units == "mm" if units is not None and np.any(units == "mm") else slice(None)
        diff = report.Y_pred[:, mm] - report.Y_true[:, mm]
        return cls(n_train=s["n_train"], n_held_out=s["n_held_out"], n_modes=s["n_modes"], rel_error=s["rel_error"],
                   pod_error=s["pod_error"], interp_error=s["interp_error"], coverage_2sigma=s["coverage_2sigma"],
                   rms_abs_error_mm=float(np.sqrt(np.mean(diff**2))), max_abs_error_mm=float(np.max(np.abs(diff))),
                   loo_error=s.get("loo_error"), fit=s.get("fit"), fit_description=s.get("fit_description"),
                   by_unit=s["by_unit"], **provenance)

    def to_dict(self):
        """JSON-able dict (the study's ``held_out_validation`` manifest, the JSON of ``podkrig
        surrogate validate``): the fields in :meth:`HeldOutReport.summary`'s order, then the absolute
        errors, the provenance and the comparison of the POD layouts; a field that is None is left out."""
        out = {"n_train": self.n_train, "n_held_out": self.n_held_out, "n_modes": self.n_modes,
               "rel_error": dict(self.rel_error), "pod_error": dict(self.pod_error),
               "interp_error": dict(self.interp_error), "coverage_2sigma": self.coverage_2sigma}
        for key in ("loo_error", "fit", "fit_description", "by_unit"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        out.update(rms_abs_error_mm=self.rms_abs_error_mm, max_abs_error_mm=self.max_abs_error_mm)
        for key in ("held_out_store", "held_out_content_hash", "backend", "layout", "layouts"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        return out

    @classmethod
    def from_dict(cls, d):
        return cls(n_train=int(d["n_train"]), n_held_out=int(d["n_held_out"]), n_modes=int(d["n_modes"]),
                   rel_error=dict(d["rel_error"]), pod_error=dict(d["pod_error"]), interp_error=dict(d["interp_error"]),
                   coverage_2sigma=float(d["coverage_2sigma"]), rms_abs_error_mm=float(d["rms_abs_error_mm"]),
                   max_abs_error_mm=float(d["max_abs_error_mm"]), **{k: d.get(k) for k in cls._OPTIONAL})


@dataclass(frozen=True, repr=False)
class ValidationModelResult(Displayed):
    """A study's validation model: its snapshot store and its surrogate.

    Attributes
    ----------
    store : OfflineResult
    scenario : str
        The validation scenario's name.
    surrogate : SurrogateFitResult
    """

    store: OfflineResult
    scenario: str
    surrogate: SurrogateFitResult

    def to_dict(self):
        """The store's dict with ``scenario`` and ``surrogate`` (the study's ``validation_model.NAME``
        manifest)."""
        return {**self.store.to_dict(), "scenario": self.scenario, "surrogate": self.surrogate.to_dict()}

    @classmethod
    def from_dict(cls, d):
        store = OfflineResult.from_dict({k: v for k, v in d.items() if k not in ("scenario", "surrogate")})
        return cls(store, d["scenario"], SurrogateFitResult.from_dict(d["surrogate"]))
