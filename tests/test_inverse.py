"""Inversion machinery (GA + polish, region of equivalence, RVC, nested analyses, MCMC) on an
analytic model with a known truth; the FE + surrogate hidden-truth tests are in
test_inverse_hidden_truth.py."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig.online.invert import invert
from podkrig.online.problem import InverseProblem
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.online.nested import information_criteria, nested_analyses
from podkrig.online.propagation import rvc
from podkrig.online.region import likelihood_ratio_region, noise_monte_carlo_region
from podkrig.reports.findings import identifiability_text

TRUTH = {"k": 12.0, "b": 0.4, "c": 0.5}


class AnalyticModel:
    """Readings of 4 sensors at 3 load levels; ``c`` has a negligible effect (unidentifiable)."""

    space = ParameterSpace((Parameter("k", 1.0, 100.0, "log", "N/mm³"), Parameter("b", 0.0, 1.0), Parameter("c", 0.0, 1.0)))
    sensor_names = ("s1", "s2", "s3", "s4")
    load_levels = np.array([10.0, 20.0, 30.0])
    W = np.array([[1.0, 0.2, 0.0], [0.3, 1.0, 0.2], [0.5, -0.4, 0.3], [0.1, 0.1, 1.0]])

    def __init__(self, std=0.0):
        self.std = std

    def predict(self, X, return_std=False):
        k, b, c = np.atleast_2d(X).T
        features = np.column_stack([10.0 / k, b, b / k * 10 + 1e-7 * c])  # (n, 3)
        per_sensor = features @ self.W.T  # (n, 4)
        Y = (self.load_levels[None, :, None] / 10.0 * per_sensor[:, None, :]).reshape(len(k), -1)
        return (Y, np.full_like(Y, self.std)) if return_std else Y


def measured(model, sigma, rng):
    clean = model.predict(np.array([[TRUTH["k"], TRUTH["b"], TRUTH["c"]]]))[0]
    noisy = clean + sigma * np.random.default_rng(rng).standard_normal(clean.shape)
    return Measurement(noisy.reshape(3, 4), model.sensor_names, model.load_levels, source="pseudo")


def test_noise_free_inversion_recovers_the_truth():
    model = AnalyticModel()
    problem = InverseProblem(model, measured(model, 0.0, 0), NoiseModel(sigma=0.01), free=("k", "b"), fixed={"c": 0.5})
    result = invert(problem, rng=1)
    assert_allclose(result.x, [TRUTH["k"], TRUTH["b"]], rtol=1e-6)
    assert result.chi2 < 1e-8 and result.dof == 10
    assert result.parameters == pytest.approx({"k": TRUTH["k"], "b": TRUTH["b"], "c": 0.5}, rel=1e-6)


class UnitCubeModel(AnalyticModel):
    """The analytic model with a unit-cube entry point, as the surrogate has; counts the rows
    each entry point evaluates."""

    def __init__(self):
        super().__init__()
        self.rows = {"physical": 0, "unit": 0}

    def predict(self, X, return_std=False):
        self.rows["physical"] += len(np.atleast_2d(X))
        return super().predict(X, return_std)

    def predict_unit(self, U, return_std=False):
        self.rows["unit"] += len(U)
        return super().predict(self.space.from_unit(U), return_std)


@pytest.mark.parametrize("free, fixed", [(("k", "b"), {"c": 0.5}), (("b", "c"), {"k": 12.0})])
def test_unit_cube_path_skips_physical_units_and_equals_the_physical_misfit(free, fixed):
    model = UnitCubeModel()
    problem = InverseProblem(model, measured(model, 0.01, 3), NoiseModel(sigma=0.01), free=free, fixed=fixed)
    U = np.random.default_rng(0).random((50, 2))
    # the same misfit through either path (a fixed log-scale k is scaled once, at construction)
    assert_allclose(problem.omega_unit(U), problem.omega(problem.free_space.from_unit(U)), rtol=1e-12)
    model.rows.update(physical=0, unit=0)
    invert(problem, rng=1, population_size=30, generations=20)
    # the GA and the polish run in the unit cube; only the reported optimum goes through physical units
    assert model.rows["unit"] > 100 and model.rows["physical"] <= 5, model.rows
    with_prior = InverseProblem(model, problem.measurement, problem.noise, free=free, fixed=fixed,
                                prior_mean=np.array([0.5, 0.5]), prior_cov=np.eye(2))
    model.rows.update(physical=0, unit=0)
    with_prior.omega_unit(U)  # the prior is over physical values: the physical path
    assert model.rows == {"physical": 50, "unit": 0}


def test_problem_validation_messages():
    model = AnalyticModel()
    meas = measured(model, 0.0, 0)
    with pytest.raises(ValueError, match=r"\['c'\] are neither free nor fixed"):
        InverseProblem(model, meas, NoiseModel(sigma=0.01), free=("k", "b"))
    with pytest.raises(ValueError, match=r"unknown parameter\(s\) \['E_b'\]"):
        InverseProblem(model, meas, NoiseModel(sigma=0.01), free=("E_b",))
    with pytest.raises(ValueError, match=r"fixed value c = 2 .*trained range \[0, 1\]"):
        InverseProblem(model, meas, NoiseModel(sigma=0.01), free=("k", "b"), fixed={"c": 2.0})


@pytest.mark.slow
def test_region_of_equivalence_covers_the_truth_at_its_nominal_rate():
    """40 noise realisations, 1 % noise: the truth lies in the 95 % likelihood-ratio region in
    ≥ 90 % of them (binomial: P(≤ 35/40 | p = 0.95) ≈ 5 %)."""
    model = AnalyticModel()
    sigma = 0.01 * 1.5  # ≈ 1 % of the largest reading
    inside = 0
    for seed in range(40):
        problem = InverseProblem(model, measured(model, sigma, seed), NoiseModel(sigma=sigma), free=("k", "b"), fixed={"c": 0.5})
        result = invert(problem, rng=seed, generations=40)
        region = likelihood_ratio_region(problem, result.x, n_samples=2**14, rng=seed)
        inside += problem.omega(np.array([[TRUTH["k"], TRUTH["b"]]]))[0] <= region.threshold
        lo, hi = region.intervals["k"]
        assert lo <= result.x[0] <= hi
    assert inside >= 36


def test_unidentifiable_parameter_is_flagged_and_identifiable_ones_are_not():
    model = AnalyticModel()
    sigma = 0.015
    problem = InverseProblem(model, measured(model, sigma, 3), NoiseModel(sigma=sigma))
    result = invert(problem, rng=3)
    region = likelihood_ratio_region(problem, result.x, rng=3)
    assert len(region.samples) > 1000 and region.n_evaluated >= 2**17
    verdict = region.identifiability
    assert verdict["k"]["identifiable"] and verdict["b"]["identifiable"]
    assert not verdict["c"]["identifiable"]
    assert "c is NOT pinned down" in identifiability_text("c", region.intervals["c"], "-", verdict["c"])
    lo, hi = region.intervals["k"]
    assert lo <= TRUTH["k"] <= hi


def test_noise_monte_carlo_region_agrees_with_likelihood_ratio():
    model = AnalyticModel()
    sigma = 0.015
    problem = InverseProblem(model, measured(model, sigma, 5), NoiseModel(sigma=sigma), free=("k", "b"), fixed={"c": 0.5})
    result = invert(problem, rng=5)
    lr = likelihood_ratio_region(problem, result.x, rng=5)
    mc = noise_monte_carlo_region(problem, result.x, n_realisations=200, rng=5)
    for name in ("k", "b"):
        w_lr = np.diff(lr.intervals[name])[0]
        w_mc = np.diff(mc.intervals[name])[0]
        # the joint-region projection (χ²₂) is wider than the marginal percentile interval (χ²₁):
        # for a near-linear model the ratio is sqrt(5.99/3.84) ≈ 1.25; allow sampling scatter
        assert 0.9 < w_lr / w_mc < 1.8


def test_surrogate_variance_widens_the_region():
    sigma = 0.015
    narrow = InverseProblem(AnalyticModel(0.0), measured(AnalyticModel(), sigma, 2), NoiseModel(sigma=sigma), free=("k", "b"), fixed={"c": 0.5})
    wide = InverseProblem(AnalyticModel(0.02), measured(AnalyticModel(), sigma, 2), NoiseModel(sigma=sigma), free=("k", "b"), fixed={"c": 0.5})
    x = invert(narrow, rng=0).x
    w_narrow = np.diff(likelihood_ratio_region(narrow, x).intervals["b"])[0]
    w_wide = np.diff(likelihood_ratio_region(wide, x).intervals["b"])[0]
    # C_D = σ² + σ_T²: the region scales by sqrt((σ² + σ_T²)/σ²) = 1.67 for a near-linear model
    assert_allclose(w_wide / w_narrow, np.sqrt((sigma**2 + 0.02**2) / sigma**2), rtol=0.15)


def test_rvc_and_information_criteria():
    model = AnalyticModel()
    sigma = 0.015
    problem = InverseProblem(model, measured(model, sigma, 7), NoiseModel(sigma=sigma), free=("k", "b"), fixed={"c": 0.5})
    result = invert(problem, rng=7)
    region = likelihood_ratio_region(problem, result.x, rng=7)
    out = rvc(region, model, fixed={"c": 0.5})
    assert out.outputs == ("s1@30", "s2@30", "s3@30", "s4@30")
    assert all(0 < cv < 0.2 for cv in out.cv)
    assert all(r >= c for r, c in zip(out.range_ratio, out.cv))
    with pytest.raises(ValueError, match=r"needs values for \['c'\]"):
        rvc(region, model)
    with pytest.raises(ValueError, match="unknown RVC output"):
        rvc(region, model, fixed={"c": 0.5}, outputs=["s9@30"])
    ic = information_criteria(result)
    assert_allclose(ic["aic"] - result.chi2, 4.0)


@pytest.mark.slow
def test_nested_analyses_flag_overparameterisation():
    model = AnalyticModel()
    sigma = 0.015
    meas = measured(model, sigma, 9)

    def make(free):
        return InverseProblem(model, meas, NoiseModel(sigma=sigma), free=free, fixed={n: 0.5 for n in ("b", "c") if n not in free})

    rows = nested_analyses(make, [("k",), ("k", "b"), ("k", "b", "c")], rng=9, n_samples=2**14, validation={"same": (model, {"c": 0.5, "b": 0.5})})
    chi2 = [r.chi2_dof for r in rows]
    assert chi2[1] < chi2[0]  # b matters: fixing it at 0.5 (truth 0.4) leaves a misfit
    assert rows[2].aic > rows[1].aic  # c adds a parameter and explains nothing
    assert rows[2].unidentified == ["c"]


def test_mcmc_posterior_converges_and_sits_inside_the_region():
    from podkrig.online.posterior import sample_posterior

    model = AnalyticModel()
    sigma = 0.015
    problem = InverseProblem(model, measured(model, sigma, 4), NoiseModel(sigma=sigma), free=("k", "b"), fixed={"c": 0.5})
    result = invert(problem, rng=4)
    post = sample_posterior(problem, result.x, n_walkers=16, n_steps=3000, rng=4)
    region = likelihood_ratio_region(problem, result.x, rng=4)
    assert post.converged and 0.15 < post.acceptance < 0.8  # stretch move in 2-D accepts often
    assert np.all(post.r_hat < 1.05)
    for name in ("k", "b"):
        lo, hi = post.intervals[name]
        rlo, rhi = region.intervals[name]
        # marginal 95 % credible interval ⊂ projection of the joint 95 % region (Gaussian case);
        # a small slack for Monte Carlo error at the interval ends
        slack = 0.05 * (rhi - rlo)
        assert rlo - slack <= lo and hi <= rhi + slack
