"""Joint calibration over several tests (issue 19, item 3) on linear models with a closed-form
answer: the joint optimum is the weighted least-squares solution of the stacked data, and its
region of equivalence is the χ² ellipsoid of the stacked Fisher information — narrower than either
test's region for a parameter both inform."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import stats

from podkrig.online.invert import InverseResult, invert
from podkrig.online.joint import JointProblem
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.problem import InverseProblem
from podkrig.online.region import likelihood_ratio_region, noise_monte_carlo_region
from podkrig.parameters import Parameter, ParameterSpace

S = Parameter("s", 0.0, 2.0, "linear", "MPa")
T = Parameter("t", 0.0, 2.0, "linear", "MPa")
E = Parameter("e", 0.5, 1.0, "linear", "-")  # the jack test's own (nuisance) parameter
TRUTH = {"s": 1.1, "t": 0.7, "e": 0.8}
SIGMA = 0.01  # mm


class LinearModel:
    """Readings ``G @ m`` at 2 load levels × n sensors (mm), no predictive variance."""

    load_levels = np.array([1.0, 2.0])
    load_unit = "kN"

    def __init__(self, params, G):
        self.space = ParameterSpace(tuple(params))
        self.G = np.asarray(G, dtype=float)  # (n_loads * n_sensors, n_params)
        self.sensor_names = tuple(f"g{j}" for j in range(len(self.G) // 2))

    def predict(self, X, return_std=False):
        Y = np.atleast_2d(X) @ self.G.T
        return (Y, None) if return_std else Y


# the wall test informs s strongly and t weakly; the jack test the other way round, with e
WALL = LinearModel((S, T), [[1.0, 0.1], [0.8, 0.05], [0.5, 0.2], [2.0, 0.2], [1.6, 0.1], [1.0, 0.4]])
JACK = LinearModel((S, T, E), [[0.1, 1.0, 0.3], [0.2, 0.7, -0.5], [0.05, 1.2, 0.4], [0.2, 2.0, 0.6], [0.4, 1.4, -1.0],
                                [0.1, 2.4, 0.8]])


def data(model, rng):
    m = np.array([TRUTH[n] for n in model.space.names])
    y = model.G @ m + SIGMA * rng.standard_normal(len(model.G))
    return Measurement(y.reshape(2, -1), model.sensor_names, model.load_levels, source=f"{len(y)} readings")


def problems(seed=0):
    rng = np.random.default_rng(seed)
    noise = NoiseModel(sigma=SIGMA)
    wall = InverseProblem(WALL, data(WALL, rng), noise)
    jack = InverseProblem(JACK, data(JACK, rng), noise)
    return wall, jack


def stacked(wall, jack):
    """The stacked linear system over (s, t, e), whitened: J (n_obs, 3), d (n_obs,)."""
    J = np.zeros((wall.n_obs + jack.n_obs, 3))
    J[: wall.n_obs, :2] = WALL.G
    J[wall.n_obs:] = JACK.G
    d = np.concatenate([wall.measurement.data, jack.measurement.data])
    return J / SIGMA, d / SIGMA


def test_the_joint_optimum_is_the_weighted_least_squares_solution_of_the_stacked_data():
    wall, jack = problems()
    joint = JointProblem({"wall": wall, "jack": jack})
    assert joint.free == ("s", "t", "e") and joint.n_obs == 6 + 6
    J, d = stacked(wall, jack)
    x_ls = np.linalg.lstsq(J, d, rcond=None)[0]
    result = invert(joint, rng=1, population_size=40, generations=30)
    # the polish stops at least-squares tolerances (1e-8 on the cost): 1e-5 relative on x
    assert_allclose(result.x, x_ls, rtol=1e-5)
    r = J @ x_ls - d
    assert result.chi2 == pytest.approx(r @ r, rel=1e-8)
    assert result.dof == 12 - 3
    # each test's view: its own parameters, χ² over its own readings, dof = its readings − its free parameters
    assert set(result.tests) == {"wall", "jack"}
    wall_view, jack_view = result.tests["wall"], result.tests["jack"]
    assert_allclose(wall_view.x, x_ls[:2], rtol=1e-12)
    assert wall_view.dof == 6 - 2 and jack_view.dof == 6 - 3
    assert wall_view.chi2 + jack_view.chi2 == pytest.approx(result.chi2, rel=1e-12)
    assert wall_view.chi2 == pytest.approx(r[:6] @ r[:6], rel=1e-8)


def test_the_joint_region_is_the_stacked_ellipsoid_and_narrower_than_each_test_alone():
    wall, jack = problems()
    joint = JointProblem({"wall": wall, "jack": jack})
    J, d = stacked(wall, jack)
    x_ls = np.linalg.lstsq(J, d, rcond=None)[0]
    region = likelihood_ratio_region(joint, x_ls, confidence=0.95, n_samples=2**16, rng=0)
    # closed form: the projection of {Δω ≤ ½ χ²_3(0.95)} on axis j is x_j ± sqrt(χ²_3 · Cov_jj);
    # sampled members fall short of the ellipsoid's tips by a few per cent at 2^16 points in 3-D
    half = np.sqrt(stats.chi2.ppf(0.95, 3) * np.diag(np.linalg.inv(J.T @ J)))
    for j, name in enumerate(joint.free):
        lo, hi = region.intervals[name]
        assert hi - lo == pytest.approx(2 * half[j], rel=0.05), name
        assert lo <= x_ls[j] <= hi
    width = {name: hi - lo for name, (lo, hi) in region.intervals.items()}
    for alone in (wall, jack):
        single = invert(alone, rng=1, population_size=30, generations=20)
        r1 = likelihood_ratio_region(alone, single.x, confidence=0.95, n_samples=2**15, rng=0)
        for name in ("s", "t"):  # informed by both tests
            lo, hi = r1.intervals[name]
            assert width[name] < hi - lo, (name, alone.measurement.source)


def test_noise_monte_carlo_region_of_a_joint_problem_matches_the_linear_covariance():
    wall, jack = problems(3)
    joint = JointProblem({"wall": wall, "jack": jack})
    J, d = stacked(wall, jack)
    x_ls = np.linalg.lstsq(J, d, rcond=None)[0]
    region = noise_monte_carlo_region(joint, x_ls, n_realisations=400, confidence=0.95, rng=5)
    sd = np.sqrt(np.diag(np.linalg.inv(J.T @ J)))
    # re-identified values scatter with the linear covariance; 400 copies give the std within ~±7 %
    # (1.96 standard errors of a sample std at n = 400 ≈ 7 %): 10 % on the 95 % width
    for j, name in enumerate(joint.free):
        lo, hi = region.intervals[name]
        assert hi - lo == pytest.approx(2 * 1.96 * sd[j], rel=0.10), name


def test_a_shared_parameter_with_two_search_ranges_is_refused_naming_both_tests():
    wall, _ = problems()
    other = LinearModel((Parameter("s", 0.0, 3.0, "linear", "MPa"), T), WALL.G)
    rng = np.random.default_rng(0)
    twin = InverseProblem(other, data(other, rng), NoiseModel(sigma=SIGMA))
    with pytest.raises(ValueError, match=r"shared parameter s .*\[0, 2\] MPa .*'wall'.*\[0, 3\] MPa .*'twin'"):
        JointProblem({"wall": wall, "twin": twin})


def test_joint_result_round_trips_with_its_tests():
    wall, jack = problems()
    result = invert(JointProblem({"wall": wall, "jack": jack}), rng=1, population_size=20, generations=10)
    d = result.to_dict()
    assert set(d["tests"]) == {"wall", "jack"} and d["measurement"]["n_obs"] == 12
    back = InverseResult.from_dict(d)
    assert back.tests["jack"].chi2_dof == pytest.approx(result.tests["jack"].chi2_dof)
    assert back.tests["wall"].free == ("s", "t") and back.free == ("s", "t", "e")
    with pytest.raises(ValueError, match="per test"):
        result.predicted()
    assert result.tests["wall"].predicted()[0].shape == (2, 3)
