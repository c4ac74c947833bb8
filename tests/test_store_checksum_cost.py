"""What keeps checksum verification cheap (issue 13, target "≤ 5 % on load or resume"): the fused
digest check, the low-level whole-dataset read, and a writer reopen that does not verify twice.
The times themselves are measured by ``scripts/bench_store.py`` (BENCHMARKS.md)."""

import h5py
import numpy as np
import pytest

from podkrig import h5integrity
from podkrig.h5integrity import mismatched_rows, row_digests
from podkrig.offline import store as store_module
from podkrig.offline.sampling import sobol
from podkrig.offline.store import DONE, FAILED, SnapshotStore
from podkrig.parameters import ParameterSpace


@pytest.mark.parametrize("a", [
    np.arange(60.0).reshape(20, 3),                      # 24-byte rows: zero-padded to 4 words
    np.arange(240.0).reshape(10, 4, 6),                  # 192-byte rows: whole words
    np.arange(10, dtype=np.int8),                        # 1-byte rows
    np.arange(10, dtype=">f8"),                          # big-endian: hashed as little-endian bytes
    np.array([b"x" * 512, b"", b"abc"], dtype="S512"),   # fixed-length text
    np.zeros((0, 3)),                                    # no rows
])
def test_mismatched_rows_names_exactly_the_changed_rows(a):
    """Reference: flatnonzero(row_digests(a) != expected), the definition of the fused check."""
    expected = row_digests(a)
    assert mismatched_rows(a, expected).tolist() == []
    if len(a) >= 3:
        damaged = expected.copy()
        damaged[[0, 2]] ^= np.uint64(1 << 63)  # a digest table with two rows changed
        assert mismatched_rows(a, damaged).tolist() == [0, 2]
        column = np.stack([expected, damaged], axis=1)[:, 1]  # a strided column of a table
        assert mismatched_rows(a, column).tolist() == [0, 2]


def test_one_flipped_bit_in_any_word_is_found():
    """Any change confined to one 64-bit word changes the digest (odd keys), whatever the word."""
    a = np.random.default_rng(0).normal(size=(8, 24))
    expected = row_digests(a)
    for word in range(24):
        for bit in (0, 31, 63):
            b = a.copy()
            b.view(np.uint64)[5, word] ^= np.uint64(1 << bit)
            assert mismatched_rows(b, expected).tolist() == [5]


def test_mismatched_rows_refuses_a_table_of_the_wrong_length():
    with pytest.raises(ValueError, match="expected 3 uint64 digests"):
        mismatched_rows(np.zeros((3, 2)), np.zeros(4, np.uint64))


@pytest.fixture(scope="module")
def store_path(tmp_path_factory, coarse_diagonal):
    space = ParameterSpace.from_scenario(coarse_diagonal, {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000)})
    path = tmp_path_factory.mktemp("cost") / "s.h5"
    with SnapshotStore.create(path, coarse_diagonal, space, sobol(8, 2, seed=0), sampling="sobol", seed=0) as store:
        rng = np.random.default_rng(1)
        store.write_results(np.arange(6), np.array([DONE] * 5 + [FAILED]),
                            rng.normal(size=(6, store.n_loads, store.n_sensors)), [""] * 5 + ["boom"], np.full(6, 0.1))
    return path


def test_whole_dataset_reads_equal_h5py_reads(store_path):
    """The low-level read returns the same dtype (enum and text included), shape and bytes."""
    with h5py.File(store_path, "r") as f:
        for name in (*store_module._ROW_DATASETS, "checksums/rows"):
            fast, slow = store_module._read_whole(f, name), f[name][...]
            assert fast.dtype == slow.dtype and fast.shape == slow.shape
            assert fast.tobytes() == slow.tobytes()
        assert h5py.check_enum_dtype(store_module._read_whole(f, "status").dtype) is not None


def test_opening_for_writing_verifies_once(store_path, monkeypatch):
    """Opening with mode "r+" validates the file read-only first; the writer then takes over what
    was just verified instead of hashing parameters and status a second time (before: twice)."""
    calls = []
    original = store_module.mismatched_rows

    def counting(data, expected):
        calls.append(len(data))
        return original(data, expected)

    monkeypatch.setattr(store_module, "mismatched_rows", counting)
    with SnapshotStore.open(store_path, "r+") as store:
        assert len(calls) == len(store_module._VERIFIED_AT_OPEN)
        assert store.counts() == {"total": 8, "done": 5, "failed": 1, "pending": 2}
        assert store.errors() == {5: "boom"}  # read later: verified then
    assert len(calls) == len(store_module._VERIFIED_AT_OPEN) + 1


def test_a_damaged_row_is_still_refused_on_load(store_path, tmp_path):
    """The cheaper path still verifies what it reads: one changed reading is named on load."""
    copy = tmp_path / "damaged.h5"
    copy.write_bytes(store_path.read_bytes())
    with h5py.File(copy, "r+") as f:
        f["readings"][3, 0, 0] += 1e-9
    with SnapshotStore.open(copy) as store, pytest.raises(h5integrity.IntegrityError, match="rows 3 of dataset 'readings'"):
        store.snapshot_matrix()
