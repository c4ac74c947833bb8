"""Benchmark: the diagnosis's strength candidates on one triplet's force–displacement curve.

One EN 1052-3 triplet (``triplet_shear`` at 0.6 MPa, 14 control levels to 2 mm), F + two gauges,
noise 1 % + 0.05 kN on the force and 1 % + 2 µm on the gauges; base model: c_bj and tanphi_bj at
the triplet series' identified values, GfII_bj free (tests/strength_trials.py). Per noise seed
(hidden effect drawn from the seed): (1) one bed joint 20–30 % weaker (``joint_strength_factors``),
(2) dilatancy tanψ 0.03–0.1, (3) clean data; the causes named and the CPU seconds per diagnosis
(process time); at the end, per kind, how many were named (the weak joint: and at the right joint)
or read adequate. The same cases are asserted in tests/test_diagnosis_strength.py, which also
measures what is left of a weak joint when c_bj is free as well (under 1σ).

    python scripts/bench_diagnosis_strength.py --seeds 20 --clean 20
"""

import argparse
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))  # the trial generator lives with the tests

from strength_trials import diagnose_trial, make_strength_trial  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5, help="noise seeds of the weak-joint and dilatancy trials")
    ap.add_argument("--clean", type=int, default=20, help="noise seeds of clean data")
    args = ap.parse_args()
    tally = {}

    def run(effect, seed):
        trial = make_strength_trial(effect, np.random.default_rng(3200 + seed))
        t0 = time.process_time()
        d = diagnose_trial(trial, seed)
        cpu = time.process_time() - t0
        named = ", ".join(f"{c.name} at {c.location.key} ({c.value:.3g})" for c in d.causes) or "—"
        truth = ""
        if effect is not None:
            joint = "" if trial.joint is None else ("lower", "upper")[trial.joint] + " joint, "
            truth = f" [truth: {joint}{trial.value:.3g}]"
        print(f"{effect or 'clean':>19} seed {seed:2d}: {d.verdict:10s} {named}{truth}  (χ² p = {d.chi2_p_value:.2g}, "
              f"{cpu:.1f} s CPU, {d.n_fe_runs} FE runs)", flush=True)
        hit = d.cause == effect if effect else d.verdict == "adequate"
        where = effect == "weak_joint_strength" and hit and d.causes[0].location.detail["joint"] == trial.joint
        tally.setdefault(effect or "clean", []).append((hit, where, cpu))

    for effect in ("weak_joint_strength", "dilatancy"):
        for seed in range(args.seeds):
            run(effect, seed)
    for seed in range(args.clean):
        run(None, seed)
    for effect, rows in tally.items():
        cpu = np.array([r[2] for r in rows])
        what = "adequate" if effect == "clean" else "named"
        extra = f", the right joint in {sum(r[1] for r in rows)}" if effect == "weak_joint_strength" else ""
        print(f"{effect}: {what} in {sum(r[0] for r in rows)}/{len(rows)}{extra}; CPU per diagnosis median "
              f"{np.median(cpu):.1f} s (max {cpu.max():.1f} s)")


if __name__ == "__main__":
    main()
