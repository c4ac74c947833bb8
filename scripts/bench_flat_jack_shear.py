"""Mesh objectivity of the flat-jack shear test (``flat_jack_shear_nl``): the critical jack pressure on
three or more meshes, with the statics estimate and the CPU time per run.

Runs phase 3 at the default parameters on Q8 meshes of nx × ny elements per unit (twice as fine in
the refined window round the jacks) and prints, per mesh, the degrees of freedom, the critical V1
pressure and Δp_V,crit (refined peak), the slip there, Δp_V at the slip levels, its ratio to the
statics estimate (L_H/h_V)(c + Km p_H tanφ)/Km, the relative difference of Δp_V,crit from the finest
mesh, and the CPU seconds of the run (``time.process_time``: comparable across machine loads)::

    python scripts/bench_flat_jack_shear.py                  # meshes 2x1, 4x2, 6x3 at p_H = 1.0
    python scripts/bench_flat_jack_shear.py --p-H 0.5 --meshes 2x1 4x2

Results are recorded in BENCHMARKS.md ("Flat-jack shear phase").
"""

import argparse
import time

import numpy as np

from fe.scenarios import build_scenario


def run(nx, ny, p_H):
    sc = build_scenario({"scenario": "flat_jack_shear_nl", "nx": nx, "ny": ny, "p_H": p_H})
    t0 = time.process_time()
    r = sc.run()
    cpu = time.process_time() - t0
    crit = sc.critical_pressures(r)[0]
    return sc, r, crit, cpu


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=["2x1", "4x2", "6x3"], help="nx x ny per unit, e.g. 2x1")
    ap.add_argument("--p-H", type=float, default=1.0, help="horizontal jack pressure, MPa")
    args = ap.parse_args(argv)
    rows = []
    for m in args.meshes:
        nx, ny = (int(v) for v in m.lower().split("x"))
        sc, r, crit, cpu = run(nx, ny, args.p_H)
        rows.append((m, sc.n_dofs, crit, r, cpu))
    finest = rows[-1][2].delta_p_V
    levels = [float(v) for v in rows[0][3].load_levels]
    print(f"flat_jack_shear_nl, p_H = {args.p_H:g} MPa, default parameters; statics Δp_V,crit = "
          f"{rows[0][2].statics:.4f} MPa")
    print(f"{'mesh':>5} {'dofs':>7} {'p_V1,crit':>9} {'Δp_V,crit':>9} {'slip':>7} {'ratio':>6} {'vs finest':>9} "
          f"{'status':>10} {'CPU s':>6}  Δp_V at slip levels {levels} mm")
    for m, n, crit, r, cpu in rows:
        curve = " ".join(f"{v:.4f}" for v in r.extra["delta_p_V"])
        print(f"{m:>5} {n:>7} {crit.p_V1:9.4f} {crit.delta_p_V:9.4f} {crit.slip:7.4f} {crit.ratio:6.3f} "
              f"{100 * (crit.delta_p_V / finest - 1):+8.2f}% {r.status:>10} {cpu:6.1f}  {curve}")
    return rows


if __name__ == "__main__":
    main()
