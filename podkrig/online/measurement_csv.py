"""Read measurements from CSV: first column ``load``, then one column per sensor, values in mm.

Every problem is reported with the file, the row (1-based, header = row 1) and the column.
"""

import csv
import io
import math
import re
from pathlib import Path

import numpy as np

from podkrig.limits import MAX_ABS_READING_MM
from podkrig.online.measurement import Measurement

#: A measurement file is one row per load level: 16 MiB is thousands of times more than needed.
MAX_FILE_BYTES = 16 * 2**20
#: Longest cell, characters (a number needs < 30).
MAX_CELL_CHARS = 4096
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)


def read_measurement_csv(path, sensor_names, load_levels, load_unit="kN"):
    """Read and validate a measurement file against a model's sensors and load levels.

    Parameters
    ----------
    path : str or Path
    sensor_names : sequence of str
        The model's sensors; the file may hold a subset, in any order.
    load_levels : array_like
        The model's load levels; the file may hold a subset.
    load_unit : str
        For messages.

    Returns
    -------
    Measurement

    Raises
    ------
    ValueError
        Missing ``load`` column, unknown or repeated sensor columns, non-numeric or NaN cells,
        duplicate or unknown load levels — naming file, row and column.
    """
    path = Path(path)
    rows = _read_rows(path)
    rows = [r for r in rows if any(c.strip() for c in r)]
    if not rows:
        raise ValueError(f"{path}: empty file; expected a header 'load,<sensor>,...'")
    header = [c.strip() for c in rows[0]]
    if header[0] != "load":
        raise ValueError(f"{path}, row 1, column 1: the first column must be 'load' ({load_unit}); got {header[0]!r}")
    sensors = header[1:]
    if not sensors:
        raise ValueError(f"{path}, row 1: no sensor columns after 'load'")
    known = list(sensor_names)
    for j, s in enumerate(sensors, start=2):
        if s not in known:
            raise ValueError(f"{path}, row 1, column {j}: unknown sensor {s!r}; sensors are {known}")
        if s in sensors[: j - 2]:
            raise ValueError(f"{path}, row 1, column {j}: sensor {s!r} appears more than once")
    levels_all = np.asarray(load_levels, dtype=float)
    loads, values = [], []
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise ValueError(f"{path}, row {i}: {len(row)} cells, expected {len(header)} (one per column of the header)")
        numbers = []
        for j, (cell, name) in enumerate(zip(row, header), start=1):
            text = cell.strip()
            if text.lower().lstrip("+-") in ("nan", "inf", "infinity"):
                raise ValueError(f"{path}, row {i}, column {j} ({name}): {text!r} is not a finite number")
            if _NUMBER.fullmatch(text) is None:  # float() also takes '2_5' and non-ASCII digits
                shown = repr(text) if len(text) <= 40 else repr(text[:40]) + "…"
                raise ValueError(f"{path}, row {i}, column {j} ({name}): {shown} is not a number "
                                 "(write plain decimals such as 0.125 or -1.5e-3)")
            v = float(text)
            if not math.isfinite(v) or (j > 1 and abs(v) > MAX_ABS_READING_MM):
                raise ValueError(f"{path}, row {i}, column {j} ({name}): {text!r} is out of range "
                                 f"(readings are mm, at most {MAX_ABS_READING_MM:g} in magnitude)")
            numbers.append(v)
        level = numbers[0]
        if not np.any(np.isclose(levels_all, level, rtol=1e-9, atol=1e-12)):
            raise ValueError(
                f"{path}, row {i}, column 1 (load): unknown load level {level:g} {load_unit}; "
                f"the model has {levels_all.tolist()}"
            )
        if any(np.isclose(level, loads, rtol=1e-9, atol=1e-12)):
            raise ValueError(f"{path}, row {i}, column 1 (load): load level {level:g} {load_unit} appears twice")
        loads.append(level)
        values.append(numbers[1:])
    if not loads:
        raise ValueError(f"{path}: no data rows after the header")
    return Measurement(np.array(values), tuple(sensors), np.array(loads), source=str(path))


def _read_rows(path):
    """The CSV rows of a measurement file, read with bounded size and cell length.

    Raises
    ------
    ValueError
        Unreadable, larger than :data:`MAX_FILE_BYTES`, not UTF-8 (with the byte offset), or a
        malformed CSV (with the row) — naming the file.
    """
    try:
        with path.open("rb") as fh:
            raw = fh.read(MAX_FILE_BYTES + 1)  # bounded: /dev/zero or a huge log stops here
    except OSError as e:
        raise ValueError(f"cannot read measurement file {path}: {e.strerror or e}") from e
    if len(raw) > MAX_FILE_BYTES:
        raise ValueError(f"{path}: larger than {MAX_FILE_BYTES // 2**20} MiB; a measurement file holds one "
                         "row per load level — pass the readings, not a raw data log")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise ValueError(f"{path}: not UTF-8 text at byte {e.start} (line {line}); save it as UTF-8 (or plain ASCII)") from None
    limit = csv.field_size_limit()
    try:
        csv.field_size_limit(MAX_CELL_CHARS)
        reader = csv.reader(io.StringIO(text, newline=""))
        try:
            return list(reader)
        except csv.Error as e:
            raise ValueError(f"{path}, row {reader.line_num}: malformed CSV ({e}); cells hold at most "
                             f"{MAX_CELL_CHARS} characters") from None
    finally:
        csv.field_size_limit(limit)


def write_measurement_csv(path, measurement):
    """Write a measurement in the format :func:`read_measurement_csv` reads."""
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["load", *measurement.sensor_names])
        for level, row in zip(measurement.load_levels, measurement.values):
            w.writerow([f"{level:g}", *[f"{v:.10g}" for v in row]])
