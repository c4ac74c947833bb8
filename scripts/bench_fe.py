"""Benchmark the FE solver: cost of one new parameter vector for the diagonal compression test.

Prints a Markdown table: DOFs, then milliseconds for mesh generation and one-time set-up
(element matrices, pattern, symbolic analysis), and per new parameter vector the stiffness sum,
the numerical factorisation, the solve + readings, and the total ``Scenario.run``, for the default
mesh and one refinement, with each available solver backend. BLAS/MKL are limited to one thread
(threadpoolctl) so that the figures are per core. With ``--convergence`` it also prints D1, D2
at 100 kN against mesh refinement with the Richardson-extrapolated limit
(``scripts/bench_support_convergence.py`` does the same for absolute displacements per support model).

For scale (issue 2): OpenSeesPy needs about 30 ms per parameter vector for a 4-node-quad mesh of
the same panel with 2.5k equations (≈ 2.5 % from convergence) and about 550 ms for a mesh
converged to 0.5 %.

Usage: python scripts/bench_fe.py [--repeat 30] [--convergence]
"""

import argparse
import platform
import time

import numpy as np


def _time(fn, repeat):
    fn()  # warm-up
    t0 = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - t0) / repeat * 1e3


def bench_mesh(nx, ny, backend, repeat, rng):
    from fe.mesh import BrickWallLayout, brick_wall
    from fe.scenarios import build_scenario

    t0 = time.perf_counter()
    brick_wall(BrickWallLayout(nx=nx, ny=ny))
    t_mesh = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    sc = build_scenario({"scenario": "diagonal_compression", "nx": nx, "ny": ny}, solver=backend)
    sc.run()
    t_setup = (time.perf_counter() - t0) * 1e3 - t_mesh
    model = sc.model
    samples = iter(rng.uniform([6000, 50, 20, 0.3], [18000, 200, 80, 1.0], (10 * repeat + 10, 4)))

    def new_params():
        E, kN, kV, r = next(samples)
        return {"E_b": E, "kN_bj": kN, "kV_bj": kV, "r_hj": r}

    theta = sc.theta(sc.resolve(new_params()))
    values = model.stiffness.values(theta)
    t_sum = _time(lambda: model.stiffness.values(sc.theta(sc.resolve(new_params()))), repeat)
    t_fact = _time(lambda: model.solver.factorize(values), repeat)
    t_solve = _time(lambda: model.readings(model.solver.solve(model.rhs)), repeat)
    t_total = _time(lambda: sc.run(new_params()), repeat)
    return dict(nx=nx, ny=ny, dofs=sc.n_dofs, backend=model.solver.name, mesh=t_mesh, setup=t_setup,
                sum=t_sum, fact=t_fact, solve=t_solve, total=t_total)


def convergence():
    from fe.scenarios import build_scenario

    rows = []
    for nx, ny in [(2, 1), (4, 2), (6, 2), (8, 4), (12, 6)]:
        sc = build_scenario({"scenario": "diagonal_compression", "nx": nx, "ny": ny})
        rows.append((nx, ny, sc.n_dofs, *sc.run().readings[-1, :2]))
    D = {r[0]: np.array(r[3:]) for r in rows}
    p = np.log2(np.abs(D[4] - D[2]) / np.abs(D[8] - D[4]))
    limit = D[12] + (D[12] - D[8]) / ((12 / 8) ** p - 1)
    print("\n| Q8 per unit | DOFs | D1 @100 kN (mm) | D2 @100 kN (mm) | D1 vs limit | D2 vs limit |")
    print("|---|---|---|---|---|---|")
    for nx, ny, n, d1, d2 in rows:
        print(f"| {nx}×{ny} | {n} | {d1:.6f} | {d2:.6f} | {100 * (d1 / limit[0] - 1):+.3f} % | {100 * (d2 / limit[1] - 1):+.3f} % |")
    print(f"| Richardson limit (12×6, 8×4; observed rates p = {p[0]:.2f}, {p[1]:.2f}) | | {limit[0]:.6f} | {limit[1]:.6f} | | |")
    print("| OpenSeesPy 3.8.0, Q4 16×8 (independent code, run separately) | | -0.240390 | 0.110351 | | |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=30, help="timed repetitions per figure")
    ap.add_argument("--convergence", action="store_true", help="also print the mesh convergence table")
    args = ap.parse_args(argv)

    from threadpoolctl import threadpool_limits

    from fe.solvers import available_backends

    rng = np.random.default_rng(0)
    print(f"# FE benchmark: diagonal_compression, {platform.processor() or platform.machine()}, "
          "BLAS/MKL limited to 1 thread (threadpoolctl); times in ms")
    print("\n| mesh (Q8 per unit) | DOFs | solver | mesh gen | set-up (once) | K(θ) sum | factorise | solve + readings | total per parameter vector |")
    print("|---|---|---|---|---|---|---|---|---|")
    with threadpool_limits(1):
        for nx, ny in [(6, 2), (12, 4)]:
            for backend in available_backends():
                r = bench_mesh(nx, ny, backend, args.repeat, rng)
                print(f"| {nx}×{ny}{' (default)' if nx == 6 else ''} | {r['dofs']} | {r['backend']} | {r['mesh']:.1f} | "
                      f"{r['setup']:.0f} | {r['sum']:.2f} | {r['fact']:.1f} | {r['solve']:.2f} | **{r['total']:.1f}** |")
    # outside the thread limit: PARDISO keeps its own thread-local MKL count (one below 200k dofs)
    r = bench_mesh(6, 2, available_backends()[0], args.repeat, rng)
    print(f"\nDefault mesh, {r['backend']}, process-default BLAS/MKL threads: "
          f"**{r['total']:.1f} ms** per parameter vector")
    if args.convergence:
        convergence()


if __name__ == "__main__":
    main()
