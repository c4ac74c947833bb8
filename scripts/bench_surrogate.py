"""Benchmark: podkrig's POD-kriging surrogate side by side with SMT, EZyRB and scikit-learn.

All methods are trained on the same Sobol' snapshots of the diagonal compression test (4 free
parameters: kN_bj 10–1000 N/mm³ log, kV_bj 4–400 N/mm³ log, r_hj 0.1–1, E_b 5000–20000 MPa; inputs
in the unit cube) and judged on the same random held-out runs:

- ``podkrig``: ``PODKriging(POD(energy=1-1e-8), OrdinaryKriging(beta="fit"))`` (the defaults), and
  ``podkrig beta=1.8`` (the thesis' smoothest fixed exponent);
- SMT ``KRG`` (corr ``pow_exp`` and ``abs_exp``), one model per POD coefficient of the same POD;
- SMT ``PODI`` (its own POD, same number of modes, KRG per mode);
- EZyRB ``POD + GPR`` and ``POD + RBF`` (same number of modes);
- scikit-learn ``GaussianProcessRegressor`` with ``Matern(nu=0.5)`` (ARD) on the same POD coefficients.

Columns: modes, median / p95 / max relative held-out error ‖ŷ − y‖/‖y‖ (-), training wall time (s),
predictions per second on one batch of random points, the same for every method (after a warm-up
call, ``--repeat`` rounds timing every method once in turn; median over the rounds). BLAS pools
(threadpoolctl) and numba are limited to ``--threads`` threads (default 1) so that timings are
repeatable on a shared machine.
Snapshots are cached in ``bench_out/`` (git-ignored). Missing peers are skipped with a note.

Usage::

    python scripts/bench_surrogate.py            # n = 64, 128, 256 (+ field variant at n = 128)
    python scripts/bench_surrogate.py --quick    # n = 64, 128; held-out 100; field at n = 64
"""

import argparse
import datetime
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

BOUNDS = {"kN_bj": (10, 1000, "log"), "kV_bj": (4, 400, "log"), "r_hj": (0.1, 1.0), "E_b": (5000, 20000)}
ENERGY = 1 - 1e-8


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="See the module docstring for the methods compared.")
    p.add_argument("--quick", action="store_true", help="n = 64, 128; 100 held-out runs; field variant at n = 64.")
    p.add_argument("--sizes", type=int, nargs="+", help="Training sizes (Sobol', powers of two).")
    p.add_argument("--held-out", type=int, default=200, help="Number of random held-out runs (default 200).")
    p.add_argument("--field-size", type=int, default=None, help="Training size of the full-field variant (0: skip).")
    p.add_argument("--batch", type=int, default=10000, help="Prediction batch for throughput (readings).")
    p.add_argument("--field-batch", type=int, default=1000, help="Prediction batch for throughput (fields).")
    p.add_argument("--threads", type=int, default=1, help="BLAS and numba threads (default 1).")
    p.add_argument("--repeat", type=int, default=5,
                   help="Rounds of timed prediction calls (every method once per round); median (default 5).")
    p.add_argument("--out", type=Path, default=Path("bench_out"), help="Cache directory (default bench_out/).")
    p.add_argument("--coarse", action="store_true", help="Coarse mesh (nx=2, ny=1) instead of the default one.")
    p.add_argument("--skip", nargs="*", default=[], help="Method names to skip (e.g. 'SMT PODI').")
    return p.parse_args(argv)


def snapshots(args, n_max, field):
    """Training (Sobol', seed 0) and held-out (uniform, seed 1) runs, cached as .npz."""
    from fe.scenarios import build_scenario
    from podkrig.parameters import ParameterSpace
    from podkrig.offline.sampling import sobol, uniform

    spec = {"scenario": "diagonal_compression", "nx": 2, "ny": 1} if args.coarse else {"scenario": "diagonal_compression"}
    tag = f"{'coarse' if args.coarse else 'default'}_n{n_max}_h{args.held_out}{'_field' if field else ''}"
    args.out.mkdir(parents=True, exist_ok=True)
    cache = args.out / f"surrogate_snapshots_{tag}.npz"
    sc = build_scenario(spec)
    space = ParameterSpace.from_scenario(sc, BOUNDS)
    if cache.is_file():
        d = np.load(cache)
        return space, d["U"], d["Y"], d["Uh"], d["Yh"], sc
    U, Uh = sobol(n_max, 4, seed=0), uniform(args.held_out, 4, seed=1)
    t0 = time.perf_counter()

    def run(U):
        out = []
        for x in space.from_unit(U):
            r = sc.run(space.as_params(x), field=field)
            out.append(r.field if field else r.readings)
        return np.stack(out)

    Y, Yh = run(U), run(Uh)
    print(f"  generated {len(U) + len(Uh)} FE runs in {time.perf_counter() - t0:.1f} s -> {cache}", flush=True)
    np.savez(cache, U=U, Y=Y, Uh=Uh, Yh=Yh)
    return space, U, Y, Uh, Yh, sc


# ----------------------------------------------------------------------------- methods
# Each returns (n_modes, predict) where predict(U) -> (m, n_outputs); inputs are in the unit cube.


def ours(beta):
    def fit(U, Y):
        from podkrig.surrogate.kriging import OrdinaryKriging
        from podkrig.parameters import Parameter, ParameterSpace
        from podkrig.surrogate.pod import POD
        from podkrig.surrogate.podkriging import PODKriging

        # U already lies in the unit cube: an identity space keeps the same inputs as the peers
        unit = ParameterSpace(tuple(Parameter(f"u{k}", 0.0, 1.0) for k in range(U.shape[1])))
        sur = PODKriging(pod=POD(energy=ENERGY), kriging=OrdinaryKriging(beta=beta), space=unit).fit(U, Y)
        return sur.n_modes_, sur.predict

    return fit


def _pod(Y):
    from podkrig.surrogate.pod import POD

    pod = POD(energy=ENERGY).fit(Y)
    return pod, pod.transform(Y)


def smt_krg(corr):
    def fit(U, Y):
        from smt.surrogate_models import KRG

        pod, A = _pod(Y)
        models = []
        for k in range(pod.n_modes_):
            m = KRG(corr=corr, print_global=False)
            m.set_training_values(U, A[:, k])
            m.train()
            models.append(m)
        return pod.n_modes_, lambda Up: pod.inverse_transform(
            np.column_stack([m.predict_values(Up)[:, 0] for m in models]))

    return fit


def smt_podi(U, Y):
    from smt.applications import PODI

    k = _pod(Y)[0].n_modes_
    podi = PODI()
    podi.compute_pod(Y.T, n_modes=k)
    podi.set_training_values(U)
    podi.train()
    return k, lambda Up: podi.predict_values(Up).T


def ezyrb(approx):
    def fit(U, Y):
        import ezyrb as ez

        k = _pod(Y)[0].n_modes_
        rom = ez.ReducedOrderModel(ez.Database(U, Y), ez.POD("svd", rank=k), ez.GPR() if approx == "GPR" else ez.RBF())
        rom.fit()
        return k, lambda Up: np.asarray(rom.predict(Up))

    return fit


def sklearn_matern(U, Y):
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern

    pod, A = _pod(Y)
    kernel = ConstantKernel(1.0) * Matern(length_scale=np.full(U.shape[1], 0.5), nu=0.5)
    gp = GaussianProcessRegressor(kernel, normalize_y=True, alpha=1e-10).fit(U, A)
    return pod.n_modes_, lambda Up: pod.inverse_transform(gp.predict(Up).reshape(len(Up), -1))


METHODS = {
    "podkrig (beta fit)": (ours("fit"), None),
    "podkrig (beta fit-shared)": (ours("fit-shared"), None),
    "podkrig (beta 1.8)": (ours(1.8), None),
    "SMT KRG pow_exp": (smt_krg("pow_exp"), "smt"),
    "SMT KRG abs_exp": (smt_krg("abs_exp"), "smt"),
    "SMT PODI": (smt_podi, "smt"),
    "EZyRB POD+GPR": (ezyrb("GPR"), "ezyrb"),
    "EZyRB POD+RBF": (ezyrb("RBF"), "ezyrb"),
    "sklearn GPR Matern(0.5)": (sklearn_matern, "sklearn"),
}


def available(module):
    if module is None:
        return True
    try:
        __import__(module)
        return True
    except ImportError:
        return False


def bench(name, fit, U, Y, Uh, Yh):
    """Fit one method and judge it on the held-out runs: (result row, predict function)."""
    from podkrig.surrogate.validation import relative_errors, summarize

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        k, predict = fit(U, Y)
        train = time.perf_counter() - t0
        e = summarize(relative_errors(predict(Uh), Yh))
    return {"method": name, "modes": k, **e, "train_s": train}, predict


def throughput(fitted, Ub, repeat):
    """Predictions per second of every fitted method on the batch ``Ub``: ``repeat`` rounds, each
    timing every method once in turn (so that the load of a shared machine, which drifts over
    minutes, weighs on all methods alike); median over the rounds."""
    times = {name: [] for name in fitted}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for predict in fitted.values():
            predict(Ub[:10])  # warm-up (numba compilation is cached, first call loads it)
        for _ in range(max(1, repeat)):
            for name, predict in fitted.items():
                # let the previous method's thread pools go idle: OpenBLAS workers keep spinning
                # after a call, and a numba parallel region started right after a two-thread
                # OpenBLAS product ran at half speed (1.97e5 instead of 3.8e5 predictions/s)
                time.sleep(0.2)
                t0 = time.perf_counter()
                predict(Ub)
                times[name].append(time.perf_counter() - t0)
    return {name: len(Ub) / float(np.median(t)) for name, t in times.items()}


def table(rows, title):
    head = "| method | modes | median | p95 | max | training (s) | predictions/s |\n|---|---|---|---|---|---|---|"
    lines = [f"\n**{title}**\n", head]
    for r in rows:
        if "note" in r:
            lines.append(f"| {r['method']} | – | – | – | – | – | {r['note']} |")
        else:
            lines.append(f"| {r['method']} | {r['modes']} | {r['median']:.2e} | {r['p95']:.2e} | {r['max']:.2e} | "
                         f"{r['train_s']:.2f} | {r['pred_per_s']:.3g} |")
    return "\n".join(lines)


def compare_methods(args, label, U, Y, Uh, Yh, batch, rng):
    """One result row per method on the same training and held-out sets (skipped or failed peers
    get a note instead of stopping the comparison); throughput of all methods on one batch."""
    rows, fitted = [], {}
    for name, (fit, module) in METHODS.items():
        if name in args.skip:
            continue
        if not available(module):
            rows.append({"method": name, "note": f"skipped: {module} not installed"})
            continue
        print(f"  {label}: {name} ...", flush=True)
        try:
            row, fitted[name] = bench(name, fit, U, Y, Uh, Yh)
            rows.append(row)
        except Exception as e:  # noqa: BLE001 - a peer failing must not stop the comparison
            rows.append({"method": name, "note": f"failed: {type(e).__name__}: {str(e)[:80]}"})
        print(f"    {rows[-1]}", flush=True)
    print(f"  {label}: throughput, {args.repeat} rounds ...", flush=True)
    rates = throughput(fitted, rng.random((batch, U.shape[1])), args.repeat)
    for row in rows:
        if row["method"] in rates:
            row["pred_per_s"] = rates[row["method"]]
    return rows


def main(argv=None):
    args = parse_args(argv)
    if args.quick:
        args.held_out = min(args.held_out, 100)
    sizes = args.sizes or ([64, 128] if args.quick else [64, 128, 256])
    field_n = args.field_size if args.field_size is not None else (64 if args.quick else 128)
    from threadpoolctl import threadpool_limits

    try:
        import numba

        numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    except ImportError:
        pass
    out = [
        (f"Date: {datetime.date.today().isoformat()}; machine: {platform.machine()}, {os.cpu_count()} cores "
         f"(shared), Python {platform.python_version()}; BLAS (threadpoolctl) and numba limited to {args.threads} "
         f"thread(s); predictions/s: median of {args.repeat} interleaved rounds."),
        f"Command: `{' '.join(['python scripts/bench_surrogate.py'] + list(sys.argv[1:] if argv is None else argv))}`",
        (f"Scenario: diagonal_compression ({'coarse mesh' if args.coarse else 'default mesh'}), 4 free parameters; "
         f"training: scrambled Sobol' (seed 0); held-out: {args.held_out} uniform random runs (seed 1). "
         "Errors are relative, ‖ŷ − y‖/‖y‖ per held-out run (-)."),
    ]
    notes = []
    rng = np.random.default_rng(2)
    with threadpool_limits(limits=args.threads):
        _, U, Y, Uh, Yh, _ = snapshots(args, max(sizes), field=False)
        Yf, Yhf = Y.reshape(len(Y), -1), Yh.reshape(len(Yh), -1)
        for n in sizes:
            rows = compare_methods(args, f"readings n={n}", U[:n], Yf[:n], Uh, Yhf, args.batch, rng)
            out.append(table(rows, f"Readings (4 loads × 6 sensors = 24 outputs), n = {n}, "
                                   f"throughput on {args.batch} points"))
        if field_n:
            _, U, Y, Uh, Yh, _ = snapshots(args, field_n, field=True)
            Yf, Yhf = Y.reshape(len(Y), -1), Yh.reshape(len(Yh), -1)
            rows = compare_methods(args, f"field n={field_n}", U, Yf, Uh, Yhf, args.field_batch, rng)
            out.append(table(rows, f"Full field ({Yf.shape[1]} outputs: 4 loads × {Yf.shape[1] // 8} nodes × 2), "
                                   f"n = {field_n}, throughput on {args.field_batch} points"))
    text = "\n".join(out + notes)
    print(text)
    return text


if __name__ == "__main__":
    main()
