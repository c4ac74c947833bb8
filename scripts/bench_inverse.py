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

Under load (issue 20): ``--background N --surrogate S.h5 --data M.csv [--noise-rel 0.01]`` times
the GA inversion, the region of equivalence from 2^20 ≈ 10⁶ evaluations and the RVC of a saved
surrogate, first on the machine as it is ("idle") and then with N single-threaded CPU hogs of its
own running (always stopped at the end, also on Ctrl-C or an error), with the thread rules of
``podkrig.parallel`` and, as the peer in the same run, with every kernel call split over all numba
threads (the rule before issue 20). Prints the thread settings and ``os.getloadavg()`` beside the
table.
"""

import argparse
import os
import platform
import subprocess
import sys
import time
from contextlib import contextmanager
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
    ap.add_argument("--background", type=int, default=None, metavar="N",
                    help="time the online stage idle and with N single-threaded CPU hogs (needs --surrogate, --data)")
    ap.add_argument("--surrogate", type=Path, help="saved surrogate (.h5) for --background")
    ap.add_argument("--data", type=Path, help="measurement CSV for --background")
    ap.add_argument("--noise-rel", type=float, default=0.01, help="relative noise δ for --background")
    ap.add_argument("--train", type=Path, help="snapshot store: with --background, also time fitting a surrogate on it")
    args = ap.parse_args(argv)
    if args.background is not None:
        if args.surrogate is None or args.data is None:
            ap.error("--background needs --surrogate S.h5 and --data M.csv")
        if args.background < 1:
            ap.error(f"--background must be at least 1 (got {args.background})")
        return under_load(args)
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


@contextmanager
def cpu_hogs(n):
    """``n`` single-threaded busy-loop subprocesses inside the block; killed and reaped on exit."""
    hogs = []
    try:
        for _ in range(n):
            hogs.append(subprocess.Popen([sys.executable, "-c", "while True: pass"]))
        time.sleep(0.5)  # let the scheduler see them
        yield hogs
    finally:
        for h in hogs:
            h.kill()
        for h in hogs:
            h.wait()


@contextmanager
def split_every_call(on):
    """With ``on``, split every kernel call over all numba threads (the rule before issue 20)."""
    from podkrig import parallel

    before = parallel.MIN_WORK_PER_THREAD
    parallel.MIN_WORK_PER_THREAD = 0 if on else before
    try:
        yield
    finally:
        parallel.MIN_WORK_PER_THREAD = before


def time_online(problem, model, repeat, train=None):
    """Seconds of the inversion (median of ``repeat``), region (2^20 evaluations) and RVC, and of a
    surrogate fit on the store ``train`` (when given)."""
    from podkrig.online.invert import invert
    from podkrig.online.propagation import rvc
    from podkrig.online.region import likelihood_ratio_region

    c0 = time.process_time()
    runs = [invert(problem, rng=seed) for seed in range(repeat)]
    c1 = time.process_time()
    region = likelihood_ratio_region(problem, runs[0].x, n_samples=2**20, rng=0)
    c2 = time.process_time()
    t0 = time.perf_counter()
    rvc(region, model, fixed=problem.fixed, rng=0)
    t_rvc, c3 = time.perf_counter() - t0, time.process_time()
    out = {"inversion": float(np.median([r.seconds for r in runs])), "evaluations": runs[0].n_evaluations,
           "region": region.seconds, "region_evaluations": region.n_evaluated, "rvc": t_rvc,
           "cpu": {"inversion": (c1 - c0) / repeat, "region": c2 - c1, "rvc": c3 - c2}, "load": os.getloadavg()[0]}
    if train is not None:
        from podkrig.offline.store import SnapshotStore
        from podkrig.surrogate.podkriging import fit_from_store

        t0 = time.perf_counter()
        with SnapshotStore.open(train) as store:
            fit_from_store(store)
        out["training"], out["cpu"]["training"] = time.perf_counter() - t0, time.process_time() - c3
    return out


def under_load(args):
    import numba
    from threadpoolctl import threadpool_info

    from podkrig import parallel
    from podkrig.cli.invert import build_problem
    from podkrig.online.invert import invert
    from podkrig.online.region import likelihood_ratio_region

    problem, model, _ = build_problem(args.surrogate, args.data, [], args.noise_rel, None, [], [])
    with parallel.one_blas_thread():  # warm-up: numba compilation of both entry points
        best = invert(problem, rng=99)
        with split_every_call(True):
            likelihood_ratio_region(problem, best.x, n_samples=2**12)
    load0 = os.getloadavg()
    results = {}
    for policy, split in (("podkrig.parallel", False), ("split every call", True)):
        with split_every_call(split):
            results[policy, "idle"] = time_online(problem, model, args.repeat, args.train)
            with cpu_hogs(args.background):
                results[policy, "loaded"] = time_online(problem, model, args.repeat, args.train)
    blas = ", ".join(sorted({f"{i['internal_api']} {i['num_threads']}" for i in threadpool_info() if i["user_api"] == "blas"}))
    print(f"# Online stage under load: {args.surrogate} + {args.data}, δ = {args.noise_rel:g}; "
          f"{platform.machine()}, {os.cpu_count()} CPUs, {parallel.available_cores()} available "
          f"(affinity {parallel.affinity_cores()}, cgroup quota {parallel.cgroup_cpu_limit()}); "
          f"numba {numba.__version__} pool {numba.config.NUMBA_NUM_THREADS} threads, layer {numba.threading_layer()}; "
          f"BLAS ({blas} by default) 1 thread in the online stage; one call split only above "
          f"{2 * parallel.MIN_WORK_PER_THREAD:.0e} work units; load average at start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    print(f"\n'loaded' = {args.background} single-threaded CPU hog(s) of this benchmark besides whatever else runs. "
          "Wall seconds (process CPU seconds); ratio = loaded / idle wall time.")
    print("\n| rule | task | evaluations | idle s (CPU s) | loaded s (CPU s) | loaded / idle | load avg idle / loaded |")
    print("|---|---|---|---|---|---|---|")
    for policy in ("podkrig.parallel", "split every call"):
        idle, loaded = results[policy, "idle"], results[policy, "loaded"]
        for task, label, n in (("inversion", f"GA inversion + polish (median of {args.repeat})", idle["evaluations"]),
                               ("region", "region of equivalence (likelihood ratio)", idle["region_evaluations"]),
                               ("rvc", "RVC of the calibration model", ""),
                               ("training", f"surrogate fit on {args.train}", "")):
            if task not in idle:
                continue
            print(f"| {policy} | {label} | {n} | {idle[task]:.3f} ({idle['cpu'][task]:.2f}) | "
                  f"{loaded[task]:.3f} ({loaded['cpu'][task]:.2f}) | {loaded[task] / idle[task]:.2f} | "
                  f"{idle['load']:.1f} / {loaded['load']:.1f} |")
    print(f"\nload average at the end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
