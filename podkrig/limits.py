"""Named input limits shared by the command line, the study file and the Python API.

Every limit is a module constant with the reason for its value; every ``check_*`` function raises
:class:`ValueError` (which the CLI prints as a one-line ``error:``) naming the setting, the value and
what is allowed — with a memory or disk estimate where size is the reason.
"""

import math
import numbers
import re
from pathlib import Path

import numpy as np

from fe.files import human_bytes, read_bounded  # noqa: F401 - podkrig's file readers call them from here

#: Region-of-equivalence samples per round: below 1024 the sampled region is far too narrow (a
#: 16-sample "region" called an unidentifiable parameter identified); above 2^24 one
#: round's predictions (n × outputs × 8 B, ~100 outputs) exceed ~13 GiB.
REGION_SAMPLES_MIN = 1024
REGION_SAMPLES_MAX = 2**24
#: Rows of a snapshot store: above this, ask first (hours of FE work, a large file) ...
CONFIRM_ROWS = 2**16
#: ... and never more than this (the design alone needs n × d × 16 B in memory; the store on disk
#: several hundred bytes per row).
MAX_ROWS = 2**24
#: A job whose estimated FE work exceeds this many hours on one core (or whose store exceeds
#: :data:`CONFIRM_STORE_BYTES`, or which has more than :data:`CONFIRM_ROWS` rows) is started by
#: the CLI only after a question or with ``--yes``.
CONFIRM_FE_HOURS = 2.0
CONFIRM_STORE_BYTES = 4 * 2**30
#: Seconds of FE work per degree of freedom and linear run on one core: 66 runs/s of the default
#: diagonal-compression mesh (9 360 dofs) in BENCHMARKS.md "offline" → 1.6 µs per dof.
FE_SECONDS_PER_DOF = 1.6e-6
#: Seconds of CPU per degree of freedom of one nonlinear (path-following) run, before any run of
#: the job is measured: the flat-jack shear test with its repeat 3' (8 006 dofs, 3.3 s CPU, the
#: longest path of the catalogue's strength tests) → 4e-4 s per dof; J4D 0–3 mm (8 102 dofs) takes
#: 1.75 s (docs/nonlinear.md). Once a store holds runs, their own mean CPU time is used instead.
NONLINEAR_SECONDS_PER_DOF = 4e-4
#: GA individuals per generation: a generation's surrogate predictions hold about
#: :data:`BYTES_PER_INDIVIDUAL` each (kriging cross-covariances with ~10³ training points, the
#: predicted outputs), so 2^18 individuals need ~2 GiB.
MAX_POPULATION = 2**18
BYTES_PER_INDIVIDUAL = 8 * 1024
#: GA evaluations (population × (generations + 1)): the run keeps every evaluated point, its
#: misfit and generation (``X_history`` …, ~(parameters + 3) × 8 B each): 2^25 evaluations of 10
#: parameters are ~3.4 GiB.
MAX_GA_EVALUATIONS = 2**25
#: Least-squares polishes after the GA (each up to a few thousand surrogate evaluations).
MAX_STARTS = 1024
#: Local FE worker processes (each holds a mesh and a factorisation: ~0.1–1 GiB) and rows per
#: task; a cluster of more machines is given as a Dask scheduler instead.
MAX_WORKERS = 1024
MAX_CHUNK_SIZE = 4096
#: Candidate-sensor grids (``podkrig sensors``): DIC points are one sensor object and two channels
#: each (~1 KiB with their sensitivities), so 2^17 points need ~128 MiB; a gauge grid pairs every
#: two points (the pair arrays take ~100 B per pair), so 2^12 points are ~8·10⁶ pairs, ~0.8 GiB.
MAX_DIC_POINTS = 2**17
MAX_GAUGE_GRID_POINTS = 2**12
#: Names that become paths, HDF5 keys or figure labels: letters, digits, '_', '-', '.', no leading
#: dot, at most 100 characters.
NAME_PATTERN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}", re.ASCII)
#: A displacement reading beyond 1 km (10^6 mm) is a unit error, and squares of larger numbers
#: overflow the misfit (1e300² = inf, χ²/dof = 0).
MAX_ABS_READING_MM = 1e6
#: Size caps of the files podkrig reads (:func:`read_bounded`): a study file is a few KiB written by
#: hand; a measurement log of a day at 10 Hz with 20 channels is ~100 MiB; a stage manifest or
#: ``summary.json`` holds results, never arrays (a few MiB at most); an array file (``region.npz``)
#: holds at most :data:`REGION_SAMPLES_MAX` samples of a few dozen parameters. Scenario spec files
#: are read by the FE package with the same cap as study files (``fe.scenarios.spec.MAX_SPEC_BYTES``).
MAX_STUDY_FILE_BYTES = 2**20
MAX_LOG_BYTES = 256 * 2**20
MAX_JSON_BYTES = 64 * 2**20
MAX_ARRAY_FILE_BYTES = 8 * 2**30
#: Characters of a file's content an error message may quote (:func:`quote`, :func:`quote_cells`):
#: enough to identify a cell, a header or a unit, never a whole line of a file that was not meant.
QUOTE_CHARS = 80


def human_duration(seconds):
    """``5400`` → ``"1.5 h"``; ``90`` → ``"1.5 min"``; ``0.25`` → ``"0.25 s"``."""
    if seconds >= 86400:
        return f"{seconds / 86400:.3g} days"
    if seconds >= 3600:
        return f"{seconds / 3600:.3g} h"
    if seconds >= 60:
        return f"{seconds / 60:.3g} min"
    return f"{seconds:.2g} s"


def quote(text, limit=QUOTE_CHARS):
    r"""A piece of a file's content for a message (a string, else any value's ``repr``): its first
    line as Python writes a string (so a
    NUL byte or a non-breaking space shows as ``\x00``, ``\xa0``), at most ``limit`` characters in
    all — cut with ``…`` after the closing quote.

    >>> quote("load [kN]")
    "'load [kN]'"
    >>> quote("l\x00o\x00a\x00d")
    "'l\\x00o\\x00a\\x00d'"
    >>> quote("x" * 100, limit=10)
    "'xxxxxxx'…"
    >>> quote(list(range(100)), limit=12)
    '[0, 1, 2, 3…'
    """
    if not isinstance(text, str):  # a value of a file (a number, an array): its repr, cut
        shown = repr(text)
        return shown if len(shown) <= limit and "\n" not in shown else shown.splitlines()[0][:limit - 1] + "…"
    lines = text.splitlines()
    line = lines[0] if lines else ""
    shown = repr(line)
    if len(shown) <= limit and len(lines) <= 1:
        return shown
    for k in range(min(len(line), limit), -1, -1):
        shown = repr(line[:k]) + "…"
        if len(shown) <= limit:
            return shown
    return "…"


def quote_cells(cells, limit=QUOTE_CHARS):
    """Cells of a row (a header) for a message, each as :func:`quote` gives it, as many as fit in
    ``limit`` characters: ``['load', 'D1', …]``.

    >>> quote_cells(["load", "D1", "D2"])
    "['load', 'D1', 'D2']"
    >>> quote_cells(f"column {k}" for k in range(20))
    "['column 0', 'column 1', 'column 2', 'column 3', 'column 4', 'column 5', …]"
    """
    shown, used = [], 2
    for cell in cells:
        q = quote(cell, limit=24)
        if used + len(q) + 3 > limit:
            shown.append("…")
            break
        shown.append(q)
        used += len(q) + 2
    return "[" + ", ".join(shown) + "]"


def _int(value, what):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{what} must be an integer; got {value!r}")
    return int(value)


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
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
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


def _bounded_int(n, what, lower, upper, estimate=None):
    """An integer in [lower, upper]; above it the message gives ``estimate(n)`` (text) if any."""
    _int(n, what)
    if n < lower:
        raise ValueError(f"{what} must be an integer >= {lower}; got {n}")
    if n > upper:
        extra = f": {estimate(n)}" if estimate is not None else ""
        raise ValueError(f"{what} = {n} is above the limit of {upper}{extra}")
    return n


def check_population(n, what="population_size"):
    """GA individuals per generation: an integer in [4, :data:`MAX_POPULATION`]."""
    return _bounded_int(n, what, 4, MAX_POPULATION, lambda n: (
        f"one generation would need about {human_bytes(n * BYTES_PER_INDIVIDUAL)} of memory for its surrogate "
        "predictions"))


def check_evaluations(evaluations, n_params=10, what="max_evaluations"):
    """GA evaluations: at most :data:`MAX_GA_EVALUATIONS` (the run keeps every evaluated point)."""
    _int(evaluations, what)
    if evaluations > MAX_GA_EVALUATIONS:
        raise ValueError(
            f"{what} allows {evaluations} GA evaluations, above the limit of {MAX_GA_EVALUATIONS}: the run's "
            f"history alone would need about {human_bytes(evaluations * (n_params + 3) * 8)}; the GA stops by "
            "stall long before (see the generations reached in a study's report)"
        )
    return evaluations


def check_generations(n, population, n_params=10, what="generations"):
    """GA generations after the first: an integer >= 1 with population × (generations + 1) at most
    :data:`MAX_GA_EVALUATIONS`."""
    _bounded_int(n, what, 1, math.inf)
    check_evaluations(population * (n + 1), n_params, f"{what} = {n} with a population of {population}")
    return n


def check_starts(n, what="n_starts"):
    """Least-squares polishes after the GA: an integer in [1, :data:`MAX_STARTS`]."""
    return _bounded_int(n, what, 1, MAX_STARTS)


def check_workers(n, what="workers"):
    """Local FE worker processes: an integer in [1, :data:`MAX_WORKERS`]."""
    return _bounded_int(n, what, 1, MAX_WORKERS, lambda n: (
        f"{n} processes each holding a mesh and its factorisation (~0.1–1 GiB); use a Dask scheduler for a "
        "cluster of several machines"))


def check_chunk_size(n, what="chunk_size"):
    """Rows per FE task: an integer in [1, :data:`MAX_CHUNK_SIZE`]."""
    return _bounded_int(n, what, 1, MAX_CHUNK_SIZE, lambda n: "a task's results are held in memory until written")


def check_grid(n_points, kind, what="grid"):
    """Points of a candidate grid (``kind`` "dic" or "gauge"): at most :data:`MAX_DIC_POINTS` or
    :data:`MAX_GAUGE_GRID_POINTS`."""
    if kind == "dic":
        limit, need = MAX_DIC_POINTS, n_points * 1024
    else:
        limit, need = MAX_GAUGE_GRID_POINTS, n_points * (n_points - 1) // 2 * 100
    if n_points > limit:
        raise ValueError(f"{what} has {n_points} points, above the limit of {limit} for {kind} candidates: about "
                         f"{human_bytes(need)} of memory; use a coarser step")
    return n_points


def check_confidence(c, what="confidence"):
    """A confidence level: a finite number in (0, 1)."""
    c = check_finite(c, what)
    if not 0 < c < 1:
        raise ValueError(f"{what} must be in (0, 1), e.g. 0.95; got {c!r}")
    return c


def fe_job_estimate(jobs, store_bytes):
    """The size of an FE job in words (runs, estimated time, disk) and whether to ask first.

    Parameters
    ----------
    jobs : sequence of (rows, n_dofs, nonlinear) or (rows, n_dofs, nonlinear, seconds_per_run)
        FE runs to do of each scenario, its mesh's degrees of freedom, whether its runs are
        path-following, and optionally the measured CPU seconds per run (the mean of the runs its
        store already holds; None or absent: :data:`FE_SECONDS_PER_DOF` per dof for a linear run,
        :data:`NONLINEAR_SECONDS_PER_DOF` for a nonlinear one).
    store_bytes : int
        Estimated size of the store(s) on disk, bytes.

    Returns
    -------
    text : str
        E.g. ``"100000 FE runs of 9360 dofs (about 25 min on one core) and 76.3 MiB on disk"``;
        ``"…, from the runs stored)"`` when any job's time is measured.
    large : bool
        More than :data:`CONFIRM_ROWS` runs, :data:`CONFIRM_FE_HOURS` of FE work or
        :data:`CONFIRM_STORE_BYTES` on disk: ask before starting.
    """
    jobs = [(int(j[0]), int(j[1]), bool(j[2]), j[3] if len(j) > 3 else None) for j in jobs if j[0] > 0]
    rows = sum(r for r, *_ in jobs)
    seconds = sum(r * (d * (NONLINEAR_SECONDS_PER_DOF if nl else FE_SECONDS_PER_DOF) if per is None else float(per))
                  for r, d, nl, per in jobs)
    measured = ", from the runs stored" if any(per is not None for *_, per in jobs) else ""
    dofs = sorted({d for _, d, _, _ in jobs})
    nonlinear = sum(r for r, _, nl, _ in jobs if nl)
    kind = ("nonlinear " if nonlinear == rows else f"({nonlinear} nonlinear) ") if nonlinear else ""
    size = f"{dofs[0]}" if len(dofs) == 1 else f"{dofs[0]}–{dofs[-1]}" if dofs else "0"
    text = (f"{rows} {kind}FE runs of {size} dofs (about {human_duration(seconds)} on one core{measured}) and "
            f"{human_bytes(store_bytes)} on disk")
    large = rows > CONFIRM_ROWS or seconds > 3600 * CONFIRM_FE_HOURS or store_bytes > CONFIRM_STORE_BYTES
    return text, large
