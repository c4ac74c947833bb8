"""Benchmark the nonlinear path-following solver on the TU Eindhoven wall J4D (issue 17).

Runs ``shear_compression_nl`` (default mesh unless ``--nx/--ny``) from zero to 3 mm of top
displacement past the peak, for each top condition asked for, and prints a Markdown table: dofs,
wall time, converged steps, attempted increments, Newton iterations, time per iteration, and the
time of one linear solve of the same mesh (factorisation + solve of the linear
``shear_compression`` scenario: the peer the issue's "≤ 2× per iteration" target refers to), plus
the peak load and its displacement. BLAS/MKL are limited to one thread (threadpoolctl); the
machine load (``os.getloadavg``) is printed beside the table, since timings on a shared machine
scale with it. Times are given as wall time and as the process' CPU time (``time.process_time``:
one thread, so it is the single-core cost, much less inflated by a loaded machine than wall time);
the CPU time is split into numerical factorisations, solves, interface-law updates and assembly
(the solver's calls, timed in place).

With ``--snapshots N`` it also runs N J4D snapshots over a Sobol' design of the eight strength and
stiffness parameters (ranges below, INFERRED: docs/references.md) on ``--workers`` processes and
prints how many reached 3 mm, the failure reasons and the wall time.

Usage: python scripts/bench_nonlinear.py [--nx 6 --ny 2] [--top fixed_vertical constant_force]
       [--snapshots 256 --workers 2 --store j4d.h5]   (--top with no value: snapshots only)
"""

import argparse
import collections
import dataclasses
import os
import platform
import tempfile
import time
from pathlib import Path

from threadpoolctl import threadpool_limits

from fe.interfaces import CompositeInterface, HyperbolicInterface

#: Sobol' ranges of the J4D snapshot study (INFERRED, reference §1a table and §2.1 Set A ± ~40 %)
SNAPSHOT_RANGES = {
    "kN_bj": (50.0, 120.0, "linear"), "kV_bj": (20.0, 50.0, "linear"),
    "ft_bj": (0.15, 0.30, "linear"), "c_bj": (0.30, 0.50, "linear"),
    "tanphi_bj": (0.6, 0.9, "linear"), "GfI_bj": (0.01, 0.03, "linear"),
    "GfII_bj": (0.05, 0.2, "linear"), "E_b": (12000.0, 20000.0, "linear"),
}


class CpuTimer:
    """Accumulates the process CPU time (s) and calls of wrapped callables by label."""

    def __init__(self):
        self.seconds = collections.Counter()
        self.calls = collections.Counter()

    def wrap(self, label, fun):
        def timed(*args, **kwargs):
            c0 = time.process_time()
            try:
                return fun(*args, **kwargs)
            finally:
                self.seconds[label] += time.process_time() - c0
                self.calls[label] += 1
        return timed


def linear_solve_ms(nx, ny, repeat=10):
    """One linear run of the same mesh: (wall ms, CPU ms)."""
    from fe.scenarios import build_scenario

    sc = build_scenario({"scenario": "shear_compression", "nx": nx, "ny": ny})
    sc.run()
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(repeat):
        sc.run()
    return (time.perf_counter() - t0) / repeat * 1e3, (time.process_time() - c0) / repeat * 1e3


def run_j4d(nx, ny, top):
    from fe.scenarios import build_scenario

    sc = build_scenario({"scenario": "shear_compression_nl", "nx": nx, "ny": ny, "top": top})
    # warm up: numba kernels loaded or compiled, PARDISO's symbolic analysis done
    sc.run(settings=dataclasses.replace(sc.options.path_settings(), max_steps=10))
    timer = CpuTimer()
    model, solver = sc.model, sc.model.solver
    solver.factorize = timer.wrap("factorisation", solver.factorize)
    solver.solve = timer.wrap("solve", solver.solve)
    model.tangent_and_force = timer.wrap("assembly", model.tangent_and_force)
    laws = (CompositeInterface, HyperbolicInterface)
    updates = [law.update for law in laws]
    for law, update in zip(laws, updates):
        law.update = timer.wrap("law update", update)
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        r = sc.run()
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        for law, update in zip(laws, updates):
            law.update = update
    p = r.path
    its = max(p.total_iterations, 1)
    split = ", ".join(f"{k} {1e3 * v / its:.1f} ms/it ({timer.calls[k]} calls)" for k, v in timer.seconds.items())
    return dict(top=top, dofs=sc.n_dofs, seconds=seconds, cpu=cpu, steps=len(p.path), attempted=p.attempted_steps,
                iterations=p.total_iterations, per_iteration=1e3 * cpu / its, split=split,
                peak=r.peak_load, peak_u=r.peak_displacement, reached=r.reached, status=r.status, message=r.message)


def snapshots(n, workers, nx, ny, store_path=None):
    """Run ``n`` J4D snapshots into ``store_path`` (a temporary store when None); returns the
    run summary, the wall time (s) and the failure reasons counted by exception name."""
    from fe.scenarios import build_scenario
    from podkrig.offline.runner import run_snapshots
    from podkrig.offline.store import SnapshotStore
    from podkrig.parameters import ParameterSpace

    sc = build_scenario({"scenario": "shear_compression_nl", "nx": nx, "ny": ny})
    space = ParameterSpace.from_scenario(sc, SNAPSHOT_RANGES)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(store_path) if store_path else Path(tmp) / "j4d.h5"
        t0 = time.perf_counter()
        summary = run_snapshots(path, sc, space, n=n, seed=0, workers=workers)
        seconds = time.perf_counter() - t0
        with SnapshotStore.open(path) as store:
            reasons = collections.Counter(e.split(":")[0] for e in store.errors().values())
    return summary, seconds, reasons


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nx", type=int, default=6)
    ap.add_argument("--ny", type=int, default=2)
    ap.add_argument("--top", nargs="*", default=["fixed_vertical", "constant_force"],
                    help="top conditions of the single J4D runs (none: only the snapshot study)")
    ap.add_argument("--snapshots", type=int, default=0)
    ap.add_argument("--store", help="keep the snapshot store in this HDF5 file (default: a temporary one)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"load average before: {', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    with threadpool_limits(1):
        lin_wall, lin_cpu = linear_solve_ms(args.nx, args.ny) if args.top else (0.0, 0.0)
        rows = [run_j4d(args.nx, args.ny, top) for top in args.top]
    if rows:
        print("\n| top | dofs | wall (s) | CPU (s) | steps | increments | iterations | CPU ms / iteration "
              "| linear solve CPU (ms) | ratio | peak (kN) | at (mm) | reached (mm) | status |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for r in rows:
        print(f"| {r['top']} | {r['dofs']} | {r['seconds']:.1f} | {r['cpu']:.1f} | {r['steps']} | {r['attempted']} "
              f"| {r['iterations']} | {r['per_iteration']:.1f} | {lin_cpu:.1f} | {r['per_iteration'] / lin_cpu:.1f} "
              f"| {r['peak']:.1f} | {r['peak_u']:.2f} | {r['reached']:.2f} | {r['status']} |")
    if rows:
        print(f"\nlinear solve wall time: {lin_wall:.1f} ms")
    for r in rows:
        print(f"{r['top']} CPU split: {r['split']}")
        if r["message"]:
            print(f"{r['top']}: {r['message']}")
    if args.snapshots:
        summary, seconds, reasons = snapshots(args.snapshots, args.workers, args.nx, args.ny, args.store)
        print(f"\n{args.snapshots} J4D snapshots on {args.workers} workers: {summary.done} reached 3 mm "
              f"({100 * summary.done / args.snapshots:.1f} %), {summary.failed} failed {dict(reasons)}; "
              f"{seconds / 60:.1f} min")
    print(f"\nload average after: {', '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
