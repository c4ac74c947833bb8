"""Cost of the diagnosis candidates of issue 18 item 5: one diagnosis per candidate on clean
pseudo-data (the base calibration included, the surrogate given), FE runs and wall time.

    python scripts/bench_diagnosis_candidates.py

Set-ups: the diagonal test on the coarse mesh (2 × 1 Q8 per unit) with six gauges and a 9 × 9 DIC
grid, the default mesh (6 × 2) with the six gauges, and the chisari flat-jack test (L18, phases
0b–2). ``gauge_fault`` is the peer measured in the same run (a candidate without FE work of its
own). FE runs count linear solves and, for ``nonlinearity_onset``, nonlinear runs (its scan).
"""

import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from diagnosis_trials import make_trial  # the trial generator lives with the tests

from fe import build_scenario
from fe.scenarios.diagonal_compression import DEFAULT_SENSORS
from podkrig.diagnosis import build_base_surrogate, diagnose
from podkrig.parameters import ParameterSpace

WALL_BOUNDS = {"kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log")}
JACK_BOUNDS = {"E_b": (2000.0, 30000.0, "log"), "kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log")}
DIC = {"kind": "dic", "x0": 65.0, "y0": 32.5, "x1": 1105.0, "y1": 1072.5, "nx": 9, "ny": 9}


def main():
    sensors = {g.name: g.to_dict() for g in DEFAULT_SENSORS}
    sensors["DIC"] = dict(DIC)
    cases = [
        ("diagonal 2×1 + DIC", {"scenario": "diagonal_compression", "nx": 2, "ny": 1, "sensors": sensors},
         WALL_BOUNDS, ["gauge_fault", "gauge_slip", "nonlinearity_onset"]),
        ("diagonal 6×2, 6 gauges", {"scenario": "diagonal_compression"}, WALL_BOUNDS,
         ["gauge_fault", "gauge_slip", "nonlinearity_onset"]),
        ("flat jack chisari L18", {"scenario": "flat_jack", "phases": ["0b", "1", "2"], "layout": "L18"}, JACK_BOUNDS,
         ["gauge_fault", "gauge_slip", "jack_efficiency", "slot_contact"]),
    ]
    print(f"# bench_diagnosis_candidates — {time.strftime('%Y-%m-%d')}, {platform.machine()}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.2f}")
    print("| set-up | candidate | FE runs | seconds | verdict |")
    print("|---|---|---|---|---|")
    for label, spec, bounds, names in cases:
        sc = build_scenario(spec)
        space = ParameterSpace.from_scenario(sc, bounds)
        surrogate = build_base_surrogate(sc, space, sc.resolve(), 64, 0)
        trial = make_trial(sc, space, {}, rng=np.random.default_rng(0))
        for name in names:
            t = time.perf_counter()
            d = diagnose(sc, trial.measurement, trial.noise, space, surrogate=surrogate, candidates=[name])
            print(f"| {label} | {name} | {d.n_fe_runs} | {time.perf_counter() - t:.1f} | {d.verdict} |", flush=True)
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
