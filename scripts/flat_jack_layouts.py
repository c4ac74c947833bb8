"""Which layout identifies what: 95 % region widths of the flat-jack parameters for the gauge
layouts L6, L18 and the DIC grid at the instrument noise levels of docs/measurements.md.

The region of equivalence {m : χ²(m) − χ²(m*) ≤ χ²_p(0.95)} is linearised at the truth (the
Gauss–Newton curvature that :func:`podkrig.online.region.likelihood_ratio_region` starts
from): with J the FE sensitivities of all readings (central differences, ±0.5 % of each value),
F = Jᵀ J / σ² and the projection of the ellipsoid on parameter i has half-width
√(χ²_p(0.95) (F⁻¹)_ii). Noise: Gaussian, independent, absolute σ per reading (LVDT: 1, 2, 5 µm;
DIC: 2.5, 5 µm per component). Test: examples/flat_jack_scenario.toml (phases 0b–2, 20 steps) at
the truth of examples/make_flat_jack_data.py; σ0 = 0.30 MPa and ν_b known. Free: E_b, kN_bj,
kV_bj, r_hj and Km (nuisance). Widths are ± % of the true value; "> 100" means not identified.

Usage: nice python scripts/flat_jack_layouts.py [--fix-km]
"""

import argparse
import os
import time

import numpy as np
from scipy import stats

from fe.scenarios import build_scenario

TRUTH = {"E_b": 9500.0, "kN_bj": 70.0, "kV_bj": 30.0, "r_hj": 0.5, "Km": 0.82}
L6 = ("G1", "G2", "G3", "G4", "G5", "G6")
CASES = (("L6", 0.001), ("L6", 0.002), ("L6", 0.005), ("L18", 0.001), ("L18", 0.002), ("L18", 0.005),
         ("DIC", 0.0025), ("DIC", 0.005), ("L18+DIC", 0.002))


def jacobian(scenario, names, rel=0.005):
    """Readings (n_obs,) at the truth and d readings / d parameter (n_obs, n_params), mm per unit."""
    base = scenario.run(TRUTH).readings.ravel()
    cols = []
    for n in names:
        h = rel * TRUTH[n]
        up = scenario.run({**TRUTH, n: TRUTH[n] + h}).readings.ravel()
        dn = scenario.run({**TRUTH, n: TRUTH[n] - h}).readings.ravel()
        cols.append((up - dn) / (2 * h))
    return base, np.column_stack(cols)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fix-km", action="store_true", help="Km known (calibrated jacks): four free parameters")
    args = ap.parse_args()
    t0 = time.perf_counter()
    print(f"machine load (1, 5, 15 min) before: {os.getloadavg()}; cores: {os.cpu_count()}")
    names = [n for n in TRUTH if not (args.fix_km and n == "Km")]
    sc = build_scenario({"scenario": "flat_jack", "phases": ["0b", "1", "2"], "layout": "L18+DIC"})
    base, J = jacobian(sc, names)
    channels = np.array(sc.sensor_names)
    n_steps = len(sc.steps)
    is_dic = np.char.startswith(channels, "DIC")
    select = {"L6": np.isin(channels, L6), "L18": ~is_dic, "DIC": is_dic, "L18+DIC": np.ones(len(channels), bool)}
    q = stats.chi2.ppf(0.95, len(names))
    print(f"\n95 % region half-widths, ± % of the true value (linearised; {len(names)} free parameters"
          f"{', Km known' if args.fix_km else ', Km a nuisance'}); largest |reading| per layout in µm\n")
    print("| layout | readings | σ (µm) | max |d| (µm) | " + " | ".join(names) + " |")
    print("|---|---|---|---|" + "---|" * len(names))
    for layout, sigma in CASES:
        mask = np.tile(select[layout], n_steps)
        Jl = J[mask]
        F = Jl.T @ Jl / sigma**2
        cov = np.linalg.pinv(F)
        half = np.sqrt(q * np.clip(np.diag(cov), 0, None))
        pct = 100 * half / np.array([TRUTH[n] for n in names])
        cells = [f"{v:.1f}" if v < 100 else "> 100" for v in pct]
        print(f"| {layout} | {mask.sum()} | {1000 * sigma:g} | {1000 * np.abs(base[mask]).max():.0f} | " + " | ".join(cells) + " |")
    # correlation of the L18 region: which combinations the gauges cannot separate
    Jl = J[np.tile(select["L18"], n_steps)]
    cov = np.linalg.pinv(Jl.T @ Jl)
    s = np.sqrt(np.diag(cov))
    corr = cov / np.outer(s, s)
    print("\ncorrelation of the L18 region (independent of σ):\n")
    print("| | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for i, n in enumerate(names):
        print(f"| {n} | " + " | ".join(f"{corr[i, j]:+.2f}" for j in range(len(names))) + " |")
    print(f"\n{time.perf_counter() - t0:.0f} s; machine load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
