"""Search for the best sensor layout: greedy and QR-pivoting starts, exchange, and the project's GA.

A :class:`PlacementProblem` is a criterion (:class:`~podkrig.sensors.criteria.LayoutCriterion`), a
candidate set, a size ``k`` *or* a cost ``budget``, and constraints: sensors that must be included,
a minimum spacing between sensor centres, and candidates excluded outright (forbidden zones and
joints are removed when candidates are built). Layouts are integer arrays of candidate indices; in
budget mode a slot may be ``-1`` (empty) so that the number of sensors follows the budget.

Methods (all evaluate layouts in vectorised batches):

- ``greedy``: add, one at a time, the feasible candidate with the largest decrease of the loss (per
  unit cost in budget mode);
- ``qr``: column-pivoted QR (Businger & Golub 1965 [1]_; the PySensors idea [2]_) of the matrix
  whose column ``c`` is the leading square-root factor of candidate ``c``'s information summed over
  the parameter points — the pivots pick informative, mutually non-redundant sensors — completed
  greedily;
- ``ga``: :class:`podkrig.ga.GeneticAlgorithm` with integer genes (one gene per free slot, the
  candidate index), Deb's feasibility rules on the constraints (duplicates, spacing, budget);
- every start is finished by an *exchange* pass (Fedorov 1972 [3]_): the best single-sensor swap is
  made while it lowers the loss.

References
----------
.. [1] P. Businger, G. H. Golub, "Linear least squares solutions by Householder transformations",
   Numer. Math. 7 (1965) 269–276.
.. [2] K. Manohar, B. W. Brunton, J. N. Kutz, S. L. Brunton, "Data-driven sparse sensor placement
   for reconstruction", IEEE Control Systems 38(3) (2018) 63–86.
.. [3] V. V. Fedorov, *Theory of Optimal Experiments*, Academic Press (1972).
"""

import functools
import logging
import time
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from podkrig.display import Displayed
from podkrig.ga import GeneticAlgorithm

logger = logging.getLogger(__name__)

METHODS = ("greedy", "qr", "ga")


@dataclass(frozen=True, eq=False)
class PlacementProblem:
    """What to choose and under which constraints.

    Parameters
    ----------
    criterion : LayoutCriterion
    candidates : CandidateSet
    k : int or None
        Number of sensors (including ``must_include``). Exactly one of ``k`` and ``budget``.
    budget : float or None
        Largest total cost (candidates' ``cost``); the number of sensors is then free.
    must_include : sequence of int
        Candidate indices always in the layout.
    min_spacing : float
        Smallest distance between the centres of two chosen sensors, mm (0: no constraint).
    exclude : sequence of int
        Candidate indices never chosen (e.g. the current layout's sensors kept only for comparison).
    """

    criterion: object
    candidates: object
    k: int | None = None
    budget: float | None = None
    must_include: tuple = ()
    min_spacing: float = 0.0
    exclude: tuple = ()

    def __post_init__(self):
        n = len(self.candidates)
        must = tuple(int(i) for i in self.must_include)
        object.__setattr__(self, "must_include", must)
        object.__setattr__(self, "exclude", tuple(int(i) for i in self.exclude))
        if (self.k is None) == (self.budget is None):
            raise ValueError("give exactly one of k (number of sensors) and budget (total cost)")
        if any(not 0 <= i < n for i in must + self.exclude):
            raise ValueError(f"candidate indices must be in [0, {n - 1}]")
        if len(set(must)) != len(must):
            raise ValueError("must_include lists a sensor twice")
        if set(must) & set(self.exclude):
            raise ValueError(f"sensor(s) {sorted(set(must) & set(self.exclude))} are both required and excluded")
        if self.min_spacing < 0:
            raise ValueError(f"min_spacing must be >= 0 mm; got {self.min_spacing}")
        allowed = np.ones(n, bool)
        allowed[list(self.exclude)] = False
        allowed[list(must)] = False
        object.__setattr__(self, "allowed", np.flatnonzero(allowed))
        cost = self.candidates.cost
        if self.k is not None:
            if not len(must) <= self.k <= len(must) + len(self.allowed):
                raise ValueError(f"k = {self.k} must be between the {len(must)} required sensor(s) and the "
                                 f"{len(must) + len(self.allowed)} available")
            n_free = self.k - len(must)
        else:
            spare = self.budget - cost[list(must)].sum()
            if spare < 0:
                raise ValueError(f"the required sensors cost {cost[list(must)].sum():g}, over the budget {self.budget:g}")
            n_free = int(min(len(self.allowed), np.floor(spare / cost[self.allowed].min() + 1e-9)))
        object.__setattr__(self, "n_free", n_free)

    @functools.cached_property
    def _distance(self):
        """Distances between the candidates' centres, ``(n_candidates, n_candidates)`` mm: built on
        first use (only a spacing constraint needs it; 200 MB for 5 000 candidates)."""
        centres = self.candidates.centres
        return np.hypot(*(centres[:, None] - centres[None]).transpose(2, 0, 1))

    def full(self, free):
        """Free slots ``(n, n_free)`` → layouts ``(n, n_must + n_free)``."""
        free = np.atleast_2d(np.asarray(free, dtype=np.intp))
        must = np.broadcast_to(np.array(self.must_include, dtype=np.intp), (len(free), len(self.must_include)))
        return np.hstack([must, free])

    def violations(self, layouts):
        """Constraint violations ``(n_layouts, 3)``: repeated sensors, pairs closer than the spacing,
        cost over the budget (≤ 0 is feasible)."""
        L = np.atleast_2d(np.asarray(layouts, dtype=np.intp))
        used = L >= 0
        same = (L[:, :, None] == L[:, None, :]) & used[:, :, None] & used[:, None, :]
        iu = np.triu_indices(L.shape[1], k=1)
        dup = same[:, iu[0], iu[1]].sum(axis=1)
        if self.min_spacing > 0:
            Lc = np.where(used, L, 0)
            d = self._distance[Lc[:, :, None], Lc[:, None, :]]
            close = (d < self.min_spacing) & used[:, :, None] & used[:, None, :] & ~same
            near = close[:, iu[0], iu[1]].sum(axis=1)
        else:
            near = np.zeros(len(L))
        if self.budget is not None:
            over = np.maximum(np.where(used, self.candidates.cost[np.where(used, L, 0)], 0.0).sum(axis=1) - self.budget, 0)
        else:
            over = np.zeros(len(L))
        return np.column_stack([dup, near, over]).astype(float)

    def feasible(self, layouts):
        return np.all(self.violations(layouts) <= 1e-12, axis=1)


@dataclass(frozen=True, eq=False, repr=False)
class LayoutResult(Displayed):
    """The chosen layout.

    Attributes
    ----------
    indices : ndarray of shape (k,)
        Candidate indices (required ones first), empty slots removed.
    names : tuple of str
    loss : float
        Criterion loss (lower is better; see :class:`LayoutCriterion`).
    value : float
        Criterion value Ψ.
    method : str
        Which start found it (after exchange).
    by_method : dict of str to float
        Criterion value found from each start.
    n_evaluations : int
        Layouts evaluated.
    seconds : float
    """

    indices: np.ndarray
    names: tuple
    loss: float
    value: float
    method: str
    by_method: dict
    n_evaluations: int
    seconds: float

    def to_dict(self):
        return {"indices": self.indices.tolist(), "names": list(self.names), "loss": self.loss, "value": self.value,
                "method": self.method, "by_method": dict(self.by_method), "n_evaluations": self.n_evaluations,
                "seconds": self.seconds}


class _Counter:
    def __init__(self, problem):
        self.problem, self.n = problem, 0

    def loss(self, layouts):
        self.n += len(layouts)
        return self.problem.criterion.loss(layouts)


def _greedy_fill(problem, counter, start):
    """Extend the free slots ``start`` (list of indices) greedily to ``n_free`` slots (``-1`` pads)."""
    chosen = list(start)
    cost = problem.candidates.cost
    while len(chosen) < problem.n_free:
        cand = np.setdiff1d(problem.allowed, chosen)
        if not len(cand):
            break
        trial = problem.full(np.column_stack([np.tile(chosen, (len(cand), 1)), cand]) if chosen else cand[:, None])
        ok = problem.feasible(trial)
        if not ok.any():
            break
        loss = counter.loss(trial[ok])
        if problem.budget is not None:  # gain per unit cost (negative = better)
            base = counter.loss(problem.full(np.array(chosen + [-1], dtype=np.intp)[None]))[0]
            score = (loss - base) / cost[cand[ok]]
        else:
            score = loss
        chosen.append(int(cand[ok][np.argmin(score)]))
    return np.array(chosen + [-1] * (problem.n_free - len(chosen)), dtype=np.intp)


def _exchange(problem, counter, free, max_sweeps=50):
    """Best single swaps (including with an empty slot in budget mode) while the loss decreases."""
    free = np.array(free, dtype=np.intp)
    best = counter.loss(problem.full(free))[0]
    options = problem.allowed if problem.budget is None else np.append(problem.allowed, -1)
    for _ in range(max_sweeps):
        trials = np.repeat(free[None], len(free) * len(options), axis=0)
        pos = np.repeat(np.arange(len(free)), len(options))
        trials[np.arange(len(trials)), pos] = np.tile(options, len(free))
        layouts = problem.full(trials)
        ok = problem.feasible(layouts)
        if not ok.any():
            break
        loss = counter.loss(layouts[ok])
        i = int(np.argmin(loss))
        if not loss[i] < best - 1e-12 * max(1.0, abs(best)):
            break
        free, best = trials[ok][i], loss[i]
    return free, best


def _qr_start(problem):
    """First pivots of a column-pivoted QR of the candidates' information square roots."""
    info = problem.criterion.info[:, problem.allowed].sum(axis=0)  # (n_allowed, m, m)
    w, v = np.linalg.eigh(info)
    M = (v[..., -1] * np.sqrt(np.maximum(w[..., -1], 0.0))[:, None]).T  # (m, n_allowed): leading factor
    _, _, piv = scipy.linalg.qr(M, pivoting=True, mode="economic")
    picks = []
    for c in problem.allowed[piv[: min(problem.n_free, M.shape[0])]]:
        trial = problem.full(np.array(picks + [int(c)], dtype=np.intp)[None])
        if problem.feasible(trial)[0]:
            picks.append(int(c))
    return picks


def _ga(problem, counter, rng, population_size, generations):
    n_opt = len(problem.allowed) + (1 if problem.budget is not None else 0)
    options = problem.allowed if problem.budget is None else np.append(problem.allowed, -1)
    if n_opt < 2:
        return np.full(problem.n_free, options[0], dtype=np.intp)

    def decode(X):
        return options[np.clip(np.rint(X).astype(np.intp), 0, n_opt - 1)]

    def fun(X):
        return counter.loss(problem.full(decode(X)))

    def constraints(X):
        return problem.violations(problem.full(decode(X)))

    ga = GeneticAlgorithm(
        fun, [(0.0, float(n_opt - 1))] * problem.n_free, population_size=population_size, n_grid=n_opt - 1,
        constraints=constraints, polish="none", max_generations=generations, stall_generations=max(20, generations // 4),
        mutation_probability=min(1.0, 2.0 / problem.n_free), rng=rng,
    )
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="GA stopped", category=RuntimeWarning)
        result = ga.run()
    return decode(np.asarray(result.x)[None])[0]


def choose_layout(problem, *, methods=METHODS, rng=0, population_size=60, generations=150):
    """The best layout found from each start in ``methods``, each finished by exchange.

    Parameters
    ----------
    problem : PlacementProblem
    methods : sequence of {"greedy", "qr", "ga"}
    rng : int
        Seed of the GA.
    population_size, generations : int
        GA budget.

    Returns
    -------
    LayoutResult
    """
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise ValueError(f"methods must be a non-empty subset of {METHODS}; got {list(methods)}")
    t0 = time.perf_counter()
    counter = _Counter(problem)
    found = {}
    for method in methods:
        if problem.n_free == 0:
            start = np.empty(0, dtype=np.intp)
        elif method == "greedy":
            start = _greedy_fill(problem, counter, [])
        elif method == "qr":
            start = _greedy_fill(problem, counter, _qr_start(problem))
        else:
            start = _ga(problem, counter, rng, population_size, generations)
        if problem.n_free and not problem.feasible(problem.full(start))[0]:
            logger.info("%s start infeasible; completing greedily", method)
            start = _greedy_fill(problem, counter, [])
        free, loss = _exchange(problem, counter, start) if problem.n_free else (start, counter.loss(problem.full(start))[0])
        found[method] = (free, loss)
    method = min(found, key=lambda m: found[m][1])
    free, loss = found[method]
    layout = problem.full(free)[0]
    layout = layout[layout >= 0]
    sign = problem.criterion.sign
    return LayoutResult(layout, tuple(problem.candidates.names[i] for i in layout), float(loss), float(sign * loss),
                        method, {m: float(sign * v[1]) for m, v in found.items()}, counter.n, time.perf_counter() - t0)
