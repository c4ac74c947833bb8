"""Fuzz suite (issue 13): measurement CSVs, scenario specs, study files and CLI arguments.

Property: for any input, podkrig either succeeds or raises its own error type with a message —
:class:`~podkrig.exceptions.PodkrigError`, ``ValueError`` (which the CLI prints as ``error:``) or
:class:`fe.exceptions.FEError` — never another exception (no ``TypeError``, ``KeyError``,
``RecursionError``, ``OverflowError``, ``UnicodeDecodeError``, ``csv.Error``, ...); the CLI ends
with exit code 0, 1 or 2 and never a traceback.

Sized for CI: ``PODKRIG_FUZZ_EXAMPLES`` examples per test (default 150; 6 tests), seed
:data:`SEED`. A larger run: ``PODKRIG_FUZZ_EXAMPLES=2000 pytest tests/test_fuzz.py -p no:xdist``.
Scenario specs are validated without building the FE model (its assembly is not under test).
"""

import json
import os
import tempfile
import traceback
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from fe.exceptions import FEError
from fe.scenarios import SCENARIOS, ScenarioSpec, build_scenario
from podkrig.cli import app
from podkrig.exceptions import PodkrigError
from podkrig.online.measurement_csv import read_measurement_csv
from podkrig.study import load_study

EXAMPLES = int(os.environ.get("PODKRIG_FUZZ_EXAMPLES", "150"))
SEED = 13_2026
OWN_ERRORS = (PodkrigError, ValueError, FEError)
FUZZ = settings(max_examples=EXAMPLES, deadline=None, database=None, derandomize=False,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                       HealthCheck.data_too_large, HealthCheck.filter_too_much])
FOLDER = Path(tempfile.mkdtemp(prefix="podkrig-fuzz-"))
runner = CliRunner()

NASTY = ["", " ", "nan", "-inf", "1e300", "1e-300", "2_5", "١٢", "0x1f", "1,5", "\"", "\"a,b\"", "\x00", "é",
         "$x^2$", "../../x", "/etc", "9" * 400, "-0", "+.5", "5.", "1e", ".", "\\", "\ud7ff", "<script>"]
scalars = st.one_of(
    st.integers(), st.integers(min_value=-(10**40), max_value=10**40), st.floats(), st.booleans(),
    st.text(max_size=12), st.sampled_from(NASTY), st.none(),
)
json_values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                            st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                           max_leaves=12)


def _own_error_or_success(fn, *args):
    try:
        fn(*args)
    except OWN_ERRORS as e:
        assert str(e).strip(), f"{type(e).__name__} without a message"
        assert not isinstance(e, UnicodeError), f"{type(e).__name__} does not name the file: {e}"
    except Exception as e:  # noqa: BLE001 - the property under test
        pytest.fail(f"{type(e).__name__} escaped for input {args!r}:\n{traceback.format_exc()}")


# ----------------------------------------------------------------------------- measurement CSV
cells = st.one_of(st.floats().map(repr), st.integers(min_value=-(10**30), max_value=10**30).map(str),
                  st.text(max_size=10), st.sampled_from(NASTY), st.sampled_from(["25", "50", "-0.1", "0.002"]))
header_names = st.one_of(st.sampled_from(["load", "D1", "D2", "load ", "LOAD", "", "D1"]), st.text(max_size=6))
separators = st.sampled_from([",", ";", "\t", ", "])
newlines = st.sampled_from(["\n", "\r\n", "\r"])


@st.composite
def csv_bytes(draw):
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=400))
    sep, nl = draw(separators), draw(newlines)
    header = draw(st.lists(header_names, max_size=5))
    rows = draw(st.lists(st.lists(cells, max_size=5), max_size=6))
    text = nl.join(sep.join(r) for r in [header, *rows])
    encoding = draw(st.sampled_from(["utf-8", "utf-8", "utf-16", "latin-1", "utf-8-sig"]))
    return text.encode(encoding, errors="replace")


@seed(SEED)
@FUZZ
@given(content=csv_bytes())
def test_fuzz_measurement_csv(content):
    path = FOLDER / "m.csv"
    path.write_bytes(content)
    _own_error_or_success(read_measurement_csv, path, ("D1", "D2", "D3"), (25.0, 50.0, 75.0))


# ----------------------------------------------------------------------------- scenario specs
@pytest.fixture(scope="module")
def no_fe_assembly():
    """Scenario construction validates its spec, then builds the FE model; skip the building."""
    with pytest.MonkeyPatch.context() as mp:
        for cls in set(SCENARIOS.values()):
            mp.setattr(cls, "_build", lambda self: None)
        yield


option_names = st.sampled_from(["nx", "ny", "n_courses", "units_per_course", "thickness", "unit_length",
                                "unit_height", "bond", "element", "load_levels", "sensors", "continuum",
                                "brick_interfaces", "precompression", "x"])


@st.composite
def spec_dicts(draw):
    d = {"scenario": draw(st.one_of(st.sampled_from(sorted(SCENARIOS)), scalars))}
    for k in draw(st.lists(option_names, max_size=4, unique=True)):
        d[k] = draw(st.one_of(json_values, st.integers(-3, 100), st.lists(st.floats(), max_size=5)))
    if draw(st.booleans()):
        d["parameters"] = draw(st.one_of(json_values, st.dictionaries(
            st.sampled_from(["E_b", "kN_bj", "kV_bj", "r_hj", "x"]), scalars, max_size=3)))
    return d


@seed(SEED)
@FUZZ
@given(d=spec_dicts())
def test_fuzz_scenario_spec_dicts(no_fe_assembly, d):
    _own_error_or_success(build_scenario, d)


@seed(SEED)
@FUZZ
@given(text=st.one_of(st.text(max_size=200), json_values.map(lambda v: json.dumps(v, default=str))),
       suffix=st.sampled_from([".toml", ".json"]))
def test_fuzz_scenario_spec_files(no_fe_assembly, text, suffix):
    path = FOLDER / f"spec{suffix}"
    path.write_bytes(text.encode("utf-8", errors="surrogatepass"))
    _own_error_or_success(lambda p: build_scenario(ScenarioSpec.from_file(p)), path)


# ----------------------------------------------------------------------------- study files
STUDY_LINES = """\
name = "check"
[scenario]
scenario = "diagonal_compression"
nx = 2
ny = 1
[parameters]
kN_bj = { lower = 30.0, upper = 300.0, scale = "log" }
[fixed]
r_hj = 0.6
[sampling]
train = { n = 16, seed = 0 }
held_out = { n = 4, seed = 1, method = "random" }
[measurement]
file = "measured.csv"
noise_rel = 0.01
[inversion]
confidence = 0.95
region_samples = 2048
[[validation]]
name = "shear"
scenario = "shear_compression"
n = 8
seed = 2
""".splitlines()
toml_values = st.one_of(
    st.sampled_from(["1", "-1", "0", "\udcff", "1e400", "nan", "inf", "true", '"x"', '"../../x"', "[]", "{}", "[[1], [2]]",
                     "{ lower = 1 }", "99999999999999999999999999999", '"$\\\\alpha$"', "[" * 60 + "]" * 60,
                     "[" * 3000 + "]" * 3000, "[{ lower = 1 }, 2]", '[["a"], "b"]', "{ lower = [1], upper = 2 }",
                     "{ a = " * 40 + "1" + " }" * 40, '""', "2026-11-24", '"\\u00e9"', "[1, 2, 3]", "1" + "0" * 400, "-" + "9" * 30]),
    st.integers().map(str), st.floats(allow_nan=False, allow_infinity=False).map(repr),
)


@st.composite
def study_texts(draw):
    lines = list(STUDY_LINES)
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(lines) - 1))
        action = draw(st.integers(0, 3))
        if action == 0 and "=" in lines[i]:
            lines[i] = lines[i].split("=", 1)[0] + "= " + draw(toml_values)
        elif action == 1:
            del lines[i]
            if not lines:
                lines = [""]
        elif action == 2:
            lines.insert(i, f"{draw(st.sampled_from(['x', 'workers', 'n', 'name', 'sensors']))} = {draw(toml_values)}")
        else:
            lines[i] = draw(st.text(max_size=30))
    return "\n".join(lines)


@seed(SEED)
@FUZZ
@given(text=study_texts())
def test_fuzz_study_files(text):
    (FOLDER / "measured.csv").write_text("load,D1\n25,-0.1\n")
    path = FOLDER / "study.toml"
    path.write_bytes(text.encode("utf-8", errors="surrogatepass"))
    _own_error_or_success(load_study, path)


# ----------------------------------------------------------------------------- CLI arguments
def _files():
    (FOLDER / "garbage.h5").write_bytes(os.urandom(256))
    (FOLDER / "data.csv").write_text("load,D1\n25,-0.1\n")
    (FOLDER / "not_utf8.csv").write_bytes(b"load,D1\n25,\xff\n")
    (FOLDER / "dir").mkdir(exist_ok=True)
    return [str(FOLDER / n) for n in ("garbage.h5", "data.csv", "not_utf8.csv", "dir", "missing.h5")]


PATHS = _files() + ["/dev/null", "", "-"]
COMMANDS = [["snapshots", "info"], ["snapshots", "verify"], ["snapshots", "export"], ["invert"],
            ["surrogate", "validate"], ["run"], ["diagnose"], ["snapshots", "run"]]
OPTIONS = ["--data", "--csv", "--store", "--out", "--format", "--region-samples", "--n", "--seed", "--workers",
           "--chunk-size", "--noise-rel", "--noise-abs", "--confidence", "--param", "--scenario", "--free",
           "--fix", "--rehash", "--yes", "-v"]
tokens = st.one_of(st.sampled_from(PATHS), st.sampled_from(OPTIONS), st.sampled_from(NASTY),
                   st.integers(-(10**20), 10**20).map(str), st.sampled_from(["json", "text", "0", "1", "-5", "1e999",
                                                                             "kN_bj=10:1000:log", "D1=0.1",
                                                                             "diagonal_compression"]))


@seed(SEED)
@FUZZ
@given(command=st.sampled_from(COMMANDS), args=st.lists(tokens, max_size=8))
def test_fuzz_cli_arguments(command, args):
    if command == ["snapshots", "run"]:  # never a valid FE job: the store is a folder or garbage
        args = [*args, "--store", PATHS[3]]
    result = runner.invoke(app, [*command, *args], input="n\n")
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        pytest.fail(f"{type(result.exception).__name__} escaped for podkrig {command + args}:\n"
                    + "".join(traceback.format_exception(result.exception)))
    assert result.exit_code in (0, 1, 2), (command + args, result.exit_code, result.output)
    assert "Traceback" not in result.output
