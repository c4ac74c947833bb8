"""Options of the genetic algorithm as one frozen value object, validated in one place.

:class:`GAOptions` holds every tuning option of :class:`podkrig.ga.GeneticAlgorithm` (operators,
stop criteria, restarts, polish); its constructor checks each value and names the option, the
value given and what is allowed. Options that depend on the problem (``mutation_probability``,
``n_elite``, ``polish_method``, ``polish_max_evaluations`` left at None, and the length of
``n_grid``) are settled by :meth:`GAOptions.resolve` once the number of parameters and the
presence of constraints are known. The meaning of each option is documented on
:class:`podkrig.ga.GeneticAlgorithm`.

Example
-------
>>> from podkrig.ga.options import GAOptions
>>> opts = GAOptions(population_size=60, selection="sus")
>>> opts.resolve(n_params=4, constrained=False).n_elite
30
>>> GAOptions(selection="rank")
Traceback (most recent call last):
...
ValueError: selection must be one of 'tournament', 'roulette', 'sus'; got 'rank'
"""

from __future__ import annotations

import dataclasses
import difflib
import numbers
from dataclasses import dataclass

import numpy as np

from podkrig.limits import check_evaluations, check_population

__all__ = ["GABudgetWarning", "GAOptions"]


class GABudgetWarning(RuntimeWarning):
    """Warned by :func:`podkrig.ga.minimize` when a run stopped because a budget (generations
    or evaluations) ran out. A caller that plans to run the GA to its budget (e.g. before a
    local polish) filters this category instead of matching the message text."""


_CHOICES = {
    "encoding": ("integer", "real"),
    "init": ("sobol", "random"),
    "selection": ("tournament", "roulette", "sus"),
    "scaling": ("none", "linear", "linear_ranking", "exponential_ranking"),
    "crossover": ("blx", "single_point", "arithmetical", "fixed_arithmetical"),
    "mutation": ("uniform", "gaussian"),
    "constraint_handling": ("deb", "penalty"),
    "on_stall": ("auto", "stop", "restart"),
    "polish": ("periodic", "final", "none"),
    "polish_method": ("L-BFGS-B", "Nelder-Mead", "SLSQP"),
}


def _check_choice(name, value, allowed):
    if value not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, allowed))}; got {value!r}")


def _check_range(name, value, low, high, *, low_open=False, high_open=False, integer=False):
    kind = numbers.Integral if integer else numbers.Real
    if isinstance(value, bool) or not isinstance(value, kind):
        raise TypeError(f"{name} must be {'an integer' if integer else 'a number'}; got {value!r}")
    too_low = value <= low if low_open else value < low
    too_high = value >= high if high_open else value > high
    if too_low or too_high or (not integer and not np.isfinite(value)):
        lb = "(" if low_open else "["
        hb = ")" if high_open else "]"
        raise ValueError(f"{name} must be in {lb}{low}, {high}{hb}; got {value!r}")


@dataclass(frozen=True)
class GAOptions:
    r"""Tuning options of the genetic algorithm (:class:`podkrig.ga.GeneticAlgorithm`).

    ``None`` in ``mutation_probability``, ``n_elite``, ``max_generations``, ``polish_method``
    and ``polish_max_evaluations`` means "derived from the problem": :meth:`resolve` fills
    them in. The references (Deb 2000, Eshelman & Schaffer 1993, Baker 1987, Hart et al.
    2005) are listed in :mod:`podkrig.ga.core`.

    Parameters
    ----------
    population_size : int, default 40
        Individuals per generation, >= 4. With half the population kept as elite, 40 found
        the global minimum of 10-D Rastrigin in 30/30 seeds with the fewest evaluations among
        30–50 (``scripts/bench_ga.py``); larger populations are more robust and slower.
    encoding : {"integer", "real"}, default "integer"
        ``"integer"``: thesis/TOSCA integer genes ``g_i ∈ {0..N_i}``,
        ``x_i = lo_i + g_i (hi_i - lo_i)/N_i`` (in the space's scale), recombination rounded
        and clipped. ``"real"``: genes anywhere in [0, 1] (clipped).
    n_grid : int or sequence of int, default 1000
        Grid intervals ``N_i`` per parameter (integer encoding). 1000 resolves 0.1 % of each
        range — below the repeatability of masonry tests — and is even, so a symmetric
        range contains its midpoint. The local polish works off the grid.
    init : {"sobol", "random"}, default "sobol"
        Initial population: scrambled Sobol' points seeded from ``rng`` (even coverage of the
        box, thesis ch. 3), or uniform random.
    selection : {"tournament", "roulette", "sus"}, default "tournament"
        Tournament of ``tournament_size``; roulette wheel; stochastic universal sampling
        (Baker 1987). Roulette and SUS use the fitness from ``scaling``. Tournament
        is the default because it needs no scaling and its pressure is set by one integer.
    tournament_size : int, default 2
        Contestants per tournament, in [1, population_size]. Binary tournament: moderate
        pressure, which keeps the diversity needed on multimodal misfits (size 3 was ~10 %
        faster on Rastrigin but is greedier).
    scaling : {"none", "linear", "linear_ranking", "exponential_ranking"}, default "linear_ranking"
        Fitness scaling for roulette / SUS (ignored by tournament); see
        :func:`podkrig.ga.operators.scale_fitness`. Ranking is the default because it is
        insensitive to the objective's magnitude (misfits span decades).
    scaling_pressure : float, default 2.0
        ``C`` of linear scaling (max scaled fitness = C × mean), > 1.
    ranking_eta_plus : float, default 1.5
        :math:`\eta^+ \in [1, 2]` of linear ranking.
    ranking_base : float, default 0.9
        Base :math:`c \in (0, 1)` of exponential ranking.
    crossover : {"blx", "single_point", "arithmetical", "fixed_arithmetical"}, default "blx"
        BLX-α (Eshelman & Schaffer 1993); single-point; arithmetical with
        :math:`\lambda \sim U(0, 1)` per mating; arithmetical with fixed ``crossover_lambda``.
        BLX-α is the default: it explores beyond the parents' interval per gene, which on
        a grid also keeps fine-tuning possible.
    crossover_probability : float, default 0.9
        Probability ``p_c`` that a pair is recombined (else copied), in [0, 1].
    blx_alpha : float, default 0.5
        α of BLX-α, >= 0 (0.5 preserves the population variance on average).
    crossover_lambda : float, default 0.25
        λ of fixed arithmetical crossover, in [0, 1] (0.5 would make twin children).
    mutation : {"uniform", "gaussian"}, default "uniform"
        Uniform reset of a gene on its grid (thesis) or Gaussian creep of standard deviation
        ``mutation_scale`` (at least one grid step on the integer grid).
    mutation_probability : float or None, default None
        Per-gene probability ``p_m`` in [0, 1]; None means ``1 / n_params`` (one gene per
        child on average, the usual rule; 0.01 slowed 10-D Rastrigin by ~50 %).
    mutation_scale : float, default 0.1
        σ of Gaussian creep, as a fraction of each range, > 0.
    n_elite : int or None, default None
        Best individuals copied unchanged into the next generation, in
        [0, population_size - 2]; None means ``population_size // 2``. Keeping the better
        half makes the replacement behave like a (μ + λ) survival: the best objective never
        increases and a good individual is never lost to a bad generation. On 10-D Rastrigin
        it cut the evaluations to success from ~18 000 (2 elites, 10/10 only with 60+
        individuals) to ~7 000.
    skip_duplicates : bool, default True
        An offspring identical to a member of the population, or to an earlier offspring of
        the same generation, is not re-evaluated and takes the known value (the objective
        must be deterministic, as a surrogate is). On the integer grid ~20 % of the
        offspring of a converging population are such copies.
    constraint_handling : {"deb", "penalty"}, default "deb"
        Deb's feasibility rules (no parameter to tune) or a static L1 penalty
        ``f + penalty * sum_j max(0, g_j)``.
    penalty : float, default 1e3
        Penalty factor (objective units per unit violation), > 0. The L1 penalty is exact
        once it exceeds the largest Lagrange multiplier of the problem.
    feasibility_tol : float, default 1e-6
        A total violation at or below this (constraint units) is recorded as 0, i.e.
        feasible: a local polish lands on active constraints only up to round-off.
    max_generations : int or None, default None
        Generations after the initial one, >= 0. None means 1000 without ``max_evaluations``
        and no limit with it (the evaluation budget governs).
    max_evaluations : int or None
        Budget of objective evaluations (polish included); never exceeded.
    target : float or None
        Stop at the first feasible evaluation with ``f <= target``.
    stall_generations : int or None, default 100
        The population has stalled when the best has not improved by more than ``stall_tol``
        for this many generations; None disables stall detection.
    stall_tol : float, default 0.0
        Absolute improvement of the best objective that resets the stall counter, >= 0.
    on_stall : {"auto", "stop", "restart"}, default "auto"
        What a stall does: ``"stop"`` ends the run (a success: converged); ``"restart"``
        keeps the best individual and redraws the rest of the population like generation 0
        (``init``), then goes on until the target, the evaluation budget or
        ``max_generations``. ``"auto"`` restarts when both ``max_evaluations`` and ``target``
        are given (the run has a goal and the means to keep looking: a user who gives a
        budget and a target expects the budget to be used) and stops otherwise. On 10-D
        Rastrigin with a 100 000 budget and ``target=1e-2`` the stall stop left 3 of seeds
        1–10 at f ≈ 1–5 with 95 % of the budget unused; with restarts all 10 reach the target.
        Keeping only the best individual escaped the hardest seed in 3 restarts, keeping the
        elite half in 6.
    polish : {"periodic", "final", "none"}, default "periodic"
        Local polish of the best individual (a memetic step): ``"periodic"`` every
        ``polish_interval`` generations when the best has changed since the last polish, and
        at the end of :meth:`run`; ``"final"`` only at the end of :meth:`run` (not after a
        target or budget stop); ``"none"``. The polished point replaces the worst individual
        (Lamarckian), off the grid. Periodic polish is the default: the GA locates the basin
        and the polish pins the minimum far cheaper than grid mutations (10-D Rastrigin,
        f <= 1e-2: 10/10 seeds at a median ~6 500 evaluations, against 5/10 within 30 000
        without polish or with a final polish only).
    polish_method : {"L-BFGS-B", "Nelder-Mead", "SLSQP"} or None, default None
        ``scipy.optimize.minimize`` method in the unit cube, bounded to it. None means
        L-BFGS-B without constraints and SLSQP with them (the only one of the three that
        handles inequality constraints). Gradients are batched forward differences
        (``n_params`` points per objective call). Nelder–Mead suits non-smooth objectives
        (e.g. minimax).
    polish_interval : int, default 10
        Generations between periodic polishes, >= 1 (5, 10 and 20 cost the same within 2 %
        on 10-D Rastrigin).
    polish_max_evaluations : int or None
        Evaluations allowed per polish; None means ``20 * (n_params + 1)``, ~20 gradient
        steps, enough to converge from inside a basin.

    Raises
    ------
    TypeError, ValueError
        From the constructor, for a value of the wrong type or outside its allowed set or
        range; the message names the option, the value and what is allowed.
    """

    population_size: int = 40
    encoding: str = "integer"
    n_grid: int | tuple[int, ...] = 1000
    init: str = "sobol"
    selection: str = "tournament"
    tournament_size: int = 2
    scaling: str = "linear_ranking"
    scaling_pressure: float = 2.0
    ranking_eta_plus: float = 1.5
    ranking_base: float = 0.9
    crossover: str = "blx"
    crossover_probability: float = 0.9
    blx_alpha: float = 0.5
    crossover_lambda: float = 0.25
    mutation: str = "uniform"
    mutation_probability: float | None = None
    mutation_scale: float = 0.1
    n_elite: int | None = None
    skip_duplicates: bool = True
    constraint_handling: str = "deb"
    penalty: float = 1e3
    feasibility_tol: float = 1e-6
    max_generations: int | None = None
    max_evaluations: int | None = None
    target: float | None = None
    stall_generations: int | None = 100
    stall_tol: float = 0.0
    on_stall: str = "auto"
    polish: str = "periodic"
    polish_method: str | None = None
    polish_interval: int = 10
    polish_max_evaluations: int | None = None

    def __post_init__(self):
        for name, allowed in _CHOICES.items():
            value = getattr(self, name)
            if not (name == "polish_method" and value is None):
                _check_choice(name, value, allowed)
        _check_range("population_size", self.population_size, 4, np.inf, integer=True)
        check_population(self.population_size)
        _check_range("tournament_size", self.tournament_size, 1, self.population_size,
                     integer=True)
        _check_range("scaling_pressure", self.scaling_pressure, 1.0, np.inf, low_open=True)
        _check_range("ranking_eta_plus", self.ranking_eta_plus, 1.0, 2.0)
        _check_range("ranking_base", self.ranking_base, 0.0, 1.0, low_open=True, high_open=True)
        _check_range("crossover_probability", self.crossover_probability, 0.0, 1.0)
        _check_range("blx_alpha", self.blx_alpha, 0.0, np.inf)
        _check_range("crossover_lambda", self.crossover_lambda, 0.0, 1.0)
        if self.mutation_probability is not None:
            _check_range("mutation_probability", self.mutation_probability, 0.0, 1.0)
        _check_range("mutation_scale", self.mutation_scale, 0.0, np.inf, low_open=True)
        if self.n_elite is not None:
            _check_range("n_elite", self.n_elite, 0, self.population_size - 2, integer=True)
        if not isinstance(self.skip_duplicates, bool | np.bool_):
            raise TypeError(f"skip_duplicates must be True or False; got {self.skip_duplicates!r}")
        _check_range("penalty", self.penalty, 0.0, np.inf, low_open=True)
        _check_range("feasibility_tol", self.feasibility_tol, 0.0, np.inf)
        if self.max_generations is not None:
            _check_range("max_generations", self.max_generations, 0, np.inf, integer=True)
        if self.max_evaluations is not None:
            _check_range("max_evaluations", self.max_evaluations, 1, np.inf, integer=True)
            check_evaluations(self.max_evaluations)
        else:  # 1000 generations by default (see resolve)
            generations = 1000 if self.max_generations is None else self.max_generations
            check_evaluations(self.population_size * (generations + 1),
                              what=f"max_generations = {self.max_generations} with a population of "
                                   f"{self.population_size}")
        if self.target is not None:
            _check_range("target", self.target, -np.inf, np.inf)
        if self.stall_generations is not None:
            _check_range("stall_generations", self.stall_generations, 1, np.inf, integer=True)
        _check_range("stall_tol", self.stall_tol, 0.0, np.inf)
        _check_range("polish_interval", self.polish_interval, 1, np.inf, integer=True)
        if self.polish_max_evaluations is not None:
            _check_range("polish_max_evaluations", self.polish_max_evaluations, 1, np.inf,
                         integer=True)
        grid = np.asarray(self.n_grid)
        if grid.ndim > 1 or not np.issubdtype(grid.dtype, np.integer) or np.any(grid < 1):
            raise ValueError(f"n_grid must be an integer >= 1 or a sequence of them, one per "
                             f"parameter; got {self.n_grid!r}")
        if grid.ndim == 1:  # a hashable, immutable copy of a sequence
            object.__setattr__(self, "n_grid", tuple(int(n) for n in grid))

    @classmethod
    def from_keywords(cls, options=None, **keywords) -> GAOptions:
        """``options`` (a :class:`GAOptions` or None) with ``keywords`` replacing its fields.

        Raises
        ------
        TypeError
            For a keyword that is not an option (with the closest name, if any).
        """
        names = tuple(f.name for f in dataclasses.fields(cls))
        for name in keywords:
            if name not in names:
                close = difflib.get_close_matches(name, names, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise TypeError(f"unknown GA option {name!r}{hint}; allowed: {', '.join(names)}")
        if options is None:
            return cls(**keywords)
        if not isinstance(options, cls):
            raise TypeError(f"options must be a GAOptions or None; got {type(options).__name__}")
        return dataclasses.replace(options, **keywords) if keywords else options

    def resolve(self, n_params: int, constrained: bool) -> GAOptions:
        """The options with every problem-dependent default filled in.

        Parameters
        ----------
        n_params : int
            Number of parameters (genes).
        constrained : bool
            Whether the problem has constraints.

        Returns
        -------
        GAOptions
            ``mutation_probability = 1 / n_params``, ``n_elite = population_size // 2``,
            ``max_generations`` = 1000 without an evaluation budget and unlimited with one,
            ``polish_method`` = L-BFGS-B (SLSQP with constraints),
            ``polish_max_evaluations = 20 (n_params + 1)``, ``n_grid`` one per parameter, and
            ``on_stall`` = ``"restart"`` with both an evaluation budget and a target and
            ``"stop"`` otherwise; unchanged where given.

        Raises
        ------
        ValueError
            If ``n_grid`` does not have ``n_params`` entries, or ``polish_method`` cannot
            handle constraints.
        """
        grid = np.broadcast_to(np.asarray(self.n_grid), (n_params,)) if np.ndim(
            self.n_grid) == 0 or len(self.n_grid) == n_params else None
        if grid is None:
            raise ValueError(
                f"n_grid must be an integer >= 1 or {n_params} of them; got {self.n_grid!r}"
            )
        budget = self.max_evaluations is not None
        goal = budget and self.target is not None
        polish_method = self.polish_method or ("SLSQP" if constrained else "L-BFGS-B")
        if constrained and self.polish != "none" and polish_method != "SLSQP":
            raise ValueError(
                f"polish_method={polish_method!r} cannot handle constraints; "
                "use polish_method='SLSQP' or polish='none'"
            )
        return dataclasses.replace(
            self,
            n_grid=tuple(int(n) for n in grid),
            mutation_probability=(1.0 / n_params if self.mutation_probability is None
                                  else self.mutation_probability),
            n_elite=self.population_size // 2 if self.n_elite is None else self.n_elite,
            max_generations=(self.max_generations if self.max_generations is not None
                             else (np.iinfo(np.int64).max if budget else 1000)),
            on_stall=(self.on_stall if self.on_stall != "auto"
                      else ("restart" if goal else "stop")),
            polish_method=polish_method,
            polish_max_evaluations=(20 * (n_params + 1) if self.polish_max_evaluations is None
                                    else self.polish_max_evaluations),
        )

    def to_dict(self) -> dict:
        """Plain fields (for JSON); ``n_grid`` as a list when given per parameter."""
        d = dataclasses.asdict(self)
        if isinstance(d["n_grid"], tuple):
            d["n_grid"] = list(d["n_grid"])
        return d
