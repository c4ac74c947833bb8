"""Benchmark the online stage: GA inversion and region of equivalence on the surrogate, and the
same inversion with the FE model in the loop.

Default diagonal compression test, 4 free parameters (E_b 5000–20000 MPa, kN_bj 10–1000 and
kV_bj 4–400 N/mm³ log-scaled, r_hj 0.1–1), surrogate from 256 Sobol' FE snapshots (β fitted),
pseudo-measured data from an FE run at a hidden truth with 1 % multiplicative noise. Prints a
Markdown table: seconds and model evaluations of a complete GA inversion (population 100 ×
100 generations + least-squares polish) on the surrogate and with the FE model in the loop, and
the seconds of a region of equivalence from 2^20 ≈ 10⁶ surrogate evaluations. BLAS/MKL limited
to one thread (threadpoolctl); numba kernels use the machine's cores.

Usage: python scripts/bench_inverse.py [--repeat 5] [--fe-generations 100] [--out bench_out]
"""

import argparse
import platform
import time
from pathlib import Path

import numpy as np

BOUNDS = {"E_b": (5000, 20000), "kN_bj": (10, 1000, "log"), "kV_bj": (4, 400, "log"), "r_hj": (0.1, 1.0)}
TRUTH = {"E_b": 11500.0, "kN_bj": 85.0, "kV_bj": 33.0, "r_hj": 0.65}


def setup(out, beta="fit"):
    from fe.scenarios import build_scenario
    from podkrig.online.problem import SurrogateModel
    from podkrig.surrogate.kriging import OrdinaryKriging
    from podkrig.parameters import ParameterSpace
    from podkrig.offline.runner import run_snapshots
    from podkrig.offline.store import SnapshotStore
    from podkrig.surrogate.podkriging import fit_from_store

    scenario = build_scenario("diagonal_compression")
    space = ParameterSpace.from_scenario(scenario, BOUNDS)
    store = out / "bench_inverse_train.h5"
    run_snapshots(store, scenario, space, n=256, seed=0, workers=1)
    t0 = time.perf_counter()
    with SnapshotStore.open(store) as s:
        model = SurrogateModel(fit_from_store(s, kriging=OrdinaryKriging(beta=beta)))
    return scenario, space, model, time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5, help="surrogate inversions timed (different GA seeds)")
    ap.add_argument("--fe-generations", type=int, default=100, help="GA generations with the FE model in the loop")
    ap.add_argument("--out", type=Path, default=Path("bench_out"), help="folder for the training store")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)

    from threadpoolctl import threadpool_limits

    from podkrig.online.invert import invert
    from podkrig.online.problem import FEModel, InverseProblem
    from podkrig.online.measurement import Measurement, NoiseModel
    from podkrig.online.region import likelihood_ratio_region

    with threadpool_limits(1):
        scenario, space, model, fit_seconds = setup(args.out)
        clean = scenario.run(TRUTH).readings
        noisy = clean * (1 + 0.01 * np.random.default_rng(42).standard_normal(clean.shape))
        meas = Measurement(noisy, scenario.sensor_names, scenario.load_levels, source="pseudo-data")
        noise = NoiseModel(delta=0.01)
        problem = InverseProblem(model, meas, noise)
        invert(problem, rng=99)  # warm-up (numba compilation)
        runs = [invert(problem, rng=seed) for seed in range(args.repeat)]
        t_inv = np.median([r.seconds for r in runs])
        n_inv = int(np.median([r.n_evaluations for r in runs]))
        best = runs[0]
        likelihood_ratio_region(problem, best.x, n_samples=2**14)  # warm-up
        region = likelihood_ratio_region(problem, best.x, n_samples=2**20, rng=0)
        # the same region on a surrogate with one exponent shared by all POD modes
        _, _, model_shared, _ = setup(args.out, beta="fit-shared")
        problem_shared = InverseProblem(model_shared, meas, noise)
        best_shared = invert(problem_shared, rng=0)
        likelihood_ratio_region(problem_shared, best_shared.x, n_samples=2**14)  # warm-up
        region_shared = likelihood_ratio_region(problem_shared, best_shared.x, n_samples=2**20, rng=0)
        # the same inversion with the FE model in the loop (no surrogate variance)
        fe_problem = InverseProblem(FEModel(scenario, space), meas, noise)
        fe_run = invert(fe_problem, rng=0, generations=args.fe_generations)

    truth = np.array([TRUTH[n] for n in space.names])
    err_s = np.max(np.abs(best.x / truth - 1))
    err_f = np.max(np.abs(fe_run.x / truth - 1))
    print(f"# Online stage benchmark: diagonal_compression (default mesh, {scenario.n_dofs} dofs), "
          f"{platform.machine()}, BLAS/MKL 1 thread; surrogate fitted in {fit_seconds:.1f} s from 256 snapshots")
    print("\n| task | model | evaluations | seconds | max relative parameter error vs truth |")
    print("|---|---|---|---|---|")
    print(f"| GA inversion 100 × 100 + polish (median of {args.repeat}) | surrogate | {n_inv} | **{t_inv:.3f}** | {err_s:.2%} |")
    print(f"| GA inversion 100 × {args.fe_generations} + polish | FE in the loop | {fe_run.n_evaluations} | {fe_run.seconds:.1f} | {err_f:.2%} |")
    print(f"| region of equivalence (likelihood ratio, 95 %) | surrogate | {region.n_evaluated} | **{region.seconds:.2f}** | {len(region.samples)} members |")
    print(f"| region of equivalence, surrogate with β fit-shared | surrogate | {region_shared.n_evaluated} | {region_shared.seconds:.2f} | {len(region_shared.samples)} members |")
    per_eval_fe = fe_run.seconds / fe_run.n_evaluations
    per_eval_s = t_inv / n_inv
    print(f"\nSpeed-up of the surrogate inversion over FE in the loop: {fe_run.seconds / t_inv:.0f}× in wall time "
          f"({per_eval_fe * 1e3:.1f} ms vs {per_eval_s * 1e6:.0f} µs per evaluation).")
    print("Intervals (95 % region): " + ", ".join(f"{n} [{lo:.4g}, {hi:.4g}]" for n, (lo, hi) in region.intervals.items())
          + "; truth: " + ", ".join(f"{n} {v:g}" for n, v in TRUTH.items()))


if __name__ == "__main__":
    main()
