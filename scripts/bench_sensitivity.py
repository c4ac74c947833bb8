"""Benchmark: Sobol' indices of a 6-parameter surrogate with 2^14 base samples (issue 19 target
≤ 10 s), against scipy.stats.sobol_indices with its own bootstrap as the peer.

The surrogate: POD + kriging of the issue's synthetic response (4 levels × 6 sensors) over its
first six inputs (the last two held at 0.5), 256 scrambled Sobol' training points (seed 0),
β = "fit-shared". Prints a Markdown table with wall and CPU seconds and the load average.

Usage: python scripts/bench_sensitivity.py [--n 16384] [--peer-resamples 5]
(scipy's bootstrap costs about a minute per replicate at n = 2^14 here: keep it small)
"""

import argparse
import os
import time

import numpy as np
from scipy import stats

from podkrig._qmc import scrambled_sobol
from podkrig.online.sensitivity import reading_sensitivity
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.surrogate.kriging import OrdinaryKriging
from podkrig.surrogate.pod import POD
from podkrig.surrogate.podkriging import PODKriging


def response(U):
    """The issue's synthetic 8-input set, ``(n, 4 levels × 6 sensors)``."""
    s = U @ np.array([1, 0.7, 0.5, 0.35, 0.25, 0.15, 0.08, 0.04])
    out = []
    for level in (0.25, 0.5, 0.75, 1.0):
        kink = np.log1p(np.exp(8 * (level - 0.4 - 0.5 * U[:, 4] * U[:, 5]))) / 8
        for j in range(6):
            w = np.cos((j + 1) * 1.3 * U[:, j % 8]) * (1 + 0.3 * U[:, (j + 3) % 8])
            out.append(level * (1 + s) / (0.5 + U[:, 1] + 0.3 * U[:, 2] * U[:, 3]) * w + 0.5 * kink * (j + 1) / 6)
    return np.column_stack(out)


class Model:
    """The surrogate as a model of readings over six parameters."""

    def __init__(self, surrogate):
        self.surrogate, self.space = surrogate, surrogate.space
        self.sensor_names = tuple(f"s{j}" for j in range(6))
        self.load_levels = np.array([0.25, 0.5, 0.75, 1.0])

    def predict_unit(self, U):
        return self.surrogate.predict_unit(U)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=2**14)
    ap.add_argument("--peer-resamples", type=int, default=5)
    args = ap.parse_args()
    space = ParameterSpace(tuple(Parameter(f"u{i}", 0.0, 1.0) for i in range(6)))
    U = scrambled_sobol(256, 6, 0)
    full = np.hstack([U, np.full((256, 2), 0.5)])
    sur = PODKriging(pod=POD(), kriging=OrdinaryKriging(beta="fit-shared"), space=space).fit(U, response(full))
    model = Model(sur)
    reading_sensitivity(model, n=64)  # warm-up (numba)
    load0 = os.getloadavg()[0]
    c0, t0 = time.process_time(), time.perf_counter()
    res = reading_sensitivity(model, n=args.n)
    ours = (time.perf_counter() - t0, time.process_time() - c0)

    def fun(x):  # scipy's layout: x (d, m) -> (s, m)
        return sur.predict_unit(np.ascontiguousarray(x.T)).T

    c0, t0 = time.process_time(), time.perf_counter()
    peer = stats.sobol_indices(func=fun, n=args.n, dists=[stats.uniform()] * 6, random_state=np.random.default_rng(0))
    t_point = (time.perf_counter() - t0, time.process_time() - c0)
    c0, t0 = time.process_time(), time.perf_counter()
    peer.bootstrap(confidence_level=0.95, n_resamples=args.peer_resamples)
    t_boot = (time.perf_counter() - t0, time.process_time() - c0)
    diff = np.nanmax(np.abs(peer.total_order - res.total))
    print(f"# Sobol' indices, 6 parameters, 24 outputs, n = {args.n} base samples ({res.n_evaluations} surrogate "
          f"evaluations); load average {load0:.2f} before, {os.getloadavg()[0]:.2f} after\n")
    print("| method | intervals | wall s | CPU s |")
    print("|---|---|---:|---:|")
    print(f"| podkrig.online.sensitivity (scipy estimators, reweighted bootstrap) | 200 replicates | {ours[0]:.2f} | {ours[1]:.2f} |")
    print(f"| scipy.stats.sobol_indices, point estimates | none | {t_point[0]:.2f} | {t_point[1]:.2f} |")
    print(f"| scipy ... .bootstrap | {args.peer_resamples} replicates | {t_boot[0]:.2f} | {t_boot[1]:.2f} |")
    print(f"\nlargest |total index difference| between the two (independent Sobol' draws): {diff:.3f}")


if __name__ == "__main__":
    main()
