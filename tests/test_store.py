"""Snapshot store: round trip, readers, write rules, and refusal of damaged or foreign files."""

import json

import h5py
import numpy as np
import pytest
from numpy.testing import assert_array_equal

from podkrig import __version__
from podkrig.exceptions import SchemaError, StoreError
from podkrig.parameters import ParameterSpace
from podkrig.offline.sampling import sobol
from podkrig.offline.store import DONE, FAILED, PENDING, SnapshotStore


@pytest.fixture(scope="module")
def scenario(coarse_diagonal):
    return coarse_diagonal


@pytest.fixture(scope="module")
def space(scenario):
    return ParameterSpace.from_scenario(scenario, {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000)})


def _make(path, scenario, space, n=8, fields=False):
    U = sobol(n, space.n_params, seed=3)
    return SnapshotStore.create(path, scenario, space, U, sampling="sobol", seed=3, fields=fields)


def _fill(store, rows, scenario, fail=()):
    X = store.parameters(only_done=False)[rows]
    R = np.stack([scenario.run(store.space.as_params(x)).readings for x in X])
    status = [FAILED if r in fail else DONE for r in rows]
    errors = ["SolverError: singular" if r in fail else "" for r in rows]
    store.write_results(rows, status, R, errors, np.full(len(rows), 0.01))
    return R


def test_round_trip_metadata(tmp_path, scenario, space):
    path = tmp_path / "s.h5"
    _make(path, scenario, space).close()
    with SnapshotStore.open(path) as store:
        assert store.spec == scenario.spec
        assert store.space == space
        assert store.sensor_names == scenario.sensor_names
        assert store.sensor_definitions == scenario.sensor_definitions()
        assert_array_equal(store.load_levels, scenario.load_levels)
        assert store.load_unit == "kN" and store.reading_unit == "mm"
        assert (store.sampling, store.seed, store.n_rows) == ("sobol", 3, 8)
        assert store.software["podkrig"] == __version__
        assert store.run_arguments == {"n": 8, "seed": 3, "sampling": "sobol", "fields": False}
        assert store.counts() == {"total": 8, "done": 0, "failed": 0, "pending": 8}
        U = sobol(8, 2, seed=3)
        assert_array_equal(store.parameters(physical=False, only_done=False), U)
        assert_array_equal(store.parameters(only_done=False), space.from_unit(U))
        assert np.isnan(store.readings(only_done=False)).all()
        assert store.snapshot_matrix().shape == (0, 24)
    with h5py.File(path) as f:  # self-describing for any HDF5 reader: plain attributes, JSON text
        assert f.attrs["format"] == "podkrig.snapshots"
        assert json.loads(f.attrs["parameter_space"]) == space.to_dict()
        assert h5py.check_enum_dtype(f["status"].dtype) == {"pending": 0, "done": 1, "failed": 2}
        assert f["readings"].attrs["unit"] == "mm"


def test_readers_after_writes(tmp_path, scenario, space):
    with _make(tmp_path / "s.h5", scenario, space) as store:
        h0 = store.content_hash()
        R = _fill(store, [5, 1, 2], scenario, fail=(2,))
        assert store.content_hash() != h0
        assert_array_equal(store.status(), [PENDING, DONE, FAILED, PENDING, PENDING, DONE, PENDING, PENDING])
        assert_array_equal(np.flatnonzero(store.done_mask()), [1, 5])
        assert store.errors() == {2: "SolverError: singular"}
        assert_array_equal(store.readings(), R[[1, 0]])  # rows 1 and 5, in row order
        assert np.isnan(store.readings(only_done=False)[2]).all()  # failed rows hold no readings
        Y = store.snapshot_matrix()
        assert Y.shape == (2, 24)
        assert_array_equal(Y[1], R[0].ravel())  # C order: all sensors at the first load, ...
        assert_array_equal(Y[1, :6], R[0][0])
        assert_array_equal(store.parameters(), store.parameters(only_done=False)[[1, 5]])
        info = store.info()
        assert info["rows"] == {"total": 8, "done": 2, "failed": 1, "pending": 5}
        assert info["failures"] == [{"row": 2, "error": "SolverError: singular"}]
        assert info["content_hash"] == store.content_hash()
        json.dumps(info)  # JSON-able


def test_content_hash_depends_on_done_values_only(tmp_path, scenario, space):
    with _make(tmp_path / "a.h5", scenario, space) as a, _make(tmp_path / "b.h5", scenario, space) as b:
        _fill(a, [0, 1], scenario)
        _fill(b, [1], scenario)
        _fill(b, [0], scenario)  # other write order, same content
        assert a.content_hash() == b.content_hash()
        _fill(b, [3], scenario, fail=(3,))  # failed rows are not content
        assert a.content_hash() == b.content_hash()


def test_finished_rows_are_never_rewritten(tmp_path, scenario, space):
    with _make(tmp_path / "s.h5", scenario, space) as store:
        _fill(store, [0, 1], scenario)
        with pytest.raises(StoreError, match=r"rows \[1\] are already done.*never rewritten"):
            _fill(store, [1, 2], scenario)
        assert store.status()[2] == PENDING  # nothing of the refused batch was written
        with pytest.raises(StoreError, match=r"distinct indices in \[0, 8\)"):
            store.write_results([8], [DONE], np.zeros((1, 4, 6)), [""], [0.0])
    with SnapshotStore.open(tmp_path / "s.h5") as store, pytest.raises(StoreError, match="read-only"):
        _fill(store, [3], scenario)


def test_fields(tmp_path, scenario, space):
    with _make(tmp_path / "f.h5", scenario, space, n=4, fields=True) as store:
        response = scenario.run(store.space.as_params(store.parameters(only_done=False)[2]), field=True)
        store.write_results([2], [DONE], response.readings[None], [""], [0.1], fields=response.field[None])
        F = store.fields()
        assert F.shape == (1, 4, scenario.mesh.n_nodes, 2)
        assert_array_equal(F[0], response.field)
        assert store._f["fields"].compression == "gzip"
    with _make(tmp_path / "nf.h5", scenario, space, n=4) as store, pytest.raises(StoreError, match="no displacement fields"):
        store.fields()


def test_extend_keeps_rows(tmp_path, scenario, space):
    path = tmp_path / "s.h5"
    with _make(path, scenario, space) as store:
        R = _fill(store, [0, 3], scenario, fail=(3,))
        h = store.content_hash()
    SnapshotStore.extend(path, sobol(8, 2, seed=3, skip=8))
    with SnapshotStore.open(path) as store:
        assert store.n_rows == 16 and store.run_arguments["n"] == 16
        assert_array_equal(store.parameters(physical=False, only_done=False), sobol(16, 2, seed=3))
        assert_array_equal(store.readings(), R[:1])
        assert store.errors() == {3: "SolverError: singular"}
        assert store.content_hash() == h
        assert [e["event"] for e in store.history] == ["created", "extended"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]  # no temporary file left


def test_create_refuses_existing_file(tmp_path, scenario, space):
    path = tmp_path / "s.h5"
    path.write_bytes(b"precious")
    with pytest.raises(StoreError, match="already exists.*never overwritten"):
        _make(path, scenario, space)
    assert path.read_bytes() == b"precious"


def _truncated(path, scenario, space):
    _make(path, scenario, space, n=64).close()
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _garbage(path, scenario, space):
    path.write_bytes(np.random.default_rng(0).bytes(4096))


def _empty(path, scenario, space):
    path.write_bytes(b"")


def _foreign(path, scenario, space):
    with h5py.File(path, "w") as f:
        f["x"] = np.arange(3)


def _damaged_header(path, scenario, space):
    _make(path, scenario, space).close()
    data = bytearray(path.read_bytes())
    data[8:200] = bytes(192)  # keep the HDF5 signature, wipe the superblock
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(
    "damage, message",
    [
        (_truncated, r"cannot be opened: .*corrupt HDF5 file.*left untouched"),
        (_garbage, r"is not an HDF5 file.*left untouched"),
        (_empty, r"is not an HDF5 file"),
        (_foreign, r"not a podkrig snapshot store"),
        (_damaged_header, r"cannot be opened: .*corrupt HDF5 file"),
    ],
)
def test_damaged_files_are_refused_and_untouched(tmp_path, scenario, space, damage, message):
    path = tmp_path / "s.h5"
    damage(path, scenario, space)
    before = path.read_bytes()
    for mode in ("r", "r+"):
        with pytest.raises(StoreError, match=message):
            SnapshotStore.open(path, mode)
    with pytest.raises(StoreError, match="already exists"):
        _make(path, scenario, space)
    assert path.read_bytes() == before


def test_schema_version_is_checked(tmp_path, scenario, space):
    path = tmp_path / "s.h5"
    _make(path, scenario, space).close()
    with h5py.File(path, "r+") as f:
        f.attrs["schema_version"] = 99
    with pytest.raises(SchemaError, match="schema version 99; this podkrig .* reads version 1"):
        SnapshotStore.open(path)


def test_missing_store(tmp_path):
    with pytest.raises(StoreError, match="no snapshot store at"):
        SnapshotStore.open(tmp_path / "nope.h5")


def test_store_in_use_by_another_process(tmp_path, scenario, space):
    import subprocess
    import sys

    path = tmp_path / "s.h5"
    _make(path, scenario, space).close()
    holder = subprocess.Popen(
        [sys.executable, "-c", f"import h5py, time; f = h5py.File({str(path)!r}, 'r+'); print('open', flush=True); time.sleep(60)"],
        stdout=subprocess.PIPE, text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "open"
        with pytest.raises(StoreError, match="is in use by another process"):
            SnapshotStore.open(path, "r+")
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
