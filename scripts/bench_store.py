"""Cost of the snapshot store's checksums: loading and resuming a store with and without them.

Builds a store of N rows (synthetic readings, no FE runs) and a copy without its checksums group
(what an older podkrig wrote, which the reader does not verify), then times, interleaved and
repeated, the two operations the checksums slow down:

- load: open + ``parameters()`` + ``snapshot_matrix()`` (what fitting a surrogate reads);
- resume: ``run_snapshots`` on the finished store (open, compare, reopen for writing, nothing to
  run) — what a rerun of a finished stage costs.

A third column measures the cheaper design the owner may choose instead (not what podkrig does):
verify only the metadata, parameters and status at opening and leave the readings to
``podkrig snapshots verify`` (patched in here; the resume reads no readings, so it is unchanged).

Usage: python scripts/bench_store.py [--rows 10000] [--repeat 30]
"""

import argparse
import contextlib
import logging
import os
import platform
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

from fe.scenarios import build_scenario
from podkrig.h5integrity import row_digests
from podkrig.offline.runner import run_snapshots
from podkrig.offline.sampling import sobol
from podkrig.offline.store import _VERIFIED_AT_OPEN, DONE, SnapshotStore
from podkrig.parameters import ParameterSpace


def build(folder, rows):
    sc = build_scenario("diagonal_compression")
    space = ParameterSpace.from_scenario(sc, {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000), "r_hj": (0.2, 1)})
    path = Path(folder) / "checked.h5"
    rng = np.random.default_rng(0)
    with SnapshotStore.create(path, sc, space, sobol(rows, 3, seed=0), sampling="sobol", seed=0) as store:
        for start in range(0, rows, 1000):
            r = np.arange(start, min(start + 1000, rows))
            store.write_results(r, np.full(len(r), DONE), rng.normal(size=(len(r), store.n_loads, store.n_sensors)),
                                [""] * len(r), np.full(len(r), 0.012))
        shape = (store.n_loads, store.n_sensors)
    legacy = Path(folder) / "legacy.h5"
    shutil.copy(path, legacy)
    with h5py.File(legacy, "r+") as f:
        del f["checksums"]
    return sc, space, path, legacy, shape


def load(path):
    with SnapshotStore.open(path) as store:
        return store.parameters(), store.snapshot_matrix()


def resume(path, sc, space, rows):
    return run_snapshots(path, sc, space, n=rows, seed=0, workers=1)


@contextlib.contextmanager
def readings_unverified():
    """The alternative design: datasets other than those verified at opening are not checked on read."""
    original = SnapshotStore._mismatched

    def opening_only(store, name, data):
        return original(store, name, data) if name in _VERIFIED_AT_OPEN else np.zeros(0, np.int64)

    SnapshotStore._mismatched = opening_only
    try:
        yield
    finally:
        SnapshotStore._mismatched = original


def timed(fn, repeat, clock=time.process_time):
    """Times of ``repeat`` calls, s. The default clock is this process's CPU time: on a shared
    machine it excludes the waits for a core that dominate wall-time noise."""
    times = []
    for _ in range(repeat):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return times


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=10000)
    ap.add_argument("--repeat", type=int, default=30)
    args = ap.parse_args()
    logging.disable(logging.WARNING)  # the copy without checksums warns at every opening
    import warnings

    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as folder:
        sc, space, checked, legacy, shape = build(folder, args.rows)
        ops = {
            "load": lambda p: load(p),
            "resume": lambda p: resume(p, sc, space, args.rows),
        }
        results = {}
        for name, op in ops.items():
            op(checked), op(legacy)  # warm the page cache and the imports
            a, b, c, wa, wb = [], [], [], [], []
            for _ in range(args.repeat):  # interleaved: all see the same machine load
                a += timed(lambda: op(checked), 1)
                b += timed(lambda: op(legacy), 1)
                with readings_unverified():
                    c += timed(lambda: op(checked), 1)
                wa += timed(lambda: op(checked), 1, time.perf_counter)
                wb += timed(lambda: op(legacy), 1, time.perf_counter)
            results[name] = [statistics.median(x) for x in (a, b, c, wa, wb)]
        readings = np.random.default_rng(0).normal(size=(args.rows, *shape))
        digest = statistics.median(timed(lambda: row_digests(readings), args.repeat, time.perf_counter))
    load1, load5, load15 = os.getloadavg()
    print(f"**Snapshot store checksums:** {args.rows} rows × {shape[0]} loads × {shape[1]} sensors, "
          f"{platform.machine()}, {os.cpu_count()} cores, load average {load1:.2f} / {load5:.2f} / {load15:.2f}; "
          f"medians of {args.repeat} interleaved runs each, ms of CPU time of this process (wall time in brackets)")
    print()
    print("| operation | verified (checksums) | unverified (same store, no checksums) | overhead CPU (wall) "
          "| alternative: readings not verified on load | its overhead CPU |")
    print("|---|---|---|---|---|---|")
    for name, (a, b, c, wa, wb) in results.items():
        print(f"| {name} | {1e3 * a:.2f} ({1e3 * wa:.2f}) | {1e3 * b:.2f} ({1e3 * wb:.2f}) | "
              f"{100 * (a / b - 1):+.1f} % ({100 * (wa / wb - 1):+.1f} %) | {1e3 * c:.2f} | "
              f"{100 * (c / b - 1):+.1f} % |")
    print()
    print(f"row_digests of the readings alone ({readings.nbytes / 1e6:.1f} MB): {1e3 * digest:.2f} ms "
          f"({readings.nbytes / digest / 1e9:.1f} GB/s)")


if __name__ == "__main__":
    main()
