"""``podkrig scenarios`` and ``podkrig --version``: discoverability of the virtual tests."""

import json

from typer.testing import CliRunner

from fe.scenarios import SCENARIOS, build_scenario
from fe.scenarios.catalogue import ScenarioDescription, describe_scenario
from podkrig import __version__
from podkrig.cli import app

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
