"""Flat-jack identification with hidden truth (issue 15, item 6): 40 pseudo-experiments on the §5
set-up (jacks H, V1, V2; phases 0b–2; layout L18) with 2 µm Gaussian noise; the truth must lie in
the 95 % region of equivalence in ≥ 36 of them.

The truths are drawn by the test and used only to make the data and to check the result; the
inversion sees the readings and the noise model. A modest surrogate (96 FE snapshots of a
coarser mesh without the refinement window: same physics, ~3× cheaper) and a small GA budget keep
the test short: 100 s of CPU (10.5 min wall) under load 9–16 on 2 cores, of which FE 3.4 s,
surrogate fit 5.5 s and ≈ 2 s per inversion and region; 39 of 40 inside when measured.
"""

import numpy as np
import pytest

from fe.scenarios import build_scenario
from podkrig.offline.runner import run_snapshots
from podkrig.offline.store import SnapshotStore
from podkrig.online.invert import invert
from podkrig.online.problem import InverseProblem, SurrogateModel
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.region import likelihood_ratio_region
from podkrig.parameters import ParameterSpace
from podkrig.surrogate.podkriging import fit_from_store

SPEC = {"scenario": "flat_jack", "phases": ["0b", "1", "2"], "layout": "L18", "refine": []}
BOUNDS = {"E_b": (5000, 16000), "kN_bj": (20, 200, "log"), "kV_bj": (10, 100, "log"), "r_hj": (0.2, 1.0),
          "Km": (0.75, 0.95)}
SIGMA = 0.002  # mm: 2 µm LVDT noise (reference §5.7)


@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    scenario = build_scenario(SPEC)
    space = ParameterSpace.from_scenario(scenario, BOUNDS)
    path = tmp_path_factory.mktemp("fj") / "train.h5"
    run_snapshots(path, scenario, space, n=96, seed=1, workers=1)
    with SnapshotStore.open(path) as store:
        model = SurrogateModel(fit_from_store(store))
    return scenario, space, model


def _hidden_truth(space, seed):
    # away from the box faces, as a test campaign would be designed; never passed to the inversion
    u = np.random.default_rng(2000 + seed).uniform(0.15, 0.85, (1, len(space.names)))
    return space.as_params(space.from_unit(u)[0])


def _pseudo_data(scenario, truth, seed):
    clean = scenario.run(truth).readings
    noisy = clean + SIGMA * np.random.default_rng(seed).standard_normal(clean.shape)
    return Measurement(noisy, scenario.sensor_names, scenario.load_levels, source=f"flat-jack pseudo-data {seed}")


def test_one_pseudo_experiment_is_identified(calibration):
    """The fast lane's case of the coverage test below: one pseudo-experiment (seed 2), its truth
    inside the 95 % region and the jack efficiency Km, the best-resolved parameter (region ±2 %),
    within 1 % of the truth (measured: 0.05 %)."""
    scenario, space, model = calibration
    truth = _hidden_truth(space, 2)
    problem = InverseProblem(model, _pseudo_data(scenario, truth, 2), NoiseModel(sigma=SIGMA))
    result = invert(problem, rng=2, population_size=40, generations=20, n_starts=1)
    region = likelihood_ratio_region(problem, result.x, n_samples=2**13, rng=2)
    x_true = np.array([[truth[n] for n in problem.free]])
    omega = problem.freeze_model_error(result.x).omega(x_true)[0]
    assert omega <= region.threshold  # measured: ω(truth) − ω* is 6 % of the threshold's height
    assert result.x[problem.free.index("Km")] == pytest.approx(truth["Km"], rel=0.01)


@pytest.mark.slow
def test_region_covers_hidden_truth(calibration):
    """≥ 36 of 40 (P(≤ 35 | p = 0.95) ≈ 5 %)."""
    scenario, space, model = calibration
    inside = 0
    for seed in range(40):
        truth = _hidden_truth(space, seed)
        problem = InverseProblem(model, _pseudo_data(scenario, truth, seed), NoiseModel(sigma=SIGMA))
        # a small GA budget and one polish: the misfit of this test has a single basin in the box
        result = invert(problem, rng=seed, population_size=40, generations=20, n_starts=1)
        region = likelihood_ratio_region(problem, result.x, n_samples=2**13, rng=seed)
        x_true = np.array([[truth[n] for n in problem.free]])
        inside += problem.freeze_model_error(result.x).omega(x_true)[0] <= region.threshold
    print(f"truth inside the 95 % region in {inside} of 40 pseudo-experiments")
    assert inside >= 36, inside
