"""``podkrig snapshots run | info | export`` through typer's CliRunner, and a SIGKILLed job resumed."""

import csv
import json
import subprocess
import sys
import time

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from typer.testing import CliRunner

from conftest import done_rows
from podkrig.cli import app
from podkrig.offline.store import SnapshotStore

COARSE = {"scenario": "diagonal_compression", "nx": 2, "ny": 1}
PARAMS = ["--param", "kN_bj=10:1000:log", "--param", "E_b=5000:20000"]

runner = CliRunner()


@pytest.fixture
def spec_file(tmp_path):
    path = tmp_path / "coarse.json"
    path.write_text(json.dumps(COARSE))
    return path


def _run_args(spec_file, store, n=16, seed=5, *extra):
    return ["snapshots", "run", "--spec", str(spec_file), *PARAMS, "--n", str(n), "--seed", str(seed),
            "--store", str(store), "--workers", "1", *extra]


def test_help():
    for cmd in (["snapshots", "--help"], ["snapshots", "run", "--help"], ["snapshots", "info", "--help"],
                ["snapshots", "export", "--help"]):
        result = runner.invoke(app, cmd)
        assert result.exit_code == 0, result.output
        assert "Usage" in result.output


def test_run_info_export(tmp_path, spec_file):
    store = tmp_path / "s.h5"
    result = runner.invoke(app, _run_args(spec_file, store))
    assert result.exit_code == 0, result.output
    last = result.stdout.strip().splitlines()[-1]
    assert last.startswith(f"created {store}: 16 done, 0 failed, 0 pending of 16 rows; ran 16 in ")
    assert "snapshots/s, serial)" in last

    result = runner.invoke(app, ["snapshots", "info", str(store)])
    assert result.exit_code == 0, result.output
    for text in ("16: 16 done, 0 failed, 0 pending", "design       sobol, seed 5", "kN_bj      10 .. 1000 N/mm³  (log)",
                 "load levels  25, 50, 75, 100 kN", "D1 ", "content      sha256:", "created      "):
        assert text in result.stdout
    info = json.loads(runner.invoke(app, ["snapshots", "info", str(store), "--format", "json"]).stdout)
    assert info["rows"]["done"] == 16 and info["scenario_spec"]["nx"] == 2

    out = tmp_path / "s.csv"
    result = runner.invoke(app, ["snapshots", "export", str(store), "--csv", str(out)])
    assert result.exit_code == 0, result.output
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    assert header[:4] == ["row", "status", "kN_bj", "E_b"]
    assert header[4:7] == ["D1@25", "D2@25", "U1@25"] and header[-1] == "HJ_H@100" and len(header) == 4 + 24
    assert [r[0] for r in rows[1:]] == [str(i) for i in range(16)] and {r[1] for r in rows[1:]} == {"done"}
    with SnapshotStore.open(store) as s:
        assert_array_equal(np.array([r[2:4] for r in rows[1:]], dtype=float), s.parameters())
        assert_array_equal(np.array([r[4:] for r in rows[1:]], dtype=float), s.snapshot_matrix())


@pytest.mark.parametrize(
    "param, message",
    [
        ("kN_bj=10", ("--param 'kN_bj=10'", "NAME=LOW:HIGH")),
        ("kN_bj=10:abc", ("--param 'kN_bj=10:abc'", "'abc'")),
        ("kN_bj=10:100:sqrt", ("--param 'kN_bj=10:100:sqrt'", "'sqrt'")),
        ("kN_bx=10:100", ("'kN_bx'", "'diagonal_compression'")),
        ("nu_b=0.1:0.7", ("'nu_b' = 0.7", "physical range")),
    ],
)
def test_bad_param_is_named(tmp_path, spec_file, param, message):
    """The CLI's smoke test of a bad --param: exit code 2, an error naming the option and value."""
    store = tmp_path / "s.h5"
    args = _run_args(spec_file, store)
    args[args.index("kN_bj=10:1000:log")] = param
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    assert "error: " in result.stderr and all(fragment in result.stderr for fragment in message), result.stderr
    assert not store.exists()


def test_mismatched_rerun_and_option_errors(tmp_path, spec_file):
    store = tmp_path / "s.h5"
    assert runner.invoke(app, _run_args(spec_file, store, 8, 5)).exit_code == 0
    before = store.read_bytes()
    result = runner.invoke(app, _run_args(spec_file, store, 8, 6))
    assert result.exit_code == 2
    assert "other arguments" in result.stderr and "seed: 5 (store) vs 6 (now)" in result.stderr
    result = runner.invoke(app, _run_args(spec_file, store, 8, 5, "--scheduler", "tcp://localhost:1"))
    assert result.exit_code == 2 and "either --workers" in result.stderr
    result = runner.invoke(app, ["snapshots", "run", *PARAMS, "--n", "8", "--seed", "5", "--store", str(store)])
    assert result.exit_code == 2 and "--scenario NAME or --spec FILE" in result.stderr
    result = runner.invoke(app, _run_args(spec_file, store, 8, 5, "--scenario", "shear_box"))
    assert result.exit_code == 2 and "'diagonal_compression', not --scenario 'shear_box'" in result.stderr
    assert store.read_bytes() == before


def test_corrupt_store_is_refused_by_every_command(tmp_path, spec_file):
    store = tmp_path / "s.h5"
    store.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(100))  # HDF5 signature, then nothing usable
    before = store.read_bytes()
    for args in (_run_args(spec_file, store), ["snapshots", "info", str(store)],
                 ["snapshots", "export", str(store), "--csv", str(tmp_path / "x.csv")]):
        result = runner.invoke(app, args)
        assert result.exit_code == 2
        assert "truncated or corrupt HDF5 file" in result.stderr and "left untouched" in result.stderr
    assert store.read_bytes() == before
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.slow
def test_sigkilled_job_resumes_to_the_uninterrupted_store(tmp_path, spec_file):
    n = 1024
    args = _run_args(spec_file, tmp_path / "killed.h5", n, 9, "--chunk-size", "4")
    job = subprocess.Popen([sys.executable, "-c", "from podkrig.cli import app; app(prog_name='podkrig')", *args],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while done_rows(tmp_path / "killed.h5") < 40:
            assert job.poll() is None, "the job ended before it could be killed"
            assert time.monotonic() < deadline, "the job wrote no rows within 60 s"
            time.sleep(0.01)
        job.kill()  # SIGKILL: no cleanup, no flush, no close
    finally:
        job.kill()
        job.wait()
    with SnapshotStore.open(tmp_path / "killed.h5") as store:
        counts = store.counts()
        done_before = store.done_mask()
        readings_before = store.readings(only_done=False)
    assert 40 <= counts["done"] < n and counts["failed"] == 0

    result = runner.invoke(app, args)  # the same command again
    assert result.exit_code == 0, result.output
    assert f"resumed {tmp_path / 'killed.h5'}" in result.stdout and f"{n} done, 0 failed" in result.stdout
    assert runner.invoke(app, _run_args(spec_file, tmp_path / "whole.h5", n, 9, "--chunk-size", "32")).exit_code == 0

    with SnapshotStore.open(tmp_path / "killed.h5") as a, SnapshotStore.open(tmp_path / "whole.h5") as b:
        assert_array_equal(a.status(), b.status())
        assert_array_equal(a.parameters(physical=False, only_done=False), b.parameters(physical=False, only_done=False))
        assert_array_equal(a.parameters(only_done=False), b.parameters(only_done=False))
        # Rows finished before the kill are never rewritten: bitwise what the killed job wrote.
        assert_array_equal(a.readings(only_done=False)[done_before], readings_before[done_before])
        # Rows computed in another process agree to round-off, not always bitwise: MKL PARDISO picks
        # its kernels per process (CPU dispatch, memory alignment) unless its conditional numerical
        # reproducibility mode is on, and a CI run once differed by 8.5e-16 mm (rtol 4.4e-13) here.
        ra, rb = a.readings(only_done=False), b.readings(only_done=False)
        np.testing.assert_allclose(ra, rb, rtol=1e-11, atol=1e-14)
        # the content hash is exact: equal precisely when the finished values are bitwise equal
        assert (a.content_hash() == b.content_hash()) == np.array_equal(ra, rb)


def test_failed_rows_are_reported_and_retried(tmp_path, spec_file, monkeypatch):
    from fe.exceptions import SolverError
    from fe.scenarios import Scenario

    store = tmp_path / "s.h5"
    original = Scenario.run

    def flaky(self, params=None, *, field=False):
        if params["E_b"] > 15000:
            raise SolverError("singular stiffness (test)")
        return original(self, params, field=field)

    monkeypatch.setattr(Scenario, "run", flaky)
    result = runner.invoke(app, _run_args(spec_file, store))
    assert result.exit_code == 0, result.output
    with SnapshotStore.open(store) as s:
        failed = int(s.failed_mask().sum())
    assert 0 < failed < 16
    assert f"{16 - failed} done, {failed} failed" in result.stdout and "of 16 rows" in result.stdout
    assert f"{failed} rows failed" in result.stderr and "--retry-failed" in result.stderr
    info = runner.invoke(app, ["snapshots", "info", str(store)]).stdout
    assert "SolverError: singular stiffness (test)" in info

    monkeypatch.setattr(Scenario, "run", original)
    result = runner.invoke(app, _run_args(spec_file, store, 16, 5, "--retry-failed"))
    assert result.exit_code == 0, result.output
    assert "16 done, 0 failed" in result.stdout and f"ran {failed} in" in result.stdout

