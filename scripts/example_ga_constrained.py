"""Constrained minimisation with the genetic algorithm: Floudas & Pardalos' problem g06.

A classic constrained test problem (Floudas & Pardalos 1990 [1]_; "g06" of the CEC 2006
benchmark [2]_, also used by Deb 2000 [3]_ to demonstrate the feasibility rules):

    minimise   f(x) = (x1 - 10)^3 + (x2 - 20)^3
    subject to g1(x) = -(x1 - 5)^2 - (x2 - 5)^2 + 100 <= 0
               g2(x) =  (x1 - 6)^2 + (x2 - 5)^2 - 82.81 <= 0
               13 <= x1 <= 100,  0 <= x2 <= 100.

The feasible region is a thin crescent between two circles (≈ 0.007 % of the box). f decreases
with both x1 and x2... towards the lower left, so the optimum is the lower intersection of the
two circles, which has a closed form: subtracting the circle equations gives
2 x1 - 11 = 17.19, x1* = 14.095, and x2* = 5 - sqrt(100 - (x1* - 5)^2) = 0.842960789…,
f* = -6961.81387558…

Run ``python scripts/example_ga_constrained.py --help``.

References
----------
.. [1] C. A. Floudas, P. M. Pardalos, *A Collection of Test Problems for Constrained Global
   Optimization Algorithms*, LNCS 455, Springer (1990).
.. [2] J. J. Liang et al., "Problem definitions and evaluation criteria for the CEC 2006
   special session on constrained real-parameter optimization", Tech. Rep. (2006).
.. [3] K. Deb, "An efficient constraint handling method for genetic algorithms", Comput.
   Methods Appl. Mech. Engrg. 186 (2000) 311–338.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

BOUNDS = [(13.0, 100.0), (0.0, 100.0)]


def objective(X):
    """f(x) = (x1 - 10)^3 + (x2 - 20)^3, ``X`` of shape (n, 2) -> (n,)."""
    return (X[:, 0] - 10.0) ** 3 + (X[:, 1] - 20.0) ** 3


def constraints(X):
    """Constraint values g(x) <= 0, ``X`` of shape (n, 2) -> (n, 2)."""
    g1 = -((X[:, 0] - 5.0) ** 2) - (X[:, 1] - 5.0) ** 2 + 100.0
    g2 = (X[:, 0] - 6.0) ** 2 + (X[:, 1] - 5.0) ** 2 - 82.81
    return np.column_stack([g1, g2])


def analytical_optimum():
    """Closed-form optimum: the lower intersection of the two constraint circles.

    Returns
    -------
    x : ndarray of shape (2,)
    f : float
    """
    x1 = (100.0 - 82.81 - 25.0 + 36.0) / 2.0  # (x1-5)^2 - (x1-6)^2 = 17.19 -> 2 x1 - 11
    x2 = 5.0 - np.sqrt(100.0 - (x1 - 5.0) ** 2)
    x = np.array([x1, x2])
    return x, float(objective(x[None])[0])


def optimise(*, rng=0, constraint_handling="deb", max_evaluations=5000):
    """Run the GA on g06 (SLSQP polish, the default with constraints).

    Returns
    -------
    GAResult
    """
    from podkrig.ga import minimize

    return minimize(objective, BOUNDS, constraints=constraints, rng=rng,
                    constraint_handling=constraint_handling, penalty=1e4,
                    max_evaluations=max_evaluations,
                    stall_generations=30)


def main(argv=None):
    """Solve g06 with the GA, compare with the closed-form optimum, write figures to ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--constraint-handling", choices=("deb", "penalty"), default="deb")
    parser.add_argument("--max-evaluations", type=int, default=5000)
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("out/ga_constrained"),
                        help="directory for the figures")
    args = parser.parse_args(argv)

    result = optimise(rng=args.seed, constraint_handling=args.constraint_handling,
                      max_evaluations=args.max_evaluations)
    x_opt, f_opt = analytical_optimum()
    print(f"GA:         x = {result.x}, f = {result.fun:.6f}, violation = {result.violation:.2e} "
          f"({result.nfev} evaluations; {result.message})")
    print(f"analytical: x = {x_opt}, f = {f_opt:.6f}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from podkrig.reports.ga import plot_history, plot_parameters, plot_statistics

    args.out.mkdir(parents=True, exist_ok=True)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    plot_history(result, ax1, log=False)
    plot_statistics(result, ax2, log=False)
    fig.savefig(args.out / "constrained_history.png", dpi=120)
    axes = plot_parameters(result, log=False)
    axes[0].figure.savefig(args.out / "constrained_parameters.png", dpi=120)
    plt.close("all")
    return result


if __name__ == "__main__":
    main()
