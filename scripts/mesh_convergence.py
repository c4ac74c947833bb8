"""Mesh-convergence study of the nonlinear scenarios: which mesh is fine enough.

For each scenario (``couplet_tension``, ``triplet_shear``, ``prism_compression`` and the wall J4D
``shear_compression_nl`` with the top vertically fixed and under constant N) it runs the same test
on at least three meshes (continuum element ``Q8``/``Q4`` and ``nx`` × ``ny`` elements per unit),
all to the end of the control range given below (the walls to 3 mm, past the default range of the
confined wall, to show where the curve stops being mesh-objective), and prints a Markdown table per
scenario: dofs, process CPU time of the run (``time.process_time``, BLAS on one thread), the
reported (refined) peak load and its displacement, and the largest difference between the mesh's
load–displacement curve and the finest mesh's up to ``--end`` (at the converged steps of the
mesh's control phase, the finest mesh's steps linearly interpolated there), divided by the finest
curve's largest load up to there. Every run uses the scenario's increments divided by
``--step-factor`` (4), so that the curves are converged in the step and what differs is the mesh:
with the default increments the finest mesh can take another post-peak branch (J4D under constant
N, Q8 12 × 4: 28.2 instead of 29.8 kN at 1.75 mm, which increments / 4 do not), and a curve
sampled at coarse steps differs from a dense one near a sharp peak by more than the mesh does.
What the default increments cost and how far their peak lies from a finer step's is measured by
``scripts/bench_nonlinear.py`` and ``scripts/bench_nonlinear_peaks.py --finer``. ``objective
to`` is the control value up to which the difference stays within ``--tolerance`` (1 %). The last
columns give the run's status and how far it reached.

The default mesh of a scenario is the cheapest one whose peak and curve stay within 1 % of the
finest (the decision is recorded in BENCHMARKS.md with the run that justifies it).

Usage: python scripts/mesh_convergence.py [--scenario couplet triplet prism j4d-fixed j4d-fixed-full
       j4d-constant] [--end 1.8] [--tolerance 0.01] [--step-factor 4]
"""

import argparse
import os
import platform
import time

import numpy as np
from threadpoolctl import threadpool_limits

from fe.scenarios import build_scenario

#: the walls to 3 mm (``j4d-fixed-full``: the confined wall past its default, mesh-objective range)
WALL_LEVELS = (0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0)
WALL_MESHES = [("Q4", 4, 2), ("Q8", 2, 1), ("Q8", 4, 1), ("Q8", 4, 2), ("Q8", 6, 2), ("Q8", 8, 3), ("Q8", 12, 4)]

#: scenario key → (base spec, meshes as (element, nx, ny), the finest last)
STUDIES = {
    "couplet": ({"scenario": "couplet_tension"},
                [("Q4", 2, 1), ("Q8", 2, 1), ("Q8", 4, 1), ("Q8", 4, 2), ("Q8", 6, 2), ("Q8", 12, 4)]),
    "triplet": ({"scenario": "triplet_shear"},
                [("Q4", 2, 1), ("Q8", 2, 1), ("Q8", 4, 1), ("Q8", 4, 2), ("Q8", 6, 2), ("Q8", 12, 4)]),
    "prism": ({"scenario": "prism_compression"},
              [("Q4", 2, 1), ("Q8", 2, 1), ("Q8", 4, 1), ("Q8", 4, 2), ("Q8", 6, 2), ("Q8", 12, 4)]),
    "j4d-fixed": ({"scenario": "shear_compression_nl", "top": "fixed_vertical"}, WALL_MESHES),
    "j4d-fixed-full": ({"scenario": "shear_compression_nl", "top": "fixed_vertical", "load_levels": WALL_LEVELS},
                       WALL_MESHES),
    "j4d-constant": ({"scenario": "shear_compression_nl", "top": "constant_force"}, WALL_MESHES),
}


def run(spec):
    """One run: (scenario, response, CPU s)."""
    sc = build_scenario(spec)
    c0 = time.process_time()
    r = sc.run()
    return sc, r, time.process_time() - c0


def curve(sc, r):
    """Control displacement and load of the converged steps of the control phase (sorted by u)."""
    p = r.path
    mask = p.of_phase(p.phase[-1])
    u = sc.control_sign * np.asarray(p.path)[mask]
    f = np.asarray(p.load)[mask]
    ahead = u > np.concatenate([[-np.inf], np.maximum.accumulate(u)[:-1]])  # skip a detour's way back
    return u[ahead], f[ahead]


def compare(u, f, u_ref, f_ref, end, tolerance):
    """Largest |f − f_ref| at the run's steps up to ``end`` (the dense reference interpolated there),
    over max |f_ref| up to ``end``, and the control value up to which it stays within ``tolerance``."""
    keep = (u <= end * (1 + 1e-9)) & (u <= u_ref[-1] * (1 + 1e-9))
    scale = np.max(np.abs(f_ref[u_ref <= end * (1 + 1e-9)]))
    diff = np.abs(f[keep] - np.interp(u[keep], u_ref, f_ref)) / scale
    bad = np.flatnonzero(diff > tolerance)
    objective_to = u[keep][bad[0] - 1] if len(bad) and bad[0] > 0 else (0.0 if len(bad) else u[keep][-1])
    return float(diff.max()) if len(diff) else float("nan"), float(objective_to)


def study(key, end, tolerance, step_factor):
    base, meshes = STUDIES[key]
    o = build_scenario(base).options
    finer = dict(increment=o.increment / step_factor, max_increment=o.max_increment / step_factor,
                 max_steps=int(step_factor * o.max_steps))
    runs = []
    for element, nx, ny in meshes:
        sc, r, cpu = run(dict(base, element=element, nx=nx, ny=ny, **finer))
        runs.append((f"{element} {nx}×{ny}", sc, r, cpu))
    sc_ref, r_ref = runs[-1][1], runs[-1][2]
    end = end if end is not None else sc_ref.load_levels[-1]
    u_ref, f_ref = curve(sc_ref, r_ref)
    print(f"\n### {key}: {base}, increments / {step_factor}, curve compared up to {end:g} {sc_ref.load_unit}\n")
    print(f"| mesh | dofs | CPU s | steps | iterations | peak {sc_ref.force_unit} | at {sc_ref.load_unit} "
          f"| peak vs finest | max curve diff | objective to | status | reached |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    for name, sc, r, cpu in runs:
        u, f = curve(sc, r)
        diff, objective_to = compare(u, f, u_ref, f_ref, end, tolerance)
        print(f"| {name} | {sc.n_dofs} | {cpu:.2f} | {len(r.path.path)} | {r.path.total_iterations} "
              f"| {r.peak_load:.3f} | {r.peak_displacement:.3f} | {100 * (r.peak_load / r_ref.peak_load - 1):+.2f} % "
              f"| {100 * diff:.2f} % | {objective_to:.3f} | {r.status} | {r.reached:.3f} |", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", nargs="+", choices=sorted(STUDIES), default=list(STUDIES))
    ap.add_argument("--end", type=float, help="compare curves up to this control value (default: the last level)")
    ap.add_argument("--tolerance", type=float, default=0.01, help="relative curve tolerance of 'objective to'")
    ap.add_argument("--step-factor", type=int, default=4,
                    help="every run's increments are the scenario's divided by this (1: the defaults)")
    args = ap.parse_args(argv)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; load average "
          f"{', '.join(f'{v:.1f}' for v in os.getloadavg())}; CPU times with BLAS on one thread")
    c0 = time.process_time()
    with threadpool_limits(1):
        run({"scenario": "triplet_shear", "nx": 2, "ny": 1})  # warm-up: numba kernels loaded or compiled
        for key in args.scenario:
            study(key, args.end, args.tolerance, args.step_factor)
    print(f"\ntotal CPU {time.process_time() - c0:.0f} s; load average after "
          f"{', '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
