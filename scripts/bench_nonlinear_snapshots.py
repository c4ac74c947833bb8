"""J4D snapshot robustness and cost: how many of N Sobol' runs reach the end of the control range.

Runs ``shear_compression_nl`` (J4D, default mesh and default control range of each top condition
asked for) on a Sobol' design (seed 0) of the eight strength and stiffness parameters of the
scenario, ``E_b, kN_bj, kV_bj, ft_bj, c_bj, tanphi_bj, GfI_bj, GfII_bj``, over the scenario's
defaults (the TU Eindhoven Set A) ± ``--spread`` (20 %: the widest equal spread whose box the
scenario admits, ``f_t ≤ c / tanφ`` at every corner; ± 30 % is refused), through the offline runner
(:func:`podkrig.offline.runner.run_snapshots`, the path of ``podkrig snapshots run``) on
``--workers`` local processes (2). It prints one Markdown row per top condition: runs, how many
reached the end of the control range (a run that stops early is a failed row), the failure
reasons, the CPU time per run (the store's ``cpu_time``: min / median / mean / p90 / max), the
wall time of the whole study and the machine load, then the parameters and the error of every
failed run. ``--busy`` keeps one core busy with a second process (a Python spin loop) for the
whole run: whether a snapshot reaches the end must not depend on it.

``--per-run`` instead runs the same Sobol' points one after the other in this process (BLAS on
one thread, no store) and prints one row per run with the solver's counts: converged steps,
failed (cut-back) increments, attempted increments, Newton iterations, relaxed steps, CPU time,
peak and the end reached, then the CPU mean and maximum and the totals. ``--rows`` picks points
and ``--set NAME=VALUE`` overrides a :class:`fe.solvers.nonlinear.PathSettings` field (a JSON
value), so that a change of the step control can be compared run by run on the slow points.

Usage: python scripts/bench_nonlinear_snapshots.py [--n 256] [--workers 2]
       [--top fixed_vertical constant_force] [--busy] [--store-dir DIR]
       python scripts/bench_nonlinear_snapshots.py --per-run [--n 16] [--rows 0 3] [--set cutback=0.25]
"""

import argparse
import collections
import dataclasses
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fe.scenarios import build_scenario
from podkrig.offline.runner import run_snapshots
from podkrig.offline.store import SnapshotStore
from podkrig.parameters import ParameterSpace

#: The eight strength and stiffness parameters of the study.
PARAMETERS = ("E_b", "kN_bj", "kV_bj", "ft_bj", "c_bj", "tanphi_bj", "GfI_bj", "GfII_bj")


def space_around_defaults(sc, spread):
    """The study's parameter space: each of :data:`PARAMETERS` over its default ± ``spread``."""
    bounds = {}
    for name in PARAMETERS:
        d = sc.parameters[name].default
        bounds[name] = (d * (1 - spread), d * (1 + spread), "linear")
    return ParameterSpace.from_scenario(sc, bounds)


def load():
    return ", ".join(f"{v:.1f}" for v in os.getloadavg())


def study(top, n, workers, spread, store_dir):
    """Run the snapshots of one top condition; returns the table row and the failed rows' lines."""
    sc = build_scenario({"scenario": "shear_compression_nl", "top": top})
    space = space_around_defaults(sc, spread)
    path = Path(store_dir) / f"j4d_{top}_{n}.h5"
    load_before = load()
    t0 = time.perf_counter()
    summary = run_snapshots(path, sc, space, n=n, seed=0, workers=workers)
    seconds = time.perf_counter() - t0
    with SnapshotStore.open(path) as store:
        errors = store.errors()
        cpu = store.cpu_times()
        params = store.parameters(only_done=False)
    cpu = cpu[np.isfinite(cpu)]
    reasons = collections.Counter(e.split(":")[0] for e in errors.values())
    stats = " / ".join(f"{v:.1f}" for v in (cpu.min(), np.median(cpu), cpu.mean(), np.percentile(cpu, 90), cpu.max()))
    end = sc.load_levels[-1]
    row = (f"| {top} | {end:g} | {summary.total} | {summary.done} ({100 * summary.done / summary.total:.1f} %) "
           f"| {dict(reasons) or '-'} | {stats} | {seconds / 60:.1f} | {load_before} → {load()} |")
    failed = [f"- {top}, row {i}: " + ", ".join(f"{k} {v:.4g}" for k, v in zip(space.names, params[i]))
              + f"; {errors[i][:300]}" for i in sorted(errors)]
    return row, failed


def settings_overrides(items):
    """``NAME=VALUE`` strings (VALUE as JSON, e.g. ``cutback=0.25``, ``line_search=false``) → dict."""
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise SystemExit(f"--set expects NAME=VALUE; got {item!r}")
        out[name] = json.loads(value)
    return out


def per_run(top, n, spread, rows=None, overrides=None):
    """Run Sobol' points of one top condition in this process; returns one dict of counts per run."""
    from threadpoolctl import threadpool_limits

    from podkrig.offline.sampling import sample

    sc = build_scenario({"scenario": "shear_compression_nl", "top": top})
    space = space_around_defaults(sc, spread)
    X = space.from_unit(sample("sobol", n, space.n_params, 0))
    settings = dataclasses.replace(sc.options.path_settings(), **(overrides or {}))
    out = []
    with threadpool_limits(1):
        for i in range(n) if rows is None else rows:
            c0 = time.process_time()
            r = sc.run(space.as_params(X[i]), settings=settings)
            p = r.path
            out.append(dict(row=i, status=r.status, steps=len(p.path), failed=p.failed_steps,
                            attempted=p.attempted_steps, iterations=p.total_iterations,
                            relaxed=len(p.relaxed_steps), cpu=time.process_time() - c0, peak=r.peak_load,
                            at=r.peak_displacement, end=float(p.path[-1]) if len(p.path) else float("nan")))
    return out


def print_per_run(top, runs):
    print(f"\n{top}\n\n| row | status | steps | failed | attempted | iterations | relaxed | CPU s | peak kN | at mm "
          "| end mm |\n|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for d in runs:
        print(f"| {d['row']} | {d['status']} | {d['steps']} | {d['failed']} | {d['attempted']} | {d['iterations']} "
              f"| {d['relaxed']} | {d['cpu']:.2f} | {d['peak']:.4f} | {d['at']:.4f} | {d['end']:.4g} |", flush=True)
    cpu = np.array([d["cpu"] for d in runs])
    print(f"\n{top}: CPU s per run mean {cpu.mean():.2f}, max {cpu.max():.2f}; failed increments "
          f"{sum(d['failed'] for d in runs)}, Newton iterations {sum(d['iterations'] for d in runs)}, "
          f"steps {sum(d['steps'] for d in runs)} over {len(runs)} runs")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=256, help="Sobol' points per top condition (a power of two)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--top", nargs="+", default=["fixed_vertical", "constant_force"],
                    choices=["fixed_vertical", "constant_force"])
    ap.add_argument("--spread", type=float, default=0.2, help="bounds: default × (1 ± spread)")
    ap.add_argument("--busy", action="store_true", help="keep one core busy with a second process during the run")
    ap.add_argument("--store-dir", help="keep the stores here (default: a temporary directory)")
    ap.add_argument("--per-run", action="store_true",
                    help="run the points one by one in this process and print the solver's counts per run")
    ap.add_argument("--rows", type=int, nargs="+", help="with --per-run: only these Sobol' points")
    ap.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE",
                    help="with --per-run: override PathSettings fields (JSON values)")
    args = ap.parse_args(argv)
    if args.per_run:
        overrides = settings_overrides(args.set)
        print(f"load average {load()}; {args.n} Sobol' points, Set A ± {100 * args.spread:g} %, "
              f"settings overrides {overrides or 'none'}; CPU times with BLAS on one thread")
        for top in args.top:
            print_per_run(top, per_run(top, args.n, args.spread, args.rows, overrides))
        return
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; {args.n} J4D snapshots per top condition on "
          f"{args.workers} workers; parameters {', '.join(PARAMETERS)} at Set A ± {100 * args.spread:g} %"
          + ("; one core kept busy by a second process" if args.busy else ""), flush=True)
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if args.busy else None
    rows, failed = [], []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            store_dir = Path(args.store_dir or tmp)
            store_dir.mkdir(parents=True, exist_ok=True)
            for top in args.top:
                row, fail = study(top, args.n, args.workers, args.spread, store_dir)
                rows.append(row)
                failed += fail
    finally:
        if busy is not None:
            busy.terminate()
            busy.wait()
    print("\n| top | end of range (mm) | runs | reached the end | failed (reason) "
          "| CPU s per run: min / median / mean / p90 / max | wall (min) | load average before → after |")
    print("|---|---:|---:|---:|---|---|---:|---|")
    print("\n".join(rows))
    if failed:
        print("\nfailed runs:\n" + "\n".join(failed))


if __name__ == "__main__":
    main()
