"""Read measurements from CSV: first column ``load``, then one column per sensor, values in mm.

Every problem is reported with the file, the row (1-based, header = row 1) and the column.
"""

import csv
import math
from pathlib import Path

import numpy as np

from podkrig.online.measurement import Measurement


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
    try:
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as e:
        raise ValueError(f"cannot read measurement file {path}: {e.strerror}") from e
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
            try:
                v = float(cell)
            except ValueError:
                raise ValueError(f"{path}, row {i}, column {j} ({name}): {cell.strip()!r} is not a number") from None
            if not math.isfinite(v):
                raise ValueError(f"{path}, row {i}, column {j} ({name}): {cell.strip()!r} is not a finite number")
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


def write_measurement_csv(path, measurement):
    """Write a measurement in the format :func:`read_measurement_csv` reads."""
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["load", *measurement.sensor_names])
        for level, row in zip(measurement.load_levels, measurement.values):
            w.writerow([f"{level:g}", *[f"{v:.10g}" for v in row]])
