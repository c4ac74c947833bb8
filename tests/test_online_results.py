"""Result objects of the online stage (to_dict / from_dict round trips) and the findings policy:
each test here fails for one specific defect (named in its docstring) of the policy, the FE check,
the multi-start polish or the stage cache; all run on analytic models in well under a second."""

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig._qmc import rng_seed
from podkrig.online.calibrate import calibrate
from podkrig.online.findings import (
    CHI2_DOF_LIMIT, COVERAGE_LIMIT, FE_CHECK_LIMIT, Finding, diagnosis_findings, fe_check_ok, held_out_findings,
    inversion_findings, is_identifiable, offline_findings,
)
from podkrig.online.invert import FECheck, InverseResult, _distinct_starts, fe_check, invert
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.nested import NestedAnalysis, OverparamResult, information_criteria, nested_analyses
from podkrig.online.problem import InverseProblem, fix_from_scenario
from podkrig.online.propagation import RVCResult, rvc
from podkrig.online.region import Region, identifiability, likelihood_ratio_region, noise_monte_carlo_region
from podkrig.online.settings import CalibrationSettings, InversionSettings, RegionSettings
from podkrig.reports.findings import FindingText, word
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.reports.inverse import write_inversion_report
from podkrig.study.cache import Progress, StageCache
from podkrig.surrogate.validation import HeldOutReport

SIGMA = 0.01  # mm, noise of the linear model's data


class LinearModel:
    """Readings ``a·m₁ + b·m₂`` of 3 sensors at 2 loads, exact (no predictive variance)."""

    space = ParameterSpace((Parameter("m1", 0.0, 2.0, unit="MPa"), Parameter("m2", 0.0, 2.0)))
    sensor_names = ("g1", "g2", "g3")
    load_levels = np.array([10.0, 20.0])
    load_unit = "kN"
    A = np.array([[1.0, 0.2], [0.3, 1.0], [0.5, 0.5], [2.0, 0.4], [0.6, 2.0], [1.0, 1.0]])  # (6 outputs, 2)

    def predict(self, X, return_std=False):
        Y = np.atleast_2d(X) @ self.A.T
        return (Y, np.zeros_like(Y)) if return_std else Y


TRUTH = np.array([0.7, 1.3])


def _problem(scale=1.0, model=None):
    """The linear problem with data at the truth, one gauge scaled by ``scale`` (1: consistent)."""
    model = model or LinearModel()
    clean = model.predict(TRUTH[None])[0].reshape(2, 3)
    noisy = clean + SIGMA * np.random.default_rng(5).standard_normal(clean.shape)  # χ²/dof ≈ 0.95
    noisy[:, 0] *= scale
    return InverseProblem(model, Measurement(noisy, model.sensor_names, model.load_levels, source="lin.csv"),
                          NoiseModel(sigma=SIGMA), model_error=False)


@pytest.fixture(scope="module")
def solved():
    problem = _problem()
    result = invert(problem, rng=0, population_size=20, generations=10, n_starts=2)
    region = likelihood_ratio_region(problem, result.x, n_samples=2**12, rng=0)
    return problem, result, region


class _Scenario:
    """An FE stand-in: the linear model's readings plus ``offset`` mm on every reading."""

    def __init__(self, offset):
        self.offset = offset

    def run(self, params):
        x = np.array([[params["m1"], params["m2"]]])

        class Response:
            readings = (LinearModel().predict(x)[0] + self.offset).reshape(2, 3)

        return Response()


def _json_round(d):
    return json.loads(json.dumps(d))


# --- round trips -------------------------------------------------------------------------------


def test_inverse_result_round_trip(solved):
    _, result, _ = solved
    result = result.with_fe_check(_Scenario(0.0))
    d = _json_round(result.to_dict())
    back = InverseResult.from_dict(d)
    assert back.to_dict() == d
    assert_allclose(back.x, result.x)
    assert back.chi2_dof == pytest.approx(result.chi2_dof) and back.fe_check.ok
    assert d["measurement"] == {"file": "lin.csv", "sensors": ["g1", "g2", "g3"], "load_levels": [10.0, 20.0],
                                "load_unit": "kN", "n_obs": 6}
    with pytest.raises(ValueError, match="read back from a dict"):
        back.predicted()


class UnsortedModel(LinearModel):
    """The linear model with its parameters named against alphabetical order (``z``, ``a``)."""

    space = ParameterSpace((Parameter("z", 0.0, 2.0, unit="MPa"), Parameter("a", 0.0, 2.0)))


def test_inverse_result_read_back_from_sorted_json_keeps_each_value_with_its_name():
    """The study writes its manifests and summary.json with sorted keys: ``parameters`` comes back
    as (a, z) while ``x`` stays in the free order (z, a). Each value must stay with its name (the
    study report's table and ``podkrig serve`` read the calibration back this way); a dict written
    before the free order was recorded is paired by name too, in the problem's order when given."""
    problem = _problem(model=UnsortedModel())
    result = invert(problem, rng=0, population_size=20, generations=10, n_starts=2)
    assert result.free == ("z", "a") and result.x[0] != pytest.approx(result.x[1], rel=1e-3)
    d = json.loads(json.dumps(result.to_dict(), sort_keys=True))
    assert list(d["parameters"]) == ["a", "z"]
    back = InverseResult.from_dict(d)
    assert back.free == ("z", "a")
    assert_allclose(back.x, result.x, rtol=0)
    assert back.free_parameters == pytest.approx(result.free_parameters, rel=0)
    old = {k: v for k, v in d.items() if k != "free"}
    assert InverseResult.from_dict(old, problem=problem).free == ("z", "a")
    assert_allclose(InverseResult.from_dict(old, problem=problem).x, result.x, rtol=0)
    legacy = InverseResult.from_dict(old)
    assert legacy.free_parameters == pytest.approx(result.free_parameters, rel=0)


def test_region_rvc_and_nested_round_trips(solved):
    problem, result, region = solved
    d = _json_round(region.to_dict(members=True))
    back = Region.from_dict(d)
    assert back.to_dict(members=True) == d
    assert_allclose(back.samples, region.samples)
    # members kept apart (as the study keeps them in region.npz)
    summary = _json_round(region.to_dict())
    assert "samples" not in summary
    assert Region.from_dict(summary, samples=region.samples, omega=region.omega).to_dict() == summary
    with pytest.raises(ValueError, match="members"):
        Region.from_dict(summary, samples=region.samples[:1], omega=region.omega[:1])

    spread = rvc(region, LinearModel())
    d = _json_round(spread.to_dict())
    assert RVCResult.from_dict(d).to_dict() == d and "values" not in d
    assert RVCResult.from_dict(d).values is None
    assert_allclose(RVCResult.from_dict(d, values=spread.values.tolist()).values, spread.values, rtol=0)

    row = NestedAnalysis(("m1", "m2"), result.free_parameters, result.misfit, result.chi2_dof, 1.0, 2.0,
                         region.intervals, region.identifiability, {"same": 0.01})
    over = OverparamResult((row,))
    d = _json_round(over.to_dict())
    assert OverparamResult.from_dict(d).to_dict() == d and len(over) == 1


class SumModel:
    """A validation model: one gauge reading ``m1 + m2`` (mm) at one load, exact."""

    space = LinearModel.space
    sensor_names = ("v",)
    load_levels = np.array([30.0])

    def predict(self, X, return_std=False):
        Y = np.atleast_2d(X).sum(axis=1, keepdims=True)
        return (Y, np.zeros_like(Y)) if return_std else Y


def test_nested_analyses_rows_are_their_seeded_analyses():
    """Defects: a row's field (free set, best fit, misfit, χ²/dof, AIC, BIC, intervals, RVC) lost
    or swapped; BIC ≠ χ² + k ln n; the confidence, sample count or seed not passed on to the
    region; a validation model fed its own value of a parameter the calibration fixed
    (docstring: it takes the calibration's value); no RVC (None) when no validation is given."""
    base = _problem()

    def make(free):
        return InverseProblem(base.model, base.measurement, base.noise, free=free,
                              fixed={} if "m2" in free else {"m2": 1.5}, model_error=False)

    seed, confidence, n_samples = 3, 0.68, 2**12
    rows = nested_analyses(make, [("m1",), ("m1", "m2")], confidence=confidence, rng=seed, n_samples=n_samples,
                           validation={"sum": (SumModel(), {"m2": 0.2})})
    assert len(rows) == 2 and [r.free for r in rows] == [("m1",), ("m1", "m2")]
    for row, m2_fixed in zip(rows, (1.5, None)):
        problem = make(row.free)
        # the documented steps run by hand with the same seed: identify, then sample the region
        result = invert(problem, rng=seed)
        region = likelihood_ratio_region(problem, result.x, confidence=confidence, rng=seed, n_samples=n_samples)
        assert row.parameters == pytest.approx({n: result.parameters[n] for n in row.free}, rel=1e-9)
        assert set(row.parameters) == set(row.free)
        assert row.misfit == pytest.approx(result.misfit, rel=1e-9)
        assert row.chi2_dof == pytest.approx(result.chi2_dof, rel=1e-9)
        k, n = len(row.free), 6  # free parameters, observations (3 gauges x 2 loads)
        assert row.aic == pytest.approx(result.chi2 + 2 * k, rel=1e-9)
        assert row.bic == pytest.approx(result.chi2 + k * np.log(n), rel=1e-9)
        assert information_criteria(result)["bic"] == pytest.approx(result.chi2 + k * np.log(n), rel=1e-12)
        for name, (lo, hi) in region.intervals.items():
            assert row.intervals[name] == pytest.approx((lo, hi), rel=1e-9)
            assert row.to_dict()["intervals"][name] == pytest.approx([lo, hi], rel=1e-9) and lo < hi
        assert row.identifiability == region.identifiability
        # RVC of m1 + m2 over the region (< 20 000 members: no subsampling), closed form std/mean;
        # m2 not freed takes the calibration's 1.5, never the validation's own 0.2
        m1 = region.samples[:, 0]
        v = m1 + (m2_fixed if m2_fixed is not None else region.samples[:, 1])
        assert len(region.samples) < 20_000
        assert row.rvc["sum"] == pytest.approx(np.std(v, ddof=1) / np.mean(v), rel=1e-9)
    wider = nested_analyses(make, [("m1",)], confidence=0.99, rng=seed, n_samples=n_samples)
    assert np.ptp(wider[0].intervals["m1"]) > 1.3 * np.ptp(rows[0].intervals["m1"])  # Wilks 1-dof: 2.58 / 0.99
    # no validation: no RVC, and the row still serialises and loads without one
    assert wider[0].rvc is None and "rvc" not in wider[0].to_dict()
    d = _json_round(wider[0].to_dict())
    assert NestedAnalysis.from_dict(d).rvc is None and NestedAnalysis.from_dict(d).to_dict() == d
    # a region of > 20 000 members: RVC uses a random subset, drawn with the analysis's seed
    many = nested_analyses(make, [("m1", "m2")], rng=seed, n_samples=2**17, validation={"sum": (SumModel(), {})})
    problem = make(("m1", "m2"))
    region = likelihood_ratio_region(problem, invert(problem, rng=seed).x, rng=seed, n_samples=2**17)
    assert len(region.samples) > 20_000
    assert many[0].rvc["sum"] == pytest.approx(float(np.max(rvc(region, SumModel(), rng=seed).cv)), rel=1e-9)
    v = region.samples.sum(axis=1)
    assert many[0].rvc["sum"] == pytest.approx(np.std(v, ddof=1) / np.mean(v), rel=0.02)  # subset of 20 000


def test_polish_starts_are_the_best_mutually_distant_points():
    """Defects (``invert``'s n_starts docstring): the best point not first, the second best skipped,
    more or fewer starts than asked, the distance to the farthest chosen start used instead of the
    nearest, a sum instead of a difference, a start exactly at the minimum distance refused."""
    U = np.array([[0.50, 0.50], [0.55, 0.50], [0.75, 0.50], [0.20, 0.90], [0.60, 0.55], [0.50, 0.25], [0.9, 0.9]])
    omega = np.array([3.0, 4.0, 5.0, 6.0, 1.0, 7.0, 8.0])  # best: U[4], then U[0] (0.1 away), U[1], U[2], ...
    # max-norm distance ≥ 0.25 to every start already chosen, best first
    assert_allclose(_distinct_starts(U, omega, 3, min_distance=0.25), U[[4, 3, 5]])
    assert_allclose(_distinct_starts(U, omega, 10, min_distance=0.25), U[[4, 3, 5, 6]])
    assert_allclose(_distinct_starts(U, omega, 1), U[[4]])
    # default 0.15: U[0] is 0.1 from U[4] and U[1] 0.05 (skipped), U[2] 0.15 (taken)
    assert_allclose(_distinct_starts(U, omega, 3), U[[4, 2, 3]])
    # exact binary distances: the second is 0.25 from the first (taken: "at least"); the third is 0.25
    # from the first but 0.125 from the second (skipped: the nearest chosen start counts)
    edge = np.array([[0.5, 0.5], [0.75, 0.5], [0.75, 0.625]])
    assert_allclose(_distinct_starts(edge, np.array([1.0, 2.0, 3.0]), 3, min_distance=0.25), edge[[0, 1]])


def test_rng_seed_draws_distinct_reproducible_seeds():
    """Defects: no seed (or one from a tiny range) drawn from a Generator, an int not passed through."""
    seeds = [rng_seed(np.random.default_rng(i)) for i in range(50)]
    assert all(isinstance(s, int) and 0 <= s < 2**31 for s in seeds) and len(set(seeds)) == 50
    assert rng_seed(np.random.default_rng(7)) == rng_seed(np.random.default_rng(7)) and rng_seed(12) == 12


def test_finding_fe_check_and_held_out_round_trips():
    f = Finding("chi2-dof", "inversion", {"chi2_dof": 5.0}, test="shear")
    assert Finding.from_dict(_json_round(f.to_dict())) == f
    check = FECheck(0.1, 2.0, 0.01, 1.5, False, np.ones(3))
    assert FECheck.from_dict(_json_round(check.to_dict())).to_dict() == check.to_dict()
    rng = np.random.default_rng(0)
    rep = HeldOutReport(rng.random(4), rng.random(4), rng.random(4), 0.9, rng.random((4, 2)), rng.random((4, 6)),
                        rng.random((4, 6)), rng.random((4, 6)), 16, 3, rng.random(16), {"note": 1})
    d = _json_round(rep.to_dict())
    back = HeldOutReport.from_dict(d)
    assert back.to_dict() == d and back.summary() == rep.summary()


# --- the findings policy and what feeds it -----------------------------------------------------


def test_fe_check_flags_a_surrogate_off_by_more_than_the_noise(solved):
    """Fails if the FE check at the optimum is forced to "ok"."""
    _, result, _ = solved
    exact = fe_check(result, _Scenario(0.0))
    assert exact.ok and exact.max_abs_diff < 1e-12
    off = fe_check(result, _Scenario(3 * SIGMA))
    assert off.max_diff_over_noise == pytest.approx(3.0) and not off.ok
    codes = [f.code for f in inversion_findings(result.with_fe_check(_Scenario(3 * SIGMA)))]
    assert codes == ["fe-check"]
    assert fe_check(result, _Scenario(0.5 * FE_CHECK_LIMIT * SIGMA)).ok


def test_chi2_warning_between_the_limit_and_far_beyond():
    """Fails if the χ²/dof threshold is raised (e.g. to 200): a fit with χ²/dof ≈ 9 must warn."""
    result = invert(_problem(scale=1.08), rng=0, population_size=20, generations=10, n_starts=2)
    assert CHI2_DOF_LIMIT < result.chi2_dof < 50
    found = inversion_findings(result)
    assert [f.code for f in found] == ["chi2-dof"] and found[0].values == {"chi2_dof": result.chi2_dof}
    consistent = invert(_problem(), rng=0, population_size=20, generations=10, n_starts=2)
    assert consistent.chi2_dof < CHI2_DOF_LIMIT and inversion_findings(consistent) == []


def test_report_shows_the_chi2_warning(tmp_path):
    """Fails if the report's χ²/dof warning threshold is raised (the report applies the policy)."""
    settings = CalibrationSettings(inversion=InversionSettings(population_size=20, generations=10, n_starts=2),
                                   region=RegionSettings(samples=2**10), fe_check=False)
    calibration = calibrate(_problem(scale=1.08), settings)
    page = write_inversion_report(tmp_path, calibration).read_text(encoding="utf-8")
    assert "within the stated noise" in page and "podkrig diagnose" in page
    assert page.count("does not reproduce the data") == 1  # said once, not by two policies


@pytest.mark.parametrize("share, identified", [(0.3, True), (0.5, True), (0.7, False), (0.9, False)])
def test_unidentifiable_share_threshold(share, identified):
    """Fails if the unidentifiable-share threshold is moved (e.g. to 0.95): a parameter whose interval
    spans 70 % of its range is not identified."""
    space = ParameterSpace((Parameter("a", 0.0, 10.0, unit="MPa"), Parameter("k", 1.0, 100.0, "log")))
    # k's interval spans `share` of its log range; a spans 10 %
    intervals = {"a": (4.0, 5.0), "k": (1.0, 10 ** (2 * share))}
    verdict = identifiability(intervals, space)
    assert verdict["a"]["identifiable"] and verdict["a"]["share"] == pytest.approx(0.1)
    assert verdict["k"]["share"] == pytest.approx(share)
    assert verdict["k"]["identifiable"] is identified
    assert is_identifiable(share) is identified


def test_unidentified_parameter_is_a_finding(solved):
    _, result, region = solved
    wide = Region(region.method, region.confidence, region.samples, region.omega, region.threshold,
                  {"m1": (0.1, 1.9), "m2": region.intervals["m2"]}, region.names, region.units, region.n_evaluated,
                  region.seconds, identifiability({"m1": (0.1, 1.9), "m2": region.intervals["m2"]},
                                                  LinearModel.space))
    found = inversion_findings(result, wide)
    assert [(f.code, f.section) for f in found] == [("unidentified", "region")]
    assert found[0].values["parameter"] == "m1" and found[0].values["unit"] == "MPa"
    assert (found[0].values["low"], found[0].values["high"]) == (0.1, 1.9)


# --- the multi-start polish --------------------------------------------------------------------


class TwoBasinModel:
    """One reading g(m) = 1 − 0.5 exp(−((m − 0.3)/0.2)²) − exp(−((m − 0.85)/0.004)²) against data 0:
    a broad basin at m = 0.3 (ω = ½ (0.5/σ)²) and a narrow global one at m = 0.85 (ω ≈ 0)."""

    space = ParameterSpace((Parameter("m", 0.0, 1.0),))
    sensor_names = ("g",)
    load_levels = np.array([1.0])

    def predict(self, X, return_std=False):
        m = np.atleast_2d(X)[:, :1]
        Y = 1 - 0.5 * np.exp(-(((m - 0.3) / 0.2) ** 2)) - np.exp(-(((m - 0.85) / 0.004) ** 2))
        return (Y, np.zeros_like(Y)) if return_std else Y


def test_multi_start_polish_finds_a_narrow_global_basin():
    """Fails if the polishes from the Sobol' screen are removed: the GA alone (small budget) ends in
    the broad basin at 0.3; only a start from the screen reaches the narrow one at 0.85."""
    model = TwoBasinModel()
    problem = InverseProblem(model, Measurement(np.zeros((1, 1)), ("g",), np.array([1.0])), NoiseModel(sigma=0.01),
                             model_error=False)
    ga_only = invert(problem, rng=0, population_size=6, generations=2, n_starts=1, polish=False)
    assert abs(ga_only.x[0] - 0.3) < 0.2  # the broad basin: the premise of this test
    result = invert(problem, rng=0, population_size=6, generations=2, n_starts=3)
    assert result.x[0] == pytest.approx(0.85, abs=1e-3)
    assert result.misfit < 1e-6


# --- unfree parameters from the scenario ---------------------------------------------------------


def test_fix_from_scenario_takes_spec_values_inside_the_box():
    class Model:
        space = ParameterSpace((Parameter("E_b", 5000.0, 20000.0), Parameter("nu_b", 0.1, 0.2),
                                Parameter("kN_bj", 10.0, 50.0)))
        scenario_spec = {"scenario": "diagonal_compression", "parameters": {"nu_b": 0.12, "kN_bj": 80.0}}

    free, fixed = fix_from_scenario(Model(), ("E_b",), {})
    assert free == ("E_b",) and fixed == {"nu_b": 0.12}  # kN_bj = 80 lies outside [10, 50]: not filled
    free, fixed = fix_from_scenario(Model(), None, {"kN_bj": 20.0})
    assert free == ("E_b", "nu_b") and fixed == {"kN_bj": 20.0}
    assert fix_from_scenario(Model()) == (None, {})


# --- the stage cache -----------------------------------------------------------------------------


def test_stage_cache_reruns_a_stage_whose_output_changed_or_vanished(tmp_path):
    """Fails if the output-file check of the cache always passes."""
    runs = []

    def compute():
        runs.append(1)
        (tmp_path / "out.txt").write_text(f"run {len(runs)}")
        return {"n": len(runs)}, ["out.txt"], 0

    def stage():
        cache = StageCache(tmp_path, Progress())
        return cache.stage("s", "a stage", {"setting": 1}, compute), cache.records[0]

    first, record = stage()
    assert not record.cached and first["result"]["n"] == 1
    _, record = stage()
    assert record.cached and len(runs) == 1  # nothing changed: cached
    (tmp_path / "out.txt").write_text("edited by hand")
    again, record = stage()
    assert not record.cached and again["result"]["n"] == 2
    (tmp_path / "out.txt").unlink()
    _, record = stage()
    assert not record.cached and len(runs) == 3


def test_finding_dict_forms_and_the_default_level():
    """Fails if the summary.json keys of a worded finding change, or a finding (codes and values, or
    words) read without a level is not a warning."""
    f = Finding("fe-failed", "offline", {"stage": "train", "failed": 2, "total": 10, "failures": []}, level="error")
    assert f.to_dict() == {"code": "fe-failed", "level": "error", "section": "offline", "values": f.values,
                           "test": None}
    text = word(f, "study")
    assert set(text.to_dict()) == {"code", "level", "section", "what", "what_to_do"}
    for cls, d in ((Finding, f.to_dict()), (FindingText, text.to_dict())):
        del d["level"]
        assert cls.from_dict(d).level == "warning"
    assert fe_check_ok(FE_CHECK_LIMIT) and not fe_check_ok(FE_CHECK_LIMIT * (1 + 1e-12))


def test_offline_held_out_and_diagnosis_findings_policy():
    """Fails if a threshold or an inequality of the surrogate, FE-failure or diagnosis findings moves:
    median relative error above δ (strictly), RMS error above the smallest per-sensor σ, ±2σ coverage
    below the limit; failed FE runs counted; a diagnosis names its cause, location and gain."""
    assert offline_findings("train", {"failed": 0, "total": 10, "failures": []}) == []
    (f,) = offline_findings("train", {"failed": 2, "total": 10, "failures": ["run 3: singular", "run 7: singular"]})
    assert (f.code, f.section) == ("fe-failed", "offline")
    assert f.values == {"stage": "train", "failed": 2, "total": 10, "failures": ["run 3: singular", "run 7: singular"]}

    def held(median, rms, coverage):
        return {"rel_error": {"median": median}, "rms_abs_error_mm": rms, "coverage_2sigma": coverage}

    ok = held(0.01, 0.002, COVERAGE_LIMIT)
    assert held_out_findings(ok, noise_rel=0.01) == [] and held_out_findings(ok) == []
    (f,) = held_out_findings(held(0.0125, 0.0, 0.95), noise_rel=0.01)
    assert (f.code, f.section, f.values) == ("surrogate-error", "held-out", {"median_rel_error": 0.0125,
                                                                             "noise_rel": 0.01})
    assert held_out_findings(held(0.5, 0.002, 0.95), noise_abs={"D1": 0.002, "D2": 0.01}) == []
    (f,) = held_out_findings(held(0.5, 0.003, 0.95), noise_abs={"D1": 0.002, "D2": 0.01})
    assert f.values == {"rms_abs_error_mm": 0.003, "sigma_mm": 0.002}
    assert [f.code for f in held_out_findings(held(0.5, 0.003, 0.7), noise_abs=0.002)] == [
        "surrogate-error", "surrogate-coverage"]
    (f,) = held_out_findings(held(0.0, 0.0, 0.7))
    assert f.code == "surrogate-coverage" and f.values == {"coverage_2sigma": 0.7}

    assert diagnosis_findings({"verdict": "adequate"}) == []
    (f,) = diagnosis_findings({"verdict": "inadequate", "cause": None, "base": {"chi2_dof": 7.5}})
    assert f.code == "diagnosis-unexplained" and f.values == {"chi2_dof": 7.5}
    (f,) = diagnosis_findings({"verdict": "inadequate", "cause": "a faulty sensor", "detail": {"location": "D2"},
                               "gain": {"chi2_dof_before": 9.0, "chi2_dof_after": 1.1}})
    assert (f.code, f.section) == ("diagnosis-cause", "diagnosis")
    assert f.values == {"causes": [{"cause": "a faulty sensor", "location": "D2"}], "chi2_dof_before": 9.0,
                        "chi2_dof_after": 1.1}
    (f,) = diagnosis_findings({"verdict": "inadequate", "cause": "bond slip", "detail": None, "gain": None})
    assert f.values == {"causes": [{"cause": "bond slip", "location": None}], "chi2_dof_before": None,
                        "chi2_dof_after": None}


def test_rvc_statistics_against_numpy_on_the_region_members(solved):
    """Fails if a statistic of the RVC changes (sample std with ddof = 1, cv and range ratio over
    |mean| even below 1 mm, min, max), if the member subset is drawn with replacement or unseeded,
    or if one member gives anything but zero spread."""
    _, _, region = solved
    model = LinearModel()
    Y = region.samples @ model.A.T
    out = rvc(region, model)
    assert out.outputs == ("g1@20", "g2@20", "g3@20") and out.n_samples == len(Y)
    y = Y[:, 3:]
    assert_allclose(out.values, y, rtol=0)
    assert_allclose(out.mean, y.mean(axis=0), rtol=1e-12)
    assert_allclose(out.std, y.std(axis=0, ddof=1), rtol=1e-12)
    assert_allclose(out.cv, y.std(axis=0, ddof=1) / np.abs(y.mean(axis=0)), rtol=1e-12)
    assert_allclose(out.range_ratio, (y.max(axis=0) - y.min(axis=0)) / np.abs(y.mean(axis=0)), rtol=1e-12)
    assert_allclose(out.min, y.min(axis=0), rtol=0)
    assert_allclose(out.max, y.max(axis=0), rtol=0)
    small = rvc(region, model, outputs=["g1@10"])  # mean ≈ 0.96 mm < 1
    assert_allclose(small.cv, Y[:, :1].std(axis=0, ddof=1) / np.abs(Y[:, :1].mean(axis=0)), rtol=1e-12)
    assert_allclose(rvc(region, model, max_samples=len(Y)).values, y, rtol=0)  # all members, in order
    sub = rvc(region, model, max_samples=len(Y) // 2)
    assert sub.n_samples == len(Y) // 2 and len(np.unique(sub.values, axis=0)) == len(Y) // 2
    assert_allclose(rvc(region, model, max_samples=len(Y) // 2).values, sub.values, rtol=0)
    two = rvc(region, model, max_samples=2)
    assert_allclose(two.std, np.abs(two.values[0] - two.values[1]) / np.sqrt(2), rtol=1e-12)
    one = rvc(region, model, max_samples=1)
    assert one.std.tolist() == [0.0, 0.0, 0.0] and one.cv.tolist() == [0.0, 0.0, 0.0]


def test_noise_monte_carlo_intervals_are_the_central_percentiles_of_the_refits(solved):
    """Fails if the interval levels move off the central ``confidence`` share of the refitted optima,
    or if the evaluation count stops accumulating over the realisations."""
    problem, result, _ = solved
    for confidence, levels in ((0.95, [2.5, 97.5]), (0.8, [10.0, 90.0])):
        mc = noise_monte_carlo_region(problem, result.x, n_realisations=30, confidence=confidence, rng=1)
        q = np.percentile(mc.samples, levels, axis=0)
        for j, name in enumerate(("m1", "m2")):
            assert_allclose(mc.intervals[name], q[:, j], rtol=1e-12)
        assert len(mc.samples) == 30 and mc.n_evaluated >= 30 * 3  # a polish evaluates ≥ 1 + 2 (one per parameter)
