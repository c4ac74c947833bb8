"""The findings policy and its words.

The policy (``podkrig.online.findings``) judges results: every threshold at its edge, each finding
a code with its values (numbers and names), in report order. The words (``podkrig.reports.findings``)
are checked by the fragments a user needs — the numbers as a user reads them (4 significant digits,
whole percent, µm for noise levels), the units, and every command-line option and study-file
setting a remedy tells the user to use, in the right context. Result objects are built directly
(no inversion is run); everything but the test that reads the command line's options runs in
milliseconds.
"""

import dataclasses

import numpy as np
import pytest
import typer.main

from podkrig.cli import app
from podkrig.online.findings import (
    AT_BOUND_SHARE, CHI2_BASIS, COVERAGE_LIMIT, FE_CHECK_LIMIT, UNIDENTIFIABLE_SHARE, Finding, at_bound, chi2_basis,
    diagnosis_findings, fe_check_ok, held_out_findings, inversion_findings, is_identifiable, measurement_findings,
    offline_findings, sensitivity_findings,
)
from podkrig.online.invert import FECheck, InverseResult
from podkrig.online.measurement import INSTRUMENTS, SIGMA_FLOOR_MM, Measurement, NoiseModel
from podkrig.online.region import Region
from podkrig.reports.findings import WORDS, FindingText, identifiability_text, word, words
from podkrig.study import settings


def _result(x, chi2=5.0, dof=10, free=("E_b", "nu"), units=("MPa", "-"), bound=(), fe_check=None):
    """An :class:`InverseResult` with the given best fit, χ² and dof (χ²/dof = chi2/dof)."""
    return InverseResult(np.asarray(x, dtype=float), dict(zip(free, x)), 0.5 * chi2, chi2, dof, 100, 1.0, free,
                         units, bound, {"file": "m.csv"}, fe_check=fe_check)


def _region(intervals, shares, names=("E_b", "nu"), units=("MPa", "-")):
    """A :class:`Region` with the given intervals and the verdicts of their shares."""
    verdicts = {n: {"share": shares[n], "identifiable": is_identifiable(shares[n])} for n in names}
    return Region("likelihood-ratio", 0.95, np.zeros((1, len(names))), np.zeros(1), 3.0, intervals, names, units,
                  1024, 0.1, verdicts)


def _held(median, rms, coverage):
    return {"rel_error": {"median": median}, "rms_abs_error_mm": rms, "coverage_2sigma": coverage}


# --- verdicts and thresholds ---------------------------------------------------------------------


def test_thresholds_at_their_edges():
    """Defects: the 50 % share judged unidentified, a best fit exactly 0.5 % of the range from a
    bound reported on it (the share is a strict limit), one at 0.49 % or 99.51 % missed, the upper
    bound tested against 1 + share, or an FE check with the surrogate off by exactly one noise σ
    failed. Exact binary fractions and limits: no tolerance."""
    assert is_identifiable(UNIDENTIFIABLE_SHARE) is True and is_identifiable(0.5000001) is False
    assert AT_BOUND_SHARE == 0.005
    names = ["a", "b", "c", "d", "e", "f", "g"]
    u = [AT_BOUND_SHARE, 0.0049, 1 - AT_BOUND_SHARE, 0.9951, 0.0, 1.0, 0.5]
    assert at_bound(names, u) == ["b", "d", "e", "f"]
    assert at_bound([], []) == []
    assert fe_check_ok(FE_CHECK_LIMIT) is True and fe_check_ok(0.0) is True
    assert fe_check_ok(1.5) is False and fe_check_ok(np.float64(2.0)) is False


def test_identifiability_words_both_ends_alike_and_drop_a_dimensionless_unit():
    """Defects: an interval end printed with an exponent below 10⁶ (``1.593e+04`` next to ``9876``),
    an exponent dropped at or above 10⁶, "-" printed as a unit (or a double space left in its place),
    the share not in whole percent, the verdict's words not following ``identifiable``."""
    ok = {"share": 0.25, "identifiable": True}
    assert identifiability_text("E_b", (9876.4, 15934.4), "MPa", ok) == (
        "E_b is identified: [9876, 15934] MPa spans 25 % of its search range")  # the one whole sentence
    assert "[-15934, 999999] N/mm³" in identifiability_text("k", (-15934.4, 999999.4), "N/mm³", ok)
    assert "[1e+06, 2.5e+06] N/mm³ spans 12 %" in identifiability_text("k", (1e6, 2.5e6), "N/mm³",
                                                                        {"share": 0.125, "identifiable": True})
    assert "[0.1, 0.35] spans" in identifiability_text("nu", (0.1, 0.35), "-", ok)
    text = identifiability_text("nu", (0.1, 0.35), "-", {"share": 0.8, "identifiable": False})
    assert "NOT pinned down" in text and "from 0.1 to 0.35 (80 %" in text and "  " not in text


# --- inversion findings ----------------------------------------------------------------------------


def test_fe_check_finding_words_each_unit_apart():
    """Defects: the largest difference of a test with a load cell and gauges printed as mm although
    it is the force's (kN), or one unit's largest difference dropped; a result read back without
    the units given a unit it may not have."""
    mixed = FECheck(0.12, 3.0, 0.05, 4.0, False, max_abs_diff_by_unit={"mm": 0.0031, "kN": 0.12})
    (f,) = inversion_findings(_result([1200.0, 0.2], fe_check=mixed))
    message = word(f, "study").message
    assert "(0.0031 mm, 0.12 kN)" in message and "0.12 mm" not in message
    (old,) = inversion_findings(_result([1200.0, 0.2], fe_check=FECheck(0.12, 3.0, 0.05, 4.0, False)))
    assert "noise (0.12)" in word(old, "cli").message


def test_fe_check_finding_values_and_remedy_per_context():
    """Defects: a failed FE check not reported, a passed one reported, its numbers lost, the factor
    or the mm difference mis-formatted, the CLI remedy not naming 'podkrig surrogate refine', or a
    study user told to run a command instead of changing the study."""
    off = FECheck(0.025, 2.5, 0.1, 3.0, False, max_abs_diff_by_unit={"mm": 0.025})
    (f,) = inversion_findings(_result([1200.0, 0.2], fe_check=off))
    assert f == Finding("fe-check", "inversion", {"max_diff_over_noise": 2.5, "max_abs_diff": 0.025,
                                                  "max_abs_diff_by_unit": {"mm": 0.025}})
    cli, study = word(f, "cli"), word(f, "study")
    assert "2.50× the noise (0.025 mm)" in cli.message and cli.message == study.message
    assert "podkrig surrogate refine" in cli.remedy
    assert "podkrig" not in study.remedy and "narrow the bounds" in study.remedy
    assert inversion_findings(_result([1200.0, 0.2], fe_check=FECheck(0.005, 0.5, 0.01, 1.0, True))) == []
    assert inversion_findings(_result([1200.0, 0.2])) == []


def test_at_bound_finding_per_parameter_with_its_unit_and_not_per_test():
    """Defects: a parameter on a bound not reported (or one not on it reported), its value or unit
    lost, a dimensionless "-" printed, the remedy naming the wrong option or table, or a per-test
    view of a joint calibration judging bounds (they belong to the joint result)."""
    result = _result([1200.0, 0.1], bound=("E_b", "nu"))
    found = inversion_findings(result)
    assert found == [Finding("at-bound", "inversion", {"parameter": "E_b", "value": 1200.0, "unit": "MPa"}),
                     Finding("at-bound", "inversion", {"parameter": "nu", "value": 0.1, "unit": "-"})]
    cli = words(found, "cli")
    assert "E_b (1200 MPa)" in cli[0].message and "nu (0.1)" in cli[1].message and "bound" in cli[1].message
    assert "--param" in cli[1].remedy and "widen the range of nu" in cli[1].remedy
    assert "[parameters]" in word(found[1], "study").remedy
    assert inversion_findings(result, per_test=True) == []


@pytest.mark.parametrize("context, enabled, then", [
    ("cli", False, "podkrig diagnose"),
    ("cli", True, "podkrig diagnose"),
    ("study", True, "the model diagnosis below names it"),
    ("study", False, "[diagnosis] enabled = true"),
])
def test_chi2_finding_strictly_above_the_limit_and_its_next_step(context, enabled, then):
    """Defects: χ²/dof = 2 exactly reported (the limit is strict), 2.02 not reported, the value not
    printed to 2 decimals, the next step wrong for the context (a command for the CLI; in a study,
    the diagnosis report when it runs, the setting that switches it on when it does not). Also
    judged for a per-test view of a joint calibration."""
    assert inversion_findings(_result([1200.0, 0.2], chi2=20.0, dof=10)) == []
    for per_test in (False, True):
        found = inversion_findings(_result([1200.0, 0.2], chi2=20.2, dof=10), per_test=per_test)
        assert [(f.code, f.section) for f in found] == [("chi2-dof", "inversion")]
        assert found[0].values["chi2_dof"] == pytest.approx(2.02, rel=1e-12)  # 20.2 / 10 in floating point
        text = word(found[0], context, diagnosis_enabled=enabled)
        assert "χ²/dof = 2.02" in text.message and "check the noise level" in text.remedy and then in text.remedy


def test_unidentified_findings_follow_the_region_in_order_with_units_and_context_remedies():
    """Defects: an identified parameter reported, an unidentified one missed or out of the
    region's order, its interval or share lost or mis-formatted or without its unit, the CLI remedy
    not naming ``--fix NAME=VALUE``, the study remedy not offering [fixed] and a joint calibration."""
    region = _region({"E_b": (5000.0, 19000.0), "nu": (0.1, 0.35)}, {"E_b": 0.93, "nu": 0.75})
    result = _result([12000.0, 0.2])
    found = inversion_findings(result, region)
    assert found == [
        Finding("unidentified", "region", {"parameter": "E_b", "low": 5000.0, "high": 19000.0, "unit": "MPa",
                                           "share": 0.93}),
        Finding("unidentified", "region", {"parameter": "nu", "low": 0.1, "high": 0.35, "unit": "-", "share": 0.75}),
    ]
    cli = words(found, "cli")
    assert "5000 to 19000 MPa (93 %" in cli[0].message
    assert "from 0.1 to 0.35 (75 %" in cli[1].message
    assert "--fix nu=VALUE" in cli[1].remedy
    study = words(found, "study")
    assert [t.message for t in study] == [t.message for t in cli]
    assert "[fixed]" in study[0].remedy and "[[test]]" in study[0].remedy
    one = _region({"E_b": (9000.0, 9500.0), "nu": (0.1, 0.35)}, {"E_b": 0.04, "nu": 0.75})
    assert [f.values["parameter"] for f in inversion_findings(result, one)] == ["nu"]


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


def test_an_unknown_context_or_code_is_refused_with_the_allowed_ones():
    """Defects: a misspelt context silently giving the study's (or the CLI's) remedies; a code
    without words passing unnoticed."""
    f = Finding("chi2-dof", "inversion", {"chi2_dof": 3.0})
    with pytest.raises(ValueError, match=r"context must be one of.*'cli', 'study'.*got 'report'"):
        word(f, "report")
    with pytest.raises(ValueError, match=r"'no-such-code'.*chi2-dof"):
        word(Finding("no-such-code", "inversion"), "cli")


# --- the other stages ------------------------------------------------------------------------------


def test_sensitivity_findings_one_per_parameter_proposed_for_fixing():
    """Defects: a parameter proposed for fixing not reported, the threshold lost or not printed as
    given, the remedy naming the wrong option or table for the context."""
    found = sensitivity_findings({"propose_fixing": ["nu_b", "r_hj"], "threshold": 0.01})
    assert found == [Finding("insensitive", "sensitivity", {"parameter": n, "threshold": 0.01})
                     for n in ("nu_b", "r_hj")]
    cli = words(found, "cli")
    assert "sensitive to r_hj" in cli[1].message and "below 0.01 over the search box" in cli[1].message
    assert "fix nu_b" in cli[0].remedy and "(--fix)" in cli[0].remedy
    assert "([fixed])" in word(found[0], "study").remedy
    assert sensitivity_findings({"propose_fixing": [], "threshold": 0.01}) == []


def test_offline_finding_values_remedy_and_a_stage_without_failures():
    """Defects: a stage JSON without a ``failed`` count (no FE failed) taken as failing, a failure
    text lost, or the remedy not naming 'podkrig snapshots info'."""
    assert offline_findings("held_out", {"total": 8}) == []
    (f,) = offline_findings("held_out", {"failed": 1, "total": 8, "failures": ["run 2: singular"]})
    assert f == Finding("fe-failed", "offline", {"stage": "held_out", "failed": 1, "total": 8,
                                                 "failures": ["run 2: singular"]})
    text = word(f, "study")
    assert "1 of 8 FE runs failed" in text.message and "'held_out' (run 2: singular)" in text.message
    assert "podkrig snapshots info" in text.remedy


def test_measurement_findings_from_a_measurement_check_summary():
    """End to end from :meth:`Measurement.check_summary`: a model sensor without a column, a column
    naming no sensor, and a 1 %-relative noise model giving σ below the 0.5 µm floor. Defects: a
    column finding missing one of its two parts or a sensor of a list, σ not converted to µm (3
    significant digits: 0.1234 µm reads 0.123, the 0.1 % of a wrong factor 1001 shows) or
    the floor not printed, the remedy not naming a resolution floor in the context's words."""
    measurement = Measurement(np.array([[0.02, 0.01234], [0.04, 0.03]]), ("D1", "D2"), np.array([10.0, 20.0]),
                              source="m.csv", ignored_columns=("T1",))
    checked = measurement.check_summary(("D1", "D2", "D3", "D4"), NoiseModel(delta=0.01))
    columns, noise = measurement_findings(checked)
    assert columns == Finding("measurement-columns", "study", {"not_used": ["D3", "D4"], "ignored": ["T1"]})
    assert (noise.code, noise.section, list(noise.values["sigma_mm"])) == ("noise-below-floor", "study", ["D1", "D2"])
    assert noise.values["sigma_floor_mm"] == SIGMA_FLOOR_MM
    cli = words([columns, noise], "cli")
    assert "not used: D3, D4" in cli[0].message and "ignored: T1" in cli[0].message
    assert "podkrig scenarios" in cli[0].remedy
    assert "σ below 0.5 µm" in cli[1].message and "D1 0.2 µm, D2 0.123 µm" in cli[1].message
    assert "--noise-abs 0.001" in cli[1].remedy and "--instrument lvdt" in cli[1].remedy
    study = word(noise, "study")
    assert study.message == cli[1].message and "noise_abs = 0.001" in study.remedy and '"lvdt"' in study.remedy
    assert word(measurement_findings({"not_used": ["D3"], "ignored": []})[0]).message.endswith("not used: D3.")
    assert word(measurement_findings({"ignored": ["T1", "T2"]})[0]).message.endswith("ignored: T1, T2.")
    clean = Measurement(measurement.values, ("D1", "D2"), measurement.load_levels, source="m.csv")
    assert measurement_findings(clean.check_summary(("D1", "D2"), NoiseModel(sigma=0.001))) == []
    assert measurement_findings({"not_used": [], "ignored": [], "sigma_below_floor": {}}) == []


def test_held_out_findings_relative_then_absolute_noise_and_coverage_edge():
    """Defects: the RMS error not compared with σ when a relative noise is given but not exceeded,
    the surrogate error reported twice (relative and absolute), the smallest per-sensor σ not the
    one compared, coverage at the limit reported or just below it missed, the remedies not naming
    the settings that help."""
    (f,) = held_out_findings(_held(0.005, 0.003, 0.95), noise_rel=0.01, noise_abs=0.002)
    assert f == Finding("surrogate-error", "held-out", {"rms_abs_error_mm": 0.003, "sigma_mm": 0.002})
    assert "RMS error" in word(f).message and "(0.003 mm)" in word(f).message and "σ = 0.002 mm" in word(f).message
    (f,) = held_out_findings(_held(0.02, 0.003, 0.95), noise_rel=0.01, noise_abs=0.002)
    assert f.values == {"median_rel_error": 0.02, "noise_rel": 0.01}
    assert "median error" in word(f).message and "(2.00 %)" in word(f).message and "(1 %)" in word(f).message
    assert "[sampling] train.n" in word(f, "study").remedy
    (f,) = held_out_findings(_held(0.5, 0.003, 0.95), noise_abs={"D1": 0.002, "D2": 0.01})
    assert f.values["sigma_mm"] == 0.002
    assert held_out_findings(_held(0.5, 0.002, COVERAGE_LIMIT), noise_abs=0.002) == []
    (f,) = held_out_findings(_held(0.0, 0.0, 0.79))
    assert f == Finding("surrogate-coverage", "held-out", {"coverage_2sigma": 0.79})
    assert "only 79 %" in word(f).message and "[surrogate] nugget" in word(f).remedy


def test_diagnosis_findings_name_every_cause_in_order():
    """Defects: several causes not kept in the order found, their count or pronoun wrong, a cause
    without a location given one, the χ²/dof gain lost."""
    (f,) = diagnosis_findings({
        "verdict": "inadequate", "cause": "bond slip", "detail": None,
        "causes": [{"cause": "bond slip", "location": None}, {"cause": "a faulty sensor", "location": "D2"}],
        "gain": {"chi2_dof_before": 12.0, "chi2_dof_after": 1.25}})
    assert f == Finding("diagnosis-cause", "diagnosis", {
        "causes": [{"cause": "bond slip", "location": None}, {"cause": "a faulty sensor", "location": "D2"}],
        "chi2_dof_before": 12.0, "chi2_dof_after": 1.25})
    text = word(f)
    assert "leaves out 2 physical effects" in text.message
    message = text.message
    assert message.index("bond slip") < message.index("faulty sensor at D2") and "12.00 → 1.25" in message
    assert "read the diagnosis report" in text.remedy
    (f,) = diagnosis_findings({"verdict": "inadequate", "cause": "a rotated support", "causes": [],
                               "detail": {"location": None}, "gain": None})
    assert f.values["chi2_dof_before"] is None
    assert word(f).message.endswith("leaves out a physical effect: the diagnosis names a rotated support.")
    (f,) = diagnosis_findings({"verdict": "inadequate", "cause": None, "base": {"chi2_dof": 3.0}})
    assert f == Finding("diagnosis-unexplained", "diagnosis", {"chi2_dof": 3.0})
    assert "(χ²/dof = 3.00)" in word(f).message and "residual pattern" in word(f).remedy
    assert diagnosis_findings({"verdict": "adequate"}) == []


def test_every_code_of_the_policy_has_words():
    """Defect: a code the policy emits without an entry in the words (a KeyError in a report)."""
    emitted = {"fe-check", "at-bound", "chi2-dof", "unidentified", "insensitive", "fe-failed", "near-failure",
               "measurement-columns",
               "noise-below-floor", "surrogate-error", "surrogate-coverage", "diagnosis-unexplained",
               "diagnosis-cause",
               # the measurement check's refusals (podkrig.online.data_check)
               "load-scale", "load-sign", "reading-scale", "reading-sign"}
    assert set(WORDS) == emitted


# --- a finding of one test, the χ² basis and the summary form -------------------------------------------


def test_a_finding_of_one_test_names_it_in_its_words():
    """Defect: a joint calibration's per-test finding worded without the test it concerns."""
    f = dataclasses.replace(Finding("chi2-dof", "inversion", {"chi2_dof": 3.0}), test="shear")
    assert word(f, "study").message.startswith("test shear: χ²/dof = 3.00")
    assert not word(dataclasses.replace(f, test=None), "study").message.startswith("test")


def test_chi2_basis_appends_how_the_error_terms_were_obtained():
    """Defects: the model-error description dropped from the diagnosis's basis (or added to
    another kind's), the FE model-form error not appended, an unknown kind not refused."""
    assert chi2_basis("diagnosis") == CHI2_BASIS["diagnosis"]
    assert chi2_basis("diagnosis", "e² from two meshes") == CHI2_BASIS["diagnosis"] + " = e² from two meshes"
    assert chi2_basis("surrogate", "e² from two meshes") == CHI2_BASIS["surrogate"]
    basis = chi2_basis("surrogate-noise", form_error="ε = 5 % of |g|")
    assert basis.startswith(CHI2_BASIS["surrogate-noise"] + " + ") and "model-form error" in basis
    assert basis.endswith("ε = 5 % of |g|")
    basis = chi2_basis("diagnosis", "e²", "ε")
    assert basis.startswith(CHI2_BASIS["diagnosis"] + " = e² + ") and basis.endswith("model-form error ε")
    with pytest.raises(KeyError):
        chi2_basis("posterior")


def test_findings_keep_their_level_through_their_dict_forms():
    """Defects: the default level changed ("warning" is what summary.json readers filter on), or a
    finding of another level read back (codes and values, or words) as a warning."""
    f = Finding("fe-failed", "offline", {"stage": "train", "failed": 2, "total": 10, "failures": []}, level="error",
                test="shear")
    assert Finding("chi2-dof", "inversion").level == "warning"
    assert Finding.from_dict(f.to_dict()) == f
    text = word(f, "study")
    assert text.level == "error" and set(text.to_dict()) == {"code", "level", "section", "what", "what_to_do"}
    assert FindingText.from_dict(text.to_dict()) == text


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


def test_an_unpinned_strength_parameter_names_the_test_that_would_inform_it():
    """Defects: a study that cannot identify the joints' tensile strength not saying which test
    would (a tension test), or naming one for a parameter the catalogue does not know."""
    unpinned = Finding("unidentified", "region", {"parameter": "ft_bj", "low": 0.05, "high": 0.13, "unit": "MPa",
                                                  "share": 1.0})
    for context in ("cli", "study"):
        assert "couplet_tension" in word(unpinned, context).remedy
    (flat,) = sensitivity_findings({"propose_fixing": ["GfI_bj"], "threshold": 0.01})
    assert "tension test" in word(flat, "study").remedy and "couplet_tension" in word(flat, "study").remedy
    other = Finding("unidentified", "region", {"parameter": "Km", "low": 0.75, "high": 0.95, "unit": "-", "share": 1.0})
    assert "A test that informs" not in word(other, "study").remedy
