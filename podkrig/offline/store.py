"""The snapshot store: a self-describing, resumable HDF5 file of FE responses over a sampling design.

One row per sample, in sample order. Every row exists from creation on (status ``pending``), with
its parameter vector; the offline runner (:mod:`podkrig.offline.runner`) fills rows in and marks them
``done`` or ``failed``. Metadata lives in HDF5 attributes, which the h5py documentation calls
"the official way to store metadata in HDF5" [1]_; bulk arrays live in datasets. Nothing is
pickled: every attribute is a number, a string or JSON text.

Layout (``n`` rows, ``d`` free parameters, readings in mm, loads in the scenario's load unit)::

    /                     attributes: format, schema_version, created, software (JSON),
                          scenario_spec (JSON), parameter_space (JSON), sensor_names (JSON),
                          sensor_definitions (JSON), load_levels, load_unit, reading_unit,
                          n_nodes, n_dofs, sampling_method, sampling_seed, run_arguments (JSON),
                          history (JSON)
    /parameters           (n, d) float64, physical values
    /unit_parameters      (n, d) float64, the design in the unit cube
    /readings             (n, n_loads, n_sensors) float64, mm; NaN until done
    /status               (n,) enum int8: pending = 0, done = 1, failed = 2
    /error                (n,) fixed-length UTF-8 bytes (first 512 bytes of the error text; a partial
                          row's starts with its status, limit and reach: partial_error)
    /wall_time            (n,) float64, s; wall time of the FE run, NaN until run
    /cpu_time             (n,) float64, s; CPU time of the thread that ran it (below wall time when
                          the worker waited for a core), NaN until run
    /fields               (n, n_loads, n_nodes, 2) float64, mm; optional, gzip, one chunk per row
    /checksums/rows       (n + 1, 8) uint64: per-row digests of the 7 datasets above + "being
                          written" flag; last row: SHA-256 of the root and of the dataset attributes
    /checksums/fields     (n,) uint64: digest of each row's fields (with fields only)

Crash safety. A store is created in a temporary file and renamed into place, so it either exists
whole or not at all; growing it (Sobol' append) rewrites it the same way. Every per-row dataset
except ``fields`` is contiguous with its space allocated at creation, so writing a row changes
raw bytes only, never the file's structure. :meth:`SnapshotStore.write_results` writes the data,
flushes, then writes the status and flushes again: a process killed at any moment leaves a file
whose ``done`` rows are complete, and an unfinished row stays ``pending``.

One writer. A writer (create, extend, ``mode="r+"``) holds an exclusive ``fcntl.flock`` on
``.NAME.lock`` beside the store for its lifetime; a second writer is refused with the first one's
PID and changes nothing. Creation publishes the temporary file with ``os.link``, which fails
rather than replace a file that appeared meanwhile; temporary files left by a killed creation are
removed by the next writer. Before each batch the free disk space is checked, and any HDF5 write
error stops the run with "disk full: N rows written ..." while the batch's rows stay pending.

Checksums (``/checksums``, absent in stores written before them, which still load with a warning):
a 64-bit multilinear digest per row of every per-row dataset and of each row's fields
(:func:`podkrig.h5integrity.row_digests`), and SHA-256 digests of the root attributes and of the
datasets' attributes. Parameters, status and metadata are verified at every opening, the other
datasets whenever they are read, everything by :meth:`SnapshotStore.verify`. A row being written
is marked in the digest table first and unmarked after its digests: a writer killed in between
leaves rows that the next writer reseals (they were verified just before the write began).

Why one long module (~1 000 lines, a third of it documentation): it is one class whose invariants
— the file layout, the write order that makes a kill harmless, and the checksums that are
verified on every read — must be read together; the file-safety helpers it relies on (locks,
atomic publication, moving aside, disk space) are in :mod:`podkrig.offline.files`.

Example
-------
>>> from fe.scenarios import build_scenario
>>> from podkrig.offline.runner import run_snapshots
>>> from podkrig.parameters import ParameterSpace
>>> sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
>>> space = ParameterSpace.from_scenario(sc, {"kN_bj": (10, 1000, "log")})
>>> _ = run_snapshots("snapshots/panel.h5", sc, space, n=8, seed=0, workers=1)
>>> with SnapshotStore.open("snapshots/panel.h5") as store:
...     Y = store.snapshot_matrix()      # (n_done, n_loads * n_sensors), mm
...     X = store.parameters()           # (n_done, n_params), physical units
>>> Y.shape, X.shape
((8, 24), (8, 1))

References
----------
.. [1] h5py documentation, "Attributes", https://docs.h5py.org/en/stable/high/attr.html
"""

import datetime
import hashlib
import json
import logging
import os
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from fe.exceptions import FEError
from podkrig import __version__
from podkrig.display import Displayed
from podkrig.exceptions import IntegrityError, SchemaError, StoreError, StoreInUseError
from podkrig.h5integrity import attrs_digest, metadata_digest, mismatched_rows, row_digests
from podkrig.offline.files import (
    DISK_MARGIN,
    acquire_lock,
    check_disk_space,
    free_bytes,
    holds_lock,
    human_bytes,
    io_reason,
    lock_holder,
    lock_path,
    publish,
    release_lock,
    remove_orphans,
    tmp_path,
)
from podkrig.parameters import ParameterSpace

logger = logging.getLogger(__name__)

FORMAT = "podkrig.snapshots"
SCHEMA_VERSION = 1
PENDING, DONE, FAILED = 0, 1, 2
#: Error prefix of failed rows that hold a partial response (a nonlinear run that stopped early)
PARTIAL_PREFIX = "NotConverged"
#: Keys of a nonlinear scenario's spec that set its path following (increments, budgets, tolerance):
#: the solver settings a store records in its scenario spec and shows apart (:meth:`SnapshotStore.info`)
SOLVER_SETTINGS = ("increment", "max_increment", "max_steps", "max_iterations", "max_total_iterations",
                   "max_cpu_seconds", "max_seconds", "tolerance")
#: The head of a partial row's error text: its status, the budget limit that ended it and its reach
_PARTIAL_HEAD = re.compile(rf"^{PARTIAL_PREFIX} \((?P<status>\w+)(?:: (?P<limit>\w+))?, reached (?P<reached>\S+) "
                           r"(?P<unit>[^)]*)\): ")
STATUS_NAMES = {PENDING: "pending", DONE: "done", FAILED: "failed"}
ERROR_BYTES = 512

_STATUS_DTYPE = h5py.enum_dtype({"pending": PENDING, "done": DONE, "failed": FAILED}, basetype="i1")
_ROOT_ATTRS = (
    "format", "schema_version", "created", "software", "scenario_spec", "parameter_space",
    "sensor_names", "sensor_definitions", "load_levels", "load_unit", "reading_unit", "n_nodes",
    "n_dofs", "sampling_method", "sampling_seed", "run_arguments", "history",
)
_JSON_ATTRS = ("software", "scenario_spec", "parameter_space", "sensor_names", "sensor_definitions",
               "run_arguments", "history")
_ROW_DATASETS = ("parameters", "unit_parameters", "readings", "status", "error", "wall_time", "cpu_time")
_CHECKSUMS = "checksums"  # group: rows (n + 1, 8) uint64, fields (n,) uint64 (see _write_checksums)
_WRITING = len(_ROW_DATASETS)  # last column of checksums/rows: 1 while the row is being written
_VERIFIED_AT_OPEN = ("parameters", "status")  # small and always needed; the rest when read
REHASH_HINT = "run 'podkrig snapshots verify --rehash {path}' to add them"


def software_versions():
    """Versions that determine a store's content: podkrig, numpy, scipy, h5py, HDF5, Python."""
    import scipy

    return {
        "podkrig": __version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "h5py": h5py.version.version,
        "hdf5": h5py.version.hdf5_version,
        "python": sys.version.split()[0],
    }


def partial_error(status, limit, reached, unit, message):
    """Error text of a nonlinear run that stopped early (a partial row), e.g.
    ``"NotConverged (budget_exhausted: iterations, reached 0.0123 mm): iteration budget of 40 ..."``;
    :meth:`SnapshotStore.partial_rows` reads its head back.

    Parameters
    ----------
    status : str
        ``"budget_exhausted"`` or ``"not_converged"`` (:attr:`fe.NonlinearResponse.status`).
    limit : str or None
        The budget limit that ended the run (``"steps"``, ``"iterations"``, ``"cpu"``, ``"wall"``).
    reached : float
        Last converged value of the control variable, ``unit``.
    unit : str
        Unit of the control variable.
    message : str
        The solver's reason.
    """
    return f"{PARTIAL_PREFIX} ({status}{f': {limit}' if limit else ''}, reached {float(reached):.6g} {unit}): {message}"


def _now():
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


def _row_bytes(n_params, n_loads, n_sensors):
    """Bytes per row of the contiguous datasets (checksums included)."""
    return 16 * n_params + 8 * n_loads * n_sensors + 1 + ERROR_BYTES + 16 + 8 * len(_ROW_DATASETS) + 9


def store_bytes_per_row(n_params, n_loads, n_sensors, n_nodes=0, fields=False):
    """Upper estimate of a store's bytes on disk per row (fields counted uncompressed)."""
    return _row_bytes(n_params, n_loads, n_sensors) + (16 * n_loads * n_nodes + 8 if fields else 0)


def estimate_store_bytes(n, n_params, n_loads, n_sensors, n_nodes=0, fields=False):
    """Upper estimate of a store's size on disk, bytes (fields counted uncompressed)."""
    return int(n) * store_bytes_per_row(n_params, n_loads, n_sensors, n_nodes, fields) + 64 * 1024


def _write_checksums(f, fields):
    """(Re)compute every checksum of an open store from its content (creation, extend, rehash).

    ``/checksums/rows`` (n + 1, 8) uint64: row ``i < n`` holds the digests of row ``i`` of each
    dataset of :data:`_ROW_DATASETS`, then 1 while a writer fills the row (else 0); row ``n``
    holds the SHA-256 of the root attributes (4 words, checked at every opening) and of the
    datasets' own attributes, dtypes and shapes (4 words, checked by :meth:`SnapshotStore.verify`).
    One table, read once at opening. ``/checksums/fields`` (n,): a digest per row of fields.
    """
    n = f["status"].shape[0]
    g = f.require_group(_CHECKSUMS)
    for name in ("rows", "fields"):
        if name in g:
            del g[name]
    table = np.zeros((n + 1, _WRITING + 1), dtype="<u8")
    table[:n, :_WRITING] = np.stack([row_digests(f[name][...]) for name in _ROW_DATASETS], axis=1)
    table[n, :4] = _sha_words(attrs_digest({k: f.attrs[k] for k in _ROOT_ATTRS}))
    table[n, 4:] = _sha_words(metadata_digest(f, _datasets(fields)))
    _early(table.shape, "<u8", 0, g, "rows", columns=json.dumps([*_ROW_DATASETS, "writing"]),
           method="multilinear 64-bit digest per row (podkrig.h5integrity.row_digests); last row: "
                  "SHA-256 of the root attributes, SHA-256 of the datasets' attributes")[...] = table
    if fields:
        fd = _early((n,), "<u8", 0, g, "fields")
        fd[...] = [row_digests(f["fields"][i][None])[0] for i in range(n)]


def _read_whole(f, name):
    """A whole dataset of an open file through h5py's low-level API: the same array as
    ``f[name][...]`` at half the cost for the 10⁴-row datasets of a store (0.29 against 0.59 ms
    for the readings; no selection objects are built), which keeps checksum verification cheap
    (``scripts/bench_store.py``)."""
    ds = h5py.h5d.open(f.id, name.encode())
    out = np.empty(ds.shape, dtype=ds.dtype)
    if out.size:
        ds.read(h5py.h5s.ALL, h5py.h5s.ALL, out)
    return out


def _sha_words(digest):
    """``"sha256:<hex>"`` as 4 little-endian uint64 words."""
    return np.frombuffer(bytes.fromhex(digest.split(":", 1)[1]), dtype="<u8")


def _datasets(fields):
    return _ROW_DATASETS + (("fields",) if fields else ())


@dataclass(repr=False)
class VerifyReport(Displayed):
    """Outcome of :meth:`SnapshotStore.verify`.

    Attributes
    ----------
    path : str
    checksummed : bool
        False for a store written before checksums existed.
    metadata_ok : bool
        Root and dataset attributes match their digest.
    bad_rows : dict
        ``{dataset: [row, ...]}`` rows whose content does not match their checksum.
    unsealed_rows : list of int
        Rows being written when a writer stopped; resealed by the next run on the store.
    rows : int
    """

    path: str
    checksummed: bool
    metadata_ok: bool = True
    bad_rows: dict = field(default_factory=dict)
    unsealed_rows: list = field(default_factory=list)
    rows: int = 0

    @property
    def ok(self):
        return self.checksummed and self.metadata_ok and not self.bad_rows

    def to_dict(self):
        return {"path": self.path, "checksummed": self.checksummed, "metadata_ok": self.metadata_ok,
                "bad_rows": self.bad_rows, "unsealed_rows": self.unsealed_rows, "rows": self.rows,
                "ok": self.ok}


def _rows_text(rows, limit=20):
    rows = [int(r) for r in rows]
    more = f" and {len(rows) - limit} more" if len(rows) > limit else ""
    return ", ".join(map(str, rows[:limit])) + more


def _early(shape, dtype, fillvalue, parent, name, **attrs):
    """A contiguous dataset whose space is allocated (and filled) at creation."""
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
    ds = parent.create_dataset(name, shape=shape, dtype=dtype, fillvalue=fillvalue, dcpl=dcpl)
    ds.attrs.update(attrs)
    return ds


def _write_layout(f, attrs, space, U, n_loads, n_sensors, n_nodes, fields):
    n, d = U.shape
    for k, v in attrs.items():
        f.attrs[k] = json.dumps(v, sort_keys=True) if k in _JSON_ATTRS else v
    X = space.from_unit(U)
    _early((n, d), "f8", np.nan, f, "parameters", unit=json.dumps(space.units), names=json.dumps(space.names))[...] = X
    _early((n, d), "f8", np.nan, f, "unit_parameters", names=json.dumps(space.names))[...] = U
    _early((n, n_loads, n_sensors), "f8", np.nan, f, "readings", unit="mm")
    _early((n,), _STATUS_DTYPE, PENDING, f, "status")
    _early((n,), f"S{ERROR_BYTES}", b"", f, "error", encoding="utf-8, truncated")
    _early((n,), "f8", np.nan, f, "wall_time", unit="s")
    _early((n,), "f8", np.nan, f, "cpu_time", unit="s")
    if fields:
        f.create_dataset(
            "fields", shape=(n, n_loads, n_nodes, 2), dtype="f8", chunks=(1, n_loads, n_nodes, 2),
            compression="gzip", compression_opts=4, shuffle=True, fillvalue=np.nan,
        ).attrs.update(unit="mm", components="x, y")


class SnapshotStore:
    """A snapshot store opened with :meth:`open` or :meth:`create`; use it as a context manager.

    Attributes read at opening (never re-read): ``spec`` (:class:`fe.ScenarioSpec`), ``space``
    (:class:`~podkrig.parameters.ParameterSpace`), ``sensor_names``, ``sensor_definitions``,
    ``load_levels`` ``(n_loads,)`` in ``load_unit``, ``sampling`` and ``seed``, ``run_arguments``,
    ``created``, ``software``, ``schema_version``, ``n_rows``, ``has_fields``.
    """

    def __init__(self, file, path, verified=None):
        self._f = file
        self.path = Path(path)
        self._raw_attrs = {k: self._f.attrs[k] for k in _ROOT_ATTRS}
        self.checksummed = self._f.id.links.exists(_CHECKSUMS.encode())
        self._digests = self._meta_words = None  # checksums/rows, read once at opening
        if self.checksummed and verified is not None:  # the same file, just verified (see open)
            self._digests, self._meta_words = verified._digests.copy(), verified._meta_words.copy()
        elif self.checksummed:  # before any attribute is interpreted
            table = _read_whole(self._f, f"{_CHECKSUMS}/rows")
            if table.ndim != 2 or table.shape[1] != _WRITING + 1 or len(table) < 1 or table.dtype != np.uint64:
                raise StoreError(f"{self.path}: the checksum table has shape {table.shape} and type {table.dtype}, "
                                 f"expected (rows + 1, {_WRITING + 1}) uint64: the file is damaged")
            self._digests, self._meta_words = table[:-1], table[-1]
            if not np.array_equal(self._meta_words[:4], _sha_words(attrs_digest(self._raw_attrs))):
                raise IntegrityError(
                    f"{self.path}: the store's metadata (scenario, parameter space, sensors, load "
                    "levels, units, history) does not match its checksum: the file was damaged after it "
                    "was written; check it with 'podkrig snapshots verify' and rebuild it or restore a copy"
                )
        a = {k: json.loads(v) if k in _JSON_ATTRS else v for k, v in self._raw_attrs.items()}
        from fe.scenarios import ScenarioSpec

        self.schema_version = int(a["schema_version"])
        self.created = str(a["created"])
        self.software = a["software"]
        self.spec = ScenarioSpec.from_dict(a["scenario_spec"])
        self.space = ParameterSpace.from_dict(a["parameter_space"])
        self.sensor_names = tuple(a["sensor_names"])
        self.sensor_definitions = a["sensor_definitions"]
        self.load_levels = np.asarray(a["load_levels"], dtype=float)
        self.load_unit = str(a["load_unit"])
        self.reading_unit = str(a["reading_unit"])
        self.n_nodes = int(a["n_nodes"])
        self.n_dofs = int(a["n_dofs"])
        self.sampling = str(a["sampling_method"])
        self.seed = int(a["sampling_seed"])
        self.run_arguments = a["run_arguments"]
        self.history = a["history"]
        self.n_rows = int(self._f["status"].shape[0])
        self.has_fields = "fields" in self._f
        self._locked = False
        self._unsealed = np.zeros(0, dtype=np.int64)
        self._cache = {}  # verified parameters, unit_parameters, status (kept current by writes)

    # ------------------------------------------------------------------ opening and creating
    @classmethod
    def open(cls, path, mode="r"):
        """Open an existing store.

        Parameters
        ----------
        path : str or Path
        mode : {"r", "r+"}
            ``"r+"`` to write results (the file is first validated read-only).

        Returns
        -------
        SnapshotStore

        Raises
        ------
        StoreError
            Missing, unreadable, truncated or corrupt file, a file that is not a podkrig snapshot
            store, or one in use by another process. The file is never modified.
        SchemaError
            A store written with an unknown schema version.
        """
        if mode not in ("r", "r+"):
            raise ValueError(f"mode must be 'r' or 'r+'; got {mode!r}")
        path = Path(path)
        if mode == "r":
            return cls._open_checked(path, "r")
        acquire_lock(path)
        try:
            checked = cls._open_checked(path, "r")  # verified before HDF5 may write to it
            checked.close()
            # the same bytes, under our lock: take over what was verified instead of rereading it
            store = cls._open_checked(path, "r+", verified=checked)
        except BaseException:
            release_lock(path)
            raise
        store._locked = True
        store._reseal()
        return store

    @classmethod
    def _open_checked(cls, path, mode, verified=None):
        hint = "it was left untouched; move it away or choose another store path"
        if not path.exists():
            raise StoreError(f"no snapshot store at {path}")
        if not path.is_file():
            raise StoreError(f"{path} is not a file")
        try:
            is_hdf5 = h5py.is_hdf5(path)
        except OSError as e:
            raise StoreError(f"cannot read {path}: {e}") from e
        if not is_hdf5:
            raise StoreError(f"{path} is not an HDF5 file (empty, corrupt or another format); {hint}")
        try:
            f = h5py.File(path, mode)
        except OSError as e:
            if isinstance(e, BlockingIOError) or "unable to lock file" in str(e):
                lock = lock_path(path)
                mine = holds_lock(path)
                holder = lock_holder(lock) if lock.exists() and not mine else "another process"
                raise StoreInUseError(
                    f"{path} is in use by {holder} (HDF5 file lock); wait for that job to "
                    "finish or stop it"
                ) from e
            raise StoreError(f"{path} cannot be opened: truncated or corrupt HDF5 file ({e}); {hint}") from e
        try:
            fmt = f.attrs.get("format")
            if fmt != FORMAT:
                raise StoreError(
                    f"{path} is an HDF5 file but not a podkrig snapshot store (attribute 'format' is "
                    f"{fmt!r}, expected {FORMAT!r}); {hint}"
                )
            version = f.attrs.get("schema_version")
            version = int(version) if isinstance(version, (int, np.integer)) else version
            if version != SCHEMA_VERSION:
                raise SchemaError(
                    f"{path} has snapshot-store schema version {version!r}; this podkrig "
                    f"({__version__}) reads version {SCHEMA_VERSION}; use a matching podkrig version"
                )
            missing = [k for k in _ROOT_ATTRS if k not in f.attrs] + [k for k in _ROW_DATASETS if k not in f]
            if missing:
                raise StoreError(f"{path} is an incomplete snapshot store: missing {missing}; {hint}")
            store = cls(f, path, verified)
            store._check_consistency(verified)
        except StoreError:
            f.close()
            raise
        except (OSError, RuntimeError, KeyError, ValueError, TypeError, FEError) as e:
            f.close()
            raise StoreError(f"{path} is a damaged snapshot store ({type(e).__name__}: {e}); {hint}") from e
        return store

    def _check_consistency(self, verified=None):
        """Shapes, checksums of the data read at every opening, status codes. ``verified``: a
        read-only store of the same file just checked (see :meth:`open`) whose results are taken."""
        if verified is not None:
            self._unsealed = verified._unsealed.copy()
            self._cache = {name: data.copy() for name, data in verified._cache.items()}
            return
        n, d = self.n_rows, self.space.n_params
        shape = (n, len(self.load_levels), len(self.sensor_names))
        expected = {"parameters": (n, d), "unit_parameters": (n, d), "readings": shape,
                    "status": (n,), "error": (n,), "wall_time": (n,), "cpu_time": (n,)}
        if self.has_fields:
            expected["fields"] = shape[:2] + (self.n_nodes, 2)
        for name, shp in expected.items():
            if self._f[name].shape != shp:
                raise StoreError(
                    f"{self.path}: dataset {name!r} has shape {self._f[name].shape}, expected {shp}"
                )
        if self.checksummed:
            if (len(self._digests) != n
                    or (self.has_fields and self._f[f"{_CHECKSUMS}/fields"].shape != (n,))):
                raise StoreError(f"{self.path}: the checksum datasets do not match the {n} rows")
            self._unsealed = np.flatnonzero(self._digests[:, _WRITING])
            if len(self._unsealed) and self._f.mode == "r":
                logger.warning(
                    "%s: rows %s were being written when the last writer stopped; they are not "
                    "verified until the store is resumed", self.path, _rows_text(self._unsealed))
        else:
            logger.warning(
                "%s has no checksums: written by an older podkrig, so damage cannot be detected; "
                + REHASH_HINT.format(path=self.path), self.path)
        for name in _VERIFIED_AT_OPEN:  # reads the data: a damaged file fails here, not later
            self._cache[name] = self._read(name)
        codes = self._cache["status"]
        if not np.isin(codes, list(STATUS_NAMES)).all():
            raise StoreError(f"{self.path}: dataset 'status' holds codes other than {STATUS_NAMES}")

    @classmethod
    def create(cls, path, scenario, space, unit_samples, *, sampling, seed, fields=False):
        """Create a store with every row pending; refuses to overwrite an existing file.

        The file is written under a temporary name and renamed into place, so ``path`` either
        holds a complete store or nothing.

        Parameters
        ----------
        path : str or Path
        scenario : fe.Scenario
            Gives the spec, sensors, load levels and mesh size.
        space : ParameterSpace
        unit_samples : ndarray of shape (n_samples, n_params)
            The design in the unit cube.
        sampling : str
            Method that produced the design (``"sobol"``, ``"lhs"``, ``"random"``).
        seed : int
            Its seed.
        fields : bool
            Reserve a dataset for full displacement fields.

        Returns
        -------
        SnapshotStore
            Open for writing (``"r+"``).

        Raises
        ------
        StoreError
            ``path`` exists.
        """
        path = Path(path)
        if path.exists():
            raise StoreError(f"{path} already exists; a store is never overwritten")
        U = np.asarray(unit_samples, dtype=float)
        if U.ndim != 2 or U.shape[1] != space.n_params or U.shape[0] < 1:
            raise ValueError(f"unit_samples must have shape (n_samples >= 1, {space.n_params}); got {U.shape}")
        path.parent.mkdir(parents=True, exist_ok=True)
        acquire_lock(path)
        try:
            return cls._create_locked(path, scenario, space, U, sampling, seed, fields)
        finally:
            release_lock(path)  # the returned store holds its own

    @classmethod
    def _create_locked(cls, path, scenario, space, U, sampling, seed, fields):
        remove_orphans(path)
        if path.exists():  # created by another writer since the check above
            raise StoreError(f"{path} already exists; a store is never overwritten")
        n_loads, n_sensors = len(scenario.load_levels), len(scenario.sensor_names)
        attrs = {
            "format": FORMAT,
            "schema_version": SCHEMA_VERSION,
            "created": _now(),
            "software": software_versions(),
            "scenario_spec": scenario.spec.to_dict(),
            "parameter_space": space.to_dict(),
            "sensor_names": list(scenario.sensor_names),
            "sensor_definitions": scenario.sensor_definitions(),
            "load_levels": np.asarray(scenario.load_levels, dtype=float),
            "load_unit": scenario.load_unit,
            "reading_unit": "mm",
            "n_nodes": int(scenario.mesh.n_nodes),
            "n_dofs": int(scenario.n_dofs),
            "sampling_method": sampling,
            "sampling_seed": int(seed),
            "run_arguments": {"n": int(U.shape[0]), "seed": int(seed), "sampling": sampling, "fields": bool(fields)},
            "history": [{"time": _now(), "event": "created", "rows": int(U.shape[0])}],
        }
        n_nodes = int(scenario.mesh.n_nodes)
        check_disk_space(path.parent, estimate_store_bytes(U.shape[0], space.n_params, n_loads, n_sensors),
                          f"a store of {U.shape[0]} rows")
        tmp = tmp_path(path)
        try:
            try:
                with h5py.File(tmp, "w") as f:
                    _write_layout(f, attrs, space, U, n_loads, n_sensors, n_nodes, fields)
                    _write_checksums(f, fields)
            except (OSError, RuntimeError) as e:
                raise StoreError(f"cannot create {path}: {io_reason(e)}") from e
            publish(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
        logger.info("created snapshot store %s with %d pending rows", path, U.shape[0])
        return cls.open(path, "r+")

    @classmethod
    def extend(cls, path, unit_samples, *, source="unspecified"):
        """Append rows (e.g. the continuation of a Sobol' sequence) to a closed store.

        The store is rewritten to a temporary file with the new rows pending and renamed into
        place; existing rows, their results and the metadata are copied unchanged.

        Parameters
        ----------
        path : str or Path
        unit_samples : ndarray of shape (n_new, n_params)
            Unit-cube design of the new rows.
        source : str, optional
            How the new rows were chosen (recorded in the store's history), e.g.
            ``"sobol, seed 3, points 64..127"``.

        Raises
        ------
        StoreError
            The store cannot be opened (see :meth:`open`).
        """
        path = Path(path)
        acquire_lock(path)
        try:
            remove_orphans(path)
            cls._extend_locked(path, unit_samples, source)
        finally:
            release_lock(path)

    @classmethod
    def _extend_locked(cls, path, unit_samples, source):
        tmp = tmp_path(path)
        with cls.open(path, "r") as old:
            U_new = np.asarray(unit_samples, dtype=float)
            if U_new.ndim != 2 or U_new.shape[1] != old.space.n_params:
                raise ValueError(f"unit_samples must have shape (n_new, {old.space.n_params}); got {U_new.shape}")
            src = old._f
            n_old = old.n_rows
            n = n_old + U_new.shape[0]
            attrs = {k: src.attrs[k] for k in _ROOT_ATTRS}
            attrs = {k: json.loads(v) if k in _JSON_ATTRS else v for k, v in attrs.items()}
            attrs["run_arguments"] = dict(attrs["run_arguments"], n=n)
            attrs["history"] = attrs["history"] + [
                {"time": _now(), "event": "extended", "rows": n, "source": str(source),
                 "software": software_versions()}
            ]
            U = np.vstack([old._read("unit_parameters"), U_new])
            check_disk_space(path.parent, path.stat().st_size + estimate_store_bytes(
                n, old.space.n_params, old.n_loads, old.n_sensors), f"growing the store to {n} rows")
            try:
                with h5py.File(tmp, "w") as f:
                    _write_layout(f, attrs, old.space, U, len(old.load_levels), len(old.sensor_names),
                                  old.n_nodes, old.has_fields)
                    f["parameters"][:n_old] = old._read("parameters")  # the stored values, bit for bit
                    for name in ("readings", "error", "wall_time", "cpu_time", "status"):
                        f[name][:n_old] = old._read(name)  # verified against their checksums
                    if old.has_fields:
                        done = np.flatnonzero(old.done_mask())
                        for start in range(0, len(done), 64):
                            rows = done[start:start + 64]
                            f["fields"][rows] = old._read_fields(rows)
                    _write_checksums(f, old.has_fields)
                os.replace(tmp, path)  # we hold the store's lock: nobody else writes it
            except (OSError, RuntimeError) as e:
                raise StoreError(f"cannot grow {path} (it is unchanged): {io_reason(e)}") from e
            finally:
                tmp.unlink(missing_ok=True)
        logger.info("extended snapshot store %s from %d to %d rows", path, n_old, n)

    def close(self):
        """Flush and close the file and release the writer's lock (idempotent)."""
        try:
            if self._f.id.valid:
                self._f.close()
        finally:
            if self._locked:
                self._locked = False
                release_lock(self.path)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        state = "open" if self._f.id.valid else "closed"
        return f"<SnapshotStore {str(self.path)!r} ({state}, {self.n_rows} rows)>"

    # ------------------------------------------------------------------ checksums
    @property
    def _table(self):
        """The digest table ``/checksums/rows`` as an h5py dataset (for writing; reads use
        :func:`_read_whole`)."""
        return self._f[f"{_CHECKSUMS}/rows"]

    def _read(self, name):
        """A whole per-row dataset, verified against its row checksums.

        Raises
        ------
        IntegrityError
            Rows whose content does not match their checksum (named in the message).
        """
        if name in self._cache:
            return self._cache[name].copy()
        data = self._h5read(name, ...)
        if self.checksummed:
            bad = self._mismatched(name, data)
            if len(bad):
                raise IntegrityError(
                    f"{self.path}: rows {_rows_text(bad)} of dataset {name!r} do not match their checksums: "
                    "the file was damaged after it was written; the store is refused (check it with "
                    "'podkrig snapshots verify', then rebuild it or restore a copy)"
                )
        return data

    def _h5read(self, name, index):
        """``self._f[name][index]``; an HDF5 read error (a damaged file) becomes a StoreError."""
        try:
            if index is Ellipsis:
                return _read_whole(self._f, name)
            return self._f[name][index]
        except (OSError, RuntimeError, KeyError, ValueError, TypeError) as e:
            raise StoreError(
                f"{self.path}: dataset {name!r} cannot be read ({type(e).__name__}: {e}): the file is damaged; "
                "check it with 'podkrig snapshots verify', then rebuild it or restore a copy"
            ) from e

    def _mismatched(self, name, data):
        bad = mismatched_rows(data, self._digests[:, _ROW_DATASETS.index(name)])
        return np.setdiff1d(bad, self._unsealed) if len(self._unsealed) and len(bad) else bad

    def _read_fields(self, rows):
        """Fields of the given rows, ndarray (len(rows), n_loads, n_nodes, 2), each row verified."""
        out = np.empty((len(rows), self.n_loads, self.n_nodes, 2))
        for j, i in enumerate(rows):  # row by row: one chunk each, no full-dataset read
            out[j] = self._h5read("fields", i)
        if self.checksummed and len(rows):
            bad = row_digests(out) != self._h5read(f"{_CHECKSUMS}/fields", ...)[rows]
            bad &= ~np.isin(rows, self._unsealed)
            if bad.any():
                raise IntegrityError(
                    f"{self.path}: the displacement fields of rows {_rows_text(np.asarray(rows)[bad])} do not "
                    "match their checksums: the file was damaged after it was written; the store is refused"
                )
        return out

    def _reseal(self):
        """Recompute the checksums of rows a killed writer left half-written (writers only).

        Such rows were verified just before that write began (see :meth:`write_results`); their
        status is written last, so a row that did not reach ``done`` is rerun anyway.
        """
        if not self.checksummed or not len(self._unsealed):
            return
        rows = self._unsealed
        g = self._f[_CHECKSUMS]
        for col, name in enumerate(_ROW_DATASETS):
            self._digests[rows, col] = row_digests(self._f[name][...][rows])
        self._table[:self.n_rows] = self._digests
        if self.has_fields:
            fd = g["fields"][...]
            for i in rows:
                fd[i] = row_digests(self._f["fields"][i][None])[0]
            g["fields"][...] = fd
        self._f.flush()
        self._digests[:, _WRITING] = 0
        self._table[:self.n_rows] = self._digests
        self._f.flush()
        logger.info("%s: resealed rows %s left by an interrupted write", self.path, _rows_text(rows))
        self._unsealed = np.zeros(0, dtype=np.int64)

    def verify(self):
        """Check every row of every dataset (fields included) against its checksum.

        Returns
        -------
        VerifyReport
            Never raises for a mismatch: the report names the rows.
        """
        report = VerifyReport(str(self.path), self.checksummed, rows=self.n_rows,
                              unsealed_rows=[int(i) for i in self._unsealed])
        if not self.checksummed:
            return report
        report.metadata_ok = np.array_equal(self._meta_words[4:],
                                            _sha_words(metadata_digest(self._f, _datasets(self.has_fields))))
        for name in _ROW_DATASETS:
            bad = self._mismatched(name, self._h5read(name, ...))
            if len(bad):
                report.bad_rows[name] = [int(i) for i in bad]
        if self.has_fields:
            stored = self._h5read(f"{_CHECKSUMS}/fields", ...)
            bad = []
            for start in range(0, self.n_rows, 256):
                rows = np.arange(start, min(start + 256, self.n_rows))
                block = np.stack([self._h5read("fields", i) for i in rows])
                bad += [int(i) for i in rows[row_digests(block) != stored[rows]] if i not in self._unsealed]
            if bad:
                report.bad_rows["fields"] = bad
        return report

    def rehash(self):
        """Add checksums to a store written before they existed (open with ``mode="r+"``).

        The current content is taken as correct: run it only on a store you trust.

        Raises
        ------
        StoreError
            The store already has checksums (rehashing would hide damage) or is open read-only.
        """
        if self._f.mode != "r+":
            raise StoreError(f"{self.path} is open read-only; open it with mode='r+' to add checksums")
        if self.checksummed:
            raise StoreError(
                f"{self.path} already has checksums; they are never recomputed (that would hide damage). "
                "Use 'podkrig snapshots verify' to check it"
            )
        check_disk_space(self.path.parent, self.n_rows * 9 * 8, "adding checksums")
        try:
            _write_checksums(self._f, self.has_fields)
            self._f.flush()
            table = self._table[...]
            self._digests, self._meta_words = table[:self.n_rows], table[self.n_rows]
        except (OSError, RuntimeError) as e:
            raise StoreError(f"cannot add checksums to {self.path}: {io_reason(e)}") from e
        self.checksummed = True

    # ------------------------------------------------------------------ reading
    @property
    def n_loads(self):
        return len(self.load_levels)

    @property
    def n_sensors(self):
        return len(self.sensor_names)

    def status(self):
        """Per-row status codes, ndarray of shape (n_rows,) int8 (see :data:`STATUS_NAMES`)."""
        return self._read("status").astype(np.int8)

    def done_mask(self):
        """Rows that hold a finished snapshot, bool ndarray of shape (n_rows,)."""
        return self.status() == DONE

    def failed_mask(self):
        """Rows whose FE run failed, bool ndarray of shape (n_rows,)."""
        return self.status() == FAILED

    def pending_mask(self):
        """Rows not run yet, bool ndarray of shape (n_rows,)."""
        return self.status() == PENDING

    def counts(self):
        """``{"total", "done", "failed", "pending"}`` row counts."""
        s = self.status()
        return {"total": self.n_rows, "done": int((s == DONE).sum()), "failed": int((s == FAILED).sum()),
                "pending": int((s == PENDING).sum())}

    def errors(self):
        """Error text of each failed row, ``{row: text}``."""
        rows = np.flatnonzero(self.failed_mask())
        if not len(rows):
            return {}
        raw = self._read("error")
        return {int(i): raw[i].decode("utf-8", errors="replace") for i in rows}

    def partial_rows(self):
        """Failed rows that hold a partial response (nonlinear runs that stopped early), with their
        reach: ``{row: {"status", "limit", "reached", "unit"}}`` — the solver status, the budget
        limit that ended the run (None: it did not converge), the last converged control value in
        ``unit``. Rows written before the reach was recorded have ``limit`` and ``reached`` None."""
        out = {}
        for row, text in self.errors().items():
            if not text.startswith(PARTIAL_PREFIX):
                continue
            m = _PARTIAL_HEAD.match(text)
            out[row] = ({"status": m["status"], "limit": m["limit"], "reached": float(m["reached"]), "unit": m["unit"]}
                        if m else {"status": None, "limit": None, "reached": None, "unit": self.load_unit})
        return out

    def wall_times(self):
        """Wall time of each row's FE run, ndarray of shape (n_rows,), s; NaN where not run."""
        return self._read("wall_time")

    def cpu_times(self):
        """CPU time of each row's FE run (the running thread's), ndarray of shape (n_rows,), s; NaN where not run."""
        return self._read("cpu_time")

    def _select(self, name, only_done):
        data = self._read(name)
        return data[self.done_mask()] if only_done else data

    def parameters(self, physical=True, only_done=True):
        """Parameter vectors of the rows.

        Parameters
        ----------
        physical : bool
            Physical values (each column in its parameter's unit) or unit-cube coordinates.
        only_done : bool
            Only rows with a finished snapshot (the rows of :meth:`snapshot_matrix`).

        Returns
        -------
        ndarray of shape (n_done or n_rows, n_params)
        """
        return self._select("parameters" if physical else "unit_parameters", only_done)

    def readings(self, only_done=True):
        """Sensor readings, ndarray of shape (n_done or n_rows, n_loads, n_sensors), mm (NaN if not done)."""
        return self._select("readings", only_done)

    def fields(self, only_done=True):
        """Nodal displacement fields, ndarray of shape (n_done or n_rows, n_loads, n_nodes, 2), mm.

        Loads every selected row into memory: ``8 * n_loads * n_nodes * 2`` bytes per row.

        Raises
        ------
        StoreError
            The store was created without fields.
        """
        if not self.has_fields:
            raise StoreError(f"{self.path} holds no displacement fields; rerun into a new store with --fields")
        rows = np.flatnonzero(self.done_mask()) if only_done else np.arange(self.n_rows)
        return self._read_fields(rows)

    def snapshot_matrix(self):
        """Finished snapshots as rows, ndarray of shape (n_done, n_loads * n_sensors), mm.

        Each row is a response's readings flattened in C order (all sensors at the first load
        level, then the next); its parameters are ``parameters()[i]``.
        """
        Y = self.readings(only_done=True)
        return Y.reshape(len(Y), self.n_loads * self.n_sensors)

    def content_hash(self):
        """SHA-256 of the finished rows: their indices, physical parameters and readings.

        Two stores with the same finished rows hash equal whatever their history; any change to a
        finished value changes the hash. Returns ``"sha256:<hex>"``.
        """
        done = self.done_mask()
        h = hashlib.sha256(b"podkrig.snapshots.content/1")
        h.update(np.flatnonzero(done).astype("<i8").tobytes())
        h.update(np.ascontiguousarray(self._read("parameters")[done], dtype="<f8").tobytes())
        h.update(np.ascontiguousarray(self._read("readings")[done], dtype="<f8").tobytes())
        return "sha256:" + h.hexdigest()

    def info(self):
        """Everything the store knows about itself, as a JSON-able dict."""
        wall = self.wall_times()
        cpu = self.cpu_times()
        cpu = cpu[np.isfinite(cpu)]
        ran = np.isfinite(wall)
        errors = self.errors()
        return {
            "path": str(self.path),
            "file_size_bytes": self.path.stat().st_size,
            "format": FORMAT,
            "schema_version": self.schema_version,
            "created": self.created,
            "software": self.software,
            "history": self.history,
            "scenario_spec": self.spec.to_dict(),
            "solver_settings": {k: v for k, v in self.spec.to_dict().items() if k in SOLVER_SETTINGS},
            "parameter_space": self.space.to_dict(),
            "sampling": {"method": self.sampling, "seed": self.seed},
            "run_arguments": self.run_arguments,
            "rows": self.counts(),
            "sensor_names": list(self.sensor_names),
            "sensor_definitions": self.sensor_definitions,
            "load_levels": self.load_levels.tolist(),
            "load_unit": self.load_unit,
            "reading_unit": self.reading_unit,
            "n_nodes": self.n_nodes,
            "n_dofs": self.n_dofs,
            "fields": self.has_fields,
            "wall_time_s": {"total": float(wall[ran].sum()), "mean": float(wall[ran].mean()) if ran.any() else None},
            "cpu_time_s": {"total": float(cpu.sum()), "mean": float(cpu.mean()) if len(cpu) else None},
            "failures": [{"row": i, "error": e} for i, e in list(errors.items())[:20]],
            "partial_rows": {str(i): v for i, v in self.partial_rows().items()},
            "content_hash": self.content_hash(),
            "checksums": self.checksummed,
        }

    # ------------------------------------------------------------------ writing
    def write_results(self, rows, status, readings, errors, wall_times, fields=None, cpu_times=None):
        """Record finished rows and flush; finished rows are never rewritten.

        Data first (flushed), status last (flushed): a crash in between leaves the rows pending.

        Parameters
        ----------
        rows : array_like of int, shape (k,)
            Row indices, distinct.
        status : array_like of int, shape (k,)
            :data:`DONE` or :data:`FAILED` per row.
        readings : ndarray of shape (k, n_loads, n_sensors)
            mm; stored as NaN for failed rows, except those whose error starts with
            :data:`PARTIAL_PREFIX` (a nonlinear run that stopped early keeps the levels it reached).
        errors : sequence of str, length k
            Error text ('' for done rows); the first 512 UTF-8 bytes are kept.
        wall_times : array_like of shape (k,)
            Wall time of each FE run, s.
        fields : ndarray of shape (k, n_loads, n_nodes, 2), optional
            mm; required when the store has fields.
        cpu_times : array_like of shape (k,), optional
            CPU time of each FE run, s (NaN when not given).

        Raises
        ------
        StoreError
            The store is read-only, a row is out of range or already done.
        """
        if self._f.mode != "r+":
            raise StoreError(f"{self.path} is open read-only; open it with mode='r+' to write")
        rows = np.asarray(rows, dtype=np.int64)
        order = np.argsort(rows)
        rows = rows[order]
        k = len(rows)
        if k == 0:
            return
        if len(np.unique(rows)) != k or rows[0] < 0 or rows[-1] >= self.n_rows:
            raise StoreError(f"rows must be distinct indices in [0, {self.n_rows}); got {rows.tolist()}")
        status = np.asarray(status, dtype=np.int8)[order]
        if not np.isin(status, (DONE, FAILED)).all():
            raise ValueError(f"status must be DONE ({DONE}) or FAILED ({FAILED}); got {status.tolist()}")
        readings = np.asarray(readings, dtype=float)[order]
        if readings.shape != (k, self.n_loads, self.n_sensors):
            raise ValueError(
                f"readings must have shape ({k}, {self.n_loads}, {self.n_sensors}); got {readings.shape}"
            )
        keep = (status == DONE) | np.array([errors[i].startswith(PARTIAL_PREFIX) for i in order])
        readings = np.where(keep[:, None, None], readings, np.nan)
        text = np.array([errors[i].encode("utf-8")[:ERROR_BYTES] for i in order], dtype=f"S{ERROR_BYTES}")
        wall = np.asarray(wall_times, dtype=float)[order]
        cpu = np.full(k, np.nan) if cpu_times is None else np.asarray(cpu_times, dtype=float)[order]
        current = self.status()[rows]
        if np.any(current == DONE):
            raise StoreError(
                f"{self.path}: rows {rows[current == DONE].tolist()} are already done; finished rows "
                "are never rewritten"
            )
        if self.has_fields:
            if fields is None:
                raise ValueError(f"{self.path} stores fields; pass fields of shape ({k}, {self.n_loads}, {self.n_nodes}, 2)")
            fields = np.asarray(fields, dtype=float)[order]
            need = int((status == DONE).sum()) * fields[0].nbytes * 101 // 100  # gzip never grows more than ~0.03 %
        else:
            need = 0
        free = free_bytes(self.path.parent)
        if free is not None and free < need + DISK_MARGIN:
            raise StoreError(self._stopped(
                f"disk full: {human_bytes(free)} free in {self.path.parent}, the next {k} rows need about "
                f"{human_bytes(need)} plus a safety margin of {human_bytes(DISK_MARGIN)}, "
                f"{human_bytes(need + DISK_MARGIN)} in all"))
        try:
            self._write_rows(rows, status, readings, text, wall, cpu, fields)
        except (OSError, RuntimeError) as e:
            reason = io_reason(e)
            head = "disk full" if reason.startswith("disk full") else f"cannot write {self.path} ({reason})"
            raise StoreError(self._stopped(head)) from e

    def _stopped(self, head):
        try:
            done = int((self._f["status"][...] == DONE).sum())
        except (OSError, RuntimeError):
            done = "the finished"
        return (f"{head}: {done} rows written and kept in {self.path}; the rows of this batch stay "
                "pending — fix the cause (free space) and rerun the same command to resume")

    def _write_rows(self, rows, status, readings, text, wall, cpu, fields):
        """Journal, data, status, checksums, each step flushed (see the module's crash safety)."""
        k = len(rows)
        contiguous = rows[-1] - rows[0] + 1 == k
        sel = slice(int(rows[0]), int(rows[-1]) + 1) if contiguous else rows
        g = self._f[_CHECKSUMS] if self.checksummed else None
        if g is not None:
            self._table[sel, _WRITING] = 1  # a crash from here on leaves these rows to be resealed
            self._f.flush()
        self._f["readings"][sel] = readings
        self._f["error"][sel] = text
        self._f["wall_time"][sel] = wall
        self._f["cpu_time"][sel] = cpu
        if self.has_fields:
            for j, i in enumerate(rows):
                if status[j] == DONE:
                    self._f["fields"][i] = fields[j]
        self._f.flush()
        self._f["status"][sel] = status
        self._f.flush()
        self._cache["status"][sel] = status
        if g is None:
            return
        digests = np.stack([row_digests(self._f[name][sel]) for name in _ROW_DATASETS] + [np.ones(k, "u8")], axis=1)
        self._table[sel] = digests  # still marked as being written
        self._digests[sel] = digests
        if self.has_fields:
            fd = g["fields"]
            for j, i in enumerate(rows):
                if status[j] == DONE:
                    fd[i] = row_digests(np.ascontiguousarray(fields[j], dtype="<f8")[None])[0]
        self._f.flush()
        self._table[sel, _WRITING] = 0
        self._digests[sel, _WRITING] = 0
        self._f.flush()
