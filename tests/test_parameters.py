"""Parameter spaces: validation, unit-cube maps (linear and log), scenario limits, CLI parsing."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from podkrig.parameters import Parameter, ParameterSpace, parse_param, parse_params


@pytest.fixture(scope="module")
def scenario(coarse_diagonal):
    return coarse_diagonal


@pytest.fixture
def space():
    return ParameterSpace((
        Parameter("E_b", 5000.0, 20000.0, unit="MPa"),
        Parameter("kN_bj", 10.0, 1000.0, scale="log", unit="N/mm³"),
        Parameter("r_hj", 0.0, 1.0),
    ))


def test_attributes(space):
    assert space.names == ("E_b", "kN_bj", "r_hj")
    assert space.units == ("MPa", "N/mm³", "-")
    assert space.scales == ("linear", "log", "linear")
    assert_array_equal(space.lower, [5000.0, 10.0, 0.0])
    assert_array_equal(space.upper, [20000.0, 1000.0, 1.0])
    assert len(space) == space.n_params == 3


def test_log_scale_maps_decades_evenly(space):
    X = space.from_unit([[0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [1.0, 1.0, 1.0]])
    # the log midpoint of 10..1000 is the geometric mean, 100
    assert_allclose(X[:, 1], [10.0, 100.0, 1000.0], rtol=1e-14, atol=0)
    assert X[0, 1] == 10.0 and X[2, 1] == 1000.0  # ends exact, not 10**log10(b)
    assert_allclose(X[:, 0], [5000.0, 12500.0, 20000.0], rtol=1e-15, atol=0)


def test_round_trip(space):
    U = np.random.default_rng(0).random((200, 3))
    X = space.from_unit(U)
    assert_allclose(space.to_unit(X), U, rtol=0, atol=1e-14)
    assert_allclose(space.from_unit(space.to_unit(X)), X, rtol=1e-13, atol=1e-15)
    assert space.from_unit(U[0]).shape == (3,)  # one sample as a vector


def test_shape_and_log_domain_errors(space):
    with pytest.raises(ValueError, match=r"shape \(n_samples, 3\).*got shape \(4, 2\)"):
        space.to_unit(np.ones((4, 2)))
    with pytest.raises(ValueError, match="'kN_bj' .*> 0; got -1"):
        space.to_unit([[6000.0, -1.0, 0.5]])


@pytest.mark.parametrize(
    "args, kwargs, message",
    [
        (("E_b", 2.0, 1.0), {}, r"'E_b' .*lower < upper; got \(2, 1\)"),
        (("E_b", 1.0, 1.0), {}, "lower < upper"),
        (("kN_bj", 0.0, 10.0), {"scale": "log"}, r"'kN_bj' .*> 0; got \(0, 10\)"),
        (("E_b", 1.0, 2.0), {"scale": "ln"}, r"scale of 'E_b' .*\('linear', 'log'\); got 'ln'"),
        (("E_b", 1.0, float("inf")), {}, "upper bound of 'E_b' .*finite"),
        (("", 1.0, 2.0), {}, "non-empty string"),
    ],
)
def test_parameter_validation(args, kwargs, message):
    with pytest.raises(ValueError, match=message):
        Parameter(*args, **kwargs)


def test_space_validation():
    with pytest.raises(ValueError, match="at least one parameter"):
        ParameterSpace(())
    with pytest.raises(ValueError, match=r"\['E_b'\] given more than once"):
        ParameterSpace((Parameter("E_b", 1, 2), Parameter("E_b", 3, 4)))


def test_dict_round_trip(space):
    import json

    d = json.loads(json.dumps(space.to_dict()))
    assert ParameterSpace.from_dict(d) == space
    with pytest.raises(ValueError, match="unknown keys \\['bound'\\]"):
        ParameterSpace.from_dict({"parameters": [{"name": "E_b", "lower": 1, "upper": 2, "bound": 3}]})


def test_from_scenario_takes_units_and_order(scenario):
    space = ParameterSpace.from_scenario(scenario, {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000)})
    assert space.names == ("kN_bj", "E_b")
    assert space.units == ("N/mm³", "MPa")
    assert space.scales == ("log", "linear")


@pytest.mark.parametrize(
    "bounds, message",
    [
        ({"kN_bx": (10, 100)}, r"'kN_bx' .*'diagonal_compression'; known: \["),
        ({"nu_b": (0.1, 0.6)}, r"upper bound of 'nu_b' = 0.6 .*physical range \[0, 0.5\)"),
        ({"kN_bj": (0, 100)}, r"'kN_bj' = 0 N/mm³ .*\(0, 1e\+09\]"),
        ({"kN_bj": (100, 10, "log")}, r"'kN_bj' .*lower < upper"),
        ({"kN_bj": (10,)}, r"'kN_bj' .*\(lower, upper\)"),
        ({}, "no free parameters"),
    ],
)
def test_from_scenario_errors(scenario, bounds, message):
    with pytest.raises(ValueError, match=message):
        ParameterSpace.from_scenario(scenario, bounds)


def test_parse_param():
    assert parse_param("kN_bj=10:1000:log") == ("kN_bj", (10.0, 1000.0, "log"))
    assert parse_param(" E_b = 5e3:2e4") == ("E_b", (5000.0, 20000.0, "linear"))


@pytest.mark.parametrize(
    "text, message",
    [
        ("kN_bj", r"--param 'kN_bj': expected NAME=LOW:HIGH"),
        ("kN_bj=10", r"--param 'kN_bj=10': expected NAME=LOW:HIGH"),
        ("=1:2", r"--param '=1:2': expected NAME=LOW:HIGH"),
        ("kN_bj=ten:100", r"--param 'kN_bj=ten:100': LOW 'ten'"),
        ("kN_bj=10:1e3x", r"--param 'kN_bj=10:1e3x': HIGH '1e3x'"),
        ("kN_bj=10:100:lg", r"--param 'kN_bj=10:100:lg': scale 'lg'"),
        ("kN_bj=10:100:log:2", r"--param 'kN_bj=10:100:log:2': expected"),
        ("kN_bj=nan:100", r"--param 'kN_bj=nan:100': LOW must be finite"),
    ],
)
def test_parse_param_errors(text, message):
    with pytest.raises(ValueError, match=message):
        parse_param(text)


def test_parse_params():
    assert parse_params(["E_b=1:2", "kN_bj=1:2:log"]) == {"E_b": (1.0, 2.0, "linear"), "kN_bj": (1.0, 2.0, "log")}
    with pytest.raises(ValueError, match="'E_b' is given more than once"):
        parse_params(["E_b=1:2", "E_b=3:4"])
    with pytest.raises(ValueError, match="no free parameters"):
        parse_params([])


def test_as_params(space):
    assert space.as_params([6000.0, 50.0, 0.5]) == {"E_b": 6000.0, "kN_bj": 50.0, "r_hj": 0.5}


def test_ga_duck_typing(space):
    """The GA takes a space through names, to_unit, from_unit and units."""
    from podkrig.ga import minimize

    target = np.array([8000.0, 200.0, 0.3])
    result = minimize(lambda X: np.sum((space.to_unit(X) - space.to_unit(target)) ** 2, axis=1), space, rng=1)
    assert result.parameter_names == space.names
    assert result.parameter_units == space.units
