"""The surrogate file: a fitted :class:`~podkrig.surrogate.PODKriging` in HDF5 (no pickle).

Layout (schema 3; ``/`` is the root group)::

    /            attrs  format = "podkrig.surrogate", schema_version, settings (JSON: the POD's and
                        the regressor's settings), provenance (JSON), parameter_space (JSON or
                        null), output_shape (JSON), saved (UTC, ISO 8601), package_version,
                        backend, backend_version, and the checksum of :mod:`podkrig.h5integrity`
                 data   X (n_samples, n_params) physical units, U (unit cube), lower, upper
                        (n_params,), train_norm, train_residual_norm (n_samples,)
    /pod         attrs  method, n_samples
                 data   mean, modes, singular_values, energy, residual_variance
    /kriging     attrs  and data of the backend's ``to_arrays`` (ours: ranges, beta, mu, sigma2,
                        alpha, L, Q, ... and kind, variogram, nugget, fit_method)

Schema history: 2 records the backend (attrs ``backend``, ``backend_version``); 3 records how the
kriging hyperparameters were fitted (attr ``fit_method``, dataset ``subset_index``) and, after a
subset fit, leaves out the factors ``L`` and ``Q`` (rebuilt at load), which schema-2 readers
require. Files of schemas 1 and 2 are still read (as exact fits of the ``"podkrig"`` backend for
schema 1).

The surrogate itself exchanges its state as arrays (:meth:`PODKriging.to_arrays` /
:meth:`PODKriging.from_arrays`); this module is the only place that knows the file.

Example
-------
>>> import numpy as np, pathlib, tempfile
>>> from podkrig.surrogate import PODKriging
>>> from podkrig.io.surrogate_file import load_surrogate, save_surrogate
>>> X = np.random.default_rng(0).uniform(1.0, 2.0, size=(8, 2))
>>> sur = PODKriging().fit(X, np.stack([X[:, 0] + X[:, 1], X[:, 0] * X[:, 1]], axis=1))
>>> path = pathlib.Path(tempfile.mkdtemp()) / "s.h5"
>>> save_surrogate(sur, path)
>>> bool(np.array_equal(load_surrogate(path).predict(X[:3]), sur.predict(X[:3])))
True
"""

import datetime
import json
import logging
from pathlib import Path

import h5py
import numpy as np

from podkrig import __version__, h5integrity
from podkrig.exceptions import SchemaError, StoreError
from podkrig.limits import MAX_ARRAY_FILE_BYTES, human_bytes
from podkrig.surrogate.podkriging import PODKriging

logger = logging.getLogger(__name__)

FORMAT = "podkrig.surrogate"
SCHEMA_VERSION = 3
READABLE_SCHEMAS = (1, 2, 3)
#: root attributes stored as JSON text
_JSON_ATTRS = ("settings", "provenance", "parameter_space", "output_shape")
#: the groups of the surrogate's parts
_PARTS = ("pod", "kriging")


def save_surrogate(surrogate, path):
    """Write a fitted surrogate to an HDF5 file, with its provenance.

    Parameters
    ----------
    surrogate : PODKriging
        Fitted.
    path : str or Path
        Written atomically (a temporary file beside it, sealed with a checksum, then renamed).

    Raises
    ------
    NotFittedError
        ``surrogate`` is not fitted.
    """
    arrays, attrs = surrogate.to_arrays()
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["format"] = FORMAT
            f.attrs["schema_version"] = SCHEMA_VERSION
            for name in _JSON_ATTRS:
                f.attrs[name] = json.dumps(attrs[name], sort_keys=name in ("settings", "provenance"),
                                           default=_jsonable)
            f.attrs["saved"] = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
            f.attrs["package_version"] = __version__
            f.attrs["backend"] = attrs["backend"]
            f.attrs["backend_version"] = attrs["backend_version"]
            for name, data in arrays.items():
                if name not in _PARTS:
                    f.create_dataset(name, data=data)
            f["X"].attrs["unit"] = "physical parameter units"
            for part in _PARTS:
                g = f.create_group(part)
                g.attrs.update(attrs[part])
                for name, data in arrays[part].items():
                    g.create_dataset(name, data=data)
        h5integrity.seal(tmp)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


def load_surrogate(path):
    """Read a surrogate written by :func:`save_surrogate`; predictions are bitwise identical.

    Reads schema 3, the files of schema 2 (written before the fit method was recorded: exact
    fits) and of schema 1 (written before the backend was recorded; always ``"podkrig"``), whose
    kriging group has the same arrays.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    PODKriging
        Fitted.

    Raises
    ------
    StoreError
        Missing, unreadable, damaged or non-surrogate file, or one over
        :data:`~podkrig.limits.MAX_ARRAY_FILE_BYTES` on disk or in its arrays unpacked (naming the cap).
    SchemaError
        Unknown schema version.
    """
    path = Path(path)
    if not path.is_file():
        raise StoreError(f"no surrogate file at {path}; build one with 'podkrig surrogate build'")
    cap = MAX_ARRAY_FILE_BYTES
    too_large = f"{path}: larger than {human_bytes(cap)} ({cap} bytes), the cap for a surrogate file: "
    if path.stat().st_size > cap:
        raise StoreError(f"{too_large}it is {human_bytes(path.stat().st_size)}")
    if not h5integrity.verify(path, "surrogate"):
        logger.warning("%s has no checksum (written by an older podkrig): damage cannot be detected; rebuild it", path)
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise StoreError(f"{path} cannot be read as HDF5 ({e}); rebuild the surrogate") from e
    with f:
        if f.attrs.get("format") != FORMAT:
            raise StoreError(f"{path} is not a podkrig surrogate (format {f.attrs.get('format')!r}); "
                             "pass the file written by 'podkrig surrogate build'")
        version = f.attrs.get("schema_version")
        version = int(version) if isinstance(version, (int, np.integer)) else version  # 99, not np.int64(99)
        if version not in READABLE_SCHEMAS:
            raise SchemaError(f"{path} has surrogate schema version {version!r}; "
                              f"this podkrig reads {', '.join(map(str, READABLE_SCHEMAS))}; rebuild it")
        sizes = []  # the arrays' sizes as their headers declare them (a compressed array unpacks to these)
        f.visititems(lambda name, item: sizes.append(item.nbytes) if isinstance(item, h5py.Dataset) else None)
        if sum(sizes) > cap:
            raise StoreError(f"{too_large}its arrays unpack to {human_bytes(sum(sizes))}")
        try:
            attrs = {name: json.loads(f.attrs[name]) for name in _JSON_ATTRS}
            if "backend" in f.attrs:  # schema 1: always ours
                attrs["backend"] = str(f.attrs["backend"])
            arrays = {name: f[name][...] for name in ("X", "U", "lower", "upper", "train_norm",
                                                       "train_residual_norm")}
            for part in _PARTS:
                g = f[part]
                arrays[part] = {name: g[name][...] for name in g}
                attrs[part] = dict(g.attrs)
            return PODKriging.from_arrays(arrays, attrs)
        except (KeyError, ValueError, TypeError) as e:
            raise StoreError(f"{path} is a damaged surrogate file ({type(e).__name__}: {e}); rebuild it") from e


def _jsonable(v):
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.integer, np.floating)):
        return v.item()
    return str(v)


__all__ = ["FORMAT", "READABLE_SCHEMAS", "SCHEMA_VERSION", "load_surrogate", "save_surrogate"]
