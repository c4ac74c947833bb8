"""Singular values of the normalised sensitivity matrix of a scenario's readings.

S[i, j] = ∂ ln r_i / ∂ ln m_j at the default parameters (forward differences, step 1e-4), rows
for every sensor at the last load level. Full rank with a modest condition number means the
chosen parameters are jointly identifiable from the sensors (locally, at that point).

Usage: python scripts/identifiability.py [--scenario diagonal_compression] [--params E_b kN_bj kV_bj r_hj]
"""

import argparse

import numpy as np


def sensitivity_matrix(scenario, names, step=1e-4):
    """Normalised sensitivities ``(n_sensors, n_params)`` at the scenario defaults."""
    base = scenario.resolve()
    r0 = scenario.run().readings[-1]
    cols = [(scenario.run({n: base[n] * (1 + step)}).readings[-1] - r0) / (step * r0) for n in names]
    return np.column_stack(cols)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="diagonal_compression")
    ap.add_argument("--params", nargs="+", default=["E_b", "kN_bj", "kV_bj", "r_hj"])
    args = ap.parse_args(argv)
    from fe.scenarios import build_scenario

    sc = build_scenario(args.scenario)
    S = sensitivity_matrix(sc, args.params)
    print(f"normalised sensitivities d ln r / d ln m ({args.scenario}, last load level)")
    print("| sensor | " + " | ".join(args.params) + " |")
    print("|---" * (len(args.params) + 1) + "|")
    for name, row in zip(sc.sensor_names, S):
        print(f"| {name} | " + " | ".join(f"{v:+.3f}" for v in row) + " |")
    sv = np.linalg.svd(S, compute_uv=False)
    print("\nsingular values, all sensors: " + ", ".join(f"{v:.3f}" for v in sv) + f" (condition number {sv[0] / sv[-1]:.1f})")
    d = [i for i, n in enumerate(sc.sensor_names) if n in ("D1", "D2")]
    if d:
        sv2 = np.linalg.svd(S[d], compute_uv=False)
        print("singular values, D1 and D2 only: " + ", ".join(f"{v:.3f}" for v in sv2) + f" (rank {len(sv2)} < {len(args.params)})")


if __name__ == "__main__":
    main()
