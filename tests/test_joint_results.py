"""What a joint calibration (:class:`podkrig.online.joint.JointProblem`) gives its users, checked on
small linear models with closed forms (issue 12, mutation testing of online/joint.py): the summed
misfit evaluated at each test's own columns, the counts, the frozen model error, the noisy copies,
each test's view, the parameter table and the data summary, and the refusal of a shared parameter
with two search ranges naming both tests and both ranges."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig.online.joint import JointProblem
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.problem import InverseProblem
from podkrig.parameters import Parameter, ParameterSpace

SIGMA = 0.01  # mm
S = Parameter("s", 0.0, 2.0, "linear", "MPa")
T = Parameter("t", 0.0, 2.0, "linear", "MPa")
E = Parameter("e", 0.5, 1.0, "linear", "-")
K = Parameter("k", 0.0, 1.0, "linear", "-")
H = Parameter("h", 0.0, 1.0, "linear", "-")


class LinearModel:
    """Readings ``G @ m`` (mm) at 2 load levels × n sensors, over the parameters ``params`` in that
    order; with ``std_slope`` a predictive std ``0.002 (1 + std_slope · m_0)`` on every reading."""

    load_levels = np.array([1.0, 2.0])
    load_unit = "kN"

    def __init__(self, params, G, std_slope=None):
        self.space = ParameterSpace(tuple(params))
        self.G = np.asarray(G, dtype=float)
        self.sensor_names = tuple(f"g{j}" for j in range(len(self.G) // 2))
        self.std_slope = std_slope

    def predict(self, X, return_std=False):
        X = np.atleast_2d(X)
        Y = X @ self.G.T
        if not return_std:
            return Y
        if self.std_slope is None:
            return Y, None
        return Y, 0.002 * (1.0 + self.std_slope * X[:, :1]) * np.ones_like(Y)


def _measurement(model, m, source, shift=0.0):
    """Readings of ``model`` at ``m`` plus a fixed pattern ``shift`` (so the optimum is not exact)."""
    y = model.G @ np.asarray(m, dtype=float) + shift * np.cos(np.arange(len(model.G)))
    return Measurement(y.reshape(2, -1), model.sensor_names, model.load_levels, source=source)


# the wall test over (s, t); the jack test over (t, e, s): the shared parameters appear in another order
WALL_G = [[1.0, 0.1], [0.8, 0.05], [0.5, 0.2], [2.0, 0.2], [1.6, 0.1], [1.0, 0.4]]
JACK_G = [[1.0, 0.3, 0.1], [0.7, -0.5, 0.2], [1.2, 0.4, 0.05], [2.0, 0.6, 0.2]]


def _tests(std_slope=None, model_error=True):
    wall_model = LinearModel((S, T), WALL_G, std_slope)
    jack_model = LinearModel((T, E, S), JACK_G, std_slope)
    wall = InverseProblem(wall_model, _measurement(wall_model, [1.1, 0.7], "wall.csv", 0.02), NoiseModel(sigma=SIGMA),
                          model_error=model_error)
    jack = InverseProblem(jack_model, _measurement(jack_model, [0.7, 0.8, 1.1], "jack.csv", -0.03),
                          NoiseModel(sigma=SIGMA), model_error=model_error)
    return wall, jack


def test_joint_misfit_is_the_sum_over_the_tests_at_their_own_parameters():
    """ω, ω on the unit cube, χ² and the stacked residuals of a joint problem are the sums (the
    concatenation) of the tests' own, each test given its parameters in its own order: the jack test
    reads (t, e, s) out of the joint vector (s, t, e). Guards against columns taken in the joint
    order, a test left out of a sum, and a single point (1-D input) not accepted. χ² is also the
    closed form |G m − d|²/σ² summed over both tests. Tolerance 1e-12 relative: the same floating
    point operations up to summation order."""
    wall, jack = _tests()
    joint = JointProblem({"wall": wall, "jack": jack})
    assert joint.free == ("s", "t", "e") and joint.n_free == 3
    assert joint.columns["wall"].tolist() == [0, 1] and joint.columns["jack"].tolist() == [1, 2, 0]
    assert joint.free_space.names == ("s", "t", "e")
    assert joint.n_obs == 6 + 4 and joint.n_removed == 0
    X = np.array([[1.0, 0.5, 0.6], [1.3, 0.9, 0.95], [0.2, 1.7, 0.7]])
    omega = wall.omega(X[:, :2]) + jack.omega(X[:, [1, 2, 0]])
    assert_allclose(joint.omega(X), omega, rtol=1e-12)
    assert_allclose(joint.omega(X[1]), omega[1:2], rtol=1e-12)  # one point as a 1-D vector
    U = joint.free_space.to_unit(X)
    assert_allclose(joint.omega_unit(U), omega, rtol=1e-12)
    chi2 = [np.sum((np.array(WALL_G) @ x[:2] - wall.measurement.data) ** 2)
            + np.sum((np.array(JACK_G) @ x[[1, 2, 0]] - jack.measurement.data) ** 2) for x in X]
    assert_allclose(joint.chi2(X), np.array(chi2) / SIGMA**2, rtol=1e-12)
    stacked = joint._residuals_batch(U)
    assert stacked.shape == (3, 10)
    assert_allclose(stacked, np.hstack([wall._residuals_batch(U[:, :2]), jack._residuals_batch(U[:, [1, 2, 0]])]),
                    rtol=1e-12)
    assert_allclose(0.5 * np.sum(stacked**2, axis=1), omega, rtol=1e-12)  # ω = ½ |r|² without prior


def test_the_problems_are_copied_and_kept_in_report_order():
    """The joint problem keeps its own copy of the tests (a frozen problem: adding a test to the
    caller's dict afterwards does not change it) in the order given (the report order)."""
    wall, jack = _tests()
    tests = {"jack": jack, "wall": wall}
    joint = JointProblem(tests)
    tests["again"] = wall
    assert list(joint.problems) == ["jack", "wall"] and joint.n_obs == 10
    assert joint.free == ("t", "e", "s")  # first appearance: the jack test's order


def test_model_error_and_the_frozen_std_of_every_test():
    """A joint problem adds the predictive variance when any test does; freezing it freezes every
    test at its own parameters (the concatenated std equals each model's std there), leaves ω at the
    freezing point unchanged, and a joint problem is frozen only when every test is (else None, the
    std is evaluated afresh). The model std 0.002 (1 + 0.5 s) is exact in floating point to 1e-15."""
    wall, jack = _tests(std_slope=0.5)
    joint = JointProblem({"wall": wall, "jack": jack})
    assert joint.model_error and joint.frozen_model_std is None
    off_wall, off_jack = _tests(std_slope=0.5, model_error=False)
    assert not JointProblem({"wall": off_wall, "jack": off_jack}).model_error
    assert JointProblem({"wall": off_wall, "jack": jack}).model_error
    x = np.array([1.2, 0.4, 0.9])  # s, t, e
    frozen = joint.freeze_model_error(x)
    assert isinstance(frozen, JointProblem) and list(frozen.problems) == ["wall", "jack"]
    std = 0.002 * (1 + 0.5 * 1.2)  # each model's std follows its first parameter: the wall's s = 1.2
    assert_allclose(frozen.problems["wall"].frozen_model_std, np.full(6, std), rtol=1e-15)
    jack_std = 0.002 * (1 + 0.5 * 0.4)  # the jack's t = 0.4
    assert_allclose(frozen.problems["jack"].frozen_model_std, np.full(4, jack_std), rtol=1e-15)
    assert_allclose(frozen.frozen_model_std, np.r_[np.full(6, std), np.full(4, jack_std)], rtol=1e-15)
    assert_allclose(frozen.omega(x), joint.omega(x), rtol=1e-12)
    y = np.array([0.3, 1.5, 0.6])
    assert frozen.omega(y)[0] != pytest.approx(joint.omega(y)[0], rel=1e-3)  # elsewhere the std differs
    half = JointProblem({"wall": frozen.problems["wall"], "jack": jack})
    assert half.frozen_model_std is None


def test_noisy_copies_are_each_tests_model_plus_independent_noise():
    """A noise Monte Carlo copy of a joint problem: every test's data replaced by its model at its
    own parameters plus its own N(0, σ² I) draw, drawn in report order from the one generator (so
    the same seed gives the same copy as the tests' own copies made in that order), the noise of the
    two tests different. Exact equality: the same arithmetic."""
    wall, jack = _tests()
    joint = JointProblem({"wall": wall, "jack": jack})
    x = np.array([1.0, 0.5, 0.6])
    copy = joint.with_noisy_data(x, np.random.default_rng(7))
    rng = np.random.default_rng(7)
    wall_copy = wall.with_noisy_data(x[:2], rng)
    jack_copy = jack.with_noisy_data(x[[1, 2, 0]], rng)
    assert isinstance(copy, JointProblem) and list(copy.problems) == ["wall", "jack"]
    assert_allclose(copy.problems["wall"].measurement.data, wall_copy.measurement.data, rtol=0, atol=0)
    assert_allclose(copy.problems["jack"].measurement.data, jack_copy.measurement.data, rtol=0, atol=0)
    noise_wall = copy.problems["wall"].measurement.data - np.array(WALL_G) @ x[:2]
    noise_jack = copy.problems["jack"].measurement.data - np.array(JACK_G) @ x[[1, 2, 0]]
    assert 0 < np.abs(noise_wall).max() < 5 * SIGMA and 0 < np.abs(noise_jack).max() < 5 * SIGMA
    assert not np.allclose(noise_wall[:4], noise_jack)
    assert copy.problems["jack"].measurement.source == "jack.csv (noisy copy)"


def test_each_tests_view_and_the_parameter_table():
    """``parts`` gives each test its problem and its values in its own order; ``parameters_at``
    lists the joint free values and the fixed values every test agrees on — not a value fixed in
    one test only, not one fixed at different values, and never a fixed value over a parameter
    free in another test (the joint value is the one used there)."""
    wall_model = LinearModel((S, T, K, H), [[1.0, 0.1, 0.2, 0.3]] * 4)
    jack_model = LinearModel((T, E, S, K, H), [[1.0, 0.3, 0.1, 0.2, 0.1]] * 4)
    noise = NoiseModel(sigma=SIGMA)
    wall = InverseProblem(wall_model, _measurement(wall_model, [1, 1, 0.5, 0.5], "w"), noise,
                          free=("s",), fixed={"t": 0.25, "k": 0.5, "h": 0.1})
    jack = InverseProblem(jack_model, _measurement(jack_model, [1, 0.7, 1, 0.5, 0.5], "j"), noise,
                          free=("t", "e", "s"), fixed={"k": 0.5, "h": 0.2})
    joint = JointProblem({"wall": wall, "jack": jack})
    assert joint.free == ("s", "t", "e")
    x = np.array([1.5, 0.75, 0.625])
    parts = joint.parts(x)
    assert list(parts) == ["wall", "jack"]
    assert parts["wall"][0] is wall and parts["jack"][0] is jack
    assert parts["wall"][1].tolist() == [1.5] and parts["jack"][1].tolist() == [0.75, 0.625, 1.5]
    table = joint.parameters_at(x)
    assert table == {"s": 1.5, "t": 0.75, "e": 0.625, "k": 0.5}
    assert all(type(v) is float for v in table.values())
    assert joint.parameters_at(x.tolist()) == table
    ints = joint.parameters_at([1, 0, 1])  # integer input: the table still holds floats, as written to reports
    assert ints == {"s": 1.0, "t": 0.0, "e": 1.0, "k": 0.5} and all(type(v) is float for v in ints.values())
    assert joint.parts([1, 0, 1])["jack"][1].dtype == np.float64  # each test's view: float, as for one test
    # one test alone: its own fixed values are agreed on by every test
    assert JointProblem({"wall": wall}).parameters_at([1.5]) == {"s": 1.5, "t": 0.25, "k": 0.5, "h": 0.1}


def test_the_data_summary_names_every_file_and_counts_all_readings():
    """The report's data summary: the files of all tests joined with "; ", the total number of
    readings, and each test's own summary under its name."""
    wall, jack = _tests()
    summary = JointProblem({"wall": wall, "jack": jack}).measurement_summary()
    assert summary["file"] == "wall.csv; jack.csv" and summary["n_obs"] == 10
    assert summary["tests"] == {"wall": wall.measurement_summary(), "jack": jack.measurement_summary()}
    assert summary["tests"]["jack"]["n_obs"] == 4


@pytest.mark.parametrize("other, shown", [
    (Parameter("s", 0.5, 2.0, "linear", "MPa"), "[0.5, 2] MPa (linear)"),
    (Parameter("s", 0.0, 3.0, "linear", "MPa"), "[0, 3] MPa (linear)"),
    (Parameter("s", 0.1, 2.0, "log", "MPa"), "[0.1, 2] MPa (log)"),
    (Parameter("s", 0.0, 2.0, "linear", "GPa"), "[0, 2] GPa (linear)"),
])
def test_a_shared_parameter_is_one_search_range(other, shown):
    """A parameter shared by two tests must have one search range: lower and upper bound, scale and
    unit are each compared, and the message names the parameter, both tests and both ranges, and
    what to do. An empty joint problem is refused too."""
    wall, _ = _tests()
    model = LinearModel((other, T), WALL_G)
    twin = InverseProblem(model, _measurement(model, [1.1, 0.7], "twin.csv"), NoiseModel(sigma=SIGMA))
    with pytest.raises(ValueError, match="shared parameter s ") as info:
        JointProblem({"wall": wall, "twin": twin})
    for fragment in ("[0, 2] MPa (linear) in test 'wall'", f"{shown} in test 'twin'", "same bounds and scale"):
        assert fragment in str(info.value)  # both ranges with their tests, and the remedy
    with pytest.raises(ValueError, match="needs at least one test"):
        JointProblem({})
