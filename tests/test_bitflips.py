"""Bit flips in a snapshot store and a surrogate file (issue 13, finding 4 and the bit-flip target).

Each trial flips one random bit (seeded) anywhere in a copy of a small file and loads everything
podkrig reads from it. Allowed outcomes: *refused* (a :class:`~podkrig.exceptions.StoreError`
with a message) or *harmless* (every loaded value bitwise identical to the undamaged file's, e.g.
a flip in HDF5 padding or free space). A *silent* outcome — different data, no error — fails.
Any other exception type fails too. ``PODKRIG_BITFLIPS`` sets the number of flips per file
(default 100); the counts of a run are printed (``-s``) and recorded in BENCHMARKS.md. The fast
lane flips one bit in the middle of each dataset's values: refused, naming the dataset.
"""

import hashlib
import json
import logging
import os

import h5py
import numpy as np
import pytest

from podkrig.exceptions import StoreError
from podkrig.io.surrogate_file import load_surrogate, save_surrogate
from podkrig.offline.sampling import sobol
from podkrig.offline.store import DONE, FAILED, SnapshotStore
from podkrig.parameters import ParameterSpace
from podkrig.surrogate.podkriging import PODKriging

FLIPS = int(os.environ.get("PODKRIG_BITFLIPS", "100"))
SEED = 20261124


def _fingerprint(*values):
    """SHA-256 of loaded values: arrays by dtype, shape and bytes (NaN payloads count), the rest as JSON."""
    h = hashlib.sha256()
    for v in values:
        if isinstance(v, np.ndarray):
            h.update(f"{v.dtype.str}{v.shape}".encode())
            h.update(np.ascontiguousarray(v).tobytes())
        else:
            h.update(json.dumps(v, sort_keys=True, default=str).encode())
    return h.hexdigest()


def _load_store(path):
    with SnapshotStore.open(path) as s:
        info = s.info()
        info.pop("path")
        info.pop("file_size_bytes")
        return _fingerprint(info, s.parameters(only_done=False), s.parameters(physical=False, only_done=False),
                            s.readings(only_done=False), s.status(), s.errors(), s.wall_times(), s.cpu_times(),
                            s.fields(only_done=False), s.spec.to_dict(), s.space.to_dict())


def _load_surrogate(path, X):
    sur = load_surrogate(path)
    mean, std = sur.predict(X, return_std=True)
    arrays = [v for obj in (sur, sur.pod_, sur.kriging_) for _, v in sorted(vars(obj).items())
              if isinstance(v, np.ndarray)]
    return _fingerprint(mean, std, *arrays, sur.provenance_, sur.output_shape_,
                        sur.space.to_dict() if sur.space else None, sur.pod.get_params(),
                        {k: str(v) for k, v in sur.kriging.get_params().items()})


def _flip_trials(path, load, tmp_path, n, seed):
    """Flip one bit n times (each in a fresh copy); returns counts and the silent trials."""
    original = path.read_bytes()
    reference = load(path)
    rng = np.random.default_rng(seed)
    counts = {"refused": 0, "harmless": 0, "silent": 0}
    silent = []
    damaged = tmp_path / f"flipped{path.suffix}"
    for trial in range(n):
        offset, bit = int(rng.integers(len(original))), int(rng.integers(8))
        data = bytearray(original)
        data[offset] ^= 1 << bit
        damaged.write_bytes(bytes(data))
        try:
            result = load(damaged)
        except StoreError as e:
            assert str(e), f"flip at byte {offset} bit {bit}: refused without a message"
            counts["refused"] += 1
            continue
        if result == reference:
            counts["harmless"] += 1
        else:
            counts["silent"] += 1
            silent.append((trial, offset, bit))
    return counts, silent


@pytest.fixture(scope="module")
def small_store(tmp_path_factory, coarse_diagonal):
    """16 rows (13 done, 2 failed, 1 pending) with fields: every dataset holds real values."""
    sc = coarse_diagonal
    space = ParameterSpace.from_scenario(sc, {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000)})
    path = tmp_path_factory.mktemp("flip") / "store.h5"
    rng = np.random.default_rng(0)
    with SnapshotStore.create(path, sc, space, sobol(16, 2, seed=1), sampling="sobol", seed=1, fields=True) as s:
        rows = np.arange(15)
        status = np.where(np.isin(rows, (4, 9)), FAILED, DONE)
        s.write_results(rows, status, rng.normal(size=(15, s.n_loads, s.n_sensors)),
                        ["SolverError: singular" if st == FAILED else "" for st in status],
                        rng.uniform(0.01, 0.02, 15), rng.normal(size=(15, s.n_loads, s.n_nodes, 2)),
                        rng.uniform(0.01, 0.02, 15))
    return path


@pytest.fixture(scope="module")
def small_surrogate(tmp_path_factory):
    rng = np.random.default_rng(0)
    X = rng.uniform([10, 4], [1000, 400], size=(30, 2))
    Y = np.stack([np.outer([1, 2, 3], [1 / x[0], 1 / x[1], 1 / x[0] + 1 / x[1]]) for x in X])
    path = tmp_path_factory.mktemp("flip") / "surrogate.h5"
    save_surrogate(PODKriging().fit(X, Y), path)
    return path, X[:5]


def _flip_in_dataset(path, name, out):
    """Copy of the file with one bit flipped in the middle of a (contiguous) dataset's values."""
    with h5py.File(path, "r") as f:
        ds = f[name]
        if ds.chunks:  # the first chunk's bytes
            chunk = ds.id.get_chunk_info(0)
            offset = chunk.byte_offset + chunk.size // 2
        else:
            offset = ds.id.get_offset() + ds.id.get_storage_size() // 2
    data = bytearray(path.read_bytes())
    data[offset] ^= 1 << 3
    out.write_bytes(bytes(data))
    return out


@pytest.mark.parametrize("name", ["readings", "parameters", "unit_parameters", "status", "fields"])
def test_a_flip_in_a_stores_values_is_refused(small_store, tmp_path, name):
    """The fast lane's case of the trials below: damage where the data are, not in padding."""
    damaged = _flip_in_dataset(small_store, name, tmp_path / "store.h5")
    with pytest.raises(StoreError, match=f"'{name}'.*damaged"):  # which dataset, and what happened
        _load_store(damaged)


@pytest.mark.parametrize("name", ["X", "pod/modes", "pod/mean", "kriging/alpha", "kriging/L"])
def test_a_flip_in_a_surrogates_arrays_is_refused(small_surrogate, tmp_path, name):
    path, X = small_surrogate
    damaged = _flip_in_dataset(path, name, tmp_path / "surrogate.h5")
    with pytest.raises(StoreError, match="checksum"):
        _load_surrogate(damaged, X)


@pytest.mark.slow
def test_bit_flips_in_a_store_are_refused_or_harmless(small_store, tmp_path, caplog):
    caplog.set_level(logging.ERROR)
    counts, silent = _flip_trials(small_store, _load_store, tmp_path, FLIPS, SEED)
    print(f"\nstore {small_store.stat().st_size} bytes, {FLIPS} flips (seed {SEED}): {counts}")
    assert counts["silent"] == 0, f"silently different data after flips (trial, byte, bit): {silent}"
    assert counts["refused"] > 0


@pytest.mark.slow
def test_bit_flips_in_a_surrogate_are_refused_or_harmless(small_surrogate, tmp_path, caplog):
    caplog.set_level(logging.ERROR)
    path, X = small_surrogate
    counts, silent = _flip_trials(path, lambda p: _load_surrogate(p, X), tmp_path, FLIPS, SEED)
    print(f"\nsurrogate {path.stat().st_size} bytes, {FLIPS} flips (seed {SEED}): {counts}")
    assert counts["silent"] == 0, f"silently different inversion inputs after flips (trial, byte, bit): {silent}"
    assert counts["refused"] > 0
