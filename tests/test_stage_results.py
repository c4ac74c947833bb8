"""The results of the offline stage, the surrogate fit and the held-out check: built from the
objects they summarise, and read back from their dicts (the study manifests, the CLI's JSON)."""

import json

import numpy as np
import pytest

from podkrig.io.surrogate_file import load_surrogate, save_surrogate
from podkrig.offline.results import OfflineResult
from podkrig.offline.runner import run_snapshots
from podkrig.offline.store import SnapshotStore
from podkrig.parameters import ParameterSpace
from podkrig.reports.html import Page
from podkrig.reports.offline import offline_table, rows_text
from podkrig.reports.surrogate import fit_tables, held_out_tables
from podkrig.surrogate.results import HeldOutResult, SurrogateFitResult, ValidationModelResult
from podkrig.surrogate.settings import SurrogateSettings, fit_surrogate
from podkrig.surrogate.validation import HeldOutReport, held_out_errors

BOUNDS = {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000)}


def _round_trip(result):
    """``result`` through its dict and JSON text, as a manifest is written and read."""
    return type(result).from_dict(json.loads(json.dumps(result.to_dict())))


@pytest.fixture(scope="module")
def store(tmp_path_factory, coarse_diagonal):
    path = tmp_path_factory.mktemp("results") / "train.h5"
    space = ParameterSpace.from_scenario(coarse_diagonal, BOUNDS)
    summary = run_snapshots(path, coarse_diagonal, space, n=8, seed=0, workers=1)
    return path, summary


def test_offline_result_holds_the_store_and_round_trips(store):
    path, summary = store
    result = OfflineResult.from_store(path, summary, ["a note"])
    with SnapshotStore.open(path) as s:
        wall = s.wall_times()
        assert result.n_dofs == s.n_dofs
    assert (result.total, result.done, result.failed, result.pending) == (8, 8, 0, 0)
    # the mean and total FE time are those of the stored rows (same numbers, same order of sums)
    assert result.fe_ms_per_run == pytest.approx(1000 * wall.mean(), rel=1e-12)
    assert result.fe_seconds_total == pytest.approx(wall.sum(), rel=1e-12)
    assert result.notes == ("a note",) and result.failures == ()
    assert _round_trip(result) == result
    assert all(f in rows_text(result) for f in ("8 done", "0 failed", "0 pending", "8 rows"))


def test_surrogate_fit_result_and_held_out_result_round_trip(store, tmp_path):
    path, _ = store
    with SnapshotStore.open(path) as s:
        sur = fit_surrogate(s, SurrogateSettings(modes=3, beta=1.5))
        X, Y = s.parameters(physical=True), s.readings()
    fit = SurrogateFitResult.from_surrogate(sur)
    assert (fit.n_train, fit.n_modes, fit.backend, fit.beta) == (8, 3, "podkrig", (1.5, 1.5, 1.5))
    assert fit.training_seconds == sur.provenance_["training_seconds"] > 0
    assert _round_trip(fit) == fit
    # a surrogate file keeps what the result needs
    save_surrogate(sur, tmp_path / "s.h5")
    assert SurrogateFitResult.from_surrogate(load_surrogate(tmp_path / "s.h5")) == fit

    rep = held_out_errors(sur, X[:4], Y[:4])
    held = HeldOutResult.from_report(rep, backend="podkrig")
    # the study's manifest: the report's summary, then the absolute errors (mm)
    assert list(held.to_dict())[:len(rep.summary())] == list(rep.summary())
    diff = rep.Y_pred - rep.Y_true
    assert held.rms_abs_error_mm == pytest.approx(np.sqrt(np.mean(diff**2)), rel=1e-12)
    assert held.max_abs_error_mm == np.max(np.abs(diff))
    assert _round_trip(held) == held


def test_held_out_result_of_a_known_report():
    # two held-out runs of two readings: errors 0.3 and 0.4 mm in one run, none in the other
    Y = np.array([[1.0, 2.0], [3.0, 4.0]])
    P = Y + np.array([[0.3, -0.4], [0.0, 0.0]])
    e = np.array([0.5 / np.sqrt(5), 0.0])
    rep = HeldOutReport(e, np.zeros(2), e, 0.75, np.zeros((2, 1)), Y, P, np.full((2, 2), 0.1), n_train=6, n_modes=2)
    held = HeldOutResult.from_report(rep, held_out_store="held.h5", held_out_content_hash="abc")
    assert held.rms_abs_error_mm == pytest.approx(np.sqrt(0.25 / 4), rel=1e-12)  # (0.09 + 0.16) / 4 readings
    assert held.max_abs_error_mm == pytest.approx(0.4, rel=1e-12)
    assert held.rel_error["max"] == pytest.approx(0.5 / np.sqrt(5), rel=1e-12)
    d = held.to_dict()
    assert "loo_error" not in d and "backend" not in d and d["held_out_store"] == "held.h5"
    assert _round_trip(held) == held


def test_validation_model_result_is_the_store_with_its_surrogate():
    store = OfflineResult(16, 16, 0, 0, "serial", 120, 10.0, 0.16)
    fit = SurrogateFitResult(16, 4, 0.999, "sklearn-gpr", description="GPR per mode", training_seconds=1.0)
    result = ValidationModelResult(store, "shear_compression", fit)
    d = result.to_dict()
    assert d["done"] == 16 and d["scenario"] == "shear_compression" and d["surrogate"]["description"] == "GPR per mode"
    assert "beta" not in d["surrogate"]
    assert _round_trip(result) == result


def test_one_renderer_draws_each_result():
    page = Page("t")
    offline_table(page, [("Training", OfflineResult(4, 3, 1, 0, "serial", 120, 12.345, 0.05, ("row 2: x",),
                                                     ("kept aside",)), "cached")])
    fit_tables(page, SurrogateFitResult(16, 4, 0.9999999, "podkrig", beta=(1.234, 1.5), training_seconds=0.25))
    stats = {"median": 0.01, "p95": 0.02, "max": 0.03, "mean": 0.012}
    held_out_tables(page, HeldOutResult(16, 8, 4, stats, stats, stats, 0.9, 0.001, 0.004, fit_description="exact"))
    text = "\n".join(page._parts)
    for fragment in ("12.3", "Training: kept aside", "1.23, 1.5", "0.9999999000", "0.25", ">1<", ">3<", "0.004",
                     "90", "Kriging: exact."):
        assert fragment in text, fragment
