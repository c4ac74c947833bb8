"""Break-even of a local Dask cluster for FE snapshots: when does ``workers = K`` pay?

Measures, on this machine:

- the start-up and shut-down of the local cluster the runner starts
  (:func:`podkrig.offline.runner.start_local_cluster`, K worker processes, first task round trip
  included: the workers import podkrig and build the scenario);
- the wall time per FE run of the scenarios below, serially in this process;
- ``run_snapshots`` with ``workers=1`` and ``workers=K`` (the serial fallback switched off) on
  small designs, end to end.

and prints the break-even number of runs, ``n* = start-up / (t_run (1 − 1/K))``: below it, a serial
run finishes first. The runner's default (:data:`podkrig.offline.runner.LOCAL_CLUSTER_STARTUP_S`)
comes from this table. The machine load (``os.getloadavg``) is printed beside it: on a shared
machine every number is an upper bound.

Usage: ``python scripts/bench_local_cluster.py [--workers 2] [--repeats 3]``
"""

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from fe.scenarios import build_scenario
from podkrig.offline import runner
from podkrig.offline.runner import run_chunk, run_snapshots, start_local_cluster
from podkrig.parameters import ParameterSpace

SCENARIOS = {
    "diagonal_compression nx=2 ny=1": {"scenario": "diagonal_compression", "nx": 2, "ny": 1},
    "diagonal_compression nx=6 ny=2 (demo)": {"scenario": "diagonal_compression", "nx": 6, "ny": 2},
}


def cluster_startup(workers, spec_json, names, x):
    """Seconds from nothing to the first finished task on a fresh cluster, and to shut it down."""
    t0 = time.perf_counter()
    client, cluster = start_local_cluster(workers)
    futures = [client.submit(run_chunk, spec_json, names, np.array([i]), x[None], False, True, pure=False)
               for i in range(workers)]
    client.gather(futures)
    t1 = time.perf_counter()
    client.close()
    cluster.close()
    return t1 - t0, time.perf_counter() - t1


def ms_per_run(spec, n=20):
    sc = build_scenario(spec)
    sc.run()  # warm-up: assembly caches, numba compilation
    t0 = time.perf_counter()
    for _ in range(n):
        sc.run()
    return 1000 * (time.perf_counter() - t0) / n


def end_to_end(spec, n, workers):
    sc = build_scenario(spec)
    space = ParameterSpace.from_scenario(sc, {"kN_bj": (10.0, 1000.0, "log"), "E_b": (5000.0, 20000.0, "linear")})
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        run_snapshots(Path(d) / "s.h5", sc, space, n=n, seed=0, workers=workers)
        return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    K = args.workers
    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} cores, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (1/5/15 min)")
    spec = SCENARIOS["diagonal_compression nx=2 ny=1"]
    sc = build_scenario(spec)
    names = ("kN_bj",)
    x = np.array([100.0])
    starts, stops = zip(*(cluster_startup(K, sc.spec.to_json(), names, x) for _ in range(args.repeats)))
    start = float(np.median(starts))
    print(f"\nlocal cluster, {K} workers: start-up to first results {start:.2f} s (median of {args.repeats}; "
          f"all {', '.join(f'{s:.2f}' for s in starts)}), shut-down {np.median(stops):.2f} s")
    print(f"\n{'scenario':40s} {'ms/run':>8s} {'break-even runs n*':>20s}")
    for label, s in SCENARIOS.items():
        t = ms_per_run(s)
        n_star = start / (t / 1000 * (1 - 1 / K))
        print(f"{label:40s} {t:8.1f} {n_star:20.0f}")
    print("\nend to end, run_snapshots (s), serial fallback off; demo mesh")
    print(f"{'runs':>6s} {'workers=1':>10s} {f'workers={K}':>10s}")
    saved = runner.LOCAL_CLUSTER_STARTUP_S
    runner.LOCAL_CLUSTER_STARTUP_S = 0.0  # never fall back: measure the cluster itself
    try:
        for n in (8, 64, 256):
            serial = end_to_end(SCENARIOS["diagonal_compression nx=6 ny=2 (demo)"], n, 1)
            parallel = end_to_end(SCENARIOS["diagonal_compression nx=6 ny=2 (demo)"], n, K)
            print(f"{n:6d} {serial:10.2f} {parallel:10.2f}")
    finally:
        runner.LOCAL_CLUSTER_STARTUP_S = saved
    load = os.getloadavg()
    print(f"\nload average after the run {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")


if __name__ == "__main__":
    main()
