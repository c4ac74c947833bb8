"""Benchmark the nonlinear path-following solver on the TU Eindhoven wall J4D: CPU per run and per iteration.

Runs ``shear_compression_nl`` (default mesh unless ``--nx/--ny/--element``) over the default
control range of each top condition asked for (0–1.75 mm with the top vertically fixed, the range
where its curve is mesh-objective; 0–3 mm under constant N; ``--full`` runs both to 3 mm) and
prints a Markdown table: dofs, wall time, converged steps, attempted increments, Newton
iterations, time per iteration, and the time of one linear solve of the same mesh (factorisation +
solve of the linear ``shear_compression`` scenario with the same mesh and beams: the peer of the
"≤ 2× per iteration" target), plus the peak load and its displacement. BLAS/MKL are limited to one
thread (threadpoolctl); the machine load (``os.getloadavg``) is printed beside the table. Times are
given as wall time and as the process' CPU time (``time.process_time``: one thread, so the
single-core cost, much less inflated by a loaded machine than wall time); the CPU time is split
into numerical factorisations, solves, interface-law updates and assembly (the solver's calls,
timed in place). The snapshot study is ``scripts/bench_nonlinear_snapshots.py``.

Usage: python scripts/bench_nonlinear.py [--nx 6 --ny 2 --element Q8] [--top fixed_vertical constant_force]
       [--full]
"""

import argparse
import collections
import dataclasses
import os
import platform
import time

from threadpoolctl import threadpool_limits

from fe.interfaces import CompositeInterface, HyperbolicInterface


class CpuTimer:
    """Accumulates the process CPU time (s) and calls of wrapped callables by label."""

    def __init__(self):
        self.seconds = collections.Counter()
        self.calls = collections.Counter()

    def wrap(self, label, fun):
        def timed(*args, **kwargs):
            c0 = time.process_time()
            try:
                return fun(*args, **kwargs)
            finally:
                self.seconds[label] += time.process_time() - c0
                self.calls[label] += 1
        return timed


def linear_solve_ms(mesh, repeat=10):
    """One linear run of the same mesh (the wall on and under its beams): (dofs, wall ms, CPU ms)."""
    from fe.scenarios import build_scenario

    sc = build_scenario({"scenario": "shear_compression", "base_joints": True, **mesh})
    sc.run()
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(repeat):
        sc.run()
    return sc.n_dofs, (time.perf_counter() - t0) / repeat * 1e3, (time.process_time() - c0) / repeat * 1e3


def run_j4d(mesh, top, full=False):
    from fe.scenarios import build_scenario

    sc = build_scenario({"scenario": "shear_compression_nl", "top": top, **mesh,
                         **({"control_range": "full"} if full else {})})
    # warm up: numba kernels loaded or compiled, PARDISO's symbolic analysis done
    sc.run(settings=dataclasses.replace(sc.options.path_settings(), max_steps=10))
    timer = CpuTimer()
    model, solver = sc.model, sc.model.solver
    solver.factorize = timer.wrap("factorisation", solver.factorize)
    solver.solve = timer.wrap("solve", solver.solve)
    model.tangent_and_force = timer.wrap("assembly", model.tangent_and_force)
    laws = (CompositeInterface, HyperbolicInterface)
    updates = [law.update for law in laws]
    for law, update in zip(laws, updates):
        law.update = timer.wrap("law update", update)
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        r = sc.run()
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        for law, update in zip(laws, updates):
            law.update = update
    p = r.path
    its = max(p.total_iterations, 1)
    split = ", ".join(f"{k} {1e3 * v / its:.1f} ms/it ({timer.calls[k]} calls)" for k, v in timer.seconds.items())
    return dict(top=top, dofs=sc.n_dofs, seconds=seconds, cpu=cpu, steps=len(p.path), attempted=p.attempted_steps,
                iterations=p.total_iterations, per_iteration=1e3 * cpu / its, split=split,
                peak=r.peak_load, peak_u=r.peak_displacement, reached=r.reached, status=r.status, message=r.message)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nx", type=int, help="elements per unit along the courses (default: the scenario's)")
    ap.add_argument("--ny", type=int, help="elements per course (default: the scenario's)")
    ap.add_argument("--element", choices=["Q4", "Q8"], help="continuum element (default: the scenario's)")
    ap.add_argument("--top", nargs="+", default=["fixed_vertical", "constant_force"],
                    choices=["fixed_vertical", "constant_force"])
    ap.add_argument("--full", action="store_true", help="run to 3 mm (control_range = 'full')")
    args = ap.parse_args()
    from fe.scenarios import build_scenario

    default = build_scenario("shear_compression_nl").options  # the linear peer gets the same mesh
    mesh = {k: getattr(args, k) if getattr(args, k) is not None else getattr(default, k) for k in ("nx", "ny", "element")}
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"load average before: {', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    with threadpool_limits(1):
        lin_dofs, lin_wall, lin_cpu = linear_solve_ms(mesh)
        rows = [run_j4d(mesh, top, args.full) for top in args.top]
    if rows:
        print("\n| top | dofs | wall (s) | CPU (s) | steps | increments | iterations | CPU ms / iteration "
              "| linear solve CPU (ms) | ratio | peak (kN) | at (mm) | reached (mm) | status |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for r in rows:
        print(f"| {r['top']} | {r['dofs']} | {r['seconds']:.1f} | {r['cpu']:.1f} | {r['steps']} | {r['attempted']} "
              f"| {r['iterations']} | {r['per_iteration']:.1f} | {lin_cpu:.1f} | {r['per_iteration'] / lin_cpu:.1f} "
              f"| {r['peak']:.1f} | {r['peak_u']:.2f} | {r['reached']:.2f} | {r['status']} |")
    if rows:
        print(f"\nlinear solve ({lin_dofs} dofs) wall time: {lin_wall:.1f} ms")
    for r in rows:
        print(f"{r['top']} CPU split: {r['split']}")
        if r["message"]:
            print(f"{r['top']}: {r['message']}")
    print(f"\nload average after: {', '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
