"""``podkrig simulate``: run one FE virtual test and print its readings."""

import dataclasses
import json
import time
import tomllib
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


def parse_option(text):
    """``"NAME=VALUE"`` → ``(name, value)`` for a scenario option: the value as a TOML value
    (``0.5``, ``3``, ``true``, ``"constant_force"``, ``[10, 20]``), or else the text itself (so
    ``top=constant_force`` needs no quotes)."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip() or not value.strip():
        raise ValueError(f"--option {text!r}: expected NAME=VALUE, e.g. --option precompression=0.5")
    try:
        return name.strip(), tomllib.loads(f"v = {value}")["v"]
    except tomllib.TOMLDecodeError:
        return name.strip(), value.strip()


def load_spec(scenario, spec_file, options=()):
    """The spec of ``scenario``, optionally read from a TOML/JSON file, with the scenario
    ``options`` (``NAME=VALUE`` texts, :func:`parse_option`) set on top."""
    from fe.scenarios import ScenarioSpec

    spec = ScenarioSpec(scenario) if spec_file is None else ScenarioSpec.from_file(spec_file)
    if spec.scenario != scenario:
        raise ValueError(f"{spec_file}: spec is for scenario {spec.scenario!r}, not {scenario!r}")
    given = dict(parse_option(t) for t in options)
    return ScenarioSpec(scenario, {**spec.options, **given}, spec.parameters) if given else spec


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
        option: list[str] = typer.Option([], "--option", help="Scenario option NAME=VALUE (repeatable), e.g. "
                                         "precompression=0.5 or top=constant_force; on top of --spec."),
        format: ResponseFormat = typer.Option(ResponseFormat.table, "--format", help="Output format: table, json or csv."),
        field: Path = typer.Option(None, "--field", help="Also write the displacement field to this CSV file."),
        solver: LinearSolver = typer.Option(LinearSolver.auto, "--solver", help="Linear solver: auto, pardiso or superlu."),
        report: Path = typer.Option(None, "--report", help="Also write figures and an HTML page to this folder (load-displacement curve and deformed mesh for nonlinear scenarios)."),
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
            sc = build_scenario(load_spec(scenario, spec, option), solver=solver.value)
            misplaced = sorted(set(params) & {f.name for f in dataclasses.fields(sc.options)})
            if misplaced:
                name = misplaced[0]
                raise ValueError(f"--set {name}: {name!r} is an option of {scenario}, not a parameter; use "
                                 f"--option {name}={params[name]:g}")
            nonlinear = hasattr(sc, "force_unit")
            values = sc.resolve(params)  # each value and the constraints between them, before the FE run
            response = sc.run(params, field=field is not None or report is not None)
            seconds = time.perf_counter() - t0
            if field is not None:
                write_field(field, sc, response)
            if report is not None:
                # local imports: matplotlib and the report modules, 0.5–2 s (python -X importtime)
                if nonlinear:
                    from podkrig.reports.nonlinear import write_nonlinear_report

                    page = write_nonlinear_report(sc, response, values, report)
                else:
                    from podkrig.reports.flat_jack import write_simulation_report

                    page = write_simulation_report(sc, response, values, report, seconds=seconds)
        _print(sc, response, values, seconds, format)
        if report is not None and format == "table":
            typer.echo(f"report: {page}")
        if nonlinear and not response.converged:  # the readings past the reach are NaN: not a result
            typer.echo(f"error: {scenario} stopped early ({response.status}"
                       + (f", {response.limit} limit" if response.limit else "") + f"): {response.message}; the "
                       "levels it did not reach read NaN", err=True)
            raise typer.Exit(1)

    return simulate


def _print(sc, response, values, seconds, format):
    if format == "json":
        # a nonlinear run's dict also has its loads, peak, status, how far it got and its solver
        out = {"scenario": sc.name, "parameters": values, "sensors": sc.sensor_definitions(), **response.to_dict(),
               "n_dofs": int(sc.n_dofs), "seconds": seconds}
        if hasattr(response, "summary"):
            out["options"] = sc.spec.to_dict()
        typer.echo(json.dumps(out, indent=2))
        return
    if format == "csv":
        from podkrig.io.measurement_log import response_csv

        typer.echo(response_csv(sc, response), nl=False)
        return
    from rich.table import Table

    from podkrig.cli._terminal import console as command_console

    nonlinear = hasattr(response, "summary")
    console = command_console()
    if nonlinear and not response.converged:  # the first line says the run is not a result
        from podkrig.reports.nonlinear import stop_line

        console.print(stop_line(response), markup=False, highlight=False)
    table = Table(title=f"{sc.name}: readings in mm ({sc.n_dofs} dofs, {seconds:.3f} s)")
    table.add_column("sensor")
    for level in response.load_levels:
        table.add_column(f"{level:g} {response.load_unit}", justify="right")
    units = sc.sensor_units
    if nonlinear and getattr(sc, "force_sensor", None) is None:  # a load that is no reading (the steps)
        table.add_row(f"load ({response.force_unit})", *[f"{v:.4g}" for v in response.loads])
    for j, name in enumerate(response.sensor_names):
        if units.get(name, "mm") == "mm":
            table.add_row(name, *[f"{v:+.5f}" for v in response.readings[:, j]])
        else:  # the load reading: a force, kN
            table.add_row(f"{name} ({units[name]})", *[f"{v:.4g}" for v in response.readings[:, j]])
    console.print(table)
    if nonlinear and response.load_unit == "step":  # a sequence of load steps (flat_jack_elastic_nl): no curve
        console.print(f"status {response.status}; reached step {response.reached:g}"
                      + (f" ({response.message})" if response.message else ""))
    elif nonlinear:
        console.print(f"peak load {response.peak_load:.4g} {response.force_unit} at {response.peak_displacement:.4g} mm; "
                      f"status {response.status}; reached {response.reached:.4g} {response.load_unit}"
                      + (f" ({response.message})" if response.message else ""))
        if not response.mesh_objective:
            console.print(f"not mesh-objective past {response.mesh_objective_limit:g} {response.load_unit}: the "
                          "readings and a peak beyond it depend on the mesh (the scenario's mesh-convergence study)")
        _print_curve(console, sc, response)
    changed = {k: v for k, v in values.items() if v != sc.parameters[k].default}
    console.print(
        "parameters: "
        + ", ".join(f"{k}={v:g} {sc.parameters[k].unit}".rstrip(" -") for k, v in values.items())
        + (f"  (changed: {', '.join(changed)})" if changed else "")
    )


def _print_curve(console, sc, response):
    """The load–displacement curve as text: one line per converged step (at most 40 lines)."""
    res = response.path
    if not len(res.phase):
        return
    mask = res.of_phase(res.phase[-1])
    disp, load = sc.control_sign * res.path[mask], res.load[mask]
    pick = np.unique(np.linspace(0, len(disp) - 1, min(40, len(disp))).round().astype(int))
    top = max(float(np.nanmax(np.abs(load))), 1e-12)
    for i in pick:
        bar = "#" * int(round(40 * max(load[i], 0.0) / top))
        console.print(f"{disp[i]:9.4f} mm {load[i]:10.4g} {response.force_unit} {bar}", highlight=False)
