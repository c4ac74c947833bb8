"""Fuzz suite (issue 13): measurement CSVs, scenario specs, study files and CLI arguments.

Property: for any input, podkrig either succeeds or raises its own error type with a message —
:class:`~podkrig.exceptions.PodkrigError`, ``ValueError`` (which the CLI prints as ``error:``) or
:class:`fe.exceptions.FEError` — never another exception (no ``TypeError``, ``KeyError``,
``RecursionError``, ``OverflowError``, ``UnicodeDecodeError``, ``csv.Error``, ...); the CLI ends
with exit code 0, 1 or 2 and never a traceback.

Sized for CI: ``PODKRIG_FUZZ_EXAMPLES`` examples per test (default 150; 8 tests), seed
:data:`SEED`. A larger run: ``PODKRIG_FUZZ_EXAMPLES=2000 pytest tests/test_fuzz.py -p no:xdist``.
Scenario specs are validated without building the FE model (its assembly is not under test).
"""

import json
import os
import tempfile
import traceback
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from fe.exceptions import FEError
from fe.scenarios import SCENARIOS, ScenarioSpec, build_scenario
from podkrig.cli import app
from podkrig.exceptions import PodkrigError
from podkrig.io.measurement_log import ImportSettings, read_measurement, read_measurement_csv
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


# ----------------------------------------------------------------------------- laboratory logs (issue 14)
LOG_HEADERS = st.one_of(
    st.sampled_from(["load", "load [kN]", "Load (N)", "load [MPa]", "load [mm]", "load []", "load [", "load [kN",
                     "time [s]", "ch", "D1", "D1 [µm]", "D1 (mm)", "D1 [um]", "D1 [kN]", "D1 [bananas]", "d1 [m]",
                     "D2 [μm]", "D2 [in]", "D3 (mm)", "D3 [1/0]", "D3 [mm**99999]", "D1 [K]", "D2 [degC]", "",
                     "phase", "Phase [-]", "step"]),
    st.text(max_size=8))
LOG_CELLS = st.one_of(cells, st.sampled_from(["10,03", "10.41", "-32,1", "", "NaN", "n/a", " 5 ", "1,5e-3", "1.5E+3",
                                              "1e308", "-1e308", "12:00:01", "∞", "1,000.5", "0,0",
                                              "precompression", "shear", "2", "2.0", "1e400"]),
                      st.floats(-200, 200).map(lambda v: f"{v:.3f}"))


@st.composite
def log_bytes(draw):
    sep, nl = draw(st.sampled_from([",", ";", "\t"])), draw(newlines)
    lines = draw(st.lists(st.text(max_size=15), max_size=2))  # a preamble
    lines.append(sep.join(draw(st.lists(LOG_HEADERS, min_size=1, max_size=6))))
    if draw(st.booleans()):
        lines.append(sep.join(draw(st.lists(st.sampled_from(["[kN]", "[µm]", "mm", "", "s", "[x]"]), max_size=6))))
    for _ in range(draw(st.integers(0, 8))):
        lines.append(sep.join(draw(st.lists(LOG_CELLS, max_size=7))))
    text = nl.join(lines)
    return text.encode(draw(st.sampled_from(["utf-8", "utf-8-sig", "cp1252", "utf-16"])), errors="replace")


import_settings = st.builds(
    ImportSettings,
    load_column=st.sampled_from(["load", "Load", "time", "F"]),
    repeats=st.sampled_from(["average", "keep"]),
    load_tolerance=st.sampled_from([0.0, 0.05, 1.0, 100.0]),
    zero=st.one_of(st.none(), st.just("first"), st.floats(-50, 150),
                   st.sampled_from(["end of precompression", "end of 2", "End of  shear "])),
    phase_column=st.sampled_from(["phase", "step", "load", "D1"]),
    load_range=st.one_of(st.none(), st.tuples(st.floats(-10, 60), st.floats(0, 200)).map(lambda t: tuple(sorted(t)))),
    delimiter=st.sampled_from([None, None, ";", "\t"]),
    decimal=st.sampled_from([None, None, ".", ","]),
)


@seed(SEED)
@FUZZ
@given(content=log_bytes(), settings=import_settings,
       model=st.sampled_from([("kN", "affine", (10.0, 20.0, 30.0, 40.0)), ("mm", "path", (0.25, 1.0, 3.0)),
                              ("step", "discrete", (1.0, 2.0, 3.0)), ("kN", "affine", (25.0,))]))
def test_fuzz_lab_logs(content, settings, model):
    """Generated lab logs read with generated settings against linear, nonlinear and stepped models;
    a log that is read must also give the model's observation operator without a traceback."""
    path = FOLDER / "log.csv"
    path.write_bytes(content)
    unit, response, levels = model
    sensors = ("D1", "D2", "D3")

    def read_and_observe():
        m = read_measurement(path, sensors, levels, unit, response, settings)
        op = m.observation(sensors, levels, response, unit)
        Y = np.arange(len(levels) * len(sensors), dtype=float)[None]
        assert op.apply(Y).shape == (1, m.n_obs)

    _own_error_or_success(read_and_observe)


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


MEASUREMENT_KEYS = ["file", "noise_rel", "noise_abs", "instrument", "load_column", "repeats", "load_tolerance",
                    "zero", "phase_column", "load_range", "delimiter", "decimal", "sheet", "range_check", "x"]
measurement_values = st.one_of(
    toml_values, st.sampled_from(['"measured.csv"', '"first"', '"none"', '"end of precompression"', '"phase"', '"lvdt"', '"dic"', '{ D1 = "lvdt" }',
                                  '{ D1 = 0.001 }', '[10, 40]', '[40, 10]', '";"', '","', '"."', '"average"',
                                  '"keep"', "0.001", "0.01", "true", '"Sheet1"', '"\\t"']))


@seed(SEED)
@FUZZ
@given(entries=st.dictionaries(st.sampled_from(MEASUREMENT_KEYS), measurement_values, max_size=6))
def test_fuzz_study_measurement_blocks(entries):
    """Generated [measurement] tables (issue 14 keys): checked by the study loader, never a traceback."""
    (FOLDER / "measured.csv").write_text("load [kN];D1 [µm]\n25;-100,5\n")
    lines = [ln for ln in STUDY_LINES if not ln.startswith(("file =", "noise_rel ="))]
    at = lines.index("[measurement]") + 1
    body = [f"{k} = {v}" for k, v in entries.items()]
    path = FOLDER / "study_m.toml"
    path.write_bytes("\n".join(lines[:at] + body + lines[at:]).encode("utf-8", errors="surrogatepass"))

    def load_and_read():
        study = load_study(path)
        m = study.measurement
        read_measurement(m.file, ("D1", "D2"), (25.0, 50.0), "kN", "affine", m.import_settings())
        m.noise.noise_model(("D1",))

    _own_error_or_success(load_and_read)


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
