"""Optimal tuned-mass-damper (TMD) design with the genetic algorithm (thesis ch. 3 example).

An undamped main structure (mass m_s, stiffness k_s, frequency ω_s) carries a TMD of mass
m_d = μ m_s, frequency ω_d and viscous damping c, and is loaded by a harmonic force F sin(ωt).
The design variables are the frequency ratio f = ω_d/ω_s and the damping ratio
ζ_d = c / (2 m_d ω_s) (Den Hartog's c/c_c, referred to the *main* structure's frequency).
The GA minimises the peak over frequency of the dynamic amplification |X_1 / X_st|,
X_st = F / k_s, and the result is checked against Den Hartog's closed form [1]_

    f_opt = 1 / (1 + μ),    ζ_opt = sqrt(3 μ / (8 (1 + μ)^3)).

Den Hartog's "fixed-point" design is approximate (it makes the response horizontal at the two
fixed points rather than making the two peaks equal), so the exact minimax optimum differs
slightly: for μ = 0.05 it lies at f ≈ 0.9524, ζ_d ≈ 0.1276 with a peak ≈ 0.01 % below Den
Hartog's. In terms of the damper's own ratio c/(2 m_d ω_d) = ζ_d / f the same optimum reads
sqrt(3μ / (8 (1 + μ))).

Run ``python scripts/example_ga_tmd.py --help``.

References
----------
.. [1] J. P. Den Hartog, *Mechanical Vibrations*, 4th ed., McGraw-Hill (1956), sect. 3.3.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


class TMDSpace:
    """Linear parameter space of the TMD design (``names``, ``units``, unit-cube maps)."""

    names = ("f", "zeta_d")
    units = ("ω_d/ω_s", "c/(2 m_d ω_s)")

    def __init__(self, lower=(0.7, 0.01), upper=(1.3, 0.4)):
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)

    def from_unit(self, U):
        return self.lower + np.asarray(U) * (self.upper - self.lower)

    def to_unit(self, X):
        return (np.asarray(X) - self.lower) / (self.upper - self.lower)


def amplification(g, f, zeta, mu):
    r"""Dynamic amplification :math:`|X_1/X_{st}|` of the main mass (Den Hartog [1]_, eq. 3.31).

    .. math::

        \left|\frac{X_1}{X_{st}}\right| = \sqrt{\frac{(2\zeta g)^2 + (g^2 - f^2)^2}
        {(2\zeta g)^2 (g^2 - 1 + \mu g^2)^2 + (\mu f^2 g^2 - (g^2 - 1)(g^2 - f^2))^2}}

    Parameters
    ----------
    g : ndarray
        Forcing frequency ratio ω/ω_s (broadcast against ``f`` and ``zeta``).
    f, zeta : ndarray
        Frequency ratio ω_d/ω_s and damping ratio c/(2 m_d ω_s) of the TMD.
    mu : float
        Mass ratio m_d/m_s.

    Returns
    -------
    ndarray
        Amplification (dimensionless), broadcast shape.
    """
    g2, f2, dz = g * g, f * f, (2.0 * zeta * g) ** 2
    num = dz + (g2 - f2) ** 2
    den = dz * (g2 - 1.0 + mu * g2) ** 2 + (mu * f2 * g2 - (g2 - 1.0) * (g2 - f2)) ** 2
    return np.sqrt(num / den)


def peak_amplification(X, mu, *, g_min=0.4, g_max=2.0, n_grid=1601, n_golden=40):
    """Peak of |X_1/X_st| over frequency, vectorised over designs.

    The response is evaluated on a dense grid of forcing frequencies; the two highest local
    maxima of each design are then refined by a golden-section search inside their grid
    bracket (``n_golden`` iterations shrink it by 0.618**40 ≈ 4e-9), so the peak is exact to
    ~1e-12 relative.

    Parameters
    ----------
    X : ndarray of shape (n_designs, 2)
        Columns ``f`` (ω_d/ω_s) and ``zeta_d`` (c/(2 m_d ω_s)).
    mu : float
        Mass ratio m_d/m_s.
    g_min, g_max : float
        Frequency band ω/ω_s searched; must contain both resonance peaks.
    n_grid : int
        Points of the coarse frequency grid.
    n_golden : int
        Golden-section iterations per peak.

    Returns
    -------
    peak : ndarray of shape (n_designs,)
    """
    f, zeta = X[:, :1], X[:, 1:2]
    g = np.linspace(g_min, g_max, n_grid)
    H = amplification(g, f, zeta, mu)
    inner = H[:, 1:-1]
    is_max = (inner >= H[:, :-2]) & (inner > H[:, 2:])
    top = np.argsort(np.where(is_max, inner, -np.inf), axis=1)[:, -2:] + 1  # (n, 2)
    a, b = g[top - 1], g[top + 1]
    f2, z2 = np.broadcast_to(f, a.shape), np.broadcast_to(zeta, a.shape)
    c, d = b - _GOLDEN * (b - a), a + _GOLDEN * (b - a)
    hc, hd = amplification(c, f2, z2, mu), amplification(d, f2, z2, mu)
    for _ in range(n_golden):  # golden-section search for the maximum, all brackets at once
        left = hc > hd
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        d_new = np.where(left, c, a + _GOLDEN * (b - a))
        c_new = np.where(left, b - _GOLDEN * (b - a), d)
        hc, hd = (np.where(left, amplification(c_new, f2, z2, mu), hd),
                  np.where(left, hc, amplification(d_new, f2, z2, mu)))
        c, d = c_new, d_new
    refined = np.maximum(hc, hd).max(axis=1)
    return np.maximum(refined, H.max(axis=1))


def den_hartog(mu):
    """Den Hartog's optimum TMD (fixed-point theory [1]_).

    Parameters
    ----------
    mu : float
        Mass ratio m_d/m_s.

    Returns
    -------
    f_opt, zeta_opt : float
        ω_d/ω_s = 1/(1+μ) and c/(2 m_d ω_s) = sqrt(3μ/(8(1+μ)^3)).
    """
    return 1.0 / (1.0 + mu), float(np.sqrt(3.0 * mu / (8.0 * (1.0 + mu) ** 3)))


def optimise(mu=0.05, *, rng=0, max_evaluations=3000):
    """Run the GA on the TMD design problem.

    Nelder–Mead is used for the polish because the minimax objective is not differentiable at
    its optimum (two equal peaks).

    Returns
    -------
    GAResult
    """
    from podkrig.ga import minimize

    return minimize(lambda X: peak_amplification(X, mu), TMDSpace(), rng=rng,
                    max_evaluations=max_evaluations, polish_method="Nelder-Mead",
                    stall_generations=15)


def main(argv=None):
    """Optimise a TMD with the GA, compare with Den Hartog and write figures to ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mu", type=float, default=0.05, help="mass ratio m_d/m_s")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-evaluations", type=int, default=3000)
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("out/ga_tmd"),
                        help="directory for the figures")
    args = parser.parse_args(argv)

    result = optimise(args.mu, rng=args.seed, max_evaluations=args.max_evaluations)
    f_dh, z_dh = den_hartog(args.mu)
    peak_dh = peak_amplification(np.array([[f_dh, z_dh]]), args.mu)[0]
    print(f"GA:         f = {result.x[0]:.5f}, zeta_d = {result.x[1]:.5f}, "
          f"peak |X1/Xst| = {result.fun:.5f} ({result.nfev} evaluations; {result.message})")
    print(f"Den Hartog: f = {f_dh:.5f}, zeta_d = {z_dh:.5f}, peak |X1/Xst| = {peak_dh:.5f}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from podkrig.reports.ga import plot_history, plot_parameters, plot_statistics

    args.out.mkdir(parents=True, exist_ok=True)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    plot_history(result, ax1)
    plot_statistics(result, ax2)
    fig.savefig(args.out / "tmd_history.png", dpi=120)
    axes = plot_parameters(result)
    axes[0].figure.savefig(args.out / "tmd_parameters.png", dpi=120)
    fig, ax = plt.subplots(figsize=(6, 4), layout="constrained")
    g = np.linspace(0.7, 1.3, 1000)
    ax.plot(g, amplification(g, result.x[0], result.x[1], args.mu), label="GA design")
    ax.plot(g, amplification(g, f_dh, z_dh, args.mu), ls="--", label="Den Hartog")
    ax.set_xlabel("forcing frequency ratio ω/ω_s")
    ax.set_ylabel("amplification |X1/Xst|")
    ax.legend()
    fig.savefig(args.out / "tmd_response.png", dpi=120)
    plt.close("all")
    return result


if __name__ == "__main__":
    main()
