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
    """Tuning options of the genetic algorithm (see :class:`podkrig.ga.GeneticAlgorithm`).

    Every field has the default documented there. ``None`` in ``mutation_probability``,
    ``n_elite``, ``max_generations``, ``polish_method`` and ``polish_max_evaluations`` means
    "derived from the problem": :meth:`resolve` fills them in.

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
