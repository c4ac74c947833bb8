"""Stores that cannot be lost or lied to (issue 13, findings 2-4): exclusive creation and a writer
lock, full disks, per-row checksums verified on read and by ``podkrig snapshots verify``, old
stores without checksums, leftovers of an interrupted creation."""

import errno
import json
import logging
import os
import shutil
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
from numpy.testing import assert_array_equal
from typer.testing import CliRunner

from podkrig.cli import app
from podkrig.exceptions import IntegrityError, StoreError, StoreInUseError
from podkrig.offline import store as store_module
from podkrig.offline.files import acquire_lock, lock_path, release_lock
from podkrig.offline.runner import measured_run_seconds, run_snapshots
from podkrig.offline.sampling import sobol
from podkrig.offline.store import DONE, FAILED, SnapshotStore
from podkrig.parameters import ParameterSpace

COARSE = {"scenario": "diagonal_compression", "nx": 2, "ny": 1}
runner = CliRunner()


@pytest.fixture(scope="module")
def scenario(coarse_diagonal):
    return coarse_diagonal


@pytest.fixture(scope="module")
def space(scenario):
    return ParameterSpace.from_scenario(scenario, {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000)})


def _make(path, scenario, space, n=8, fields=False):
    return SnapshotStore.create(path, scenario, space, sobol(n, space.n_params, seed=3), sampling="sobol",
                                seed=3, fields=fields)


def _filled(path, scenario, space, n=8, fields=False):
    """A store whose rows are all done with synthetic readings (no FE runs)."""
    rng = np.random.default_rng(1)
    with _make(path, scenario, space, n, fields) as store:
        rows = np.arange(n)
        f = rng.normal(size=(n, store.n_loads, store.n_nodes, 2)) if fields else None
        store.write_results(rows, np.full(n, DONE), rng.normal(size=(n, store.n_loads, store.n_sensors)),
                            [""] * n, np.full(n, 0.01), f)
    return path


def _holder(code):
    """A subprocess running ``code`` that prints 'ready' and then sleeps until killed."""
    job = subprocess.Popen([sys.executable, "-c", code + "\nprint('ready', flush=True)\nimport time; time.sleep(120)"],
                           stdout=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONPATH=os.getcwd()))
    assert job.stdout.readline().strip() == "ready"
    return job


# ----------------------------------------------------------------------------- finding 2: creation race
def test_creation_never_replaces_a_file_that_appeared_meanwhile(tmp_path, scenario, space, monkeypatch):
    """Finding 2: another writer's store appearing between the existence check and the rename."""
    path = tmp_path / "s.h5"
    write_layout = store_module._write_layout

    def racing_layout(*args, **kwargs):
        write_layout(*args, **kwargs)
        path.write_bytes(b"the other writer's store")  # it finished first

    monkeypatch.setattr(store_module, "_write_layout", racing_layout)
    with pytest.raises(StoreError, match="already exists.*never overwritten"):
        _make(path, scenario, space)
    assert path.read_bytes() == b"the other writer's store"
    assert not list(tmp_path.glob(".s.h5.tmp-*"))


def test_second_writer_gets_the_pid_and_changes_nothing(tmp_path, scenario, space):
    path = tmp_path / "s.h5"
    job = _holder(f"from podkrig.offline.files import acquire_lock; acquire_lock({str(path)!r})")
    try:
        with pytest.raises(StoreInUseError, match=rf"in use by PID {job.pid} on .*nothing was changed"):
            _make(path, scenario, space)
        assert not path.exists()
        _filled(tmp_path / "t.h5", scenario, space)
    finally:
        job.kill()
        job.wait()
        job.stdout.close()
    _make(path, scenario, space).close()  # the lock died with its process: no stale lock
    assert not lock_path(path).exists()


def test_two_runs_on_one_store(tmp_path):
    """Two `snapshots run` on one new store: the second is refused, the first completes untouched."""
    spec = tmp_path / "coarse.json"
    spec.write_text(json.dumps(COARSE))
    store = tmp_path / "s.h5"
    args = ["snapshots", "run", "--spec", str(spec), "--param", "kN_bj=10:1000:log", "--n", "256", "--seed", "1",
            "--store", str(store), "--workers", "1", "--chunk-size", "4"]
    first = subprocess.Popen([sys.executable, "-c", "from podkrig.cli import app; app(prog_name='podkrig')", *args],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not store.exists():
            assert first.poll() is None and time.monotonic() < deadline
            time.sleep(0.01)
        second = runner.invoke(app, args)
        assert second.exit_code == 2
        assert f"in use by PID {first.pid}" in second.output
        out, err = first.communicate(timeout=300)
    finally:
        first.kill()
        first.wait()
    assert first.returncode == 0, err
    assert "created" in out and "256 done, 0 failed, 0 pending" in out
    with SnapshotStore.open(store) as s:
        assert s.verify().ok and s.counts()["done"] == 256


def test_orphan_temporary_files_are_removed(tmp_path, scenario, space):
    path = tmp_path / "s.h5"
    orphan = tmp_path / ".s.h5.tmp-999999"
    orphan.write_bytes(b"half a store")
    other = tmp_path / ".other.h5.tmp-999999"
    other.write_bytes(b"not ours")
    _make(path, scenario, space).close()
    assert not orphan.exists() and other.exists()


# ----------------------------------------------------------------------------- finding 3: full disk
def test_write_error_propagates_and_a_rerun_completes(tmp_path, scenario, space, monkeypatch):
    """Finding 3 (injected): an HDF5 write error stops the run, rows stay pending, a rerun completes."""
    ref = tmp_path / "ref.h5"
    run_snapshots(ref, scenario, space, n=32, seed=2, workers=1, chunk_size=4)
    path = tmp_path / "s.h5"
    real = h5py.Dataset.__setitem__
    writes = {"n": 0}

    def failing(self, key, value):
        if self.name == "/readings":
            writes["n"] += 1
            if writes["n"] > 3:
                raise OSError(errno.ENOSPC, "No space left on device")
        real(self, key, value)

    monkeypatch.setattr(h5py.Dataset, "__setitem__", failing)
    with pytest.raises(StoreError, match=r"disk full: 12 rows written.*rerun the same command"):
        run_snapshots(path, scenario, space, n=32, seed=2, workers=1, chunk_size=4)
    monkeypatch.setattr(h5py.Dataset, "__setitem__", real)
    with SnapshotStore.open(path) as s:
        assert s.counts() == {"total": 32, "done": 12, "failed": 0, "pending": 20}
    assert not lock_path(path).exists()
    run_snapshots(path, scenario, space, n=32, seed=2, workers=1, chunk_size=4)
    with SnapshotStore.open(path) as a, SnapshotStore.open(ref) as b:
        assert a.verify().ok
        assert_array_equal(a.status(), b.status())
        assert_array_equal(a.readings(only_done=False), b.readings(only_done=False))


@pytest.fixture
def tiny_fs(tmp_path):
    """A 2 MiB tmpfs (needs root; skipped where mounting is not permitted)."""
    mnt = tmp_path / "tmpfs"
    mnt.mkdir()
    if shutil.which("mount") is None:
        pytest.skip("no mount command")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mnt)], capture_output=True, check=False)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode(errors='replace').strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


@pytest.mark.slow
def test_full_disk_with_fields_on_a_small_filesystem(tmp_path, tiny_fs):
    """Finding 3 (real): `snapshots run --fields` on a 2 MiB file system stops with a message, keeps
    its rows, and completes after the file system grows; every field matches an uncut run."""
    spec = tmp_path / "coarse.json"
    spec.write_text(json.dumps(COARSE))

    def args(store):
        return ["snapshots", "run", "--spec", str(spec), "--param", "kN_bj=10:1000:log", "--n", "64", "--seed",
                "4", "--store", str(store), "--workers", "1", "--chunk-size", "4", "--fields"]

    cli = [sys.executable, "-c", "from podkrig.cli import app; app(prog_name='podkrig')"]
    full = subprocess.run(cli + args(tiny_fs / "s.h5"), capture_output=True, text=True, timeout=600, check=False)
    assert full.returncode == 2, full.stderr  # a message, not a crash (a segfault is -11)
    assert "disk full" in full.stderr and "rows written and kept" in full.stderr
    assert "Traceback" not in full.stderr
    with SnapshotStore.open(tiny_fs / "s.h5") as s:
        written = s.counts()["done"]
        assert 0 < written < 64 and s.verify().ok
    subprocess.run(["mount", "-o", "remount,size=64m", str(tiny_fs)], check=True)
    rerun = subprocess.run(cli + args(tiny_fs / "s.h5"), capture_output=True, text=True, timeout=600, check=False)
    assert rerun.returncode == 0, rerun.stderr
    assert subprocess.run(cli + args(tmp_path / "ref.h5"), capture_output=True, timeout=600, check=False).returncode == 0
    with SnapshotStore.open(tiny_fs / "s.h5") as a, SnapshotStore.open(tmp_path / "ref.h5") as b:
        assert a.verify().ok and a.counts()["done"] == 64
        assert_array_equal(a.readings(only_done=False), b.readings(only_done=False))
        assert_array_equal(a.fields(), b.fields())


# ----------------------------------------------------------------------------- finding 4: checksums
def _poke(path, dataset, index, bit=3):
    """Flip one bit of one stored value behind the store's back (as a bad disk would)."""
    with h5py.File(path, "r+") as f:
        data = f[dataset][...]
        data.view(np.uint8).reshape(data.shape[0], -1)[index] ^= np.uint8(1 << bit)
        f[dataset][...] = data


@pytest.mark.parametrize("dataset, when", [("parameters", "open"), ("unit_parameters", "read"),
                                           ("status", "open"), ("readings", "read"), ("wall_time", "read")])
def test_a_flipped_bit_is_refused_with_the_row_named(tmp_path, scenario, space, dataset, when):
    """Finding 4: one bit flip in a stored value was adopted silently."""
    path = _filled(tmp_path / "s.h5", scenario, space)
    _poke(path, dataset, (5, 1) if dataset != "status" else (5, 0), bit=0)
    message = rf"rows 5 of dataset .*{dataset}.*checksums"
    if when == "open":
        with pytest.raises(IntegrityError, match=message):
            SnapshotStore.open(path)
    else:
        with SnapshotStore.open(path) as s, pytest.raises(IntegrityError, match=message):
            {"readings": s.readings, "wall_time": s.wall_times,
             "unit_parameters": lambda: s.parameters(physical=False)}[dataset]()
    result = runner.invoke(app, ["snapshots", "verify", str(path)])
    assert result.exit_code == 1
    assert "rows 5" in result.output and dataset in result.output


def test_damaged_fields_and_metadata_are_refused(tmp_path, scenario, space):
    path = _filled(tmp_path / "s.h5", scenario, space, n=4, fields=True)
    with h5py.File(path, "r+") as f:
        row = f["fields"][2]
        row[0, 7, 1] = np.nextafter(row[0, 7, 1], np.inf)
        f["fields"][2] = row
    with SnapshotStore.open(path) as s:
        assert s.verify().bad_rows == {"fields": [2]}
        with pytest.raises(IntegrityError, match="fields of rows 2 .*match"):
            s.fields()
    path = _filled(tmp_path / "m.h5", scenario, space)
    with h5py.File(path, "r+") as f:
        f.attrs["load_levels"] = f.attrs["load_levels"] * 1.0000001
    with pytest.raises(IntegrityError, match="metadata .* does not match its checksum"):
        SnapshotStore.open(path)


def test_interrupted_write_is_resealed_by_the_next_writer(tmp_path, scenario, space):
    """A writer killed between a row's status and its checksums: readers are told, the next writer reseals."""
    path = _filled(tmp_path / "s.h5", scenario, space)
    with h5py.File(path, "r+") as f:  # the state a SIGKILL in that window leaves
        f["checksums/rows"][6, 7] = 1
        f["checksums/rows"][6, 2] ^= np.uint64(1)
    with SnapshotStore.open(path) as s:
        assert s.verify().unsealed_rows == [6]
        s.readings()
    with SnapshotStore.open(path, "r+"):
        pass
    with SnapshotStore.open(path) as s:
        report = s.verify()
        assert report.ok and report.unsealed_rows == []


def test_store_without_checksums_loads_and_can_be_rehashed(tmp_path, scenario, space, caplog):
    """A store written before checksums existed still loads, with a warning saying what to do."""
    path = _filled(tmp_path / "s.h5", scenario, space)
    with h5py.File(path, "r+") as f:
        del f["checksums"]
    with SnapshotStore.open(path) as s:
        assert not s.checksummed and s.readings().shape[0] == 8
    (record,) = [r for r in caplog.records if "checksums" in r.getMessage()]
    assert record.levelno == logging.WARNING and "--rehash" in record.getMessage()  # the remedy's option
    result = runner.invoke(app, ["snapshots", "verify", str(path)])
    assert result.exit_code == 1 and "no checksums" in result.output
    assert runner.invoke(app, ["snapshots", "verify", "--rehash", str(path)]).exit_code == 0
    result = runner.invoke(app, ["snapshots", "verify", str(path)])
    assert result.exit_code == 0 and "8 rows match their checksums" in result.output
    again = runner.invoke(app, ["snapshots", "verify", "--rehash", str(path)])
    assert again.exit_code == 2 and "never recomputed" in again.output


def test_extend_keeps_checksums(tmp_path, scenario, space):
    path = _filled(tmp_path / "s.h5", scenario, space)
    SnapshotStore.extend(path, sobol(16, 2, seed=3)[8:])
    with SnapshotStore.open(path) as s:
        assert s.n_rows == 16 and s.verify().ok and s.counts()["done"] == 8


def test_lock_is_reentrant_and_released(tmp_path):
    path = tmp_path / "s.h5"
    acquire_lock(path)
    acquire_lock(path)
    release_lock(path)
    assert lock_path(path).exists()
    release_lock(path)
    assert not lock_path(path).exists()


def test_measured_run_seconds_is_the_mean_cpu_time_of_the_runs_stored(tmp_path, scenario, space):
    """The job estimate's measured cost: failed runs count (they cost most), pending rows do not."""
    path = tmp_path / "s.h5"
    assert measured_run_seconds(path) is None  # no store yet
    with _make(path, scenario, space, n=4) as store:
        n_loads, n_sensors = store.n_loads, store.n_sensors
    assert measured_run_seconds(path) is None  # rows pending, none timed
    with SnapshotStore.open(path, mode="r+") as store:
        store.write_results(np.arange(3), np.array([DONE, DONE, FAILED]), np.zeros((3, n_loads, n_sensors)),
                            ["", "", "NotConverged: x"], np.full(3, 9.0), cpu_times=[2.0, 4.0, 30.0])
    assert measured_run_seconds(path) == pytest.approx(12.0, rel=1e-12)  # (2 + 4 + 30) / 3, float sums
    (tmp_path / "junk.h5").write_bytes(b"not a store")
    assert measured_run_seconds(tmp_path / "junk.h5") is None  # the run itself says what is wrong
