"""Tests of the genetic algorithm (podkrig.ga): operators, solver contract, known optima."""

import dataclasses
import pathlib
import subprocess
import sys
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from conftest import load_file
from podkrig.ga import (
    GABudgetWarning,
    GAOptions,
    GAResult,
    GeneticAlgorithm,
    minimize,
)
from podkrig.ga import operators as ops
from podkrig.reports.ga import plot_history, plot_parameters, plot_statistics

SCRIPTS = pathlib.Path(__file__).resolve().parents[1] / "scripts"


def load_script(name):
    """Import ``scripts/<name>.py`` as a module (scripts/ is not a package)."""
    return load_file(SCRIPTS / f"{name}.py")


def sphere(X):
    return np.sum((X - 0.3) ** 2, axis=1)


def rastrigin(X):
    return 10.0 * X.shape[1] + np.sum(X**2 - 10.0 * np.cos(2.0 * np.pi * X), axis=1)


class LogSpace:
    """Duck-typed stand-in for podkrig.parameters.ParameterSpace (log scale, with units)."""

    def __init__(self, lower, upper):
        self.names = tuple(f"k{i}" for i in range(len(lower)))
        self.units = ("N/mm3",) * len(lower)
        self._lo, self._hi = np.log(lower), np.log(upper)

    def from_unit(self, U):
        return np.exp(self._lo + np.asarray(U) * (self._hi - self._lo))

    def to_unit(self, X):
        return (np.log(X) - self._lo) / (self._hi - self._lo)


# --------------------------------------------------------------------------- operators
def test_sobol_initial_population_in_unit_cube_without_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # 40 is not a power of 2: must not warn
        U = ops.initial_population(40, 3, method="sobol", rng=np.random.default_rng(0))
    assert U.shape == (40, 3)
    assert np.all((U >= 0.0) & (U < 1.0))


def test_snap_to_grid_rounds_and_clips():
    U = np.array([[-0.2, 0.26, 1.3], [0.5, 0.74, 0.049]])
    out = ops.snap_to_grid(U.copy(), np.array([4.0, 4.0, 10.0]))
    assert_array_equal(out, [[0.0, 0.25, 1.0], [0.5, 0.75, 0.0]])
    assert_array_equal(ops.snap_to_grid(U.copy(), None), np.clip(U, 0.0, 1.0))


def test_linear_scaling_sets_max_to_c_times_mean_and_keeps_mean():
    cost = np.array([5.0, 4.0, 3.0, 2.5, 2.0])  # raw fitness 0, 1, 2, 2.5, 3: no clipping
    fit = ops.scale_fitness(cost, "linear", pressure=1.5)
    raw = cost.max() - cost
    # exact linear algebra, round-off only
    assert_allclose(fit.mean(), raw.mean(), rtol=1e-12, atol=0.0)
    assert_allclose(fit.max(), 1.5 * raw.mean(), rtol=1e-12, atol=0.0)


def test_linear_scaling_clips_at_zero_when_pressure_is_unreachable():
    cost = np.array([10.0, 1.0, 1.0, 1.0, 0.0])
    fit = ops.scale_fitness(cost, "linear", pressure=2.0)
    raw = cost.max() - cost
    assert_allclose(fit.min(), 0.0, rtol=0.0, atol=1e-12)
    assert_allclose(fit.mean(), raw.mean(), rtol=1e-12, atol=0.0)


def test_linear_ranking_ends_at_eta_plus_and_eta_minus():
    cost = np.array([3.0, 1.0, 2.0, 0.5])
    fit = ops.scale_fitness(cost, "linear_ranking", eta_plus=1.8)
    assert_allclose(fit[3], 1.8, rtol=1e-12, atol=0.0)  # best
    assert_allclose(fit[0], 0.2, rtol=1e-12, atol=1e-15)  # worst, eta- = 2 - eta+
    assert_allclose(fit.sum(), cost.size, rtol=1e-12, atol=0.0)  # expected copies sum to n


def test_exponential_ranking_is_geometric_in_rank():
    cost = np.array([3.0, 1.0, 2.0])
    fit = ops.scale_fitness(cost, "exponential_ranking", base=0.5)
    assert_allclose(fit, [0.25, 1.0, 0.5], rtol=1e-12, atol=0.0)


def test_sus_gives_floor_or_ceil_of_expected_counts():
    rng = np.random.default_rng(1)
    fitness = np.array([0.5, 1.7, 3.1, 0.0, 2.2, 0.9])
    expected = fitness / fitness.sum() * 60
    for _ in range(20):  # Baker (1987): zero bias and minimum spread, for every spin
        counts = np.bincount(ops.select_sus(fitness, 60, rng), minlength=fitness.size)
        assert np.all(counts >= np.floor(expected)) and np.all(counts <= np.ceil(expected))


def test_roulette_frequencies_are_proportional():
    rng = np.random.default_rng(2)
    fitness = np.array([1.0, 2.0, 0.0, 5.0])
    counts = np.bincount(ops.select_roulette(fitness, 80_000, rng), minlength=4)
    # 80 000 draws: binomial standard error of a frequency <= 0.0018, 4 sigma below 0.01
    assert_allclose(counts / 80_000, fitness / fitness.sum(), rtol=0.0, atol=0.01)


def test_tournament_favours_low_cost_and_size_one_is_uniform():
    rng = np.random.default_rng(3)
    cost = np.arange(10.0)
    picks = ops.select_tournament(cost, 20_000, 3, rng)
    counts = np.bincount(picks, minlength=10)
    assert counts[0] > counts[5] > counts[9]
    uniform = np.bincount(ops.select_tournament(cost, 20_000, 1, rng), minlength=10)
    # 20 000 draws over 10 bins: 4 standard errors of a frequency ~ 0.0085
    assert_allclose(uniform / 20_000, 0.1, rtol=0.0, atol=0.0085)


def test_single_point_crossover_swaps_tails():
    rng = np.random.default_rng(4)
    P1, P2 = np.zeros((50, 6)), np.ones((50, 6))
    C1, C2 = ops.crossover_single_point(P1, P2, rng)
    assert_array_equal(C1 + C2, 1.0)
    # each child is a head of one parent followed by the tail of the other (one cut)
    assert np.all(np.diff(C1, axis=1) >= 0.0)
    assert np.all(C1[:, 0] == 0.0) and np.all(C1[:, -1] == 1.0)


def test_arithmetical_crossovers_preserve_the_parents_sum():
    rng = np.random.default_rng(5)
    P1, P2 = rng.random((30, 4)), rng.random((30, 4))
    for lam in (rng.random((30, 1)), 0.25):
        C1, C2 = ops.crossover_arithmetical(P1, P2, lam)
        assert_allclose(C1 + C2, P1 + P2, rtol=1e-12, atol=1e-15)
    C1, _ = ops.crossover_arithmetical(P1, P2, 0.25)
    assert_allclose(C1, 0.25 * P1 + 0.75 * P2, rtol=1e-12, atol=1e-15)


def test_blx_children_stay_in_the_extended_interval():
    rng = np.random.default_rng(6)
    P1, P2 = rng.random((200, 3)), rng.random((200, 3))
    C1, C2 = ops.crossover_blx(P1, P2, 0.5, rng)
    low, high, width = np.minimum(P1, P2), np.maximum(P1, P2), np.abs(P1 - P2)
    for C in (C1, C2):
        assert np.all(C >= low - 0.5 * width - 1e-15) and np.all(C <= high + 0.5 * width + 1e-15)
    assert np.any(C1 < low) and np.any(C1 > high)  # alpha > 0 explores outside


def test_uniform_mutation_resets_on_the_grid():
    rng = np.random.default_rng(7)
    grid = np.array([4.0, 10.0])
    U = np.full((100, 2), 0.5)
    assert_array_equal(ops.mutate_uniform(U.copy(), 0.0, grid, rng), U)
    M = ops.mutate_uniform(U.copy(), 1.0, grid, rng)
    assert_allclose(M * grid, np.rint(M * grid), rtol=0.0, atol=1e-12)
    assert len(np.unique(M[:, 0])) == 5  # all of {0, .25, .5, .75, 1} are reached


def test_gaussian_mutation_moves_at_least_one_grid_step():
    rng = np.random.default_rng(8)
    grid = np.array([1000.0])
    U = np.full((500, 1), 0.5)
    M = ops.mutate_gaussian(U.copy(), 1.0, 1e-6, grid, rng)
    assert np.all(np.abs(M - 0.5) >= 1e-3 - 1e-12)


def test_deb_cost_orders_by_feasibility_then_objective_then_violation():
    f = np.array([5.0, -100.0, 1.0, -50.0])
    v = np.array([0.0, 0.3, 0.0, 0.1])
    cost = ops.deb_cost(f, v)
    # feasible (2 then 0) before infeasible (3 then 1, by violation), whatever f is
    assert_array_equal(np.argsort(cost), [2, 0, 3, 1])


def test_tournament_with_deb_rules_prefers_feasible():
    rng = np.random.default_rng(9)
    f = np.array([10.0, -1e6])
    v = np.array([0.0, 1e-3])  # the infeasible one has a far better objective
    picks = ops.select_tournament(ops.deb_cost(f, v), 1000, 2, rng)
    # a pair contains the feasible individual with probability 3/4 and then it must win
    assert_allclose(np.mean(picks == 0), 0.75, rtol=0.0, atol=0.06)


@pytest.mark.filterwarnings("ignore:GA stopped on its budget:RuntimeWarning")
# --------------------------------------------------------------------------- solver contract
@pytest.mark.parametrize("encoding", ["integer", "real"])
@pytest.mark.parametrize("crossover", ["blx", "single_point", "arithmetical",
                                       "fixed_arithmetical"])
def test_shapes_and_bounds_are_never_left(encoding, crossover):
    bounds = [(-1.0, 2.0), (10.0, 11.0), (-5.0, -4.0)]
    # linear objective: the optimum is on the bounds, so BLX-alpha pushes children outside
    res = minimize(lambda X: X.sum(axis=1), bounds, rng=1, encoding=encoding,
                   crossover=crossover, blx_alpha=2.0, max_generations=15, polish="none",
                   population_size=10)
    lo, hi = np.array(bounds).T
    n = res.nfev
    assert isinstance(res, GAResult)
    assert res.X_history.shape == (n, 3) and res.f_history.shape == (n,)
    assert res.generation_history.shape == (n,) and res.polish_mask.shape == (n,)
    assert res.generation_best.shape == (res.ngen + 1,) == res.generation_nfev.shape
    assert res.population.shape == (10, 3) and res.population_fun.shape == (10,)
    for X in (res.X_history, res.population, res.x[None]):
        assert np.all(X >= lo) and np.all(X <= hi)
    assert_allclose(res.fun, res.f_history.min(), rtol=0.0, atol=0.0)


@pytest.mark.filterwarnings("ignore:GA stopped on its budget:RuntimeWarning")
def test_integer_genes_lie_on_the_grid_of_a_log_parameter_space():
    space = LogSpace([10.0, 1.0], [1000.0, 100.0])
    res = minimize(lambda X: np.sum(np.log(X / [100.0, 3.0]) ** 2, axis=1), space, rng=2,
                   n_grid=[8, 16], polish="none", max_generations=5)
    G = space.to_unit(res.X_history) * [8, 16]
    # log/exp round trip: round-off only
    assert_allclose(G, np.rint(G), rtol=0.0, atol=1e-9)
    assert res.parameter_names == ("k0", "k1") and res.parameter_units == ("N/mm3",) * 2


def test_parameter_space_with_polish_finds_log_optimum():
    space = LogSpace([10.0, 1.0], [1000.0, 100.0])
    x_true = np.array([123.0, 4.5])
    res = minimize(lambda X: np.sum(np.log(X / x_true) ** 2, axis=1), space, rng=3,
                   target=1e-12)
    assert res.success and res.stop_reason == "target"
    # f <= 1e-12 means |log(x/x_true)| <= 1e-6
    assert_allclose(res.x, x_true, rtol=2e-6, atol=0.0)


def test_same_rng_gives_identical_results():
    def run(rng):
        return minimize(rastrigin, [(-5.12, 5.12)] * 3, rng=rng, max_generations=20,
                        stall_generations=None, selection="sus")

    with pytest.warns(RuntimeWarning, match="budget"):
        a, b, c = run(7), run(np.random.default_rng(7)), run(8)
    assert_array_equal(a.X_history, b.X_history)
    assert_array_equal(a.f_history, b.f_history)
    assert_array_equal(a.population, b.population)
    assert a.seed == 7 and b.seed is None
    assert not np.array_equal(a.X_history[: c.nfev], c.X_history[: a.nfev])


@pytest.mark.parametrize(
    "options",
    [
        {"selection": "tournament", "tournament_size": 3},
        {"selection": "roulette", "scaling": "none"},
        {"selection": "roulette", "scaling": "linear", "scaling_pressure": 1.8},
        {"selection": "sus", "scaling": "linear_ranking", "ranking_eta_plus": 2.0},
        {"selection": "sus", "scaling": "exponential_ranking", "ranking_base": 0.8},
        {"crossover": "single_point"},
        {"crossover": "arithmetical"},
        {"crossover": "fixed_arithmetical", "crossover_lambda": 0.3},
        {"crossover": "blx", "blx_alpha": 0.3, "crossover_probability": 0.6},
        {"mutation": "gaussian", "mutation_scale": 0.05, "mutation_probability": 0.3},
        {"init": "random", "n_elite": 0},
        {"encoding": "real", "skip_duplicates": False},
        {"polish": "final", "polish_method": "Nelder-Mead"},
    ],
)
def test_every_operator_reduces_the_sphere(options):
    opts = {"polish": "none", "max_generations": 40, "stall_generations": None} | options
    with pytest.warns(RuntimeWarning, match="budget"):
        res = minimize(sphere, [(-2.0, 2.0)] * 4, rng=11, **opts)
    # 40 generations of any operator set get well below the initial population's best
    assert res.fun < 0.2 * res.generation_best[0]
    assert res.fun <= res.f_history.min()


@pytest.mark.filterwarnings("ignore:GA stopped on its budget:RuntimeWarning")
def test_elitism_makes_the_population_best_non_increasing():
    res = minimize(rastrigin, [(-5.12, 5.12)] * 4, rng=12, n_elite=1, max_generations=30,
                   stall_generations=None, polish="none", crossover="arithmetical")
    assert np.all(np.diff(res.generation_best) <= 0.0)
    assert np.all(np.diff(res.generation_nfev) >= 0)


def test_target_stop_counts_evaluations_up_to_the_first_hit():
    seen = []

    def fun(X):
        f = sphere(X)
        seen.append(f)
        return f

    res = minimize(fun, [(-2.0, 2.0)] * 3, rng=13, target=0.05, polish="none",
                   population_size=30)
    f_all = np.concatenate(seen)  # every value computed, in evaluation order
    first_hit = int(np.argmax(f_all <= 0.05))
    assert res.stop_reason == "target" and res.success
    assert res.nfev == first_hit + 1 == res.f_history.size
    assert f_all.size > res.nfev  # the hit was inside a generation, not at its end
    assert res.f_history[-1] <= 0.05 and np.all(res.f_history[:-1] > 0.05)
    assert "target" in res.message


def test_max_evaluations_is_never_exceeded_polish_included():
    with pytest.warns(RuntimeWarning, match=r"maximum number of evaluations \(333\)"):
        res = minimize(rastrigin, [(-5.12, 5.12)] * 5, rng=14, max_evaluations=333,
                       polish_interval=1)
    assert res.nfev == 333 == res.f_history.size
    assert res.polish_mask.any() and not res.success


def test_polish_is_counted_and_improves_the_grid_optimum():
    res = minimize(sphere, [(-2.0, 2.0)] * 3, rng=15, n_grid=7, polish="final",
                   stall_generations=5)
    # 0.3 is not on the 7-interval grid of [-2, 2]; the L-BFGS-B polish finds it
    # (forward differences, step 1.5e-8: accuracy ~1e-7 in x)
    assert_allclose(res.x, 0.3, rtol=0.0, atol=1e-5)
    assert res.polish_mask.sum() > 0 and res.nfev == res.f_history.size
    assert res.polish_mask[-1]


def test_sphere_optimum_within_atol():
    res = minimize(sphere, [(-5.0, 5.0)] * 6, rng=16)
    assert res.success and res.stop_reason == "stall"
    # L-BFGS-B polish with forward differences: |x - x*| ~ sqrt(eps) scale
    assert_allclose(res.x, 0.3, rtol=0.0, atol=1e-5)


def test_skip_duplicates_saves_evaluations_on_a_coarse_grid():
    kw = {"rng": 17, "n_grid": 4, "max_generations": 20, "stall_generations": None,
          "polish": "none"}
    skip = GeneticAlgorithm(sphere, [(-1.0, 1.0)] * 2, skip_duplicates=True, **kw).run()
    full = GeneticAlgorithm(sphere, [(-1.0, 1.0)] * 2, skip_duplicates=False, **kw).run()
    assert full.nfev == 40 + 20 * 20
    assert skip.nfev < full.nfev / 2  # only 25 distinct grid points exist


def test_steppable_class_callback_and_stop():
    seen = []

    def callback(ga):
        seen.append((ga.generation, ga.nfev, ga.best_fun))
        return ga.generation == 3

    ga = GeneticAlgorithm(sphere, [(-1.0, 1.0)] * 2, rng=18, callback=callback)
    x, f = next(ga)
    assert x.shape == (2,) and f == ga.best_fun and ga.generation == 0
    for _ in ga:
        pass
    assert ga.stop_reason == "callback" and [g for g, _, _ in seen] == [0, 1, 2, 3]
    with pytest.raises(StopIteration):
        ga.step()
    res = ga.result()
    assert res.ngen == 3 and not res.success and "callback" in res.message
    assert ga.population.shape == (40, 2)


def test_result_is_frozen_and_read_only():
    res = minimize(sphere, [(-1.0, 1.0)] * 2, rng=19, stall_generations=3)
    with pytest.raises(AttributeError):
        res.fun = 0.0
    with pytest.raises(ValueError, match="read-only"):
        res.X_history[0, 0] = 1.0


# --------------------------------------------------------------------------- known optima
def test_rastrigin_2d_is_found():
    res = minimize(rastrigin, [(-5.12, 5.12)] * 2, rng=20, target=1e-2, max_evaluations=5000)
    assert res.success and res.fun <= 1e-2
    # f <= 1e-2 implies |x_i| <= ~0.007 (f ~ 2 pi^2 |x|^2 * 10 near the origin)
    assert_allclose(res.x, 0.0, rtol=0.0, atol=8e-3)


def test_rastrigin_10d_is_found():
    res = minimize(rastrigin, [(-5.12, 5.12)] * 10, rng=21, target=1e-2,
                   max_evaluations=20_000, stall_generations=None)
    assert res.success and res.fun <= 1e-2
    assert_allclose(res.x, 0.0, rtol=0.0, atol=8e-3)


def test_restart_after_a_stall_reaches_the_target_the_stall_stop_missed():
    # seed 5 of the issue-12 run (10-D Rastrigin, budget 100 000, target 1e-2, all else
    # default) used to stop on stall in a local minimum with 95 % of the budget unused
    bounds, kw = [(-5.12, 5.12)] * 10, {"rng": 5, "max_evaluations": 100_000, "target": 1e-2}
    stalled = minimize(rastrigin, bounds, on_stall="stop", **kw)
    assert stalled.stop_reason == "stall" and stalled.fun > 0.5
    assert stalled.nfev < 0.2 * kw["max_evaluations"]
    res = minimize(rastrigin, bounds, **kw)  # on_stall="auto": restarts (budget and target)
    assert res.stop_reason == "target" and res.fun <= 1e-2 and res.n_restarts >= 1
    # up to the stall (before the stopped run's final polish) the two runs are the same run
    k = stalled.generation_nfev[-1]
    assert_array_equal(res.X_history[:k], stalled.X_history[:k])
    assert res.fun < stalled.fun


def test_restart_keeps_the_best_and_respects_the_budget():
    # target below the minimum: the run restarts on every stall until the budget is spent
    with pytest.warns(GABudgetWarning, match=r"maximum number of evaluations \(3000\)"):
        res = minimize(sphere, [(-2.0, 2.0)] * 3, rng=31, max_evaluations=3000, target=-1.0,
                       stall_generations=5)
    assert res.nfev == 3000 == res.f_history.size and not res.success
    assert res.n_restarts >= 2
    # the best individual survives each restart: the population's best never increases
    assert np.all(np.diff(res.generation_best) <= 0.0)
    assert res.fun == res.f_history.min()


def test_stall_stops_without_a_budget_or_without_a_target():
    assert GeneticAlgorithm(sphere, [(-1.0, 1.0)], target=0.0).options.on_stall == "stop"
    assert GeneticAlgorithm(sphere, [(-1.0, 1.0)], max_evaluations=10).options.on_stall == "stop"
    both = GeneticAlgorithm(sphere, [(-1.0, 1.0)], max_evaluations=10, target=0.0).options
    assert both.on_stall == "restart" and both.max_generations > 10**9
    assert GeneticAlgorithm(sphere, [(-1.0, 1.0)]).options.max_generations == 1000
    res = minimize(sphere, [(-2.0, 2.0)] * 3, rng=32, target=-1.0, stall_generations=5)
    assert res.stop_reason == "stall" and res.n_restarts == 0


def test_options_object_and_keywords_give_the_same_run():
    opts = GAOptions(population_size=20, selection="sus", polish="none", max_generations=15,
                     stall_generations=None)
    with pytest.warns(GABudgetWarning):
        a = minimize(sphere, [(-2.0, 2.0)] * 3, opts, rng=33)
    with pytest.warns(GABudgetWarning):
        b = minimize(sphere, [(-2.0, 2.0)] * 3, rng=33, **opts.to_dict())
    with pytest.warns(GABudgetWarning):  # keywords replace fields of the options object
        c = minimize(sphere, [(-2.0, 2.0)] * 3, opts, rng=33, selection="tournament")
    assert_array_equal(a.X_history, b.X_history)
    assert not np.array_equal(a.X_history, c.X_history)
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.population_size = 30
    resolved = GeneticAlgorithm(sphere, [(-1.0, 1.0)] * 4, opts).options
    assert resolved.n_elite == 10 and resolved.mutation_probability == 0.25
    assert resolved.polish_method == "L-BFGS-B" and resolved.polish_max_evaluations == 100
    assert resolved.n_grid == (1000,) * 4


def test_tmd_matches_or_beats_den_hartog():
    tmd = load_script("example_ga_tmd")
    mu = 0.05
    res = tmd.optimise(mu, rng=22)
    f_dh, z_dh = tmd.den_hartog(mu)
    peak_dh = tmd.peak_amplification(np.array([[f_dh, z_dh]]), mu)[0]
    # Den Hartog's fixed-point design is approximate: the exact minimax optimum has a peak
    # ~0.01 % lower, so the GA must match or beat it (0.5 % allowance for a coarse search)
    assert res.fun <= 1.005 * peak_dh
    # and lie close to it: the exact optimum differs from Den Hartog's by ~0.002 % in f and
    # ~0.2 % in zeta; the peak is flat in zeta (second order), hence the looser 2 %
    assert_allclose(res.x[0], f_dh, rtol=5e-3, atol=0.0)
    assert_allclose(res.x[1], z_dh, rtol=2e-2, atol=0.0)


def test_tmd_peak_matches_a_brute_force_frequency_sweep():
    tmd = load_script("example_ga_tmd")
    X = np.array([[0.95, 0.12], [1.1, 0.3], [0.8, 0.02]])
    g = np.linspace(0.4, 2.0, 400_001)
    brute = tmd.amplification(g, X[:, :1], X[:, 1:], 0.05).max(axis=1)
    peak = tmd.peak_amplification(X, 0.05)
    assert np.all(peak >= brute * (1.0 - 1e-12))  # the refined peak is never lower
    # the sweep (spacing 4e-6) misses the top of the sharpest peak (zeta = 0.02, curvature
    # ~4e3) by up to ~curvature * spacing**2 / 4 ~ 2e-8 relative
    assert_allclose(peak, brute, rtol=5e-8, atol=0.0)


@pytest.mark.parametrize("handling", ["deb", "penalty"])
def test_constrained_problem_reaches_the_analytical_optimum(handling):
    g06 = load_script("example_ga_constrained")
    x_opt, f_opt = g06.analytical_optimum()
    res = g06.optimise(rng=23, constraint_handling=handling)
    assert res.violation == 0.0
    # feasibility_tol = 1e-6 on g allows |dx| ~ 1e-6 / |grad g| ~ 1e-7 along the active set
    assert_allclose(res.x, x_opt, rtol=0.0, atol=1e-5)
    assert_allclose(res.fun, f_opt, rtol=1e-6, atol=0.0)
    assert np.all(res.f_history[res.violation_history == 0.0] >= f_opt - 0.01)


def test_deb_rules_return_a_feasible_point_over_a_better_infeasible_one():
    # unconstrained minimum at x = 0 is infeasible; the constrained one is x = 1
    res = minimize(lambda X: X[:, 0] ** 2, [(-3.0, 3.0)], rng=24,
                   constraints=lambda X: 1.0 - X[:, :1], stall_generations=10)
    assert res.violation == 0.0 and (res.violation_history > 0).any()
    assert_allclose(res.x, [1.0], rtol=0.0, atol=1e-6)  # SLSQP on an active bound


def test_the_result_as_json_names_its_parameters_and_has_no_nan():
    """``GAResult.to_dict`` is strict JSON: a run where no individual is feasible has no best
    feasible objective per generation (NaN in the result), None in the dict; the best individual by
    name with its units; the per-evaluation history only when asked, one row per evaluation.
    Defects: NaN written into a JSON file, the history (nfev × n_params) in every dict."""
    import json

    with pytest.warns(GABudgetWarning):
        res = minimize(lambda X: np.sum(X, axis=1), LogSpace([1.0, 10.0], [5.0, 50.0]), rng=3, max_generations=3,
                       constraints=lambda X: 100.0 - X[:, 1:])  # k1 <= 50 < 100: never feasible
    assert np.isnan(res.generation_best).all() and res.violation > 0
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert d["generation_best"] == [None] * (res.ngen + 1) and d["generation_nfev"] == res.generation_nfev.tolist()
    assert d["parameters"] == {"k0": res.x[0], "k1": res.x[1]} and d["units"] == {"k0": "N/mm3", "k1": "N/mm3"}
    assert (d["fun"], d["nfev"], d["stop_reason"], d["seed"]) == (res.fun, res.nfev, "max_generations", 3)
    assert "X_history" not in d and "population" not in d
    full = json.loads(json.dumps(res.to_dict(history=True), allow_nan=False))
    assert np.array_equal(full["X_history"], res.X_history) and len(full["polish_mask"]) == res.nfev
    assert np.array_equal(full["population_fun"], res.population_fun)


# --------------------------------------------------------------------------- errors
@pytest.mark.parametrize(
    "options, error, match",
    [
        ({"popsize": 10}, TypeError, "unknown GA option 'popsize'.*population_size"),
        ({"crossover_probability": 1.5}, ValueError,
         r"crossover_probability .*in \[0.0, 1.0\]; got 1.5"),
        ({"selection": "rank"}, ValueError,
         "selection .*'tournament', 'roulette', 'sus'; got 'rank'"),
        ({"tournament_size": 50}, ValueError, r"tournament_size .*in \[1, 40\]; got 50"),
        ({"ranking_eta_plus": 2.5}, ValueError, r"ranking_eta_plus .*in \[1.0, 2.0\]"),
        ({"ranking_base": 1.0}, ValueError, r"ranking_base .*in \(0.0, 1.0\); got 1.0"),
        ({"population_size": 3}, ValueError, r"population_size .*in \[4, inf\]; got 3"),
        ({"population_size": 10.0}, TypeError, "population_size .*integer; got 10.0"),
        ({"n_elite": 39}, ValueError, r"n_elite .*in \[0, 38\]; got 39"),
        ({"n_grid": 0}, ValueError,
         "n_grid .*integer >= 1.*one per parameter; got 0"),
        ({"n_grid": (10, 10, 10)}, ValueError,
         r"n_grid .*2 of them.*got \(10, 10, 10\)"),
        ({"on_stall": "retry"}, ValueError,
         "on_stall .*'auto', 'stop', 'restart'; got 'retry'"),
        ({"options": {"population_size": 10}}, TypeError,
         "options .*GAOptions or None; got dict"),
        ({"polish": "always"}, ValueError, "polish must be one of"),
        ({"constraints": lambda X: X, "polish_method": "L-BFGS-B"}, ValueError,
         "polish_method='L-BFGS-B' .*constraints.*polish_method='SLSQP'"),
    ],
)
def test_bad_options_are_refused_with_a_message(options, error, match):
    with pytest.raises(error, match=match):
        minimize(sphere, [(-1.0, 1.0)] * 2, **options)


def test_bad_bounds_and_objective_are_refused():
    with pytest.raises(ValueError, match=r"bounds\[1\] .*low < high; got \(1.0, 0.0\)"):
        minimize(sphere, [(-1.0, 1.0), (1.0, 0.0)])
    with pytest.raises(ValueError, match=r"bounds must have shape \(n_params, 2\)"):
        minimize(sphere, [(-1.0, 0.0, 1.0)])
    with pytest.raises(ValueError, match=r"fun must return shape \(40,\).*got \(40, 1\)"):
        minimize(lambda X: sphere(X)[:, None], [(-1.0, 1.0)] * 2)
    with pytest.raises(ValueError, match="fun returned NaN at x = "):
        minimize(lambda X: np.full(X.shape[0], np.nan), [(-1.0, 1.0)] * 2)


def test_importing_the_ga_does_not_import_matplotlib():
    code = "import sys, podkrig.ga; assert 'matplotlib' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


# --------------------------------------------------------------------------- figures
def test_figures_have_labelled_axes():
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after choosing the backend (and only if installed)

    space = LogSpace([10.0, 1.0], [1000.0, 100.0])
    res = minimize(lambda X: np.sum(np.log(X / 30.0) ** 2, axis=1), space, rng=25,
                   stall_generations=5)
    axes = [plot_history(res), plot_statistics(res), *plot_parameters(res, xscale=["log"] * 2)]
    for ax in axes:
        assert ax.get_xlabel() and ax.get_ylabel()
    assert axes[2].get_xlabel() == "k0 (N/mm3)"
    plt.close("all")


def test_unit_fun_replaces_the_physical_objective_on_the_genes():
    from podkrig.parameters import Parameter, ParameterSpace

    space = ParameterSpace((Parameter("k", 1.0, 1000.0, "log"), Parameter("b", -1.0, 1.0)))

    def fun(X):
        return (np.log10(X[:, 0]) - 1.5) ** 2 + X[:, 1] ** 2

    calls = []

    def unit_fun(U):
        calls.append(len(U))
        return fun(space.from_unit(U))

    kw = dict(rng=4, population_size=20, max_generations=15)
    physical = GeneticAlgorithm(fun, space, **kw).run()
    unit = GeneticAlgorithm(lambda X: pytest.fail("fun called despite unit_fun"), space, unit_fun=unit_fun, **kw).run()
    # the same objective through the genes: the same run, evaluation for evaluation
    assert_array_equal(unit.x, physical.x)
    assert unit.nfev == physical.nfev
    assert sum(calls) == unit.nfev
    with pytest.raises(TypeError, match="unit_fun must be callable"):
        GeneticAlgorithm(fun, space, unit_fun=3)
