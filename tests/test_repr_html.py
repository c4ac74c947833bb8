"""The HTML helpers behind the Jupyter display of the result objects (``podkrig/reports/jupyter.py``):
numbers as a reader sees them, tables exactly (issue 12: mutation survivors), and the registration
with IPython's HTML formatter."""

import math

from podkrig.reports import jupyter
from podkrig.reports.jupyter import html_table, number


def test_numbers_show_significant_digits_and_a_dash_when_missing():
    """Floats with ``digits`` significant digits; integers and strings as they are; None, NaN and
    ±inf as an em dash (a cell a reader can tell from a number). Defects: NaN printed as "nan", an
    integer or a name formatted as a float, the dash lost."""
    assert number(None) == number(math.nan) == number(math.inf) == number(-math.inf) == "—"
    assert number(1.23456789) == "1.235" and number(1.23456789, 2) == "1.2" and number(2.0e-7) == "2e-07"
    assert number(3) == "3" and number("E_b") == "E_b"


def test_tables_are_exact_escaped_and_captioned_only_when_asked():
    """The whole table string: a caption only when given, every cell escaped, rows one after the
    other. Defects: an empty caption element, cells unescaped (a name with ``<`` breaks the page),
    separators between rows."""
    assert html_table(["name", "value"], [["a<b", 1], ["c", "d&e"]]) == (
        "<table><thead><tr><th>name</th><th>value</th></tr></thead><tbody>"
        "<tr><td>a&lt;b</td><td>1</td></tr><tr><td>c</td><td>d&amp;e</td></tr></tbody></table>")
    assert html_table(["x"], [], caption="Fit & region").startswith(
        "<table><caption style='text-align:left'><b>Fit &amp; region</b></caption><thead>")


def test_a_running_ipython_shows_the_online_results_as_these_tables(monkeypatch):
    """``import podkrig`` in a notebook registers, by type name, one HTML function per online result
    with IPython's ``text/html`` formatter (a stand-in shell records the calls; IPython is not a
    dependency); outside IPython nothing is registered."""
    import importlib
    import sys
    import types

    import podkrig

    calls = []

    class Formatter:
        def for_type_by_name(self, module, name, function):
            calls.append((module, name, function))

    shell = types.SimpleNamespace(display_formatter=types.SimpleNamespace(formatters={"text/html": Formatter()}))
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: shell))
    importlib.reload(podkrig)
    assert calls == [("podkrig.online.calibrate", "CalibrationResult", jupyter.calibration_html),
                     ("podkrig.online.invert", "InverseResult", jupyter.inverse_result_html),
                     ("podkrig.online.region", "Region", jupyter.region_html)]
    for module, name, _ in calls:  # the names are real
        assert getattr(importlib.import_module(module), name).__name__ == name
    calls.clear()
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: None))
    importlib.reload(podkrig)
    assert calls == []
