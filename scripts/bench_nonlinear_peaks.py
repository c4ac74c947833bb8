"""Step control and exact peaks of the nonlinear solver (issue 30, deliverable 4): counts, not times.

For each case (default: J4D on the default and the coarse Q8 2 × 1 mesh, both top conditions, and
the three specimens at their defaults; also J6D and the diagonal panel on the coarse mesh) it runs the scenario twice, with the step control before
issue 30 (``predictor = "tangent"``, ``step_rule = "easy_steps"``, no peak refinement) and with
the current defaults (secant predictor, peaks refined to ``peak_tolerance``), and with
``--finer`` also with ten times finer increments. It prints a Markdown table per case: converged
steps, failed (cut-back) increments of the recorded path, attempted increments (detours and peak
refinements included), Newton iterations, process CPU time (``time.process_time``, BLAS limited
to one thread), the reported peak and its displacement, and whether the peak was resolved to the
tolerance. The counts are the comparison; the CPU times are indicative on a shared machine.

Usage: python scripts/bench_nonlinear_peaks.py [--case j4d|j4d-4x2|j4d-coarse|j6d-coarse|diagonal-coarse|specimens ...]
       [--finer]
"""

import argparse
import dataclasses
import os
import time

from threadpoolctl import threadpool_limits

from fe.scenarios import build_scenario

CASES = {
    "j4d": [{"scenario": "shear_compression_nl", "top": top} for top in ("fixed_vertical", "constant_force")],
    "j4d-4x2": [{"scenario": "shear_compression_nl", "top": top, "nx": 4, "ny": 2}
                for top in ("fixed_vertical", "constant_force")],
    "j4d-coarse": [{"scenario": "shear_compression_nl", "top": top, "nx": 2, "ny": 1}
                   for top in ("fixed_vertical", "constant_force")],
    "j6d-coarse": [{"scenario": "shear_compression_nl", "top": top, "nx": 2, "ny": 1, "precompression": 1.21}
                   for top in ("fixed_vertical", "constant_force")],
    "diagonal-coarse": [{"scenario": "diagonal_compression_nl", "nx": 2, "ny": 1}],
    "specimens": [{"scenario": "couplet_tension"}, {"scenario": "triplet_shear"}, {"scenario": "prism_compression"}],
}

#: The step control before issue 30 and the current defaults (PathSettings fields).
VARIANTS = {
    "before": {"predictor": "tangent", "step_rule": "easy_steps", "peak_tolerance": 0.0},
    "now": {},
}


def run(spec, variant, factor=1):
    """One run; returns a dict of counts, CPU time and the peak."""
    if factor != 1:
        o = build_scenario(spec).options
        spec = dict(spec, increment=o.increment / factor, max_increment=o.max_increment / factor,
                    max_steps=factor * o.max_steps)
    sc = build_scenario(spec)
    settings = dataclasses.replace(sc.options.path_settings(), **VARIANTS[variant])
    c0 = time.process_time()
    r = sc.run(settings=settings)
    cpu = time.process_time() - c0
    p = r.path
    peak = p.peaks.get(p.phase[-1]) if p.peaks else None
    return dict(variant=variant + ("" if factor == 1 else f" (increments / {factor})"), status=r.status,
                steps=len(p.path), failed=p.failed_steps, attempted=p.attempted_steps,
                iterations=p.total_iterations, cpu=cpu, peak=r.peak_load, at=r.peak_displacement,
                resolved="-" if peak is None or not peak.refined else ("yes" if peak.resolved else "no"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", nargs="+", choices=sorted(CASES), default=["j4d", "j4d-coarse", "specimens"])
    ap.add_argument("--finer", action="store_true", help="also run the current defaults with increments / 10")
    args = ap.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.1f}; CPU times with BLAS on one thread")
    with threadpool_limits(1):
        for case in args.case:
            for spec in CASES[case]:
                print(f"\n{spec}\n")
                print("| step control | status | steps | failed | attempted | iterations | CPU s | "
                      "peak kN | at mm | resolved |")
                print("|---|---|---:|---:|---:|---:|---:|---:|---:|---|")
                rows = [run(spec, "before"), run(spec, "now")] + ([run(spec, "now", 10)] if args.finer else [])
                for r in rows:
                    print(f"| {r['variant']} | {r['status']} | {r['steps']} | {r['failed']} | {r['attempted']} | "
                          f"{r['iterations']} | {r['cpu']:.2f} | {r['peak']:.4f} | {r['at']:.4f} | {r['resolved']} |",
                          flush=True)


if __name__ == "__main__":
    main()
