"""How the result objects show themselves: the HTML helpers of ``podkrig/reports/jupyter.py``
(numbers as a reader sees them, tables exactly), the renderers' registration, and a short text repr
and an escaped ``_repr_html_`` on every result a user gets (``podkrig/display.py``, ``fe/display.py``)."""

import dataclasses
import html.parser
import importlib
import math
import pkgutil
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import fe
import fe.display
import podkrig
from podkrig.display import MAX_REPR, summary
from podkrig.online.calibrate import CalibrationResult
from podkrig.online.invert import InverseResult
from podkrig.online.region import Region
from podkrig.online.settings import CalibrationSettings
from podkrig.reports import jupyter
from podkrig.reports.findings import FindingText
from podkrig.reports.jupyter import html_table, number
from podkrig.study import StageRecord, StudyResult, load_study

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


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


def test_a_summary_is_a_few_characters():
    """Numbers with 4 significant digits, positional where a reader expects it; texts cut; arrays,
    long sequences and tables by size. Defects: 2e+04 for a bound of 20000, a whole array."""
    assert [summary(v) for v in (20000.0, 0.123456, 1e-7, 3.0e9, 0.0, float("nan"), 7, True, None)] == [
        "20000", "0.1235", "1e-07", "3e+09", "0", "nan", "7", "True", "None"]
    assert summary("x" * 100, 10) == repr("x" * 9 + "…") and summary(np.zeros((500, 3))) == "array(500, 3) float64"
    assert summary(np.array([1.0, 2.5])) == "[1, 2.5]" and summary(list(range(100))) == "100 items"
    assert summary({"a": 1, "b": 2.5}) == "{a: 1, b: 2.5}" and summary({i: i for i in range(9)}).startswith("9 entries")


def test_a_running_ipython_gets_the_renderers_and_plain_python_imports_nothing(monkeypatch):
    """``import podkrig`` in a notebook registers this module's renderers with the results'
    ``_repr_html_`` (a stand-in shell; IPython is not a dependency); outside IPython the reports are
    not imported. The registered names are real classes."""
    registered = {}
    monkeypatch.setattr("podkrig.display._RENDERERS", registered)
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: None))
    importlib.reload(podkrig)
    assert registered == {}
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: object()))
    importlib.reload(podkrig)
    assert registered == {name: getattr(jupyter, function) for name, function in jupyter.RENDERERS.items()}
    for name in registered:
        module, _, cls = name.rpartition(".")
        assert getattr(importlib.import_module(module), cls).__name__ == cls


def _result_classes():
    """Every class of ``fe`` and ``podkrig`` a user gets as a result: those with ``to_dict`` named
    ``…Result`` or ``…Report``, and the other results of the stages by name."""
    others = {"Region", "Posterior", "FECheck", "ModelError", "NestedAnalysis", "LayoutScore", "Study", "Response",
              "NonlinearResponse", "Peak", "Phase3Check", "DDMSolution", "GAResult", "StudyResult"}
    found = {}
    for package in (fe, podkrig):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            module = importlib.import_module(info.name)
            for name, cls in vars(module).items():
                if (isinstance(cls, type) and cls.__module__ == module.__name__
                        and (name in others or (name.endswith(("Result", "Report")) and hasattr(cls, "to_dict")))):
                    found[f"{cls.__module__}.{name}"] = cls
    return found


RESULT_CLASSES = _result_classes()


def test_every_result_class_has_a_short_repr_and_html():
    """Every result class (found by walking the packages, not listed by hand) mixes in the display:
    its repr is not the dataclass's field dump and it has ``_repr_html_``. Defect: a new result
    class that prints its arrays whole in a notebook."""
    named = {"InverseResult", "Region", "StudyResult", "CalibrationResult", "OfflineResult", "SurrogateFitResult",
             "HeldOutResult", "ValidationModelResult", "DiagnosisResult", "SensitivityResult", "PlacementResult",
             "PathResult", "Study", "GAResult"}
    assert named <= {name.rpartition(".")[2] for name in RESULT_CLASSES}
    for name, cls in RESULT_CLASSES.items():
        assert issubclass(cls, fe.display.Displayed), name
        assert "__repr__" not in vars(cls) and callable(cls._repr_html_), name  # repr=False: the mixin's


_BIG = 10 ** 5


def _adversarial(field):
    """A large value for any field: a long array, a long text with markup, a big table."""
    return {0: np.linspace(0.0, 1.0, _BIG), 1: "<script>alert(1)</script>" * 200,
            2: {f"k{i}": np.arange(i + 5.0) for i in range(500)}, 3: list(range(_BIG))}[hash(field.name) % 4]


@pytest.mark.parametrize("name", sorted(n for n, c in RESULT_CLASSES.items()
                                        if c._repr_lines is fe.display.Displayed._repr_lines))
def test_a_large_result_prints_in_a_few_lines_and_its_html_is_escaped(name):
    """Each result with the generic display, every field filled with 10⁵ numbers, a long text with
    markup or a table of 500 arrays: the repr is at most MAX_REPR characters with no run of the
    array's values, and its HTML has the markup escaped (no ``<script>``) and is well-formed."""
    cls = RESULT_CLASSES[name]
    obj = object.__new__(cls)  # the values need not make sense: only their size matters here
    for field in dataclasses.fields(cls):
        object.__setattr__(obj, field.name, _adversarial(field))
    text = repr(obj)
    assert len(text) <= MAX_REPR and text.startswith(cls.__name__), text
    assert "0.00001" not in text and "99999" not in text
    markup = obj._repr_html_()
    assert "<script>" not in markup and len(markup) < 100 * MAX_REPR
    _well_formed(markup)


def _well_formed(markup):
    class Page(html.parser.HTMLParser):
        stack = []

        def handle_starttag(self, tag, attrs):
            if tag not in ("br", "img"):
                self.stack.append(tag)

        def handle_endtag(self, tag):
            assert self.stack.pop() == tag, tag

    page = Page()
    page.stack = []
    page.feed(markup)
    page.close()
    assert page.stack == []


def _inverse_and_region(n_params, n_members, name=lambda j: f"p{j}"):
    names = tuple(name(j) for j in range(n_params))
    units = ("MPa",) * n_params
    x = np.linspace(1.0, 2.0, n_params)
    inv = InverseResult(x, dict(zip(names, x)), 12.5, 40.0, 38, 2400, 1.5, names, units, names[:1],
                        {"n_obs": 48})
    region = Region("likelihood-ratio", 0.95, np.ones((n_members, n_params)), np.zeros(n_members), 13.0,
                    {n: (0.5, 2.5) for n in names}, names, units, 10 ** 5, 3.0,
                    {n: {"share": 0.25, "identifiable": j % 2 == 0} for j, n in enumerate(names)})
    return inv, region


def test_the_inversion_and_the_region_print_their_numbers_in_a_few_lines():
    """An inversion and its region read as a summary: χ²/dof, dof, each parameter's value and unit,
    the bound it sits on, the interval and whether it is identified — and with 40 parameters and
    10⁵ members still at most MAX_REPR characters, cut at a line with the count left out."""
    inv, region = _inverse_and_region(3, 504)
    text = repr(inv)
    assert "χ²/dof 1.053 (dof 38)" in text and "p0 = 1 MPa (on a bound)" in text and "p2 = 2 MPa" in text
    text = repr(region)
    assert "504 members of 100000 evaluations" in text and "p1 in [0.5, 2.5] MPa (not identified)" in text
    big_inv, big_region = _inverse_and_region(40, 10 ** 5)
    for obj in (big_inv, big_region):
        text = repr(obj)
        assert len(text) <= MAX_REPR and "more lines" in text, text
    calibration = CalibrationResult(big_inv, big_region, None, {}, [], CalibrationSettings(), 9.0, 2)
    text = repr(calibration)
    assert len(text) <= MAX_REPR and "p0 = 1 MPa in [0.5, 2.5]" in text and "2 FE runs" in text


def test_names_with_markup_are_escaped_in_the_html():
    """A parameter named with markup shows as text in every table of the inversion, the region and
    the calibration (escaped), and the pages are well-formed."""
    inv, region = _inverse_and_region(2, 10, name=lambda j: f"<b>p{j}</b>")
    calibration = CalibrationResult(inv, region, None, {}, [], CalibrationSettings(), 9.0)
    for obj in (inv, region, calibration):
        markup = obj._repr_html_()
        assert "<b>p0</b>" not in markup and "&lt;b&gt;p0&lt;/b&gt;" in markup
        _well_formed(markup)


def test_a_study_shows_its_scenario_designs_and_parameters():
    """A loaded study (the diagonal-compression example) prints its scenario, designs and search
    ranges in a few lines and shows them as HTML tables in a notebook."""
    study = load_study(EXAMPLES / "diagonal_compression.toml")
    text = repr(study)
    assert len(text) <= MAX_REPR and text.startswith(f"Study {study.name!r}: 1 test, 4 free parameters")
    assert f"scenario {study.spec.scenario}, {study.train.n} training and {study.held_out.n} held-out" in text
    first = study.space.parameters[0]
    assert f"{first.name} in [{summary(first.lower)}, {summary(first.upper)}] {first.unit}" in text
    markup = study._repr_html_()
    for word in ("Free parameters", first.name, first.unit, f"{study.train.n} FE runs"):
        assert word in html.unescape(markup), word
    _well_formed(markup)
    joint = load_study(EXAMPLES / "joint_three_tests.toml")  # one line per test, every test's parameters
    text = repr(joint)
    assert len(text) <= MAX_REPR and f"{len(joint.tests)} tests" in text
    for t in joint.tests:
        assert f"test {t.name}: scenario {t.spec.scenario}" in text and t.name in html.unescape(joint._repr_html_())
    assert {p.name for t in joint.tests for p in t.space.parameters} == {p.name for p in joint.free_parameters}


def test_a_study_result_prints_its_stages_and_warnings_in_a_few_lines(tmp_path):
    """A study result: stages run and cached, FE runs, warnings (each cut to a line) and where
    the report is; bounded however many warnings."""
    study = load_study(EXAMPLES / "diagonal_compression.toml")
    stages = (StageRecord("offline", "Offline", False, 10.0, 64, {}), StageRecord("surrogate", "Surrogate", True, 0.0, 0, {}))
    warnings = [FindingText("code", "fit", "<i>w</i>" * 100, "do this")] * 50
    result = StudyResult(study, tmp_path, stages, warnings, tmp_path / "report" / "index.html", 12.0)
    text = repr(result)
    assert len(text) <= MAX_REPR and "2 stages (1 run, 1 cached), 64 FE runs, 50 warnings" in text, text
