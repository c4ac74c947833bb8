"""Benchmark of the offline stage: snapshots per second and overheads of store and scheduler.

Measures, on the default ``diagonal_compression`` scenario (default mesh) and one Sobol' design:

1. the FE alone: ``scenario.run(params)`` in a loop, per snapshot;
2. the serial runner (``workers=1``): FE plus sampling, the HDF5 store and its flushes;
3. ``--workers`` local Dask worker processes, warm (cluster started and the scenario built on every
   worker beforehand, as in a long job), against the ideal ``FE time / workers``;
4. the same end to end, including starting the cluster and building the scenario on the workers.

Every process runs one BLAS/MKL/OpenMP thread (threadpoolctl here, ``OMP_NUM_THREADS=1
MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1`` for the workers); local clusters use the runner's
settings (:data:`podkrig.offline.runner.LOCAL_DASK_CONFIG`: worker profiler off). The measurements are
repeated ``--repeat`` times, interleaved, and the best of each is kept. A fifth line runs the same
FE loops in plain processes (no Dask, no store): the ceiling of any parallel executor on the
machine. Prints Markdown.

Usage::

    .venv/bin/python scripts/bench_offline.py --n 256
"""

import argparse
import multiprocessing
import os
import platform
import tempfile
import time
from pathlib import Path


def _independent(spec_json, names, X, barrier, results):
    """One plain process (no Dask): build, wait for the others, time an FE loop over ``X``."""
    from podkrig.offline.runner import cached_scenario, limit_threads_to_one

    limit_threads_to_one()
    sc = cached_scenario(spec_json)
    sc.run(dict(zip(names, X[0].tolist())))
    barrier.wait()
    t0 = time.perf_counter()
    for x in X:
        sc.run(dict(zip(names, x.tolist())))
    results.put(time.perf_counter() - t0)


def _parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=256, help="snapshots per measurement (default 256)")
    p.add_argument("--workers", type=int, default=2, help="local Dask workers (default 2)")
    p.add_argument("--chunk-size", type=int, default=None, help="rows per Dask task (default: the runner's)")
    p.add_argument("--repeat", type=int, default=3, help="repetitions; the best time is kept (default 3)")
    return p.parse_args(argv)


def main(argv=None):
    args = _parse_args(argv)
    from podkrig.offline.runner import limit_threads_to_one

    limit_threads_to_one()  # before any scenario is built (PARDISO keeps its analysis thread count)
    import numpy as np
    import psutil

    from fe.scenarios import build_scenario
    from podkrig.parameters import ParameterSpace
    from podkrig.offline.runner import run_chunk, run_snapshots, start_local_cluster
    from podkrig.offline.sampling import sobol
    from podkrig.offline.store import SnapshotStore

    t = time.perf_counter()
    sc = build_scenario("diagonal_compression")
    build_s = time.perf_counter() - t
    space = ParameterSpace.from_scenario(sc, {
        "E_b": (5000, 20000), "kN_bj": (10, 1000, "log"), "kV_bj": (5, 500, "log"), "r_hj": (0.2, 1.0),
    })
    n, seed = args.n, 0
    X = space.from_unit(sobol(n, space.n_params, seed))
    sc.run(space.as_params(X[0]))  # first run: solver analysis

    tmp_dir = tempfile.TemporaryDirectory(prefix="bench_offline_")  # removed at exit, even on errors
    tmp = Path(tmp_dir.name)
    counter = iter(range(10**6))
    spec_json = sc.spec.to_json()
    me = psutil.Process()

    def cpu_seconds():
        """CPU time (user + system) of this process and all its children (Dask nannies, workers), s."""
        total = sum(me.cpu_times()[:2])
        for child in me.children(recursive=True):
            try:
                total += sum(child.cpu_times()[:2])
            except psutil.Error:
                pass
        return total

    def measure(run):
        """Wall and CPU time of ``run()``, plus the FE times the store recorded per row (s)."""
        c0, t0 = cpu_seconds(), time.perf_counter()
        path = run()
        wall, cpu = time.perf_counter() - t0, cpu_seconds() - c0
        fe_wall = fe_cpu = float("nan")
        if path is not None:
            with SnapshotStore.open(path) as store:
                assert store.counts()["done"] == n
                fe_wall, fe_cpu = store.wall_times().sum(), store.cpu_times().sum()
        return {"wall": wall, "cpu": cpu, "fe_wall": fe_wall, "fe_cpu": fe_cpu}

    def fe_loop():
        for x in X:
            sc.run(space.as_params(x))

    def serial():
        path = tmp / f"s{next(counter)}.h5"
        run_snapshots(path, sc, space, n=n, seed=seed, workers=1)
        return path

    def plain_processes():
        # the ceiling of any executor on this machine: K plain processes, no scheduler, no store
        ctx = multiprocessing.get_context("spawn")
        barrier, results = ctx.Barrier(args.workers), ctx.Queue()
        procs = [ctx.Process(target=_independent, args=(spec_json, space.names, part, barrier, results))
                 for part in np.array_split(X, args.workers)]
        for p in procs:
            p.start()
        elapsed = max(results.get() for _ in procs)
        for p in procs:
            p.join()
        return elapsed

    t = time.perf_counter()
    client, cluster = start_local_cluster(args.workers)  # as the runner starts it
    start_s = time.perf_counter() - t
    t = time.perf_counter()
    warm = [client.submit(run_chunk, spec_json, space.names, np.array([0]), X[:1], False, True, workers=[w],
                          pure=False, allow_other_workers=False) for w in client.scheduler_info()["workers"]]
    client.gather(warm)
    warm_s = time.perf_counter() - t

    def dask_warm():
        path = tmp / f"d{next(counter)}.h5"
        run_snapshots(path, sc, space, n=n, seed=seed, scheduler=cluster.scheduler_address,
                      chunk_size=args.chunk_size)
        return path

    # interleaved repetitions, best of each: a shared machine's load then hits every executor alike
    runs = {"fe": [], "serial": [], "dask": []}
    plain = []
    for _ in range(args.repeat):
        runs["fe"].append(measure(fe_loop))
        runs["serial"].append(measure(serial))
        plain.append(plain_processes())
        runs["dask"].append(measure(dask_warm))
    client.close()
    cluster.close()

    t = time.perf_counter()
    summary = run_snapshots(tmp / "e2e.h5", sc, space, n=n, seed=seed, workers=args.workers,
                            chunk_size=args.chunk_size)
    e2e_s = time.perf_counter() - t
    assert summary.done == n
    tmp_dir.cleanup()

    def best(key, f):
        return min(f(r) for r in runs[key])

    w, ms = args.workers, 1000 / n  # s per run -> ms per snapshot
    fe_s, serial_s, dask_s, plain_s = best("fe", lambda r: r["wall"]), best("serial", lambda r: r["wall"]), \
        best("dask", lambda r: r["wall"]), min(plain)
    # CPU time per snapshot, each repetition net of the FE runs' own CPU time as the store recorded it
    fe_ms = ms * best("serial", lambda r: r["fe_cpu"])
    store_ms = ms * best("serial", lambda r: r["cpu"] - r["fe_cpu"])
    dask_ms = ms * best("dask", lambda r: r["cpu"] - r["fe_cpu"])  # store + scheduler + workers' idle
    sched_ms = dask_ms - store_ms
    worker_wall_ms = ms * best("dask", lambda r: r["fe_wall"])
    worker_cpu_ms = ms * best("dask", lambda r: r["fe_cpu"])
    speedup = serial_s / dask_s
    overhead = dask_ms / fe_ms

    print(f"Default `diagonal_compression` ({sc.n_dofs} dofs, {sc.mesh.n_nodes} nodes), {n} Sobol' samples of "
          f"{', '.join(space.names)}; {os.cpu_count()} cores ({platform.machine()}), shared: load average "
          f"{os.getloadavg()[0]:.2f} at the end; one BLAS/MKL thread per process (threadpoolctl; "
          f"OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 for workers); Dask worker profiler off; "
          f"best of {args.repeat} interleaved repetitions; scenario build {build_s:.2f} s.\n")
    print("| executor | wall time, s | snapshots/s | vs serial runner |")
    print("|---|---:|---:|---:|")
    rows = [
        ("FE alone (`scenario.run` loop)", fe_s),
        ("serial runner (`--workers 1`, store included)", serial_s),
        (f"ideal {w} workers (FE alone / {w})", fe_s / w),
        (f"{w} plain processes: FE loops, no Dask, no store (the machine's ceiling)", plain_s),
        (f"{w} local Dask workers, warm", dask_s),
        (f"{w} local Dask workers, end to end (cluster start + worker builds + run)", e2e_s),
    ]
    for name, wall in rows:
        print(f"| {name} | {wall:.2f} | {n / wall:.1f} | {serial_s / wall:.2f}× |")
    print()
    print("| CPU time per snapshot (all processes) | ms | % of FE |")
    print("|---|---:|---:|")
    print(f"| FE run (recorded per row by the serial runner) | {fe_ms:.2f} | 100 % |")
    print(f"| store and runner: serial runner − its FE runs | {store_ms:.2f} | {100 * store_ms / fe_ms:.1f} % |")
    print(f"| scheduler: Dask run − its FE runs − store | {sched_ms:.2f} | {100 * sched_ms / fe_ms:.1f} % |")
    print(f"| store + scheduler | {dask_ms:.2f} | {100 * overhead:.1f} % |")
    print()
    print(f"Inside the {w} Dask workers an FE run took {worker_wall_ms:.2f} ms wall, {worker_cpu_ms:.2f} ms CPU "
          f"(single process: {1000 * fe_s / n:.2f} ms wall): {w} busy processes on {os.cpu_count()} shared cores "
          f"run each FE solve slower, which the plain-process line shows as the machine's ceiling; Dask "
          f"reaches {100 * plain_s / dask_s:.0f} % of it. Cluster start {start_s:.2f} s; scenario build on the "
          f"workers {warm_s:.2f} s (once per worker).\n")
    print(f"Targets: {w} workers ≥ 1.8× serial throughput: {speedup:.2f}× "
          f"({'met' if speedup >= 1.8 else 'MISSED'}); store + scheduler overhead < 10 % of FE time "
          f"(CPU): {100 * overhead:.1f} % ({'met' if overhead < 0.10 else 'MISSED'}).")

if __name__ == "__main__":
    main()
