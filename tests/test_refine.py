"""Adaptive enrichment of a snapshot store (podkrig/surrogate/refine.py, issue 12): the greedy
spaced batch choice on hand-computed 1-D designs, the setting checks, and a small refinement on
the coarse diagonal-compression model (two parameters, 8 training and 4 held-out FE runs of
~0.2 s each, with displacement fields) with its stop reasons, the runs added to the store and the record in the file.
"""

import inspect
import logging

import numpy as np
import pytest
import typer
from numpy.testing import assert_allclose, assert_array_equal

from fe.exceptions import SolverError
from fe.scenarios import Scenario
from podkrig.cli import app
from podkrig.config import field_info
from podkrig.io.surrogate_file import load_surrogate, save_surrogate
from podkrig.offline.runner import run_snapshots
from podkrig.offline.sampling import sample
from podkrig.offline.store import SnapshotStore
from podkrig.parameters import ParameterSpace
from podkrig.surrogate import refine
from podkrig.surrogate.kriging import OrdinaryKriging
from podkrig.surrogate.pod import POD
from podkrig.surrogate.podkriging import fit_from_store
from podkrig.surrogate.refine import refine_surrogate, select_batch
from podkrig.surrogate.settings import RefineSettings

BOUNDS = {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000)}
U_TRAIN = np.array([[0.0], [0.5], [1.0]])  # nearest-neighbour distances 0.5: radius 0.25


# ---------------------------------------------------------------- select_batch
def test_batch_takes_the_highest_scores_that_are_a_radius_apart():
    """Radius = half the mean nearest-neighbour distance of the design (0.25 here). Scores in
    decreasing order 0.1, 0.2, 0.6, 0.9: 0.2 is 0.1 from the chosen 0.1 (skipped), 0.6 and 0.9
    (0.3 apart) are kept, 0.65 (0.05 from 0.6, far from 0.1) is not: the distance to the nearest
    chosen point counts; k limits the count, the order is by score, and the indices are integers
    (also none, for k = 0)."""
    U = np.array([[0.6], [0.1], [0.9], [0.2], [0.65]])
    score = np.array([2.0, 4.0, 1.0, 3.0, 1.5])
    assert_array_equal(select_batch(U, score, U_TRAIN, 3), [1, 0, 2])  # 0.65 is 0.05 from the chosen 0.6
    assert_array_equal(select_batch(U, score, U_TRAIN, 2), [1, 0])
    assert_array_equal(select_batch(U, score, U_TRAIN, 1), [1])
    assert select_batch(U, score, U_TRAIN, 3).dtype.kind == "i"
    empty = select_batch(U, score, U_TRAIN, 0)
    assert empty.shape == (0,) and empty.dtype.kind == "i" and U[empty].shape == (0, 1)  # usable as an index


def test_a_candidate_exactly_one_radius_away_is_kept():
    """The exclusion is strict (< radius): 0.125 and 0.375 are exactly 0.25 apart (dyadic, no
    rounding) and both kept; 0.3125 (0.1875 from 0.125) is not."""
    U = np.array([[0.125], [0.3125], [0.375]])
    score = np.array([3.0, 2.0, 1.0])
    assert_array_equal(select_batch(U, score, U_TRAIN, 3), [0, 2])


def test_fewer_than_k_when_the_candidates_crowd_together():
    """All candidates within one radius of the best: a batch of one, not k clustered points."""
    U = np.array([[0.50], [0.52], [0.48], [0.55]])
    assert_array_equal(select_batch(U, np.array([1.0, 4.0, 2.0, 3.0]), U_TRAIN, 3), [1])


def test_radius_follows_the_training_design():
    """A denser design (spacing 0.125: radius 1/16) lets candidates 0.1 apart both in."""
    U = np.array([[0.1], [0.2]])
    dense = np.linspace(0, 1, 9)[:, None]
    assert_array_equal(select_batch(U, np.array([2.0, 1.0]), dense, 2), [0, 1])
    assert_array_equal(select_batch(U, np.array([2.0, 1.0]), U_TRAIN, 2), [0])


# ---------------------------------------------------------------- settings
@pytest.mark.parametrize("settings, message", [
    ({"budget": -1}, r"budget -1: .*integer in \[0, "),
    ({"budget": 4.0}, r"budget 4\.0: .*integer in \[0, "),
    ({"batch": 0}, "batch 0: .*integer >= 1"),
    ({"batch": True}, "batch True: .*integer >= 1"),
    ({"n_candidates": 0}, r"n_candidates 0: .*integer in \[1, "),
    ({"target_error": 0.0}, r"target_error 0\.0: .*\(0, 1\]"),
    ({"target_error": float("nan")}, r"target_error nan: .*\(0, 1\]"),
    ({"target_error": float("inf")}, r"target_error inf: .*\(0, 1\]"),
    ({"sampling": "grid"}, "sampling 'grid': .*sobol, "),
    ({"rng": -1}, "rng -1: .*integer >= 0"),
    ({"workers": 0}, r"workers 0: .*integer in \[1, "),
])
def test_setting_errors_name_the_value_before_any_file_is_read(tmp_path, settings, message):
    """Bad settings are refused with the value and what is allowed, before the surrogate is used or
    the (missing) stores are opened."""
    with pytest.raises(ValueError, match=message):
        refine_surrogate(None, tmp_path / "none.h5", tmp_path / "none.h5", **settings)


# ---------------------------------------------------------------- refinement
@pytest.fixture(scope="module")
def stores(tmp_path_factory, coarse_diagonal):
    d = tmp_path_factory.mktemp("refine")
    space = ParameterSpace.from_scenario(coarse_diagonal, BOUNDS)
    run_snapshots(d / "train.h5", coarse_diagonal, space, n=8, seed=0, workers=1, fields=True)
    run_snapshots(d / "held.h5", coarse_diagonal, space, n=4, seed=3, sampling="random", workers=1, fields=True)
    with SnapshotStore.open(d / "train.h5") as s:
        save_surrogate(fit_from_store(s), d / "sur.h5")
    return d


def _copies(stores, tmp_path):
    for name in ("train.h5", "sur.h5"):
        (tmp_path / name).write_bytes((stores / name).read_bytes())
    return tmp_path / "sur.h5", tmp_path / "train.h5", stores / "held.h5"


def _refine(file, train, held, **settings):
    """The summary of refining the surrogate of ``file`` and the refined surrogate."""
    sur = refine_surrogate(load_surrogate(file), train, held, **settings)
    return sur.provenance_["refinement"], sur


def test_budget_stops_after_the_rounds_it_pays_for(stores, tmp_path, caplog):
    """Budget 3 in batches of 2 with an unreachable target: rounds add 2 then 1 (the rest of the
    budget), the third fit stops on the budget; the 3 runs are done rows of the store, the history
    has one entry per fit (8, 10, 11 snapshots) and the refined surrogate records it all."""
    file, train, held = _copies(stores, tmp_path)
    with caplog.at_level(logging.INFO, logger="podkrig.surrogate.refine"):
        out, sur = _refine(file, train, held, target_error=1e-12, budget=3, batch=2, n_candidates=64)
    assert out["added"] == 3 and out["stop_reason"] == "budget of 3 FE runs used"
    assert [h["n_train"] for h in out["history"]] == [8, 10, 11]
    assert all(0 < h["median"] <= h["p95"] for h in out["history"])
    with SnapshotStore.open(train) as s:
        assert s.counts()["done"] == 11 and s.n_rows == 11
    assert sur.provenance_["refinement"] == out
    assert sur.X_.shape[0] == 11  # the final surrogate, of all 11 snapshots
    logged = [r.getMessage() for r in caplog.records if r.name == "podkrig.surrogate.refine"]
    assert logged == [f"refine: {h['n_train']} snapshots, held-out median {h['median']:.3g}" for h in out["history"]]


def test_a_reached_target_adds_nothing(stores, tmp_path):
    """A target above the first fit's error stops at once: no FE run, the store unchanged, the
    reason names the target."""
    file, train, held = _copies(stores, tmp_path)
    out, sur = _refine(file, train, held, target_error=1.0, budget=4, batch=2, n_candidates=64)
    assert out["added"] == 0 and out["stop_reason"] == "target 1 reached" and len(out["history"]) == 1
    with SnapshotStore.open(train) as s:
        assert s.n_rows == 8


def test_new_runs_are_the_spaced_highest_variance_candidates_of_the_seeded_set(stores, tmp_path, monkeypatch):
    """Each round draws the candidate set with seed ``rng + round`` (design ``sampling``), scores
    it by the variance summed over the outputs of the surrogate fitted with the file's own
    settings (here the power variogram, 3 POD modes and the displacement field as output, none
    of them a default; all kept in the refined surrogate) and appends
    ``select_batch`` of it: the new store rows are exactly those points, in that order (the
    refinement is reproducible and resumable from the store)."""
    file, train, held = _copies(stores, tmp_path)
    with SnapshotStore.open(train) as s:
        template = fit_from_store(s, pod=POD(n_modes=3), kriging=OrdinaryKriging(variogram="power"), output="field")
        U0 = s.parameters(physical=False)
    save_surrogate(template, file)
    scores = []
    monkeypatch.setattr(refine, "select_batch", lambda U, score, *rest: scores.append(score) or select_batch(U, score, *rest))
    out, sur = _refine(file, train, held, target_error=1e-12, budget=2, batch=2, n_candidates=32, rng=5,
                           sampling="random")
    assert out["added"] == 2
    U_cand = sample("random", 32, 2, 5 + 1)
    _, std = template.predict_unit(U_cand, return_std=True)
    assert len(scores) == 1
    assert_allclose(scores[0], np.sum(std**2, axis=1), rtol=1e-9)  # the total predictive variance, mm²
    pick = select_batch(U_cand, np.sum(std**2, axis=1), U0, 2)
    with SnapshotStore.open(train) as s:
        assert_allclose(s.parameters(physical=False)[8:], U_cand[pick], rtol=0, atol=1e-12)
    assert sur.kriging_.hyperparameters_.variogram == "power" and sur.pod_.n_modes_ == 3
    assert sur.provenance_["output"] == "field"
    assert sur.predict_unit(U0[:1]).shape == template.predict_unit(U0[:1]).shape


def test_a_zero_budget_only_reports_the_current_error(stores, tmp_path):
    """budget = 0 is allowed: one fit, its held-out error in the history, no FE run."""
    file, train, held = _copies(stores, tmp_path)
    out, sur = _refine(file, train, held, target_error=1e-12, budget=0, batch=1, n_candidates=1)
    assert out["added"] == 0 and out["stop_reason"] == "budget of 0 FE runs used" and len(out["history"]) == 1


def test_failed_new_runs_are_kept_as_failed_rows_and_left_out_of_the_fit(stores, tmp_path, monkeypatch, caplog):
    """Every new FE run fails: the rows stay in the store as failed, the warning counts them, and
    the next fit (and the spacing of the next batch) uses the 8 finished rows only."""

    def failing(self, params=None, *, field=False):
        raise SolverError("singular stiffness (test)")

    file, train, held = _copies(stores, tmp_path)
    monkeypatch.setattr(Scenario, "run", failing)
    with caplog.at_level(logging.WARNING, logger="podkrig.surrogate.refine"):
        out, sur = _refine(file, train, held, target_error=1e-12, budget=2, batch=2, n_candidates=32)
    assert [h["n_train"] for h in out["history"]] == [8, 8] and out["added"] == 2
    (warning,) = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert warning.name == "podkrig.surrogate.refine" and warning.args[:2] == (2, 2)  # failed, new runs
    with SnapshotStore.open(train) as s:
        assert s.counts()["failed"] == 2 and s.counts()["done"] == 8


def test_library_defaults_are_the_commands_defaults():
    """One definition of the defaults, :class:`RefineSettings`: ``refine_surrogate``'s keywords
    default to None (its settings' defaults) and ``podkrig surrogate refine``'s options show the
    same values, so a Python user and a command-line user get the same refinement."""
    command = typer.main.get_command(app).commands["surrogate"].commands["refine"]
    cli = {p.name: getattr(p.default, "value", p.default) for p in command.params}
    library = {k: p.default for k, p in inspect.signature(refine_surrogate).parameters.items()
               if p.default is not inspect.Parameter.empty}
    option = {"n_candidates": "candidates", "rng": "seed"}
    field = {"rng": "seed"}
    assert set(library) == {"target_error", "budget", "batch", "n_candidates", "rng", "workers", "sampling"}
    assert all(v is None for v in library.values()), library
    defaults = {k: f["default"] for k, f in field_info(RefineSettings).items()}
    assert {k: cli[option.get(k, k)] for k in library} == {k: defaults[field.get(k, k)] for k in library}
