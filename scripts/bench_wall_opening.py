"""Mesh convergence of the TU Eindhoven wall with a central opening (``wall_opening_nl``, J2G/J3G).

Runs the scenario with its default settings (Set B, the default opening, both top conditions) on
a ladder of meshes (Q8, ``nx`` × ``ny`` elements per unit) to the end of the default control range
and prints one Markdown table per top condition: degrees of freedom, status and how far the run
got, the refined peak load and its displacement, the peak's difference from the finest mesh's,
the largest difference of the load at the levels from the finest mesh's (in % of the finest
peak), and the process CPU time of the run (``time.process_time``, BLAS limited to one thread,
after a warm-up run that compiles the interface law, so that compilation is not counted) and its
Newton iterations; then the load at every level on every mesh. The default mesh is the cheapest
whose peak load lies within 1 % of the finest mesh's (the line below each table says which, and
which is the cheapest whose load at every level also does); a peak at the end of the control
range is the largest load reached, not a maximum, and is marked so.

``--factor N`` runs the ladder with increments N times finer (budgets N times larger), to tell
the mesh's effect from the step's. With ``--finer`` it also compares the default mesh's peak under constant N with the peak of the
same run with ten times finer increments.

Usage: python scripts/bench_wall_opening.py [--mesh 2x1 4x1 4x2 6x2 8x2 8x3 12x4] [--top fixed_vertical constant_force]
       [--jobs 2] [--factor 4] [--finer]
"""

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from threadpoolctl import threadpool_limits

from fe.scenarios import build_scenario

MESHES = ("2x1", "4x1", "4x2", "6x2", "8x2", "8x3", "12x4")
TOPS = ("fixed_vertical", "constant_force")
TOLERANCE = 0.01  # peak within 1 % of the finest mesh's


def run(mesh, top, factor=1):
    """One run of ``wall_opening_nl`` on mesh ``"NXxNY"`` (Q8) with top condition ``top``
    (``factor``: increments that many times finer, budgets that many times larger)."""
    nx, ny = (int(v) for v in mesh.split("x"))
    spec = {"scenario": "wall_opening_nl", "top": top, "nx": nx, "ny": ny}
    if factor != 1:
        o = build_scenario(spec).options
        spec.update(increment=o.increment / factor, max_increment=o.max_increment / factor,
                    max_steps=factor * o.max_steps, max_total_iterations=factor * o.max_total_iterations,
                    max_cpu_seconds=factor * o.max_cpu_seconds)
    with threadpool_limits(1):
        build_scenario(dict(spec, load_levels=[0.01], increment=0.01, max_increment=0.01)).run()  # compile
        c0 = time.process_time()
        sc = build_scenario(spec)
        r = sc.run()
        cpu = time.process_time() - c0
    peak = r.path.peaks.get(r.path.phase[-1]) if r.path.peaks else None
    return dict(mesh=mesh, top=top, n_dofs=int(sc.n_dofs), status=r.status, reached=float(r.reached),
                peak=float(r.peak_load), at=float(r.peak_displacement), end=sc.options.load_levels[-1],
                levels=sc.options.load_levels,
                resolved=bool(peak is not None and peak.resolved), loads=np.asarray(r.loads, float),
                cpu=cpu, iterations=int(r.path.total_iterations))


def table(rows):
    """Markdown table of one top condition's rows (mesh order: the last is the finest)."""
    finest = rows[-1]
    lines = [f"`wall_opening_nl`, top = `{finest['top']}`",
             "",
             "| mesh (Q8) | dofs | status | reached (mm) | peak (kN) | at (mm) | peak vs finest | "
             "curve vs finest | CPU (s) | iterations |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    default = both = None
    for row in rows:
        dpeak = row["peak"] / finest["peak"] - 1.0
        dcurve = np.nanmax(np.abs(row["loads"] - finest["loads"])) / finest["peak"]
        at_end = abs(row["at"] - row["end"]) < 1e-9
        lines.append(
            f"| {row['mesh']} | {row['n_dofs']} | {row['status']} | {row['reached']:.3g} | {row['peak']:.2f}"
            f"{' (end of range)' if at_end else ''} | {row['at']:.3f} | {100 * dpeak:+.2f} % | "
            f"{100 * dcurve:.2f} % | {row['cpu']:.1f} | {row['iterations']} |")
        if default is None and row["status"] == "converged" and abs(dpeak) <= TOLERANCE:
            default = row["mesh"]
        if both is None and row["status"] == "converged" and max(abs(dpeak), dcurve) <= TOLERANCE:
            both = row["mesh"]
    lines += ["", f"cheapest mesh with the peak within {100 * TOLERANCE:g} % of the finest: {default}; "
              f"with the peak and the curve: {both}", "",
              "load (kN) at the levels (mm):", "",
              "| mesh | " + " | ".join(f"{v:g}" for v in finest["levels"]) + " |",
              "|---|" + "---|" * len(finest["levels"])]
    lines += ["| " + row["mesh"] + " | " + " | ".join(f"{v:.2f}" for v in row["loads"]) + " |" for row in rows]
    return "\n".join(lines + [""])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh", nargs="+", default=list(MESHES), help="meshes NXxNY, coarse to fine")
    parser.add_argument("--top", nargs="+", default=list(TOPS), choices=TOPS)
    parser.add_argument("--jobs", type=int, default=1, help="processes running meshes side by side")
    parser.add_argument("--factor", type=int, default=1,
                        help="run the ladder with increments this many times finer than the default")
    parser.add_argument("--finer", action="store_true",
                        help="also: the default mesh under constant N with ten times finer increments")
    args = parser.parse_args(argv)
    cases = [(m, t) for t in args.top for m in args.mesh]
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(run, *zip(*cases), [args.factor] * len(cases)))
    for top in args.top:
        print(table([r for r in results if r["top"] == top]))
    if args.finer:
        o = build_scenario("wall_opening_nl").options
        mesh = f"{o.nx}x{o.ny}"
        default, finer = run(mesh, "constant_force"), run(mesh, "constant_force", factor=10)
        print(f"constant N, default mesh {mesh}: peak {default['peak']:.3f} kN at {default['at']:.3f} mm; with ten "
              f"times finer increments {finer['peak']:.3f} kN at {finer['at']:.3f} mm "
              f"({100 * (default['peak'] / finer['peak'] - 1):+.2f} %; CPU {finer['cpu']:.1f} s)")


if __name__ == "__main__":
    main()
