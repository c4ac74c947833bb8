"""The findings policy: when an identification deserves a warning, in which words, and what to do.

One place for every threshold and sentence that the ``podkrig invert`` command, the inversion and
study reports and a study's ``summary.json`` show: a :class:`Finding` is a warning in plain words
(``message``) with its remedy (``remedy``), a stable ``code`` for scripts and the report
``section`` it belongs to. Remedies name the user's next step in their own context: a command
line option for ``context="cli"``, a study-file setting for ``context="study"``.

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

The functions take result objects (:class:`~podkrig.online.invert.InverseResult`,
:class:`~podkrig.online.region.Region`) or, for stages a study reads back from its cache, their
``to_dict`` form; they compute nothing else.
"""

from dataclasses import dataclass

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

CONTEXTS = ("cli", "study")


def _g(value):
    """4 significant digits without an exponent below 10⁶ (``15934``, not ``1.593e+04``): both ends
    of an interval read alike."""
    text = f"{value:.4g}"
    return f"{value:.0f}" if "e+" in text and abs(value) < 1e6 else text

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
    """A warning in plain words.

    Attributes
    ----------
    code : str
        Stable identifier for scripts, e.g. ``"chi2-dof"``, ``"unidentified"``.
    section : str
        Report section it belongs to (``"inversion"``, ``"region"``, ``"held-out"``, ...).
    message : str
        What was found, with the numbers and their units.
    remedy : str
        What to do about it.
    level : str
        ``"warning"`` (every finding today).
    """

    code: str
    section: str
    message: str
    remedy: str
    level: str = "warning"

    def to_dict(self):
        """``{"code", "level", "section", "what", "what_to_do"}`` (the ``summary.json`` form)."""
        return {"code": self.code, "level": self.level, "section": self.section, "what": self.message,
                "what_to_do": self.remedy}

    @classmethod
    def from_dict(cls, d):
        return cls(d["code"], d["section"], d["what"], d["what_to_do"], d.get("level", "warning"))


def _unit(unit):
    """`` unit`` to append to a number, or nothing for a dimensionless one."""
    return f" {unit}" if unit and unit != "-" else ""


def _check_context(context):
    if context not in CONTEXTS:
        raise ValueError(f"context must be one of {CONTEXTS}; got {context!r}")


def identifiability_verdict(name, interval, unit, share):
    """The verdict on one parameter: ``{"share", "identifiable", "message"}``.

    Parameters
    ----------
    name : str
    interval : (float, float)
        Its equivalence interval, physical units.
    unit : str
    share : float
        Share of its search range (scaled unit coordinate) the interval spans, in [0, 1].
    """
    lo, hi = interval
    ok = share <= UNIDENTIFIABLE_SHARE
    unit = unit if unit != "-" else ""
    msg = (
        f"{name} is identified: [{_g(lo)}, {_g(hi)}] {unit} spans {100 * share:.0f} % of its search range"
        if ok else
        f"{name} is NOT pinned down by these data: values from {_g(lo)} to {_g(hi)} {unit} "
        f"({100 * share:.0f} % of its search range) fit equally well; fix it from other tests, "
        "add sensors sensitive to it, or report it as unidentified"
    )
    return {"share": float(share), "identifiable": bool(ok), "message": msg.replace("  ", " ")}


def at_bound(names, u):
    """Names whose unit-cube coordinate ``u`` lies within :data:`AT_BOUND_SHARE` of a bound."""
    return [n for n, uj in zip(names, u) if uj < AT_BOUND_SHARE or uj > 1 - AT_BOUND_SHARE]


def fe_check_ok(max_diff_over_noise):
    """Whether the FE check passes: ``max |FE − surrogate| / σ ≤`` :data:`FE_CHECK_LIMIT`."""
    return bool(max_diff_over_noise <= FE_CHECK_LIMIT)


def inversion_findings(result, region=None, *, context="cli", diagnosis_enabled=False, per_test=False):
    """Findings of an inversion and its region of equivalence, in report order.

    Parameters
    ----------
    result : InverseResult
        With its FE check when one was run.
    region : Region, optional
    context : {"cli", "study"}
        Where the remedies point: command-line options or study-file settings.
    diagnosis_enabled : bool
        (study) whether the study runs the model diagnosis, which names a missing effect.
    per_test : bool
        ``result`` is one test's view of a joint calibration: only its FE check and χ²/dof are
        judged (bounds and the region belong to the joint result).

    Returns
    -------
    list of Finding
    """
    _check_context(context)
    found = []
    fe = result.fe_check
    if fe is not None and not fe.ok:
        found.append(Finding(
            "fe-check", "inversion",
            f"at the optimum the surrogate differs from the FE model by up to {fe.max_diff_over_noise:.2f}× the "
            f"noise ({fe.max_abs_diff:.3g} mm): the identification is limited by the surrogate, not by the data.",
            "refine the surrogate near the optimum ('podkrig surrogate refine', or more snapshots in a narrower box) "
            "and invert again." if context == "cli" else
            "add training snapshots or narrow the bounds around the identified values, and run again."))
    units = dict(zip(result.free, result.units))
    for name in () if per_test else result.at_bound:
        found.append(Finding(
            "at-bound", "inversion",
            f"the best fit of {name} ({result.free_parameters[name]:.4g}{_unit(units[name])}) lies on a bound "
            "of its search range: the data may prefer a value outside it.",
            f"widen the range of {name} in the snapshot design (--param) and build the surrogate again."
            if context == "cli" else f"widen the bounds of {name} in [parameters] and run again."))
    if result.chi2_dof > CHI2_DOF_LIMIT:
        if context == "cli":
            then = "(run 'podkrig diagnose')."
        elif diagnosis_enabled:
            then = "the model diagnosis below names it."
        else:
            then = "switch on the model diagnosis ([diagnosis] enabled = true) to name it."
        found.append(Finding(
            "chi2-dof", "inversion",
            f"χ²/dof = {result.chi2_dof:.2f}: the calibrated model does not reproduce the data within the stated "
            "noise.",
            "check the noise level; if it is right, a physical effect is missing from the model"
            + (" " if context == "cli" else ": ") + then))
    if region is not None and not per_test:
        for name, v in region.identifiability.items():
            if v["identifiable"]:
                continue
            lo, hi = region.intervals[name]
            how = f"--fix {name}=VALUE" if context == "cli" else "[fixed]"
            found.append(Finding(
                "unidentified", "region",
                f"{name} is not pinned down by these data: values from {_g(lo)} to {_g(hi)}"
                f"{_unit(units[name])} ({100 * v['share']:.0f} % of its search range) fit equally well.",
                f"fix {name} from other tests ({how})"
                + ("" if context == "cli" else " or calibrate jointly with a test that informs it ([[test]] tables)")
                + ", add sensors sensitive to it, or report it as unidentified."))
    return found


def sensitivity_findings(result, *, context="cli"):
    """Findings of a global sensitivity analysis (the ``sensitivity`` stage's result dict): one per
    parameter proposed for fixing, because no reading and not the misfit is sensitive to it."""
    _check_context(context)
    found = []
    for name in result["propose_fixing"]:
        found.append(Finding(
            "insensitive", "sensitivity",
            f"no reading and not the misfit is sensitive to {name}: its total Sobol' index stays below "
            f"{result['threshold']:g} over the search box, so these data cannot inform it.",
            f"fix {name} from other tests or the literature ({'--fix' if context == 'cli' else '[fixed]'}) before "
            "the inversion, or add a test or sensors that respond to it."))
    return found


def offline_findings(title, store_result):
    """A finding for FE runs that failed in a snapshot stage (``store_result``: the stage's JSON)."""
    r = store_result
    if not r.get("failed"):
        return []
    return [Finding(
        "fe-failed", "offline",
        f"{r['failed']} of {r['total']} FE runs failed in stage '{title}' ({'; '.join(r['failures'])}).",
        "the surrogate was trained without them; read the errors (e.g. a parameter range that makes the "
        "model singular) and narrow the bounds, or inspect the store with 'podkrig snapshots info'.")]


def measurement_findings(checked, *, context="cli"):
    """Findings of the measurement check (``podkrig run``'s first stage, ``podkrig invert``).

    Parameters
    ----------
    checked : dict
        ``not_used`` (sensors of the model without a column), ``ignored`` (columns that name
        no sensor), ``sigma_below_floor`` (sensor → smallest σ, mm) and ``sigma_floor_mm``.
    """
    _check_context(context)
    found = []
    if checked.get("not_used") or checked.get("ignored"):
        parts = []
        if checked.get("not_used"):
            parts.append(f"sensor(s) of the model without a column, not used: {', '.join(checked['not_used'])}")
        if checked.get("ignored"):
            parts.append(f"column(s) that name no sensor, ignored: {', '.join(checked['ignored'])}")
        found.append(Finding(
            "measurement-columns", "study", "; ".join(parts) + ".",
            "nothing if intended; otherwise name each column as the sensor it reads (see 'podkrig scenarios "
            "NAME' for the sensor names)."))
    low = checked.get("sigma_below_floor") or {}
    if low:
        floor = checked.get("sigma_floor_mm")
        listed = ", ".join(f"{k} {1000 * v:.3g} µm" for k, v in low.items())
        found.append(Finding(
            "noise-below-floor", "study",
            f"the noise model gives σ below {1000 * floor:g} µm for {listed}: no laboratory instrument reads that "
            "finely (an LVDT or dial gauge resolves about 1 µm, DIC 2.5–5 µm), so the region of equivalence is "
            "optimistic.",
            ("give a resolution floor: --noise-abs 0.001 with --noise-rel, or --instrument lvdt" if context == "cli"
             else "give a resolution floor in [measurement]: noise_abs = 0.001 (mm) with noise_rel, or "
             "instrument = \"lvdt\".")))
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
        Absolute measurement noise σ, mm (per sensor: the smallest counts).
    """
    found = []
    more = "add training snapshots ([sampling] train.n, e.g. double it) or narrow the parameter bounds, and run again."
    if noise_rel is not None and held["rel_error"]["median"] > noise_rel:
        found.append(Finding(
            "surrogate-error", "held-out",
            f"the surrogate's median error on the held-out FE runs ({100 * held['rel_error']['median']:.2f} %) "
            f"exceeds the measurement noise ({100 * noise_rel:g} %): the identification is limited by the surrogate.",
            more))
    elif noise_abs is not None:
        sigma = min(noise_abs.values()) if isinstance(noise_abs, dict) else noise_abs
        if held["rms_abs_error_mm"] > sigma:
            found.append(Finding(
                "surrogate-error", "held-out",
                f"the surrogate's RMS error on the held-out FE runs ({held['rms_abs_error_mm']:.3g} mm) exceeds the "
                f"measurement noise (σ = {sigma:g} mm): the identification is limited by the surrogate.",
                more))
    if held["coverage_2sigma"] < COVERAGE_LIMIT:
        found.append(Finding(
            "surrogate-coverage", "held-out",
            f"only {100 * held['coverage_2sigma']:.0f} % of the held-out FE readings lie within ±2σ of the "
            "surrogate: its error bars are too narrow, so the region of equivalence may be too small.",
            "add training snapshots, or set a small [surrogate] nugget (e.g. 1e-6)."))
    return found


def diagnosis_findings(d):
    """Findings of a model diagnosis (``d``: :meth:`podkrig.diagnosis.Diagnosis.to_dict`)."""
    if d["verdict"] == "adequate":
        return []
    if d["cause"] is None:
        return [Finding(
            "diagnosis-unexplained", "diagnosis",
            f"the calibrated model does not explain the data (χ²/dof = {d['base']['chi2_dof']:.2f}) and no "
            "candidate cause in the library explains the residual.",
            "check the noise level and the measurement file; read the residual pattern in the diagnosis report "
            "for an effect outside the library (nonlinearity, another test set-up).")]
    causes = d.get("causes") or [{"cause": d["cause"], "location": d["detail"]["location"] if d["detail"] else None}]
    named = " and then ".join(c["cause"] + (f" at {c['location']}" if c["location"] else "") for c in causes)
    gain = (f" (χ²/dof {d['gain']['chi2_dof_before']:.2f} → {d['gain']['chi2_dof_after']:.2f} with "
            f"{'it' if len(causes) == 1 else 'them'})" if d["gain"] else "")
    effect = "a physical effect" if len(causes) == 1 else f"{len(causes)} physical effects"
    return [Finding(
        "diagnosis-cause", "diagnosis",
        f"the calibrated model leaves out {effect}: the diagnosis names {named}{gain}.",
        "read the diagnosis report; add the effect to the model (or repair the named sensor or set-up) "
        "and calibrate again: the parameters identified without it are biased.")]


__all__ = [
    "AT_BOUND_SHARE", "CHI2_BASIS", "CHI2_DOF_LIMIT", "COVERAGE_LIMIT", "FE_CHECK_LIMIT", "Finding",
    "RESIDUAL_CONVENTION", "UNIDENTIFIABLE_SHARE", "at_bound", "chi2_basis", "diagnosis_findings", "fe_check_ok", "held_out_findings", "identifiability_verdict",
    "inversion_findings", "offline_findings", "sensitivity_findings",
]
