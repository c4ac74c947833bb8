"""The findings policy (``podkrig.online.findings``): every threshold at its edge, every sentence the
``podkrig invert`` command, the reports and a study's ``summary.json`` show, and every command-line
option and study-file setting a remedy tells the user to use.

The module is the one place where these words live, so the expected texts below are written out by
hand, with the numbers formatted as a user reads them (4 significant digits, whole percent, µm for
noise levels): a changed sentence, a lost unit, a wrong rounding or a remedy for the wrong context
fails here. Result objects are built directly (no inversion is run); everything but the test that
reads the command line's options runs in milliseconds.
"""

import dataclasses

import numpy as np
import pytest
import typer.main

from podkrig.cli import app
from podkrig.online.findings import (
    AT_BOUND_SHARE, CHI2_BASIS, COVERAGE_LIMIT, FE_CHECK_LIMIT, Finding, at_bound, chi2_basis, diagnosis_findings,
    fe_check_ok, held_out_findings, identifiability_verdict, inversion_findings, measurement_findings,
    offline_findings, sensitivity_findings,
)
from podkrig.online.invert import FECheck, InverseResult
from podkrig.online.measurement import INSTRUMENTS, SIGMA_FLOOR_MM, Measurement, NoiseModel
from podkrig.online.region import Region
from podkrig.study import settings

NOISE_TAIL = ": the calibrated model does not reproduce the data within the stated noise."
CHI2_REMEDY = "check the noise level; if it is right, a physical effect is missing from the model"
HELD_OUT_MORE = ("add training snapshots ([sampling] train.n, e.g. double it) or narrow the parameter bounds, "
                 "and run again.")


def _result(x, chi2=5.0, dof=10, free=("E_b", "nu"), units=("MPa", "-"), bound=(), fe_check=None):
    """An :class:`InverseResult` with the given best fit, χ² and dof (χ²/dof = chi2/dof)."""
    return InverseResult(np.asarray(x, dtype=float), dict(zip(free, x)), 0.5 * chi2, chi2, dof, 100, 1.0, free,
                         units, bound, {"file": "m.csv"}, fe_check=fe_check)


def _region(intervals, shares, names=("E_b", "nu"), units=("MPa", "-")):
    """A :class:`Region` whose identifiability verdicts are those of :func:`identifiability_verdict`."""
    verdicts = {n: identifiability_verdict(n, intervals[n], u, shares[n]) for n, u in zip(names, units)}
    return Region("likelihood-ratio", 0.95, np.zeros((1, len(names))), np.zeros(1), 3.0, intervals, names, units,
                  1024, 0.1, verdicts)


def _held(median, rms, coverage):
    return {"rel_error": {"median": median}, "rms_abs_error_mm": rms, "coverage_2sigma": coverage}


# --- verdicts and thresholds ---------------------------------------------------------------------


def test_identifiability_verdict_words_both_ends_alike_and_drops_a_dimensionless_unit():
    """Defects: an interval end printed with an exponent below 10⁶ (``1.593e+04`` next to ``9876``),
    an exponent dropped at or above 10⁶, "-" printed as a unit (or a double space left in its place),
    the share not in whole percent, the 50 % edge judged unidentified."""
    v = identifiability_verdict("E_b", (9876.4, 15934.4), "MPa", 0.25)
    assert v == {"share": 0.25, "identifiable": True,
                 "message": "E_b is identified: [9876, 15934] MPa spans 25 % of its search range"}
    assert isinstance(v["share"], float) and isinstance(v["identifiable"], bool)
    assert identifiability_verdict("k", (-15934.4, 999999.4), "N/mm³", 0.5)["message"] == (
        "k is identified: [-15934, 999999] N/mm³ spans 50 % of its search range")
    assert identifiability_verdict("k", (1e6, 2.5e6), "N/mm³", 0.125)["message"] == (
        "k is identified: [1e+06, 2.5e+06] N/mm³ spans 12 % of its search range")
    assert identifiability_verdict("nu", (0.1, 0.35), "-", 0.5)["message"] == (
        "nu is identified: [0.1, 0.35] spans 50 % of its search range")
    v = identifiability_verdict("nu", (0.1, 0.35), "-", 0.8)
    assert v["identifiable"] is False and v["message"] == (
        "nu is NOT pinned down by these data: values from 0.1 to 0.35 (80 % of its search range) fit "
        "equally well; fix it from other tests, add sensors sensitive to it, or report it as unidentified")
    assert identifiability_verdict("E_b", (5000.0, 19000.0), "MPa", 0.93)["message"].startswith(
        "E_b is NOT pinned down by these data: values from 5000 to 19000 MPa (93 % of its search range) fit")


def test_at_bound_and_fe_check_thresholds_at_their_edges():
    """Defects: a best fit exactly 0.5 % of the range from a bound reported on it (the share is a
    strict limit), one at 0.49 % or 99.51 % missed, the upper bound tested against 1 + share, or an
    FE check with the surrogate off by exactly one noise σ failed. Exact binary fractions and
    limits: no tolerance."""
    assert AT_BOUND_SHARE == 0.005
    names = ["a", "b", "c", "d", "e", "f", "g"]
    u = [AT_BOUND_SHARE, 0.0049, 1 - AT_BOUND_SHARE, 0.9951, 0.0, 1.0, 0.5]
    assert at_bound(names, u) == ["b", "d", "e", "f"]
    assert at_bound([], []) == []
    assert fe_check_ok(FE_CHECK_LIMIT) is True and fe_check_ok(0.0) is True
    assert fe_check_ok(1.5) is False and fe_check_ok(np.float64(2.0)) is False


# --- inversion findings ----------------------------------------------------------------------------


def test_fe_check_finding_words_and_remedy_per_context():
    """Defects: a failed FE check not reported, a passed one reported, the factor or the mm
    difference mis-formatted, the CLI remedy not naming 'podkrig surrogate refine', or a study user
    told to run a command instead of changing the study."""
    off = FECheck(0.025, 2.5, 0.1, 3.0, False)
    cli = inversion_findings(_result([1200.0, 0.2], fe_check=off), context="cli")
    assert cli == [Finding(
        "fe-check", "inversion",
        "at the optimum the surrogate differs from the FE model by up to 2.50× the noise (0.025 mm): the "
        "identification is limited by the surrogate, not by the data.",
        "refine the surrogate near the optimum ('podkrig surrogate refine', or more snapshots in a narrower box) "
        "and invert again.")]
    (study,) = inversion_findings(_result([1200.0, 0.2], fe_check=off), context="study")
    assert study.message == cli[0].message
    assert study.remedy == "add training snapshots or narrow the bounds around the identified values, and run again."
    assert inversion_findings(_result([1200.0, 0.2], fe_check=FECheck(0.005, 0.5, 0.01, 1.0, True))) == []
    assert inversion_findings(_result([1200.0, 0.2])) == []


def test_at_bound_finding_per_parameter_with_its_unit_and_not_per_test():
    """Defects: a parameter on a bound not reported (or one not on it reported), its unit lost or
    a dimensionless "-" printed, the remedy naming the wrong option or table, or a per-test view of
    a joint calibration judging bounds (they belong to the joint result)."""
    result = _result([1200.0, 0.1], bound=("E_b", "nu"))
    cli = inversion_findings(result, context="cli")
    assert cli == [
        Finding("at-bound", "inversion",
                "the best fit of E_b (1200 MPa) lies on a bound of its search range: the data may prefer a value "
                "outside it.",
                "widen the range of E_b in the snapshot design (--param) and build the surrogate again."),
        Finding("at-bound", "inversion",
                "the best fit of nu (0.1) lies on a bound of its search range: the data may prefer a value "
                "outside it.",
                "widen the range of nu in the snapshot design (--param) and build the surrogate again."),
    ]
    study = inversion_findings(_result([1200.0, 0.1], bound=("nu",)), context="study")
    assert [f.remedy for f in study] == ["widen the bounds of nu in [parameters] and run again."]
    assert inversion_findings(_result([1200.0, 0.1], units=("MPa", ""), bound=("nu",)))[0].message.startswith(
        "the best fit of nu (0.1) lies")
    assert inversion_findings(result, per_test=True) == []


@pytest.mark.parametrize("context, enabled, then", [
    ("cli", False, " (run 'podkrig diagnose')."),
    ("cli", True, " (run 'podkrig diagnose')."),
    ("study", True, ": the model diagnosis below names it."),
    ("study", False, ": switch on the model diagnosis ([diagnosis] enabled = true) to name it."),
])
def test_chi2_finding_strictly_above_the_limit_and_its_next_step(context, enabled, then):
    """Defects: χ²/dof = 2 exactly reported (the limit is strict), 2.02 not reported, the value not
    printed to 2 decimals, the next step wrong for the context (a command for the CLI; in a study,
    the diagnosis report when it runs, the setting that switches it on when it does not). Also
    judged for a per-test view of a joint calibration."""
    assert inversion_findings(_result([1200.0, 0.2], chi2=20.0, dof=10), context=context,
                              diagnosis_enabled=enabled) == []
    for per_test in (False, True):
        found = inversion_findings(_result([1200.0, 0.2], chi2=20.2, dof=10), context=context,
                                   diagnosis_enabled=enabled, per_test=per_test)
        assert found == [Finding("chi2-dof", "inversion", "χ²/dof = 2.02" + NOISE_TAIL, CHI2_REMEDY + then)]


def test_unidentified_findings_follow_the_region_in_order_with_units_and_context_remedies():
    """Defects: an identified parameter reported, an unidentified one missed or out of the
    region's order, its interval or share mis-formatted or without its unit, the CLI remedy not
    naming ``--fix NAME=VALUE``, the study remedy not offering [fixed] and a joint calibration."""
    region = _region({"E_b": (5000.0, 19000.0), "nu": (0.1, 0.35)}, {"E_b": 0.93, "nu": 0.75})
    result = _result([12000.0, 0.2])
    cli = inversion_findings(result, region, context="cli")
    assert [(f.code, f.section) for f in cli] == [("unidentified", "region")] * 2
    assert [f.message for f in cli] == [
        "E_b is not pinned down by these data: values from 5000 to 19000 MPa (93 % of its search range) fit "
        "equally well.",
        "nu is not pinned down by these data: values from 0.1 to 0.35 (75 % of its search range) fit equally well.",
    ]
    assert cli[1].remedy == ("fix nu from other tests (--fix nu=VALUE), add sensors sensitive to it, or report it "
                             "as unidentified.")
    study = inversion_findings(result, region, context="study")
    assert [f.message for f in study] == [f.message for f in cli]
    assert study[0].remedy == (
        "fix E_b from other tests ([fixed]) or calibrate jointly with a test that informs it ([[test]] tables), "
        "add sensors sensitive to it, or report it as unidentified.")
    one = _region({"E_b": (9000.0, 9500.0), "nu": (0.1, 0.35)}, {"E_b": 0.04, "nu": 0.75})
    assert [f.message[:2] for f in inversion_findings(result, one)] == ["nu"]


def test_a_per_test_view_judges_only_its_fe_check_and_chi2():
    """Defect (found here and fixed): a per-test view of a joint calibration given the region
    reported the region's unidentified parameters, although the docstring says only its FE check
    and χ²/dof are judged (bounds and the region belong to the joint result)."""
    result = _result([1200.0, 0.2], chi2=50.0, dof=10, bound=("E_b",), fe_check=FECheck(0.1, 10.0, 0.1, 9.0, False))
    region = _region({"E_b": (1000.0, 1900.0), "nu": (0.1, 0.35)}, {"E_b": 0.05, "nu": 0.75})
    assert [f.code for f in inversion_findings(result, region, per_test=True)] == ["fe-check", "chi2-dof"]


def test_inversion_findings_come_in_report_order():
    """Defect: findings reordered (the report and ``summary.json`` list them as the checks run: FE
    check, bounds, χ²/dof, region)."""
    result = _result([1200.0, 0.2], chi2=50.0, dof=10, bound=("E_b",), fe_check=FECheck(0.1, 10.0, 0.1, 9.0, False))
    region = _region({"E_b": (1000.0, 1900.0), "nu": (0.1, 0.35)}, {"E_b": 0.05, "nu": 0.75})
    assert [f.code for f in inversion_findings(result, region)] == ["fe-check", "at-bound", "chi2-dof", "unidentified"]


def test_an_unknown_context_is_refused_with_the_allowed_ones():
    """Defect: a misspelt context silently giving the study's (or the CLI's) remedies."""
    message = "context must be one of \\('cli', 'study'\\); got 'report'"
    with pytest.raises(ValueError, match=message):
        inversion_findings(_result([1200.0, 0.2]), context="report")
    with pytest.raises(ValueError, match=message):
        sensitivity_findings({"propose_fixing": [], "threshold": 0.01}, context="report")
    with pytest.raises(ValueError, match=message):
        measurement_findings({}, context="report")


# --- the other stages ------------------------------------------------------------------------------


def test_sensitivity_findings_one_per_parameter_proposed_for_fixing():
    """Defects: a parameter proposed for fixing not reported, the threshold not printed as given,
    the remedy naming the wrong option or table for the context."""
    result = {"propose_fixing": ["nu_b", "r_hj"], "threshold": 0.01}
    cli = sensitivity_findings(result, context="cli")
    assert [(f.code, f.section) for f in cli] == [("insensitive", "sensitivity")] * 2
    assert cli[1].message == ("no reading and not the misfit is sensitive to r_hj: its total Sobol' index stays "
                              "below 0.01 over the search box, so these data cannot inform it.")
    assert cli[0].remedy == ("fix nu_b from other tests or the literature (--fix) before the inversion, or add a "
                             "test or sensors that respond to it.")
    assert sensitivity_findings(result, context="study")[0].remedy == (
        "fix nu_b from other tests or the literature ([fixed]) before the inversion, or add a test or sensors that "
        "respond to it.")
    assert sensitivity_findings({"propose_fixing": [], "threshold": 0.01}) == []


def test_offline_finding_remedy_and_a_stage_without_failures():
    """Defects: a stage JSON without a ``failed`` count (no FE failed) taken as failing, or the
    remedy not naming 'podkrig snapshots info'."""
    assert offline_findings("held_out", {"total": 8}) == []
    (f,) = offline_findings("held_out", {"failed": 1, "total": 8, "failures": ["run 2: singular"]})
    assert f.message == "1 of 8 FE runs failed in stage 'held_out' (run 2: singular)."
    assert f.remedy == ("the surrogate was trained without them; read the errors (e.g. a parameter range that makes "
                        "the model singular) and narrow the bounds, or inspect the store with 'podkrig snapshots "
                        "info'.")


def test_measurement_findings_from_a_measurement_check_summary():
    """End to end from :meth:`Measurement.check_summary`: a model sensor without a column, a column
    naming no sensor, and a 1 %-relative noise model giving σ below the 0.5 µm floor. Defects: a
    column finding missing one of its two parts or a sensor of a list, σ not converted to µm (3
    significant digits: 0.1234 µm reads 0.123, the 0.1 % of a wrong factor 1001 shows) or
    the floor not printed, the remedy not naming a resolution floor in the context's words."""
    measurement = Measurement(np.array([[0.02, 0.01234], [0.04, 0.03]]), ("D1", "D2"), np.array([10.0, 20.0]),
                              source="m.csv", ignored_columns=("T1",))
    checked = measurement.check_summary(("D1", "D2", "D3", "D4"), NoiseModel(delta=0.01))
    cli = measurement_findings(checked, context="cli")
    assert cli == [
        Finding("measurement-columns", "study",
                "sensor(s) of the model without a column, not used: D3, D4; column(s) that name no sensor, ignored: "
                "T1.",
                "nothing if intended; otherwise name each column as the sensor it reads (see 'podkrig scenarios "
                "NAME' for the sensor names)."),
        Finding("noise-below-floor", "study",
                "the noise model gives σ below 0.5 µm for D1 0.2 µm, D2 0.123 µm: no laboratory instrument reads "
                "that finely (an LVDT or dial gauge resolves about 1 µm, DIC 2.5–5 µm), so the region of "
                "equivalence is optimistic.",
                "give a resolution floor: --noise-abs 0.001 with --noise-rel, or --instrument lvdt"),
    ]
    study = measurement_findings(checked, context="study")
    assert [f.message for f in study] == [f.message for f in cli]
    assert study[1].remedy == ("give a resolution floor in [measurement]: noise_abs = 0.001 (mm) with noise_rel, "
                               "or instrument = \"lvdt\".")
    assert measurement_findings({"not_used": ["D3"], "ignored": []})[0].message == (
        "sensor(s) of the model without a column, not used: D3.")
    assert measurement_findings({"ignored": ["T1", "T2"]})[0].message == (
        "column(s) that name no sensor, ignored: T1, T2.")
    clean = Measurement(measurement.values, ("D1", "D2"), measurement.load_levels, source="m.csv")
    assert measurement_findings(clean.check_summary(("D1", "D2"), NoiseModel(sigma=0.001))) == []
    assert measurement_findings({"not_used": [], "ignored": [], "sigma_below_floor": {}}) == []


def test_held_out_findings_relative_then_absolute_noise_and_coverage_edge():
    """Defects: the RMS error not compared with σ when a relative noise is given but not exceeded,
    the surrogate error reported twice (relative and absolute), coverage at the limit reported or
    just below it missed, the remedies not naming the settings that help."""
    (f,) = held_out_findings(_held(0.005, 0.003, 0.95), noise_rel=0.01, noise_abs=0.002)
    assert f == Finding("surrogate-error", "held-out",
                        "the surrogate's RMS error on the held-out FE runs (0.003 mm) exceeds the measurement "
                        "noise (σ = 0.002 mm): the identification is limited by the surrogate.", HELD_OUT_MORE)
    (f,) = held_out_findings(_held(0.02, 0.003, 0.95), noise_rel=0.01, noise_abs=0.002)
    assert f.message.startswith("the surrogate's median error on the held-out FE runs (2.00 %) exceeds")
    assert f.remedy == HELD_OUT_MORE
    assert held_out_findings(_held(0.5, 0.002, COVERAGE_LIMIT), noise_abs=0.002) == []
    (f,) = held_out_findings(_held(0.0, 0.0, 0.79))
    assert f == Finding("surrogate-coverage", "held-out",
                        "only 79 % of the held-out FE readings lie within ±2σ of the surrogate: its error bars are "
                        "too narrow, so the region of equivalence may be too small.",
                        "add training snapshots, or set a small [surrogate] nugget (e.g. 1e-6).")


def test_diagnosis_findings_name_every_cause_in_order():
    """Defects: several causes not joined in the order found, their count or pronoun wrong, a cause
    without a location given one, the remedies changed."""
    (f,) = diagnosis_findings({
        "verdict": "inadequate", "cause": "bond slip", "detail": None,
        "causes": [{"cause": "bond slip", "location": None}, {"cause": "a faulty sensor", "location": "D2"}],
        "gain": {"chi2_dof_before": 12.0, "chi2_dof_after": 1.25}})
    assert f == Finding(
        "diagnosis-cause", "diagnosis",
        "the calibrated model leaves out 2 physical effects: the diagnosis names bond slip and then a faulty sensor "
        "at D2 (χ²/dof 12.00 → 1.25 with them).",
        "read the diagnosis report; add the effect to the model (or repair the named sensor or set-up) and calibrate "
        "again: the parameters identified without it are biased.")
    (f,) = diagnosis_findings({"verdict": "inadequate", "cause": "a rotated support", "causes": [],
                               "detail": {"location": None}, "gain": None})
    assert f.message == "the calibrated model leaves out a physical effect: the diagnosis names a rotated support."
    (f,) = diagnosis_findings({"verdict": "inadequate", "cause": None, "base": {"chi2_dof": 3.0}})
    assert (f.code, f.section) == ("diagnosis-unexplained", "diagnosis")
    assert f.message == ("the calibrated model does not explain the data (χ²/dof = 3.00) and no candidate cause in "
                         "the library explains the residual.")
    assert f.remedy == ("check the noise level and the measurement file; read the residual pattern in the diagnosis "
                        "report for an effect outside the library (nonlinearity, another test set-up).")


# --- the χ² basis and the summary form ---------------------------------------------------------------


def test_chi2_basis_appends_how_the_error_terms_were_obtained():
    """Defects: the model-error description dropped from the diagnosis's basis (or added to
    another kind's), the FE model-form error not appended, an unknown kind not refused."""
    assert chi2_basis("diagnosis") == CHI2_BASIS["diagnosis"]
    assert chi2_basis("diagnosis", "e² from two meshes") == CHI2_BASIS["diagnosis"] + " = e² from two meshes"
    assert chi2_basis("surrogate", "e² from two meshes") == CHI2_BASIS["surrogate"]
    assert chi2_basis("surrogate-noise", form_error="ε = 5 % of |g|") == (
        "surrogate at its best fit; C_D = data noise C_d only + FE model-form error ε = 5 % of |g|")
    assert chi2_basis("diagnosis", "e²", "ε") == CHI2_BASIS["diagnosis"] + " = e² + FE model-form error ε"
    with pytest.raises(KeyError):
        chi2_basis("posterior")


def test_a_finding_is_a_warning_unless_told_otherwise_and_keeps_its_level():
    """Defects: the default level changed ("warning" is what summary.json readers filter on), or a
    finding of another level read back from summary.json (:meth:`Finding.from_dict`) as a warning."""
    f = Finding("chi2-dof", "inversion", "χ²/dof = 5", "check the noise")
    assert f.level == "warning" and f.to_dict()["level"] == "warning"
    error = Finding("fe-failed", "offline", "2 of 10 FE runs failed", "narrow the bounds", level="error")
    assert Finding.from_dict(error.to_dict()) == error


# --- remedies name options and settings that exist -----------------------------------------------


def _options(command):
    return {o for p in command.params for o in p.opts}


def test_remedies_name_options_commands_and_settings_that_exist():
    """Defect: a remedy pointing at a command-line option, a command or a study-file setting that
    does not exist (renamed or removed), or a suggested resolution floor that is itself below the
    floor. Checked against the typer app and the study-file declarations."""
    cli = typer.main.get_command(app)
    assert {"--fix", "--noise-abs", "--noise-rel", "--instrument"} <= _options(cli.commands["invert"])
    assert "--param" in _options(cli.commands["snapshots"].commands["run"])
    assert "refine" in cli.commands["surrogate"].commands and "info" in cli.commands["snapshots"].commands
    assert {"diagnose", "scenarios"} <= set(cli.commands)
    assert "lvdt" in INSTRUMENTS and INSTRUMENTS["lvdt"]["sigma_res_mm"] == 0.001 >= SIGMA_FLOOR_MM

    def fields(cls):
        return {f.name: f for f in dataclasses.fields(cls)}

    study = fields(settings.StudyFile)
    assert {"parameters", "fixed", "test", "sampling", "surrogate", "measurement", "diagnosis"} <= set(study)
    assert "enabled" in fields(settings.DiagnosisSettings) and "nugget" in fields(settings.SurrogateSettings)
    assert "n" in fields(settings.TrainingDesign) and "train" in fields(settings.SamplingSettings)
    assert {"noise_abs", "noise_rel", "instrument"} <= set(fields(settings.MeasurementSettings))
