"""The words of every finding: what was found, in plain words with its numbers, and what to do.

The numerics judge (:mod:`podkrig.online.findings`: a :class:`~podkrig.online.findings.Finding`
is a code, a section and its values); this module is the one place that words each code. Remedies
name the user's next step in their own context: a command-line option for ``context="cli"``
(``podkrig invert``), a study-file setting for ``context="study"`` (``podkrig run``, the study
report and ``summary.json``).

Example
-------
>>> from podkrig.online.findings import Finding
>>> text = word(Finding("chi2-dof", "inversion", {"chi2_dof": 3.5}), "study", diagnosis_enabled=True)
>>> text.message
'χ²/dof = 3.50: the calibrated model does not reproduce the data within the stated noise.'
>>> text.remedy
'check the noise level; if it is right, a physical effect is missing from the model: the model diagnosis below names it.'
"""

import math
import re
from dataclasses import dataclass

from podkrig.limits import quote
from podkrig.reports.html import num

CONTEXTS = ("cli", "study")


@dataclass(frozen=True)
class FindingText:
    """A finding in plain words.

    Attributes
    ----------
    code : str
        The finding's stable code (:mod:`podkrig.online.findings`).
    section : str
        Report section it belongs to.
    message : str
        What was found, with the numbers and their units.
    remedy : str
        What to do about it.
    level : str
        ``"warning"``, or ``"error"`` for a refusal of the measurement check.
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


def identifiability_text(name, interval, unit, verdict):
    """The verdict on one parameter in words, e.g. ``"E_b is identified: [9876, 15934] MPa spans
    25 % of its search range"``.

    Parameters
    ----------
    name : str
    interval : (float, float)
        Its equivalence interval, physical units.
    unit : str
    verdict : dict
        ``{"share", "identifiable"}`` of :func:`podkrig.online.region.identifiability`.
    """
    lo, hi = interval
    share = verdict["share"]
    unit = unit if unit != "-" else ""
    msg = (
        f"{name} is identified: [{num(lo)}, {num(hi)}] {unit} spans {100 * share:.0f} % of its search range"
        if verdict["identifiable"] else
        f"{name} is NOT pinned down by these data: values from {num(lo)} to {num(hi)} {unit} "
        f"({100 * share:.0f} % of its search range) fit equally well; fix it from other tests, "
        "add sensors sensitive to it, or report it as unidentified"
    )
    return msg.replace("  ", " ")


# ------------------------------------------------------------------------------ one function per code
# each takes (values, context, diagnosis_enabled) and returns (message, remedy)


def fe_difference(by_unit, largest=None):
    """The FE check's largest |FE − surrogate| in words, per unit of the readings: ``"0.0031 mm"``,
    ``"0.0031 mm, 0.12 kN"`` for a test with gauges and a load cell (a kN and a mm difference are
    never one number). ``by_unit``: unit → difference
    (:attr:`~podkrig.online.invert.FECheck.max_abs_diff_by_unit`); a result written without it has
    only ``largest``, its unit unknown (shown bare)."""
    if not by_unit:
        return f"{largest:.3g}"
    return ", ".join(f"{v:.3g} {u}" for u, v in by_unit.items())


def _fe_check(v, context, diagnosis_enabled):
    if v.get("stopped"):
        return (f"the FE run at the optimum stopped early ({v['stopped']}): the surrogate's best fit cannot be "
                "checked at the levels it did not reach"
                + (f", and at those it reached they differ by up to {v['max_diff_over_noise']:.2f}× the noise."
                   if v["max_diff_over_noise"] == v["max_diff_over_noise"] else "."),
                "raise the scenario's solver budgets (max_total_iterations, max_cpu_seconds) so that the FE run at "
                "the optimum finishes, then build the snapshots and the surrogate again.")
    return (f"at the optimum the surrogate differs from the FE model by up to {v['max_diff_over_noise']:.2f}× the "
            f"noise ({fe_difference(v.get('max_abs_diff_by_unit'), v['max_abs_diff'])}): the identification is limited by the surrogate, not by the data.",
            "refine the surrogate near the optimum ('podkrig surrogate refine', or more snapshots in a narrower box) "
            "and invert again." if context == "cli" else
            "add training snapshots or narrow the bounds around the identified values, and run again.")


def _at_bound(v, context, diagnosis_enabled):
    name = v["parameter"]
    return (f"the best fit of {name} ({v['value']:.4g}{_unit(v['unit'])}) lies on a bound of its search range: "
            "the data may prefer a value outside it.",
            f"widen the range of {name} in the snapshot design (--param) and build the surrogate again."
            if context == "cli" else f"widen the bounds of {name} in [parameters] and run again.")


def _chi2_dof(v, context, diagnosis_enabled):
    if context == "cli":
        then = "(run 'podkrig diagnose')."
    elif diagnosis_enabled:
        then = "the model diagnosis below names it."
    else:
        then = "switch on the model diagnosis ([diagnosis] enabled = true) to name it."
    return (f"χ²/dof = {v['chi2_dof']:.2f}: the calibrated model does not reproduce the data within the stated "
            "noise.",
            "check the noise level; if it is right, a physical effect is missing from the model"
            + (" " if context == "cli" else ": ") + then)


#: the test that informs a parameter of the masonry (scenario names of ``podkrig scenarios``), for the
#: remedies of ``unidentified`` and ``insensitive``: what a study that cannot pin it down should add
INFORMING_TEST = {
    "ft_bj": "a tension test of the bed joint (couplet_tension: its peak is A f_t)",
    "GfI_bj": "a tension test of the bed joint with its softening branch (couplet_tension)",
    "c_bj": "shear tests at two or more pre-compressions (triplet_shear: the peaks give c and tanφ)",
    "tanphi_bj": "shear tests at two or more pre-compressions (triplet_shear: the peaks give c and tanφ)",
    "tanphir_bj": "a shear test followed to its residual plateau (triplet_shear to a slip of 1-2 mm)",
    "GfII_bj": "a shear test with its softening branch (triplet_shear)",
    "tanpsi_bj": "a shear test that measures the joint's opening (triplet_shear with the V_top gauge)",
    "fc": "a compression test of a prism (prism_compression: its peak is A f_c)",
    "E_b": "an elastic test with gauges on the units (diagonal_compression, flat_jack)",
    "kN_bj": "an elastic test with gauges across the bed joints (diagonal_compression, flat_jack)",
    "kV_bj": "an elastic test with gauges across the bed joints (diagonal_compression, flat_jack)",
    "r_hj": "an elastic test with gauges across the head joints (diagonal_compression)",
}


def _informing(name):
    """`` A test that informs NAME: ...`` when :data:`INFORMING_TEST` names one, else nothing."""
    test = INFORMING_TEST.get(name)
    return f" A test that informs {name}: {test}." if test else ""


def _unidentified(v, context, diagnosis_enabled):
    name = v["parameter"]
    how = f"--fix {name}=VALUE" if context == "cli" else "[fixed]"
    return (f"{name} is not pinned down by these data: values from {num(v['low'])} to {num(v['high'])}"
            f"{_unit(v['unit'])} ({100 * v['share']:.0f} % of its search range) fit equally well.",
            f"fix {name} from other tests ({how})"
            + ("" if context == "cli" else " or calibrate jointly with a test that informs it ([[test]] tables)")
            + ", add sensors sensitive to it, or report it as unidentified." + _informing(name))


def _insensitive(v, context, diagnosis_enabled):
    name = v["parameter"]
    return (f"no reading and not the misfit is sensitive to {name}: its total Sobol' index stays below "
            f"{v['threshold']:g} over the search box, so these data cannot inform it.",
            f"fix {name} from other tests or the literature ({'--fix' if context == 'cli' else '[fixed]'}) before "
            "the inversion, or add a test or sensors that respond to it." + _informing(name))


def _fe_failed(v, context, diagnosis_enabled):
    return (f"{v['failed']} of {v['total']} FE runs failed in stage '{v['stage']}' ({'; '.join(v['failures'])}).",
            "the surrogate was trained without them; read the errors (e.g. a parameter range that makes the "
            "model singular) and narrow the bounds, or inspect the store with 'podkrig snapshots info'.")


def _near_failure(v, context, diagnosis_enabled):
    towards = " and ".join(f"{d['towards']} {d['parameter']}" for d in v["driving"])
    where = f" (towards {towards})" if towards else ""
    return (f"the best fit lies where {100 * v['failed_share']:.0f} % of the training FE runs failed{where}: the "
            f"classifier of the failed runs predicts a {100 * v['probability']:.0f} % chance that an FE run fails "
            "there, so the surrogate had few or no complete runs near the optimum.",
            ("run the FE model at the optimum ('podkrig simulate' with the identified values); if it stops early, "
             "raise the scenario's budgets (max_total_iterations, max_cpu_seconds in its spec) and run the snapshots "
             "into a new store." if context == "cli" else
             "check the FE run at the optimum; if it stops early, raise the scenario's solver budgets "
             "(max_total_iterations, max_cpu_seconds) and run again."))


def _measurement_columns(v, context, diagnosis_enabled):
    parts = []
    if v.get("not_used"):
        parts.append(f"sensor(s) of the model without a column, not used: {', '.join(v['not_used'])}")
    if v.get("ignored"):
        parts.append(f"column(s) that name no sensor, ignored: {', '.join(v['ignored'])}")
    return ("; ".join(parts) + ".",
            "nothing if intended; otherwise name each column as the sensor it reads (see 'podkrig scenarios "
            "NAME' for the sensor names).")


def _noise_below_floor(v, context, diagnosis_enabled):
    listed = ", ".join(f"{k} {1000 * s:.3g} µm" for k, s in v["sigma_mm"].items())
    return (f"the noise model gives σ below {1000 * v['sigma_floor_mm']:g} µm for {listed}: no laboratory instrument "
            "reads that finely (an LVDT or dial gauge resolves about 1 µm, DIC 2.5–5 µm), so the region of "
            "equivalence is optimistic.",
            "give a resolution floor: --noise-abs 0.001 with --noise-rel, or --instrument lvdt" if context == "cli"
            else "give a resolution floor in [measurement]: noise_abs = 0.001 (mm) with noise_rel, or "
            "instrument = \"lvdt\".")


def _surrogate_error(v, context, diagnosis_enabled):
    if "median_rel_error" in v:
        what = (f"the surrogate's median error on the held-out FE runs ({100 * v['median_rel_error']:.2f} %) "
                f"exceeds the measurement noise ({100 * v['noise_rel']:g} %)")
    else:
        what = (f"the surrogate's RMS error on the held-out FE runs ({v['rms_abs_error_mm']:.3g} mm) exceeds the "
                f"measurement noise (σ = {v['sigma_mm']:g} mm)")
    return (what + ": the identification is limited by the surrogate.",
            "add training snapshots ([sampling] train.n, e.g. double it) or narrow the parameter bounds, and run "
            "again.")


def _surrogate_coverage(v, context, diagnosis_enabled):
    return (f"only {100 * v['coverage_2sigma']:.0f} % of the held-out FE readings lie within ±2σ of the "
            "surrogate: its error bars are too narrow, so the region of equivalence may be too small.",
            "add training snapshots, or set a small [surrogate] nugget (e.g. 1e-6).")


def _diagnosis_unexplained(v, context, diagnosis_enabled):
    return (f"the calibrated model does not explain the data (χ²/dof = {v['chi2_dof']:.2f}) and no candidate cause "
            "in the library explains the residual.",
            "check the noise level and the measurement file; read the residual pattern in the diagnosis report "
            "for an effect outside the library (nonlinearity, another test set-up).")


def _diagnosis_cause(v, context, diagnosis_enabled):
    causes = v["causes"]
    named = " and then ".join(c["cause"] + (f" at {c['location']}" if c["location"] else "") for c in causes)
    gain = (f" (χ²/dof {v['chi2_dof_before']:.2f} → {v['chi2_dof_after']:.2f} with "
            f"{'it' if len(causes) == 1 else 'them'})" if v.get("chi2_dof_before") is not None else "")
    effect = "a physical effect" if len(causes) == 1 else f"{len(causes)} physical effects"
    return (f"the calibrated model leaves out {effect}: the diagnosis names {named}{gain}.",
            "read the diagnosis report; add the effect to the model (or repair the named sensor or set-up) "
            "and calibrate again: the parameters identified without it are biased.")


# the measurement check's refusals (:mod:`podkrig.online.data_check`, level "error")


def _where(v):
    row = f", row {v['row']}" if v.get("row") is not None else ""
    return f"{v['source']}{row}, column {quote(v['column'])}"


def _load_scale(v, context, diagnosis_enabled):
    unit, likely = v["unit"], v.get("likely_unit")
    if v.get("quantity") == "control displacement":
        return _control_scale(v, context)
    guess = f": loads in {likely} under a {unit} header?" if likely else ": a unit error?"
    how = ("--load-column names the column" if context == "cli"
           else "[measurement] load_column names the column")
    base = re.split(r"[\[(]", v["column"])[0].strip() or "load"
    example = (f"here probably {quote(f'{base} [{likely}]')}" if likely
               else f"e.g. {quote(f'{base} [N]')} for loads in newtons")
    return (f"{_where(v)}: a load of {v['load_max']:g} {unit} is about {_power_of_ten(v['ratio'])}× the model's top "
            f"load level {v['level_max']:g} {unit}{guess}",
            f"state the load's unit in the header of the load column ({example}) or convert the column to {unit} "
            f"({how}).")


def _control_scale(v, context):
    """``load-scale`` of a displacement-controlled scenario: the control column's unit."""
    unit, likely = v["unit"], v.get("likely_unit")
    guess = f": displacements in {likely} under a {unit} header?" if likely else ": a unit error?"
    how = "--load-column names the column" if context == "cli" else "[measurement] load_column names the column"
    base = re.split(r"[\[(]", v["column"])[0].strip() or "load"
    example = f"here probably {quote(f'{base} [{likely}]')}" if likely else f"e.g. {quote(f'{base} [µm]')}"
    return (f"{_where(v)}: a control displacement of {v['load_max']:g} {unit} is about {_power_of_ten(v['ratio'])}× "
            f"the model's last control level {v['level_max']:g} {unit}{guess}",
            f"state the unit in the header of the control column ({example}) or convert the column to {unit} ({how}).")


def _load_sign(v, context, diagnosis_enabled):
    unit = v["unit"]
    side = "positive" if v["level_min"] >= 0 else "negative"
    rows = ("--load-range LOWER,UPPER" if context == "cli" else "[measurement] load_range = [lower, upper]")
    if v.get("quantity") == "control displacement":
        return (f"{_where(v)}: {v['n_loads']} control displacement(s) are "
                f"{'negative' if side == 'positive' else 'positive'} (as far as {v['load_min']:g} {unit}) while the "
                f"model's control levels are {side} ({v['level_min']:g} to {v['level_max']:g} {unit}): a sign "
                "convention?",
                f"the control is the displacement along the loading direction (a push, a pull, a shortening), "
                f"positive: negate the control column, or leave those rows out ({rows}).")
    return (f"{_where(v)}: {v['n_loads']} load(s) are {'negative' if side == 'positive' else 'positive'} (as far as "
            f"{v['load_min']:g} {unit}) while the model's load levels are {side} ({v['level_min']:g} to "
            f"{v['level_max']:g} {unit}): a sign convention?",
            f"the load is the magnitude of the applied load: negate the load column, or leave those rows out "
            f"({rows}).")


def _runs_text(v):
    n = v["n_runs"]
    if v["runs"] == "probe":
        return f"{n} probe FE run(s) (the box centre" + ("" if n == 1 else " and each parameter at its bounds") + ")"
    if v["runs"] == "surrogate":
        return f"surrogate's {n} training FE runs"
    return f"{n} training FE runs"


def _reading_problem(v):
    if v["code"] == "reading-sign":
        return (f"{v['sensor']} has the opposite sign of every FE run at every reading beyond 3σ: a sign error (a "
                "gauge mounted the other way round, or another sign convention)?")
    force = v.get("unit") == "kN"  # the load reading of a curve
    if v["direction"] == "larger":
        slip = ": N read as kN?" if force else ": µm read as mm?"
    else:
        slip = ": kN read as N (or MN)?" if force else ": mm read as µm (or m)?"
    guess = slip if v["unit_slip"] else ": a unit error?"
    return f"{v['sensor']} is about {_power_of_ten(v['ratio'])}× {v['direction']} than every FE run{guess}"


def _reading_remedy(context):
    off = ("--no-range-check inverts anyway" if context == "cli"
           else "[measurement] range_check = false runs anyway")
    return (f"state the unit in the column header (e.g. 'D1 [µm]'), check the sign convention, or widen the "
            f"parameter bounds; {off}.")


def _reading_scale(v, context, diagnosis_enabled):
    return (f"{v['source']}: {_reading_problem({**v, 'code': 'reading-scale'})}", _reading_remedy(context))


def _reading_sign(v, context, diagnosis_enabled):
    return (f"{v['source']}: {_reading_problem({**v, 'code': 'reading-sign'})}", _reading_remedy(context))


def _power_of_ten(r):
    if not r < float("inf"):
        return "infinitely"
    if r >= 3:
        return f"{10 ** round(math.log10(r)):g}"
    return f"{r:.2g}"


#: code → the function that words it
WORDS = {
    "fe-check": _fe_check,
    "at-bound": _at_bound,
    "chi2-dof": _chi2_dof,
    "unidentified": _unidentified,
    "insensitive": _insensitive,
    "fe-failed": _fe_failed,
    "near-failure": _near_failure,
    "measurement-columns": _measurement_columns,
    "noise-below-floor": _noise_below_floor,
    "surrogate-error": _surrogate_error,
    "surrogate-coverage": _surrogate_coverage,
    "diagnosis-unexplained": _diagnosis_unexplained,
    "diagnosis-cause": _diagnosis_cause,
    "load-scale": _load_scale,
    "load-sign": _load_sign,
    "reading-scale": _reading_scale,
    "reading-sign": _reading_sign,
}


def word(finding, context="cli", *, diagnosis_enabled=False):
    """A finding in plain words, with the remedy for ``context``.

    Parameters
    ----------
    finding : Finding
    context : {"cli", "study"}
        Where the remedies point: command-line options or study-file settings.
    diagnosis_enabled : bool
        (study) whether the study runs the model diagnosis, which names a missing effect.

    Returns
    -------
    FindingText
        A finding of one test of a joint calibration (``finding.test``) has its message prefixed
        with ``test NAME:``.

    Raises
    ------
    ValueError
        An unknown context or code.
    """
    if context not in CONTEXTS:
        raise ValueError(f"context must be one of {CONTEXTS}; got {context!r}")
    if finding.code not in WORDS:
        raise ValueError(f"no words for finding code {finding.code!r}; known codes: {', '.join(WORDS)}")
    message, remedy = WORDS[finding.code](finding.values, context, diagnosis_enabled)
    if finding.test is not None:
        message = f"test {finding.test}: {message}"
    return FindingText(finding.code, finding.section, message, remedy, finding.level)


def words(findings, context="cli", *, diagnosis_enabled=False):
    """:func:`word` for each finding, in order (a list of :class:`FindingText`)."""
    return [word(f, context, diagnosis_enabled=diagnosis_enabled) for f in findings]


def refusal(error, context="cli"):
    """The one-paragraph message of a measurement refused by the measurement check
    (:class:`~podkrig.online.data_check.MeasurementCheckError`): each problem, then what to do.

    Readings flagged against FE runs are grouped in one sentence: ``FILE: the readings do not look
    like any of the 7 probe FE run(s) (...) — D1 is about 1000× larger than every FE run: µm read as
    mm?; ... State the unit ...``.

    Parameters
    ----------
    error : MeasurementCheckError
    context : {"cli", "study"}
    """
    if context not in CONTEXTS:
        raise ValueError(f"context must be one of {CONTEXTS}; got {context!r}")
    findings = list(error.findings)
    readings = [f for f in findings if f.code in ("reading-scale", "reading-sign")]
    parts = []
    for f in findings:
        if f not in readings:
            message, remedy = WORDS[f.code](f.values, context, False)
            parts.append(f"{message}{'' if message[-1] in '.?!' else '.'} {remedy[0].upper()}{remedy[1:]}")
    if readings:
        v = readings[0].values
        listed = "; ".join(_reading_problem({**f.values, "code": f.code}) for f in readings)
        remedy = _reading_remedy(context)
        end = "" if listed[-1] in ".?!" else "."
        parts.append(f"{v['source']}: the readings do not look like any of the {_runs_text(v)} — {listed}{end} "
                     f"{remedy[0].upper()}{remedy[1:]}")
    return " ".join(parts)


__all__ = ["CONTEXTS", "INFORMING_TEST", "WORDS", "FindingText", "fe_difference", "identifiability_text", "refusal", "word", "words"]
