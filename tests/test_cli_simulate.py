"""``podkrig simulate`` through typer's CliRunner."""

import json
import re
import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

from podkrig.cli import app

runner = CliRunner()
DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_help():
    result = runner.invoke(app, ["simulate", "--help"])
    assert result.exit_code == 0 and "--set" in result.output


def test_json_output_keys(tmp_path):
    spec = tmp_path / "coarse.toml"
    spec.write_text('scenario = "diagonal_compression"\nnx = 2\nny = 1\n')
    field = tmp_path / "field.csv"
    result = runner.invoke(
        app, ["simulate", "diagonal_compression", "--spec", str(spec), "--set", "kN_bj=80", "--format", "json", "--field", str(field)]
    )
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert set(out) >= {"scenario", "parameters", "load_levels", "sensors", "readings", "n_dofs", "seconds"}
    assert out["parameters"]["kN_bj"] == 80.0 and out["parameters"]["E_b"] == 12000.0
    assert out["load_levels"] == [25.0, 50.0, 75.0, 100.0]
    assert out["sensors"]["D1"] == {"kind": "gauge", "p1": [302.157, 302.157], "p2": [867.843, 867.843]}
    assert len(out["readings"]["D1"]) == 4 and out["readings"]["D1"][-1] < 0
    header = field.read_text().splitlines()[0]
    assert header.startswith("node,x_mm,y_mm,ux_mm@25kN")


def test_scenario_options_on_the_command_line(tmp_path):
    """--option sets a scenario option (a TOML value, or plain text) on top of --spec: the same run
    as a spec file that says so; an option given to --set is refused naming --option."""
    spec = tmp_path / "coarse.toml"
    spec.write_text('scenario = "diagonal_compression"\nnx = 2\nny = 1\n')
    by_file = json.loads(runner.invoke(app, ["simulate", "diagonal_compression", "--spec", str(spec),
                                             "--format", "json"]).output)
    by_option = json.loads(runner.invoke(app, ["simulate", "diagonal_compression", "--option", "nx=2",
                                               "--option", "ny=1", "--format", "json"]).output)
    assert by_option["n_dofs"] == by_file["n_dofs"] and by_option["readings"] == by_file["readings"]
    finer = json.loads(runner.invoke(app, ["simulate", "diagonal_compression", "--spec", str(spec),
                                           "--option", "nx=4", "--format", "json"]).output)
    assert finer["n_dofs"] > by_file["n_dofs"]
    misplaced = runner.invoke(app, ["simulate", "diagonal_compression", "--set", "nx=3"])
    assert misplaced.exit_code == 2 and "--option nx=3" in misplaced.output
    unknown = runner.invoke(app, ["simulate", "diagonal_compression", "--option", "nz=3"])
    assert unknown.exit_code == 2 and "nz" in unknown.output and "nx" in unknown.output


def test_a_nonlinear_run_that_stops_early_fails(tmp_path):
    """A run ended by its budget prints what it reached and exits 1 (its missing levels are NaN,
    not a result), its partial result still written (the report, whose first line says it
    stopped); the same run with the default budget exits 0."""
    stopped = runner.invoke(app, ["simulate", "couplet_tension", "--option", "max_total_iterations=3",
                                  "--format", "json", "--report", str(tmp_path / "r")])
    assert stopped.exit_code == 1 and "iterations limit" in stopped.output
    assert json.loads(stopped.stdout)["status"] == "budget_exhausted"
    page = (tmp_path / "r" / "index.html").read_text(encoding="utf-8")
    assert re.search(r"</h1>\s*<div class=\"warn\">.*?budget_exhausted.*?</div>", page)
    assert runner.invoke(app, ["simulate", "couplet_tension", "--format", "json"]).exit_code == 0


def test_csv_and_table_output(tmp_path):
    spec = tmp_path / "coarse.toml"
    spec.write_text('scenario = "shear_compression"\nnx = 2\nny = 1\n')
    result = runner.invoke(app, ["simulate", "shear_compression", "--spec", str(spec), "--format", "csv"])
    assert result.exit_code == 0, result.output
    lines = result.stdout.strip().splitlines()
    assert lines[0].startswith("load [kN],top_ux [mm]") and len(lines) == 5
    result = runner.invoke(app, ["simulate", "shear_compression", "--spec", str(spec)])
    assert result.exit_code == 0 and "readings in mm" in result.output


@pytest.mark.parametrize(
    "args, message",
    [
        (["simulate", "diagonal_compression", "--set", "kN_bj"], "expected NAME=VALUE"),
        (["simulate", "diagonal_compression", "--set", "kN_bj=soft"], "is not a number"),
        (["simulate", "diagonal_compression", "--set", "kN_bj=-1"], "outside its physical range"),
        (["simulate", "dome"], "unknown scenario 'dome'"),
        (["simulate", "diagonal_compression", "--spec", "missing.toml"], "cannot read scenario spec missing.toml"),
    ],
)
def test_errors_are_one_line_with_exit_code_2(args, message):
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    assert message in result.output


def test_csv_output_is_a_valid_measurement_file(tmp_path):
    """``simulate --format csv`` writes the measurement layout, so it can serve as pseudo-data."""
    from fe.scenarios import build_scenario
    from podkrig.io.measurement_log import read_measurement_csv

    spec = tmp_path / "coarse.toml"
    spec.write_text('scenario = "diagonal_compression"\nnx = 2\nny = 1\n')
    result = runner.invoke(app, ["simulate", "diagonal_compression", "--spec", str(spec), "--format", "csv"])
    path = tmp_path / "measured.csv"
    path.write_text(result.output)
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    m = read_measurement_csv(path, sc.sensor_names, sc.load_levels)
    assert m.sensor_names == sc.sensor_names
    # 8 significant digits in the CSV
    import numpy as np

    np.testing.assert_allclose(m.values, sc.run().readings, rtol=1e-7, atol=0)


def test_flat_jack_report(tmp_path):
    spec = tmp_path / "single.toml"
    spec.write_text('scenario = "flat_jack"\npreset = "single"\nlayout = "standard"\n')
    out = tmp_path / "report"
    result = runner.invoke(app, ["simulate", "flat_jack", "--spec", str(spec), "--report", str(out), "--format", "csv"])
    assert result.exit_code == 0, result.output
    rows = result.stdout.strip().splitlines()
    assert rows[0] == "load,S1 [mm],S2 [mm],S3 [mm]" and len(rows) == 1 + 13  # the cut, then 12 pressure steps
    assert float(rows[1].split(",")[1]) < 0  # the cut closes the gauges
    names = {p.name for p in out.iterdir()}
    assert {"index.html", "setup.png", "readings.png", "deformed_step1.png", "deformed_step13.png"} <= names
    assert "loading steps" in (out / "index.html").read_text()


def _doc_commands(path):
    """The ``podkrig ...`` lines of the bash blocks of a markdown page, as argument lists (comments
    dropped)."""
    commands, in_bash = [], False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            in_bash = line.strip() == "```bash"
            continue
        if in_bash and line.startswith("podkrig "):
            commands.append(shlex.split(line, comments=True)[1:])
    return commands


@pytest.mark.slow
def test_the_nonlinear_page_examples_run_as_written(tmp_path, monkeypatch):
    """Every ``podkrig`` command of docs/nonlinear.md runs and ends with exit code 0 (output folders
    inside a scratch folder)."""
    commands = _doc_commands(DOCS / "nonlinear.md")
    assert len(commands) >= 3
    monkeypatch.chdir(tmp_path)
    for args in commands:
        result = runner.invoke(app, args)
        assert result.exit_code == 0, (args, result.output[-2000:])
