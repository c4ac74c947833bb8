"""MCMC posterior (thesis eq. 2.12): the split-R̂ diagnostic against the BDA3 formula written out
independently, and the bookkeeping of :func:`sample_posterior` (burn-in, intervals, medians,
effective sample size) against its own samples."""

import numpy as np
import pytest

from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.posterior import _split_r_hat, sample_posterior
from podkrig.online.problem import InverseProblem
from podkrig.parameters import Parameter, ParameterSpace


def r_hat_bda3(chain):
    """Split-R̂ (Gelman et al., BDA3 §11.4) with explicit loops: each walker's chain cut in two
    halves of n = ⌊steps / 2⌋, giving m = 2 × walkers sequences."""
    steps, walkers, p = chain.shape
    n = steps // 2
    seqs = [chain[:n, w] for w in range(walkers)] + [chain[n:2 * n, w] for w in range(walkers)]
    m = len(seqs)
    out = []
    for k in range(p):
        means = [sum(s[i, k] for i in range(n)) / n for s in seqs]
        grand = sum(means) / m
        B = n / (m - 1) * sum((mu - grand) ** 2 for mu in means)
        W = sum(sum((s[i, k] - mu) ** 2 for i in range(n)) / (n - 1) for s, mu in zip(seqs, means)) / m
        out.append(((n - 1) / n * W + B / n) / W)
    return np.sqrt(out)


def test_split_r_hat_is_the_bda3_formula():
    chain = np.random.default_rng(0).standard_normal((41, 3, 2)) * [1.0, 5.0] + [0.0, 2.0]  # odd length: last step dropped
    np.testing.assert_allclose(_split_r_hat(chain), r_hat_bda3(chain), rtol=1e-12)


def test_split_r_hat_flags_a_drift_and_passes_stationary_chains():
    gen = np.random.default_rng(1)
    stationary = gen.standard_normal((4000, 8, 1))
    # iid sequences: R̂ − 1 ~ 1/(n m) ≪ 0.01 at n = 2000, m = 16
    assert abs(_split_r_hat(stationary)[0] - 1) < 0.01
    drifting = stationary + np.linspace(0, 3, 4000)[:, None, None]  # the halves disagree by ~1.5σ
    assert _split_r_hat(drifting)[0] > 1.2


class Line:
    """Readings a·load + b at 3 loads × 2 sensors; a Gaussian posterior in (a, b)."""

    space = ParameterSpace((Parameter("a", 0.0, 2.0), Parameter("b", -1.0, 1.0)))
    sensor_names = ("s1", "s2")
    load_levels = np.array([1.0, 2.0, 3.0])

    def predict(self, X, return_std=False):
        a, b = np.atleast_2d(X).T
        Y = (a[:, None, None] * self.load_levels[None, :, None] * np.array([1.0, 0.5])[None, None, :]
             + b[:, None, None]).reshape(len(a), -1)
        return (Y, None) if return_std else Y


def test_sample_posterior_bookkeeping():
    model = Line()
    clean = model.predict(np.array([[1.2, 0.1]]))[0].reshape(3, 2)
    data = Measurement(clean + 0.05 * np.random.default_rng(2).standard_normal((3, 2)), model.sensor_names,
                       model.load_levels)
    problem = InverseProblem(model, data, NoiseModel(sigma=0.05))
    post = sample_posterior(problem, np.array([1.2, 0.1]), n_walkers=12, n_steps=900, confidence=0.9, rng=3)
    # a third of the chain discarded by default: (900 − 300) steps × 12 walkers kept
    assert post.samples.shape == (600 * 12, 2) and post.n_steps == 900 and post.names == ("a", "b")
    for j, name in enumerate(post.names):
        lo, med, hi = np.percentile(post.samples[:, j], [5, 50, 95])
        assert post.intervals[name] == pytest.approx((lo, hi), rel=1e-12)
        assert post.median[name] == pytest.approx(med, rel=1e-12)
    assert post.effective_samples == pytest.approx(len(post.samples) / np.max(post.autocorr_time))
    assert 0.2 < post.acceptance < 0.9 and post.r_hat.shape == (2,)
    assert np.all(post.samples[:, 0] >= 0) and np.all(post.samples[:, 0] <= 2)  # inside the box
    shorter = sample_posterior(problem, np.array([1.2, 0.1]), n_walkers=12, n_steps=900, burn=100, rng=3)
    assert shorter.samples.shape == (800 * 12, 2)
    # the posterior sits on the data: its median within 4 posterior std of the least-squares fit
    A = np.column_stack([(model.load_levels[:, None] * [1.0, 0.5]).ravel(), np.ones(6)])
    ls = np.linalg.lstsq(A, data.data, rcond=None)[0]
    sd = post.samples.std(axis=0)
    assert np.all(np.abs(np.array([post.median["a"], post.median["b"]]) - ls) < 4 * sd)


def _line_problem(a_true):
    model = Line()
    clean = model.predict(np.array([[a_true, 0.1]]))[0].reshape(3, 2)
    data = Measurement(clean + 0.05 * np.random.default_rng(2).standard_normal((3, 2)), model.sensor_names,
                       model.load_levels)
    return InverseProblem(model, data, NoiseModel(sigma=0.05))


def test_sample_posterior_is_seeded_and_stays_in_the_box():
    problem = _line_problem(1.2)
    one, again, other = (sample_posterior(problem, np.array([1.2, 0.1]), n_walkers=8, n_steps=200, rng=r)
                         for r in (5, 5, 6))
    np.testing.assert_array_equal(one.samples, again.samples)
    assert not np.array_equal(one.samples, other.samples)
    # data made with a = 2.3, above the box's upper bound 2: the posterior piles up at the bound, never past it
    edge = sample_posterior(_line_problem(2.3), np.array([1.99, 0.1]), n_walkers=8, n_steps=300, rng=1)
    assert edge.samples[:, 0].max() <= 2.0 and np.median(edge.samples[:, 0]) > 1.9


def test_a_short_chain_is_not_called_converged():
    # 60 steps (40 kept) cannot be 50 autocorrelation times long, whatever R̂ says
    post = sample_posterior(_line_problem(1.2), np.array([1.2, 0.1]), n_walkers=8, n_steps=60, rng=0)
    assert not post.converged
