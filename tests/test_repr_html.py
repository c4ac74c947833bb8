"""The HTML helpers behind the ``_repr_html_`` of the result objects (``podkrig/online/_repr.py``):
numbers as a reader sees them, tables exactly (issue 12: mutation survivors)."""

import math

from podkrig.online._repr import html_table, number


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
