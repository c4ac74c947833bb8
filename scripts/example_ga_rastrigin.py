"""Minimise the Rastrigin function with the genetic algorithm (thesis ch. 3 example, n = 2).

    f(x) = 10 n + sum_i (x_i^2 - 10 cos(2 pi x_i)),   -5.12 <= x_i <= 5.12,

has about 10^n local minima on the integer lattice and its global minimum f = 0 at x = 0
(Rastrigin 1974 [1]_). The GA runs with its default operators until f <= 1e-2 and writes the
individual history, the population statistics (thesis Fig. 3.17) and the parameter–objective
scatter (thesis Fig. 3.23) for each dimension.

Run ``python scripts/example_ga_rastrigin.py --help``.

References
----------
.. [1] L. A. Rastrigin, *Systems of Extremal Control*, Nauka, Moscow (1974).
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np


def rastrigin(X):
    """Rastrigin function, ``X`` of shape (n, d) -> (n,); minimum 0 at the origin."""
    return 10.0 * X.shape[1] + np.sum(X**2 - 10.0 * np.cos(2.0 * np.pi * X), axis=1)


def main(argv=None):
    """Run the GA on Rastrigin in each of ``--dims`` and write figures to ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dims", type=int, nargs="+", default=[2, 10],
                        help="dimensions to solve (default: 2 10)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--target", type=float, default=1e-2, help="stop at f <= target")
    parser.add_argument("--max-evaluations", type=int, default=50_000)
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("out/ga_rastrigin"),
                        help="directory for the figures")
    args = parser.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from podkrig.ga import minimize
    from podkrig.reports.ga import plot_history, plot_parameters, plot_statistics

    args.out.mkdir(parents=True, exist_ok=True)
    results = {}
    for d in args.dims:
        res = minimize(rastrigin, [(-5.12, 5.12)] * d, rng=args.seed, target=args.target,
                       max_evaluations=args.max_evaluations, stall_generations=None)
        results[d] = res
        print(f"Rastrigin {d}-D: f = {res.fun:.3g} after {res.nfev} evaluations, "
              f"{res.ngen} generations ({res.message})")
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
        plot_history(res, ax1)
        plot_statistics(res, ax2)
        fig.savefig(args.out / f"rastrigin_{d}d_history.png", dpi=120)
        axes = plot_parameters(res)
        axes[0].figure.savefig(args.out / f"rastrigin_{d}d_parameters.png", dpi=100)
        plt.close("all")
    return results


if __name__ == "__main__":
    main()
