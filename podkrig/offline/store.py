"""The snapshot store: a self-describing, resumable HDF5 file of FE responses over a sampling design.

One row per sample, in sample order. Every row exists from creation on (status ``pending``), with
its parameter vector; the offline runner (:mod:`podkrig.runner`) fills rows in and marks them
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
    /error                (n,) fixed-length UTF-8 bytes (first 512 bytes of the error text)
    /wall_time            (n,) float64, s; wall time of the FE run, NaN until run
    /cpu_time             (n,) float64, s; CPU time of the thread that ran it (below wall time when
                          the worker waited for a core), NaN until run
    /fields               (n, n_loads, n_nodes, 2) float64, mm; optional, gzip, one chunk per row

Crash safety. A store is created in a temporary file and renamed into place, so it either exists
whole or not at all; growing it (Sobol' append) rewrites it the same way. Every per-row dataset
except ``fields`` is contiguous with its space allocated at creation, so writing a row changes
raw bytes only, never the file's structure. :meth:`SnapshotStore.write_results` writes the data,
flushes, then writes the status and flushes again: a process killed at any moment leaves a file
whose ``done`` rows are complete, and an unfinished row stays ``pending``.

Example
-------
>>> with SnapshotStore.open("snapshots/panel.h5") as store:      # doctest: +SKIP
...     Y = store.snapshot_matrix()      # (n_done, n_loads * n_sensors), mm
...     X = store.parameters()           # (n_done, n_params), physical units

References
----------
.. [1] h5py documentation, "Attributes", https://docs.h5py.org/en/stable/high/attr.html
"""

import datetime
import hashlib
import json
import logging
import os
import sys
from pathlib import Path

import h5py
import numpy as np

from podkrig import __version__
from podkrig.exceptions import SchemaError, StoreError
from podkrig.parameters import ParameterSpace

logger = logging.getLogger(__name__)

FORMAT = "podkrig.snapshots"
SCHEMA_VERSION = 1
PENDING, DONE, FAILED = 0, 1, 2
#: Error prefix of failed rows that hold a partial response (a nonlinear run that stopped early)
PARTIAL_PREFIX = "NotConverged"
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


def _now():
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


def _tmp_path(path):
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


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

    def __init__(self, file, path):
        self._f = file
        self.path = Path(path)
        a = {k: self._f.attrs[k] for k in _ROOT_ATTRS}
        a = {k: json.loads(v) if k in _JSON_ATTRS else v for k, v in a.items()}
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
        store = cls._open_checked(path, "r")
        if mode == "r":
            return store
        store.close()
        return cls._open_checked(path, "r+")

    @classmethod
    def _open_checked(cls, path, mode):
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
                raise StoreError(
                    f"{path} is in use by another process (HDF5 file lock); wait for that job to "
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
            store = cls(f, path)
            store._check_consistency()
        except StoreError:
            f.close()
            raise
        except (OSError, KeyError, ValueError, TypeError) as e:
            f.close()
            raise StoreError(f"{path} is a damaged snapshot store ({type(e).__name__}: {e}); {hint}") from e
        return store

    def _check_consistency(self):
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
        codes = self._f["status"][...]  # reads the data: a damaged file fails here, not later
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
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = _tmp_path(path)
        try:
            with h5py.File(tmp, "w") as f:
                _write_layout(f, attrs, space, U, n_loads, n_sensors, int(scenario.mesh.n_nodes), fields)
            os.replace(tmp, path)
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
        tmp = _tmp_path(path)
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
            U = np.vstack([src["unit_parameters"][...], U_new])
            try:
                with h5py.File(tmp, "w") as f:
                    _write_layout(f, attrs, old.space, U, len(old.load_levels), len(old.sensor_names),
                                  old.n_nodes, old.has_fields)
                    f["parameters"][:n_old] = src["parameters"][...]  # the stored values, bit for bit
                    for name in ("readings", "error", "wall_time", "cpu_time", "status"):
                        f[name][:n_old] = src[name][...]
                    if old.has_fields:
                        for i in np.flatnonzero(src["status"][...] == DONE):
                            f["fields"][i] = src["fields"][i]
                os.replace(tmp, path)
            finally:
                tmp.unlink(missing_ok=True)
        logger.info("extended snapshot store %s from %d to %d rows", path, n_old, n)

    def close(self):
        """Flush and close the file (idempotent)."""
        if self._f.id.valid:
            self._f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        state = "open" if self._f.id.valid else "closed"
        return f"<SnapshotStore {str(self.path)!r} ({state}, {self.n_rows} rows)>"

    # ------------------------------------------------------------------ reading
    @property
    def n_loads(self):
        return len(self.load_levels)

    @property
    def n_sensors(self):
        return len(self.sensor_names)

    def status(self):
        """Per-row status codes, ndarray of shape (n_rows,) int8 (see :data:`STATUS_NAMES`)."""
        return self._f["status"][...].astype(np.int8)

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
        raw = self._f["error"][...]
        return {int(i): raw[i].decode("utf-8", errors="replace") for i in rows}

    def wall_times(self):
        """Wall time of each row's FE run, ndarray of shape (n_rows,), s; NaN where not run."""
        return self._f["wall_time"][...]

    def cpu_times(self):
        """CPU time of each row's FE run (the running thread's), ndarray of shape (n_rows,), s; NaN where not run."""
        return self._f["cpu_time"][...]

    def _select(self, name, only_done):
        data = self._f[name][...]
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
        out = np.empty((len(rows), self.n_loads, self.n_nodes, 2))
        for j, i in enumerate(rows):  # row by row: one chunk each, no full-dataset read
            out[j] = self._f["fields"][i]
        return out

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
        h.update(np.ascontiguousarray(self._f["parameters"][done], dtype="<f8").tobytes())
        h.update(np.ascontiguousarray(self._f["readings"][done], dtype="<f8").tobytes())
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
            "content_hash": self.content_hash(),
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
        current = self._f["status"][...][rows]
        if np.any(current == DONE):
            raise StoreError(
                f"{self.path}: rows {rows[current == DONE].tolist()} are already done; finished rows "
                "are never rewritten"
            )
        contiguous = rows[-1] - rows[0] + 1 == k
        sel = slice(int(rows[0]), int(rows[-1]) + 1) if contiguous else rows
        self._f["readings"][sel] = readings
        self._f["error"][sel] = text
        self._f["wall_time"][sel] = wall
        self._f["cpu_time"][sel] = cpu
        if self.has_fields:
            if fields is None:
                raise ValueError(f"{self.path} stores fields; pass fields of shape ({k}, {self.n_loads}, {self.n_nodes}, 2)")
            fields = np.asarray(fields, dtype=float)[order]
            for j, i in enumerate(rows):
                if status[j] == DONE:
                    self._f["fields"][i] = fields[j]
        self._f.flush()
        self._f["status"][sel] = status
        self._f.flush()
