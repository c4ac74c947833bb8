"""Nonlinear scenarios through the offline runner: converged rows, runs that stop early kept as
partial rows with their status and reach, the solver settings recorded and checked on resume, the
surrogate's explicit choice about failed rows, and the failure report of the store."""

import json
import logging

import numpy as np
import pytest
from typer.testing import CliRunner

from fe.scenarios import build_scenario
from podkrig.cli import app
from podkrig.exceptions import StoreError
from podkrig.offline import runner
from podkrig.offline.failures import failure_report
from podkrig.offline.results import OfflineResult
from podkrig.offline.runner import run_snapshots
from podkrig.offline.store import DONE, FAILED, SnapshotStore
from podkrig.parameters import ParameterSpace
from podkrig.surrogate.settings import SurrogateSettings, fit_surrogate

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
        assert all(e.startswith("NotConverged (budget_exhausted: steps, reached 0.002 mm): step budget of 3")
                   for e in errors.values())
        partial = store.readings(only_done=False)
        assert np.isfinite(partial[:, 0]).all() and np.isnan(partial[:, -1]).all()


#: a couplet whose brittle joints (low GfI_bj) need more Newton iterations than a budget of 10: in
#: that part of the box the runs stop early, deterministically (an iteration count, not a time)
BUDGET = dict(SPEC, max_total_iterations=10)
BOX = {"ft_bj": (0.15, 0.4, "linear"), "GfI_bj": (0.005, 0.05, "log")}


@pytest.fixture(scope="module")
def partial_store(tmp_path_factory):
    path = tmp_path_factory.mktemp("nl") / "part.h5"
    sc = build_scenario(BUDGET)
    summary = run_snapshots(path, sc, ParameterSpace.from_scenario(sc, BOX), n=32, seed=0, workers=1)
    return path, summary


def test_part_of_the_box_stops_early_as_partial_rows_with_status_and_reach(partial_store):
    path, summary = partial_store
    assert 0 < summary.failed < summary.total and summary.pending == 0
    with SnapshotStore.open(path) as store:
        partial = store.partial_rows()
        assert sorted(partial) == sorted(store.errors())  # every failed row stopped early, none raised
        for info in partial.values():
            assert info["status"] == "budget_exhausted" and info["limit"] == "iterations" and info["unit"] == "mm"
            assert 0.002 <= info["reached"] < 0.05  # past the first level, short of the last
        rows = sorted(partial)
        readings = store.readings(only_done=False)[rows]
        assert np.isfinite(readings[:, 0]).all() and np.isnan(readings[:, -1]).all()
        assert store.info()["solver_settings"]["max_total_iterations"] == 10
        report = failure_report(store)
    assert report.reasons == {"iterations": summary.failed} and report.share == summary.failed / 32
    assert report.region is not None and report.region.driving()[0] == "GfI_bj"
    assert report.region.direction("GfI_bj") == "low"


def test_resuming_adds_nothing_twice_and_other_solver_settings_are_refused(partial_store, tmp_path):
    path, first = partial_store
    copy = tmp_path / "part.h5"
    copy.write_bytes(path.read_bytes())
    with SnapshotStore.open(copy) as store:
        before = store.content_hash(), store.errors()
    sc = build_scenario(BUDGET)
    again = run_snapshots(copy, sc, ParameterSpace.from_scenario(sc, BOX), n=32, seed=0, workers=1)
    assert again.ran == 0 and (again.done, again.failed) == (first.done, first.failed)
    with SnapshotStore.open(copy) as store:
        assert (store.content_hash(), store.errors()) == before
    other = build_scenario(dict(BUDGET, max_total_iterations=30000))
    with pytest.raises(StoreError, match="solver setting 'max_total_iterations': 10 \\(store\\) vs 30000"):
        run_snapshots(copy, other, ParameterSpace.from_scenario(other, BOX), n=32, seed=0, workers=1)


def test_the_surrogate_refuses_or_drops_failed_rows_saying_how_many_and_which(partial_store, caplog):
    path, summary = partial_store
    with SnapshotStore.open(path) as store:
        failed = sorted(store.errors())
        with pytest.raises(StoreError, match=f"{summary.failed} of 32 FE runs .*failed_rows='drop'"):
            fit_surrogate(store, SurrogateSettings(failed_rows="refuse"))
        with caplog.at_level(logging.WARNING, logger="podkrig.surrogate.settings"):
            sur = fit_surrogate(store, SurrogateSettings())
    (record,) = [r for r in caplog.records if r.name == "podkrig.surrogate.settings"]
    assert record.levelno == logging.WARNING and record.args[1:3] == (summary.failed, 32)
    assert str(failed[0]) in record.args[4]
    assert sur.provenance_["dropped_rows"] == failed and sur.provenance_["failure_region"]["names"] == ["ft_bj", "GfI_bj"]
    assert sur.provenance_["n_train"] == summary.done


def test_the_failure_report_reaches_the_offline_result_and_snapshots_info(partial_store):
    path, summary = partial_store
    result = OfflineResult.from_store(path, summary)
    assert OfflineResult.from_dict(json.loads(json.dumps(result.to_dict()))) == result
    assert result.failure.n_failed == summary.failed
    out = CliRunner().invoke(app, ["snapshots", "info", str(path)])
    assert out.exit_code == 0, out.output
    assert "towards low GfI_bj" in out.output and "iteration budget" in out.output
    assert '"max_total_iterations": 10' in out.output


@pytest.mark.slow
@pytest.mark.parametrize("executor", ["local", "scheduler"])
def test_nonlinear_rows_on_a_dask_cluster_match_the_serial_store(partial_store, tmp_path, monkeypatch, executor):
    """Two local Dask worker processes, or the workers of an existing cluster reached by its
    scheduler's address (as a remote one is), run the same nonlinear rows: the same done and
    partial rows, readings within the Newton tolerance (the same solver in another process)."""
    path, summary = partial_store
    monkeypatch.setattr(runner, "LOCAL_CLUSTER_STARTUP_S", 0.0)  # use the cluster however small the job
    sc = build_scenario(BUDGET)
    space = ParameterSpace.from_scenario(sc, BOX)
    if executor == "local":
        dask = run_snapshots(tmp_path / "d.h5", sc, space, n=32, seed=0, workers=2, chunk_size=4)
        assert dask.executor == "local Dask cluster, 2 workers"
    else:
        from distributed import LocalCluster

        with LocalCluster(n_workers=1, threads_per_worker=2, processes=True, dashboard_address=None) as cluster:
            dask = run_snapshots(tmp_path / "d.h5", sc, space, n=32, seed=0, scheduler=cluster.scheduler_address,
                                 chunk_size=4)
        assert dask.executor.startswith("Dask scheduler tcp://")
    with SnapshotStore.open(path) as serial, SnapshotStore.open(tmp_path / "d.h5") as other:
        assert np.array_equal(serial.status(), other.status())
        assert serial.partial_rows() == other.partial_rows()
        done = serial.status() == DONE
        # another process: BLAS / sparse-solver rounding, far inside the solver's 1e-3 force tolerance
        np.testing.assert_allclose(other.readings(only_done=False)[done], serial.readings(only_done=False)[done],
                                   rtol=1e-6, atol=1e-12)
        assert (serial.status() == FAILED).sum() == summary.failed


STUDY = """name = "couplet_budget"
[scenario]
scenario = "couplet_tension"
nx = 2
ny = 1
load_levels = [0.002, 0.005, 0.01, 0.02, 0.05]
increment = 0.001
max_increment = 0.01
max_total_iterations = 10
[parameters]
ft_bj = { lower = 0.15, upper = 0.4 }
GfI_bj = { lower = 0.005, upper = 0.05, scale = "log" }
[sampling]
train = { n = 32, seed = 0 }
held_out = { n = 8, seed = 1, method = "random" }
workers = 1
[measurement]
file = "couplet.csv"
noise_abs = { F = 0.05, joint_opening = 0.0005, top_uy = 0.0005 }
noise_rel = 0.01
[inversion]
seed = 0
"""


@pytest.mark.parametrize("gfi, inside", [(0.006, True), (0.04, False)])
def test_podkrig_run_reports_the_failures_and_warns_when_the_best_fit_lies_where_runs_fail(tmp_path, gfi, inside):
    """``podkrig run`` on a couplet whose iteration budget stops the brittle runs (low GfI_bj): the
    offline stage reports the failed share and its region, and the data of a specimen inside that
    region (GfI_bj = 0.006 N/mm, simulated with the full budget, as a lab would measure it) raise
    ``near-failure`` and an FE check that names the early stop; data from far outside it do not."""
    opts = {"nx": 2, "ny": 1, "load_levels": [0.002, 0.005, 0.01, 0.02, 0.05], "increment": 0.001,
            "max_increment": 0.01}
    full = build_scenario({"scenario": "couplet_tension", **opts})
    r = full.run({"ft_bj": 0.25, "GfI_bj": gfi})
    header = ",".join(["load [mm]", *(f"{n} [{'kN' if n == 'F' else 'mm'}]" for n in full.sensor_names)])
    rows = [",".join(f"{v:.6g}" for v in (level, *reading)) for level, reading in zip(full.load_levels, r.readings)]
    (tmp_path / "couplet.csv").write_text("\n".join([header, *rows]))
    (tmp_path / "couplet.toml").write_text(STUDY)
    out = CliRunner().invoke(app, ["run", str(tmp_path / "couplet.toml"), "--out", str(tmp_path / "out")])
    assert out.exit_code == 0, out.output[-3000:]
    summary = json.loads(next((tmp_path / "out").rglob("summary.json")).read_text())
    failure = summary["stages"]["offline"]["failure"]
    assert 0 < failure["n_failed"] < 32 and failure["reasons"] == {"iterations": failure["n_failed"]}
    assert "GfI_bj" in failure["region"]["names"]
    findings = {f["code"]: f["values"] for f in summary["stages"]["calibration"]["findings"]}
    assert ("near-failure" in findings) == inside
    if inside:
        assert findings["near-failure"]["probability"] >= 0.2
        assert findings["fe-check"]["stopped"].startswith("budget_exhausted: iterations, reached")
    assert summary["stages"]["surrogate"]["dropped_rows"] == failure["rows"]
    html = (tmp_path / "out" / "report" / "index.html").read_text()
    assert "failed or stopped early" in html and "Runs fail towards" in html and "left out of the fit" in html


def test_the_commands_run_a_nonlinear_spec_report_its_failures_and_refuse_or_drop_them(tmp_path):
    """``podkrig snapshots run`` with a nonlinear spec file prints the failed share and where runs
    fail; ``podkrig surrogate build --failed-rows refuse`` stops naming the count and the option,
    the default drops them and builds."""
    (tmp_path / "couplet.json").write_text(json.dumps(BUDGET))
    store = tmp_path / "c.h5"
    out = CliRunner().invoke(app, ["snapshots", "run", "--spec", str(tmp_path / "couplet.json"), "--param",
                                   "ft_bj=0.15:0.4", "--param", "GfI_bj=0.005:0.05:log", "--n", "32", "--seed", "0",
                                   "--store", str(store), "--workers", "1"])
    assert out.exit_code == 0, out.output
    with SnapshotStore.open(store) as s:
        n_failed = s.counts()["failed"]
    assert f"{n_failed} of 32 FE runs" in out.output and "towards low GfI_bj" in out.output
    out = CliRunner().invoke(app, ["surrogate", "build", str(store), "--out", str(tmp_path / "s.h5"),
                                   "--failed-rows", "refuse"])
    assert out.exit_code != 0 and f"{n_failed} of 32 FE runs" in out.output and "failed_rows='drop'" in out.output
    out = CliRunner().invoke(app, ["surrogate", "build", str(store), "--out", str(tmp_path / "s.h5")])
    assert out.exit_code == 0, out.output
    assert f"{32 - n_failed} snapshots" in out.output and f"{n_failed} failed training runs" in out.output
