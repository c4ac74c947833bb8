"""Global sensitivity before the inversion: Sobol' indices of the readings (and of the misfit) over
the box of the free parameters, on the surrogate.

The papers' step 3 (parameter reduction before the inversion): a parameter that no reading is
sensitive to cannot be identified from the test and should be fixed. Variance-based indices over
the prior box (uniform in the unit-cube coordinates, i.e. log-uniform for log-scaled parameters)
of each output :math:`Y = g(m)`:

.. math::

    S_i = \\frac{V[E(Y \\mid m_i)]}{V(Y)}, \\qquad
    S_{Ti} = \\frac{E[V(Y \\mid m_{\\sim i})]}{V(Y)},

first order (the share of the variance that ``m_i`` explains alone) and total (with all its
interactions). Estimators: Saltelli et al. (2010) for :math:`S_i` and Jansen (1999) for
:math:`S_{Ti}`, as :func:`scipy.stats.sobol_indices` (``method="saltelli_2010"``) computes them
from the model values at two scrambled Sobol' matrices A, B and the ``d`` matrices A_B^i (A with
column i from B): ``n (d + 2)`` surrogate evaluations for ``n`` base samples. Confidence
intervals: percentile bootstrap over the ``n`` base rows (each replicate resamples rows of
A, B, A_B^i together and re-applies the same estimators, as reweighted row means: one matrix
product for all replicates; scipy's own ``bootstrap`` method took minutes for 200 replicates).

A parameter is *proposed for fixing* when its total index stays below ``threshold`` (default
0.01: it explains under 1 % of the variance) for every reading — and for the misfit when a
measurement is given, which weighs the readings by their noise.
"""

import time
from dataclasses import dataclass

import numpy as np
from scipy import stats

from podkrig._qmc import scrambled_sobol
from podkrig.display import Displayed
from podkrig.online.problem import fix_from_scenario, unit_template
from podkrig.online.settings import SENSITIVITY

#: total index below which a parameter is proposed for fixing (1 % of an output's variance)
NEGLIGIBLE_TOTAL_INDEX = 0.01
#: relative standard deviation at or below which an output counts as constant over the box (its
#: spread is the surrogate's round-off, ~1e-14 of its size)
ROUND_OFF = 1e-10


@dataclass(frozen=True, eq=False, repr=False)
class SensitivityResult(Displayed):
    """Sobol' indices of several outputs over the free parameters.

    Attributes
    ----------
    parameters : tuple of str
        Free parameters, ``d``.
    outputs : tuple of str
        Output names (``"SENSOR@LOAD"`` for readings, ``"misfit"`` for ω), ``s``.
    first, total : ndarray of shape (s, d)
        First-order and total indices (-).
    first_low, first_high, total_low, total_high : ndarray of shape (s, d)
        Bootstrap percentile interval at ``confidence``.
    variance : ndarray of shape (s,)
        Output variance over the box (output units², mm² for readings); an output whose standard
        deviation is at most :data:`ROUND_OFF` of its largest magnitude counts as constant:
        variance 0 and NaN indices.
    confidence : float
    n_base : int
        Base samples ``n``; the model was evaluated ``n (d + 2)`` times.
    seconds : float
    """

    parameters: tuple
    outputs: tuple
    first: np.ndarray
    total: np.ndarray
    first_low: np.ndarray
    first_high: np.ndarray
    total_low: np.ndarray
    total_high: np.ndarray
    variance: np.ndarray
    confidence: float
    n_base: int
    seconds: float

    @property
    def n_evaluations(self):
        return self.n_base * (len(self.parameters) + 2)

    @property
    def max_total(self):
        """Largest total index of each parameter over the outputs with variance, ``(d,)``."""
        return np.nanmax(np.where(self.variance[:, None] > 0, self.total, np.nan), axis=0)

    def negligible(self, threshold=NEGLIGIBLE_TOTAL_INDEX):
        """Parameters whose total index stays below ``threshold`` for every output: proposed for
        fixing (tuple of str)."""
        return tuple(n for n, t in zip(self.parameters, self.max_total) if t < threshold)

    def to_dict(self):
        arrays = ("first", "total", "first_low", "first_high", "total_low", "total_high")
        return {
            "parameters": list(self.parameters), "outputs": list(self.outputs),
            **{k: np.asarray(getattr(self, k)).tolist() for k in arrays},
            "variance": self.variance.tolist(), "confidence": self.confidence, "n_base": self.n_base,
            "n_evaluations": self.n_evaluations, "seconds": self.seconds,
            "max_total": dict(zip(self.parameters, self.max_total.tolist())),
            "negligible": list(self.negligible()), "threshold": NEGLIGIBLE_TOTAL_INDEX,
        }

    @classmethod
    def from_dict(cls, d):
        arrays = ("first", "total", "first_low", "first_high", "total_low", "total_high")
        return cls(tuple(d["parameters"]), tuple(d["outputs"]),
                   *(np.asarray(d[k], dtype=float) for k in arrays), np.asarray(d["variance"], dtype=float),
                   float(d["confidence"]), int(d["n_base"]), float(d["seconds"]))


def sobol_indices(fun_unit, parameters, outputs, *, n=SENSITIVITY.n, rng=SENSITIVITY.seed,
                  confidence=SENSITIVITY.confidence, n_resamples=200):
    """Sobol' indices of a batched function of the unit cube.

    Parameters
    ----------
    fun_unit : callable
        ``fun_unit(U) -> Y``: ``U`` ``(m, d)`` in [0, 1], ``Y`` ``(m, s)`` (or ``(m,)`` for one
        output); called once on all ``n (d + 2)`` points (batch it inside if memory matters).
    parameters : sequence of str
        Names of the ``d`` inputs.
    outputs : sequence of str
        Names of the ``s`` outputs.
    n : int
        Base samples, a power of two (default: :class:`~podkrig.online.settings.SensitivitySettings`).
    rng : int or numpy.random.Generator
        Source of the scrambled Sobol' matrices and of the bootstrap (an integer gives the same
        indices on every run).
    confidence : float
        Level of the bootstrap intervals.
    n_resamples : int
        Bootstrap replicates.

    Returns
    -------
    SensitivityResult
    """
    if n < 2 or n & (n - 1):
        raise ValueError(f"n must be a power of two >= 2 (base samples of the Sobol' design); got {n}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1); got {confidence}")
    if n_resamples < 10:
        raise ValueError(f"n_resamples must be >= 10 for a percentile interval; got {n_resamples}")
    t0 = time.perf_counter()
    d = len(parameters)
    AB = scrambled_sobol(n, 2 * d, rng)
    A, B = AB[:, :d], AB[:, d:]
    mixed = np.repeat(A[None], d, axis=0)  # (d, n, d): A with column i from B
    mixed[np.arange(d), :, np.arange(d)] = B.T
    Y = np.asarray(fun_unit(np.vstack([A, B, mixed.reshape(-1, d)])), dtype=float)
    Y = Y.reshape(len(Y), -1)
    s = Y.shape[1]
    if s != len(outputs):
        raise ValueError(f"fun_unit returned {s} outputs for {len(outputs)} output names")
    f_A, f_B = Y[:n].T, Y[n : 2 * n].T  # (s, n)
    f_AB = Y[2 * n :].reshape(d, n, s).transpose(0, 2, 1)  # (d, s, n)
    variance = np.var(np.concatenate([f_A, f_B], axis=1), axis=1)
    # an output whose spread is round-off of its own size (a reading at an elastic level, which no
    # strength parameter moves) is constant: its indices would be ratios of rounding errors
    live = variance > (ROUND_OFF * np.abs(f_A).max(axis=1)) ** 2 + 1e-300
    variance = np.where(live, variance, 0.0)
    first, total = _estimate(f_A, f_B, f_AB, live)
    boot_first, boot_total = _bootstrap(f_A, f_B, f_AB, live, n_resamples, np.random.default_rng(rng))
    q = 100 * np.array([(1 - confidence) / 2, (1 + confidence) / 2])
    fl, fh = np.percentile(boot_first, q, axis=0)
    tl, th = np.percentile(boot_total, q, axis=0)
    return SensitivityResult(tuple(parameters), tuple(outputs), first, total, fl, fh, tl, th, variance,
                             float(confidence), int(n), time.perf_counter() - t0)


def _estimate(f_A, f_B, f_AB, live):
    """First-order and total indices ``(s, d)`` by scipy's Saltelli-2010/Jansen estimators; NaN for
    outputs without variance.

    A single live output is passed twice (the estimators work output by output): scipy 1.17 turns
    the indices of one output of one parameter into a scalar and then fails writing into it."""
    first = np.full((f_A.shape[0], f_AB.shape[0]), np.nan)
    total = first.copy()
    if live.any():
        fa, fb, fab = f_A[live], f_B[live], f_AB[:, live]
        k = len(fa)
        if k == 1:
            fa, fb, fab = np.repeat(fa, 2, axis=0), np.repeat(fb, 2, axis=0), np.repeat(fab, 2, axis=1)
        res = stats.sobol_indices(func={"f_A": fa, "f_B": fb, "f_AB": fab}, n=f_A.shape[1])
        first[live] = np.reshape(res.first_order, (-1, f_AB.shape[0]))[:k]
        total[live] = np.reshape(res.total_order, (-1, f_AB.shape[0]))[:k]
    return first, total


def _bootstrap(f_A, f_B, f_AB, live, n_resamples, rng):
    """Bootstrap replicates of the indices, ``(n_resamples, s, d)`` each.

    The estimators are ratios of row means — :math:`\\overline{f^2} - \\bar f^2` over the rows of A
    and B (the variance), :math:`\\overline{(f_B - \\bar f)(f_{AB_i} - f_A)}` (scipy centres the
    outputs first) and :math:`\\tfrac12 \\overline{(f_A - f_{AB_i})^2}` — so a replicate that draws
    row ``k`` ``w_k`` times only reweights those means: every replicate at once is one product of
    the per-row terms with the ``(n_resamples, n)`` matrix of multinomial counts (no resampled
    copies of the data).
    With all counts 1 this is exactly :func:`_estimate` (tested).
    """
    n = f_A.shape[1]
    d, s = f_AB.shape[0], f_A.shape[0]
    W = rng.multinomial(n, np.full(n, 1.0 / n), size=n_resamples).astype(float) / n  # (R, n), rows sum to 1
    first = np.full((n_resamples, s, d), np.nan)
    total = first.copy()
    if not live.any():
        return first, total
    fa, fb, fab = f_A[live], f_B[live], f_AB[:, live]  # (s', n), (d, s', n)
    moments = W @ np.stack([fa, fb, fa * fa, fb * fb]).reshape(-1, n).T  # (R, 4 s')
    m_a, m_b, m2_a, m2_b = moments.reshape(n_resamples, 4, -1).transpose(1, 0, 2)
    mean = 0.5 * (m_a + m_b)
    var = 0.5 * (m2_a + m2_b) - mean**2  # (R, s'): A and B rows pooled, as scipy does
    diff = fab - fa[None]  # (d, s', n)
    p0 = diff.reshape(-1, n)
    p1 = (fb[None] * diff).reshape(-1, n)
    p2 = (0.5 * diff**2).reshape(-1, n)
    # scipy centres the outputs by the pooled mean first (Sobol' & Levitan 1999): mean((f_B − μ) Δ)
    centred = (W @ p1.T).reshape(n_resamples, d, -1) - (W @ p0.T).reshape(n_resamples, d, -1) * mean[:, None, :]
    S1 = centred.transpose(0, 2, 1) / var[:, :, None]
    ST = (W @ p2.T).reshape(n_resamples, d, -1).transpose(0, 2, 1) / var[:, :, None]
    first[:, live], total[:, live] = S1, ST
    return first, total


def reading_sensitivity(model, *, free=None, fixed=None, **options):
    """Sobol' indices of every reading of ``model`` (a :class:`~podkrig.online.problem.SurrogateModel`
    or any model with ``space``, ``sensor_names``, ``load_levels`` and ``predict_unit`` or
    ``predict``) over the box of the free parameters, the others at ``fixed``.

    ``free``/``fixed`` as in :func:`~podkrig.online.problem.fix_from_scenario` (unfree parameters
    keep the scenario's values). ``options``: see :func:`sobol_indices`.
    """
    free, fixed = fix_from_scenario(model, free, fixed)
    space = model.space
    names = tuple(space.names if free is None else free)
    index = np.array([space.names.index(nm) for nm in names])
    template_unit = unit_template(space, index, fixed)

    def readings(U):
        full = np.tile(template_unit, (len(U), 1))
        full[:, index] = U
        if hasattr(model, "predict_unit"):
            return model.predict_unit(full)
        return model.predict(space.from_unit(full))

    outputs = tuple(f"{s}@{level:g}" for level in model.load_levels for s in model.sensor_names)
    return sobol_indices(readings, names, outputs, **options)


def misfit_sensitivity(problem, **options):
    """Sobol' indices of the misfit ω (thesis eq. 2.13) of an
    :class:`~podkrig.online.problem.InverseProblem` over its free box: the readings weighed by
    their noise. ``options``: see :func:`sobol_indices`."""
    return sobol_indices(problem.omega_unit, problem.free, ("misfit",), **options)


__all__ = ["NEGLIGIBLE_TOTAL_INDEX", "SensitivityResult", "misfit_sensitivity", "reading_sensitivity",
           "sobol_indices"]
