"""The stage cache of a study: manifests, input hashes and output checks.

Each stage writes ``DIR/stages/STAGE.json``, a manifest with the hash of its inputs (settings,
and the SHA-256 of the files it reads: upstream outputs, the measurement CSV), the SHA-256 of
every file it wrote, its JSON results and its wall time. A stage whose manifest has the same
input hash and whose files are unchanged is *cached*: :meth:`StageCache.stage` does not run it
again. The stages themselves are in :mod:`podkrig.study.stages`.
"""

import datetime
import hashlib
import json
import logging
import os
import time
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from podkrig import __version__
from podkrig.limits import MAX_ARRAY_FILE_BYTES, MAX_JSON_BYTES, human_bytes, read_bounded

logger = logging.getLogger(__name__)

MANIFEST_VERSION = 1


class Progress:
    """Callbacks of :func:`run_study` (the default does nothing; the CLI draws progress bars)."""

    def stage_started(self, name, title, total=None):
        """A stage starts; ``total`` FE runs for FE stages (None for others)."""

    def advance(self, completed, total):
        """``completed`` of ``total`` FE runs of the running stage are done."""

    def stage_finished(self, record):
        """A stage finished or was found cached (:class:`StageRecord`)."""


@dataclass(frozen=True)
class StageRecord:
    """What happened to one stage in a run.

    Attributes
    ----------
    name, title : str
    cached : bool
        True when the stage's previous results were reused.
    seconds : float
        Wall time of this run of the stage, s (about 0 when cached).
    fe_runs : int
        FE runs done by this run of the stage (0 when cached).
    manifest : dict
        The stage manifest (``result`` holds its numbers).
    """

    name: str
    title: str
    cached: bool
    seconds: float
    fe_runs: int
    manifest: dict

    @property
    def result(self):
        return self.manifest["result"]


def jsonable(v):
    """JSON form of NumPy arrays and scalars and of paths (``default=`` of :func:`json.dumps`)."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.integer, np.floating, np.bool_)):
        return v.item()
    if isinstance(v, Path):
        return str(v)
    raise TypeError(f"not JSON-able: {type(v).__name__}")


def input_hash(name, inputs):
    """SHA-256 of a stage's name, the package version and its inputs (canonical JSON)."""
    text = json.dumps({"stage": name, "podkrig": __version__, "manifest": MANIFEST_VERSION, "inputs": inputs},
                      sort_keys=True, default=jsonable)
    return hashlib.sha256(text.encode()).hexdigest()


def file_sha256(path):
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def now():
    """The current UTC time, ISO 8601 to the second."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


class StageCache:
    """Stages of one run in an output folder: each is run, or reused when cached.

    Parameters
    ----------
    out : str or Path
        The output folder; manifests go to ``out/stages/STAGE.json``.
    progress : Progress
    """

    def __init__(self, out, progress):
        self.out = Path(out)
        self.progress = progress
        self.records = []

    def outputs(self, name):
        """Output files (relative paths) → SHA-256 of a finished stage."""
        return self.manifest(name)["outputs"]

    def manifest(self, name):
        for record in self.records:
            if record.name == name:
                return record.manifest
        raise KeyError(name)

    def stage(self, name, title, inputs, compute, total=None):
        """Run ``compute() -> (result, outputs, fe_runs)`` unless the stage is cached.

        ``result`` is a JSON-able dict, ``outputs`` the files written (paths relative to the
        output folder). Returns the stage manifest.
        """
        digest = input_hash(name, inputs)
        manifest = self._cached_manifest(name, digest)
        if manifest is not None:
            record = StageRecord(name, title, True, 0.0, 0, manifest)
        else:
            self.progress.stage_started(name, title, total)
            t0 = time.perf_counter()
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                result, outputs, fe_runs = compute()
            seconds = time.perf_counter() - t0
            # warnings of the numerics (e.g. a Sobol' size that is not a power of two) become notes in the report
            notes = sorted({str(w.message) for w in caught if issubclass(w.category, (UserWarning, RuntimeWarning))})
            result = dict(result, notes=result.get("notes", []) + notes)
            manifest = {
                "stage": name, "title": title, "input_hash": digest, "inputs": inputs,
                "outputs": {str(p): file_sha256(self.out / p) for p in outputs},
                "result": result, "seconds": seconds, "fe_runs": fe_runs, "finished": now(),
                "podkrig": __version__,
            }
            write_json(self.out / "stages" / f"{name}.json", manifest)
            record = StageRecord(name, title, False, seconds, fe_runs, manifest)
        self.records.append(record)
        self.progress.stage_finished(record)
        return manifest

    def is_cached(self, name, inputs):
        """Whether :meth:`stage` would reuse stage ``name`` with these inputs (nothing is run)."""
        return self._cached_manifest(name, input_hash(name, inputs)) is not None

    def _cached_manifest(self, name, digest):
        """The manifest of stage ``name`` when it has this input hash and its files are unchanged, else None."""
        manifest = read_manifest(self.out / "stages" / f"{name}.json")
        if manifest is not None and manifest.get("input_hash") == digest and self.unchanged(manifest["outputs"]):
            return manifest
        return None

    def unchanged(self, outputs):
        """Whether every output file (relative path → SHA-256) exists with these bytes."""
        return all((self.out / p).is_file() and file_sha256(self.out / p) == sha for p, sha in outputs.items())


def read_manifest(path):
    """A manifest (or any JSON file), or None when it is missing or unreadable; a file over
    :data:`~podkrig.limits.MAX_JSON_BYTES` is unreadable (logged), never read whole."""
    try:
        return json.loads(read_bounded(path, MAX_JSON_BYTES, "stage manifest").decode("utf-8"))
    except OSError:
        return None
    except ValueError as e:  # not JSON, not UTF-8, or over the cap: the stage runs again
        if "the cap" in str(e):
            logger.warning("%s; the stage runs again", e)
        return None


def read_arrays(path):
    """The arrays of an ``.npz`` file podkrig wrote (``region.npz``, ``probe.npz``), name → array.

    The file must be a regular file of at most :data:`~podkrig.limits.MAX_ARRAY_FILE_BYTES`, and
    so must the sum of its members' sizes once decompressed (as the zip directory declares them,
    which ``zipfile`` holds each member to); nothing is unpickled.

    Raises
    ------
    ValueError
        A file over the cap (naming the file, its size and the cap), or not an ``.npz`` file.
    """
    path = Path(path)
    cap = MAX_ARRAY_FILE_BYTES
    too_large = f"{path}: larger than {human_bytes(cap)} ({cap} bytes), the cap for an array file: "
    if not path.is_file():
        raise ValueError(f"{path}: not a regular file; an array file (.npz) is expected")
    size = path.stat().st_size
    if size > cap:
        raise ValueError(f"{too_large}it is {human_bytes(size)}")
    try:
        with zipfile.ZipFile(path) as z:
            unpacked = sum(info.file_size for info in z.infolist())
    except zipfile.BadZipFile:
        raise ValueError(f"{path}: not an .npz array file (damaged or of another kind)") from None
    if unpacked > cap:
        raise ValueError(f"{too_large}its arrays unpack to {human_bytes(unpacked)}")
    with np.load(path, allow_pickle=False) as f:
        return {name: f[name] for name in f.files}


def write_json(path, data):
    """Write ``data`` as sorted, indented JSON, atomically (a temporary file, then a rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True, default=jsonable, ensure_ascii=False), encoding="utf-8")
    tmp.replace(path)


__all__ = ["MANIFEST_VERSION", "Progress", "StageCache", "StageRecord", "file_sha256", "input_hash", "jsonable", "now",
           "read_arrays", "read_manifest", "write_json"]
