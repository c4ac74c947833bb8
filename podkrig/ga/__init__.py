"""Genetic algorithm of the thesis, chapter 3 (TOSCA): operators, solver and figures.

- :mod:`podkrig.ga.operators` — vectorised initialisation, fitness scaling, selection,
  crossover and mutation on populations in the unit hypercube;
- :mod:`podkrig.ga.options` — :class:`GAOptions`, every tuning option as one frozen, validated
  value object, and :class:`GABudgetWarning`;
- :mod:`podkrig.ga.core` — :class:`GeneticAlgorithm` (steppable), :func:`minimize`,
  :class:`GAResult`;

Figures of a run (history, statistics, parameter–fitness) are in :mod:`podkrig.reports.ga`.

Conventions: ``X`` is ``(n_individuals, n_params)`` in physical units, objective values are
``(n_individuals,)``, lower is better.
"""

from podkrig.ga.core import GAResult, GeneticAlgorithm, minimize
from podkrig.ga.options import GABudgetWarning, GAOptions

__all__ = [
    "GABudgetWarning",
    "GAOptions",
    "GAResult",
    "GeneticAlgorithm",
    "minimize",
]
