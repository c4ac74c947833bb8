"""Mesh convergence of the diagonal compression test's absolute displacements per support model (issue 18).

For each support model (``pinned`` = the pre-issue-18 nodes pinned by coordinate, the peer; the
new ``rigid`` shoe bonded over whole edges; ``springs`` of ``support_stiffness`` N/mm³ over
exactly the length) and each mesh of 6×2, 12×4, 24×8 (and ``--finest 48``: 48×16) Q8 elements
per unit, prints at 100 kN the top-right corner displacement (ux, uy), D1, D2, three interior
points and the rms of a 5 × 6 DIC grid, then the observed rate
p = log2((u_h − u_h/2)/(u_h/2 − u_h/4)) of each quantity from the three finest meshes.

Usage: python scripts/bench_support_convergence.py [--finest 24|48] [--support-length 130]
"""

import argparse
import os
import time

import numpy as np

from fe import build_scenario
from fe.constraints import constraint_transform
from fe.model import LinearModel
from fe.scenarios.masonry import masonry_parts

W = 1170.0
SENSORS = {
    "corner_ux": {"kind": "point", "point": [W, W], "component": "x"},
    "corner_uy": {"kind": "point", "point": [W, W], "component": "y"},
    "D1": {"kind": "gauge", "p1": [302.157, 302.157], "p2": [867.843, 867.843]},
    "D2": {"kind": "gauge", "p1": [302.157, 867.843], "p2": [867.843, 302.157]},
    "P_mid_ux": {"kind": "point", "point": [600.0, 600.0], "component": "x"},
    "P_top_uy": {"kind": "point", "point": [300.0, 1100.0], "component": "y"},
    "P_low_ux": {"kind": "point", "point": [1100.0, 300.0], "component": "x"},
    "DIC": {"kind": "dic", "x0": 200.0, "y0": 200.0, "x1": 970.0, "y1": 970.0, "nx": 5, "ny": 6},
}
SHOWN = ("corner_ux", "corner_uy", "D1", "D2", "P_mid_ux", "P_top_uy", "P_low_ux", "DIC_rms")


def pinned_readings(sc):
    """The pre-issue-18 supports (the peer): every node with y = 0 and x ≤ L or x = 0 and y ≤ L
    pinned in x and y, the duplicated node across a bed joint included."""
    mesh, L = sc.mesh, sc.options.support_length
    x, y = mesh.nodes.T
    tol = 1e-9 * mesh.width
    nodes = np.flatnonzero(((abs(y) < tol) & (x <= L + tol)) | ((abs(x) < tol) & (y <= L + tol)))
    T = constraint_transform(mesh.n_dofs, np.concatenate([2 * nodes, 2 * nodes + 1]))
    model = LinearModel(mesh, masonry_parts(mesh, sc.options.thickness), T, sc.model.load_patterns,
                        sc.sensors, solver="auto")
    return sc.load_coefficients[-1] @ model.readings(model.solve(sc.theta(sc.resolve())))


def quantities(sc, readings):
    names = sc.sensor_names
    out = {k: readings[names.index(k)] for k in SHOWN[:-1]}
    dic = np.array([readings[i] for i, n in enumerate(names) if n.startswith("DIC[")])
    out["DIC_rms"] = float(np.sqrt(np.mean(dic**2)))
    return out, dic


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--finest", type=int, default=24, choices=(24, 48), help="finest nx (ny = nx / 3)")
    ap.add_argument("--support-length", type=float, default=130.0, help="mm")
    ap.add_argument("--support-stiffness", type=float, default=1000.0, help="N/mm³ for the springs")
    args = ap.parse_args(argv)
    meshes = [(n, n // 3) for n in (6, 12, 24, 48) if n <= args.finest]
    print(f"load avg {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} (2 cores); support_length "
          f"{args.support_length:g} mm; springs {args.support_stiffness:g} N/mm³; readings at 100 kN, mm\n")
    print("| supports | Q8 per unit | dofs | time (s) | " + " | ".join(SHOWN) + " |")
    print("|---" * (4 + len(SHOWN)) + "|")
    rate_rows = []
    for model in ("pinned", "rigid", "springs"):
        rows, dics = [], []
        for nx, ny in meshes:
            t0 = time.perf_counter()
            spec = {"scenario": "diagonal_compression", "nx": nx, "ny": ny, "sensors": SENSORS,
                    "support_length": args.support_length, "support": "springs" if model == "springs" else "rigid",
                    "support_stiffness": args.support_stiffness}
            sc = build_scenario(spec)
            r = pinned_readings(sc) if model == "pinned" else sc.run().readings[-1]
            q, dic = quantities(sc, r)
            rows.append(q)
            dics.append(dic)
            used = getattr(sc, "support_length_used", {})
            print(f"| {model} | {nx}×{ny} | {sc.n_dofs} | {time.perf_counter() - t0:.1f} | "
                  + " | ".join(f"{q[k]:+.5f}" for k in SHOWN) + " |", flush=True)
            if model == "rigid" and used != {"bottom": args.support_length, "left": args.support_length}:
                print(f"|   (rigid length used {used}) |" + " |" * (3 + len(SHOWN)))
        if len(rows) >= 3:
            a, b, c = rows[-3:]
            rates = {k: np.log2(abs(b[k] - a[k]) / abs(c[k] - b[k])) for k in SHOWN}
            d1, d2 = np.linalg.norm(dics[-2] - dics[-3]), np.linalg.norm(dics[-1] - dics[-2])
            rates["DIC_field"] = np.log2(d1 / d2)
            mono = all(np.sign(b[k] - a[k]) == np.sign(c[k] - b[k]) for k in SHOWN)
            rich = {k: c[k] + (c[k] - b[k]) / (2 ** max(rates[k], 0.5) - 1) for k in ("corner_uy", "D1")}
            rate_rows.append(f"| {model} | " + " | ".join(f"{rates[k]:.2f}" for k in (*SHOWN, "DIC_field"))
                             + f" | {'yes' if mono else 'NO'} | {rich['corner_uy']:+.5f} |")
    names = (*SHOWN, "DIC_field")
    print(f"\nObserved rate p = log2((u_h − u_h/2)/(u_h/2 − u_h/4)) from the three finest meshes "
          f"(DIC_field: the norm of the grid's change); load avg {os.getloadavg()[0]:.2f}\n")
    print("| supports | " + " | ".join(f"p {k}" for k in names) + " | monotone | Richardson corner_uy |")
    print("|---" * (3 + len(names)) + "|")
    print("\n".join(rate_rows))


if __name__ == "__main__":
    main()
