"""Offline runner: resume after interruption, Sobol' growth, refused reruns, failed rows, Dask."""

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from fe.exceptions import SolverError
from fe.scenarios import Scenario, build_scenario
from podkrig.exceptions import StoreError
from podkrig.offline import runner
from podkrig.offline.runner import prepare_store, run_pending, run_snapshots
from podkrig.offline.store import DONE, FAILED, PENDING, SnapshotStore
from podkrig.parameters import ParameterSpace

COARSE = {"scenario": "diagonal_compression", "nx": 2, "ny": 1}


@pytest.fixture(scope="module")
def scenario(coarse_diagonal):
    return coarse_diagonal


@pytest.fixture(scope="module")
def space(scenario):
    return ParameterSpace.from_scenario(scenario, {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000), "r_hj": (0.2, 1)})


def _content(path):
    with SnapshotStore.open(path) as store:
        return (store.status(), store.parameters(only_done=False), store.readings(only_done=False),
                store.content_hash())


def _assert_same_store(a, b, same_process=True):
    """The stores hold the same rows. Computed in this process: bitwise. Computed in worker
    processes: statuses and parameters bitwise, readings to round-off -- the sparse solver may pick
    other kernels per process (CPU dispatch, memory alignment; a CI run once differed by 8.5e-16 mm,
    rtol 4.4e-13), so 1e-11 relative; the content hash then is equal exactly when the readings are
    bitwise equal."""
    (sa, pa, ra, ha), (sb, pb, rb, hb) = _content(a), _content(b)
    assert_array_equal(sa, sb)
    assert_array_equal(pa, pb)
    if same_process:
        assert_array_equal(ra, rb)
        assert ha == hb
    else:
        np.testing.assert_allclose(ra, rb, rtol=1e-11, atol=1e-14)
        assert (ha == hb) == np.array_equal(ra, rb)


@pytest.fixture(scope="module")
def reference(tmp_path_factory, scenario, space):
    """An uninterrupted serial run of 64 rows."""
    path = tmp_path_factory.mktemp("ref") / "ref.h5"
    summary = run_snapshots(path, scenario, space, n=64, seed=7, workers=1)
    assert (summary.action, summary.done, summary.ran, summary.executor) == ("created", 64, 64, "serial")
    return path


def test_readings_match_direct_runs(reference, scenario):
    with SnapshotStore.open(reference) as store:
        X = store.parameters()
        for i in (0, 17, 63):
            assert_array_equal(store.readings()[i], scenario.run(store.space.as_params(X[i])).readings)


@pytest.mark.parametrize("seconds, written", [(0.0, list(range(1, 17))), (1e9, [1, 5, 9, 13, 16])])
def test_serial_chunks_hold_the_rows_that_take_the_write_interval(tmp_path, scenario, space, monkeypatch, seconds,
                                                                 written):
    """A serial run writes its first row alone, then chunks of the rows that take
    ``SERIAL_WRITE_SECONDS``: at 0 s (every FE run slower than the interval, a nonlinear wall) each
    row is written as it finishes, so an interruption loses at most the run in progress; at a huge
    interval (FE runs of milliseconds) the chunks grow to the cap, ceil(16 / 4) = 4 rows."""
    monkeypatch.setattr(runner, "SERIAL_WRITE_SECONDS", seconds)
    calls = []
    run_snapshots(tmp_path / "s.h5", scenario, space, n=16, seed=7, workers=1,
                  progress=lambda completed, total: calls.append(completed))
    assert calls == written


def test_interrupted_run_resumes_to_the_same_store(tmp_path, reference, scenario, space):
    path = tmp_path / "s.h5"
    calls = []

    def interrupt(completed, total):
        calls.append((completed, total))
        if len(calls) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_snapshots(path, scenario, space, n=64, seed=7, workers=1, chunk_size=8, progress=interrupt)
    with SnapshotStore.open(path) as store:
        assert store.counts() == {"total": 64, "done": 16, "failed": 0, "pending": 48}
        first = store.readings(only_done=False)[:16]
    summary = run_snapshots(path, COARSE, space, n=64, seed=7, workers=1, chunk_size=8)
    assert (summary.action, summary.ran, summary.done) == ("resumed", 48, 64)
    _assert_same_store(path, reference)
    with SnapshotStore.open(path) as store:
        assert_array_equal(store.readings(only_done=False)[:16], first)
    again = run_snapshots(path, scenario, space, n=64, seed=7, workers=1)
    assert again.ran == 0 and again.done == 64  # nothing to do, nothing rewritten
    _assert_same_store(path, reference)


def test_growing_a_sobol_store_continues_the_sequence(tmp_path, reference, scenario, space):
    path = tmp_path / "s.h5"
    run_snapshots(path, scenario, space, n=16, seed=7, workers=1)
    first = _content(path)
    summary = run_snapshots(path, scenario, space, n=64, seed=7, workers=1)
    assert (summary.action, summary.ran, summary.total) == ("extended", 48, 64)
    _assert_same_store(path, reference)  # rows 16..63 are those of one 64-point design
    with SnapshotStore.open(path) as store:
        assert store.history[-1]["source"] == "sobol, seed 7, points 16..63"
    with SnapshotStore.open(path) as store:
        assert_array_equal(store.readings(only_done=False)[:16], first[2])


@pytest.mark.parametrize(
    "change, message",
    [
        ({"seed": 8}, r"seed: 7 \(store\) vs 8 \(now\)"),
        ({"sampling": "lhs"}, r"sampling: 'sobol' \(store\) vs 'lhs' \(now\)"),
        ({"fields": True}, r"fields: False \(store\) vs True \(now\)"),
        ({"n": 32}, r"n: the store has 64 rows, n=32 asks for fewer"),
        ({"space": {"kN_bj": (10, 2000, "log"), "E_b": (5000, 20000), "r_hj": (0.2, 1)}},
         r"parameter 'kN_bj': 10:1000:log N/mm³ \(store\) vs 10:2000:log N/mm³ \(now\)"),
        ({"space": {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000)}},
         r"free parameters: \['kN_bj', 'E_b', 'r_hj'\] \(store\) vs \['kN_bj', 'E_b'\] \(now\)"),
        ({"spec": dict(COARSE, ny=2)}, r"scenario spec 'ny': 1 \(store\) vs 2 \(now\)"),
        ({"spec": dict(COARSE, parameters={"nu_b": 0.2})},
         r"scenario spec 'parameters': \{\} \(store\) vs \{'nu_b': 0.2\} \(now\)"),
    ],
)
def test_mismatched_rerun_is_refused(reference, scenario, space, change, message):
    before = reference.read_bytes()
    kwargs = {"n": 64, "seed": 7, "sampling": "sobol", "fields": False}
    kwargs.update({k: v for k, v in change.items() if k in kwargs})
    spec = build_scenario(change["spec"]) if "spec" in change else scenario
    sp = ParameterSpace.from_scenario(scenario, change["space"]) if "space" in change else space
    with pytest.raises(StoreError, match="was written with other arguments: " + message):
        run_snapshots(reference, spec, sp, workers=1, **kwargs)
    assert reference.read_bytes() == before


def test_non_sobol_store_cannot_grow(tmp_path, scenario, space):
    path = tmp_path / "lhs.h5"
    prepare_store(path, scenario, space, n=8, seed=1, sampling="lhs")
    with pytest.raises(StoreError, match=r"only a 'sobol' store can grow.*'lhs'"):
        prepare_store(path, scenario, space, n=16, seed=1, sampling="lhs")


def test_failed_fe_runs_become_failed_rows_and_can_be_retried(tmp_path, monkeypatch, scenario, space):
    path = tmp_path / "s.h5"
    original = Scenario.run

    def flaky(self, params=None, *, field=False):
        if params["kN_bj"] > 300:
            raise SolverError("stiffness matrix is singular (test)")
        return original(self, params, field=field)

    monkeypatch.setattr(Scenario, "run", flaky)
    summary = run_snapshots(path, scenario, space, n=32, seed=2, workers=1)
    with SnapshotStore.open(path) as store:
        X = store.parameters(only_done=False)
        expected_failed = np.flatnonzero(X[:, 0] > 300)
        assert 0 < len(expected_failed) < 32
        assert_array_equal(np.flatnonzero(store.failed_mask()), expected_failed)
        assert store.errors()[int(expected_failed[0])] == "SolverError: stiffness matrix is singular (test)"
        assert np.isnan(store.readings(only_done=False)[expected_failed]).all()
    assert (summary.failed, summary.failed_now, summary.done) == (len(expected_failed),) * 2 + (32 - len(expected_failed),)

    monkeypatch.setattr(Scenario, "run", original)
    assert run_snapshots(path, scenario, space, n=32, seed=2, workers=1).ran == 0  # failed rows stay failed
    summary = run_snapshots(path, scenario, space, n=32, seed=2, workers=1, retry_failed=True)
    assert (summary.ran, summary.done, summary.failed) == (len(expected_failed), 32, 0)
    with SnapshotStore.open(path) as store:
        assert store.errors() == {}
        for i in expected_failed[:3]:
            assert_array_equal(store.readings(only_done=False)[i], scenario.run(store.space.as_params(X[i])).readings)


def test_argument_errors(tmp_path, scenario, space):
    with pytest.raises(ValueError, match="either workers .* or scheduler"):
        run_snapshots(tmp_path / "s.h5", scenario, space, n=4, seed=0, workers=2, scheduler="tcp://x:1")
    with pytest.raises(ValueError, match="chunk_size .*>= 1; got 0"):
        run_snapshots(tmp_path / "s.h5", scenario, space, n=4, seed=0, workers=1, chunk_size=0)
    with pytest.raises(ValueError, match="n must be .*>= 1; got 0"):
        run_snapshots(tmp_path / "t.h5", scenario, space, n=0, seed=0, workers=1)
    with pytest.raises(StoreError, match="no snapshot store at"):
        run_pending(tmp_path / "missing.h5", workers=1)


def test_a_small_job_runs_serially_with_workers_2_and_says_why(tmp_path, reference, scenario, space, monkeypatch):
    """64 coarse runs (≈ 7 ms each) save far less than a local cluster takes to start: the runner
    runs them in this process (no cluster is started) and the executor text gives the numbers."""
    def no_cluster(*args):
        raise AssertionError("a local cluster was started for a small job")

    monkeypatch.setattr(runner, "_dask_client", no_cluster)
    monkeypatch.setattr(runner, "SERIAL_REASON_MIN_SAVING_S", 0.0)  # say why however small the saving
    path = tmp_path / "small.h5"
    summary = run_snapshots(path, COARSE, space, n=64, seed=7, workers=2)
    assert summary.executor.startswith("serial: 2 workers asked, but 64 runs ×"), summary.executor
    assert "local cluster" in summary.executor  # why: the cluster's start-up
    assert summary.done == 64 and summary.ran == 64
    _assert_same_store(path, reference)


def test_a_job_too_small_for_its_reason_to_matter_runs_serially_without_a_word(tmp_path, space, monkeypatch):
    """4 coarse runs would save milliseconds on a cluster ("4 runs × 0 ms per run would save 0.0 s"
    before every small stage): plain "serial", no reason for the stage's notes."""
    monkeypatch.setattr(runner, "_dask_client", lambda *args: pytest.fail("a local cluster was started"))
    summary = run_snapshots(tmp_path / "tiny.h5", COARSE, space, n=4, seed=7, workers=2)
    assert summary.executor == "serial" and summary.done == 4


@pytest.mark.slow
def test_two_local_dask_workers_give_the_serial_store(tmp_path, reference, scenario, space, monkeypatch):
    monkeypatch.setattr(runner, "LOCAL_CLUSTER_STARTUP_S", 0.0)  # use the cluster however small the job
    path = tmp_path / "dask.h5"
    summary = run_snapshots(path, COARSE, space, n=64, seed=7, workers=2, chunk_size=4)
    assert summary.executor == "local Dask cluster, 2 workers" and summary.done == 64
    _assert_same_store(path, reference, same_process=False)


@pytest.mark.slow
def test_existing_scheduler_resumes_a_serial_store(tmp_path, reference, scenario, space):
    """A partial serial store finished on an existing cluster (a worker with two threads)."""
    from distributed import LocalCluster

    path = tmp_path / "s.h5"
    prepare_store(path, scenario, space, n=64, seed=7)
    with SnapshotStore.open(path, "r+") as store:  # rows 0..9 done serially, as by an earlier job
        rows = np.arange(10)
        X = store.parameters(only_done=False)[rows]
        R = np.stack([scenario.run(space.as_params(x)).readings for x in X])
        store.write_results(rows, [DONE] * 10, R, [""] * 10, np.zeros(10))
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True, dashboard_address=None) as cluster:
        summary = run_snapshots(path, scenario, space, n=64, seed=7, scheduler=cluster.scheduler_address, chunk_size=3)
    assert summary.executor.startswith("Dask scheduler tcp://") and summary.ran == 54
    _assert_same_store(path, reference, same_process=False)
    with SnapshotStore.open(path) as store:
        assert not np.isin(store.status(), (PENDING, FAILED)).any()


def test_fields_are_stored(tmp_path, scenario, space):
    path = tmp_path / "f.h5"
    summary = run_snapshots(path, scenario, space, n=4, seed=3, fields=True, workers=1)
    assert summary.done == 4
    with SnapshotStore.open(path) as store:
        F = store.fields()
        assert F.shape == (4, 4, scenario.mesh.n_nodes, 2)
        x = store.parameters()[1]
        assert_array_equal(F[1], scenario.run(space.as_params(x), field=True).field)
    run_snapshots(path, scenario, space, n=8, seed=3, fields=True, workers=1)  # grow keeps the fields
    with SnapshotStore.open(path) as store:
        assert_array_equal(store.fields()[:4], F)


def test_benchmark_script_imports_cleanly_and_has_help():
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).parents[1] / "scripts" / "bench_offline.py"
    result = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True, timeout=60,
                            check=False)
    assert result.returncode == 0, result.stderr
    assert "--n N" in result.stdout and "snapshots per measurement" in result.stdout


def test_importing_distributed_keeps_project_warnings_and_quiets_dask(caplog):
    """A dict-schema logging config (what importing ``distributed`` applies when the Dask config
    has ``logging: {version: 1}``) disables every logger that exists; after
    :func:`runner.import_distributed` podkrig's warnings are recorded again, and Dask's loggers are
    at WARNING unless podkrig logs at DEBUG."""
    import logging.config

    ours = logging.getLogger("podkrig.offline.runner")
    dask_logger = logging.getLogger("distributed")
    level = dask_logger.level
    loggers = [lg for lg in logging.root.manager.loggerDict.values() if isinstance(lg, logging.Logger)]
    was_disabled = [lg.disabled for lg in loggers]
    try:
        logging.config.dictConfig({"version": 1})  # disable_existing_loggers defaults to True
        assert ours.disabled
        runner.import_distributed()
        assert not ours.disabled
        with caplog.at_level(logging.WARNING, logger="podkrig"):
            ours.warning("still heard")
        assert "still heard" in caplog.text
        dask_logger.setLevel(logging.INFO)
        runner.import_distributed()
        assert dask_logger.level == logging.WARNING  # podkrig at WARNING: Dask quiet
        dask_logger.setLevel(logging.INFO)
        logging.getLogger("podkrig").setLevel(logging.DEBUG)  # --verbose
        runner.import_distributed()
        assert dask_logger.level == logging.INFO
    finally:
        logging.getLogger("podkrig").setLevel(logging.NOTSET)
        dask_logger.setLevel(level)
        for lg, disabled in zip(loggers, was_disabled):  # other libraries' loggers as they were
            lg.disabled = disabled
