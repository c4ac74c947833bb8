"""Rigid-body removal (issue 18, deliverable 2): what it changes on data from an independent
discretisation, and what it costs in the misfit.

Usage::

    python scripts/bench_rigid_body.py                 # 6 clean data sets (~10 min on 2 cores)
    python scripts/bench_rigid_body.py --controls 3    # a quick look

1. Independent discretisation: clean data (no hidden effect) from Q4 24 × 8 elements per unit,
   against the default Q8 6 × 2 model, diagonal test with its six gauges and a 9 × 9 DIC grid
   (σ = 1 % of the largest reading, ≥ 1 µm, as ``scripts/bench_diagnosis.py``): the diagnosis with
   ``rigid_body = "keep"`` and ``"auto"`` on the same data; rows: base χ²/dof, verdict, causes, and
   the rigid rotation of the DIC grid between the two discretisations at the top load (rad).
2. Cost of the projected whitening in the misfit for a population of 100 (per-sample σ, as with
   the surrogate's C_T), against the plain division.
"""

import argparse
import os
import pathlib
import platform
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))  # the trial generator lives with the tests

from diagnosis_trials import make_trial

from fe import build_scenario
from fe.scenarios.diagonal_compression import DEFAULT_SENSORS
from fe.sensors import DICGrid, Gauge, absolute_displacements
from podkrig.diagnosis import DiagnosisSettings, build_base_surrogate, diagnose
from podkrig.online.measurement import Measurement
from podkrig.online.rigid_body import rigid_body_modes
from podkrig.parameters import ParameterSpace

BOUNDS = {"kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log")}
DIC = {"kind": "dic", "x0": 65.0, "y0": 32.5, "x1": 1105.0, "y1": 1072.5, "nx": 9, "ny": 9}


def spec(nx, ny, element="Q8"):
    sensors = {g.name: g.to_dict() for g in DEFAULT_SENSORS}
    sensors["DIC"] = dict(DIC)
    return {"scenario": "diagonal_compression", "nx": nx, "ny": ny, "element": element, "sensors": sensors}


def independent_series(n, seed):
    fine = build_scenario(spec(24, 8, "Q4"))
    model = build_scenario(spec(6, 2))
    space = ParameterSpace.from_scenario(model, BOUNDS)
    surrogate = build_base_surrogate(model, space, model.resolve(), 64, 0)
    fine_space = ParameterSpace.from_scenario(fine, BOUNDS)
    rng = np.random.default_rng(seed)
    print("\n## Clean data from Q4 24×8, model Q8 6×2 (diagonal test, six gauges + 9 × 9 DIC)\n")
    print("| data set | truth kN_bj, kV_bj | ω between codes, top load (rad) | rigid_body | base χ²/dof | dof | verdict | causes | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    alarms = {"keep": 0, "auto": 0}
    for k in range(n):
        truth = {"kN_bj": float(np.exp(rng.uniform(np.log(30), np.log(300)))),
                 "kV_bj": float(np.exp(rng.uniform(np.log(12), np.log(120))))}
        trial = make_trial(fine, fine_space, truth, rng=rng)
        diff = Measurement(fine.run(truth).readings - model.run(truth).readings, model.sensor_names, model.load_levels)
        modes = rigid_body_modes(diff, absolute_displacements(model.sensors))
        omega = modes.fit(diff.data)[-1, 2]
        for option in ("keep", "auto"):
            t = time.perf_counter()
            d = diagnose(model, trial.measurement, trial.noise, space, DiagnosisSettings(seed=k), surrogate=surrogate,
                         rigid_body=option)
            alarms[option] += d.verdict != "adequate"
            print(f"| {k} | {truth['kN_bj']:.1f}, {truth['kV_bj']:.1f} | {omega:.2e} | {option} | {d.base.chi2_dof:.2f} | "
                  f"{d.base.dof} | {d.verdict} | {', '.join(c.name for c in d.causes) or '—'} | "
                  f"{time.perf_counter() - t:.0f} |", flush=True)
    print(f"\nfalse alarms: keep {alarms['keep']}/{n}, auto {alarms['auto']}/{n}")


def whitening_cost():
    print("\n## Projected whitening, population of 100, per-sample σ (ms)\n")
    print("| DIC grid | load levels | n_obs | removed dof | plain u/σ | with rigid removal |")
    print("|---|---|---|---|---|---|")
    rng = np.random.default_rng(0)
    for nx, ny, n_loads in ((9, 9, 4), (40, 30, 10)):
        sensors = [Gauge("D1", (0, 0), (1, 1)), DICGrid("G", 0, 0, 1000, 1000, nx, ny)]
        names = ["D1", *sensors[1].channel_names]
        meas = Measurement(np.ones((n_loads, len(names))), names, np.arange(1.0, n_loads + 1))
        modes = rigid_body_modes(meas, absolute_displacements(sensors))
        r, sd = rng.normal(size=(100, meas.n_obs)), rng.uniform(1, 2, size=(100, meas.n_obs))
        times = []
        for removal in (False, True):
            t = time.perf_counter()
            for _ in range(5):
                u = r / sd
                if removal:
                    modes.whiten_diagonal(u, sd)
            times.append((time.perf_counter() - t) / 5 * 1e3)
        print(f"| {nx} × {ny} | {n_loads} | {meas.n_obs} | {modes.n_removed} | {times[0]:.2f} | {times[1]:.2f} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controls", type=int, default=6, help="clean data sets from the independent discretisation")
    parser.add_argument("--seed", type=int, default=11)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"load {os.getloadavg()[0]:.2f} (1 min) at start")
    whitening_cost()
    if args.controls:
        independent_series(args.controls, args.seed)
    print(f"\nload {os.getloadavg()[0]:.2f} (1 min) at the end")


if __name__ == "__main__":
    main()
