"""Named input limits shared by the command line, the study file and the Python API.

Every limit is a module constant with the reason for its value; every ``check_*`` function raises
:class:`ValueError` (which the CLI prints as a one-line ``error:``) naming the setting, the value and
what is allowed — with a memory or disk estimate where size is the reason.
"""

import math
import re
from pathlib import Path

#: Region-of-equivalence samples per round: below 1024 the sampled region is far too narrow (a
#: 16-sample "region" called an unidentifiable parameter identified, issue 13 #5); above 2^24 one
#: round's predictions (n × outputs × 8 B, ~100 outputs) exceed ~13 GiB.
REGION_SAMPLES_MIN = 1024
REGION_SAMPLES_MAX = 2**24
#: Rows of a snapshot store: above this, ask first (hours of FE work, a large file) ...
CONFIRM_ROWS = 2**16
#: ... and never more than this (the design alone needs n × d × 16 B in memory; the store on disk
#: several hundred bytes per row).
MAX_ROWS = 2**24
#: Names that become paths, HDF5 keys or figure labels: letters, digits, '_', '-', '.', no leading
#: dot, at most 100 characters.
NAME_PATTERN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}", re.ASCII)
#: A displacement reading beyond 1 km (10^6 mm) is a unit error, and squares of larger numbers
#: overflow the misfit (1e300² = inf, χ²/dof = 0).
MAX_ABS_READING_MM = 1e6


def human_bytes(nbytes):
    """``1536`` → ``"1.5 KiB"``."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(nbytes) < 1024 or unit == "PiB":
            return f"{nbytes:.0f} {unit}" if unit == "B" else f"{nbytes:.1f} {unit}"
        nbytes /= 1024


def _int(value, what):
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{what} must be an integer; got {value!r}")
    return value


def check_region_samples(n, what="--region-samples"):
    """Samples per region-of-equivalence round: an integer in [1024, 2^24]."""
    _int(n, what)
    if n < REGION_SAMPLES_MIN:
        raise ValueError(
            f"{what} must be at least {REGION_SAMPLES_MIN} (surrogate evaluations per sampling round); got {n}: "
            "fewer samples report a far too narrow region of equivalence"
        )
    if n > REGION_SAMPLES_MAX:
        raise ValueError(
            f"{what} must be at most {REGION_SAMPLES_MAX}; got {n} (one round would need about "
            f"{human_bytes(n * 100 * 8)} for the predictions)"
        )
    return n


def check_rows(n, bytes_per_row, what="--n"):
    """Rows of a snapshot store: an integer in [1, MAX_ROWS]; returns the estimated store size, bytes."""
    _int(n, what)
    if n < 1:
        raise ValueError(f"{what} must be at least 1; got {n}")
    size = n * bytes_per_row
    if n > MAX_ROWS:
        raise ValueError(
            f"{what} = {n} is above the limit of {MAX_ROWS} rows: the store would need about "
            f"{human_bytes(size)} and {n} FE runs; split the design into several stores"
        )
    return size


def check_name(name, what="name"):
    """A name that becomes a file name, an HDF5 key or a figure label: see :data:`NAME_PATTERN`."""
    if not isinstance(name, str) or NAME_PATTERN.fullmatch(name) is None or name in (".", ".."):
        raise ValueError(
            f"{what} must be 1-100 characters of letters, digits, '_', '-' and '.', not starting with '.' "
            f"(it becomes a folder or file name); got {name!r}"
        )
    return name


def check_output_folder(path, what="--out"):
    """An output folder: missing (it is created) or an existing folder, never a file."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {path} is a file; give a folder (it is created if missing)")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise ValueError(f"{what} {path}: {parent} is a file, not a folder")
            break
    return path


def check_finite(value, what, *, lower=None, upper=None):
    """A finite real number (optionally within [lower, upper])."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{what} must be a number; got {value!r}")
    try:
        v = float(value)
    except OverflowError:
        raise ValueError(f"{what} is too large; got an integer of {len(str(value))} digits") from None
    if not math.isfinite(v):
        raise ValueError(f"{what} must be a finite number; got {value!r}")
    if (lower is not None and v < lower) or (upper is not None and v > upper):
        raise ValueError(f"{what} must be in [{lower}, {upper}]; got {value!r}")
    return v
