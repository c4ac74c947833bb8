"""Read laboratory measurement logs (CSV or Excel ``.xlsx``) into a :class:`Measurement`.

A log has a header row naming its columns — the load column (``load`` unless
:attr:`ImportSettings.load_column` says otherwise) and one column per sensor, each optionally
with its unit: ``load [kN]``, ``D1 [µm]``, ``D1 (mm)`` — or a units row right below the header.
What the reader does, in order:

* the delimiter (``,`` ``;`` tab) and the decimal mark (``.`` or ``,``) are detected (or set);
  lines before the header (a test's title, date …) are skipped;
* units are converted with pint to the scenario's units (readings mm, loads the scenario's load
  unit); an unknown or incompatible unit is refused naming the file, the column and the unit; a
  column without a unit is read in those units (and the notes say so);
* columns that are neither the load nor a sensor of the model (time, channel numbers …) are
  ignored, and sensors of the model without a column are not used — both listed in the notes;
* an empty cell (or ``NaN``, ``NA``, ``n/a``) is a missing reading; a row without a load is skipped;
* gauges are zeroed at the reference ``zero`` — the first row, a given load, the end of a phase
  (``"end of PHASE"``: the last row whose ``phase_column`` cell names it; the rows up to it are not
  used), or none — and the model is then compared as ``g(P) − g(P_ref)``; rows outside
  ``load_range`` are dropped (the end of a phase is found in the whole log, the first row and a
  load within the range);
* several readings at one load step (consecutive rows within ``load_tolerance``) are averaged or
  kept (``repeats``);
* the measured loads are checked against the model: their unit and sign against its load levels
  (:func:`podkrig.online.data_check.check_loads`: N under a ``kN`` header is refused), then any
  load for a linear scenario (its readings are affine in the load), the modelled range for a
  nonlinear one, the levels themselves for a stepped test.

Every problem is reported with the file, the row (1-based, as a spreadsheet shows it) and the
column.

Why one module of ~650 lines (a third documentation): one reader whose format detection
(delimiter, decimal comma, units rows, title lines), unit conversion and error messages by file,
row and column must agree with each other.
"""

import csv
import difflib
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from podkrig.limits import MAX_ABS_READING_MM, MAX_LOG_BYTES, quote, quote_cells, read_bounded
from podkrig.online.data_check import check_loads
from podkrig.online.measurement import LOAD_RESPONSES, Measurement, level_weights

#: Largest log read, bytes (:data:`podkrig.limits.MAX_LOG_BYTES`): 100 000 rows of a dozen
#: channels is ~10 MiB; 256 MiB bounds memory.
MAX_FILE_BYTES = MAX_LOG_BYTES
#: Longest cell, characters (a number needs < 30).
MAX_CELL_CHARS = 4096
#: Rows of an Excel sheet read at most (a 1 Hz log of 12 days).
MAX_XLSX_ROWS = 1_000_000
#: Cells read as a missing reading (case-insensitive), besides an empty cell.
MISSING = ("nan", "na", "n/a")
REPEATS = ("average", "keep")
_NUMBER = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_NUMBER_RE = re.compile(_NUMBER, re.ASCII)
_DECIMAL_COMMA = re.compile(r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?", re.ASCII)
_DECIMAL_POINT = re.compile(r"[+-]?\d*\.\d+(?:[eE][+-]?\d+)?", re.ASCII)
# whitespace around a cell (spaces, tabs, a spreadsheet's non-breaking space, a quoted carriage
# return): every whitespace but the newline that joins the cells of a column
_BLANK = re.compile(r"[^\S\n]")
_SPACES = re.compile(r"[^\S\n]*\n[^\S\n]*")
_MISSING_RE = re.compile(r"^(?:nan|na|n/a)$", re.IGNORECASE | re.MULTILINE)
_NOT_NUMERIC = re.compile(r"[^0-9eE+\-.\n]")
_HEADER = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")
_UNITS = None
#: ``zero = "end of PHASE"`` (case-insensitive "end of"): gauges zeroed at the last row of that phase.
_ZERO_PHASE = re.compile(r"^\s*end of\s+(\S.*?)\s*$", re.IGNORECASE)


def zero_phase(zero):
    """The phase named by ``zero = "end of PHASE"`` (normalised as a phase cell is), else None."""
    m = _ZERO_PHASE.match(zero) if isinstance(zero, str) else None
    return phase_label(m.group(1)) if m else None


def phase_label(cell):
    """A phase cell as compared with ``zero = "end of PHASE"``: stripped, and a whole number written
    plainly (``2.0`` from an Excel sheet reads as ``2``)."""
    text = cell.strip()
    if _NUMBER_RE.fullmatch(text):
        value = float(text)
        if value.is_integer() and abs(value) < 2**53:
            return str(int(value))
    return text


@dataclass(frozen=True)
class ImportSettings:
    """How to read a laboratory log (see the module docstring).

    Parameters
    ----------
    load_column : str
        Name of the load column (without its unit; case-insensitive).
    repeats : {"average", "keep"}
        Several readings at one load step: average them (one observation per step and sensor) or
        keep each as an observation.
    load_tolerance : float
        Consecutive rows whose loads lie within this of the step's first load form one step, in
        the scenario's load unit (0: only equal loads).
    zero : None, "first", "end of PHASE" or float
        Gauges zeroed at a reference: None (readings are absolute, as the model's), "first" (the
        first row used), "end of PHASE" (the last row whose ``phase_column`` cell is PHASE,
        case-insensitive; that row and every row before it are not used), or a load in the
        scenario's load unit (the readings where the log first reaches it, interpolated between rows).
    phase_column : str
        Name of the column holding each row's phase (case-insensitive), read only for
        ``zero = "end of PHASE"``; otherwise it is an ignored column like any other.
    load_range : tuple of float or None
        ``(lower, upper)`` loads to use, scenario's load unit, inclusive.
    delimiter : str or None
        ``","``, ``";"`` or ``"\\t"``; None detects it.
    decimal : str or None
        ``"."`` or ``","``; None detects it.
    sheet : str or None
        Worksheet of an ``.xlsx`` file (default: the first).
    """

    load_column: str = "load"
    repeats: str = "average"
    load_tolerance: float = 0.0
    zero: object = None
    phase_column: str = "phase"
    load_range: tuple | None = None
    delimiter: str | None = None
    decimal: str | None = None
    sheet: str | None = None

    def __post_init__(self):
        if not isinstance(self.load_column, str) or not self.load_column.strip():
            raise ValueError(f"load_column must be a non-empty column name; got {self.load_column!r}")
        if self.repeats not in REPEATS:
            raise ValueError(f"repeats must be one of {', '.join(REPEATS)}; got {self.repeats!r}")
        if isinstance(self.load_tolerance, bool) or not (isinstance(self.load_tolerance, int | float)
                                                         and 0 <= self.load_tolerance < math.inf):
            raise ValueError(f"load_tolerance must be a number >= 0 (scenario load unit); got {self.load_tolerance!r}")
        z = self.zero
        if not (z is None or z == "first" or zero_phase(z) is not None
                or (isinstance(z, int | float) and not isinstance(z, bool) and math.isfinite(z))):
            raise ValueError(f"zero must be \"first\", \"end of PHASE\" (a phase of the phase column), a load "
                             f"(number, scenario load unit) or none; got {z!r}")
        if not isinstance(self.phase_column, str) or not self.phase_column.strip():
            raise ValueError(f"phase_column must be a non-empty column name; got {self.phase_column!r}")
        if self.load_range is not None:
            r = tuple(self.load_range) if isinstance(self.load_range, list | tuple) else ()
            if (len(r) != 2 or any(isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v)
                                   for v in r) or not r[0] <= r[1]):
                raise ValueError(f"load_range must be [lower, upper] with lower <= upper (scenario load unit); "
                                 f"got {self.load_range!r}")
            object.__setattr__(self, "load_range", (float(r[0]), float(r[1])))
        if self.delimiter not in (None, ",", ";", "\t"):
            raise ValueError(f"delimiter must be ',', ';' or a tab; got {self.delimiter!r}")
        if self.decimal not in (None, ".", ","):
            raise ValueError(f"decimal must be '.' or ','; got {self.decimal!r}")
        if self.delimiter == "," and self.decimal == ",":
            raise ValueError("a comma cannot be both the delimiter and the decimal mark")


def read_measurement(path, sensor_names, load_levels, load_unit="kN", load_response="discrete", settings=None,
                     sensor_units=None):
    """Read and check a laboratory log against a model's sensors and load levels.

    Parameters
    ----------
    path : str or Path
        A ``.csv`` (or ``.txt``) or ``.xlsx`` file.
    sensor_names : sequence of str
        The model's sensors; the file may hold a subset, in any order, among other columns.
    load_levels : array_like
        The model's load levels (scenario load unit).
    load_unit : str
        The scenario's load unit (``kN``, ``mm`` for a nonlinear scenario's control displacement,
        ``step`` for a stepped test): the load column is converted to it.
    load_response : {"affine", "path", "discrete"}
        How the model's readings depend on the load (:mod:`podkrig.online.measurement`): which
        measured loads the model can be evaluated at.
    settings : ImportSettings, optional
    sensor_units : dict of str to str, optional
        Sensor name → the unit of the model's readings (``Scenario.sensor_units``: mm, and kN for
        a nonlinear scenario's load reading ``F``); a column is converted to its sensor's unit. Default:
        every sensor in mm.

    Returns
    -------
    Measurement
        Readings in their sensors' units (mm; kN for a force) (NaN where missing) at the measured
        loads, with ``notes`` on what the import did.

    Raises
    ------
    ValueError
        Naming the file, and the row and column where there is one.
    """
    path = Path(path)
    s = settings or ImportSettings()
    if load_response not in LOAD_RESPONSES:
        raise ValueError(f"load_response must be one of {LOAD_RESPONSES}; got {load_response!r}")
    notes = []
    if path.suffix.lower() in (".xlsx", ".xlsm"):
        rows = _xlsx_rows(path, s.sheet)
        delimiter = None
    else:
        text = _read_text(path, notes)
        delimiter = s.delimiter or _detect_delimiter(text, s.load_column)
        rows = _csv_rows(path, text, delimiter)
    table = _Table(path, rows, s, sensor_names, load_unit, notes, sensor_units)
    table.parse_header()
    table.parse_numbers(delimiter)
    return table.measurement(load_levels, load_response)


def read_measurement_csv(path, sensor_names, load_levels, load_unit="kN", load_response="discrete", settings=None,
                         sensor_units=None):
    """:func:`read_measurement` (the name of the exact-load reader it replaces)."""
    return read_measurement(path, sensor_names, load_levels, load_unit, load_response, settings, sensor_units)


# --------------------------------------------------------------------------------------------- files


def _read_text(path, notes):
    """The text of a CSV log, bounded in size; UTF-8 (with or without BOM), UTF-16 with a BOM, or
    Windows-1252 (which lab software writes, µ as byte 0xB5) — the notes say which."""
    try:  # bounded: /dev/zero or a huge log stops here
        raw = read_bounded(path, MAX_FILE_BYTES, "measurement file",
                           "thin the log (e.g. one row per second) or pass the load steps only")
    except OSError as e:
        raise ValueError(f"cannot read measurement file {path}: {e.strerror or e}") from e
    try:
        if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
            try:
                text = raw.decode("utf-16")
            except UnicodeDecodeError as e:
                raise ValueError(f"{path}: damaged UTF-16 text at byte {e.start}; save it as UTF-8") from None
        else:
            text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        try:
            text = raw.decode("cp1252")
        except UnicodeDecodeError:
            raise ValueError(f"{path}: not UTF-8 text at byte {e.start} (line {line}); save it as UTF-8 "
                             "(or plain ASCII)") from None
        if "\x00" in text:
            raise ValueError(f"{path}: not a text file (NUL bytes; line {line}); save it as UTF-8 CSV") from None
        notes.append(f"read as Windows-1252 text (not UTF-8 at line {line})")
        return text
    if "\x00" in text:  # UTF-16 without its byte-order mark (or encoded twice), or a binary file
        line = text[:text.index("\x00")].count("\n") + 1
        raise ValueError(f"{path}: not a text file (NUL characters from line {line}; UTF-16 without a byte-order "
                         "mark, or saved twice?); save it as UTF-8 CSV")
    return text


def _column_name(cell):
    """A header cell naming a column in a message: unquoted, at most 40 characters (:func:`quote`)."""
    shown = quote(cell, 42)
    return shown[1:-1] if shown[-1] in "'\"" else shown[1:-2] + "…"


def _detect_delimiter(text, load_column="load"):
    """The most frequent of tab, ';' and ',' in the header (the first line with a cell, split at any
    of them, naming the load column — not a title line that merely contains the word; else the first
    line with any of them)."""
    lines = text.splitlines()[:200]
    want = load_column.strip().casefold()
    header = [ln for ln in lines if any(split_header(c.strip().strip('"'))[0].casefold() == want
                                        for d in ("\t", ";", ",") for c in ln.split(d))][:1]
    for line in header + lines[:50]:
        counts = {d: line.count(d) for d in ("\t", ";", ",")}
        best = max(counts, key=counts.get)
        if counts[best]:
            return best
    return ","


def _csv_rows(path, text, delimiter):
    limit = csv.field_size_limit()
    try:
        csv.field_size_limit(MAX_CELL_CHARS)
        reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
        try:
            return list(reader)
        except csv.Error as e:
            raise ValueError(f"{path}, row {reader.line_num}: malformed CSV ({e}); cells hold at most "
                             f"{MAX_CELL_CHARS} characters") from None
    finally:
        csv.field_size_limit(limit)


def _xlsx_rows(path, sheet):
    """The rows of a worksheet as lists of text (numbers written exactly, ``repr``)."""
    # openpyxl import: ~0.25 s, needed only for Excel files
    try:
        import openpyxl
    except ImportError:  # pragma: no cover - openpyxl is a dependency
        raise ValueError(f"{path}: reading Excel files needs openpyxl: pip install 'openpyxl>=3.1' "
                         "(or save the sheet as CSV)") from None
    try:
        if not path.is_file() or path.stat().st_size > MAX_FILE_BYTES:  # a workbook is a zip: its size is on disk
            read_bounded(path, MAX_FILE_BYTES, "measurement file", "thin the log or save one sheet as CSV")
        book = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except ValueError:
        raise
    except Exception as e:  # noqa: BLE001 - any damage of a user file (BadZipFile, KeyError, XML errors ...)
        raise ValueError(f"{path}: not a readable Excel .xlsx workbook ({type(e).__name__}: {str(e)[:200]})") from None
    try:
        if sheet is not None and sheet not in book.sheetnames:
            raise ValueError(f"{path}: no worksheet {sheet!r}; the workbook has {quote_cells(book.sheetnames)}")
        ws = book[sheet] if sheet is not None else book.worksheets[0]
        rows = []
        for i, row in enumerate(ws.iter_rows(values_only=True), start=1):
            if i > MAX_XLSX_ROWS:
                raise ValueError(f"{path}: more than {MAX_XLSX_ROWS} rows; thin the log")
            rows.append(["" if c is None else repr(float(c)) if isinstance(c, int | float) and not isinstance(c, bool)
                         else str(c) for c in row])
        return rows
    except ValueError:
        raise
    except Exception as e:  # noqa: BLE001 - any damage of a user file
        raise ValueError(f"{path}: cannot read the Excel sheet ({type(e).__name__}: {str(e)[:200]})") from None
    finally:
        book.close()


# --------------------------------------------------------------------------------------------- units


def _units():
    """The pint unit registry, built once."""
    global _UNITS
    if _UNITS is None:
        # pint import + registry: ~0.9 s + 0.15 s (cached definitions) measured under load 1.8; needed
        # only when a header states a unit
        import pint
        _UNITS = pint.UnitRegistry(cache_folder=":auto:")
    return _UNITS


def unit_factor(unit, target, where, what="reading"):
    """Factor converting values in ``unit`` to ``target`` (a pint unit), or a ValueError naming ``where``
    (``what``: "reading" or "load", for the message)."""
    if unit == target:
        return 1.0
    ureg = _units()
    # pint import errors are not ValueErrors: catch its own and the parser's
    try:
        q = ureg.Quantity(1.0, unit.replace("μ", "µ"))
    except Exception:  # noqa: BLE001 - pint raises several types for unparsable text
        raise ValueError(f"{where}: unknown unit {quote(unit)} (use e.g. mm, µm, um, m for readings; kN, N for loads)") from None
    try:
        factor = float(q.to(target).magnitude)
    except Exception:  # noqa: BLE001 - DimensionalityError and friends
        want = ("a length (readings are displacements)" if what == "reading" and target == "mm"
                else f"a force (this sensor reads the load, {target})" if what == "reading"
                else f"convertible to {target}")
        raise ValueError(f"{where}: unit {quote(unit)} is not {want}") from None
    if not (math.isfinite(factor) and factor > 0):
        raise ValueError(f"{where}: unit {quote(unit)} has no usable conversion to {target}")
    return factor


def split_header(cell):
    """``"D1 [µm]"`` → ``("D1", "µm")``; ``"D1 (mm)"`` → ``("D1", "mm")``; ``"D1"`` → ``("D1", None)``."""
    cell = cell.strip()
    m = _HEADER.match(cell)
    if m and m.group(1).strip():
        return m.group(1).strip(), (m.group(2).strip() or None)
    return cell, None


# --------------------------------------------------------------------------------------------- table


class _Table:
    """One log being read: header, columns used, numbers (an implementation detail of
    :func:`read_measurement`)."""

    def __init__(self, path, rows, settings, sensor_names, load_unit, notes, sensor_units=None):
        self.path, self.settings, self.notes = path, settings, notes
        self.sensor_names = list(sensor_names)
        self.sensor_units = {n: (sensor_units or {}).get(n, "mm") for n in self.sensor_names}
        self.load_unit = load_unit
        self.rows = rows

    def _where(self, row=None, col=None, name=None):
        out = str(self.path)
        if row is not None:
            out += f", row {row}"
        if col is not None:
            out += f", column {col}" + (f" ({_column_name(name)})" if name else "")
        return out

    def parse_header(self):
        s = self.settings
        want = s.load_column.strip().casefold()
        header_at = None
        for i, row in enumerate(self.rows[:200]):
            if any(split_header(c)[0].casefold() == want for c in row):
                header_at = i
                break
        if header_at is None:
            first = next((r for r in self.rows if any(c.strip() for c in r)), None)
            if first is None:
                raise ValueError(f"{self.path}: empty file; expected a header such as 'load [kN],D1 [mm],...'")
            raise ValueError(f"{self._where(1 + self.rows.index(first))}: no load column {s.load_column!r} in the "
                             f"header {quote_cells(c.strip() for c in first)} (set the load column's name with load_column)")
        if header_at:
            self.notes.append(f"skipped {header_at} line(s) before the header")
        header = [c.strip() for c in self.rows[header_at]]
        self.header_row = header_at + 1
        names, units = zip(*(split_header(c) for c in header))
        units = list(units)
        body = header_at + 1
        # an optional units row right below the header: no numbers, every non-empty cell a unit
        if body < len(self.rows):
            nxt = [c.strip() for c in self.rows[body]]
            if (any(nxt) and not any(_NUMBER_RE.fullmatch(c.replace(",", ".")) for c in nxt)
                    and all(u is None for u in units)):
                units = [c.strip("[]() ") or None for c in nxt] + [None] * (len(names) - len(nxt))
                units = units[:len(names)]
                body += 1
                self.notes.append(f"units from row {body} (below the header)")
        self.body = body
        load_cols = [j for j, n in enumerate(names) if n.casefold() == want]
        if len(load_cols) > 1:
            raise ValueError(f"{self._where(self.header_row, load_cols[1] + 1)}: a second load column "
                             f"{quote(header[load_cols[1]])}")
        self.load_col = load_cols[0]
        self.phase_col = self._find_phase_column(names, header)
        exact = {n: n for n in self.sensor_names}
        folded = {n.casefold(): n for n in self.sensor_names}
        self.sensor_cols, self.sensors = [], []
        ignored = []
        for j, n in enumerate(names):
            if j in (self.load_col, self.phase_col):
                continue
            sensor = exact.get(n) or folded.get(n.casefold())
            if sensor is None:
                if header[j]:
                    ignored.append(header[j])
                continue
            if sensor in self.sensors:
                raise ValueError(f"{self._where(self.header_row, j + 1)}: sensor {sensor!r} appears more than once")
            self.sensor_cols.append(j)
            self.sensors.append(sensor)
        if not self.sensors:
            raise ValueError(f"{self._where(self.header_row)}: no column names a sensor of the model "
                             f"{self.sensor_names}; the header has {quote_cells(h for h in header if h)}")
        not_used = [n for n in self.sensor_names if n not in self.sensors]
        self.ignored = ignored
        if ignored:
            hint = ""
            for col in ignored:
                close = difflib.get_close_matches(split_header(col)[0], not_used, n=1, cutoff=0.75)
                if close:
                    hint += f" ('{col}' is close to sensor {close[0]!r}: a typo?)"
            self.notes.append(f"ignored column(s) that name no sensor: {', '.join(ignored)}{hint}")
        if not_used:
            self.notes.append(f"sensor(s) of the model not in the file, not used: {', '.join(not_used)}")
        where = self._where(self.header_row, self.load_col + 1, header[self.load_col])
        lu = units[self.load_col]
        if self.load_unit == "step":
            if lu not in (None, "step", "-"):
                raise ValueError(f"{where}: this scenario's loads are step numbers 1, 2, …; the load column "
                                 f"has the unit {quote(lu)}")
            self.load_factor = 1.0
        else:
            self.load_factor = 1.0 if lu is None else unit_factor(lu, self.load_unit, where, "load")
            if lu is None:
                self.notes.append(f"load column without a unit: read as {self.load_unit}")
            elif self.load_factor != 1.0:
                self.notes.append(f"loads converted from {lu} to {self.load_unit} (× {self.load_factor:g})")
        self.factors = []
        bare = []
        for j, sensor in zip(self.sensor_cols, self.sensors):
            u, target = units[j], self.sensor_units[sensor]
            if u is None:
                bare.append((sensor, target))
                self.factors.append(1.0)
                continue
            f = unit_factor(u, target, self._where(self.header_row, j + 1, header[j]))
            self.factors.append(f)
            if f != 1.0:
                self.notes.append(f"{sensor} converted from {u} to {target} (× {f:g})")
        for target in dict.fromkeys(t for _, t in bare):
            names = ", ".join(n for n, t in bare if t == target)
            self.notes.append(f"no unit in the header of {names}: read as {target}")
        self.header = header

    def _find_phase_column(self, names, header):
        """The column of the phases when ``zero = "end of PHASE"`` (else None): named
        ``phase_column``, once, and not the load column."""
        s = self.settings
        phase = zero_phase(s.zero)
        if phase is None:
            return None
        want = s.phase_column.strip().casefold()
        cols = [j for j, n in enumerate(names) if n.casefold() == want]
        if not cols:
            raise ValueError(f"{self._where(self.header_row)}: zero = {s.zero!r} needs a phase column "
                             f"{s.phase_column!r}; the header has {quote_cells(h for h in header if h)} (name the "
                             "column holding each row's phase with phase_column)")
        if len(cols) > 1:
            raise ValueError(f"{self._where(self.header_row, cols[1] + 1)}: a second phase column {quote(header[cols[1]])}")
        if cols[0] == self.load_col or want in {n.casefold() for n in self.sensor_names}:
            what = "the load column" if cols[0] == self.load_col else "a sensor of the model"
            raise ValueError(f"{self._where(self.header_row, cols[0] + 1)}: phase_column {s.phase_column!r} is {what}; "
                             "name the column holding each row's phase")
        return cols[0]

    def parse_numbers(self, delimiter):
        """Numbers of the load and sensor columns: ``loads (n,)``, ``values (n, n_sensors)`` mm.

        Vectorised over rows: each used column is joined into one string, checked by one regular
        expression and converted by NumPy; only a column with a bad cell is scanned cell by cell
        (for the message)."""
        rows = self.rows[self.body:]
        width = len(self.header)
        numbered = [(i, r) for i, r in enumerate(rows, start=self.body + 1) if "".join(r).strip()]
        if not numbered:
            raise ValueError(f"{self.path}: no data rows after the header (row {self.header_row})")
        row_numbers = np.array([i for i, _ in numbered])
        rows = [r for _, r in numbered]
        long = [k for k, r in enumerate(rows) if len(r) > width and "".join(r[width:]).strip()]
        if long:
            k = long[0]
            raise ValueError(f"{self._where(int(row_numbers[k]))}: {len(rows[k])} cells, expected {width} (one per "
                             "column of the header)")
        short = [k for k, r in enumerate(rows) if len(r) < width]
        for k in short:  # a row cut short: its missing cells are missing readings
            rows[k] = rows[k] + [""] * (width - len(rows[k]))
        columns = list(zip(*rows))
        cols = [self.load_col, *self.sensor_cols]
        decimal = self.settings.decimal or self._detect_decimal([columns[j][:500] for j in cols], delimiter)
        if decimal == ",":
            self.notes.append("decimal comma")
        numbers = [self._column(columns[j], j, decimal, row_numbers) for j in cols]
        loads = numbers[0] * self.load_factor
        values = np.column_stack(numbers[1:]) * np.array(self.factors)
        no_load = np.isnan(loads)
        if np.any(no_load):
            self.notes.append(f"{int(no_load.sum())} row(s) without a load skipped (e.g. row "
                              f"{int(row_numbers[np.argmax(no_load)])})")
        big = np.abs(values) > MAX_ABS_READING_MM
        if np.any(big):
            i, k = np.argwhere(big)[0]
            unit = self.sensor_units[self.sensors[k]]
            raise ValueError(f"{self._where(int(row_numbers[i]), self.sensor_cols[k] + 1, self.header[self.sensor_cols[k]])}: "
                             f"{values[i, k]:g} {unit} is out of range (readings are at most {MAX_ABS_READING_MM:g} "
                             f"{unit} in magnitude)")
        self.loads, self.values, self.row_numbers = loads[~no_load], values[~no_load], row_numbers[~no_load]
        if self.phase_col is not None:
            self.phases = np.array([phase_label(c) for c in columns[self.phase_col]], dtype=object)[~no_load]

    @staticmethod
    def _detect_decimal(text, delimiter):
        """``","`` when some cell is a decimal-comma number and none a decimal-point one."""
        if delimiter == ",":
            return "."  # a comma decimal would need quoting in every cell: rare, set decimal = ","
        sample = [c.strip() for col in text for c in col if c.strip()]
        if any(_DECIMAL_POINT.fullmatch(c) for c in sample):
            return "."
        return "," if any(_DECIMAL_COMMA.fullmatch(c) for c in sample) else "."

    def _column(self, cells, j, decimal, row_numbers):
        """One column of text as floats (NaN where missing), every bad cell named."""
        name = self.header[j]
        joined = "\n".join(cells)
        if _BLANK.search(joined):
            joined = _SPACES.sub("\n", f"\n{joined}\n")[1:-1]
        if decimal == ",":
            joined = joined.replace(",", ".")
        if _NOT_NUMERIC.search(joined):  # letters: missing-reading words, or a bad cell
            joined = _MISSING_RE.sub("", joined)
        out = None
        if joined.count("\n") == len(cells) - 1 and not _NOT_NUMERIC.search(joined):
            padded = ("\n" + joined + "\n").replace("\n\n", "\nnan\n").replace("\n\n", "\nnan\n")
            try:  # only digits, signs, '.', 'e' here: what float() accepts of them is a plain decimal
                out = np.array(padded[1:-1].split("\n"), dtype=float)
            except ValueError:
                out = None
        if out is None:
            for i, cell in enumerate(cells):  # a bad cell: find it, for the message
                c = cell.strip()
                c = c.replace(",", ".") if decimal == "," else c
                if c and c.casefold() not in MISSING and _NUMBER_RE.fullmatch(c) is None:
                    where = self._where(int(row_numbers[i]), j + 1, name)
                    if c.lower().lstrip("+-") in ("inf", "infinity"):
                        raise ValueError(f"{where}: {quote(cell.strip())} is not a finite number")
                    raise ValueError(f"{where}: {quote(cell.strip(), 43)} is not a number (write plain decimals such as 0.125 or "
                                     "-1.5e-3; an empty cell is a missing reading)")
            raise ValueError(f"{self._where(None, j + 1, name)}: unreadable cells")  # pragma: no cover
        inf = np.isinf(out)
        if np.any(inf):
            i = int(np.argmax(inf))
            raise ValueError(f"{self._where(int(row_numbers[i]), j + 1, name)}: {quote(cells[i].strip())} is out of range")
        return out

    # ----------------------------------------------------------------------------------- processing

    def measurement(self, load_levels, load_response):
        s = self.settings
        loads, values, rows = self.loads, self.values, self.row_numbers
        unit = f" {self.load_unit}"
        reference = None
        if self.phase_col is not None:  # a moment of the test: found in the whole log, before load_range
            loads, values, rows, reference = self._zero_at_phase_end(loads, values, rows)
        if s.load_range is not None:
            lo, hi = s.load_range
            inside = (loads >= lo) & (loads <= hi)
            if not np.any(inside):
                raise ValueError(f"{self.path}: no row has a load in load_range [{lo:g}, {hi:g}]{unit}; the loads "
                                 f"span [{loads.min():g}, {loads.max():g}]{unit}" if len(loads) else
                                 f"{self.path}: no rows with a load")
            if not np.all(inside):
                self.notes.append(f"{int((~inside).sum())} row(s) outside load_range [{lo:g}, {hi:g}]{unit} dropped")
            loads, values, rows = loads[inside], values[inside], rows[inside]
        if not len(loads):
            raise ValueError(f"{self.path}: no data rows with a load")
        if s.zero is not None and self.phase_col is None:
            ref_values, reference, ref_row = self._zero(loads, values, rows)
            values = values - ref_values
            self.notes.append(f"gauges zeroed at {reference:g}{unit} ({ref_row}); the model is compared as "
                              "g(P) − g(P_ref)")
            if s.zero == "first":
                loads, values, rows = loads[1:], values[1:], rows[1:]
                if not len(loads):
                    raise ValueError(f"{self.path}: only the zero reference row; no readings left")
        loads, values, rows = self._repeats(loads, values, rows)
        if not np.any(np.isfinite(values)):
            raise ValueError(f"{self.path}: no readings (every sensor cell is empty)")
        check_loads(loads, load_levels, self.load_unit, source=str(self.path), column=self.header[self.load_col],
                    rows=rows)
        self._check_loads(loads, rows, load_levels, load_response)
        if reference is not None:
            level_weights([reference], load_levels, load_response, self.load_unit,
                          f"{self.path} (zero reference {reference:g}{unit})")
        return Measurement(values, tuple(self.sensors), loads, source=str(self.path), reference_load=reference,
                           notes=tuple(self.notes), ignored_columns=tuple(self.ignored),
                           sensor_units=tuple(self.sensor_units[n] for n in self.sensors))

    def _zero_at_phase_end(self, loads, values, rows):
        """Readings zeroed at the last row of the phase ``zero = "end of PHASE"`` names: the rows
        after it ``(loads, values, rows)`` and the reference load."""
        s = self.settings
        phase = zero_phase(s.zero)
        name = self.header[self.phase_col]
        folded = np.array([p.casefold() for p in self.phases], dtype=object)
        hit = np.flatnonzero(folded == phase.casefold())
        found = list(dict.fromkeys(p for p in self.phases if p))
        if not len(hit):
            where = self._where(None, self.phase_col + 1, name)
            if not found:
                raise ValueError(f"{where}: zero = {s.zero!r}, but the phase column is empty")
            close = difflib.get_close_matches(phase, found, n=1, cutoff=0.6)
            hint = f" (a typo of {quote(close[0])}?)" if close else ""
            raise ValueError(f"{where}: no row of phase {phase!r} (zero = {s.zero!r}){hint}; the phases in this "
                             f"column are {quote_cells(found)}")
        i = int(hit[-1])
        ref, row = values[i], int(rows[i])
        missing = [self.sensors[k] for k in np.flatnonzero(np.isnan(ref))]
        if missing:
            raise ValueError(f"{self._where(row)}: the zero reference (end of phase {quote(self.phases[i])}) has no reading "
                             f"of {', '.join(missing)}")
        if i + 1 == len(loads):
            raise ValueError(f"{self._where(row, self.phase_col + 1, name)}: the phase {quote(self.phases[i])} ends at the "
                             "last row; no readings after the zero reference")
        reference = float(loads[i])
        self.notes.append(f"gauges zeroed at the end of phase {self.phases[i]!r} (row {row}, {reference:g} "
                          f"{self.load_unit}); the {i + 1} row(s) up to it are not used; phases in column "
                          f"{self.phase_col + 1} ({name}): {', '.join(found[:20])}; the model is compared as "
                          "g(P) − g(P_ref)")
        return loads[i + 1:], values[i + 1:] - ref, rows[i + 1:], reference

    def _zero(self, loads, values, rows):
        """Readings at the zero reference ``(n_sensors,)``, the reference load and where it was read."""
        s = self.settings
        unit = f" {self.load_unit}"
        if s.zero == "first":
            ref = values[0]
            missing = [self.sensors[k] for k in np.flatnonzero(np.isnan(ref))]
            if missing:
                raise ValueError(f"{self._where(int(rows[0]))}: the zero reference (first row) has no reading of "
                                 f"{', '.join(missing)}")
            return ref, float(loads[0]), f"row {int(rows[0])}"
        p0 = float(s.zero)
        hit = np.flatnonzero(np.isclose(loads, p0, rtol=1e-9, atol=1e-12))
        d = loads - p0
        cross = np.flatnonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)
        if not (len(hit) or len(cross)):
            raise ValueError(f"{self.path}: the log never reaches the zero reference load {p0:g}{unit} (its loads "
                             f"span [{loads.min():g}, {loads.max():g}]{unit})")
        if len(hit) and (not len(cross) or hit[0] <= cross[0]):  # where the log first reaches p0
            i = hit[0]
            ref, where = values[i], f"row {int(rows[i])}"
        else:
            i = cross[0]
            t = (p0 - loads[i]) / (loads[i + 1] - loads[i])
            ref = (1 - t) * values[i] + t * values[i + 1]
            where = f"interpolated between rows {int(rows[i])} and {int(rows[i + 1])}"
        missing = [self.sensors[k] for k in np.flatnonzero(np.isnan(ref))]
        if missing:
            raise ValueError(f"{self.path}: no reading of {', '.join(missing)} at the zero reference load "
                             f"{p0:g}{unit} ({where})")
        return ref, p0, where

    def _repeats(self, loads, values, rows):
        """Average consecutive rows of one load step (``repeats = "average"``) or keep them."""
        s = self.settings
        if s.repeats == "keep" or len(loads) < 2:
            return loads, values, rows
        if s.load_tolerance == 0:
            start = np.concatenate([[True], loads[1:] != loads[:-1]])
        else:
            start = np.zeros(len(loads), dtype=bool)
            first = None
            for i, p in enumerate(loads.tolist()):  # a step is measured from its first load: sequential
                if first is None or abs(p - first) > s.load_tolerance:
                    start[i], first = True, p
        if np.all(start):
            return loads, values, rows
        starts = np.flatnonzero(start)
        counts = np.diff(np.append(starts, len(loads)))
        present = np.isfinite(values)
        sums = np.add.reduceat(np.where(present, values, 0.0), starts, axis=0)
        n = np.add.reduceat(present.astype(float), starts, axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(n > 0, sums / np.maximum(n, 1), np.nan)
        step_loads = np.add.reduceat(loads, starts) / counts
        self.notes.append(f"{len(loads)} rows averaged into {len(starts)} load steps (repeats = \"average\", "
                          f"load_tolerance = {s.load_tolerance:g} {self.load_unit})")
        return step_loads, mean, rows[starts]

    def _check_loads(self, loads, rows, load_levels, load_response):
        """Every measured load can be evaluated by the model: the error names the first row that cannot."""
        levels = np.asarray(load_levels, dtype=float)
        unit = f" {self.load_unit}"
        try:
            level_weights(loads, levels, load_response, self.load_unit, str(self.path))
        except ValueError as e:
            exact = np.any(np.isclose(loads[:, None], levels[None, :], rtol=1e-9, atol=1e-12), axis=1)
            if load_response == "discrete" or len(levels) < 2:
                bad = ~exact
            else:
                bad = ~exact & ((loads < levels.min()) | (loads > levels.max()))
            if not np.any(bad):
                raise
            i = int(np.argmax(bad))
            where = self._where(int(rows[i]), self.load_col + 1, self.header[self.load_col])
            if load_response == "discrete":
                raise ValueError(f"{where}: unknown load level {loads[i]:g}{unit}; the model has "
                                 f"{levels.tolist()} (its levels are steps: readings are taken only there)") from None
            raise ValueError(f"{where}: {e}".replace(f"{self.path}: ", "", 1)) from None


def response_csv(scenario, response):
    """A simulated response as the measurement file :func:`read_measurement` reads back unchanged
    (what ``podkrig simulate --format csv`` prints).

    The column ``load`` (the scenario's load, or a nonlinear scenario's control displacement, with
    its unit; step numbers bare), then each sensor with its unit (mm; the load reading ``F`` in
    kN); levels to 6 significant digits, readings to 8; a level the run did not reach has empty
    cells (missing readings). A reading the same at every level (the peak readings ``F_peak``,
    ``d_peak``: sensor definitions of kind ``"peak"``) is written in the first row only — one
    observation, as a lab log states it.

    Parameters
    ----------
    scenario : fe.scenarios.Scenario
        Its ``sensor_units`` and ``sensor_definitions()``.
    response : fe.response.Response

    Returns
    -------
    str
    """
    units = scenario.sensor_units
    once = {n for n, d in scenario.sensor_definitions().items() if d.get("kind") == "peak"}
    unit = response.load_unit
    header = ["load" if unit == "step" else f"load [{unit}]"]
    header += [f"{name} [{units.get(name, 'mm')}]" for name in response.sensor_names]
    lines = [",".join(header)]
    for k, (level, row) in enumerate(zip(response.load_levels, response.readings)):
        cells = [f"{v:.8g}" if np.isfinite(v) and (k == 0 or name not in once) else ""
                 for name, v in zip(response.sensor_names, row)]
        lines.append(",".join([f"{level:g}", *cells]))
    return "\n".join(lines) + "\n"


def write_measurement_csv(path, measurement):
    """Write a measurement in the plain form :func:`read_measurement` reads (missing readings empty)."""
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["load", *measurement.sensor_names])
        for level, row in zip(measurement.load_levels, measurement.values):
            w.writerow([f"{level:.10g}", *["" if not np.isfinite(v) else f"{v:.10g}" for v in row]])


__all__ = ["MAX_FILE_BYTES", "REPEATS", "ImportSettings", "phase_label", "read_measurement", "read_measurement_csv",
           "response_csv", "split_header", "unit_factor", "write_measurement_csv", "zero_phase"]
