"""Uncertainty of an identification: region of equivalence, identifiability, RVC, nested analyses.

Region of equivalence (thesis ch. 5; Chisari 2019, Eng. Comput. 35:381): the parameter vectors
whose misfit is statistically indistinguishable from the best fit. Two constructions:

- *likelihood ratio*: ``{m : ω(m) − ω(m*) ≤ ½ χ²_p(c)}`` with p free parameters and confidence
  c (Wilks), sampled densely (≥ 10⁵ Sobol points) on the surrogate inside a box sized from the
  Gauss–Newton curvature at m* and grown until the accepted set no longer touches its faces;
- *noise Monte Carlo*: re-identify from many noisy copies of the best-fit prediction; the cloud
  of re-identified parameters is the region (percentile intervals).

Per-parameter intervals are the projections of the region on each axis. RVC (response
variability of calibration/validation models) is the spread of a model's predictions over the
region: coefficient of variation and (max − min)/|mean| per output.
"""

import logging
import time
from dataclasses import dataclass

import numpy as np
from scipy import stats

from podkrig._qmc import scrambled_sobol
from podkrig.parallel import one_blas_thread
from podkrig.online.inverse import InverseProblem, invert
from podkrig.online.measurement import Measurement

logger = logging.getLogger(__name__)

#: a parameter whose equivalence interval spans more than this share of its search range (in the
#: scaled unit coordinate) is reported as not identifiable from the data
UNIDENTIFIABLE_SHARE = 0.5


@dataclass(frozen=True, eq=False)
class Region:
    """A region of equivalence.

    Attributes
    ----------
    method : {"likelihood-ratio", "noise-monte-carlo"}
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

    def identifiability(self, space):
        """Per parameter: share of the search range its interval spans, and a verdict in words.

        Returns
        -------
        dict of str to dict
            ``{"share": float, "identifiable": bool, "message": str}``.
        """
        bounds = np.array([[self.intervals[n][k] for n in self.names] for k in (0, 1)])
        U = np.clip(space.to_unit(bounds), 0.0, 1.0)
        out = {}
        for j, name in enumerate(self.names):
            lo, hi = self.intervals[name]
            share = float(U[1, j] - U[0, j])
            ok = share <= UNIDENTIFIABLE_SHARE
            unit = self.units[j] if self.units[j] != "-" else ""
            msg = (
                f"{name} is identified: [{lo:.4g}, {hi:.4g}] {unit} spans {100 * share:.0f} % of its search range"
                if ok else
                f"{name} is NOT pinned down by these data: values from {lo:.4g} to {hi:.4g} {unit} "
                f"({100 * share:.0f} % of its search range) fit equally well; fix it from other tests, "
                "add sensors sensitive to it, or report it as unidentified"
            )
            out[name] = {"share": share, "identifiable": ok, "message": msg.replace("  ", " ")}
        return out


def likelihood_ratio_region(problem, x_best, *, confidence=0.95, n_samples=2**17, rng=0, max_grow=6, batch=2**16,
                            freeze_model_error=True):
    """Region of equivalence by the likelihood-ratio (χ²) bound, sampled densely.

    Parameters
    ----------
    problem : podkrig.inverse.InverseProblem
    x_best : ndarray of shape (n_free,)
        The best fit m*, physical units.
    confidence : float
        c in ω(m) − ω(m*) ≤ ½ χ²_p(c).
    n_samples : int
        Sobol points per sampling round (rounded to a power of two; ≥ 10⁵ recommended).
    rng : int or Generator
        Seed of the scrambled Sobol sequence.
    max_grow : int
        Rounds in which the sampling box may grow when members touch its faces.
    freeze_model_error : bool
        Evaluate the surrogate's predictive variance C_T once at m* and keep it over the region
        (it varies little there), so that only the mean is predicted: several times faster.

    Returns
    -------
    Region
    """
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
        if len(members) == 0:
            lo, hi = np.clip(u_best - 0.5 * (hi - lo), 0, 1), np.clip(u_best + 0.5 * (hi - lo), 0, 1)
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
                  tuple(space.units), n_eval, time.perf_counter() - t0)


def noise_monte_carlo_region(problem, x_best, *, n_realisations=200, confidence=0.95, rng=0):
    """Region of equivalence by noise Monte Carlo: re-identify from noisy copies of g(m*).

    Each copy adds Gaussian noise with the data covariance to the best-fit prediction and is
    re-identified by bounded least squares from m* (fast on the surrogate). Intervals are the
    central ``confidence`` percentiles of the re-identified parameters.
    """
    t0 = time.perf_counter()
    gen = np.random.default_rng(rng)
    meas = problem.measurement
    mean, _ = problem.misfit.predict(np.atleast_2d(x_best))
    C = problem.noise.covariance_matrix(meas)
    L = np.linalg.cholesky(C)
    X, n_eval = [], 0
    for _ in range(n_realisations):
        d = mean[0] + L @ gen.standard_normal(len(mean[0]))
        copy = Measurement(d.reshape(meas.values.shape), meas.sensor_names, meas.load_levels, source=meas.source + " (noisy copy)")
        sub = InverseProblem(problem.model, copy, problem.noise, problem.free, problem.fixed, problem.prior_mean,
                             problem.prior_cov, problem.kind, problem.model_error)
        x, n = sub.polish(x_best)
        X.append(x)
        n_eval += n
    X = np.array(X)
    a = 100 * (1 - confidence) / 2
    q = np.percentile(X, [a, 100 - a], axis=0)
    intervals = {n: (float(q[0, j]), float(q[1, j])) for j, n in enumerate(problem.free_space.names)}
    return Region("noise-monte-carlo", confidence, X, np.full(len(X), np.nan), float("nan"), intervals,
                  tuple(problem.free_space.names), tuple(problem.free_space.units), n_eval, time.perf_counter() - t0)


def rvc(region, model, *, fixed=None, outputs=None, max_samples=20000, rng=0):
    """Response variability of a (calibration or validation) model over a region of equivalence.

    Parameters
    ----------
    region : Region
    model : object
        A batched model (``space``, ``sensor_names``, ``load_levels``, ``predict``) whose space
        contains the region's parameters; its other parameters take the values in ``fixed``.
    fixed : dict of str to float, optional
    outputs : sequence of str, optional
        Output names ``"SENSOR@LOAD"`` to report (default: every sensor at the last load level).
    max_samples : int
        Region members used (a seeded random subset when there are more).

    Returns
    -------
    dict
        ``outputs`` (names), ``mean``, ``std``, ``cv`` (std/|mean|), ``range_ratio``
        ((max − min)/|mean|), ``min``, ``max`` — lists aligned with ``outputs`` — and
        ``n_samples``; plus ``values`` ``(n_samples, n_outputs)`` for figures.
    """
    fixed = dict(fixed or {})
    names = list(model.space.names)
    missing = [n for n in names if n not in region.names and n not in fixed]
    if missing:
        raise ValueError(f"RVC model needs values for {missing} (not calibrated): pass them as fixed")
    X = region.samples
    if len(X) > max_samples:
        X = X[np.random.default_rng(rng).choice(len(X), max_samples, replace=False)]
    full = np.empty((len(X), len(names)))
    for j, n in enumerate(names):
        full[:, j] = X[:, region.names.index(n)] if n in region.names else fixed[n]
    levels = np.asarray(model.load_levels, dtype=float)
    all_names = [f"{s}@{level:g}" for level in levels for s in model.sensor_names]
    if outputs is None:
        outputs = [f"{s}@{levels[-1]:g}" for s in model.sensor_names]
    unknown = [o for o in outputs if o not in all_names]
    if unknown:
        raise ValueError(f"unknown RVC output(s) {unknown}; outputs are SENSOR@LOAD, e.g. {all_names[:3]}")
    idx = [all_names.index(o) for o in outputs]
    Y, _ = model.predict(full, return_std=True)
    Y = Y[:, idx]
    mean = Y.mean(axis=0)
    std = Y.std(axis=0, ddof=1) if len(Y) > 1 else np.zeros_like(mean)
    scale = np.maximum(np.abs(mean), 1e-300)
    return {
        "outputs": list(outputs),
        "mean": mean.tolist(),
        "std": std.tolist(),
        "cv": (std / scale).tolist(),
        "range_ratio": ((Y.max(axis=0) - Y.min(axis=0)) / scale).tolist(),
        "min": Y.min(axis=0).tolist(),
        "max": Y.max(axis=0).tolist(),
        "n_samples": int(len(Y)),
        "values": Y,
    }


def information_criteria(result):
    """AIC and BIC of an inversion with Gaussian noise of known covariance.

    −2 log L = χ² + const, so AIC = χ² + 2k and BIC = χ² + k ln n (k free parameters, n
    observations); differences between nested analyses are what matter.
    """
    k, n = result.problem.n_free, result.problem.n_obs
    return {"aic": result.chi2 + 2 * k, "bic": result.chi2 + k * np.log(n)}


def nested_analyses(make_problem, free_sets, *, confidence=0.95, rng=0, validation=None, n_samples=2**16):
    """Compare nested sets of free parameters (thesis ch. 5, analyses 0–5).

    Parameters
    ----------
    make_problem : callable
        ``make_problem(free) -> InverseProblem`` for a tuple of free names.
    free_sets : sequence of sequence of str
    validation : dict of str to (model, fixed), optional
        Validation models for RVC.

    Returns
    -------
    list of dict
        Per analysis: ``free``, ``misfit``, ``chi2_dof``, ``aic``, ``bic``, ``intervals``,
        ``identifiability`` (with messages), ``rvc`` (per validation model: max CV).
    """
    rows = []
    for free in free_sets:
        problem = make_problem(tuple(free))
        result = invert(problem, rng=rng)
        region = likelihood_ratio_region(problem, result.x, confidence=confidence, rng=rng, n_samples=n_samples)
        row = {
            "free": list(free),
            "parameters": {n: result.parameters[n] for n in free},
            "misfit": result.misfit,
            "chi2_dof": result.chi2_dof,
            **information_criteria(result),
            "intervals": region.intervals,
            "identifiability": region.identifiability(problem.free_space),
        }
        if validation:
            row["rvc"] = {}
            for name, (model, fixed) in validation.items():
                fx = {**fixed, **{k: v for k, v in result.parameters.items() if k not in free and k in model.space.names}}
                row["rvc"][name] = max(rvc(region, model, fixed=fx, rng=rng)["cv"])
        rows.append(row)
    return rows


__all__ = [
    "Region", "likelihood_ratio_region", "noise_monte_carlo_region", "rvc", "information_criteria",
    "nested_analyses", "UNIDENTIFIABLE_SHARE",
]
