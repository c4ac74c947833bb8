"""The study file: validation errors name the file, the line, the key and the allowed values."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import load_file
from fe.scenarios import SCENARIOS
from podkrig.cli import app
from podkrig.study import StudyError, key_lines, load_study

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

VALID = """\
name = "check"

[scenario]
scenario = "diagonal_compression"
nx = 2
ny = 1

[parameters]
kN_bj = { lower = 30.0, upper = 300.0, scale = "log" }
kV_bj = { lower = 10.0, upper = 120.0, scale = "log" }

[fixed]
r_hj = 0.6

[sampling]
train = { n = 16, seed = 0 }
held_out = { n = 4, seed = 1, method = "random" }

[surrogate]
beta = "fit-shared"

[measurement]
file = "measured.csv"
noise_rel = 0.01

[inversion]
confidence = 0.95

[[validation]]
name = "shear"
scenario = "shear_compression"
n = 8
seed = 2

[[validation]]
name = "shear_fine"
scenario = "shear_compression"
n = 16
seed = 3
"""


def _write(tmp_path, text):
    (tmp_path / "measured.csv").write_text("load,D1\n25,-0.1\n")
    path = tmp_path / "study.toml"
    path.write_text(text)
    return path


def test_valid_study_and_defaults(tmp_path):
    study = load_study(_write(tmp_path, VALID))
    assert study.space.names == ("kN_bj", "kV_bj") and study.space.scales == ("log", "log")
    assert study.spec.parameters == {"r_hj": 0.6} and study.spec.options["nx"] == 2
    assert study.train.method == "sobol" and study.held_out.method == "random" and study.workers == 1
    assert study.surrogate.beta == "fit-shared" and study.inversion.population_size == 100
    assert study.measurement.file == (tmp_path / "measured.csv").resolve()
    assert [v.name for v in study.validation] == ["shear", "shear_fine"]
    assert study.validation[0].spec.parameters == {"r_hj": 0.6}  # the fixed material holds there too
    assert study.validation[0].fe_runs == 0  # a linear FE run cannot fail: no runs at region members
    assert study.diagnosis.enabled is False


@pytest.mark.parametrize(
    "old, new, marker, patterns",
    [
        # unknown keys, with the allowed ones (and a suggestion)
        ('name = "check"', 'name = "check"\nfitness = 1', "fitness", [r"fitness: unknown key", r"allowed: .*sampling"]),
        ("train = {", "trian = {", "trian", [r"sampling\.trian: unknown key \(did you mean 'train'\?\)",
                                             r"allowed: keys in \[sampling\]: held_out, scheduler, train, workers"]),
        ("seed = 0 }", "seed = 0, size = 3 }", "size = 3", [r"sampling\.train\.size: unknown key", r"method, n, seed"]),
        ("nx = 2", "nxx = 2", "nxx", [r"scenario\.nxx: unknown key \(did you mean 'nx'\?\)", r"allowed: .*ny"]),
        ("r_hj = 0.6", "G_f = 0.6", "G_f", [r"fixed\.G_f: unknown parameter of diagonal_compression",
                                            r"allowed: E_b, nu_b, kN_bj"]),
        ("kN_bj = {", "kN_bx = {", "kN_bx", [r"parameters\.kN_bx: unknown parameter", r"allowed: .*kN_bj"]),
        # wrong types
        ('beta = "fit-shared"', "beta = true", "beta = true",
         [r"surrogate\.beta: must be a number; got boolean True", r"\"fit\" or \"fit-shared\""]),
        ("n = 16,", 'n = "16",', 'n = "16"', [r"sampling\.train\.n: must be an integer; got string '16'"]),
        ("noise_rel = 0.01", 'noise_rel = "1 %"', "noise_rel", [r"measurement\.noise_rel: must be a number"]),
        # out of range, with the allowed range
        ("confidence = 0.95", "confidence = 1.5", "confidence", [r"inversion\.confidence: 1\.5 is out of range",
                                                                 r"allowed: a number in \(0, 1\)"]),
        ("n = 16,", "n = 2,", "n = 2", [r"sampling\.train\.n: 2 is out of range", r"an integer in \[4, 16777216\]"]),
        ('method = "random"', 'method = "halton"', "halton", [r"held_out\.method: 'halton' is out of range",
                                                             r"allowed: sobol, lhs, random, lhs-ese"]),
        ('scale = "log" }\nkV', 'scale = "ln" }\nkV', '"ln"', [r"parameters\.kN_bj\.scale: 'ln' is out of range",
                                                             r"allowed: linear or log"]),
        ("upper = 300.0", "upper = 20.0", "upper = 20.0", [r"parameters\.kN_bj\.upper: must exceed lower = 30",
                                                           r"allowed: upper > 30"]),
        ("lower = 30.0", "lower = -1.0", "lower = -1.0", [r"parameters\.kN_bj\.lower: -1\.0 is out of range",
                                                          r"allowed: \(0, 1e\+09\] N/mm³"]),
        ("r_hj = 0.6", "r_hj = 12.0", "r_hj", [r"fixed\.r_hj: = 12\.0 is outside its physical range",
                                               r"allowed: \[0, 10\]"]),
        ('beta = "fit-shared"', 'beta = "fitted"', "beta", [r"'fitted' is not a known exponent setting"]),
        ("noise_rel = 0.01", "noise_rel = 0.01\ninstrument = \"lvdt\"", "instrument",
         [r"measurement\.instrument: give either instrument or noise_rel, not both"]),
        ("noise_rel = 0.01", 'instrument = "laser"', "instrument",
         [r"measurement\.instrument: 'laser' is not a known instrument", r'"lvdt" \| "dial_gauge" \| "dic"']),
        ("noise_rel = 0.01", 'noise_rel = 0.01\nzero = "last"', "zero", [r"measurement\.zero: 'last' is not a zero "
                                                                      r"reference", r'"first", "none" or a load']),
        ("noise_rel = 0.01", "noise_rel = 0.01\nload_range = [40, 10]", "load_range",
         [r"measurement\.load_range: \[40, 10\] is not a load range"]),
        ("noise_rel = 0.01", 'noise_rel = 0.01\nrepeats = "median"', "repeats", [r"measurement\.repeats"]),
        ("noise_rel = 0.01", 'noise_rel = 0.01\nrigid_body = "off"', "rigid_body",
         [r"measurement\.rigid_body: 'off' is out of range", r'allowed: "auto" .*"remove" .*"keep"']),
        ("noise_rel = 0.01", 'noise_rel = 0.01\nmodel_form_error = "guessed"', "model_form_error",
         [r"measurement\.model_form_error: got 'guessed'", r'allowed: "none", "estimated" or a number in \[0, 0\.5\)']),
        ("noise_rel = 0.01", "noise_rel = 0.01\nmodel_form_error = 0.8", "model_form_error",
         [r"measurement\.model_form_error: got 0\.8"]),
        ("noise_rel = 0.01", 'noise_rel = 0.01\nrigid_groups = { top = "P1" }', "rigid_groups",
         [r"measurement\.rigid_groups\.top: must be a non-empty array of sensor names; got string 'P1'"]),
        ("noise_rel = 0.01", 'noise_rel = 0.01\nrigid_body = "keep"\nrigid_groups = { top = ["P1"] }', "rigid_groups",
         [r"measurement\.rigid_groups: rigid_groups name sensors .* removes none"]),
        ('file = "measured.csv"', 'file = "missing.csv"', "missing.csv", [r"measurement\.file: no measurement file"]),
        ('scenario = "diagonal_compression"', 'scenario = "diagonal"', '"diagonal"',
         [r"scenario\.scenario: unknown scenario 'diagonal'",
          "allowed: " + re.escape(", ".join(sorted(SCENARIOS)))]),
        ("r_hj = 0.6", "kN_bj = 90.0", "kN_bj = 90", [r"fixed\.kN_bj: is also a free parameter"]),
        # the second [[validation]] table
        ("n = 16\nseed = 3", "n = 2\nseed = 3", "n = 2", [r"validation\[2\]\.n: 2 is out of range"]),
            ('name = "shear_fine"', 'name = "shear"', 'name = "shear"',
         [r"validation\[2\]\.name: 'shear' names two validation models"]),
    ],
)
def test_errors_name_file_line_key_and_allowed_values(tmp_path, old, new, marker, patterns):
    assert old in VALID
    text = VALID.replace(old, new, 1)
    path = _write(tmp_path, text)
    # the expected line: where the marker lies in the edited text
    line = text[: VALID.index(old) + new.index(marker)].count("\n") + 1
    with pytest.raises(StudyError) as info:
        load_study(path)
    message = str(info.value)
    assert message.startswith(f"{path}, line {line}: "), message
    for pattern in patterns:
        assert re.search(pattern, message), (pattern, message)


def test_missing_table_and_toml_syntax_errors(tmp_path):
    path = _write(tmp_path, VALID.replace("[measurement]", "[measurements]"))
    line = VALID[: VALID.index("[measurement]")].count("\n") + 1
    with pytest.raises(StudyError, match=rf"line {line}: measurements: .*'measurement'"):
        load_study(path)
    text = VALID.replace("[measurement]\n", "")
    text = text.replace('file = "measured.csv"\nnoise_rel = 0.01\n', "")
    path = _write(tmp_path, text)
    with pytest.raises(StudyError, match=r"study\.toml: missing key 'measurement'"):
        load_study(path)
    path = _write(tmp_path, VALID.replace("nx = 2", "nx = = 2"))
    with pytest.raises(StudyError, match=r"study\.toml: not valid TOML: .*line 5"):
        load_study(path)


def test_key_lines():
    text = (
        'a = 1\n[t]\nb = { c = 1, d = { e = [1, { f = 2 }] } }  # { g = 3 }\n"q.r".s = 4\n'
        '[[arr]]\nx = 1\n[[arr]]\nx = """\ny = 2\n"""\nz = 3\n'
    )
    lines = key_lines(text)
    assert lines[("a",)] == 1 and lines[("t",)] == 2
    assert lines[("t", "b", "c")] == lines[("t", "b", "d", "e")] == 3
    assert ("t", "b", "d", "e", "f") not in lines and ("t", "b", "g") not in lines  # inside an array; a comment
    assert lines[("t", "q.r", "s")] == lines[("t", "q.r")] == 4
    assert lines[("arr", 0, "x")] == 6 and lines[("arr", 1)] == 7 and lines[("arr", 1, "x")] == 8
    assert ("arr", 1, "y") not in lines and lines[("arr", 1, "z")] == 11


def test_cli_reports_study_errors(tmp_path):
    path = _write(tmp_path, VALID.replace("confidence = 0.95", "confidence = 2"))
    line = VALID[: VALID.index("confidence")].count("\n") + 1
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert re.search(rf"error: .*study\.toml, line {line}: inversion\.confidence: 2 is out of range", result.output)
    assert not (tmp_path / "out").exists()


def test_help():
    for command in (["run", "--help"], ["demo", "--help"]):
        result = CliRunner().invoke(app, command)
        assert result.exit_code == 0 and "Usage" in result.output


def test_demo_study_is_valid():
    study = load_study(EXAMPLES / "diagonal_compression.toml")
    assert study.spec.scenario == "diagonal_compression" and study.space.names == ("E_b", "kN_bj", "kV_bj", "r_hj")
    assert study.measurement.file == (EXAMPLES / "diagonal_compression_measured.csv").resolve()


def test_demo_data_is_reproducible(tmp_path):
    """examples/make_measured_data.py regenerates the shipped pseudo-measured data (the demo's and
    the joint calibration's shear wall)."""
    module = load_file(EXAMPLES / "make_measured_data.py")
    for scenario, (shipped_path, seed) in module.SHIPPED.items():
        made = module.make(tmp_path / "made.csv", seed, scenario=scenario)
        shipped = shipped_path.read_text().splitlines()
        again = made.read_text().splitlines()
        assert again[0] == shipped[0]
        a = np.array([[float(c) for c in row.split(",")] for row in again[1:]])
        b = np.array([[float(c) for c in row.split(",")] for row in shipped[1:]])
        # 6 significant digits are written; PARDISO and SuperLU differ far below that
        np.testing.assert_allclose(a, b, rtol=2e-6, atol=0, err_msg=scenario)


def test_bench_demo_help():
    script = Path(__file__).resolve().parents[1] / "scripts" / "bench_demo.py"
    proc = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True, check=False)
    assert proc.returncode == 0 and "--fresh-venv" in proc.stdout
