"""Joint calibration over two tests (issue 19, item 3): the example study end to end, and the
coverage of the joint region of equivalence over pseudo-experiments with hidden values.

1. ``podkrig run examples/joint_diagonal_shear.toml`` (the diagonal compression test plus the shear
   wall, sharing E_b, kN_bj, kV_bj, r_hj; 256 training + 32 held-out FE runs per test) from an
   empty output folder, timed (target: ≤ 3 minutes on two cores).
2. On that run's two surrogates: ``--experiments`` pseudo-experiments, each the FE readings of both
   tests at the hidden values plus a fresh LVDT noise realisation (σ² = (1 µm)² + (1 % d)²). Each is
   calibrated jointly and by each test alone (GA + polish, then a likelihood-ratio region at 95 %).
   Printed: how often the hidden values lie inside the joint region (membership: ω(m_true) ≤ the
   region's threshold; target ≥ 36 of 40) and inside every joint interval, and the median width of
   each parameter's interval, joint against each test alone.

    python scripts/bench_joint.py [--out out/bench_joint] [--experiments 40]
"""

import argparse
import os
import platform
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from fe.scenarios import build_scenario
from podkrig.io.surrogate_file import load_surrogate
from podkrig.online.invert import invert
from podkrig.online.joint import JointProblem
from podkrig.online.measurement import Measurement, instrument_noise
from podkrig.online.problem import InverseProblem, SurrogateModel, fix_from_scenario
from podkrig.online.region import likelihood_ratio_region
from podkrig.study import load_study, run_study

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples"))
from make_measured_data import TRUTH  # noqa: E402  (the hidden values of both example files)

STUDY = ROOT / "examples" / "joint_diagonal_shear.toml"


def run_example(out):
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    c0 = time.process_time()
    result = run_study(load_study(STUDY), out)
    return result, time.perf_counter() - t0, time.process_time() - c0


def pseudo_experiments(out, study, n, rng_seed=100):
    tests = study.calibration_tests
    models = {t.name: SurrogateModel(load_surrogate(out / t.file("surrogate.h5"))) for t in tests}
    clean = {t.name: build_scenario(t.spec).run({**t.fixed, **TRUTH}).readings for t in tests}
    rng = np.random.default_rng(rng_seed)
    inside = inside_box = 0
    widths = {"joint": [], **{t.name: [] for t in tests}}
    names = list(study.space.names)
    truth = np.array([TRUTH[n] for n in names])
    for _ in range(n):
        problems = {}
        for t in tests:
            model = models[t.name]
            noise = instrument_noise("lvdt", model.sensor_names)
            c = clean[t.name]
            sigma = np.sqrt(0.001**2 + (0.01 * c) ** 2)
            data = Measurement(c + sigma * rng.standard_normal(c.shape), model.sensor_names, model.load_levels,
                               source=f"pseudo {t.name}")
            free, fixed = fix_from_scenario(model)
            problems[t.name] = InverseProblem(model, data, noise, free=free, fixed=fixed)
        for label, problem in (("joint", JointProblem(problems)), *problems.items()):
            best = invert(problem, rng=0)
            region = likelihood_ratio_region(problem, best.x, confidence=0.95, n_samples=2**15, rng=0)
            widths[label].append([region.intervals[n][1] - region.intervals[n][0] for n in names])
            if label == "joint":
                inside += bool(problem.omega(truth[None])[0] <= region.threshold)
                inside_box += all(region.intervals[n][0] <= TRUTH[n] <= region.intervals[n][1] for n in names)
    return inside, inside_box, {k: np.median(np.array(v), axis=0) for k, v in widths.items()}, names


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "bench_joint")
    parser.add_argument("--experiments", type=int, default=40)
    args = parser.parse_args()
    load0 = os.getloadavg()[0]
    result, wall, cpu = run_example(args.out)
    load1 = os.getloadavg()[0]
    print(f"# {time.strftime('%Y-%m-%d %H:%M')} {platform.machine()} {os.cpu_count()} cores; load average "
          f"{load0:.2f} at start, {load1:.2f} after the study")
    print("\n| step | wall (s) | CPU of this process (s) | FE runs |\n|---|---|---|---|")
    print(f"| `podkrig run examples/joint_diagonal_shear.toml` (empty output folder) | {wall:.1f} | {cpu:.1f} | "
          f"{result.fe_runs} |")
    for r in result.stages:
        print(f"| &nbsp; {r.title} | {r.seconds:.1f} | | {r.fe_runs} |")
    t0 = time.perf_counter()
    inside, inside_box, widths, names = pseudo_experiments(args.out, result.study, args.experiments)
    print(f"\n{args.experiments} pseudo-experiments in {time.perf_counter() - t0:.0f} s (load average "
          f"{os.getloadavg()[0]:.2f}): hidden values inside the joint 95 % region in {inside} of "
          f"{args.experiments} (ω(m_true) ≤ threshold), inside every joint interval in {inside_box}.")
    print("\nMedian width of the 95 % interval (each parameter's unit):\n")
    labels = list(widths)
    print("| parameter | " + " | ".join(labels) + " | joint / narrowest single |\n|---" * 1 + "|---" * (len(labels) + 1) + "|")
    for j, n in enumerate(names):
        single = min(widths[k][j] for k in labels if k != "joint")
        print(f"| {n} | " + " | ".join(f"{widths[k][j]:.4g}" for k in labels) + f" | {widths['joint'][j] / single:.2f} |")


if __name__ == "__main__":
    main()
