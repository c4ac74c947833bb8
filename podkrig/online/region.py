"""Region of equivalence of an identification, and the identifiability of each parameter.

Region of equivalence (thesis ch. 5; Chisari 2019, Eng. Comput. 35:381): the parameter vectors
whose misfit is statistically indistinguishable from the best fit. Two constructions:

- *likelihood ratio* (:func:`likelihood_ratio_region`): ``{m : ω(m) − ω(m*) ≤ ½ χ²_p(c)}`` with
  p free parameters and confidence c (Wilks), sampled densely (≥ 10⁵ Sobol points) on the
  surrogate inside a box sized from the Gauss–Newton curvature at m* and grown until the
  accepted set no longer touches its faces;
- *noise Monte Carlo* (:func:`noise_monte_carlo_region`): re-identify from many noisy copies of
  the best-fit prediction; the cloud of re-identified parameters is the region (percentile
  intervals).

Per-parameter intervals are the projections of the region on each axis; :func:`identifiability`
judges each by the share of its search range it spans (the threshold is the findings policy's,
:mod:`podkrig.online.findings`; the words are :func:`podkrig.reports.findings.identifiability_text`).
"""

import logging
import time
from dataclasses import dataclass

import numpy as np
from scipy import stats

from podkrig._qmc import scrambled_sobol
from podkrig.display import Displayed, summary
from podkrig.parallel import one_blas_thread
from podkrig.limits import check_confidence, check_region_samples
from podkrig.online.findings import UNIDENTIFIABLE_SHARE, is_identifiable
from podkrig.online.settings import CONFIDENCE, REGION_SAMPLES

logger = logging.getLogger(__name__)


def identifiability(intervals, space):
    """Per parameter: share of the search range its interval spans, and whether it is identified.

    Parameters
    ----------
    intervals : dict of str to (float, float)
        Equivalence intervals, physical units, keyed by the names of ``space``.
    space : ParameterSpace
        The free parameter space (search ranges and scales).

    Returns
    -------
    dict of str to dict
        ``{"share": float, "identifiable": bool}``; identifiable when the share is at most
        :data:`~podkrig.online.findings.UNIDENTIFIABLE_SHARE`.
    """
    names = list(space.names)
    bounds = np.array([[intervals[n][k] for n in names] for k in (0, 1)])
    U = np.clip(space.to_unit(bounds), 0.0, 1.0)
    shares = {name: float(U[1, j] - U[0, j]) for j, name in enumerate(names)}
    return {name: {"share": share, "identifiable": is_identifiable(share)} for name, share in shares.items()}


@dataclass(frozen=True, eq=False, repr=False)
class Region(Displayed):
    """A region of equivalence.

    Attributes
    ----------
    method : {"likelihood-ratio", "noise-mc"}
    confidence : float
    samples : ndarray of shape (n_members, n_free)
        Members of the region, physical units.
    omega : ndarray of shape (n_members,)
        Their misfit (likelihood-ratio method; NaN for noise Monte Carlo).
    threshold : float
        ω(m*) + ½ χ²_p(c) (likelihood ratio) or NaN.
    intervals : dict of str to (float, float)
        Per-parameter [low, high], physical units.
    names, units : tuple of str
    n_evaluated : int
        Model evaluations spent.
    seconds : float
    identifiability : dict of str to dict
        :func:`identifiability` of the intervals.
    """

    method: str
    confidence: float
    samples: np.ndarray
    omega: np.ndarray
    threshold: float
    intervals: dict
    names: tuple
    units: tuple
    n_evaluated: int
    seconds: float
    identifiability: dict

    def _repr_lines(self):
        """The method, the members and one interval per parameter (repr)."""
        return [f"Region ({self.method}, {100 * self.confidence:.0f} %): {len(self.samples)} members of "
                f"{self.n_evaluated} evaluations",
                *(f"  {n} in [{summary(float(self.intervals[n][0]))}, {summary(float(self.intervals[n][1]))}] {u}"
                  f"{'' if self.identifiability.get(n, {}).get('identifiable', True) else ' (not identified)'}".rstrip()
                  for n, u in zip(self.names, self.units))]

    def to_dict(self, *, members=False):
        """JSON-able summary: ``method``, ``confidence``, ``threshold``, ``intervals``, ``names``,
        ``units``, ``n_members``, ``n_evaluated``, ``seconds``, ``identifiability``; with
        ``members=True`` also ``samples`` and ``omega`` (lists)."""
        d = {
            "method": self.method, "confidence": self.confidence, "threshold": self.threshold,
            "intervals": {k: list(v) for k, v in self.intervals.items()},
            "names": list(self.names), "units": list(self.units),
            "n_members": len(self.samples), "n_evaluated": int(self.n_evaluated), "seconds": self.seconds,
            "identifiability": self.identifiability,
        }
        if members:
            d.update(samples=self.samples.tolist(), omega=self.omega.tolist())
        return d

    @classmethod
    def from_dict(cls, d, *, samples=None, omega=None):
        """Read back :meth:`to_dict`; the members come from ``d`` or from ``samples`` and ``omega``
        (e.g. kept in an ``.npz`` beside the JSON)."""
        samples = np.asarray(d["samples"] if samples is None else samples, dtype=float)
        omega = np.asarray(d["omega"] if omega is None else omega, dtype=float)
        if len(samples) != d["n_members"] or len(omega) != len(samples):
            raise ValueError(f"the region has {d['n_members']} members; got {len(samples)} samples and "
                             f"{len(omega)} misfits")
        return cls(d["method"], float(d["confidence"]), samples, omega, float(d["threshold"]),
                   {k: (float(v[0]), float(v[1])) for k, v in d["intervals"].items()}, tuple(d["names"]),
                   tuple(d["units"]), int(d["n_evaluated"]), float(d["seconds"]),
                   {k: dict(v) for k, v in d["identifiability"].items()})


def likelihood_ratio_region(problem, x_best, *, confidence=CONFIDENCE, n_samples=REGION_SAMPLES, rng=0, max_grow=6,
                            batch=2**16,
                            freeze_model_error=True):
    """Region of equivalence by the likelihood-ratio (χ²) bound, sampled densely.

    Parameters
    ----------
    problem : InverseProblem
    x_best : ndarray of shape (n_free,)
        The best fit m*, physical units.
    confidence : float
        c in ω(m) − ω(m*) ≤ ½ χ²_p(c).
    n_samples : int
        Sobol points per sampling round (rounded to a power of two; ≥ 10⁵ recommended).
    rng : int or Generator
        Seed of the scrambled Sobol sequence.
    max_grow : int
        Rounds in which the sampling box may grow when members touch its faces (or, when no
        sample is accepted, shrink to half its width about m*).
    freeze_model_error : bool
        Evaluate the surrogate's predictive variance C_T once at m* and keep it over the region
        (it varies little there), so that only the mean is predicted: several times faster.

    Returns
    -------
    Region
    """
    check_region_samples(n_samples, "n_samples")
    check_confidence(confidence)
    t0 = time.perf_counter()
    if freeze_model_error and problem.model_error and problem.frozen_model_std is None:
        problem = problem.freeze_model_error(x_best)
    space = problem.free_space
    p = len(space.names)
    omega_best = float(problem.omega(np.atleast_2d(x_best))[0])
    delta = 0.5 * stats.chi2.ppf(confidence, p)
    threshold = omega_best + delta
    u_best = np.clip(space.to_unit(np.atleast_2d(x_best))[0], 0, 1)
    # Gauss–Newton curvature of ω in unit coordinates: ω ≈ ω* + ½ Δuᵀ JᵀJ Δu
    J = problem.jacobian_unit(u_best)
    # covariance of the quadratic model; directions the data do not constrain (tiny eigenvalues
    # of JᵀJ) get an unbounded width, so the box spans the whole range along them
    lam, vec = np.linalg.eigh(J.T @ J)
    floor = 1e-10 * max(lam.max(), 1e-300)
    cov = (vec / np.maximum(lam, floor)) @ vec.T
    half = 1.5 * np.sqrt(np.maximum(np.diag(cov), 0.0) * 2 * delta)
    half = np.where(np.isfinite(half) & (half > 1e-9), half, 1.0)
    lo, hi = np.clip(u_best - half, 0, 1), np.clip(u_best + half, 0, 1)
    engine_seed = rng
    n_eval = 0
    m = int(np.ceil(np.log2(max(n_samples, 2))))
    for round_ in range(max_grow + 1):
        U = lo + (hi - lo) * scrambled_sobol(2**m, p, engine_seed)
        with one_blas_thread():
            om = np.concatenate([problem.omega_unit(U[i : i + batch]) for i in range(0, len(U), batch)])
        n_eval += len(U)
        keep = om <= threshold
        members = U[keep]
        if len(members) == 0:  # a region narrower than the sample spacing: halve the box about m*
            lo, hi = np.clip(u_best - 0.25 * (hi - lo), 0, 1), np.clip(u_best + 0.25 * (hi - lo), 0, 1)
            continue
        width = hi - lo
        margin = 0.02 * width
        touch_lo = (members.min(axis=0) < lo + margin) & (lo > 0)
        touch_hi = (members.max(axis=0) > hi - margin) & (hi < 1)
        if not (touch_lo.any() or touch_hi.any()):
            break
        lo = np.where(touch_lo, np.clip(lo - width, 0, 1), lo)
        hi = np.where(touch_hi, np.clip(hi + width, 0, 1), hi)
        logger.info("region round %d: members touch the sampling box; growing it", round_)
    # the best fit is a member by definition, whether or not a sample landed next to it
    X = np.vstack([np.atleast_2d(x_best)] + ([space.from_unit(members)] if len(members) else []))
    omegas = np.concatenate([[omega_best], om[keep] if len(members) else []])
    intervals = {n: (float(X[:, j].min()), float(X[:, j].max())) for j, n in enumerate(space.names)}
    return Region("likelihood-ratio", confidence, X, omegas, threshold, intervals, tuple(space.names),
                  tuple(space.units), n_eval, time.perf_counter() - t0, identifiability(intervals, space))


def noise_monte_carlo_region(problem, x_best, *, n_realisations=200, confidence=CONFIDENCE, rng=0):
    """Region of equivalence by noise Monte Carlo: re-identify from noisy copies of g(m*).

    Each copy adds Gaussian noise with the data covariance to the best-fit prediction and is
    re-identified by bounded least squares from m* (fast on the surrogate). Intervals are the
    central ``confidence`` percentiles of the re-identified parameters.
    """
    check_confidence(confidence)
    if isinstance(n_realisations, bool) or not isinstance(n_realisations, int) or not 20 <= n_realisations <= 10**5:
        raise ValueError(f"n_realisations must be an integer in [20, 100000] (each re-identifies the parameters; "
                         f"fewer give no percentile of the region); got {n_realisations!r}")
    t0 = time.perf_counter()
    gen = np.random.default_rng(rng)
    X, n_eval = [], 0
    for _ in range(n_realisations):
        x, n = problem.with_noisy_data(x_best, gen).polish(x_best)
        X.append(x)
        n_eval += n
    X = np.array(X)
    a = 100 * (1 - confidence) / 2
    q = np.percentile(X, [a, 100 - a], axis=0)
    space = problem.free_space
    intervals = {n: (float(q[0, j]), float(q[1, j])) for j, n in enumerate(space.names)}
    return Region("noise-mc", confidence, X, np.full(len(X), np.nan), float("nan"), intervals,
                  tuple(space.names), tuple(space.units), n_eval, time.perf_counter() - t0,
                  identifiability(intervals, space))


__all__ = ["Region", "UNIDENTIFIABLE_SHARE", "identifiability", "likelihood_ratio_region", "noise_monte_carlo_region"]
