"""``podkrig scenarios`` and ``podkrig --version``: discoverability of the virtual tests."""

import json

from rich.console import Console
from typer.testing import CliRunner

from fe.scenarios import SCENARIOS, build_scenario
from fe.scenarios.catalogue import ScenarioDescription, describe_scenario
from podkrig import __version__
from podkrig.cli import app
from podkrig.cli._common import print_findings
from podkrig.reports.findings import FindingText

runner = CliRunner()


def test_description_matches_the_built_scenario():
    d = describe_scenario("diagonal_compression")
    sc = build_scenario("diagonal_compression")
    assert [p.name for p in d.parameters] == list(sc.parameter_names)
    assert list(d.sensors) == list(sc.sensor_names)
    assert d.load_levels == tuple(sc.load_levels) and d.load_unit == "kN"
    assert d.options["shoe_length"] == 130.0 and "sensors" not in d.options
    assert ScenarioDescription.from_dict(json.loads(json.dumps(d.to_dict()))) == d


def test_cli_lists_every_registered_scenario():
    out = runner.invoke(app, ["scenarios", "--json"])
    assert out.exit_code == 0, out.output
    assert sorted(d["name"] for d in json.loads(out.output)) == sorted(SCENARIOS)


def test_cli_describes_one_scenario_and_keeps_bracketed_words():
    out = runner.invoke(app, ["scenarios", "shear_compression"], env={"COLUMNS": "200"})
    assert out.exit_code == 0, out.output
    for word in ("precompression", "kN_bj", "N/mm³", "top_ux", '{ kind = "gauge"', "[parameters]", "[scenario.sensors]"):
        assert word in out.output


def test_cli_unknown_scenario_is_a_message():
    out = runner.invoke(app, ["scenarios", "flat_jak"])
    assert out.exit_code == 2
    assert "unknown scenario 'flat_jak'" in out.output and "diagonal_compression" in out.output


def test_version():
    out = runner.invoke(app, ["--version"])
    assert out.exit_code == 0 and out.output.strip() == f"podkrig {__version__}"


_TABLE_SPEC = """\
scenario = "diagonal_compression"
nx = 2
ny = 1

[sensors]
D1 = { kind = "gauge", p1 = [302.2, 302.2], p2 = [867.8, 867.8] }
P = { kind = "point", point = [600.0, 600.0], component = "y" }
"""

_ARRAY_SPEC = """\
scenario = "diagonal_compression"
nx = 2
ny = 1

[[sensors]]
name = "D1"
kind = "gauge"
p1 = [302.2, 302.2]
p2 = [867.8, 867.8]

[[sensors]]
name = "P"
kind = "point"
point = [600.0, 600.0]
component = "y"
"""


def test_sensors_as_a_toml_array_of_tables_read_like_the_table(tmp_path):
    (tmp_path / "table.toml").write_text(_TABLE_SPEC)
    (tmp_path / "array.toml").write_text(_ARRAY_SPEC)
    outs = [runner.invoke(app, ["simulate", "diagonal_compression", "--spec", str(tmp_path / f), "--format", "json"])
            for f in ("table.toml", "array.toml")]
    assert all(o.exit_code == 0 for o in outs), [o.output for o in outs]
    table, array = (json.loads(o.output) for o in outs)
    assert list(table["sensors"]) == list(array["sensors"]) == ["D1", "P"]
    assert table["sensors"] == array["sensors"]
    assert table["readings"] == array["readings"]


def test_malformed_sensors_are_refused_with_the_accepted_forms(tmp_path):
    """An array entry without a name (or sensors that are neither a table nor an array of tables):
    one message with both accepted TOML forms, exit code 2, no traceback."""
    for text in (_ARRAY_SPEC.replace('name = "P"\n', ""), 'scenario = "diagonal_compression"\nsensors = [1, 2]\n'):
        (tmp_path / "bad.toml").write_text(text)
        out = runner.invoke(app, ["simulate", "diagonal_compression", "--spec", str(tmp_path / "bad.toml")])
        assert out.exit_code == 2, out.output
        assert "Traceback" not in out.output and out.exception is None or isinstance(out.exception, SystemExit)
        assert "[[sensors]]" in out.output and "[sensors]" in out.output and 'name = "D1"' in out.output


def test_advice_is_printed_literally():
    """Rich markup would eat "[fixed]" from "fix E_b from other tests ([fixed])"."""
    console = Console(record=True, width=200)
    print_findings(console, [FindingText("unidentified", "region", "E_b is not identified [see the region]",
                                         "fix E_b from other tests ([fixed])")])
    text = console.export_text()
    assert "([fixed])" in text and "[see the region]" in text and "warning:" in text
