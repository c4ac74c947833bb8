"""Nonlinear scenarios through the offline runner: converged rows, and runs that stop early kept
as failed rows with their reason and partial readings."""

import numpy as np

from fe.scenarios import build_scenario
from podkrig.offline.runner import run_snapshots
from podkrig.offline.store import SnapshotStore
from podkrig.parameters import ParameterSpace

SPEC = {"scenario": "couplet_tension", "nx": 2, "ny": 1, "load_levels": [0.002, 0.01, 0.05],
        "increment": 0.001, "max_increment": 0.01}


def test_nonlinear_snapshots_converge_and_record_the_solver_settings(tmp_path):
    sc = build_scenario(SPEC)
    space = ParameterSpace.from_scenario(sc, {"ft_bj": (0.1, 0.3, "linear")})
    summary = run_snapshots(tmp_path / "s.h5", sc, space, n=4, seed=0, workers=1)
    assert summary.done == 4
    with SnapshotStore.open(tmp_path / "s.h5") as store:
        assert np.isfinite(store.readings()).all()
        assert store.spec.options["max_steps"] == 600 and store.spec.options["tolerance"] == 1e-3


def test_runs_that_stop_early_are_failed_rows_with_partial_readings(tmp_path):
    sc = build_scenario(dict(SPEC, max_steps=3))
    space = ParameterSpace.from_scenario(sc, {"ft_bj": (0.1, 0.3, "linear")})
    summary = run_snapshots(tmp_path / "s.h5", sc, space, n=2, seed=0, workers=1)
    assert summary.failed == 2
    with SnapshotStore.open(tmp_path / "s.h5") as store:
        errors = store.errors()
        assert all(e.startswith("NotConverged (budget_exhausted): step budget of 3") for e in errors.values())
        partial = store.readings(only_done=False)
        assert np.isfinite(partial[:, 0]).all() and np.isnan(partial[:, -1]).all()
