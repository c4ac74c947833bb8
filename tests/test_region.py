"""Region of equivalence (podkrig.online.region) on models whose region is known in closed form.

A linear model with Gaussian noise has ω(m) − ω(m*) = ½ (m − m*)ᵀ AᵀA (m − m*)/σ² exactly, so its
likelihood-ratio region is an ellipse whose projections, sampling share and threshold are known;
a saturating (tanh) model has a region wider than its Gauss–Newton curvature predicts, so the
sampling box must grow. Each test names the defect it guards; all run in well under a second.
"""

import logging
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import stats

from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.problem import InverseProblem
from podkrig.online.region import Region, identifiability, likelihood_ratio_region, noise_monte_carlo_region
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.reports.findings import identifiability_text
from podkrig.reports.jupyter import region_html

SIGMA = 0.01  # mm


class LinearModel:
    """Readings ``A m`` (mm) of 3 sensors at 2 loads; predictive std ``std_slope · m₁`` (0: none)."""

    space = ParameterSpace((Parameter("m1", 0.0, 2.0, unit="MPa"), Parameter("m2", 0.0, 2.0)))
    sensor_names = ("g1", "g2", "g3")
    load_levels = np.array([10.0, 20.0])
    A = np.array([[1.0, 0.2], [0.3, 1.0], [0.5, 0.5], [2.0, 0.4], [0.6, 2.0], [1.0, 1.0]])

    def __init__(self, std_slope=0.0):
        self.std_slope = std_slope

    def predict(self, X, return_std=False):
        X = np.atleast_2d(X)
        Y = X @ self.A.T
        return (Y, self.std_slope * X[:, :1] * np.ones_like(Y)) if return_std else Y


def _linear(std_slope=0.0, model_error=False):
    """The linear problem (data at m = (0.7, 1.3) plus seeded noise) and its exact least-squares fit."""
    model = LinearModel(std_slope)
    data = model.A @ [0.7, 1.3] + SIGMA * np.random.default_rng(5).standard_normal(6)
    problem = InverseProblem(model, Measurement(data.reshape(2, 3), model.sensor_names, model.load_levels),
                             NoiseModel(sigma=SIGMA), model_error=model_error)
    return problem, np.linalg.lstsq(model.A, data, rcond=None)[0]


class _OneReadingModel:
    """A one-parameter, one-reading surrogate ``reading(m)`` (mm) that keeps the smallest and largest
    m it was evaluated at."""

    space = ParameterSpace((Parameter("m", 0.0, 1.0, unit="MPa"),))
    sensor_names = ("g",)
    load_levels = np.array([1.0])

    def __init__(self, centre=0.5):
        self.centre = centre
        self.seen = [np.inf, -np.inf]

    def predict(self, X, return_std=False):
        m = np.atleast_2d(X)[:, :1]
        self.seen = [min(self.seen[0], m.min()), max(self.seen[1], m.max())]
        Y = self.reading(m)
        return (Y, np.zeros_like(Y)) if return_std else Y


class TanhModel(_OneReadingModel):
    """One reading ``S tanh((m − centre)/W)`` (mm) against data 0: ω = ½ (S/σ)² tanh², whose region
    |m − centre| ≤ W atanh(√(2δ) σ/S) is 1.9 times the Gauss–Newton estimate √(2δ) σ W/S."""

    S, W = 1.0, 0.01
    Q = 0.95  # √(2δ) σ / S at 95 %

    def reading(self, m):
        return self.S * np.tanh((m - self.centre) / self.W)


def _tanh_problem(centre=0.5):
    sigma = TanhModel.Q * TanhModel.S / np.sqrt(stats.chi2.ppf(0.95, 1))
    return InverseProblem(TanhModel(centre), Measurement(np.zeros((1, 1)), ("g",), np.array([1.0])),
                          NoiseModel(sigma=sigma), model_error=False)


def test_linear_region_is_the_chi2_ellipse():
    """Fails if the threshold leaves ω* + ½ χ²_p(c), if a member lies outside it or carries a wrong
    misfit, if the best fit is not the first member, if an interval is not the members' extent or
    misses the ellipse's projection m*_j ± √(2δ σ² [(AᵀA)⁻¹]_jj), or if the result's labels (method,
    confidence, names, units, identifiability) are wrong. Tolerance of the projection: 1 % of its
    half-width (the Sobol' members come within ~N^(-2/3) of an ellipse's tip)."""
    problem, x_best = _linear()
    t0 = time.perf_counter()
    region = likelihood_ratio_region(problem, x_best, confidence=0.95, n_samples=2**14, rng=0)
    wall = time.perf_counter() - t0
    omega_best = problem.omega(x_best[None])[0]
    delta = -np.log(1 - 0.95)  # ½ χ²₂(c) = −ln(1 − c)
    assert region.threshold == pytest.approx(omega_best + delta, rel=1e-12)
    assert_allclose(region.samples[0], x_best, rtol=0)
    assert region.omega[0] == omega_best
    assert np.all(region.omega <= region.threshold)
    assert_allclose(region.omega, problem.omega(region.samples), rtol=1e-10)
    cov = SIGMA**2 * np.linalg.inv(LinearModel.A.T @ LinearModel.A)
    for j, name in enumerate(("m1", "m2")):
        lo, hi = region.intervals[name]
        assert (lo, hi) == (region.samples[:, j].min(), region.samples[:, j].max())
        half = np.sqrt(2 * delta * cov[j, j])
        assert lo == pytest.approx(x_best[j] - half, abs=0.01 * half)
        assert hi == pytest.approx(x_best[j] + half, abs=0.01 * half)
    assert (region.method, region.confidence, region.names, region.units) == (
        "likelihood-ratio", 0.95, ("m1", "m2"), ("MPa", "-"))
    assert region.identifiability == identifiability(region.intervals, problem.free_space)
    assert 0 < region.seconds <= wall


def test_linear_region_is_sampled_in_one_round_of_a_box_from_the_curvature():
    """Fails if the sample count is not rounded up to a power of two, if the box is not sized from
    the Gauss–Newton curvature (1.5 × the ellipse's projections) or grows although no member
    touches its faces: one round of 2^12 points (3000 asked), and the share of points accepted is
    the ellipse's share of that box, π/9 · √(1 − ρ²) (ρ the correlation of the quadratic model),
    to 3 % (Sobol' points estimate an area to ~1/N)."""
    problem, x_best = _linear()
    region = likelihood_ratio_region(problem, x_best, n_samples=3000, rng=0)
    assert region.n_evaluated == 2**12
    cov = np.linalg.inv(LinearModel.A.T @ LinearModel.A)
    rho = cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1])
    share = (len(region.samples) - 1) / region.n_evaluated  # the best fit is added to the members
    assert share == pytest.approx(np.pi / 9 * np.sqrt(1 - rho**2), rel=0.03)


def test_region_wider_than_the_curvature_grows_the_box_until_no_member_touches_it():
    """Fails if the box does not grow when members touch its faces (or grows by the wrong amount):
    the tanh model's region, |m − 0.5| ≤ W atanh(0.95) = 0.0183, is 1.9 × the Gauss–Newton estimate
    and so touches the first box (1.5 ×); after one growth (by its width on each touched side) it is
    sampled whole: 2 rounds of 2^10 points, interval to 1 % of its half-width."""
    region = likelihood_ratio_region(_tanh_problem(), np.array([0.5]), n_samples=2**10, rng=0)
    half = TanhModel.W * np.arctanh(TanhModel.Q)
    lo, hi = region.intervals["m"]
    assert lo == pytest.approx(0.5 - half, abs=0.01 * half) and hi == pytest.approx(0.5 + half, abs=0.01 * half)
    assert region.n_evaluated == 2 * 2**10
    # with no growth allowed, the region stops at the first box: 1.5 × the curvature's estimate
    gn = 1.5 * TanhModel.W * TanhModel.Q
    capped = likelihood_ratio_region(_tanh_problem(), np.array([0.5]), n_samples=2**10, rng=0, max_grow=0)
    assert capped.n_evaluated == 2**10
    assert capped.intervals["m"] == pytest.approx((0.5 - gn, 0.5 + gn), abs=0.01 * gn)


@pytest.mark.parametrize("centre", [0.01, 0.025, 0.975, 0.99])
def test_region_growth_never_samples_outside_the_search_range(centre, caplog):
    """Fails if the grown sampling box is not clipped to the search range: near a bound (region
    [centre ∓ 0.0183], first box ∓ 0.0142, grown by its width) the model, which a surrogate only
    knows inside its training box, would be evaluated at m < 0 or m > 1; or if a box clipped at
    one face and touched at the other only is not grown (centre 0.01, 0.99). The interval is still
    the exact one (1 % of its half-width); the growth is logged."""
    problem = _tanh_problem(centre)
    with caplog.at_level(logging.INFO, logger="podkrig.online.region"):
        region = likelihood_ratio_region(problem, np.array([centre]), n_samples=2**10, rng=0)
    (record,) = caplog.records
    assert (record.name, record.levelno, record.args) == ("podkrig.online.region", logging.INFO, (0,))  # round 0
    assert 0.0 <= problem.model.seen[0] and problem.model.seen[1] <= 1.0
    half = TanhModel.W * np.arctanh(TanhModel.Q)
    exact = (max(centre - half, 0.0), min(centre + half, 1.0))  # the region ends at the range's face
    assert region.intervals["m"] == pytest.approx(exact, abs=0.01 * half)


def test_unconstrained_parameter_spans_its_range_without_leaving_it():
    """Fails if a direction the data do not constrain (zero column of the Jacobian) does not get a
    sampling box over its whole search range, or if that box is not clipped to the range: a
    reading that ignores m2 gives m2's interval [0, 2] (to 1 %), evaluated only inside [0, 2]."""

    class IgnoresM2(LinearModel):
        A = LinearModel.A * [1.0, 0.0]
        seen = []

        def predict(self, X, return_std=False):
            self.seen.append(np.atleast_2d(X))
            return super().predict(X, return_std)

    model = IgnoresM2()
    data = model.A @ [0.7, 1.3]
    problem = InverseProblem(model, Measurement(data.reshape(2, 3), model.sensor_names, model.load_levels),
                             NoiseModel(sigma=SIGMA), model_error=False)
    region = likelihood_ratio_region(problem, np.array([0.7, 1.3]), n_samples=2**12, rng=0)
    assert region.intervals["m2"] == pytest.approx((0.0, 2.0), abs=0.02)
    assert region.n_evaluated == 2**12  # members at a face of the range do not grow the box: one round
    seen = np.vstack(model.seen)
    assert seen.min(axis=0).tolist() >= [0.0, 0.0] and np.all(seen.max(axis=0) <= [2.0, 2.0])
    assert not region.identifiability["m2"]["identifiable"] and region.identifiability["m1"]["identifiable"]


class WallModel(_OneReadingModel):
    """One reading x + 10⁹ sign(x) (|x| − 1)₊³, x = (m − centre)/W, against data 0: linear (slope 1/W)
    within W of the centre, then a wall. The Gauss–Newton box (from the slope) is 3000 times wider than the region
    |m − 0.5| ≤ 1.0215 W: a 1024-point Sobol' round over it has no sample in the region."""

    W = 3e-5

    def reading(self, m):
        x = (m - self.centre) / self.W
        return x + 1e9 * np.sign(x) * np.maximum(np.abs(x) - 1, 0) ** 3


def test_region_narrower_than_the_sample_spacing_shrinks_the_box():
    """Fails if a round without any accepted sample is repeated over the same box (the defect this
    test was written for: 7 identical rounds, then a region of the best fit alone, a zero-width
    interval reported as "identified"): the box halves about m* until samples land in the region;
    every member lies in the exact region |m − centre| ≤ 1.0215 W (x + 10⁹ (x − 1)³ = 10⁴), and near a
    bound the shrunken box stays inside the search range."""
    for centre in (0.5, 0.3, 0.002, 0.998):
        sigma = 1e4 / np.sqrt(stats.chi2.ppf(0.95, 1))  # √(2δ) σ = 10⁴: the region's edge at g = 10⁴
        problem = InverseProblem(WallModel(centre), Measurement(np.zeros((1, 1)), ("g",), np.array([1.0])),
                                 NoiseModel(sigma=sigma), model_error=False)
        region = likelihood_ratio_region(problem, np.array([centre]), n_samples=2**10, rng=0)
        lo, hi = region.intervals["m"]
        assert len(region.samples) > 1 and hi > lo, (centre, region.intervals)
        assert centre - 1.0215 * WallModel.W <= lo and hi <= centre + 1.0215 * WallModel.W
        assert region.n_evaluated < 7 * 2**10  # stopped once samples were accepted
        # the shrunken boxes stay inside the search range
        assert 0.0 <= problem.model.seen[0] and problem.model.seen[1] <= 1.0


def test_region_is_seeded_and_independent_of_the_batch_size():
    """Fails if the seed is not passed to the Sobol' scrambling (same seed, same members; another
    seed, other members) or if splitting the evaluations into batches loses or repeats points."""
    problem, x_best = _linear()
    a = likelihood_ratio_region(problem, x_best, n_samples=2**12, rng=3)
    b = likelihood_ratio_region(problem, x_best, n_samples=2**12, rng=3, batch=1000)
    assert_allclose(b.samples, a.samples, rtol=0)
    assert_allclose(b.omega, a.omega, rtol=1e-12)
    c = likelihood_ratio_region(problem, x_best, n_samples=2**12, rng=4)
    assert not np.array_equal(c.samples[1:6], a.samples[1:6])


def test_region_freezes_the_model_error_at_the_best_fit_by_default():
    """Fails if the default stops freezing the surrogate's predictive std at m* (the documented
    speed-up) or freezes it when asked not to: with std = 0.005 m₁ mm in C_D, the members' misfits
    are those of the frozen problem by default and of the full problem with ``freeze_model_error=False``."""
    problem, x_best = _linear(std_slope=0.005, model_error=True)
    frozen = problem.freeze_model_error(x_best)
    region = likelihood_ratio_region(problem, x_best, n_samples=2**12, rng=0)
    assert_allclose(region.omega, frozen.omega(region.samples), rtol=1e-10)
    assert not np.allclose(region.omega[1:], problem.omega(region.samples[1:]), rtol=1e-6)
    full = likelihood_ratio_region(problem, x_best, n_samples=2**12, rng=0, freeze_model_error=False)
    assert_allclose(full.omega, problem.omega(full.samples), rtol=1e-10)
    # a problem frozen already (elsewhere) keeps its own frozen std: it is not re-frozen at m*
    elsewhere = problem.freeze_model_error(x_best + [0.2, 0.0])
    kept = likelihood_ratio_region(elsewhere, x_best, n_samples=2**12, rng=0)
    assert_allclose(kept.omega, elsewhere.omega(kept.samples), rtol=1e-10)
    assert not np.allclose(kept.omega[1:], frozen.omega(kept.samples[1:]), rtol=1e-6)


@pytest.mark.parametrize("kwargs, message", [
    ({"n_samples": 1000}, "n_samples must be at least 1024"),
    ({"n_samples": 2**25}, "n_samples must be at most 16777216"),
    ({"confidence": 1.0}, r"confidence .*\(0, 1\).*got 1.0"),
    ({"confidence": 0.0}, r"confidence must be in \(0, 1\)"),
])
def test_likelihood_ratio_region_names_the_bad_setting(kwargs, message):
    """Fails if a refused sample count or confidence is reported under another name or without
    the allowed range."""
    problem, x_best = _linear()
    with pytest.raises(ValueError, match=message):
        likelihood_ratio_region(problem, x_best, **kwargs)


def test_identifiability_share_is_clipped_to_the_search_range():
    """Fails if an interval reaching past the search range is not clipped to it before its share is
    taken (the share is of the search range, at most 1), if the share is not taken in the
    parameter's scaled (log) coordinate, or if the verdict in words does not name the parameter."""
    space = ParameterSpace((Parameter("a", 0.0, 2.0, unit="MPa"), Parameter("k", 1.0, 100.0, "log")))
    verdict = identifiability({"a": (-1.0, 0.5), "k": (10.0, 1000.0)}, space)
    assert verdict["a"]["share"] == pytest.approx(0.25) and verdict["a"]["identifiable"]
    assert verdict["k"]["share"] == pytest.approx(0.5)  # log10: [1, 2] of [0, 2]
    wide = identifiability({"a": (-5.0, 5.0), "k": (0.1, 10.0)}, space)
    assert wide["a"]["share"] == 1.0 and not wide["a"]["identifiable"]
    assert wide["k"]["share"] == pytest.approx(0.5)
    text = identifiability_text("a", (-5.0, 5.0), "MPa", wide["a"])
    assert "a is NOT pinned down" in text and "-5 to 5 MPa (100 %" in text


def test_region_summary_keys_html_table_and_round_trip():
    """Fails if the summary JSON loses a key or a type (counts as int), if the members are written
    without ``members=True``, or if the Jupyter table misses a parameter's unit, interval, share or
    verdict, or the caption's method, confidence and counts."""
    space = ParameterSpace((Parameter("a", 0.0, 2.0, unit="MPa"), Parameter("b", 0.0, 1.0)))
    intervals = {"a": (0.5, 0.75), "b": (0.1, 0.9)}
    region = Region("likelihood-ratio", 0.9, np.array([[0.6, 0.5], [0.5, 0.1], [0.75, 0.9]]),
                    np.array([1.0, 1.5, 2.0]), 2.5, intervals, ("a", "b"), ("MPa", "-"), np.int64(4096), 0.25,
                    identifiability(intervals, space))
    d = region.to_dict()
    assert d == {"method": "likelihood-ratio", "confidence": 0.9, "threshold": 2.5,
                 "intervals": {"a": [0.5, 0.75], "b": [0.1, 0.9]}, "names": ["a", "b"], "units": ["MPa", "-"],
                 "n_members": 3, "n_evaluated": 4096, "seconds": 0.25, "identifiability": region.identifiability}
    assert type(d["n_evaluated"]) is int
    full = region.to_dict(members=True)
    assert full["samples"] == region.samples.tolist() and full["omega"] == [1.0, 1.5, 2.0]
    back = Region.from_dict(full)
    assert back.to_dict(members=True) == full and back.intervals == intervals
    with pytest.raises(ValueError, match="3 members.*2 samples and 3 misfits"):
        Region.from_dict(d, samples=region.samples[:2], omega=region.omega)
    with pytest.raises(ValueError, match="3 members.*3 samples and 2 misfits"):
        Region.from_dict(d, samples=region.samples, omega=region.omega[:2])
    page = region_html(region)
    assert "<caption" in page and "likelihood-ratio, 90 %" in page and "3 members of 4096 evaluations" in page
    assert ("<thead><tr><th>parameter</th><th>unit</th><th>low</th><th>high</th>"
            "<th>share of search range (%)</th><th>identified</th></tr></thead>") in page
    assert "<tr><td>a</td><td>MPa</td><td>0.5</td><td>0.75</td><td>12</td><td>yes</td></tr>" in page
    assert "<tr><td>b</td><td>-</td><td>0.1</td><td>0.9</td><td>80</td><td>NO</td></tr>" in page


def _noisy_refits(problem, x_best, n, seed):
    """The documented noise Monte Carlo steps, by hand: refits from noisy copies of g(m*)."""
    gen = np.random.default_rng(seed)
    fits = [problem.with_noisy_data(x_best, gen).polish(x_best) for _ in range(n)]
    return np.array([x for x, _ in fits]), sum(n for _, n in fits)


def test_noise_monte_carlo_region_is_its_seeded_refits():
    """Fails if the refits are not drawn from the given seed, if the evaluation count is not the
    sum of the polishes' counts, or if a field of the result is wrong (method, confidence, NaN misfits
    and threshold, names, units, identifiability, elapsed time)."""
    problem, x_best = _linear()
    t0 = time.perf_counter()
    mc = noise_monte_carlo_region(problem, x_best, n_realisations=20, confidence=0.9, rng=7)
    wall = time.perf_counter() - t0
    X, n_eval = _noisy_refits(problem, x_best, 20, 7)
    assert_allclose(mc.samples, X, rtol=0)
    assert mc.n_evaluated == n_eval
    assert (mc.method, mc.confidence, mc.names, mc.units) == ("noise-mc", 0.9, ("m1", "m2"), ("MPa", "-"))
    assert np.isnan(mc.threshold) and mc.omega.shape == (20,) and np.isnan(mc.omega).all()
    assert mc.identifiability == identifiability(mc.intervals, problem.free_space)
    assert 0 < mc.seconds <= wall


class _FirstRefit(Exception):
    """Raised by :class:`_StopAtFirstRefit` when the first noisy copy is asked for."""


class _StopAtFirstRefit:
    """A problem that stops at the first noisy copy: the argument checks have passed by then."""

    def with_noisy_data(self, x, rng):
        raise _FirstRefit


@pytest.mark.parametrize("n", [19, 100_001, 20.0, True])
def test_noise_monte_carlo_refuses_a_bad_number_of_realisations(n):
    """Fails if fewer than 20 or more than 100 000 realisations, a float or a bool are accepted, or
    the message does not give the allowed range and the value (a stub problem stops a run that
    wrongly starts at its first refit)."""
    with pytest.raises(ValueError, match=rf"n_realisations .*\[20, 100000\].*got {n!r}"):
        noise_monte_carlo_region(_StopAtFirstRefit(), np.array([0.5]), n_realisations=n)


@pytest.mark.parametrize("n", [20, 100_000])
def test_noise_monte_carlo_accepts_both_ends_of_the_range(n):
    """Fails if 20 or 100 000 realisations (the documented limits, inclusive) are refused: the run
    reaches its first refit (a stub problem stops it there, so 100 000 refits are not run)."""
    with pytest.raises(_FirstRefit):
        noise_monte_carlo_region(_StopAtFirstRefit(), np.array([0.5]), n_realisations=n)
