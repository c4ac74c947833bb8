"""Checksums that make damaged HDF5 files fail loudly instead of loading silently different data.

Two tools, both independent of what the file holds:

- :func:`row_digests`: one 64-bit digest per row (first axis) of an array, vectorised. A row's
  bytes are read as little-endian 64-bit words ``w_0 .. w_{m-1}`` (zero-padded) and hashed as the
  multilinear sum ``h = Σ_i k_i · w_i mod 2^64`` with fixed odd keys ``k_i`` [1]_. Because every
  key is odd, any change confined to one word (any number of flipped bits in it) changes ``h``:
  ``Δh = k_i · Δw_i`` is a multiple of ``2^64`` only if ``Δw_i`` is. Changes spread over several
  words cancel only by accident (keys are pseudo-random). Cost: one integer dot product per row,
  ≈ 0.15 ms for 10⁴ rows of 24 words on one core (numba) — cheap enough to verify on every read.
- :func:`seal` / :func:`verify`: a SHA-256 over a whole file's content (every group, dataset and
  attribute, by name, dtype, shape and value), stored in the root attribute
  :data:`DIGEST_ATTR`. Meant for small files written once (surrogates): one call after saving,
  one before loading.

Neither guards against a deliberate forgery (the multilinear keys are public); both catch the bit
rot, truncation and partial writes that real disks produce.

References
----------
.. [1] D. Lemire, O. Kaser, "Strongly universal string hashing is fast", The Computer Journal
   57(11), 1624–1638, 2014 (multilinear hashing).
"""

import hashlib
import json
from pathlib import Path

import h5py
import numba
import numpy as np

from podkrig.exceptions import IntegrityError, StoreError

#: Root attribute holding a file's SHA-256 (``"sha256:<hex>"``); see :func:`seal`.
DIGEST_ATTR = "integrity_sha256"
_KEY_SEED = 0x9E3779B97F4A7C15


def _splitmix64(i):
    """SplitMix64 of uint64 counters (vectorised); deterministic across numpy versions."""
    with np.errstate(over="ignore"):
        z = (np.asarray(i, dtype=np.uint64) + np.uint64(_KEY_SEED)) * np.uint64(_KEY_SEED)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


_KEYS = _splitmix64(np.arange(1024, dtype=np.uint64)) | np.uint64(1)


def _keys(m):
    global _KEYS
    if m > len(_KEYS):
        _KEYS = _splitmix64(np.arange(max(m, 2 * len(_KEYS)), dtype=np.uint64)) | np.uint64(1)
    return _KEYS[:m]


def _words(a):
    """Each row's little-endian bytes as zero-padded 64-bit words: contiguous (n, m) uint64."""
    a = np.asarray(a)
    if a.dtype.byteorder == ">":
        a = a.astype(a.dtype.newbyteorder("<"))
    n = a.shape[0]
    b = np.ascontiguousarray(a).reshape(n, -1).view(np.uint8) if n else np.zeros((0, 8), np.uint8)
    if b.shape[1] in (1, 2, 4):  # one zero-padded word per row, without a padded byte copy
        return b.view(f"<u{b.shape[1]}").astype(np.uint64)
    pad = -b.shape[1] % 8
    if pad or b.shape[1] == 0:
        b = np.concatenate([b, np.zeros((n, pad or 8), np.uint8)], axis=1)
    return b.view("<u8")


def row_digests(a):
    """Multilinear 64-bit digest of each row (first axis) of an array.

    Parameters
    ----------
    a : ndarray of shape (n, ...)
        Any fixed-size dtype; hashed as its little-endian bytes.

    Returns
    -------
    ndarray of shape (n,) uint64
    """
    words = _words(a)
    return _multilinear(words, _keys(words.shape[1]))


def mismatched_rows(a, expected):
    """Rows of ``a`` whose digest differs from ``expected``: ``flatnonzero(row_digests(a) != expected)``
    in one pass without the intermediate arrays (what verifying a dataset on every read costs).

    Parameters
    ----------
    a : ndarray of shape (n, ...)
    expected : ndarray of shape (n,) uint64 (any stride, e.g. a column of a digest table)

    Returns
    -------
    ndarray of int64, ascending row indices
    """
    words = _words(a)
    expected = np.asarray(expected)
    if expected.shape != (len(words),) or expected.dtype != np.uint64:
        raise ValueError(f"expected {len(words)} uint64 digests; got {expected.dtype} {expected.shape}")
    return _mismatches(words, _keys(words.shape[1]), expected)


@numba.njit(cache=True)
def _digest(words, keys, i):
    h = np.uint64(0)
    for j in range(words.shape[1]):
        h += keys[j] * words[i, j]  # uint64 arithmetic wraps: mod 2^64
    return h


@numba.njit(cache=True)
def _multilinear(words, keys):
    """``words @ keys`` mod 2^64 row by row: 0.14 ms for 10⁴ rows of 24 words against 0.23 ms for
    ``np.einsum``, which also allocates."""
    out = np.empty(words.shape[0], dtype=np.uint64)
    for i in range(words.shape[0]):
        out[i] = _digest(words, keys, i)
    return out


@numba.njit(cache=True)
def _mismatches(words, keys, expected):
    bad = np.empty(words.shape[0], dtype=np.int64)
    k = 0
    for i in range(words.shape[0]):
        if _digest(words, keys, i) != expected[i]:
            bad[k] = i
            k += 1
    return bad[:k].copy()


def _update(h, name, value):
    h.update(name.encode("utf-8") + b"\0")
    if isinstance(value, (bytes, np.bytes_)):
        h.update(b"b" + bytes(value))
    elif isinstance(value, str):
        h.update(b"s" + value.encode("utf-8"))
    else:
        arr = np.asarray(value)
        if arr.dtype.kind == "O":  # variable-length strings
            h.update(b"o" + json.dumps([str(v) for v in arr.ravel()]).encode("utf-8"))
        else:
            h.update(f"a{arr.dtype.str}{arr.shape}".encode())
            h.update(np.ascontiguousarray(arr).tobytes())
    h.update(b"\0")


def file_digest(f):
    """SHA-256 of an open HDF5 file's content (all objects and attributes but :data:`DIGEST_ATTR`).

    Returns ``"sha256:<hex>"``.
    """
    h = hashlib.sha256(b"podkrig.h5integrity/1")
    items = []
    f.visititems(lambda name, obj: items.append((name, obj)))
    for name, obj in [("/", f), *sorted(items, key=lambda t: t[0])]:
        h.update(("G" if isinstance(obj, h5py.Group) else "D").encode() + name.encode("utf-8") + b"\0")
        for key in sorted(obj.attrs):
            if not (obj is f and key == DIGEST_ATTR):
                _update(h, "@" + key, obj.attrs[key])
        if isinstance(obj, h5py.Dataset):
            _update(h, "=", obj[()])
    return "sha256:" + h.hexdigest()


def attrs_digest(attrs):
    """SHA-256 of a mapping of attribute values (as h5py returns them). Returns ``"sha256:<hex>"``."""
    h = hashlib.sha256(b"podkrig.h5integrity.attrs/1")
    for key in sorted(attrs):
        _update(h, "@" + key, attrs[key])
    return "sha256:" + h.hexdigest()


def metadata_digest(f, datasets):
    """SHA-256 of an open file's root attributes and of the named datasets' attributes, dtypes and
    shapes (not their data: see :func:`row_digests`). Returns ``"sha256:<hex>"``."""
    h = hashlib.sha256(b"podkrig.h5integrity.metadata/1")
    for key in sorted(f.attrs):
        if key != DIGEST_ATTR:
            _update(h, "@" + key, f.attrs[key])
    for name in datasets:
        ds = f[name]
        h.update(f"D{name}{ds.dtype.str}{ds.shape}".encode())
        for key in sorted(ds.attrs):
            _update(h, "@" + key, ds.attrs[key])
    return "sha256:" + h.hexdigest()


def seal(path):
    """Store the SHA-256 of a closed HDF5 file's content in its root attribute :data:`DIGEST_ATTR`."""
    with h5py.File(path, "r+") as f:
        f.attrs[DIGEST_ATTR] = file_digest(f)


def verify(path, what="file"):
    """Check a file against the digest :func:`seal` stored in it.

    Parameters
    ----------
    path : str or Path
    what : str
        What the file is, for messages (e.g. ``"surrogate"``).

    Returns
    -------
    bool
        True if verified; False for a file written before checksums existed (no digest: the caller
        says so to the user).

    Raises
    ------
    IntegrityError
        The content does not match its digest.
    StoreError
        The file cannot be read as HDF5.
    """
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            stored = f.attrs.get(DIGEST_ATTR)
            if stored is None:
                return False
            actual = file_digest(f)
    except (OSError, RuntimeError, KeyError, ValueError) as e:
        raise StoreError(f"{path} cannot be read: damaged {what} file ({e})") from e
    if isinstance(stored, bytes):
        stored = stored.decode("utf-8", errors="replace")
    if stored != actual:
        raise IntegrityError(
            f"{path}: the {what} file does not match its checksum (stored {str(stored)[:20]}…, content "
            f"{actual[:20]}…): it was damaged after it was written; rebuild it or restore a copy"
        )
    return True
