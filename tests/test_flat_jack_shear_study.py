"""The in-situ flat-jack studies: the flat-jack test with its shear phase
(``examples/flat_jack_shear.toml``: its elastic and shear logs as two tests of one wall, Km a
nuisance parameter) and its joint calibration with a diagonal compression test
(``examples/joint_diagonal_flat_jack.toml``: a linear and two nonlinear tests, Km the flat jack's
own). The study files load with the parameters each test shares, each log is read for its test
with the stated noise, the make script reproduces the logs, and the boxes keep the joints'
constraints."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fe.exceptions import ConstraintError
from fe.scenarios import SCENARIOS, build_scenario
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

