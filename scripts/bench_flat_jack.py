"""Benchmark the flat-jack pieces (issue 15 targets).

1. Analytical closed forms (podkrig.analytical.flat_jack), 10⁵ points: the elliptical hole's
   stresses and displacements, the slot's axis formulas, and the DDM field of the three §5 slots
   (80 elements each; not a closed form: cost ∝ points × elements). Target: < 50 ms.
2. One elastic flat-jack run, all phases (45 steps of the §5 set-up), default mesh, after set-up:
   set-up, then per parameter vector the stiffness sum, the numerical factorisation, the solves
   (release + 3 jacks), the readings of every step. Target: ≤ 50 ms on one core. BLAS/MKL limited
   to one thread (threadpoolctl).

Prints the machine load (os.getloadavg) beside the tables: on a shared machine the wall times
grow with it, so the process CPU time (time.process_time, one BLAS/MKL thread) is printed too.

Usage: nice python scripts/bench_flat_jack.py [--repeat 20]
"""

import argparse
import os
import platform
import time

import numpy as np
from threadpoolctl import threadpool_limits

from fe.scenarios import build_scenario
from podkrig.analytical.flat_jack import (
    Slot,
    elliptical_hole_field,
    slot_opening_axis,
    slot_stress_axis,
    solve_slots,
)


def best_of(fn, repeat):
    """Best and median wall time and best process CPU time of ``fn()``, ms (after a warm-up)."""
    fn()
    wall, cpu = [], []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return 1e3 * np.min(wall), 1e3 * np.median(wall), 1e3 * np.min(cpu)


def analytical(repeat):
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-1000, 1000, 10**5), rng.uniform(-1000, 1000, 10**5)
    ya = np.abs(y)
    sol = solve_slots([Slot((1040, 780), 390, 0, 1.0), Slot((845, 877.5), 195, np.pi / 2, 0.5),
                       Slot((1235, 877.5), 195, np.pi / 2, 0.5)], 4000.0, 0.2, 80)
    xs, ys = x[:10**4] + 1040, y[:10**4] + 877.5
    rows = [
        ("elliptical hole: stresses", lambda: elliptical_hole_field(x, y, 195.0, 2.0, sy=-0.3, p=1.0), 10**5),
        ("elliptical hole: stresses + displacements", lambda: elliptical_hole_field(x, y, 195.0, 2.0, sy=-0.3, p=1.0, E=4000.0, nu=0.2), 10**5),
        ("slot: u_y and σ on the axis", lambda: (slot_opening_axis(ya, 195.0, 1.0, 4000.0, 0.2), slot_stress_axis(ya, 195.0, 1.0)), 10**5),
        ("DDM solve, 3 slots × 80 elements", lambda: solve_slots([Slot((0, 0), 390, 0, 1.0), Slot((-195, 97.5), 195, np.pi / 2, 0.5),
                                                               Slot((195, 97.5), 195, np.pi / 2, 0.5)], 4000.0, 0.2, 80), 240),
        ("DDM field, 240 elements", lambda: sol.field(xs, ys), 10**4),
    ]
    print("\n**Analytical closed forms** (ms: wall best / median, process CPU best)\n")
    print("| function | points | wall best | wall median | CPU best | CPU per 10⁵ points |")
    print("|---|---|---|---|---|---|")
    for name, fn, n in rows:
        b, m, c = best_of(fn, repeat)
        print(f"| {name} | {n} | {b:.1f} | {m:.1f} | {c:.1f} | {c * 1e5 / n:.0f} |", flush=True)


def fe(repeat):
    print("\n**One flat-jack run, all phases** (§5 set-up, default mesh; ms: CPU best for the parts, wall and CPU for the run)\n")
    print("| set-up | layout | release | DOFs | steps × channels | set-up (s) | K(θ) sum | factorise + solves | readings | run wall best | run wall median | run CPU best |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(1)
    for layout, release in (("L18", "nominal"), ("DIC", "nominal"), ("L18", "exact")):
        _fe_case(layout, release, repeat, rng)


def _fe_case(layout, release, repeat, rng):
    t0 = time.perf_counter()
    sc = build_scenario({"scenario": "flat_jack", "layout": layout, "release": release})
    sc.run()
    setup = time.perf_counter() - t0
    samples = iter(rng.uniform([6000, 30, 15, 0.3, 0.8], [14000, 150, 80, 1.0, 0.9], (10 * repeat + 10, 5)))

    def params():
        E, kN, kV, r, km = next(samples)
        return {"E_b": E, "kN_bj": kN, "kV_bj": kV, "r_hj": r, "Km": km}

    values = sc.resolve(params())
    theta = sc.theta(values)
    t_sum = best_of(lambda: sc.model.stiffness.values(theta), repeat)[2]
    t_solve = best_of(lambda: sc.pattern_solution(values), repeat)[2]
    q = sc.pattern_solution(values)
    t_read = best_of(lambda: sc.step_coefficients(values) @ sc.model.readings(q), repeat)[2]
    b, m, c = best_of(lambda: sc.run(params()), repeat)
    n_ch = len(sc.sensor_names)
    print(f"| chisari | {layout} | {release} | {sc.n_dofs} | {len(sc.steps)} × {n_ch} | {setup:.1f} | {t_sum:.2f} | {t_solve:.1f} | {t_read:.2f} | {b:.1f} | {m:.1f} | **{c:.1f}** |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    print(f"{platform.machine()}, {os.cpu_count()} cores; machine load (1, 5, 15 min) before: {os.getloadavg()}")
    with threadpool_limits(1):
        analytical(args.repeat)
        fe(args.repeat)
    print(f"\nmachine load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
