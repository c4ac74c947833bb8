"""Benchmark: the diagnosis's verdict against its candidates, on hidden truths from our own FE.

The diagonal test (coarse mesh, Q8 2×1 per unit) with its six gauges and a 5 × 6 DIC grid,
kN_bj = 100, kV_bj = 40 N/mm³, σ = 1 % of the largest reading. Prints, per noise seed, the causes
named for (1) a whole bed joint (y = 585 mm) weakened to 10 % (every segment of it), (2) a gain
fault of +40 % on gauge D2, and the verdicts on clean data (false alarms). CPU seconds per
diagnosis (process time). The same cases are asserted in tests/test_diagnosis_gate.py.

    python scripts/bench_diagnosis_gate.py --clean 20
"""

import argparse
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))  # the trial generator lives with the tests

from diagnosis_trials import make_trial, make_whole_joint_trial  # noqa: E402
from fe import build_scenario  # noqa: E402
from fe.scenarios.diagonal_compression import DEFAULT_SENSORS  # noqa: E402
from podkrig.diagnosis import CANDIDATES, DiagnosisSettings, FEContext, build_base_surrogate, diagnose  # noqa: E402
from podkrig.parameters import ParameterSpace  # noqa: E402

BOUNDS = {"kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log")}
TRUTH = {"kN_bj": 100.0, "kV_bj": 40.0}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="noise seeds of the joint and gain-fault trials")
    ap.add_argument("--clean", type=int, default=20, help="noise seeds of clean data")
    args = ap.parse_args()
    sensors = {g.name: g.to_dict() for g in DEFAULT_SENSORS}
    sensors["DIC"] = {"kind": "dic", "x0": 65.0, "y0": 32.5, "x1": 1105.0, "y1": 1072.5, "nx": 5, "ny": 6}
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1, "sensors": sensors})
    space = ParameterSpace.from_scenario(sc, BOUNDS)
    surrogate = build_base_surrogate(sc, space, sc.resolve(), 64, 0)
    ctx = FEContext(sc, space.names, sc.resolve(TRUTH))
    d2 = next(loc for loc in CANDIDATES["gauge_fault"].locations(ctx) if loc.key == "D2 gain")

    def run(label, trial, seed):
        t0 = time.process_time()
        d = diagnose(sc, trial.measurement, trial.noise, space, DiagnosisSettings(seed=seed), surrogate=surrogate)
        named = ", ".join(f"{c.name} at {c.location.key}" for c in d.causes) or "—"
        print(f"{label:>6} seed {seed:2d}: {d.verdict:10s} {named}  (χ² p = {d.chi2_p_value:.2g}, "
              f"{time.process_time() - t0:.1f} s CPU)", flush=True)
        return d

    for seed in range(args.seeds):
        run("joint", make_whole_joint_trial(sc, space, TRUTH, 585.0, 0.1, rng=np.random.default_rng(100 + seed)), seed)
    for seed in range(args.seeds):
        run("gain", make_trial(sc, space, TRUTH, "gauge_fault", d2, 0.4, rng=np.random.default_rng(100 + seed)), seed)
    alarms = sum(run("clean", make_trial(sc, space, TRUTH, rng=np.random.default_rng(100 + seed)), seed).verdict
                 != "adequate" for seed in range(args.clean))
    print(f"false alarms on clean data: {alarms}/{args.clean}")


if __name__ == "__main__":
    main()
