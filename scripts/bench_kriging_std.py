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

``--approx`` adds a second table: the candidate fast variances, each the exact ordinary-kriging
variance (same hyperparameters, same formula) of a *subset* of the training points, against the
exact σ on ``--held-out`` random points (default 200): relative error of σ (median, 95th
percentile, max), the share of points where it is at least the exact σ (a subset's kriging
variance is never below the full one), its flops per point and output and its points per CPU
second (NumPy, all outputs):

- ``local k``: the k nearest training points in the scaled correlation metric
  (:math:`\\sum_k |\\Delta_k / a_k|^\\beta`, a ``scipy.spatial.cKDTree`` on :math:`x / a` with the
  Minkowski exponent β), one k × k system per point and output (k³/3 flops);
- ``inducing m``: the first m pivots of the pivoted Cholesky factorisation of the correlation matrix
  (LAPACK ``dpstrf``: the points that best span the others; the Nyström / inducing-point subset),
  one stored m × m factor (m² flops per point and output); ``rank(1e-8)``: the pivots after which
  every training point's residual variance is below 1e-8 of the sill, per output.

"σ ≥ exact" allows 1e-4 relative: the exact σ itself carries rounding of a few 1e-6 relative (the
correlation matrices of these smooth responses are near their conditioning limit), which is also
the error of both candidates at k = n and m = n.

Usage::

    PYTHONPATH=. nice python scripts/bench_kriging_std.py --n 1024 4096 8192
    PYTHONPATH=. nice python scripts/bench_kriging_std.py --n 1024 4096 --approx
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


def correlation(A, B, ranges, beta):
    """Correlation :math:`\\exp(-\\sum_k |A_k - B_k|^\\beta / a_k^\\beta)`, ``(len(A), len(B))``."""
    s = np.zeros((len(A), len(B)))
    for k in range(A.shape[1]):
        s += (np.abs(A[:, None, k] - B[None, :, k]) / ranges[k]) ** beta
    return np.exp(-s)


def ok_variance(L, r, sigma2):
    """Ordinary-kriging variance (Sacks et al. 1989) from the lower Cholesky factor ``L`` of the
    training correlations, ``(k, k)`` shared by all points or ``(p, k, k)`` one per point, and the
    cross-correlations ``r`` ``(p, k)``."""
    if L.ndim == 2:
        from scipy.linalg import solve_triangular

        u = solve_triangular(L, np.column_stack([r.T, np.ones(len(L))]), lower=True, check_finite=False)
        ur, u1 = u[:, :-1].T, u[:, -1]
    else:
        u = np.linalg.solve(L, np.stack([r, np.ones_like(r)], -1))  # batched: L solved as a general matrix
        ur, u1 = u[..., 0], u[..., 1]
    q, w, c = (ur * ur).sum(-1), (ur * u1).sum(-1), (u1 * u1).sum(-1)
    return sigma2 * (1.0 - q + (1.0 - w) ** 2 / c)


def approx_rows(ok, Xh, std, neighbours, inducing):
    """Rows ``(method, setting, errors, share_above, flops, points_per_s)`` of the candidate fast
    variances against the exact ``std`` ``(n_held_out, n_outputs)`` at ``Xh``."""
    from scipy.linalg.lapack import dpstrf
    from scipy.spatial import cKDTree

    hp, X = ok.hyperparameters_, ok.X_
    n, (h, n_out) = len(X), std.shape

    def row(name, setting, var, seconds, flops):
        s = np.sqrt(np.maximum(var, 0.0))
        err = np.abs(s / std - 1.0)
        return name, setting, err, float(np.mean(s >= std * (1 - 1e-4))), flops, h / seconds

    rows = []
    for k in neighbours:
        var, t0 = np.empty_like(std), time.process_time()
        for j in range(n_out):
            a, b = hp.ranges[j], float(hp.beta[j])
            Z = X / a
            idx = cKDTree(Z).query(Xh / a, k=k, p=max(b, 1.0))[1]
            for s in range(0, h, 32):
                I = idx[s:s + 32]
                R = np.stack([correlation(X[i], X[i], a, b) for i in I]) + hp.nugget * np.eye(k)
                r = np.stack([correlation(x[None], X[i], a, b)[0] for x, i in zip(Xh[s:s + 32], I)])
                var[s:s + 32, j] = ok_variance(np.linalg.cholesky(R), r, hp.sigma2[j])
        rows.append(row("local", f"k = {k}", var, time.process_time() - t0, k**3 / 3 + 2 * k * k))
    pivots, ranks = [], []
    for j in range(n_out):
        a, b = hp.ranges[j], float(hp.beta[j])
        R = correlation(X, X, a, b) + hp.nugget * np.eye(n)
        c, piv, rank, _ = dpstrf(R, lower=1, tol=-1)
        # pivot i is the largest residual variance of a training point after i pivots
        small = np.diag(c)[:rank] ** 2 <= 1e-8
        ranks.append(int(np.argmax(small)) if small.any() else int(rank))
        pivots.append((np.tril(c), piv - 1))
        del R
    for m in inducing:
        var, t0 = np.empty_like(std), time.process_time()
        for j in range(n_out):
            a, b = hp.ranges[j], float(hp.beta[j])
            Lm, P = pivots[j][0][:m, :m], pivots[j][1][:m]
            var[:, j] = ok_variance(Lm, correlation(Xh, X[P], a, b), hp.sigma2[j])
        rows.append(row("inducing", f"m = {m} (rank(1e-8) {'/'.join(map(str, ranks))})", var,
                        time.process_time() - t0, m * m))
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--n", nargs="+", type=int, default=[1024, 4096, 8192])
    p.add_argument("--outputs", type=int, default=4, help="Output columns (POD modes), default 4.")
    p.add_argument("--batch", type=int, default=2000, help="Points of the mean-only rate (default 2000).")
    p.add_argument("--std-seconds", type=float, default=3.0,
                   help="Aim of the CPU seconds of each σ timing; sets its points (default 3).")
    p.add_argument("--approx", action="store_true",
                   help="Also measure the candidate fast variances (local, inducing) against the exact σ.")
    p.add_argument("--held-out", type=int, default=200, help="Held-out points of --approx (default 200).")
    p.add_argument("--neighbours", nargs="+", type=int, default=[64, 256], help="k of the local variance.")
    p.add_argument("--inducing", nargs="+", type=float, default=[0.125, 0.5],
                   help="m of the inducing-point variance, as shares of n (default 0.125 0.5).")
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
    approx = []
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
        if args.approx:
            Xh = rng.random((args.held_out, 8))
            with one_blas_thread():
                std = ok.predict(Xh, return_std=True)[1]
                approx += [(n, *r) for r in approx_rows(ok, Xh, std, args.neighbours,
                                                         [int(round(f * n)) for f in args.inducing])]
        del ok, shared
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"| {n} | {fit_s:.0f} | {mean_rate:.3g} | {std_rate:.3g} | {shared_rate:.3g} | "
              f"{floor:.3g} | {factors_mb:.0f} | {rss:.0f} |", flush=True)
    if approx:
        print("\n| n | fast variance | setting | σ rel. error median / p95 / max | σ ≥ exact | flops per point "
              "and output | pts/s (NumPy) |\n|---|---|---|---|---|---|---|")
        for n, name, setting, err, above, flops, rate in approx:
            print(f"| {n} | {name} | {setting} | {np.median(err):.3g} / {np.percentile(err, 95):.3g} / "
                  f"{err.max():.3g} | {above:.0%} | {flops:.3g} | {rate:.3g} |", flush=True)


if __name__ == "__main__":
    main()
