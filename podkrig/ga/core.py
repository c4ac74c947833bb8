"""Genetic algorithm of the thesis, chapter 3 (TOSCA): steppable solver, result, ``minimize``.

The genetic algorithm (GA) minimises an objective over a box of parameters, evaluating the whole
population in one call of the objective (a surrogate's ``predict`` is batched). Genes live in the
unit hypercube; a parameter space object (``names``, ``to_unit``, ``from_unit``; linear or log
scale) or plain ``(low, high)`` bounds map them to physical values.

The options live in :class:`~podkrig.ga.options.GAOptions` (documented and validated there).
This module is long (~820 lines, about 40 % of it documentation) because it is one class, the
steppable GA with its bookkeeping, and the local polish that runs through the GA's own
evaluation path (budget, target, history); splitting them would expose that path.

Conventions: ``X`` has shape ``(n_individuals, n_params)`` in physical units; the objective
returns ``f`` of shape ``(n_individuals,)``; optional constraints return ``G`` of shape
``(n_individuals, n_constraints)`` with ``g_j(x) <= 0`` meaning satisfied.

Example
-------
>>> import numpy as np
>>> from podkrig.ga import minimize
>>> res = minimize(lambda X: np.sum(X**2, axis=1), [(-1.0, 2.0)] * 3, rng=0, target=1e-10)
>>> res.success, bool(np.all(np.abs(res.x) < 1e-4))
(True, True)

References
----------
.. [1] C. Chisari, C. Amadio, "TOSCA: a Tool for Optimisation in Structural and Civil
   engineering Analyses", Int. J. Adv. Struct. Eng. 10 (2018) 401–419,
   doi:10.1007/s40091-018-0205-1; and C. Chisari, PhD thesis, ch. 3.
.. [2] K. Deb, "An efficient constraint handling method for genetic algorithms", Comput.
   Methods Appl. Mech. Engrg. 186 (2000) 311–338.
.. [3] L. J. Eshelman, J. D. Schaffer, "Real-coded genetic algorithms and interval-schemata",
   Foundations of Genetic Algorithms 2 (1993) 187–202.
.. [4] J. E. Baker, "Reducing bias and inefficiency in the selection algorithm", Proc. 2nd
   Int. Conf. on Genetic Algorithms (1987) 14–21.
.. [5] W. E. Hart, N. Krasnogor, J. E. Smith (eds.), *Recent Advances in Memetic Algorithms*,
   Springer (2005) (GA + local search, Lamarckian replacement).
"""

from __future__ import annotations

import logging
import numbers
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import optimize

from podkrig.display import Displayed
from podkrig.ga import operators as ops
from podkrig.ga.options import GABudgetWarning, GAOptions

logger = logging.getLogger(__name__)

__all__ = ["GAResult", "GeneticAlgorithm", "minimize"]

_STOP_MESSAGES = {
    "target": "target f <= {target:g} reached at evaluation {nfev}",
    "stall": "no improvement > {stall_tol:g} in {stall_generations} generations",
    "max_generations": "maximum number of generations ({max_generations}) reached",
    "max_evaluations": "maximum number of evaluations ({max_evaluations}) reached",
    "callback": "stopped by the callback at generation {generation}",
}
_SUCCESSFUL_STOPS = ("target", "stall")


@dataclass(frozen=True, repr=False)
class GAResult(Displayed):
    """Outcome of a genetic-algorithm run (all arrays read-only, physical units).

    Attributes
    ----------
    x : ndarray of shape (n_params,)
        Best individual: lowest objective among feasible ones, or lowest violation if none is
        feasible (Deb's ordering [2]_, also with the penalty option).
    fun : float
        Objective at ``x``.
    violation : float
        Total constraint violation at ``x``, ``sum_j max(0, g_j)``; 0 when feasible.
    nfev : int
        Objective evaluations, polish included. With ``target``, counted up to and including
        the first evaluation that reached it.
    ngen : int
        Generations after the initial population (generation 0).
    success : bool
        True when the run stopped on ``target`` or on stall (converged) with a feasible
        ``x``; False when a budget (generations, evaluations) ran out, the callback stopped
        it, or no feasible individual was found.
    stop_reason : {"target", "stall", "max_generations", "max_evaluations", "callback"}
    message : str
        Human-readable stop reason.
    X_history : ndarray of shape (nfev, n_params)
        Every evaluated individual, in evaluation order.
    f_history : ndarray of shape (nfev,)
        Their objective values.
    violation_history : ndarray of shape (nfev,)
        Their total constraint violation (zeros without constraints).
    generation_history : ndarray of shape (nfev,) of int
        Generation in which each was evaluated (0 = initial population).
    polish_mask : ndarray of shape (nfev,) of bool
        True for evaluations made by the local polish.
    generation_best, generation_mean, generation_std : ndarray of shape (ngen + 1,)
        Per generation, over the population after replacement: best feasible objective (NaN
        if none is feasible), mean and standard deviation of the objective.
    generation_nfev : ndarray of shape (ngen + 1,) of int
        Cumulative evaluations at the end of each generation.
    population : ndarray of shape (population_size, n_params)
        Final population.
    population_fun, population_violation : ndarray of shape (population_size,)
        Its objective values and constraint violation.
    parameter_names : tuple of str
        From the parameter space, or ``("x0", "x1", …)``.
    parameter_units : tuple of str or None
        From the parameter space's optional ``units`` attribute.
    seed : int or None
        The integer seed given as ``rng`` (None if a Generator or None was given).
    n_restarts : int
        Restarts after a stall (see ``on_stall`` of :class:`GeneticAlgorithm`).
    """

    x: np.ndarray
    fun: float
    violation: float
    nfev: int
    ngen: int
    success: bool
    stop_reason: str
    message: str
    X_history: np.ndarray
    f_history: np.ndarray
    violation_history: np.ndarray
    generation_history: np.ndarray
    polish_mask: np.ndarray
    generation_best: np.ndarray
    generation_mean: np.ndarray
    generation_std: np.ndarray
    generation_nfev: np.ndarray
    population: np.ndarray
    population_fun: np.ndarray
    population_violation: np.ndarray
    parameter_names: tuple[str, ...]
    parameter_units: tuple[str, ...] | None = None
    seed: int | None = None
    n_restarts: int = 0

    def __post_init__(self):
        for value in vars(self).values():
            if isinstance(value, np.ndarray):
                value.flags.writeable = False

    def to_dict(self, *, history=False):
        """JSON-able (strict JSON: a NaN or ±inf is None): the best individual ``x`` and by name
        ``parameters`` (with ``units`` when the space has them), ``fun``, ``violation``, ``nfev``,
        ``ngen``, ``success``, ``stop_reason``, ``message``, ``seed``, ``n_restarts`` and the
        convergence per generation (``generation_best``, ``generation_mean``, ``generation_std``,
        ``generation_nfev``: ``ngen + 1`` numbers each). With ``history``, also every evaluation
        (``X_history`` ``(nfev, n_params)``, ``f_history``, ``violation_history``,
        ``generation_history``, ``polish_mask``) and the final population (``population``,
        ``population_fun``, ``population_violation``): ``nfev × (n_params + 4)`` numbers."""
        out = {
            "x": _json_floats(self.x),
            "parameters": dict(zip(self.parameter_names, _json_floats(self.x))),
            **({"units": dict(zip(self.parameter_names, self.parameter_units))} if self.parameter_units else {}),
            "fun": _json_floats(self.fun), "violation": _json_floats(self.violation), "nfev": int(self.nfev),
            "ngen": int(self.ngen), "success": bool(self.success), "stop_reason": self.stop_reason,
            "message": self.message, "seed": self.seed, "n_restarts": int(self.n_restarts),
            "generation_best": _json_floats(self.generation_best), "generation_mean": _json_floats(self.generation_mean),
            "generation_std": _json_floats(self.generation_std), "generation_nfev": self.generation_nfev.tolist(),
        }
        if history:
            out.update({name: _json_floats(getattr(self, name)) for name in (
                "X_history", "f_history", "violation_history", "population", "population_fun", "population_violation")})
            out.update(generation_history=self.generation_history.tolist(), polish_mask=self.polish_mask.tolist())
        return out


def _json_floats(a):
    """A float or an array of floats as JSON numbers (nested lists), a non-finite value as None."""
    a = np.asarray(a, dtype=float)
    return np.where(np.isfinite(a), a, None).tolist()


class _BoxSpace:
    """Linear map between the unit cube and ``(low, high)`` bounds."""

    def __init__(self, bounds):
        try:
            B = np.asarray(bounds, dtype=float)
        except (TypeError, ValueError) as e:
            raise TypeError(
                "bounds must be a sequence of (low, high) pairs or a parameter space with "
                f"names, to_unit and from_unit; got {type(bounds).__name__}"
            ) from e
        if B.ndim != 2 or B.shape[1] != 2 or B.shape[0] == 0:
            raise ValueError(
                f"bounds must have shape (n_params, 2) with n_params >= 1; got shape {B.shape}"
            )
        for i, (lo, hi) in enumerate(B):
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(
                    f"bounds[{i}] must be finite with low < high; got ({lo}, {hi})"
                )
        self.lower, self.upper = B[:, 0].copy(), B[:, 1].copy()
        self._width = self.upper - self.lower
        self.names = tuple(f"x{i}" for i in range(B.shape[0]))

    def from_unit(self, U):
        return self.lower + U * self._width

    def to_unit(self, X):
        return (np.asarray(X, dtype=float) - self.lower) / self._width


class _Buffer:
    """Preallocated columns that grow geometrically (no Python list of arrays)."""

    def __init__(self, n_params, capacity):
        self.n = 0
        self.X = np.empty((capacity, n_params))
        self.f = np.empty(capacity)
        self.v = np.empty(capacity)
        self.gen = np.empty(capacity, dtype=np.int64)
        self.polish = np.empty(capacity, dtype=bool)

    def append(self, X, f, v, generation, polish):
        k = f.size
        if self.n + k > self.f.size:
            capacity = max(2 * self.f.size, self.n + k)
            for name in ("X", "f", "v", "gen", "polish"):
                old = getattr(self, name)
                new = np.empty((capacity,) + old.shape[1:], dtype=old.dtype)
                new[: self.n] = old[: self.n]
                setattr(self, name, new)
        s = slice(self.n, self.n + k)
        self.X[s], self.f[s], self.v[s] = X, f, v
        self.gen[s], self.polish[s] = generation, polish
        self.n += k


class _StopPolish(Exception):
    """Internal: ends a local polish (budget or global stop reached)."""


class _PolishProblem:
    """Scalar views of the batched objective for ``scipy.optimize.minimize``.

    Gradients are forward differences in the unit cube, the ``n_params`` shifted points
    evaluated in one batched call. Every evaluation goes through the GA's bookkeeping.
    """

    _STEP = np.sqrt(np.finfo(float).eps)  # forward-difference step in the unit cube

    def __init__(self, ga, budget, scale):
        self.ga, self.budget, self.used = ga, budget, 0
        self.scale = scale  # the objective is divided by |f| at the start point
        self.cache = {}

    def _run(self, U):
        if self.used + U.shape[0] > self.budget:
            raise _StopPolish
        self.used += U.shape[0]
        _, f, _, G = self.ga._evaluate(U, polish=True)
        if f.size < U.shape[0] or self.ga.stop_reason is not None:
            raise _StopPolish
        return f, G

    def _point(self, u):
        # the cache holds only the last point (and its differences): scipy asks for the
        # value, gradient, constraints and their Jacobian at the same point in turn
        key = u.tobytes()
        if key not in self.cache:
            f, G = self._run(u[None, :])
            self.cache = {key: (f[0], None if G is None else G[0])}
        return self.cache[key]

    def value(self, u):
        return self._point(u)[0] / self.scale

    def constraint(self, u):
        return -self._point(u)[1]  # scipy wants c(u) >= 0

    def _differences(self, u):
        key = u.tobytes() + b"d"
        if key not in self.cache:
            f0, g0 = self._point(u)
            h = np.where(u + self._STEP <= 1.0, self._STEP, -self._STEP)
            U = u + np.diag(h)
            f, G = self._run(U)
            grad = (f - f0) / h
            jac = None if G is None else ((G - g0) / h[:, None]).T
            self.cache[key] = (grad, jac)
        return self.cache[key]

    def gradient(self, u):
        return self._differences(u)[0] / self.scale

    def constraint_jacobian(self, u):
        return -self._differences(u)[1]


class GeneticAlgorithm:
    r"""Steppable genetic algorithm with the operators of the thesis, ch. 3 / TOSCA [1]_.

    Each :meth:`step` (or ``next(ga)``) runs one generation: selection on the (scaled) cost,
    crossover of pairs with probability ``crossover_probability``, per-gene mutation, snapping
    to the gene grid, one batched evaluation of the offspring, and generational replacement
    that keeps the ``n_elite`` best individuals. The first step evaluates the initial
    population (generation 0). :meth:`run` steps until a stop criterion holds and then, if
    asked, polishes the best individual.

    Parameters
    ----------
    fun : callable
        ``fun(X) -> f``, ``X`` of shape (n_individuals, n_params) in physical units, ``f`` of
        shape (n_individuals,). Lower is better; ``+inf`` is allowed, NaN is an error.
    bounds : sequence of (low, high) or parameter space
        Either ``n_params`` pairs (linear scale), or an object with ``names``,
        ``to_unit(X)`` and ``from_unit(U)`` (arrays of shape (n, n_params); e.g.
        ``podkrig.parameters.ParameterSpace``, linear or log scale) and optionally ``units``.
        Genes live in the unit cube, so log-scaled parameters get a log-uniform grid.
    options : GAOptions or None
        All the tuning options below (operators, stops, restarts, polish) as one frozen,
        validated :class:`~podkrig.ga.options.GAOptions`. They may also be given as keywords
        (``GeneticAlgorithm(fun, bounds, population_size=60)``); keywords replace the fields
        of ``options``. The settled options (problem-dependent defaults filled in) are the
        attribute ``options``.
    constraints : callable or None
        ``constraints(X) -> G`` of shape (n_individuals, n_constraints), ``g_j <= 0`` feasible.
    unit_fun : callable or None
        The same objective at the genes themselves, ``unit_fun(U) -> f`` with ``U`` in the unit
        cube of ``bounds``: when given, the GA calls it instead of ``fun`` (a model that works in
        the unit cube, such as the surrogate, then needs no round trip through physical units).
    **keyword_options
        Any field of :class:`~podkrig.ga.options.GAOptions`, where every option is documented
        with its default and why (population 40, half of it elite, binary tournament, BLX-α,
        uniform mutation on a 1000-interval grid, periodic L-BFGS-B polish, stall after 100
        generations, restart on stall with a budget and a target).
    rng : int, numpy.random.Generator or None
        Seed or generator; the only source of randomness.
    callback : callable or None
        ``callback(ga)`` after every generation, with this object (read ``generation``,
        ``nfev``, ``best_x``, ``best_fun``, ``population``, ``population_fun``). Returning
        True stops the run.

    Attributes
    ----------
    generation : int
        Index of the last completed generation (-1 before the first step).
    nfev : int
        Evaluations so far.
    best_x : ndarray of shape (n_params,)
        Best individual so far (Deb's ordering), physical units.
    best_fun, best_violation : float
    population : ndarray of shape (population_size, n_params)
        Current population, physical units.
    population_fun, population_violation : ndarray of shape (population_size,)
    n_restarts : int
        Restarts after a stall so far (``on_stall``).
    options : GAOptions
        The settled options.
    stop_reason : str or None
        Why the run stopped (see :class:`GAResult`), None while running.

    Notes
    -----
    Everything is vectorised over the population; the per-generation overhead of the GA
    itself (selection, variation, bookkeeping) is well under 1 ms for 100 individuals in 10-D
    (``scripts/bench_ga.py``). History arrays grow geometrically.

    References
    ----------
    .. [1] C. Chisari, C. Amadio, "TOSCA: a Tool for Optimisation in Structural and Civil
       engineering Analyses", Int. J. Adv. Struct. Eng. 10 (2018) 401–419,
       doi:10.1007/s40091-018-0205-1; C. Chisari, PhD thesis, ch. 3.
    .. [2] K. Deb, "An efficient constraint handling method for genetic algorithms", Comput.
       Methods Appl. Mech. Engrg. 186 (2000) 311–338.
    .. [3] L. J. Eshelman, J. D. Schaffer, "Real-coded genetic algorithms and
       interval-schemata", Foundations of Genetic Algorithms 2 (1993) 187–202.
    .. [4] J. E. Baker, "Reducing bias and inefficiency in the selection algorithm", Proc.
       2nd Int. Conf. on Genetic Algorithms (1987) 14–21.
    .. [5] W. E. Hart, N. Krasnogor, J. E. Smith (eds.), *Recent Advances in Memetic
       Algorithms*, Springer (2005).
    """

    _RESTART_KEEP = 1  # individuals kept by a restart (see ``on_stall``)

    def __init__(
        self,
        fun: Callable[[np.ndarray], np.ndarray],
        bounds,
        options: GAOptions | None = None,
        *,
        constraints: Callable[[np.ndarray], np.ndarray] | None = None,
        rng=None,
        callback: Callable[[GeneticAlgorithm], bool | None] | None = None,
        unit_fun: Callable[[np.ndarray], np.ndarray] | None = None,
        **keyword_options,
    ):
        if not callable(fun):
            raise TypeError(f"fun must be callable; got {type(fun).__name__}")
        if unit_fun is not None and not callable(unit_fun):
            raise TypeError(f"unit_fun must be callable or None; got {unit_fun!r}")
        if all(hasattr(bounds, a) for a in ("names", "to_unit", "from_unit")):
            self._space = bounds
        else:
            self._space = _BoxSpace(bounds)
        names = tuple(str(n) for n in self._space.names)
        n_params = len(names)
        units = getattr(self._space, "units", None)
        self.parameter_names = names
        self.parameter_units = None if units is None else tuple(str(u) for u in units)
        if constraints is not None and not callable(constraints):
            raise TypeError(f"constraints must be callable or None; got {constraints!r}")
        if callback is not None and not callable(callback):
            raise TypeError(f"callback must be callable or None; got {callback!r}")
        opts = GAOptions.from_keywords(options, **keyword_options)
        self.options: GAOptions = opts.resolve(n_params, constrained=constraints is not None)
        o = self.options
        self._n_grid = np.asarray(o.n_grid, dtype=float) if o.encoding == "integer" else None
        self._fun, self._unit_fun, self._constraints, self._callback = fun, unit_fun, constraints, callback
        self.n_params = n_params
        self.population_size = o.population_size
        self.max_generations = o.max_generations
        self.max_evaluations = o.max_evaluations
        self.target = o.target
        self.stall_generations = o.stall_generations
        self.stall_tol = o.stall_tol
        self.seed = int(rng) if isinstance(rng, numbers.Integral) else None
        self._rng = np.random.default_rng(rng)

        self.generation = -1
        self.nfev = 0
        self.stop_reason: str | None = None
        self._history = _Buffer(n_params, 4 * o.population_size)
        self._stats = np.empty((64, 4))  # best, mean, std, nfev per generation
        self.best_x = np.full(n_params, np.nan)
        self._best_u = np.full(n_params, np.nan)
        self.best_fun = np.inf
        self.best_violation = np.inf
        self._last_improvement = 0
        self.n_restarts = 0
        self._polished_u: np.ndarray | None = None
        self._U = self._f = self._v = self._cost = None

    # ----------------------------------------------------------------- evaluation
    def _evaluate(self, U, *, polish=False):
        """Evaluate genes ``U`` (n, n_params) within the budget; record everything.

        Returns the evaluated rows ``(U, f, v, G)``: fewer than given when the evaluation
        budget ran out or the target was reached (then ``stop_reason`` is set).
        """
        if self.max_evaluations is not None:
            U = U[: max(self.max_evaluations - self.nfev, 0)]
        n = U.shape[0]
        if n == 0:
            return U, np.empty(0), np.empty(0), None
        X = np.asarray(self._space.from_unit(U), dtype=float)  # for the history and the constraints
        f = np.asarray(self._fun(X) if self._unit_fun is None else self._unit_fun(U), dtype=float)
        if f.shape != (n,):
            raise ValueError(f"fun must return shape ({n},) for {n} individuals; got {f.shape}")
        if np.isnan(f).any():
            i = int(np.flatnonzero(np.isnan(f))[0])
            raise ValueError(f"fun returned NaN at x = {X[i].tolist()}")
        G = None
        if self._constraints is None:
            v = np.zeros(n)
        else:
            G = np.asarray(self._constraints(X), dtype=float)
            if G.ndim != 2 or G.shape[0] != n:
                raise ValueError(
                    f"constraints must return shape ({n}, n_constraints); got {G.shape}"
                )
            v = ops.constraint_violation(G)
            v[v <= self.options.feasibility_tol] = 0.0
        if self.target is not None:
            hit = (f <= self.target) & (v <= 0.0)
            if hit.any():
                k = int(np.argmax(hit)) + 1  # evaluations up to and including the first hit
                U, X, f, v = U[:k], X[:k], f[:k], v[:k]
                G = None if G is None else G[:k]
                n = k
                self.stop_reason = "target"
        self._history.append(X, f, v, max(self.generation, 0), polish)
        self.nfev += n
        self._update_best(U, X, f, v)
        if self.stop_reason is None and self.nfev == self.max_evaluations:
            self.stop_reason = "max_evaluations"
        return U, f, v, G

    def _update_best(self, U, X, f, v):
        feasible = v <= 0.0
        i = int(np.argmin(np.where(feasible, f, np.inf))) if feasible.any() else int(np.argmin(v))
        fi, vi = f[i], v[i]
        if vi < self.best_violation:
            improved = True
        elif vi == self.best_violation == 0.0 and fi < self.best_fun:
            improved = self.best_fun - fi > self.stall_tol
        else:
            return
        if improved:
            self._last_improvement = max(self.generation, 0)
        self.best_fun, self.best_violation = float(fi), float(vi)
        self.best_x, self._best_u = X[i].copy(), U[i].copy()

    def _cost_of(self, f, v):
        if self._constraints is None:
            return f
        if self.options.constraint_handling == "deb":
            return ops.deb_cost(f, v)
        return ops.penalty_cost(f, v, self.options.penalty)

    # ----------------------------------------------------------------- one generation
    def _initialise(self):
        self.generation = 0
        U0 = ops.initial_population(
            self.population_size, self.n_params, method=self.options.init, rng=self._rng
        )
        U0 = ops.snap_to_grid(U0, self._n_grid)
        U, f, v, _ = self._evaluate(U0)
        if f.size < self.population_size:  # stopped inside generation 0: keep what exists
            U0[: f.size] = U
            f = np.concatenate([f, np.full(self.population_size - f.size, np.inf)])
            v = np.concatenate([v, np.zeros(self.population_size - v.size)])
            U = U0
        self._U, self._f, self._v = U, f, v
        self._cost = self._cost_of(f, v)

    def _select(self, n_select):
        o, rng = self.options, self._rng
        if o.selection == "tournament":
            return ops.select_tournament(self._cost, n_select, o.tournament_size, rng)
        fitness = ops.scale_fitness(
            self._cost, o.scaling, pressure=o.scaling_pressure,
            eta_plus=o.ranking_eta_plus, base=o.ranking_base,
        )
        if o.selection == "roulette":
            return ops.select_roulette(fitness, n_select, rng)
        return ops.select_sus(fitness, n_select, rng)

    def _offspring(self, n_offspring):
        o, rng = self.options, self._rng
        n_pairs = (n_offspring + 1) // 2
        parents = self._select(2 * n_pairs)
        P1, P2 = self._U[parents[:n_pairs]], self._U[parents[n_pairs:]]
        kind = o.crossover
        if kind == "blx":
            C1, C2 = ops.crossover_blx(P1, P2, o.blx_alpha, rng)
        elif kind == "single_point":
            C1, C2 = ops.crossover_single_point(P1, P2, rng)
        elif kind == "arithmetical":
            C1, C2 = ops.crossover_arithmetical(P1, P2, rng.random((n_pairs, 1)))
        else:
            C1, C2 = ops.crossover_arithmetical(P1, P2, o.crossover_lambda)
        keep = (rng.random(n_pairs) >= o.crossover_probability)[:, None]
        children = np.concatenate([np.where(keep, P1, C1), np.where(keep, P2, C2)])
        children = children[:n_offspring]
        if o.mutation == "uniform":
            ops.mutate_uniform(children, o.mutation_probability, self._n_grid, rng)
        else:
            ops.mutate_gaussian(
                children, o.mutation_probability, o.mutation_scale, self._n_grid, rng
            )
        return ops.snap_to_grid(children, self._n_grid)

    def _next_generation(self):
        self.generation += 1
        n_elite = self.options.n_elite
        n_offspring = self.population_size - n_elite
        children = self._offspring(n_offspring)
        f_child = np.empty(n_offspring)
        v_child = np.empty(n_offspring)
        n_pop = self._U.shape[0]
        if self.options.skip_duplicates:
            # an offspring equal to a member of the population takes its known value; of
            # identical offspring only the first is evaluated (deterministic objective).
            # Rows are compared bytewise through a void view (sort-based, O(n log n)).
            A = np.ascontiguousarray(np.concatenate([self._U, children]))
            rows = A.view(np.dtype((np.void, A.dtype.itemsize * A.shape[1]))).ravel()
            _, first_index, inverse = np.unique(rows, return_index=True, return_inverse=True)
            source = first_index[inverse.ravel()[n_pop:]]  # first row equal to each child
            in_population = source < n_pop
            member = source[in_population]
            f_child[in_population] = self._f[member]
            v_child[in_population] = self._v[member]
            first = np.where(in_population, np.arange(n_offspring), source - n_pop)
            new = ~in_population & (first == np.arange(n_offspring))
        else:
            in_population = np.zeros(n_offspring, dtype=bool)
            first = np.arange(n_offspring)
            new = np.ones(n_offspring, dtype=bool)
        new_index = np.flatnonzero(new)
        _, f, v, _ = self._evaluate(children[new_index])
        f_child[new_index[: f.size]] = f
        v_child[new_index[: f.size]] = v
        known = in_population.copy()
        known[new_index[: f.size]] = True
        known = known[first]  # a repeated offspring is known when its first copy is
        f_child, v_child = f_child[first][known], v_child[first][known]
        order = np.argsort(self._cost, kind="stable")
        # generational replacement with elitism; if the evaluation stopped early, the best
        # of the previous population fill the remaining places
        keep = order[: n_elite + n_offspring - f_child.size]
        self._U = np.concatenate([self._U[keep], children[known]])
        self._f = np.concatenate([self._f[keep], f_child])
        self._v = np.concatenate([self._v[keep], v_child])
        self._cost = self._cost_of(self._f, self._v)

    def _record_stats(self):
        g = self.generation
        if g >= self._stats.shape[0]:
            self._stats = np.concatenate([self._stats, np.empty_like(self._stats)])
        feasible = self._v <= 0.0
        best = self._f[feasible].min() if feasible.any() else np.nan
        self._stats[g] = best, self._f.mean(), self._f.std(), self.nfev

    def _check_stop(self):
        if self.stop_reason is not None:
            return
        if self.generation >= self.max_generations:
            self.stop_reason = "max_generations"
        elif (
            self.stall_generations is not None
            and self.generation - self._last_improvement >= self.stall_generations
        ):
            if self.options.on_stall == "restart":
                self._restart()
            else:
                self.stop_reason = "stall"

    def _restart(self):
        """Keep the best individual, redraw the rest as a fresh initial population.

        The best individual (by cost) survives; the others are replaced by new points drawn
        like generation 0 and evaluated now (within the budget). The stall counter starts
        again. If the evaluation stops early (target or budget), the best of the old
        population fill the places left.
        """
        self.n_restarts += 1
        order = np.argsort(self._cost, kind="stable")
        n_keep = self._RESTART_KEEP
        n_new = self.population_size - n_keep
        U_new = ops.initial_population(n_new, self.n_params, method=self.options.init,
                                       rng=self._rng)
        U, f, v, _ = self._evaluate(ops.snap_to_grid(U_new, self._n_grid))
        fill = order[n_keep: n_keep + n_new - f.size]
        keep = np.concatenate([order[:n_keep], fill])
        self._U = np.concatenate([self._U[keep], U])
        self._f = np.concatenate([self._f[keep], f])
        self._v = np.concatenate([self._v[keep], v])
        self._cost = self._cost_of(self._f, self._v)
        self._last_improvement = self.generation
        logger.debug("restart %d at generation %d (nfev=%d, best f=%.6g)",
                     self.n_restarts, self.generation, self.nfev, self.best_fun)

    def step(self):
        """Run one generation (the first call evaluates the initial population).

        Returns
        -------
        self : GeneticAlgorithm

        Raises
        ------
        StopIteration
            If the run has already stopped (``stop_reason`` is set).
        """
        if self.stop_reason is not None:
            raise StopIteration(self.stop_reason)
        if self.generation < 0:
            self._initialise()
        else:
            self._next_generation()
            if (
                self.options.polish == "periodic"
                and self.stop_reason is None
                and self.generation % self.options.polish_interval == 0
            ):
                self.polish()
        self._record_stats()
        self._check_stop()
        if logger.isEnabledFor(logging.DEBUG):
            logger.debug(
                "generation %d: nfev=%d best f=%.6g violation=%.3g",
                self.generation, self.nfev, self.best_fun, self.best_violation,
            )
        if self._callback is not None and self._callback(self) and self.stop_reason is None:
            self.stop_reason = "callback"
        return self

    def __iter__(self):
        return self

    def __next__(self):
        """Run one generation; return ``(best_x, best_fun)`` (like scipy's DE solver)."""
        self.step()
        return self.best_x, self.best_fun

    # ----------------------------------------------------------------- polish
    def polish(self):
        """Locally minimise from the best individual with ``polish_method`` (memetic step).

        Works in the unit cube within the bounds, counts its evaluations in ``nfev`` and the
        history (``polish_mask``), stops at the budget ``polish_max_evaluations``, at
        ``max_evaluations`` or at ``target``. Does nothing if the best was already polished.
        If the polish improves the best, the polished point replaces the worst individual of
        the population (Lamarckian replacement, off the gene grid).

        Returns
        -------
        improved : bool
            Whether the best individual improved.
        """
        if self.generation < 0:
            raise RuntimeError("polish() needs an evaluated population; call step() first")
        u0 = self._best_u
        if self._polished_u is not None and np.array_equal(u0, self._polished_u):
            return False
        f0, v0 = self.best_fun, self.best_violation
        # scale-free polish: SLSQP and the L-BFGS-B gradient tolerance depend on the
        # magnitude of the objective, so it is normalised by its value at the start point
        scale = abs(f0) if np.isfinite(f0) and f0 != 0.0 else 1.0
        problem = _PolishProblem(self, self.options.polish_max_evaluations, scale)
        method = self.options.polish_method
        kwargs: dict[str, Any] = {"bounds": [(0.0, 1.0)] * self.n_params}
        if method == "Nelder-Mead":
            kwargs["options"] = {"xatol": 1e-10, "fatol": 0.0}
        else:
            kwargs["jac"] = problem.gradient
        if method == "SLSQP" and self._constraints is not None:
            kwargs["constraints"] = [
                {"type": "ineq", "fun": problem.constraint, "jac": problem.constraint_jacobian}
            ]
        try:
            with warnings.catch_warnings():
                # the polish may step onto the bounds or stop early; the GA judges the result
                warnings.simplefilter("ignore", RuntimeWarning)
                optimize.minimize(problem.value, u0.copy(), method=method, **kwargs)
        except _StopPolish:
            pass
        self._polished_u = self._best_u.copy()
        improved = self.best_violation < v0 or self.best_fun < f0
        if improved:
            worst = int(np.argmax(self._cost))
            self._U[worst] = self._best_u
            self._f[worst], self._v[worst] = self.best_fun, self.best_violation
            self._cost = self._cost_of(self._f, self._v)
        logger.debug("polish: %d evaluations, best f %.6g -> %.6g", problem.used, f0, self.best_fun)
        return improved

    # ----------------------------------------------------------------- results
    @property
    def population(self):
        return np.asarray(self._space.from_unit(self._U), dtype=float)

    @property
    def population_fun(self):
        return self._f.copy()

    @property
    def population_violation(self):
        return self._v.copy()

    def run(self):
        """Step until a stop criterion holds, polish as configured, return the result.

        Returns
        -------
        GAResult
        """
        while self.stop_reason is None:
            self.step()
        if self.options.polish != "none" and self.stop_reason in (
            "stall", "max_generations",
        ):
            reason = self.stop_reason
            self.stop_reason = None
            self.polish()
            if self.stop_reason is None:
                self.stop_reason = reason
        logger.info("GA stopped after %d generations, %d evaluations: %s",
                    self.generation, self.nfev, self.message)
        return self.result()

    @property
    def message(self):
        if self.stop_reason is None:
            return "running"
        return _STOP_MESSAGES[self.stop_reason].format(
            target=self.target, nfev=self.nfev, stall_tol=self.stall_tol,
            stall_generations=self.stall_generations, max_generations=self.max_generations,
            max_evaluations=self.max_evaluations, generation=self.generation,
        )

    def result(self):
        """Snapshot of the current state as a :class:`GAResult` (copies)."""
        if self.generation < 0:
            raise RuntimeError("no generation has been evaluated yet; call step() or run()")
        h, n, g = self._history, self._history.n, self.generation + 1
        return GAResult(
            x=self.best_x.copy(), fun=self.best_fun, violation=self.best_violation,
            nfev=self.nfev, ngen=self.generation,
            success=self.stop_reason in _SUCCESSFUL_STOPS and self.best_violation == 0.0,
            stop_reason=self.stop_reason or "running", message=self.message,
            X_history=h.X[:n].copy(), f_history=h.f[:n].copy(),
            violation_history=h.v[:n].copy(), generation_history=h.gen[:n].copy(),
            polish_mask=h.polish[:n].copy(),
            generation_best=self._stats[:g, 0].copy(), generation_mean=self._stats[:g, 1].copy(),
            generation_std=self._stats[:g, 2].copy(),
            generation_nfev=self._stats[:g, 3].astype(np.int64),
            population=self.population, population_fun=self.population_fun,
            population_violation=self.population_violation,
            parameter_names=self.parameter_names, parameter_units=self.parameter_units,
            seed=self.seed, n_restarts=self.n_restarts,
        )


def minimize(fun, bounds, options: GAOptions | None = None, *, rng=None, constraints=None,
             callback=None, **operator_options) -> GAResult:
    """Minimise ``fun`` over ``bounds`` with the genetic algorithm.

    Parameters
    ----------
    fun : callable
        ``fun(X) -> f``, ``X`` of shape (n_individuals, n_params) in physical units, ``f``
        of shape (n_individuals,).
    bounds : sequence of (low, high) or parameter space
        See :class:`GeneticAlgorithm`.
    options : GAOptions or None
        Tuning options; keywords in ``operator_options`` replace its fields.
    rng : int, numpy.random.Generator or None
        Seed or generator.
    constraints : callable or None
        ``constraints(X) -> G`` of shape (n_individuals, n_constraints), ``g <= 0`` feasible.
    callback : callable or None
        ``callback(ga)`` after each generation; returning True stops.
    **operator_options
        Any field of :class:`~podkrig.ga.options.GAOptions` (``max_evaluations``, ``target``,
        ``population_size``, ``selection``, …; documented on :class:`GeneticAlgorithm`). An
        unknown name raises ``TypeError``.

    Returns
    -------
    GAResult

    Warns
    -----
    GABudgetWarning
        (a ``RuntimeWarning``) If the run stopped because a budget (generations or
        evaluations) ran out.

    Raises
    ------
    TypeError
        For an unknown option name.
    ValueError
        For an option value outside its allowed range.
    """
    ga = GeneticAlgorithm(fun, bounds, options, rng=rng, constraints=constraints,
                          callback=callback, **operator_options)
    result = ga.run()
    if result.stop_reason in ("max_generations", "max_evaluations"):
        warnings.warn(f"GA stopped on its budget: {result.message}", GABudgetWarning,
                      stacklevel=2)
    return result
