"""The calibration stage (:func:`podkrig.online.calibrate.calibrate`): hidden truth on a cheap
problem, one test and several, its result read back from its dict, the region methods under one
spelling, the settings it consumes — and the same numbers through ``podkrig invert`` and
``podkrig run``."""

import dataclasses
import json

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError
from typer.testing import CliRunner

from fe.scenarios import build_scenario
from podkrig.cli import app
from podkrig.cli._common import RegionMethod
from podkrig.config import choices
from podkrig.io.measurement_log import write_measurement_csv
from podkrig.online.calibrate import CalibrationResult, calibrate
from podkrig.online.joint import JointProblem
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.problem import InverseProblem
from podkrig.online.settings import CalibrationSettings, InversionSettings, NoiseSettings, RegionSettings
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.study.settings import InversionTable

SIGMA = 0.01  # mm
TRUTH = {"m1": 0.7, "m2": 1.3, "m3": 0.4}


class Linear:
    """Readings ``A m`` of 3 sensors at 2 loads over the parameters ``names`` (exact: no
    predictive variance), and its own FE stand-in (:meth:`scenario`)."""

    sensor_names = ("g1", "g2", "g3")
    load_levels = np.array([10.0, 20.0])
    load_unit = "kN"

    def __init__(self, names, seed):
        self.space = ParameterSpace(tuple(Parameter(n, 0.0, 2.0, unit="MPa") for n in names))
        self.A = np.random.default_rng(seed).uniform(0.2, 2.0, (6, len(names)))

    def predict(self, X, return_std=False):
        Y = np.atleast_2d(X) @ self.A.T
        return (Y, np.zeros_like(Y)) if return_std else Y

    def scenario(self):
        return _Scenario(self)


class _Scenario:
    """The FE model of :class:`Linear` with ``offset`` mm on every reading; counts its runs."""

    def __init__(self, model, offset=0.0):
        self.model, self.offset, self.runs = model, offset, 0

    def run(self, params, field=False):
        self.runs += 1
        x = np.array([[params[n] for n in self.model.space.names]])
        readings = self.model.predict(x)[0].reshape(2, 3) + self.offset
        return type("Response", (), {"readings": readings, "field": "field" if field else None})()


def _problem(names=("m1", "m2"), seed=0, noise_seed=5):
    model = Linear(names, seed)
    truth = np.array([TRUTH[n] for n in names])
    clean = model.predict(truth[None])[0].reshape(2, 3)
    noisy = clean + SIGMA * np.random.default_rng(noise_seed).standard_normal(clean.shape)
    return InverseProblem(model, Measurement(noisy, model.sensor_names, model.load_levels, source="lin.csv"),
                          NoiseModel(sigma=SIGMA), model_error=False)


#: a small GA and region: the problems are linear, the polish finishes them
SMALL = CalibrationSettings(inversion=InversionSettings(population_size=20, generations=10, n_starts=2),
                            region=RegionSettings(samples=2**12))


def test_calibrate_finds_the_hidden_truth_within_its_region():
    """Data from known parameters plus 1 % noise: the best fit is within 4σ of the truth (σ of the
    linear least-squares estimate, exact here: the model is linear and the noise known), the
    truth lies in the 95 % region, and every step ran."""
    problem = _problem()
    scenario = _Scenario(problem.model)
    result = calibrate(problem, dataclasses.replace(SMALL, mcmc_steps=600), scenarios=scenario)
    A = problem.model.A / SIGMA
    sd = np.sqrt(np.diag(np.linalg.inv(A.T @ A)))  # σ of the least-squares estimate (linear model)
    truth = np.array([TRUTH["m1"], TRUTH["m2"]])
    assert np.all(np.abs(result.inversion.x - truth) < 4 * sd), (result.inversion.x, truth, sd)
    for j, name in enumerate(("m1", "m2")):
        lo, hi = result.region.intervals[name]
        assert lo <= truth[j] <= hi
    # the FE check: one run of an exact stand-in agrees with the surrogate to rounding
    assert scenario.runs == 1 and result.n_fe_runs == 1
    assert result.inversion.fe_check.max_abs_diff < 1e-12 and result.inversion.fe_check.ok
    assert result.posterior is not None and set(result.posterior.intervals) == {"m1", "m2"}
    assert set(result.rvc) == {"calibration"} and result.rvc["calibration"].n_samples > 0
    assert result.seconds > 0


def test_calibrate_a_joint_problem_checks_every_test_and_names_its_findings():
    """Two tests sharing m1: the joint fit recovers the truth, each test gets its own FE check and
    RVC model, and a test whose FE model is 5σ off is named in the FE-check finding."""
    joint = JointProblem({"a": _problem(("m1", "m2"), seed=0), "b": _problem(("m1", "m3"), seed=1, noise_seed=6)})
    scenarios = {"a": _Scenario(joint.problems["a"].model),
                 "b": _Scenario(joint.problems["b"].model, offset=5 * SIGMA)}
    result = calibrate(joint, SMALL, scenarios=scenarios)
    assert result.inversion.free == ("m1", "m2", "m3")
    assert_allclose(result.inversion.x, [TRUTH[n] for n in ("m1", "m2", "m3")], atol=0.1)  # ~10σ of the estimate
    assert set(result.tests) == {"a", "b"} and result.n_fe_runs == 2
    assert result.tests["a"].fe_check.ok and not result.tests["b"].fe_check.ok
    assert set(result.rvc) == {"calibration.a", "calibration.b"}
    fe = [f for f in result.findings if f.code == "fe-check"]
    assert len(fe) == 1 and fe[0].test == "b" and fe[0].values["max_diff_over_noise"] > 1


def test_a_tolerance_model_form_error_is_in_the_inversion_and_the_region():
    """ε = 5 % adds (ε d)² to C_D: χ² falls below the noise-only fit's, the region widens, and the
    result says what C_D held."""
    problem = _problem()
    plain = calibrate(problem, dataclasses.replace(SMALL, fe_check=False))
    loose = calibrate(problem, dataclasses.replace(SMALL, fe_check=False, model_form_error=0.05))
    assert loose.inversion.chi2 < plain.inversion.chi2
    for name in ("m1", "m2"):
        assert np.diff(loose.region.intervals[name]) > np.diff(plain.region.intervals[name])
    assert loose.inversion.measurement["model_form_error"]["tolerance"] == 0.05
    assert "ε = 5 %" in loose.inversion.chi2_basis


def test_the_result_shows_in_jupyter_as_the_reports_show_it():
    """The calibration's notebook view is well-formed HTML with the parameters, their region and
    the findings in words (the report's renderer)."""
    import html.parser

    from podkrig.reports.jupyter import calibration_html

    result = calibrate(_problem(), dataclasses.replace(SMALL, fe_check=False))
    text = calibration_html(result)
    parser = html.parser.HTMLParser()
    parser.feed(text)
    parser.close()
    assert "m1" in text and "region of equivalence (95 %)" in text and "χ² includes" in text


def test_the_result_reads_back_from_its_dict():
    """to_dict → JSON → from_dict → to_dict is the same JSON (with the model-form error in C_D, the
    region's members and the posterior's samples kept when asked)."""
    problem = _problem()
    result = calibrate(problem, dataclasses.replace(SMALL, mcmc_steps=300, model_form_error=0.02),
                       scenarios=_Scenario(problem.model))
    assert set(result.model_form_errors) == {None}
    d = json.loads(json.dumps(result.to_dict(members=True)))
    back = CalibrationResult.from_dict(d)
    assert back.to_dict(members=True) == d
    assert back.settings == result.settings and back.inversion.fe_check.ok
    assert_allclose(back.model_form_errors[None].std, result.model_form_errors[None].std, rtol=0, atol=0)
    assert_allclose(back.region.samples, result.region.samples, rtol=0, atol=0)  # JSON keeps a float exactly
    # without members: the region's come from elsewhere (a study's region.npz)
    slim = json.loads(json.dumps(result.to_dict()))
    assert "samples" not in slim["region"]
    again = CalibrationResult.from_dict(slim, samples=result.region.samples, omega=result.region.omega)
    assert again.to_dict() == slim


@pytest.mark.parametrize("method", choices(RegionSettings, "method"))
def test_one_spelling_of_each_region_method(method):
    """The settings' words are the CLI's choices, the study's and the spelling the region records."""
    assert method in [m.value for m in RegionMethod]
    assert InversionTable(region_method=method).calibration().region.method == method
    result = calibrate(_problem(), dataclasses.replace(SMALL, region=RegionSettings(method=method), fe_check=False))
    assert result.region.method == method


@pytest.mark.parametrize("values, fragments", [
    ({"region": {"method": "noise-monte-carlo"}}, ["method"]),
    ({"confidence": 1.5}, ["confidence"]),
    ({"model_form_error": "guessed"}, ["model_form_error", "estimated"]),
    ({"inversion": {"population_size": 2**18, "generations": 10**6}}, ["generations"]),
])
def test_calibration_settings_refuse_what_they_do_not_allow(values, fragments):
    """The refusal names the field and, for a rule of the settings, what is allowed (what the study
    checker and the CLI show)."""
    with pytest.raises(ValidationError) as e:
        CalibrationSettings(**values)
    shown = str(e.value) + str((e.value.errors()[0].get("ctx") or {}).get("allowed"))
    for fragment in fragments:
        assert fragment in shown


def test_noise_settings_build_the_model_and_say_it():
    noise = NoiseSettings(noise_abs={"g1": 0.002, "g2": 0.001, "g3": 0.001}, noise_rel=0.01)
    model = noise.noise_model(("g1", "g2", "g3"))
    assert model.sigma == {"g1": 0.002, "g2": 0.001, "g3": 0.001} and model.delta == 0.01
    assert "σ_res" in noise.describe() and "δ = 1 %" in noise.describe()
    assert NoiseSettings(instrument="lvdt").levels() == (0.01, 0.001)
    with pytest.raises(ValidationError, match="either instrument or noise_rel"):
        NoiseSettings(instrument="lvdt", noise_rel=0.01)


# ------------------------------------------------------------------ the two front doors agree

STUDY = """\
name = "same"

[scenario]
scenario = "diagonal_compression"
nx = 2
ny = 1

[parameters]
kN_bj = { lower = 30.0, upper = 300.0, scale = "log" }
kV_bj = { lower = 10.0, upper = 120.0, scale = "log" }

[fixed]
E_b = 11000.0
r_hj = 0.6

[sampling]
train = { n = 8, seed = 0 }
held_out = { n = 4, seed = 1, method = "random" }
workers = 1

[measurement]
file = "measured.csv"
noise_rel = 0.01
range_check = false

[inversion]
population_size = 20
generations = 10
n_starts = 2
region_samples = 4096

[sensitivity]
enabled = false
"""


def test_invert_and_run_give_the_same_calibration(tmp_path):
    """The same surrogate, data and settings through ``podkrig run`` (the study's calibration
    stage) and through ``podkrig invert`` on the study's surrogate: the same numbers, bit for bit
    (one process, one machine: the same operations in the same order)."""
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    clean = sc.run({"E_b": 11000.0, "r_hj": 0.6, "kN_bj": 90.0, "kV_bj": 35.0}).readings
    noisy = clean * (1 + 0.01 * np.random.default_rng(0).standard_normal(clean.shape))
    write_measurement_csv(tmp_path / "measured.csv", Measurement(noisy, sc.sensor_names, sc.load_levels))
    (tmp_path / "study.toml").write_text(STUDY)
    runner = CliRunner()
    ran = runner.invoke(app, ["run", str(tmp_path / "study.toml"), "--out", str(tmp_path / "out")])
    assert ran.exit_code == 0, ran.output
    study = json.loads((tmp_path / "out" / "summary.json").read_text())["stages"]["calibration"]
    inverted = runner.invoke(app, ["invert", str(tmp_path / "out" / "surrogate.h5"), "--data",
                                   str(tmp_path / "measured.csv"), "--noise-rel", "0.01", "--format", "json",
                                   "--region-samples", "4096", "--population-size", "20", "--generations", "10",
                                   "--n-starts", "2"])
    assert inverted.exit_code == 0, inverted.output
    cli = json.loads(inverted.stdout)
    assert cli["settings"] == study["settings"]
    for part in ("inversion", "region", "rvc"):
        a, b = dict(cli[part]), dict(study[part])
        for d in (a, b):
            d.pop("seconds", None)
        assert a == b, part
    assert cli["posterior"] is None and study["posterior"] is None


def test_a_study_run_reads_each_measurement_and_surrogate_once(tmp_path, monkeypatch):
    """One ``podkrig run`` parses the measurement log once and loads the surrogate once, though the
    measurement check, the range checks, the calibration and the sensitivity all use them."""
    from podkrig.study import stages

    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    clean = sc.run({"E_b": 11000.0, "r_hj": 0.6, "kN_bj": 90.0, "kV_bj": 35.0}).readings
    write_measurement_csv(tmp_path / "measured.csv", Measurement(clean, sc.sensor_names, sc.load_levels))
    (tmp_path / "study.toml").write_text(STUDY.replace("range_check = false", "range_check = true")
                                         .replace("enabled = false", "enabled = true\nn = 256"))
    calls = {"read": 0, "load": 0}
    read, load = stages.read_measurement, stages.load_surrogate

    def counted_read(*args, **kwargs):
        calls["read"] += 1
        return read(*args, **kwargs)

    def counted_load(path):
        calls["load"] += 1
        return load(path)

    monkeypatch.setattr(stages, "read_measurement", counted_read)
    monkeypatch.setattr(stages, "load_surrogate", counted_load)
    ran = CliRunner().invoke(app, ["run", str(tmp_path / "study.toml"), "--out", str(tmp_path / "out")])
    assert ran.exit_code == 0, ran.output
    assert calls == {"read": 1, "load": 1}
