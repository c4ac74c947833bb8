"""``podkrig simulate``: run one FE virtual test and print its readings."""

import json
import time
from pathlib import Path

import numpy as np
import typer

from podkrig.cli._common import LinearSolver, ResponseFormat, configure_logging, user_errors


def parse_assignment(text, option="--set"):
    """``"NAME=VALUE"`` → ``(name, float)``; a clear error otherwise."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise ValueError(f"{option} {text!r}: expected NAME=VALUE, e.g. {option} kN_bj=80")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise ValueError(f"{option} {text!r}: value {value!r} is not a number") from None


def load_spec(scenario, spec_file):
    """The spec of ``scenario``, optionally read from a TOML/JSON file."""
    from fe.scenarios import ScenarioSpec

    if spec_file is None:
        return ScenarioSpec(scenario)
    spec = ScenarioSpec.from_file(spec_file)
    if spec.scenario != scenario:
        raise ValueError(f"{spec_file}: spec is for scenario {spec.scenario!r}, not {scenario!r}")
    return spec


def write_field(path, scenario, response):
    """Nodal displacement field as CSV: node, x, y, then ux@LOAD, uy@LOAD per load level (mm)."""
    nodes = scenario.mesh.nodes
    cols = [np.arange(len(nodes)), nodes[:, 0], nodes[:, 1]]
    header = ["node", "x_mm", "y_mm"]
    for k, level in enumerate(response.load_levels):
        cols += [response.field[k, :, 0], response.field[k, :, 1]]
        header += [f"ux_mm@{level:g}{response.load_unit}", f"uy_mm@{level:g}{response.load_unit}"]
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=",".join(header), comments="", fmt="%.10g")


def register(app):
    @app.command()
    def simulate(
        scenario: str = typer.Argument(..., help="Scenario name, e.g. diagonal_compression."),
        spec: Path = typer.Option(None, "--spec", help="Scenario spec file (TOML or JSON)."),
        set_: list[str] = typer.Option([], "--set", help="Parameter value NAME=VALUE (repeatable)."),
        format: ResponseFormat = typer.Option(ResponseFormat.table, "--format", help="Output format: table, json or csv."),
        field: Path = typer.Option(None, "--field", help="Also write the displacement field to this CSV file."),
        solver: LinearSolver = typer.Option(LinearSolver.auto, "--solver", help="Linear solver: auto, pardiso or superlu."),
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """Run one virtual test of SCENARIO and print the sensor readings (mm) per load level."""
        configure_logging(verbose)
        with user_errors():
            from fe.scenarios import SCENARIOS, build_scenario

            if format not in ("table", "json", "csv"):
                raise ValueError(f"--format must be table, json or csv; got {format!r}")
            if scenario not in SCENARIOS:
                raise ValueError(f"unknown scenario {scenario!r}; available: {sorted(SCENARIOS)}")
            params = dict(parse_assignment(s) for s in set_)
            t0 = time.perf_counter()
            sc = build_scenario(load_spec(scenario, spec), solver=solver.value)
            response = sc.run(params, field=field is not None)
            seconds = time.perf_counter() - t0
            values = sc.resolve(params)
            if field is not None:
                write_field(field, sc, response)
        _print(sc, response, values, seconds, format)

    return simulate


def _print(sc, response, values, seconds, format):
    if format == "json":
        out = {
            "scenario": sc.name,
            "parameters": values,
            "load_levels": response.load_levels.tolist(),
            "load_unit": response.load_unit,
            "sensors": sc.sensor_definitions(),
            "readings": response.as_dict(),
            "n_dofs": int(sc.n_dofs),
            "seconds": seconds,
        }
        typer.echo(json.dumps(out, indent=2))
        return
    if format == "csv":
        # the measurement-file layout (first column "load" in the scenario load unit, readings in mm),
        # so that a simulated response can serve as pseudo-measured data
        typer.echo(",".join(["load"] + list(response.sensor_names)))
        for level, row in zip(response.load_levels, response.readings):
            typer.echo(",".join([f"{level:g}"] + [f"{v:.8g}" for v in row]))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"{sc.name}: readings in mm ({sc.n_dofs} dofs, {seconds:.3f} s)")
    table.add_column("sensor")
    for level in response.load_levels:
        table.add_column(f"{level:g} {response.load_unit}", justify="right")
    for j, name in enumerate(response.sensor_names):
        table.add_row(name, *[f"{v:+.5f}" for v in response.readings[:, j]])
    console = Console()
    console.print(table)
    changed = {k: v for k, v in values.items() if v != sc.parameters[k].default}
    console.print(
        "parameters: "
        + ", ".join(f"{k}={v:g} {sc.parameters[k].unit}".rstrip(" -") for k, v in values.items())
        + (f"  (changed: {', '.join(changed)})" if changed else "")
    )
