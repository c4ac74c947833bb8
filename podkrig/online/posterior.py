"""Bayesian posterior of the free parameters by MCMC on the same misfit: p(m | d) ∝ exp(−ω(m)).

Thesis eq. (2.12): the posterior density is k·exp(−ω(m)) with the misfit of eq. (2.13). The prior
is the one inside ω (Gaussian, optional) times a uniform density on the search box in its scaled
(linear or log10) coordinates. Sampling uses the affine-invariant ensemble sampler of
Goodman & Weare (2010) as implemented by emcee (Foreman-Mackey et al. 2013), with the whole
ensemble evaluated in one batched surrogate call per step.

Convergence diagnostics: the integrated autocorrelation time τ per parameter, the effective
sample size, the mean acceptance fraction, and the split-R̂ of Gelman & Rubin computed over
walkers (first vs second half of the chain).
"""

import logging
import time
from dataclasses import dataclass

import numpy as np

from podkrig.display import Displayed
from podkrig.parallel import one_blas_thread
from podkrig.online.settings import CONFIDENCE

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False, repr=False)
class Posterior(Displayed):
    """MCMC samples of the posterior.

    Attributes
    ----------
    samples : ndarray of shape (n_kept, n_free)
        Flattened post-burn-in samples, physical units.
    names : tuple of str
    intervals : dict of str to (float, float)
        Central credible intervals at ``confidence``.
    median : dict of str to float
    autocorr_time : ndarray of shape (n_free,)
        Integrated autocorrelation time, steps.
    effective_samples : float
        n_kept / max τ.
    acceptance : float
        Mean acceptance fraction (0.2–0.5 is healthy).
    r_hat : ndarray of shape (n_free,)
        Split-R̂ (< 1.01–1.05 for converged chains).
    converged : bool
        Chain longer than 50 τ and R̂ < 1.05.
    seconds : float
    """

    samples: np.ndarray
    names: tuple
    confidence: float
    intervals: dict
    median: dict
    autocorr_time: np.ndarray
    effective_samples: float
    acceptance: float
    r_hat: np.ndarray
    converged: bool
    n_steps: int
    seconds: float

    def to_dict(self, *, members=False):
        """JSON-able summary (without the samples unless ``members``)."""
        d = {"names": list(self.names), "confidence": self.confidence,
             "intervals": {k: list(v) for k, v in self.intervals.items()}, "median": dict(self.median),
             "autocorr_time": np.asarray(self.autocorr_time, dtype=float).tolist(),
             "effective_samples": self.effective_samples, "acceptance": self.acceptance,
             "r_hat": np.asarray(self.r_hat, dtype=float).tolist(), "converged": self.converged,
             "n_steps": self.n_steps, "seconds": self.seconds}
        if members:
            d["samples"] = self.samples.tolist()
        return d

    @classmethod
    def from_dict(cls, d, *, samples=None):
        """Read back :meth:`to_dict`; the samples from ``d``, from ``samples``, or none (an empty
        array)."""
        if samples is None:
            samples = d.get("samples", np.empty((0, len(d["names"]))))
        return cls(np.asarray(samples, dtype=float), tuple(d["names"]), float(d["confidence"]),
                   {k: (float(v[0]), float(v[1])) for k, v in d["intervals"].items()},
                   {k: float(v) for k, v in d["median"].items()}, np.asarray(d["autocorr_time"], dtype=float),
                   float(d["effective_samples"]), float(d["acceptance"]), np.asarray(d["r_hat"], dtype=float),
                   bool(d["converged"]), int(d["n_steps"]), float(d["seconds"]))


def _split_r_hat(chain):
    """Split-R̂ of a chain ``(n_steps, n_walkers, n_free)`` (Gelman et al., BDA3, §11.4)."""
    n = chain.shape[0] // 2
    halves = np.concatenate([chain[:n], chain[n : 2 * n]], axis=1)  # (n, 2 walkers, p)
    means = halves.mean(axis=0)
    W = halves.var(axis=0, ddof=1).mean(axis=0)
    B = n * means.var(axis=0, ddof=1)
    var = (n - 1) / n * W + B / n
    return np.sqrt(var / np.maximum(W, 1e-300))


def sample_posterior(problem, x_start, *, n_walkers=32, n_steps=3000, burn=None, confidence=CONFIDENCE, rng=0):
    """Sample exp(−ω(m)) over the free parameters' box.

    Parameters
    ----------
    problem : podkrig.online.problem.InverseProblem
    x_start : ndarray of shape (n_free,)
        Best fit; walkers start in a small ball around it (unit coordinates ± 1e-3).
    n_walkers, n_steps : int
    burn : int, optional
        Steps discarded (default: a third of the chain).
    confidence : float
        Of the credible intervals.
    rng : int
        Seed.

    Returns
    -------
    Posterior
    """
    import emcee

    t0 = time.perf_counter()
    space = problem.free_space
    p = len(space.names)
    gen = np.random.default_rng(rng)
    u0 = np.clip(space.to_unit(np.atleast_2d(x_start))[0], 1e-6, 1 - 1e-6)
    start = np.clip(u0 + 1e-3 * gen.standard_normal((n_walkers, p)), 1e-9, 1 - 1e-9)

    def log_prob(U):
        out = np.full(len(U), -np.inf)
        inside = np.all((U >= 0) & (U <= 1), axis=1)
        if inside.any():
            out[inside] = -problem.omega_unit(U[inside])
        return out

    sampler = emcee.EnsembleSampler(n_walkers, p, log_prob, vectorize=True)
    sampler.random_state = np.random.RandomState(int(gen.integers(2**31))).get_state()  # seeded
    with one_blas_thread():
        sampler.run_mcmc(start, n_steps, progress=False)
    burn = n_steps // 3 if burn is None else burn
    chain = sampler.get_chain(discard=burn)  # (steps, walkers, p)
    tau = emcee.autocorr.integrated_time(chain, quiet=True, tol=0)
    flat = space.from_unit(chain.reshape(-1, p))
    a = 100 * (1 - confidence) / 2
    q = np.percentile(flat, [a, 50, 100 - a], axis=0)
    r_hat = _split_r_hat(chain)
    ess = flat.shape[0] / np.max(tau)
    converged = bool(chain.shape[0] > 50 * np.max(tau) and np.all(r_hat < 1.05))
    if not converged:
        logger.warning("MCMC may not have converged: τ = %s steps, R̂ = %s; run longer", tau, r_hat)
    return Posterior(
        samples=flat,
        names=tuple(space.names),
        confidence=confidence,
        intervals={n: (float(q[0, j]), float(q[2, j])) for j, n in enumerate(space.names)},
        median={n: float(q[1, j]) for j, n in enumerate(space.names)},
        autocorr_time=tau,
        effective_samples=float(ess),
        acceptance=float(np.mean(sampler.acceptance_fraction)),
        r_hat=r_hat,
        converged=converged,
        n_steps=n_steps,
        seconds=time.perf_counter() - t0,
    )
