"""The in-situ flat-jack studies: the flat-jack test with its shear phase
(``examples/flat_jack_shear.toml``: its elastic and shear logs as two tests of one wall, Km a
nuisance parameter) and its joint calibration with a diagonal compression test
(``examples/joint_diagonal_flat_jack.toml``: a linear and two nonlinear tests, Km the flat jack's
own). The study files load with the parameters each test shares, each log is read for its test
with the stated noise, the make script reproduces the logs, the boxes keep the joints'
constraints, and (slow) the joint study's elastic part finds the hidden stiffness."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from typer.testing import CliRunner

from fe.exceptions import ConstraintError
from fe.scenarios import SCENARIOS, build_scenario
from podkrig.cli import app
from podkrig.study.schema import load_study
from podkrig.study.stages import read_study_measurement

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
IN_SITU = EXAMPLES / "flat_jack_shear.toml"
JOINT = EXAMPLES / "joint_diagonal_flat_jack.toml"
FLAT_JACK = ("kN_bj", "kV_bj", "r_hj", "c_bj", "tanphi_bj", "Km")


def _make_script():
    spec = importlib.util.spec_from_file_location("make_flat_jack_shear", EXAMPLES / "make_flat_jack_shear.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _read(test):
    sc = build_scenario(test.spec)
    return sc, *read_study_measurement(test, sc.sensor_names, sc.load_levels, sc.load_unit, sc.load_response,
                                       sc.sensor_units)


def test_the_in_situ_study_reads_the_elastic_steps_and_the_shear_phase_with_their_noise():
    """Two logs of one test sharing the six free parameters: the 18 gauges at steps 1–20, and the
    gauges with V1's gauge pressure and the repeat's at the 8 slip levels; σ² = σ_abs² + (0.01 d)²
    with σ_abs = 2 µm on the gauges and 0.01 MPa on the pressures (the make script's)."""
    make = _make_script()
    study = load_study(IN_SITU)
    assert [p.name for p in study.free_parameters] == list(FLAT_JACK)
    assert study.sensitivity.enabled
    elastic, shear = study.calibration_tests
    assert [p.name for p in elastic.space.parameters] == [p.name for p in shear.space.parameters] == list(FLAT_JACK)
    assert list(shear.spec.options["further_p_H"]) == make.FURTHER_P_H
    for test in (elastic, shear):
        assert test.spec.parameters["sigma0"] == 0.30 and test.spec.parameters["E_b"] == make.TRUTH["E_b"]
        sc, data, noise = _read(test)
        assert_allclose(data.load_levels, sc.load_levels, rtol=1e-12)
        units = np.array(data.sensor_units)
        sigma_abs = np.where(units == "MPa", 0.01, 0.002)
        expected = np.hypot(sigma_abs, make.NOISE_REL * np.abs(data.values)).ravel()
        assert_allclose(noise.std(data), expected, rtol=1e-12)
    assert data.sensor_names[-2:] == ("p_V1", "p_V1_repeat1") and data.sensor_units[-1] == "MPa"
    p_V1 = data.values[:, -2]
    assert 0 < np.argmax(p_V1) < len(p_V1) - 1  # the critical pressure, then the sliding branch


def test_the_joint_study_gives_km_and_the_strength_to_the_flat_jack_only():
    """The diagonal test (linear) has the four elastic parameters; the flat-jack logs (nonlinear)
    those and c_bj, tanphi_bj and the jacks' efficiency Km, one search range each."""
    study = load_study(JOINT)
    assert [p.name for p in study.free_parameters] == ["E_b", *FLAT_JACK]
    diagonal, elastic, shear = study.calibration_tests
    assert [p.name for p in diagonal.space.parameters] == ["E_b", "kN_bj", "kV_bj", "r_hj"]
    assert [p.name for p in elastic.space.parameters] == [p.name for p in shear.space.parameters] == ["E_b", *FLAT_JACK]
    assert "Km" not in diagonal.spec.parameters and shear.spec.parameters["sigma0"] == 0.30
    _, data, _ = _read(diagonal)
    assert data.values.shape == (4, 6)
    in_situ = {t.name: t for t in load_study(IN_SITU).calibration_tests}
    for test, same in ((elastic, "elastic"), (shear, "shear")):  # the same logs, the same fixed values
        assert test.measurement.file == in_situ[same].measurement.file
        assert test.spec.parameters == {k: v for k, v in in_situ[same].spec.parameters.items() if k != "E_b"}


def test_the_make_script_reproduces_the_shipped_logs(tmp_path):
    """Same truth, seeds and solver: the shipped files to the 8 digits written (rtol 1e-6 leaves room
    for solver round-off across machines; the noise is ≥ 1 % of every reading)."""
    make = _make_script()
    for made in make.make(tmp_path):
        shipped = EXAMPLES / made.name
        assert made.read_text().splitlines()[0] == shipped.read_text().splitlines()[0]
        a, b = (np.loadtxt(f, delimiter=",", skiprows=1) for f in (made, shipped))
        assert_allclose(a, b, rtol=1e-6, atol=1e-9, err_msg=made.name)


@pytest.mark.parametrize("study", [IN_SITU, JOINT], ids=["in_situ", "joint"])
def test_the_box_keeps_the_joints_constraints_and_a_wider_cohesion_breaks_one(study):
    """Every constraint of the nonlinear joints holds over each test's box (no snapshot can fail on
    one); the cohesion's upper bound is not arbitrary: at c_bj = 0.7 MPa the head joints' shear
    softening would be steeper than their elastic branch (c² / G_f^II < r_hj·kV_bj fails at r_hj =
    0.3, kV_bj = 12 N/mm³)."""
    for test in load_study(study).calibration_tests:
        cls = SCENARIOS[test.spec.scenario]
        bounds = {p.name: (p.lower, p.upper, p.scale) for p in test.space.parameters}
        cls.check_spec_box(test.spec, bounds)
        if "c_bj" in bounds:
            with pytest.raises(ConstraintError, match="c_bj"):
                cls.check_spec_box(test.spec, {**bounds, "c_bj": (0.15, 0.7, "linear")})



@pytest.mark.slow
def test_the_diagonal_test_and_the_flat_jacks_elastic_log_find_the_hidden_stiffness(tmp_path):
    """The joint study reduced to its elastic part — the diagonal test (linear) and the flat jack's
    elastic log (nonlinear) with c_bj and tanphi_bj fixed at the truth; 48 + 8 runs each, about 1 min
    of CPU: a linear and a nonlinear test join end to end (snapshots, surrogates, one inversion, one
    region, the sensitivity), the make script's truth lies in the 95 % region of every parameter, and
    the data pin down E_b, kN_bj, kV_bj and Km (measured: Km in [0.810, 0.828]) but not r_hj."""
    truth = _make_script().TRUTH
    study = tmp_path / "elastic_part.toml"
    study.write_text(f"""name = "elastic_part"
[parameters]
E_b   = {{ lower = 5000.0, upper = 16000.0 }}
kN_bj = {{ lower = 30.0, upper = 300.0, scale = "log" }}
kV_bj = {{ lower = 12.0, upper = 120.0, scale = "log" }}
r_hj  = {{ lower = 0.3, upper = 1.0 }}
Km    = {{ lower = 0.75, upper = 0.95 }}
[fixed]
nu_b = 0.15
[sampling]
train    = {{ n = 48, seed = 0 }}
held_out = {{ n = 8, seed = 1, method = "random" }}
[inversion]
seed = 0
[sensitivity]
enabled = true
n = 256
[[test]]
name = "diagonal"
scenario = {{ scenario = "diagonal_compression", nx = 6, ny = 2 }}
measurement = {{ file = "{EXAMPLES / 'joint_diagonal_flat_jack_diagonal.csv'}", instrument = "lvdt" }}
[[test]]
name = "flat_jack_elastic"
scenario = {{ scenario = "flat_jack_elastic_nl", p_H = 0.6 }}
measurement = {{ file = "{EXAMPLES / 'flat_jack_shear_elastic.csv'}", noise_abs = 0.002, noise_rel = 0.01 }}
fixed = {{ sigma0 = 0.30, ft_bj = 0.15, GfI_bj = 0.012, GfII_bj = 0.10, tanphir_bj = 0.70, c_bj = {truth['c_bj']}, tanphi_bj = {truth['tanphi_bj']} }}
""")
    result = CliRunner().invoke(app, ["run", str(study), "--out", str(tmp_path / "out"), "--yes"])
    assert result.exit_code == 0, result.output[-3000:]
    region = json.loads((tmp_path / "out" / "summary.json").read_text())["stages"]["calibration"]["region"]
    for name in ("E_b", "kN_bj", "kV_bj", "r_hj", "Km"):
        lo, hi = region["intervals"][name]
        assert lo <= truth[name] <= hi, (name, lo, hi)
    found = {name: v["identifiable"] for name, v in region["identifiability"].items()}
    assert found == {"E_b": True, "kN_bj": True, "kV_bj": True, "Km": True, "r_hj": False}
