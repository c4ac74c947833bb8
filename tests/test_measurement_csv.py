"""Reading laboratory logs (:mod:`podkrig.io.measurement_log`): every refusal names the file,
the row and the column and says what is allowed (the fragments a user needs: row, column, cell,
setting); the import notes tell the user what was done (their numbers and rows); format
detection (delimiter, decimal mark, units row, encodings), zeroing, averaging of repeats and the
checks of the settings, by hand-computed values."""

import csv
import math
import re
import sys
import zipfile

import numpy as np
import openpyxl
import pytest
from numpy.testing import assert_allclose

from podkrig.io import measurement_log
from podkrig.online.measurement import Measurement
from podkrig.io.measurement_log import (
    ImportSettings,
    phase_label,
    read_measurement,
    read_measurement_csv,
    split_header,
    unit_factor,
    write_measurement_csv,
    zero_phase,
)

SENSORS = ("D1", "D2", "U1")
LEVELS = (10.0, 20.0, 30.0, 40.0)
HINT = "(write plain decimals such as 0.125 or -1.5e-3; an empty cell is a missing reading)"


def _write(tmp_path, content, name="log.csv"):
    p = tmp_path / name
    p.write_bytes(content.encode("utf-8") if isinstance(content, str) else content)
    return p


def _read(tmp_path, content, unit="kN", response="affine", settings=None, levels=LEVELS, name="log.csv"):
    return read_measurement(_write(tmp_path, content, name), SENSORS, levels, unit, response, settings)


def _error(tmp_path, content, **kwargs):
    """The message of the ValueError reading ``content`` raises, the file's path as ``{p}``."""
    with pytest.raises(ValueError) as info:
        _read(tmp_path, content, **kwargs)
    return str(info.value).replace(str(tmp_path / kwargs.get("name", "log.csv")), "{p}")


def _refused(tmp_path, content, *fragments, **kwargs):
    """Reading ``content`` raises a ValueError whose message holds every fragment (the file as
    ``{p}``, the row and column, the cell, the remedy)."""
    message = _error(tmp_path, content, **kwargs)
    missing = [f for f in fragments if f not in message]
    assert not missing, (missing, message)


def _contains(message, *fragments):
    """``message`` holds every fragment."""
    missing = [f for f in fragments if f not in str(message)]
    assert not missing, (missing, str(message))


def _note(measurement, *fragments):
    """The one import note holding every fragment (the numbers, rows and settings a user reads)."""
    found = [n for n in measurement.notes if all(f in n for f in fragments)]
    assert len(found) == 1, (fragments, measurement.notes)
    return found[0]


# ------------------------------------------------------------------------------------ settings


ZERO = ("zero", '"first"', '"end of PHASE"', "a load", "none")
RANGE = ("load_range", "[lower, upper]", "lower <= upper")


@pytest.mark.parametrize("kwargs, fragments", [
    ({"load_column": " "}, ("load_column", "non-empty", "got ' '")),
    ({"load_column": 3}, ("load_column", "got 3")),
    ({"repeats": "median"}, ("repeats", "average, keep", "got 'median'")),
    ({"load_tolerance": -0.1}, ("load_tolerance", ">= 0", "got -0.1")),
    ({"load_tolerance": True}, ("load_tolerance", "got True")),
    ({"load_tolerance": math.inf}, ("load_tolerance", "got inf")),
    ({"load_tolerance": "0.1"}, ("load_tolerance", "got '0.1'")),
    ({"zero": "last"}, (*ZERO, "got 'last'")),
    ({"zero": True}, (*ZERO, "got True")),
    ({"zero": math.nan}, (*ZERO, "got nan")),
    ({"phase_column": ""}, ("phase_column", "non-empty", "got ''")),
    ({"phase_column": None}, ("phase_column", "got None")),
    ({"load_range": (1.0,)}, (*RANGE, "got (1.0,)")),
    ({"load_range": (2, 1)}, (*RANGE, "got (2, 1)")),
    ({"load_range": (0, math.inf)}, (*RANGE, "got (0, inf)")),
    ({"load_range": (True, 2)}, (*RANGE, "got (True, 2)")),
    ({"load_range": (0, "2")}, (*RANGE, "got (0, '2')")),
    ({"load_range": "12"}, (*RANGE, "got '12'")),
    ({"load_range": 5}, (*RANGE, "got 5")),
    ({"delimiter": "|"}, ("delimiter", "';'", "a tab", "got '|'")),
    ({"decimal": ";"}, ("decimal", "'.' or ','", "got ';'")),
    ({"delimiter": ",", "decimal": ","}, ("comma", "delimiter", "decimal mark")),
])
def test_settings_are_checked_with_what_is_allowed(kwargs, fragments):
    """Every setting refused with its name, its value and the allowed forms (the study file passes
    these on)."""
    with pytest.raises(ValueError, match=re.escape(fragments[0])) as info:
        ImportSettings(**kwargs)
    _contains(info.value, *fragments)


def test_settings_accepted_at_their_limits():
    """The limits are inclusive: tolerance 0, a load range of one load, zero at load 0 (an int);
    a load range given as a list is stored as a tuple of floats; "end of" is case-insensitive."""
    s = ImportSettings(load_tolerance=0, load_range=[5, 5], zero=0, delimiter="\t", decimal=",")
    assert s.load_range == (5.0, 5.0) and all(type(v) is float for v in s.load_range)
    assert ImportSettings(zero="first").zero == "first" and ImportSettings(load_tolerance=0.5).load_tolerance == 0.5
    assert ImportSettings(zero="END OF  Shear ").zero == "END OF  Shear "
    assert ImportSettings(delimiter=";", decimal=",").decimal == ","


def test_phase_names_and_labels():
    """``zero = "end of PHASE"`` names a phase (stripped, case of "end of" ignored); a phase cell
    holding a whole number reads as that number written plainly (Excel's 2.0 is phase 2), any other
    cell as its stripped text; numbers beyond 2^53 are not rewritten (not exact as floats)."""
    assert zero_phase("end of precompression") == "precompression"
    assert zero_phase("  End Of   shear 2  ") == "shear 2"
    assert zero_phase("end of 2.0") == "2"
    assert zero_phase("end of ") is None and zero_phase("first") is None and zero_phase(5.0) is None
    assert phase_label(" 3 ") == "3" and phase_label("3.0") == "3" and phase_label("1e3") == "1000"
    assert phase_label("-2.0") == "-2" and phase_label("2.5") == "2.5" and phase_label(" shear ") == "shear"
    assert phase_label("9007199254740991.0") == "9007199254740991"  # 2^53 − 1
    assert phase_label("9007199254740992.0") == "9007199254740992.0"  # 2^53: left as written


# ---------------------------------------------------------------------------------- units, header


def test_unit_factors_and_their_errors():
    """Conversion factors to mm and kN (exact to 1e-15); the Greek mu (U+03BC) reads as the micro sign;
    an unknown unit, a reading unit that is no length and a load unit that does not convert are
    refused naming where and what is allowed. The same unit converts without pint (factor exactly 1)."""
    assert unit_factor("mm", "mm", "w") == 1.0
    assert unit_factor("µm", "mm", "w") == pytest.approx(1e-3, rel=1e-15)
    assert unit_factor("\u03bcm", "mm", "w") == pytest.approx(1e-3, rel=1e-15)
    assert unit_factor("um", "mm", "w") == pytest.approx(1e-3, rel=1e-15)
    assert unit_factor("in", "mm", "w") == pytest.approx(25.4, rel=1e-15)
    assert unit_factor("N", "kN", "w", "load") == pytest.approx(1e-3, rel=1e-15)
    assert type(unit_factor("m", "mm", "w")) is float
    cases = [(("bananas", "mm", "f, row 1"), ("f, row 1: ", "unknown unit 'bananas'", "mm, µm", "kN, N")),
             (("0.1 mm", "mm", "f"), ("f: ", "unknown unit '0.1 mm'")),  # a unit, not a quantity: no hidden scale
             (("(ym/Ym)**20*mm", "mm", "f"), ("f: ", "'(ym/Ym)**20*mm'", "no usable conversion to mm")),  # 0.0
             (("kN", "mm", "f"), ("f: ", "'kN' is not a length")),
             (("kN", "mm", "f", "load"), ("f: ", "'kN' is not convertible to mm")),
             (("mm", "kN", "f", "load"), ("f: ", "'mm' is not convertible to kN"))]
    for args, fragments in cases:
        with pytest.raises(ValueError, match=re.escape(fragments[1])) as info:
            unit_factor(*args)
        _contains(info.value, *fragments)
        assert str(info.value).startswith(fragments[0])


@pytest.mark.parametrize("cell, split", [
    ("D1 [µm]", ("D1", "µm")), ("D1 (mm)", ("D1", "mm")), (" D1 ", ("D1", None)), ("D1 [ mm ]", ("D1", "mm")),
    ("D1[mm]", ("D1", "mm")), ("D1 []", ("D1", None)), ("[mm]", ("[mm]", None)), ("load [kN/m]", ("load", "kN/m")),
])
def test_header_cells_split_into_name_and_unit(cell, split):
    """A header cell's name and unit; a cell that is only a unit is a name (no column is nameless)."""
    assert split_header(cell) == split


def test_header_notes_say_what_was_converted_ignored_and_assumed(tmp_path):
    """The notes list, in order, what the reader did with the header: lines skipped, units row,
    ignored columns (with a typo hint for a near miss of a sensor not in the file), sensors not in
    the file, load and reading conversions with their factors, and the columns read without a
    unit. A unit equal to the target (kN, mm) gives no conversion note."""
    m = _read(tmp_path, "title\n\nload [N],D1 [mm],D22,D3 [µm],time\n10000,1,2,3,4\n")
    assert len(m.notes) == 4  # in order: skipped lines, ignored columns, missing sensors, load conversion
    assert "skipped 2 line(s)" in m.notes[0]
    assert all(f in m.notes[1] for f in ("D22, D3 [µm], time", "'D22'", "'D2'", "typo"))
    assert "not in the file" in m.notes[2] and m.notes[2].endswith("D2, U1")
    assert all(f in m.notes[3] for f in ("from N to kN", "× 0.001"))
    assert m.ignored_columns == ("D22", "D3 [µm]", "time")
    m = _read(tmp_path, "load,d2 [µm],u1\n10,2,3\n")
    assert m.sensor_names == ("D2", "U1")  # case-insensitive, in the file's order, the model's spelling
    assert_allclose(m.values, [[0.002, 3.0]], rtol=1e-15)
    assert len(m.notes) == 4
    assert "not in the file" in m.notes[0] and m.notes[0].endswith("D1")
    assert "load column without a unit" in m.notes[1] and "kN" in m.notes[1]
    assert all(f in m.notes[2] for f in ("D2", "from µm to mm", "× 0.001"))
    assert "no unit" in m.notes[3] and "U1" in m.notes[3] and "mm" in m.notes[3]
    m = _read(tmp_path, "load [kN],D1 [mm],D2 [mm],U1 [mm]\n10,1,2,3\n")
    assert m.notes == () and m.ignored_columns == ()


def test_a_units_row_below_the_header(tmp_path):
    """A row of units below a header without units: brackets stripped, padded when shorter and cut
    when longer than the header, noted; a row holding a number (decimal comma too) is data, not units."""
    m = _read(tmp_path, "load;D1;D2\n[kN];(µm)\n10;1,5;2\n")
    assert_allclose(m.values, [[0.0015, 2.0]], rtol=1e-15)
    assert "units from row 2" in m.notes[0]
    _note(m, "no unit", "D2", "mm")
    m = _read(tmp_path, "load;D1;D2\nN;µm;mm;s\n10000;1,5;2\n")
    assert_allclose(m.load_levels, [10.0], rtol=1e-15)
    assert_allclose(m.values, [[0.0015, 2.0]], rtol=1e-15)
    assert not any("no unit" in n for n in m.notes)
    _refused(tmp_path, "load [kN];D1;D2\nkN;1,5;\n10;1,5;2\n", "{p}, row 2, column 1 (load [kN])", "'kN' is not a number")
    _refused(tmp_path, "load;D1\nkN;1,5\n10;2\n", "{p}, row 2, column 1 (load)", "'kN' is not a number")


@pytest.mark.parametrize("content, kwargs, fragments", [
    ("", {}, ("{p}: empty file", "load [kN],D1 [mm]")),
    ("\n ,\nforce,D1,a,b,c,d,e,f,g,h,i,j,k\n", {},
     ("{p}, row 3", "no load column 'load'", "'force'", "'k']", "load_column")),  # the header listed in 80 characters
    ("load,D1,Load [N]\n10,1,2\n", {}, ("{p}, row 1, column 3", "second load column 'Load [N]'")),
    ("x\nload,D1,d1\n10,1,2\n", {}, ("{p}, row 2, column 3", "'D1' appears more than once")),
    ("load,D9,,a,b,c,d,e,f,g,h,i,j,k\n10,1\n", {},
     ("{p}, row 1", "['D1', 'D2', 'U1']", "['load', 'D9', 'a'", "'k']")),
    ("load [kN],D1\n1,1\n", {"unit": "step", "response": "discrete", "levels": (1, 2)},
     ("{p}, row 1, column 1 (load [kN])", "step numbers", "'kN'")),
    ("x\nload [kN],D1 [kN]\n10,1\n", {}, ("{p}, row 2, column 2 (D1 [kN])", "'kN' is not a length")),
    ("load,D1\n", {}, ("{p}: no data rows", "(row 1)")),
    ("t\nload,D1\n\n10,1,,\n20,2,3\n", {}, ("{p}, row 5", "3 cells, expected 2")),
    ("load,D1 [m]\n10,1\n20,-2000\n", {}, ("{p}, row 3, column 2 (D1 [m])", "-2e+06 mm", "out of range", "1e+06 mm")),
    ("load,D1\n10,1\n20,-inf\n", {}, ("{p}, row 3, column 2 (D1)", "'-inf'", "not a finite number")),
    ("load,D1\n10,1\n20, Infinity\n", {}, ("{p}, row 3, column 2 (D1)", "'Infinity'", "not a finite number")),
    ("load,D1\n10,1\n20,1e400\n", {}, ("{p}, row 3, column 2 (D1)", "'1e400'", "out of range")),
    ("load,D1\n10,1\n20, " + "x" * 50 + "\n", {}, ("{p}, row 3, column 2 (D1)", "'" + "x" * 40 + "'…", "not a number")),
    ("load,D1\n10,1\n20," + "x" * 40 + "\n", {}, ("{p}, row 3, column 2 (D1)", "'" + "x" * 40 + "' is")),
    ("load,D1\n10,1\n20," + "x" * 41 + "\n", {}, ("{p}, row 3, column 2 (D1)", "'" + "x" * 41 + "' is")),
    ("load,D1\n10,1\n20," + "x" * 42 + "\n", {}, ("{p}, row 3, column 2 (D1)", "'" + "x" * 40 + "'…")),
    ("load;D1\n10;1\n20;1,2,3\n", {}, ("{p}, row 3, column 2 (D1)", "'1,2,3'", "not a number", HINT)),
    ("load,D1\n10,1.5\n20,\"1,5\"\n", {}, ("{p}, row 3, column 2 (D1)", "'1,5'", "not a number")),
    ("load,D1\n10,1\n20,1..5\n", {}, ("{p}, row 3, column 2 (D1)", "'1..5'", "not a number")),
    ("load,D1\n1 0,1\n", {}, ("{p}, row 2, column 1 (load)", "'1 0'", "not a number")),
    ("load,D1\n10, 1\n20,2X\n", {}, ("{p}, row 3, column 2 (D1)", "'2X'", "not a number")),
    ("load;D1\n10;1,5\n20;abc\n", {}, ("{p}, row 3, column 2 (D1)", "'abc'", "not a number")),
    ("load,D1\n10,\"1,5\"\n", {}, ("{p}, row 2, column 2 (D1)", "'1,5'", "not a number")),
    ("phase,load,D1,Phase\na,10,1,a\nb,20,2,b\n", {"settings": ImportSettings(zero="end of a")},
     ("{p}, row 1, column 4", "second phase column 'Phase'")),
    ("phase,load,D1\na,10,1\nb,20,2\n", {"settings": ImportSettings(zero="end of a", phase_column="LOAD")},
     ("{p}, row 1, column 2", "phase_column 'LOAD'", "load column")),
    ("phase,load,D1\na,10,1\nb,20,2\n", {"settings": ImportSettings(zero="end of a", phase_column="d1")},
     ("{p}, row 1, column 3", "phase_column 'd1'", "sensor")),
    ("load,D1,a,b,c,d,e,f,g,h,i,j,k,l\n10,1\n", {"settings": ImportSettings(zero="end of a")},
     ("{p}, row 1", "zero = 'end of a'", "phase column 'phase'", "'k', 'l']", "phase_column")),
    ("load,D1\n,1\n", {}, ("{p}: no data rows with a load",)),
    ("load,D1\n,1\n", {"settings": ImportSettings(load_range=(12, 35))}, ("{p}: no rows with a load",)),
    ("load,D1\n10,1\n20,2\n", {"settings": ImportSettings(load_range=(0, 5))},
     ("{p}: ", "load_range [0, 5] kN", "span [10, 20] kN")),
    ("load,D1\n10,1\n", {"settings": ImportSettings(zero="first")}, ("{p}: ", "zero reference row", "no readings")),
    ("load,D1,D2\n10,,\n20,,\n", {}, ("{p}: no readings", "empty")),
    ("load,D1,D2,U1\n10,1,,\n20,2,3,4\n", {"settings": ImportSettings(zero="first")},
     ("{p}, row 2", "zero reference (first row)", "D2, U1")),
    ("load,D1,D2,U1\n2,1,1,\n10,2,,1\n", {"settings": ImportSettings(zero=6)},
     ("{p}: ", "D2, U1", "load 6 kN", "between rows 2 and 3")),
    ("load,D1,D2\n2,1,1\n6,2,\n10,3,3\n", {"settings": ImportSettings(zero=6)},
     ("{p}: ", "of D2 at", "load 6 kN (row 3)")),
    ("load,D1\n2,1\n10,2\n", {"settings": ImportSettings(zero=12)},
     ("{p}: ", "never reaches", "load 12 kN", "[2, 10] kN")),
    ("load,D1\n2,1\n10,2\n", {"settings": ImportSettings(zero=6), "response": "discrete", "levels": (2, 10)},
     ("{p} (zero reference 6 kN)", "unknown load level 6 kN", "[2.0, 10.0]")),
    ("load [mm],D1\n1,1\n2,1\n3.5,2\n", {"unit": "mm", "response": "path", "levels": (1, 3)},
     ("{p}, row 4, column 1 (load [mm])", "range [1, 3] mm", "e.g. 3.5 mm", "load_range", "load_levels")),
    ("load,D1\n10,1\n15,2\n", {"response": "discrete"},
     ("{p}, row 3, column 1 (load)", "load level 15 kN", "[10.0, 20.0, 30.0, 40.0]")),
    ("load,D1\n10,1\n10.00001,1\n", {"response": "discrete"},  # 1e-6 off a level is not that level (1e-9)
     ("{p}, row 3, column 1 (load)", "load level 10 kN")),
    ("load,D1\n1,1\n4,1\n", {"response": "discrete", "levels": (1, 2, 3)},  # integer levels listed as floats
     ("{p}, row 3, column 1 (load)", "load level 4 kN", "[1.0, 2.0, 3.0]")),
])
def test_bad_logs_are_refused_naming_file_row_and_column(tmp_path, content, kwargs, fragments):
    """Each refusal names the file, the 1-based row a spreadsheet shows (title and blank lines
    counted), the column with its header, the offending cell or unit, and what to write instead
    (the setting to use, the allowed values)."""
    _refused(tmp_path, content, *fragments, **kwargs)


def test_a_path_scenario_names_the_first_load_it_cannot_evaluate(tmp_path):
    """For a nonlinear ("path") scenario loads between its levels are interpolated (no error), so
    the error names the first load outside the modelled range, not the first that is no level."""
    m = _read(tmp_path, "load [mm],D1\n1.5,1\n2,1\n", unit="mm", response="path", levels=(1, 3))
    assert_allclose(m.load_levels, [1.5, 2.0])
    message = _error(tmp_path, "load [mm],D1\n1.5,1\n2,1\n0.5,2\n", unit="mm", response="path", levels=(1, 3))
    assert message.startswith("{p}, row 4, column 1 (load [mm]): 1 measured control value(s) lie outside")


def test_a_single_level_model_refuses_any_other_load(tmp_path):
    """A model with one level can be evaluated only there, whatever its load response."""
    message = _error(tmp_path, "load,D1\n10,1\n12,2\n", response="path", levels=(10,))
    assert message.startswith("{p}, row 3, column 1 (load): ")
    assert _read(tmp_path, "load,D1\n10,1\n", response="path", levels=(10,)).n_obs == 1


# ------------------------------------------------------------------------------ format detection


def test_delimiter_is_taken_from_the_header_line(tmp_path):
    """The delimiter is the most frequent of tab, ';' and ',' on the line naming the load column,
    not on a title line before it; with a load column named otherwise that name is looked for.
    A log whose header has no delimiter is read as a one-column comma file."""
    m = _read(tmp_path, "Wall 3; shear; 2026\nload,D1,D2\n10,1,2\n")
    assert_allclose(m.values, [[1.0, 2.0]])
    m = _read(tmp_path, "Wall 3, 2026\nforce\tD1\n10\t1,5\n", settings=ImportSettings(load_column="Force"))
    assert_allclose(m.values, [[1.5]])
    assert "decimal comma" in m.notes
    m = _read(tmp_path, "a;b\nload;D1\n10;2\n", settings=ImportSettings(load_column="LOAD "))
    assert_allclose(m.values, [[2.0]])
    _refused(tmp_path, "load\n10\n", "{p}, row 1", "['D1', 'D2', 'U1']", "['load']")
    m = _read(tmp_path, "load,D1,D2;a;b\n10,1,2;3;4\n", settings=ImportSettings(delimiter=","))  # as set
    assert_allclose(m.values, [[1.0]])
    assert m.ignored_columns == ("D2;a;b",)


def test_decimal_mark_detection_and_setting(tmp_path):
    """A decimal comma is detected when some used cell is written with one and none with a decimal
    point; whole numbers alone read with a point; a comma-delimited file is read with a point (a
    decimal comma there would need quotes); a decimal point in any used column decides for the
    point. An explicit ``decimal`` overrides the detection."""
    m = _read(tmp_path, "load;D1;D2\n10;1;-0,25\n20;,5;\n")
    assert m.notes[-1] == "decimal comma"  # the note is the setting's name
    assert_allclose(m.values, [[1.0, -0.25], [0.5, np.nan]], rtol=1e-15)
    m = _read(tmp_path, "load;D1;D2\n10;1;2\n20;3;4\n")
    assert "decimal comma" not in m.notes
    _refused(tmp_path, "load;D1;D2\n10.5;1;2,5\n", "{p}, row 2, column 3 (D2)", "'2,5' is not a number")
    assert_allclose(_read(tmp_path, "load;D1\n10;2,5\n", settings=ImportSettings(decimal=",")).values, [[2.5]])
    _refused(tmp_path, "load;D1\n10;2,5\n", "{p}, row 2, column 2 (D1)", "'2,5' is not a number",
             settings=ImportSettings(decimal="."))
    m = _read(tmp_path, "load;D1;t\n10;2,5;0.5\n")  # an ignored column does not decide
    assert_allclose(m.values, [[2.5]])


# ---------------------------------------------------------------------------------- files, encodings


def test_encodings_and_damaged_or_binary_files(tmp_path):
    """UTF-8 with a BOM and UTF-16 with a BOM read like plain UTF-8; Windows-1252 (µ as byte 0xB5)
    reads with a note naming the first line that is not UTF-8; damaged UTF-16, bytes no encoding
    accepts and NUL bytes are refused naming the byte or line and what to save instead."""
    plain = _read(tmp_path, "load,D1\n10,1.5\n")
    for content in ("\ufeffload,D1\n10,1.5\n".encode(), "load,D1\n10,1.5\n".encode("utf-16"),
                    "load,D1\n10,1.5\n".encode("utf-16-be").join([b"\xfe\xff", b""])):
        m = _read(tmp_path, content)
        assert m.notes == plain.notes and m.values.tolist() == [[1.5]]
    m = _read(tmp_path, b"t\nx\nload,D1 [\xb5m]\n10,1\n")
    assert "Windows-1252" in m.notes[0] and "line 3" in m.notes[0] and "skipped 2 line(s)" in m.notes[1]
    assert_allclose(m.values, [[0.001]], rtol=1e-15)
    _refused(tmp_path, b"\xff\xfe" + "load,D1\n".encode("utf-16-le") + b"\x00\xd8", "{p}: ", "UTF-16",
             "byte 18", "UTF-8")
    _refused(tmp_path, b"load,D1\n10,1\x81\n", "{p}: not UTF-8", "byte 12 (line 2)", "save it as UTF-8")
    _refused(tmp_path, b"load,D1\n\x00\xb5\n", "{p}: not a text file", "NUL", "line 2", "UTF-8 CSV")
    _refused(tmp_path, "load,D1\n", "{p}: no data rows", "(row 1)")
    missing = tmp_path / "nope.csv"
    with pytest.raises(ValueError, match="No such file") as info:
        read_measurement(missing, SENSORS, LEVELS)
    assert str(missing) in str(info.value)


def test_size_limits_of_a_log(tmp_path, monkeypatch):
    """A log of exactly the size limit is read (blank lines after the data are no rows); one byte
    more is refused with the limit in MiB and what to do; a cell longer than 4096 characters is
    refused naming its row, and the csv module's own limit is restored afterwards."""
    monkeypatch.setattr(measurement_log, "MAX_FILE_BYTES", 2**20)
    body = "load,D1\n10,1\n"
    m = _read(tmp_path, body + "\n" * (2**20 - len(body)))
    assert m.values.tolist() == [[1.0]]
    _refused(tmp_path, body + "\n" * (2**20 + 1 - len(body)), "{p}: larger than 1 MiB", "thin the log")
    monkeypatch.undo()
    limit = csv.field_size_limit()
    _refused(tmp_path, "load,D1\n10,1\n20," + "1" * 5000 + "\n", "{p}, row 3", "malformed CSV", "4096 characters")
    assert csv.field_size_limit() == limit
    m = _read(tmp_path, "load,D1\n10," + "0" * 4090 + "1\n")  # 4091 characters: read
    assert m.values.tolist() == [[1.0]] and csv.field_size_limit() == limit


def _workbook(path, sheets):
    book = openpyxl.Workbook()
    book.remove(book.active)
    for title, rows in sheets.items():
        ws = book.create_sheet(title)
        for row in rows:
            ws.append(row)
    book.save(path)
    return path


def test_excel_sheets_numbers_and_limits(tmp_path, monkeypatch):
    """An Excel log: the first sheet unless one is named; integer cells are numbers like floats;
    a boolean cell is not a number (named with its row and column); a sheet longer than the row
    limit and a file over the size limit are refused saying so."""
    p = _workbook(tmp_path / "log.xlsx", {"first": [["load [kN]", "D1 [mm]"], [10, 1], [20, 2.5]],
                                          "second": [["load", "D2"], [30, None], [40, -3]]})
    m = read_measurement(p, SENSORS, LEVELS, "kN", "affine")
    assert m.sensor_names == ("D1",) and m.values.tolist() == [[1.0], [2.5]] and m.load_levels.tolist() == [10, 20]
    macro = tmp_path / "log.xlsm"  # a macro-enabled workbook, upper case or not, is read as Excel too
    for q in (macro, tmp_path / "LOG.XLSM"):
        q.write_bytes(p.read_bytes())
        assert read_measurement(q, SENSORS, LEVELS, "kN", "affine").values.tolist() == [[1.0], [2.5]]
    m = read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(sheet="second"))
    assert m.sensor_names == ("D2",) and m.load_levels.tolist() == [30.0, 40.0]
    assert_allclose(m.values, [[np.nan], [-3.0]], rtol=0)  # an empty cell: a missing reading
    bad = _workbook(tmp_path / "bool.xlsx", {"s": [["load", "D1"], [10, True]]})
    with pytest.raises(ValueError, match="'True' is not a number") as info:
        read_measurement(bad, SENSORS, LEVELS, "kN", "affine")
    assert str(info.value).startswith(f"{bad}, row 2, column 2 (D1)")
    monkeypatch.setattr(measurement_log, "MAX_XLSX_ROWS", 3)
    assert read_measurement(p, SENSORS, LEVELS, "kN", "affine").n_obs == 2  # 3 rows: at the limit
    long = _workbook(tmp_path / "long.xlsx", {"s": [["load", "D1"], [10, 1], [20, 2], [30, 3]]})
    with pytest.raises(ValueError, match="more than 3 rows") as info:
        read_measurement(long, SENSORS, LEVELS, "kN", "affine")
    assert str(info.value).startswith(f"{long}: ") and "thin the log" in str(info.value)
    monkeypatch.setattr(measurement_log, "MAX_FILE_BYTES", p.stat().st_size - 1)
    with pytest.raises(ValueError, match=r"larger than .* bytes\), the cap for a measurement file") as info:
        read_measurement(p, SENSORS, LEVELS, "kN", "affine")
    assert str(info.value).startswith(f"{p}: ")
    monkeypatch.setattr(measurement_log, "MAX_FILE_BYTES", p.stat().st_size)
    assert read_measurement(p, SENSORS, LEVELS, "kN", "affine").n_obs == 2


# ----------------------------------------------------------------------------- rows, zero, repeats


def test_missing_cells_rows_without_a_load_and_short_rows(tmp_path):
    """Empty cells and NaN/NA/n/a (any case, with spaces) are missing readings; a row cut short
    has its last cells missing; a row without a load is skipped and counted with an example row;
    trailing empty cells beyond the header are allowed."""
    m = _read(tmp_path, "load;D1;D2\n10; 1,5 ;NaN\n;7;7\n20;n/A\n 30 ; NA ;2\n;8;8\n40;;3;;\n")
    assert m.load_levels.tolist() == [10, 20, 30, 40]
    assert_allclose(m.values, [[1.5, np.nan], [np.nan, np.nan], [np.nan, 2.0], [np.nan, 3.0]], rtol=1e-15)
    _note(m, "2 row(s) without a load", "row 3")
    m = _read(tmp_path, "load,D1\n10,1\n,\n\n20,2\n , \n")  # rows of empty cells (spreadsheet exports): no rows
    assert m.load_levels.tolist() == [10, 20] and not any("without a load" in n for n in m.notes)


def test_repeats_are_averaged_per_step_from_its_first_load(tmp_path):
    """Consecutive rows within ``load_tolerance`` of a step's first load form one step (a load
    exactly at the tolerance belongs to it; the step is measured from its first load, not the
    previous row); the step's load and readings are the means, an empty cell not counted, a step
    without any reading of a sensor left missing; the note counts rows and steps; with tolerance
    0 only equal consecutive loads are merged; a single row or distinct loads are left as they
    are (no note). Values are exact binary fractions: compared to 1e-12."""
    m = _read(tmp_path, "load,D1,D2\n10,1,\n10.25,3,5\n10.5,5,6\n10.75,1,1\n20,4,\n20,6,\n",
              settings=ImportSettings(load_tolerance=0.5))
    assert_allclose(m.load_levels, [10.25, 10.75, 20.0], rtol=1e-12)
    assert_allclose(m.values, [[3.0, 5.5], [1.0, 1.0], [5.0, np.nan]], rtol=1e-12)
    _contains(m.notes[-1], "6 rows averaged into 3 load steps", "load_tolerance = 0.5 kN")
    m = _read(tmp_path, "load,D1\n10,1\n10,3\n20,4\n10,8\n")
    assert m.load_levels.tolist() == [10, 20, 10] and m.values.tolist() == [[2.0], [4.0], [8.0]]
    _contains(m.notes[-1], "4 rows averaged into 3 load steps", "load_tolerance = 0 kN")
    m = _read(tmp_path, "load,D1\n10,1\n10.25,3\n", settings=ImportSettings(load_tolerance=0.25, repeats="keep"))
    assert m.load_levels.tolist() == [10, 10.25] and not any("averaged" in n for n in m.notes)
    for content in ("load,D1\n10,1\n", "load,D1\n10,1\n20,3\n"):
        m = _read(tmp_path, content, settings=ImportSettings(load_tolerance=0.25))
        assert not any("averaged" in n for n in m.notes)
    m = _read(tmp_path, "load,D1\n10,1\n10.5,3\n", settings=ImportSettings(load_tolerance=0.25))
    assert m.load_levels.tolist() == [10, 10.5]
    m = _read(tmp_path, "load,D1\n10,1\n10.5,3\n", settings=ImportSettings(load_tolerance=1))  # two rows, 1 kN
    assert m.load_levels.tolist() == [10.25] and m.values.tolist() == [[2.0]]
    m = _read(tmp_path, "load,D1\n10,1\n10,3\n")  # two rows of one load: averaged
    assert m.load_levels.tolist() == [10.0] and m.values.tolist() == [[2.0]]


def test_zeroing_at_the_first_row_or_a_load(tmp_path):
    """zero = "first": the first row used (after load_range) is subtracted and dropped; zero = a
    load: the readings at the first row reaching it (to 1e-9 relative), or interpolated linearly
    at the first crossing (also when unloading), are subtracted and every row kept; the note says
    where. Hand-computed values, exact binary fractions: compared to 1e-12."""
    content = "load,D1,D2\n0,9,9\n2,1,2\n10,2,6\n6,3,1\n"
    m = _read(tmp_path, content, settings=ImportSettings(zero="first", load_range=(1, 20)))
    assert m.reference_load == 2.0 and m.load_levels.tolist() == [10, 6]
    assert_allclose(m.values, [[1.0, 4.0], [2.0, -1.0]], rtol=1e-12)
    _note(m, "zeroed at 2 kN", "(row 3)", "g(P_ref)")
    _note(m, "1 row(s) outside load_range [1, 20] kN")
    m = _read(tmp_path, "load,D1,D2\n0,9,9\n2,1,2\n10,2,6\n", settings=ImportSettings(zero=6))
    assert m.reference_load == 6.0 and m.load_levels.tolist() == [0, 2, 10]
    assert_allclose(m.values, [[7.5, 5.0], [-0.5, -2.0], [0.5, 2.0]], rtol=1e-12)  # at 6 kN: 1.5, 4
    _note(m, "zeroed at 6 kN", "between rows 3 and 4")
    m = _read(tmp_path, "load,D1\n0,1\n8,3\n4,7\n8,9\n", settings=ImportSettings(zero=8.000000001))
    assert m.reference_load == 8.000000001
    assert_allclose(m.values, [[-2.0], [0.0], [4.0], [6.0]], rtol=1e-12)  # the first row at 8 kN
    _note(m, "zeroed at 8 kN", "(row 3)")
    m = _read(tmp_path, "load,D1\n10,1\n2,5\n", settings=ImportSettings(zero=4))  # unloading: 10 → 2
    assert_allclose(m.values, [[-3.0], [1.0]], rtol=1e-12)
    # through zero (a load cell's small offset at rest: -0.5 kN, 1.25 % of the top level 40 kN)
    m = _read(tmp_path, "load,D1\n-0.5,1\n1.5,5\n", settings=ImportSettings(zero=0))
    assert m.reference_load == 0.0
    assert_allclose(m.values, [[-1.0], [3.0]], rtol=1e-12)


def test_written_logs_read_back_exactly(tmp_path):
    """``write_measurement_csv`` writes the plain form: a header ``load,<sensors>``, 10 significant
    digits, missing readings as empty cells; reading it back gives the same measurement."""
    m = Measurement(np.array([[-0.0625, np.nan], [1.25e-4, 3.0]]), ("D2", "U1"), np.array([10.0, 20.0]))
    p = tmp_path / "out.csv"
    write_measurement_csv(p, m)
    assert p.read_bytes() == b"load,D2,U1\r\n10,-0.0625,\r\n20,0.000125,3\r\n"  # CSV's CRLF rows
    back = read_measurement(p, SENSORS, LEVELS)
    assert back.sensor_names == ("D2", "U1") and back.load_levels.tolist() == [10, 20]
    assert_allclose(back.values, m.values, rtol=1e-15)
    m = Measurement(np.array([[1 / 3]]), ("D1",), np.array([10.0]))
    write_measurement_csv(p, m)
    assert p.read_text().splitlines()[1] == "10,0.3333333333"


def test_zero_at_a_load_is_where_the_log_first_reaches_it(tmp_path):
    """A defect found by mutation testing (issue 12): with zero = a load, the reference must be where
    the log *first* reaches that load (ImportSettings docs). The log loads 2 → 10 kN (passing 6 kN
    between rows 3 and 4) and unloads to exactly 6 kN at row 5; the reference is the interpolated
    loading reading (1.5, 4), not the unloading row (3, 1) — hysteresis makes them differ. Before
    the fix an exact row anywhere in the log took precedence over an earlier crossing."""
    m = _read(tmp_path, "load,D1,D2\n0,9,9\n2,1,2\n10,2,6\n6,3,1\n", settings=ImportSettings(zero=6))
    assert m.reference_load == 6.0 and m.load_levels.tolist() == [0, 2, 10, 6]
    assert_allclose(m.values, [[7.5, 5.0], [-0.5, -2.0], [0.5, 2.0], [1.5, -3.0]], rtol=1e-12)
    _note(m, "zeroed at 6 kN", "between rows 3 and 4")
    m = _read(tmp_path, "load,D1\n0,1\n6,3\n10,5\n2,7\n", settings=ImportSettings(zero=6))  # row 3 first
    assert_allclose(m.values[:, 0], [-2.0, 0.0, 2.0, 4.0], rtol=1e-12)
    _note(m, "zeroed at 6 kN", "(row 3)")


def test_excel_formulas_read_as_the_values_excel_saved(tmp_path):
    """A formula cell reads as the value the spreadsheet saved with it (``=B2*2`` saved as 2), not
    as its formula text; an unreadable workbook is refused with the kind of damage."""
    plain = _workbook(tmp_path / "plain.xlsx", {"s": [["load", "D1", "D2"], [10, 1, "=B2*2"]]})
    p = tmp_path / "log.xlsx"
    with zipfile.ZipFile(plain) as src, zipfile.ZipFile(p, "w") as dst:
        for item in src.infolist():  # the cached value a spreadsheet program writes next to the formula
            data = src.read(item.filename)
            dst.writestr(item, data.replace(b"<f>B2*2</f><v />", b"<f>B2*2</f><v>2</v>"))
    m = read_measurement(p, SENSORS, LEVELS, "kN", "affine")
    assert m.values.tolist() == [[1.0, 2.0]]
    bad = _write(tmp_path, b"PK\x03\x04 not really a zip", "bad.xlsx")
    with pytest.raises(ValueError, match=r"not a readable Excel \.xlsx workbook") as info:
        read_measurement(bad, SENSORS, LEVELS, "kN", "affine")
    assert str(info.value).startswith(f"{bad}: ") and "BadZipFile" in str(info.value)


def test_the_former_reader_name_passes_every_argument_on(tmp_path):
    """``read_measurement_csv`` (the name of the former exact-load reader) is ``read_measurement``
    with the same arguments, settings included."""
    p = _write(tmp_path, "load [N];D1\n10000;1,5\n20000;2,5\n")
    m = read_measurement_csv(p, SENSORS, LEVELS, "kN", "discrete", ImportSettings(load_range=(15, 25)))
    assert m.load_levels.tolist() == [20.0] and m.values.tolist() == [[2.5]]
    with pytest.raises(ValueError, match="load_response must be one of"):
        read_measurement_csv(p, SENSORS, LEVELS, "kN", "exact")


def test_excel_damage_and_a_missing_openpyxl_are_explained(tmp_path, monkeypatch):
    """A workbook whose sheet is cut off is refused naming the damage; a file over the size limit is
    refused before it is opened, with the limit in MiB; without openpyxl the user is told to install
    it or save the sheet as CSV."""
    plain = _workbook(tmp_path / "plain.xlsx", {"s": [["load", "D1"], [10, 1]]})
    p = tmp_path / "cut.xlsx"
    with zipfile.ZipFile(plain) as src, zipfile.ZipFile(p, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            if item.filename == "xl/worksheets/sheet1.xml":
                data = data[: data.index(b'<row r="2">') + 15]
            dst.writestr(item, data)
    with pytest.raises(ValueError, match="cannot read the Excel sheet") as info:
        read_measurement(p, SENSORS, LEVELS, "kN", "affine")
    assert str(info.value).startswith(f"{p}: ") and "ParseError" in str(info.value)  # the kind of damage
    big = _write(tmp_path, b"x" * (2**21 + 1), "big.xlsx")  # refused on its size alone
    monkeypatch.setattr(measurement_log, "MAX_FILE_BYTES", 2**21)
    with pytest.raises(ValueError, match="larger than 2 MiB") as info:
        read_measurement(big, SENSORS, LEVELS, "kN", "affine")
    assert str(info.value).startswith(f"{big}: ")
    monkeypatch.setitem(sys.modules, "openpyxl", None)  # as if not installed
    with pytest.raises(ValueError, match="needs openpyxl") as info:
        read_measurement(plain, SENSORS, LEVELS, "kN", "affine")
    _contains(info.value, str(plain), "pip install 'openpyxl>=3.1'", "CSV")  # the two remedies


def test_the_unit_registry_is_built_on_first_use(monkeypatch):
    """pint's registry is built the first time a unit is converted (not at import) and then reused."""
    monkeypatch.setattr(measurement_log, "_UNITS", None)
    assert unit_factor("µm", "mm", "w") == pytest.approx(1e-3, rel=1e-15)
    registry = measurement_log._UNITS
    assert registry is not None
    assert unit_factor("cm", "mm", "w") == pytest.approx(10.0, rel=1e-15) and measurement_log._UNITS is registry


def test_zero_at_a_load_is_read_exactly_or_interpolated(tmp_path):
    """A zero load a row reaches to 1e-9 relative is read at that row; one 1.25e-6 relative away is
    interpolated (8.00001 kN between 8 and 10 kN: 3 + 2 · 5e-6). Compared to 1e-12 absolute (the
    rounding of 3 − 3.00001 is ~4e-16; reading at the row instead would be off by 1e-5)."""
    m = _read(tmp_path, "load,D1\n0,1\n8,3\n10,5\n", settings=ImportSettings(zero=8.00001))
    assert_allclose(m.values[:, 0], [1 - 3.00001, 3 - 3.00001, 5 - 3.00001], rtol=0, atol=1e-12)
    _note(m, "zeroed at 8.00001 kN", "between rows 3 and 4")


def test_phase_errors_and_notes(tmp_path):
    """zero = "end of PHASE": an empty phase column, a phase not in the column (no typo hint when no
    phase is close; the phases listed in at most 80 characters), readings missing at the reference
    (every sensor named) are refused naming the column or row; the note lists at most 20 phases."""
    phases = [f"p{k:02d}" for k in range(21)]
    rows = "".join(f"{ph},{k},{k},{2 * k}\n" for k, ph in enumerate(phases))
    log = "phase,load,D1,D2\n" + rows
    listed = "[" + ", ".join(repr(ph) for ph in phases[:11]) + ", …]"
    message = _error(tmp_path, log, settings=ImportSettings(zero="end of shear"))
    _contains(message, "{p}, column 1 (phase)", "phase 'shear'", listed)
    assert "'p11'" not in message and "close to" not in message  # what fits in 80 characters; no typo hint
    m = _read(tmp_path, log, settings=ImportSettings(zero="end of p05"))
    note = _note(m, "phase 'p05'", "(row 7, 5 kN)", "6 row(s)", ", ".join(phases[:20]))
    assert "p20" not in note
    assert_allclose(m.values[0], [1.0, 2.0], rtol=1e-15)
    _refused(tmp_path, "phase,load,D1\n,10,1\n ,20,2\n", "{p}, column 1 (phase)", "'end of x'", "empty",
             settings=ImportSettings(zero="end of x"))
    _refused(tmp_path, "phase,load,D1,D2,U1\na,10,,,1\nb,20,2,2,2\n", "{p}, row 2", "phase 'a'", "of D1, D2",
             settings=ImportSettings(zero="end of a"))


def test_a_title_line_mentioning_the_load_is_not_the_header(tmp_path):
    """A defect found by mutation testing (issue 12): the delimiter was taken from the first line
    *containing* the load column's name, so a title such as "Load test, wall 3" above a semicolon
    header made the reader split at commas and refuse the file ("no load column 'load' in the header
    ['Load test', 'wall 3']"). The header is the first line with a *cell* naming the load column
    (quoted or with a unit as well)."""
    m = _read(tmp_path, "Load test, wall 3\nload;D1\n10;1,5\n")
    assert m.values.tolist() == [[1.5]] and "skipped 1 line(s)" in m.notes[0]
    m = _read(tmp_path, "Wall 3 (load-controlled)\nDate: 2026, Nov 2\n\"Load [kN]\";\"D1\"\n10;1,5\n")
    assert m.values.tolist() == [[1.5]] and "skipped 2 line(s)" in m.notes[0]
    m = _read(tmp_path, "Wall 3, 2026\nt;FX;D1\n0;10;1,5\n", settings=ImportSettings(load_column="Fx"))
    assert m.values.tolist() == [[1.5]]  # a load column whose name ends in X is found too


def test_load_range_is_inclusive_and_rows_stay_aligned(tmp_path):
    """``load_range`` keeps the loads at both ends (documented inclusive) and notes only when rows
    are dropped; after zeroing at the first row an error still names the right row of the file."""
    content = "load,D1\n10,1\n20,2\n30,3\n40,4\n"
    m = _read(tmp_path, content, settings=ImportSettings(load_range=(10, 30)))
    assert m.load_levels.tolist() == [10, 20, 30]
    _note(m, "1 row(s) outside load_range [10, 30] kN")
    m = _read(tmp_path, content, settings=ImportSettings(load_range=(10, 40)))
    assert m.load_levels.tolist() == [10, 20, 30, 40] and not any("load_range" in n for n in m.notes)
    _refused(tmp_path, "load,D1\n10,0\n20,1\n25,2\n", "{p}, row 4, column 1 (load)", "load level 25 kN",
             "[10.0, 20.0, 30.0, 40.0]", response="discrete", settings=ImportSettings(zero="first"))


def test_cells_padded_with_tabs_or_spaces_and_the_source(tmp_path):
    """Cells padded with tabs or spaces in a comma file read as their numbers; a comma-delimited
    file with quoted decimal-comma cells reads with ``decimal = ","``; the measurement names its file."""
    p = _write(tmp_path, "load,D1,D2\n10,\t1.5,2\n20, 2.5\t,\t\n")
    m = read_measurement(p, SENSORS, LEVELS, "kN", "affine")
    assert_allclose(m.values, [[1.5, 2.0], [2.5, np.nan]], rtol=0)
    assert m.source == str(p)
    m = _read(tmp_path, "load,D1\n10,\"1,5\"\n", settings=ImportSettings(decimal=","))
    assert m.values.tolist() == [[1.5]]


def test_a_number_padded_with_a_non_breaking_space_reads(tmp_path):
    """A cell "1.5" followed by a non-breaking space (spreadsheets in European locales write them) or
    a quoted carriage return is a number with whitespace around it, read as such. Defect (found by
    mutation testing, issue 12): the vectorised path stripped only spaces and tabs, so such a column
    ended in an "unreadable cells" error naming no row. Whitespace inside a number is still refused,
    naming the cell."""
    m = _read(tmp_path, "load,D1\n10,1.5\xa0\n20,\"2\r\"\n")
    assert m.values.tolist() == [[1.5], [2.0]]
    m = _read(tmp_path, "load,D1\n10,\u20091.5\n20,\n")  # a thin space before, an empty cell after
    assert m.values[0].tolist() == [1.5] and np.isnan(m.values[1, 0])
    _refused(tmp_path, "load,D1\n10,1.5\n20,2\xa05\n", "row 3, column 2 (D1)", repr("2\xa05") + " is not a number")


def test_step_loads_and_every_typo_hint(tmp_path):
    """A stepped test's load column (unit "step", "-" or none) is read as the step numbers themselves
    (no conversion); every near miss of a sensor gets its own hint (similarity ≥ 0.75: "Dxx2" at 0.67
    gets none)."""
    for unit in ("step", "-"):
        m = _read(tmp_path, f"load [{unit}],D1,D22,U11,Dxx2\n1,1,2,3,4\n2,2,3,4,5\n", unit="step",
                  response="discrete", levels=(1, 2))
        assert m.load_levels.tolist() == [1.0, 2.0] and m.values.tolist() == [[1.0], [2.0]]
        _contains(m.notes[0], "D22, U11, Dxx2", "'D22' is close to sensor 'D2'", "'U11' is close to sensor 'U1'")
        assert m.notes[0].count("typo") == 2  # "Dxx2" gets none


def test_units_after_a_column_without_one_and_the_default_load_unit(tmp_path):
    """A sensor with a unit after one without is still converted, every column without a unit is
    named, and the load unit defaults to kN (a load in N is converted)."""
    p = _write(tmp_path, "load [N],D1,D2 [µm],U1\n10000,1,2,3\n")
    m = read_measurement(p, SENSORS, LEVELS)
    assert m.load_levels.tolist() == [10.0]
    assert_allclose(m.values, [[1.0, 0.002, 3.0]], rtol=1e-15)
    _note(m, "no unit", "D1, U1", "mm")
