"""``podkrig scenarios [NAME]``: the virtual tests, their parameters, options and sensors."""

import json

import typer
from rich.markup import escape
from rich.table import Table

from fe.scenarios import SCENARIOS
from fe.scenarios.catalogue import SENSOR_KINDS, describe_scenario, typical_range
from podkrig.cli._common import user_errors
from podkrig.cli._terminal import console as command_console


def _fmt(v):
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, tuple):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


def _print_one(console, d):
    console.print(f"[bold]{d.name}[/bold] — {escape(d.summary)}")
    console.print(f"default mesh: {d.n_dofs} dofs; load levels {_fmt(d.load_levels)} {d.load_unit}")
    t = Table(title=escape("parameters ([parameters] / [fixed] of a study, --set of simulate)"), title_justify="left")
    for col in ("name", "default", "unit", "typical", "admissible", "meaning"):
        t.add_column(col, justify="right" if col == "default" else "left")
    for p in d.parameters:
        t.add_row(p.name, f"{p.default:g}", p.unit, escape(typical_range(p.name, p.unit)), escape(p.admissible_range()),
                  escape(p.description))
    console.print(t)
    if d.constraints:
        t = Table(title="constraints between parameters (checked over the whole sampling box before any FE run)",
                  title_justify="left")
        for col in ("constraint", "unit", "interfaces", "why"):
            t.add_column(col)
        for c in d.constraints:
            t.add_row(escape(c["formula"]), escape(c["unit"]), escape(c["where"]), escape(c["reason"]))
        console.print(t)
    else:
        console.print("constraints between parameters: none (each parameter only within its admissible range)")
    t = Table(title=escape("options (keys of the [scenario] table or a spec file, --option of simulate; "
                           "lengths mm)"), title_justify="left")
    t.add_column("option")
    t.add_column("default", justify="right")
    for k, v in d.options.items():
        t.add_row(k, escape(_fmt(v)))
    console.print(t)
    t = Table(title=escape("default sensors (replace them with a [scenario.sensors] table or [[scenario.sensors]] "
                           "entries; docs/scenarios.md)"), title_justify="left")
    t.add_column("name")
    t.add_column("definition (mm)")
    for k, v in d.sensors.items():
        t.add_row(escape(k), escape(json.dumps(v)))
    console.print(t)
    console.print(escape("typical: a starting range for a study's [parameters] bounds (clay-brick masonry, "
                         "literature); admissible: what the model accepts."))
    t = Table(title=escape("sensor kinds"), title_justify="left")
    t.add_column("kind")
    t.add_column("reads")
    t.add_column("TOML form")
    for k, (reads, form) in SENSOR_KINDS.items():
        t.add_row(k, escape(reads), escape(form))
    console.print(t)


def register(app):
    @app.command("scenarios")
    def scenarios(
        name: str = typer.Argument(None, help="A scenario to describe in full; omit to list them all."),
        json_output: bool = typer.Option(False, "--json", help="Print JSON instead of tables."),
    ):
        """List the virtual tests, or describe one: parameters with units, defaults and admissible
        ranges, the constraints between parameters, options, default sensors and load levels, and
        the sensor kinds with their TOML forms."""
        with user_errors():
            names = [name] if name else sorted(SCENARIOS)
            descriptions = [describe_scenario(n) for n in names]
        if json_output:
            typer.echo(json.dumps([d.to_dict() for d in descriptions] if not name else descriptions[0].to_dict(),
                                  indent=2))
            return
        console = command_console(highlight=False)
        if name:
            _print_one(console, descriptions[0])
            return
        t = Table(title=escape("scenarios (podkrig scenarios NAME for details)"), title_justify="left")
        t.add_column("name", no_wrap=True)
        for col in ("test", "load unit", "parameters", "default sensors"):
            t.add_column(col)
        for d in descriptions:
            names = [p.name for p in d.parameters]
            t.add_row(d.name, escape(d.summary), d.load_unit,
                      ", ".join(names[:5]) + (f" … ({len(names)} in all)" if len(names) > 5 else ""),
                      escape(", ".join(list(d.sensors)[:8]) + (" …" if len(d.sensors) > 8 else "")))
        console.print(t)
