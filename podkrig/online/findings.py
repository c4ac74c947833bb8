"""The findings policy: when an identification deserves a warning, as a code and its numbers.

One place for every threshold behind the warnings that the ``podkrig invert`` command, the
inversion and study reports and a study's ``summary.json`` show: a :class:`Finding` is a stable
``code`` for scripts, the report ``section`` it belongs to, a ``level`` and the ``values`` it is
about (numbers with their units in the key names, parameter and sensor names). The sentences and
the remedies — in the user's own context, a command-line option or a study-file setting — are
written by :mod:`podkrig.reports.findings`, the one place that words each code.

Thresholds
----------
- :data:`CHI2_DOF_LIMIT`: χ²/dof above it means the calibrated model does not explain the data
  within the stated noise (the χ² statistic per degree of freedom is about 1 ± √(2/dof) when it
  does; 2 is beyond the 99.9th percentile for dof ≥ 20).
- :data:`FE_CHECK_LIMIT`: the surrogate and the FE model at the optimum should agree within one
  noise σ at every observed reading.
- :data:`UNIDENTIFIABLE_SHARE`: a parameter whose equivalence interval spans more than half its
  (scaled) search range is not pinned down by the data.
- :data:`AT_BOUND_SHARE`: a best fit within 0.5 % of its scaled search range from a bound lies on
  the bound.
- :data:`COVERAGE_LIMIT`: fewer held-out readings than this share inside the surrogate's ±2σ
  means its error bars are too narrow.
- :data:`FAILURE_PROBABILITY_LIMIT`: a best fit where the classifier of the training runs that
  failed (:class:`~podkrig.offline.failures.FailureRegion`) predicts at least this probability
  of failure lies in or near the failing region, where the surrogate had no data.

The functions take result objects (:class:`~podkrig.online.invert.InverseResult`,
:class:`~podkrig.online.region.Region`) or, for stages a study reads back from its cache, their
``to_dict`` form; they compute nothing else.

Codes and their ``values``
--------------------------
- ``fe-check``: ``max_diff_over_noise`` (-), ``max_abs_diff`` (the largest difference, in its
  entry's unit), ``max_abs_diff_by_unit`` (unit of the readings → the largest difference of that
  unit, mm or kN; None for a result read back without it), and ``stopped`` when the FE run
  at the optimum stopped early (:attr:`~podkrig.online.invert.FECheck.stopped`);
- ``at-bound``: ``parameter``, ``value``, ``unit``;
- ``chi2-dof``: ``chi2_dof`` (-);
- ``unidentified``: ``parameter``, ``low``, ``high``, ``unit``, ``share`` (-);
- ``insensitive``: ``parameter``, ``threshold`` (-);
- ``fe-failed``: ``stage``, ``failed``, ``total``, ``failures`` (list of str);
- ``near-failure``: ``probability`` (-, predicted failure probability at the best fit),
  ``failed_share`` (-, of the training runs), ``driving`` (list of ``{"parameter", "towards"}``);
- ``measurement-columns``: ``not_used``, ``ignored`` (lists of names);
- ``noise-below-floor``: ``sigma_mm`` (sensor → smallest σ, mm), ``sigma_floor_mm``;
- ``surrogate-error``: ``median_rel_error`` and ``noise_rel`` (-), or ``rms_abs_error_mm`` and
  ``sigma_mm``;
- ``surrogate-coverage``: ``coverage_2sigma`` (-);
- ``diagnosis-unexplained``: ``chi2_dof`` (-);
- ``diagnosis-cause``: ``causes`` (list of ``{"cause", "location"}``), ``chi2_dof_before``,
  ``chi2_dof_after`` (-, None without a refit).
"""

import dataclasses
from dataclasses import dataclass, field

import numpy as np

#: χ²/dof above which the calibrated model does not reproduce the data within the noise (-)
CHI2_DOF_LIMIT = 2.0
#: largest |FE − surrogate| / σ_noise at the optimum for which the surrogate counts as exact (-)
FE_CHECK_LIMIT = 1.0
#: a parameter whose equivalence interval spans more than this share of its search range (in the
#: scaled unit coordinate) is reported as not identifiable from the data (-)
UNIDENTIFIABLE_SHARE = 0.5
#: a best fit within this share of its scaled search range from a bound lies on the bound (-)
AT_BOUND_SHARE = 0.005
#: least share of held-out FE readings within ±2σ of the surrogate (-)
COVERAGE_LIMIT = 0.8
#: predicted probability of a failed FE run at the best fit from which it lies near the failing
#: region (-): the classifier's 50 % boundary is the region's edge, and 0.2 is where its log-odds
#: are 1.4 short of it — within the transition band of the training runs, not inside the region
FAILURE_PROBABILITY_LIMIT = 0.2


#: the one sign convention of standardised residuals, on every page, table and JSON field:
#: positive where the specimen moved more than the model predicts
RESIDUAL_CONVENTION = "(measured − model)/σ"

#: what each χ²/dof of a study measures: the model whose readings are compared with the data,
#: and what the covariance C_D in χ² = rᵀ C_D⁻¹ r holds. Three numbers for "the best fit" differ
#: for these reasons only (the diagnosis also refits the parameters with the FE model).
CHI2_BASIS = {
    "surrogate": "surrogate at its best fit; C_D = data noise C_d + surrogate variance C_T",
    "surrogate-noise": "surrogate at its best fit; C_D = data noise C_d only",
    "fe_check": "FE model at the surrogate's best fit; C_D = data noise C_d only",
    "diagnosis": "FE model refitted by the diagnosis; C_D = data noise C_d + model-form error C_T",
}


def chi2_basis(kind, model_error=None, form_error=None):
    """The sentence of :data:`CHI2_BASIS` for ``kind``; for ``"diagnosis"`` with how the model-form
    error C_T was obtained (``model_error``: its description, e.g. "e², e estimated per reading
    from two meshes ..."); for an inversion with the FE model's model-form error in C_D
    (``form_error``: its description), that term appended."""
    text = CHI2_BASIS[kind]
    if kind == "diagnosis" and model_error is not None:
        text += f" = {model_error}"
    if form_error is not None:
        text += f" + FE model-form error {form_error}"
    return text


@dataclass(frozen=True)
class Finding:
    """A result that deserves a warning: its code and the numbers and names it is about.

    Attributes
    ----------
    code : str
        Stable identifier, e.g. ``"chi2-dof"``, ``"unidentified"`` (the module docstring lists
        every code with its ``values``).
    section : str
        Report section it belongs to (``"inversion"``, ``"region"``, ``"held-out"``, ...).
    values : dict
        What was found: numbers (units in the key names), parameter and sensor names.
    level : str
        ``"warning"``, or ``"error"`` for a refusal of the measurement check
        (:mod:`podkrig.online.data_check`).
    test : str or None
        The test of a joint calibration it concerns (None: the study or the one test).
    """

    code: str
    section: str
    values: dict = field(default_factory=dict)
    level: str = "warning"
    test: str | None = None

    def to_dict(self):
        """``{"code", "level", "section", "values", "test"}`` (JSON-able when the values are)."""
        return {"code": self.code, "level": self.level, "section": self.section, "values": dict(self.values),
                "test": self.test}

    @classmethod
    def from_dict(cls, d):
        return cls(d["code"], d["section"], dict(d.get("values", {})), d.get("level", "warning"), d.get("test"))


def of_test(name, findings):
    """``findings`` of test ``name`` of a joint calibration, each naming it (``name`` None: of the
    study or its one test, as they are)."""
    if name is None:
        return list(findings)
    return [dataclasses.replace(f, test=name) for f in findings]


def is_identifiable(share):
    """Whether a parameter whose equivalence interval spans ``share`` of its scaled search range
    (in [0, 1]) is identified: ``share <=`` :data:`UNIDENTIFIABLE_SHARE`."""
    return bool(share <= UNIDENTIFIABLE_SHARE)


def at_bound(names, u):
    """Names whose unit-cube coordinate ``u`` lies within :data:`AT_BOUND_SHARE` of a bound."""
    return [n for n, uj in zip(names, u) if uj < AT_BOUND_SHARE or uj > 1 - AT_BOUND_SHARE]


def fe_check_ok(max_diff_over_noise):
    """Whether the FE check passes: ``max |FE − surrogate| / σ ≤`` :data:`FE_CHECK_LIMIT`."""
    return bool(max_diff_over_noise <= FE_CHECK_LIMIT)


def inversion_findings(result, region=None, *, per_test=False):
    """Findings of an inversion and its region of equivalence, in report order.

    Parameters
    ----------
    result : InverseResult
        With its FE check when one was run.
    region : Region, optional
    per_test : bool
        ``result`` is one test's view of a joint calibration: only its FE check and χ²/dof are
        judged (bounds and the region belong to the joint result).

    Returns
    -------
    list of Finding
        Codes ``fe-check``, ``at-bound`` (one per parameter), ``chi2-dof``, ``unidentified``
        (one per parameter), in this order.
    """
    found = []
    fe = result.fe_check
    if fe is not None and not fe.ok:
        by_unit = None if fe.max_abs_diff_by_unit is None else dict(fe.max_abs_diff_by_unit)
        values = {"max_diff_over_noise": float(fe.max_diff_over_noise), "max_abs_diff": float(fe.max_abs_diff),
                  "max_abs_diff_by_unit": by_unit}
        found.append(Finding("fe-check", "inversion", values | ({"stopped": fe.stopped} if fe.stopped else {})))
    units = dict(zip(result.free, result.units))
    for name in () if per_test else result.at_bound:
        found.append(Finding("at-bound", "inversion", {"parameter": name, "value": result.free_parameters[name],
                                                       "unit": units[name]}))
    if result.chi2_dof > CHI2_DOF_LIMIT:
        found.append(Finding("chi2-dof", "inversion", {"chi2_dof": float(result.chi2_dof)}))
    if region is not None and not per_test:
        for name, v in region.identifiability.items():
            if v["identifiable"]:
                continue
            lo, hi = region.intervals[name]
            found.append(Finding("unidentified", "region", {"parameter": name, "low": float(lo), "high": float(hi),
                                                            "unit": units[name], "share": float(v["share"])}))
    return found


def failure_findings(region, failed_share, u):
    """A ``near-failure`` finding when the best fit lies in or near the region where the training
    runs failed.

    Parameters
    ----------
    region : FailureRegion
        The classifier of the training store's failed runs (:mod:`podkrig.offline.failures`).
    failed_share : float
        Failed share of the training runs (-).
    u : array_like of shape (d,)
        The best fit in the unit cube of the store's parameters (``region.names``).

    Returns
    -------
    list of Finding
        One ``near-failure`` when the predicted failure probability at ``u`` is at least
        :data:`FAILURE_PROBABILITY_LIMIT`, else none.
    """
    p = float(region.probability(np.asarray(u, dtype=float)[None])[0])
    if p < FAILURE_PROBABILITY_LIMIT:
        return []
    return [Finding("near-failure", "inversion", {
        "probability": p, "failed_share": float(failed_share),
        "driving": [{"parameter": n, "towards": region.direction(n)} for n in region.driving()]})]


def sensitivity_findings(result):
    """Findings of a global sensitivity analysis (the ``sensitivity`` stage's result dict): one
    ``insensitive`` per parameter proposed for fixing, because no reading and not the misfit is
    sensitive to it."""
    return [Finding("insensitive", "sensitivity", {"parameter": name, "threshold": float(result["threshold"])})
            for name in result["propose_fixing"]]


def offline_findings(title, store_result):
    """An ``fe-failed`` finding for FE runs that failed in a snapshot stage (``store_result``: the
    stage's JSON; ``title``: the stage's title)."""
    r = store_result
    if not r.get("failed"):
        return []
    return [Finding("fe-failed", "offline", {"stage": title, "failed": int(r["failed"]), "total": int(r["total"]),
                                             "failures": list(r["failures"])})]


def measurement_findings(checked):
    """Findings of the measurement check (``podkrig run``'s first stage, ``podkrig invert``).

    Parameters
    ----------
    checked : dict
        ``not_used`` (sensors of the model without a column), ``ignored`` (columns that name
        no sensor), ``sigma_below_floor`` (sensor → smallest σ, mm) and ``sigma_floor_mm``.

    Returns
    -------
    list of Finding
        ``measurement-columns`` and ``noise-below-floor``, when they apply.
    """
    found = []
    if checked.get("not_used") or checked.get("ignored"):
        found.append(Finding("measurement-columns", "study", {"not_used": list(checked.get("not_used") or ()),
                                                             "ignored": list(checked.get("ignored") or ())}))
    low = checked.get("sigma_below_floor") or {}
    if low:
        found.append(Finding("noise-below-floor", "study", {"sigma_mm": dict(low),
                                                           "sigma_floor_mm": checked.get("sigma_floor_mm")}))
    return found


def held_out_findings(held, *, noise_rel=None, noise_abs=None):
    """Findings of the surrogate's check on held-out FE runs.

    Parameters
    ----------
    held : dict
        The held-out stage's JSON: :meth:`HeldOutReport.summary` plus ``rms_abs_error_mm``.
    noise_rel : float, optional
        Relative measurement noise δ (-).
    noise_abs : float or dict of str to float, optional
        Absolute measurement noise σ, mm (per sensor, in the sensor's unit: the smallest of the mm
        sensors counts; a scalar is the gauges' σ in mm). The errors of other units (a force in
        kN) are never compared with it.

    Returns
    -------
    list of Finding
        ``surrogate-error`` (the median relative error above ``noise_rel``, or else the RMS error
        above σ) and ``surrogate-coverage`` (fewer than :data:`COVERAGE_LIMIT` of the readings
        within ±2σ).
    """
    found = []
    median = held["rel_error"]["median"]
    if noise_rel is not None and median > noise_rel:
        found.append(Finding("surrogate-error", "held-out", {"median_rel_error": float(median),
                                                            "noise_rel": float(noise_rel)}))
    elif noise_abs is not None:
        if isinstance(noise_abs, dict):
            mm = (held.get("by_unit") or {}).get("mm", {}).get("sensors")  # the gauges' σ, not a load cell's kN
            sigmas = [v for k, v in noise_abs.items() if mm is None or k in mm]
            sigma = min(sigmas) if sigmas else None
        else:
            sigma = noise_abs
        if sigma is not None and held["rms_abs_error_mm"] > sigma:
            found.append(Finding("surrogate-error", "held-out", {"rms_abs_error_mm": float(held["rms_abs_error_mm"]),
                                                                "sigma_mm": float(sigma)}))
    if held["coverage_2sigma"] < COVERAGE_LIMIT:
        found.append(Finding("surrogate-coverage", "held-out", {"coverage_2sigma": float(held["coverage_2sigma"])}))
    return found


def diagnosis_findings(d):
    """Findings of a model diagnosis (``d``: :meth:`podkrig.diagnosis.DiagnosisResult.to_dict`):
    ``diagnosis-unexplained`` or ``diagnosis-cause`` unless the model is adequate."""
    if d["verdict"] == "adequate":
        return []
    if d["cause"] is None:
        return [Finding("diagnosis-unexplained", "diagnosis", {"chi2_dof": float(d["base"]["chi2_dof"])})]
    causes = d.get("causes") or [{"cause": d["cause"], "location": d["detail"]["location"] if d["detail"] else None}]
    gain = d.get("gain")
    return [Finding("diagnosis-cause", "diagnosis", {
        "causes": [{"cause": c["cause"], "location": c["location"]} for c in causes],
        "chi2_dof_before": None if not gain else float(gain["chi2_dof_before"]),
        "chi2_dof_after": None if not gain else float(gain["chi2_dof_after"])})]


__all__ = [
    "AT_BOUND_SHARE", "CHI2_BASIS", "CHI2_DOF_LIMIT", "COVERAGE_LIMIT", "FAILURE_PROBABILITY_LIMIT", "FE_CHECK_LIMIT",
    "Finding", "failure_findings",
    "RESIDUAL_CONVENTION", "UNIDENTIFIABLE_SHARE", "at_bound", "chi2_basis", "diagnosis_findings", "fe_check_ok",
    "held_out_findings", "inversion_findings", "is_identifiable", "measurement_findings", "of_test", "offline_findings",
    "sensitivity_findings",
]
