"""Vectorised genetic operators: initialisation, scaling, selection, crossover, mutation.

The operators of the genetic algorithm of the thesis, chapter 3, as implemented in TOSCA [1]_,
written as pure functions on whole populations (no Python loop over individuals).

Conventions
-----------
- Genes live in the unit hypercube: a population is ``U`` of shape ``(n_individuals, n_params)``
  with values in [0, 1]. The mapping to physical values (linear or log scale) belongs to the
  parameter space, not to the operators.
- Integer genes (thesis ch. 3, "integer representation") are the grid points
  ``u_i = g_i / N_i`` with ``g_i ∈ {0, …, N_i}``; the physical value is then
  ``x_i = lo_i + g_i (hi_i − lo_i) / N_i`` for a linear scale. Real-valued recombination is
  rounded back to the grid and clipped by :func:`snap_to_grid`.
- ``cost`` is what the GA minimises (the objective, or the constraint-handled cost of
  :func:`deb_cost` / :func:`penalty_cost`); ``fitness`` is the non-negative, larger-is-better
  quantity that fitness-proportional selection needs (:func:`scale_fitness`).
- Randomness comes only from the ``rng`` argument (a :class:`numpy.random.Generator`).

References
----------
.. [1] C. Chisari, C. Amadio, "TOSCA: a Tool for Optimisation in Structural and Civil
   engineering Analyses", Int. J. Adv. Struct. Eng. 10 (2018) 401–419,
   doi:10.1007/s40091-018-0205-1.
.. [2] K. Deb, "An efficient constraint handling method for genetic algorithms", Comput.
   Methods Appl. Mech. Engrg. 186 (2000) 311–338.
.. [3] J. E. Baker, "Reducing bias and inefficiency in the selection algorithm", Proc. 2nd
   Int. Conf. on Genetic Algorithms (1987) 14–21.
.. [4] L. J. Eshelman, J. D. Schaffer, "Real-coded genetic algorithms and interval-schemata",
   Foundations of Genetic Algorithms 2 (1993) 187–202.
.. [5] D. E. Goldberg, *Genetic Algorithms in Search, Optimization and Machine Learning*,
   Addison-Wesley (1989), ch. 3 (linear fitness scaling).
.. [6] J. E. Baker, "Adaptive selection methods for genetic algorithms", Proc. 1st Int. Conf.
   on Genetic Algorithms (1985) 101–111 (linear ranking).
"""

from __future__ import annotations

import logging

import numpy as np

from podkrig._qmc import scrambled_sobol

logger = logging.getLogger(__name__)

__all__ = [
    "constraint_violation",
    "crossover_arithmetical",
    "crossover_blx",
    "crossover_single_point",
    "deb_cost",
    "initial_population",
    "mutate_gaussian",
    "mutate_uniform",
    "penalty_cost",
    "scale_fitness",
    "select_roulette",
    "select_sus",
    "select_tournament",
    "snap_to_grid",
]


def initial_population(n_individuals, n_params, *, method, rng):
    """Draw the initial population in the unit hypercube.

    Parameters
    ----------
    n_individuals : int
        Population size.
    n_params : int
        Number of genes (parameters).
    method : {"sobol", "random"}
        ``"sobol"``: a scrambled Sobol' sequence (``scipy.stats.qmc.Sobol``) seeded from ``rng``;
        the first ``n_individuals`` points of a base-2 block of ``2**ceil(log2 n)`` points are
        taken, so a power-of-two population keeps the balance properties of the sequence.
        ``"random"``: independent uniform draws.
    rng : numpy.random.Generator
        Source of randomness.

    Returns
    -------
    U : ndarray of shape (n_individuals, n_params)
        Genes in [0, 1).
    """
    if method == "sobol":
        m = max(0, int(np.ceil(np.log2(n_individuals))))
        return scrambled_sobol(2**m, n_params, rng)[:n_individuals]
    if method == "random":
        return rng.random((n_individuals, n_params))
    raise ValueError(f"init must be 'sobol' or 'random'; got {method!r}")


def snap_to_grid(U, n_grid):
    """Round genes to the integer grid and clip them to the unit hypercube (in place).

    Parameters
    ----------
    U : ndarray of shape (n_individuals, n_params)
        Real-valued genes, possibly outside [0, 1] after recombination; modified in place.
    n_grid : ndarray of shape (n_params,) of int, or None
        Number of grid intervals ``N_i`` per parameter; ``None`` for real coding (clip only).

    Returns
    -------
    U : ndarray of shape (n_individuals, n_params)
        The same array, with ``U[:, i] ∈ {0, 1/N_i, …, 1}`` (or clipped to [0, 1]).
    """
    np.clip(U, 0.0, 1.0, out=U)
    if n_grid is not None:
        U *= n_grid
        np.rint(U, out=U)
        U /= n_grid
    return U


def constraint_violation(G):
    r"""Total constraint violation of each individual.

    .. math:: v(x) = \sum_j \max(0, g_j(x))

    Parameters
    ----------
    G : ndarray of shape (n_individuals, n_constraints)
        Constraint values; ``g_j(x) <= 0`` means satisfied.

    Returns
    -------
    violation : ndarray of shape (n_individuals,)
        Zero exactly for feasible individuals.
    """
    return np.maximum(G, 0.0).sum(axis=1)


def deb_cost(f, violation):
    r"""Scalar cost that implements Deb's feasibility rules [2]_.

    Deb's tournament rules are: (i) a feasible solution beats an infeasible one; (ii) of two
    feasible solutions the one with lower objective wins; (iii) of two infeasible solutions the
    one with lower violation wins. The penalty-parameter-less cost of [2]_, eq. (4),

    .. math::

        F(x) = \begin{cases} f(x) & v(x) = 0 \\
               f_{\max} + v(x) & v(x) > 0 \end{cases}

    with :math:`f_{\max}` the worst objective among the feasible individuals of the population
    (0 if there are none), orders any population exactly as the rules do, so it can drive every
    selection scheme, not only tournaments.

    Parameters
    ----------
    f : ndarray of shape (n_individuals,)
        Objective values.
    violation : ndarray of shape (n_individuals,)
        Total violation from :func:`constraint_violation`.

    Returns
    -------
    cost : ndarray of shape (n_individuals,)
    """
    feasible = violation <= 0.0
    f_max = f[feasible].max() if feasible.any() else 0.0
    return np.where(feasible, f, f_max + violation)


def penalty_cost(f, violation, penalty):
    r"""Static (exterior, exact L1) penalty cost, :math:`F = f + r\,v(x)`.

    Parameters
    ----------
    f, violation : ndarray of shape (n_individuals,)
        Objective and total violation.
    penalty : float
        Penalty factor ``r`` > 0, in units of the objective per unit of violation. The L1 penalty
        is exact (its minimiser is the constrained one) once ``r`` exceeds the largest Lagrange
        multiplier of the problem.

    Returns
    -------
    cost : ndarray of shape (n_individuals,)
    """
    return f + penalty * violation


def _ranks(cost):
    """Rank 0 for the lowest cost; ties broken by index (stable)."""
    order = np.argsort(cost, kind="stable")
    ranks = np.empty(cost.size, dtype=np.intp)
    ranks[order] = np.arange(cost.size)
    return ranks


def scale_fitness(cost, method, *, pressure=2.0, eta_plus=1.5, base=0.9):
    r"""Turn costs (lower is better) into non-negative fitness for proportional selection.

    Parameters
    ----------
    cost : ndarray of shape (n_individuals,)
        Costs; ``+inf`` is allowed and receives zero fitness.
    method : {"none", "linear", "linear_ranking", "exponential_ranking"}
        ``"none"``: raw fitness :math:`\phi = F_{\max} - F` (worst finite cost minus cost).
        ``"linear"``: Goldberg's linear scaling [5]_ of the raw fitness,
        :math:`\phi' = a\phi + b` with :math:`\bar\phi' = \bar\phi` and
        :math:`\max\phi' = C\,\bar\phi`; if that would make some :math:`\phi'` negative, the
        scaling is instead chosen with :math:`\min\phi' = 0` (same mean).
        ``"linear_ranking"``: Baker's linear ranking [6]_, individual of rank :math:`r`
        (0 = best) gets :math:`\eta^+ - (\eta^+ - \eta^-)\,r/(n-1)`, :math:`\eta^- = 2 - \eta^+`.
        ``"exponential_ranking"``: :math:`c^{\,r}` with base :math:`c \in (0, 1)`.
    pressure : float, default 2.0
        ``C`` of linear scaling, > 1 (expected copies of the best individual).
    eta_plus : float, default 1.5
        :math:`\eta^+ \in [1, 2]` of linear ranking (expected copies of the best).
    base : float, default 0.9
        :math:`c \in (0, 1)` of exponential ranking; smaller is greedier.

    Returns
    -------
    fitness : ndarray of shape (n_individuals,)
        Non-negative; not normalised.
    """
    n = cost.size
    if method in ("linear_ranking", "exponential_ranking"):
        ranks = _ranks(cost)
        if method == "linear_ranking":
            eta_minus = 2.0 - eta_plus
            return eta_plus - (eta_plus - eta_minus) * ranks / max(n - 1, 1)
        return base ** ranks.astype(float)
    finite = np.isfinite(cost)
    if not finite.any():
        return np.ones(n)
    raw = np.where(finite, cost[finite].max() - cost, 0.0)
    if method == "none":
        return raw
    if method != "linear":
        raise ValueError(
            "scaling must be 'none', 'linear', 'linear_ranking' or 'exponential_ranking'; "
            f"got {method!r}"
        )
    mean, top, low = raw.mean(), raw.max(), raw.min()
    if top - mean <= 1e-300 * max(1.0, abs(mean)):
        return np.ones(n)
    if low > (pressure * mean - top) / (pressure - 1.0):
        # Goldberg (1989): max φ' = C·mean φ, mean preserved
        a = (pressure - 1.0) * mean / (top - mean)
    else:
        # the line through (mean, mean) with φ'(min φ) = 0
        a = mean / (mean - low)
    return np.maximum(a * (raw - mean) + mean, 0.0)


def select_tournament(cost, n_select, size, rng):
    """Tournament selection: the lowest cost among ``size`` contestants drawn with replacement.

    Parameters
    ----------
    cost : ndarray of shape (n_individuals,)
    n_select : int
        Number of parents to select.
    size : int
        Tournament size ``s`` >= 1; larger is greedier.
    rng : numpy.random.Generator

    Returns
    -------
    index : ndarray of shape (n_select,) of int
        Indices of the selected individuals.
    """
    contestants = rng.integers(0, cost.size, size=(n_select, size))
    winner = np.argmin(cost[contestants], axis=1)
    return contestants[np.arange(n_select), winner]


def _cumulative(fitness):
    total = fitness.sum()
    if not total > 0.0:
        fitness = np.ones_like(fitness)
        total = float(fitness.size)
    return np.cumsum(fitness), total


def select_roulette(fitness, n_select, rng):
    """Roulette-wheel selection: ``n_select`` independent spins, probability ∝ fitness.

    Parameters
    ----------
    fitness : ndarray of shape (n_individuals,)
        Non-negative fitness (:func:`scale_fitness`); all zero means uniform.
    n_select : int
    rng : numpy.random.Generator

    Returns
    -------
    index : ndarray of shape (n_select,) of int
    """
    cumulative, total = _cumulative(fitness)
    index = np.searchsorted(cumulative, rng.random(n_select) * total, side="right")
    return np.minimum(index, fitness.size - 1)


def select_sus(fitness, n_select, rng):
    """Stochastic universal sampling (Baker 1987 [3]_), returned in random order.

    One spin of a wheel with ``n_select`` equally spaced pointers: every individual is
    selected either ⌊e_i⌋ or ⌈e_i⌉ times, ``e_i`` being its expected count — the minimum
    spread of any unbiased proportional scheme. The selection is shuffled so that mating
    pairs are random.

    Parameters
    ----------
    fitness : ndarray of shape (n_individuals,)
    n_select : int
    rng : numpy.random.Generator

    Returns
    -------
    index : ndarray of shape (n_select,) of int
    """
    cumulative, total = _cumulative(fitness)
    pointers = (rng.random() + np.arange(n_select)) * (total / n_select)
    index = np.minimum(np.searchsorted(cumulative, pointers, side="right"), fitness.size - 1)
    return rng.permutation(index)


def crossover_single_point(P1, P2, rng):
    """Single-point crossover: the children swap the genes after a random cut.

    Parameters
    ----------
    P1, P2 : ndarray of shape (n_pairs, n_params)
        Parents, paired by row.
    rng : numpy.random.Generator

    Returns
    -------
    C1, C2 : ndarray of shape (n_pairs, n_params)
        Children. With one parameter there is no cut and the children copy the parents.
    """
    n_pairs, n_params = P1.shape
    if n_params < 2:
        return P1.copy(), P2.copy()
    cut = rng.integers(1, n_params, size=(n_pairs, 1))
    tail = np.arange(n_params) >= cut
    return np.where(tail, P2, P1), np.where(tail, P1, P2)


def crossover_arithmetical(P1, P2, lam):
    r"""Arithmetical (whole) crossover, :math:`c_1 = \lambda p_1 + (1-\lambda) p_2`,
    :math:`c_2 = (1-\lambda) p_1 + \lambda p_2`.

    Parameters
    ----------
    P1, P2 : ndarray of shape (n_pairs, n_params)
    lam : float or ndarray of shape (n_pairs, 1)
        Blend weight: one value per mating drawn from U(0, 1) (arithmetical crossover), or a
        fixed user value (fixed arithmetical crossover).

    Returns
    -------
    C1, C2 : ndarray of shape (n_pairs, n_params)
    """
    D = P1 - P2
    return P2 + lam * D, P1 - lam * D


def crossover_blx(P1, P2, alpha, rng):
    r"""BLX-α crossover (Eshelman & Schaffer 1993 [4]_).

    Each child gene is drawn independently from
    :math:`U[\min(p_1, p_2) - \alpha I,\ \max(p_1, p_2) + \alpha I]`, :math:`I = |p_1 - p_2|`.
    Genes leaving [0, 1] are clipped afterwards by :func:`snap_to_grid`.

    Parameters
    ----------
    P1, P2 : ndarray of shape (n_pairs, n_params)
    alpha : float
        Extension of the parents' interval, >= 0; 0.5 keeps the gene variance of the
        population unchanged on average [4]_.
    rng : numpy.random.Generator

    Returns
    -------
    C1, C2 : ndarray of shape (n_pairs, n_params)
    """
    low = np.minimum(P1, P2)
    width = np.abs(P1 - P2)
    r = rng.random((2,) + P1.shape)
    r *= 1.0 + 2.0 * alpha
    r -= alpha
    r *= width
    r += low
    return r[0], r[1]


def mutate_uniform(U, probability, n_grid, rng):
    """Uniform-reset mutation (in place): each gene is redrawn with probability ``probability``.

    Parameters
    ----------
    U : ndarray of shape (n_individuals, n_params)
        Genes in [0, 1]; modified in place.
    probability : float
        Per-gene mutation probability ``p_m``.
    n_grid : ndarray of shape (n_params,) of int, or None
        Grid intervals: a mutated gene is redrawn uniformly among the ``N_i + 1`` grid points;
        ``None`` for a uniform draw on [0, 1].
    rng : numpy.random.Generator

    Returns
    -------
    U : ndarray of shape (n_individuals, n_params)
    """
    rows, cols = np.nonzero(rng.random(U.shape) < probability)
    new = rng.random(rows.size)
    if n_grid is not None:
        n = n_grid[cols]
        new = np.floor(new * (n + 1)) / n
    U[rows, cols] = new
    return U


def mutate_gaussian(U, probability, scale, n_grid, rng):
    """Gaussian creep mutation (in place): ``u + σ z``, ``z ~ N(0, 1)``, then clipped.

    On an integer grid the step is rounded to whole grid intervals and is at least one
    interval, so a mutation always moves the gene (before clipping at the bounds).

    Parameters
    ----------
    U : ndarray of shape (n_individuals, n_params)
        Genes in [0, 1]; modified in place.
    probability : float
        Per-gene mutation probability ``p_m``.
    scale : float
        Standard deviation σ as a fraction of the parameter range (unit-cube length).
    n_grid : ndarray of shape (n_params,) of int, or None
    rng : numpy.random.Generator

    Returns
    -------
    U : ndarray of shape (n_individuals, n_params)
    """
    rows, cols = np.nonzero(rng.random(U.shape) < probability)
    step = scale * rng.standard_normal(rows.size)
    if n_grid is not None:
        n = n_grid[cols]
        k = np.rint(step * n)
        k = np.where(k == 0.0, np.where(step < 0.0, -1.0, 1.0), k)
        step = k / n
    U[rows, cols] = np.clip(U[rows, cols] + step, 0.0, 1.0)
    return U
