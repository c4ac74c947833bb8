"""Benchmark: training POD-kriging surrogates on 512-8192 snapshots, podkrig beside SMT and scikit-learn.

Methods (every one a :class:`~podkrig.surrogate.PODKriging` on the same POD, ``energy = 1 - 1e-8``,
so only the regressor of the POD coefficients differs):

- ``podkrig-exact``: :class:`~podkrig.surrogate.kriging.OrdinaryKriging` with its hyperparameters
  fitted on all n snapshots (``fit_subset=None``), the only method before issue 19;
- ``podkrig-subset``: hyperparameters fitted on a random subset of ``SUBSET_SIZE`` snapshots,
  then one factorisation on all n (``fit_subset=SUBSET_SIZE``; the default ``"auto"`` does this
  above ``EXACT_FIT_MAX_SAMPLES``);
- ``smt-krg``, ``smt-kpls``: SMT's ``KRG`` / ``KPLS`` per POD mode (``podkrig.surrogate.backends``);
- ``sklearn-gpr``: scikit-learn's ``GaussianProcessRegressor`` (Matérn 5/2, ARD) per POD mode;
- ``smt-krg-subset``, ``sklearn-gpr-subset``: the same libraries with their hyperparameters fitted
  on ``SUBSET_SIZE`` random snapshots, then the model of all n built at them without optimising
  (``fit_subset`` of the backends).

Data sets:

- ``synthetic``: the 8-parameter, 24-output ``response()`` of issue 19 (training: scrambled
  Sobol', seed 0; held-out: 500 uniform random points, ``numpy.random.default_rng(1)``);
- ``fe``: readings (4 loads × 6 sensors) of the bundled diagonal compression test with 5 free
  parameters (kN_bj, kV_bj log; r_hj, E_b, nu_b linear; Sobol' seed 0, held-out 500 uniform
  random runs, seed 1), cached in ``--out``.

Each (method, data set, n) runs in its own subprocess with a time limit (``--timeout``, default
30 min); a method that timed out is not run at larger n on that data set. Columns: training wall
time (and CPU time of the process), held-out median and p95 relative error ‖ŷ − y‖/‖y‖, share of
held-out outputs within ±2σ, predictions per second of means (batch of ``--batch`` random points)
and with standard deviations (the held-out points), and the load average (1 min) before and after.
Results are appended as JSON lines to ``OUT/results.jsonl``; ``--table`` prints the table of a
results file.

Usage::

    nice python scripts/bench_surrogate_scale.py --methods smt-krg smt-kpls sklearn-gpr --cases synthetic:512,2048,8192
    nice python scripts/bench_surrogate_scale.py --methods podkrig-exact podkrig-subset --cases fe:1024,4096
    python scripts/bench_surrogate_scale.py --table bench_out/scale/results.jsonl
"""

import argparse
import datetime
import json
import os
import platform
import resource
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

METHODS = ("podkrig-exact", "podkrig-subset", "smt-krg", "smt-kpls", "sklearn-gpr", "smt-krg-subset",
           "sklearn-gpr-subset")
CASES = ("synthetic:512,2048,8192", "fe:1024,4096")
ENERGY = 1 - 1e-8
N_HELD_OUT = 500
FE_BOUNDS = {"kN_bj": (10, 1000, "log"), "kV_bj": (4, 400, "log"), "r_hj": (0.1, 1.0), "E_b": (5000, 20000),
             "nu_b": (0.1, 0.3)}
SYNTHETIC_WEIGHTS = np.array([1, .7, .5, .35, .25, .15, .08, .04])


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    p.add_argument("--cases", nargs="+", default=list(CASES),
                   help="DATASET:n1,n2,... with DATASET 'synthetic' or 'fe' (default: %(default)s)")
    p.add_argument("--timeout", type=float, default=1800.0, help="Seconds per (method, data set, n) (default 1800).")
    p.add_argument("--batch", type=int, default=2000, help="Random points for the mean-prediction rate (default 2000).")
    p.add_argument("--out", type=Path, default=Path("bench_out/scale"), help="Results and FE cache (default %(default)s).")
    p.add_argument("--table", type=Path, help="Only print the table of this results file.")
    p.add_argument("--worker", nargs=3, metavar=("METHOD", "DATASET", "N"), help=argparse.SUPPRESS)
    return p.parse_args(argv)


# ----------------------------------------------------------------------------- data


def response(U):
    """The synthetic 8-parameter response of issue 19: ``(n, 4 levels, 6 sensors)``."""
    U = np.asarray(U, dtype=float)
    s = U @ SYNTHETIC_WEIGHTS
    out = np.empty((len(U), 4, 6))
    for a, level in enumerate((0.25, 0.5, 0.75, 1.0)):  # 4 x 6 outputs, each vectorised over samples
        kink = np.log1p(np.exp(8.0 * (level - 0.4 - 0.5 * U[:, 4] * U[:, 5]))) / 8.0
        for j in range(6):
            w = np.cos((j + 1) * 1.3 * U[:, j % 8]) * (1.0 + 0.3 * U[:, (j + 3) % 8])
            out[:, a, j] = level * (1.0 + s) / (0.5 + U[:, 1] + 0.3 * U[:, 2] * U[:, 3]) * w + 0.5 * kink * (j + 1) / 6.0
    return out


def synthetic(n):
    from scipy.stats import qmc

    U = qmc.Sobol(8, scramble=True, seed=0).random(n)
    Uh = np.random.default_rng(1).random((N_HELD_OUT, 8))
    return U, response(U), Uh, response(Uh)


def fe_cache(out):
    return out / "fe_diagonal_5p.npz"


def fe_generate(out, n_max):
    """Sobol' (seed 0) training and uniform (seed 1) held-out FE runs, cached; returns the path."""
    from fe.scenarios import build_scenario
    from podkrig.offline.sampling import sobol, uniform
    from podkrig.parameters import ParameterSpace

    path = fe_cache(out)
    if path.is_file() and len(np.load(path)["U"]) >= n_max:
        return path
    sc = build_scenario({"scenario": "diagonal_compression"})
    space = ParameterSpace.from_scenario(sc, FE_BOUNDS)
    U, Uh = sobol(n_max, len(FE_BOUNDS), seed=0), uniform(N_HELD_OUT, len(FE_BOUNDS), seed=1)
    t0 = time.perf_counter()
    # one linear FE run per row (~10-80 ms each); the FE run is the unit of work, not a kernel
    Y = np.stack([sc.run(space.as_params(x)).readings for x in space.from_unit(U)])
    Yh = np.stack([sc.run(space.as_params(x)).readings for x in space.from_unit(Uh)])
    out.mkdir(parents=True, exist_ok=True)
    np.savez(path, U=U, Y=Y, Uh=Uh, Yh=Yh)
    print(f"generated {len(U) + len(Uh)} FE runs in {time.perf_counter() - t0:.0f} s -> {path}", flush=True)
    return path


def dataset(name, n, out):
    if name == "synthetic":
        return synthetic(n)
    d = np.load(fe_cache(out))
    return d["U"][:n], d["Y"][:n], d["Uh"], d["Yh"]


# ----------------------------------------------------------------------------- one run


def regressor(method):
    from podkrig.surrogate.backends import make_backend
    from podkrig.surrogate.kriging import OrdinaryKriging, ordinary

    if method == "podkrig-exact":
        return OrdinaryKriging(fit_subset=None)
    if method == "podkrig-subset":
        return OrdinaryKriging(fit_subset=ordinary.SUBSET_SIZE)
    if method.endswith("-subset"):
        return make_backend(method.removesuffix("-subset"), fit_subset=ordinary.SUBSET_SIZE)
    return make_backend(method)


def worker(method, name, n, args):
    """Fit one method on one data set and print its result row as one JSON line."""
    from podkrig.parameters import Parameter, ParameterSpace
    from podkrig.surrogate.pod import POD
    from podkrig.surrogate.podkriging import PODKriging
    from podkrig.surrogate.validation import held_out_errors

    U, Y, Uh, Yh = dataset(name, n, args.out)
    unit = ParameterSpace(tuple(Parameter(f"u{k}", 0.0, 1.0) for k in range(U.shape[1])))
    load0 = os.getloadavg()[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        c0, t0 = time.process_time(), time.perf_counter()
        sur = PODKriging(pod=POD(energy=ENERGY), kriging=regressor(method), space=unit).fit(U, Y)
        train, cpu = time.perf_counter() - t0, time.process_time() - c0
        t0 = time.perf_counter()
        rep = held_out_errors(sur, Uh, Yh, with_loo=False)
        std_rate = len(Uh) / (time.perf_counter() - t0)
        Ub = np.random.default_rng(2).random((args.batch, U.shape[1]))
        sur.predict(Ub[:10])  # warm-up (numba kernels load from the cache)
        t0 = time.perf_counter()
        sur.predict(Ub)
        mean_rate = len(Ub) / (time.perf_counter() - t0)
    s = rep.summary()
    fit = getattr(sur.kriging_, "fit_method_", None)
    row = {"method": method, "dataset": name, "n": n, "d": U.shape[1], "modes": sur.n_modes_, "train_s": train,
           "train_cpu_s": cpu, "median": s["rel_error"]["median"], "p95": s["rel_error"]["p95"],
           "coverage_2sigma": s["coverage_2sigma"], "pred_per_s": mean_rate, "pred_std_per_s": std_rate,
           "load_before": load0, "load_after": os.getloadavg()[0],
           "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
           "fit": fit.to_dict() if fit is not None else None}
    print(json.dumps(row), flush=True)


def run_case(method, name, n, args, results):
    cmd = [sys.executable, __file__, "--worker", method, name, str(n), "--out", str(args.out), "--batch", str(args.batch)]
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    print(f"{datetime.datetime.now():%H:%M:%S} {method} {name} n={n} ...", flush=True)
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout, check=False)
    except subprocess.TimeoutExpired:
        row = {"method": method, "dataset": name, "n": n, "note": f"did not finish within {args.timeout / 60:.0f} min",
               "load_before": load0, "load_after": os.getloadavg()[0]}
    else:
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
        if proc.returncode == 0 and lines:
            row = json.loads(lines[-1])
        else:
            tail = (proc.stderr.strip().splitlines() or ["?"])[-1]
            row = {"method": method, "dataset": name, "n": n, "note": f"failed: {tail[:100]}",
                   "load_before": load0, "load_after": os.getloadavg()[0]}
    row["wall_s"] = time.perf_counter() - t0
    row["date"] = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    with open(results, "a") as f:
        f.write(json.dumps(row) + "\n")
    print(f"    {row}", flush=True)
    return "note" not in row


# ----------------------------------------------------------------------------- table


def table(results):
    rows = [json.loads(ln) for ln in Path(results).read_text().splitlines() if ln.strip()]
    latest = {}
    for r in rows:  # the last run of each (method, subset size, data set, n) counts
        fit = r.get("fit") or {}
        m = fit.get("subset_size", 0) if fit.get("method") == "subset" else 0
        latest[(r["dataset"], r["n"], r["method"], m)] = r
    order = {m: k for k, m in enumerate(METHODS)}
    head = ("| data set | n | method | training s (CPU s) | median | p95 | ±2σ coverage | predictions/s (mean) "
            "| predictions/s (with σ) | load 1 min (before → after) |\n|---|---|---|---|---|---|---|---|---|---|")
    machine = (f"Machine: {platform.machine()}, {os.cpu_count()} cores (shared); Python {platform.python_version()}; "
               f"table printed {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC, load now "
               f"{' / '.join(f'{v:.1f}' for v in os.getloadavg())}")
    lines = [machine, "", head]
    for key in sorted(latest, key=lambda k: (k[0], k[1], order.get(k[2], 99), k[3])):
        r = latest[key]
        load = f"{r['load_before']:.1f} → {r['load_after']:.1f}"
        if "note" in r:
            lines.append(f"| {r['dataset']} | {r['n']} | {r['method']} | {r['note']} | – | – | – | – | – | {load} |")
            continue
        fit = r.get("fit") or {}
        method = r["method"] + (f" [{fit['method']}, m={fit['subset_size']}]" if fit.get("method") == "subset" else "")
        lines.append(f"| {r['dataset']} | {r['n']} | {method} | {r['train_s']:.1f} ({r['train_cpu_s']:.1f}) | "
                     f"{r['median']:.2e} | {r['p95']:.2e} | {r['coverage_2sigma']:.3f} | {r['pred_per_s']:.3g} | "
                     f"{r['pred_std_per_s']:.3g} | {load} |")
    return "\n".join(lines)


def main(argv=None):
    args = parse_args(argv)
    if args.table:
        print(table(args.table))
        return
    if args.worker:
        method, name, n = args.worker
        worker(method, name, int(n), args)
        return
    args.out.mkdir(parents=True, exist_ok=True)
    results = args.out / "results.jsonl"
    for case in args.cases:
        name, _, sizes = case.partition(":")
        if name not in ("synthetic", "fe"):
            raise SystemExit(f"unknown data set {name!r} in --cases {case!r}; use 'synthetic' or 'fe'")
        sizes = sorted(int(s) for s in sizes.split(","))
        if name == "fe":
            fe_generate(args.out, max(sizes))
        for method in args.methods:
            for n in sizes:
                if not run_case(method, name, n, args, results):
                    print(f"    {method} skipped at larger n on {name}", flush=True)
                    break
    print(table(results))


if __name__ == "__main__":
    main()
