"""Benchmark: kriging predictions per CPU second with and without the standard deviation at 1 024-8 192 samples.

:class:`~podkrig.surrogate.kriging.OrdinaryKriging` on the synthetic 8-parameter response of
``scripts/bench_surrogate_scale.py`` (scrambled Sobol' training points, seed 0; its first
``--outputs`` columns, default 4, standing for POD modes), hyperparameters fitted on a subset of
512 samples (the default above 512). Columns, all in points per CPU second of this process (one
BLAS thread, as ``predict`` runs; the machine is shared, so wall time would measure the others):

- ``mean``: ``predict(X)``, ``--batch`` random points (default 2 000);
- ``σ``: ``predict(X, return_std=True)``, the same code as ``podkrig`` ships;
- ``σ shared``: all outputs at the ranges and exponent of the first (``optimizer=None``): equal
  Cholesky factors, one triangular product per block for all of them;
- ``floor``: the BLAS bound of the exact variance, ``rate / (n² × outputs)`` with ``rate`` the
  triangular solve's flop rate measured here (512 right-hand sides, n² flops each): a point's
  variance needs :math:`\\lVert L^{-1} k \\rVert^2` per output, n² flops, whatever the form
  (solves, a stored inverse, a quadratic form in :math:`K^{-1}` being twice that);
- ``factors``: memory of the stored Cholesky factors (n² doubles per output), and the peak
  resident memory of the process after that n.

Usage::

    PYTHONPATH=. nice python scripts/bench_kriging_std.py --n 1024 4096 8192
"""

import argparse
import datetime
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_surrogate_scale import response  # noqa: E402


def cpu_rate(fn, n_points):
    t0 = time.process_time()
    fn()
    return n_points / (time.process_time() - t0)


def trsm_rate(L, m=512):
    """Flops per CPU second of one triangular solve with ``m`` right-hand sides (n² flops each)."""
    from scipy.linalg import solve_triangular

    B = np.random.default_rng(0).random((L.shape[0], m))
    t0 = time.process_time()
    solve_triangular(L, B, lower=True, check_finite=False)
    return L.shape[0] ** 2 * m / (time.process_time() - t0)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--n", nargs="+", type=int, default=[1024, 4096, 8192])
    p.add_argument("--outputs", type=int, default=4, help="Output columns (POD modes), default 4.")
    p.add_argument("--batch", type=int, default=2000, help="Points of the mean-only rate (default 2000).")
    p.add_argument("--std-seconds", type=float, default=3.0,
                   help="Aim of the CPU seconds of each σ timing; sets its points (default 3).")
    args = p.parse_args(argv)

    from scipy.stats import qmc

    from podkrig.parallel import one_blas_thread
    from podkrig.surrogate.kriging import OrdinaryKriging

    now = datetime.datetime.now(datetime.timezone.utc)
    print(f"# {now:%Y-%m-%d %H:%M} UTC, {platform.processor() or platform.machine()}, "
          f"python {platform.python_version()}, numpy {np.__version__}, d = 8, {args.outputs} outputs")
    print("| n | fit CPU s | mean pts/s | σ pts/s | σ shared pts/s | floor pts/s | factors MB | peak RSS MB |")
    print("|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(1)
    for n in args.n:
        X = qmc.Sobol(8, scramble=True, seed=0).random(n)
        Y = response(X).reshape(n, -1)[:, : args.outputs]
        t0 = time.process_time()
        ok = OrdinaryKriging().fit(X, Y)
        fit_s = time.process_time() - t0
        with one_blas_thread():
            flops = trsm_rate(ok.L_[0])
        floor = flops / (n * n * args.outputs)
        m = max(50, int(args.std_seconds * floor))
        Xm, Xs = rng.random((args.batch, 8)), rng.random((m, 8))
        ok.predict(Xs[:5], return_std=True)  # numba compiles the kernels on first use: not timed
        mean_rate = cpu_rate(lambda: ok.predict(Xm), args.batch)
        std_rate = cpu_rate(lambda: ok.predict(Xs, return_std=True), m)
        shared = OrdinaryKriging(beta=float(ok.beta_[0]), ranges=ok.ranges_[0], optimizer=None,
                                 fit_subset=min(512, n - 1)).fit(X, Y)
        assert np.all(shared._shared == 0)
        shared_rate = cpu_rate(lambda: shared.predict(Xs, return_std=True), m)
        factors_mb = ok.L_.nbytes / 2**20
        del ok, shared
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"| {n} | {fit_s:.0f} | {mean_rate:.3g} | {std_rate:.3g} | {shared_rate:.3g} | "
              f"{floor:.3g} | {factors_mb:.0f} | {rss:.0f} |", flush=True)


if __name__ == "__main__":
    main()
