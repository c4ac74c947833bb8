"""``podkrig snapshots``: run the offline stage into a snapshot store, describe it, export it."""

import csv
import json
import math
from pathlib import Path

import typer

from podkrig.cli._common import (
    SamplingMethod, TextFormat, configure_logging, confirm_large_job, settings_from_options, user_errors,
)
from podkrig.cli._terminal import Progress
from podkrig.config import field_info
from podkrig.exceptions import StoreError
from podkrig.limits import CONFIRM_FE_HOURS, CONFIRM_ROWS, check_chunk_size, check_rows, check_workers, fe_job_estimate
from podkrig.offline.settings import Design

snapshots_app = typer.Typer(
    name="snapshots",
    help="Offline stage: FE snapshots over a Sobol' design in a resumable HDF5 store.",
    no_args_is_help=True,
)


def _scenario_spec(scenario, spec_file):
    from fe.scenarios import ScenarioSpec

    if spec_file is None and scenario is None:
        raise ValueError("give the scenario: --scenario NAME or --spec FILE")
    if spec_file is None:
        return ScenarioSpec(scenario)
    spec = ScenarioSpec.from_file(spec_file)
    if scenario is not None and spec.scenario != scenario:
        raise ValueError(f"--spec {spec_file} is for scenario {spec.scenario!r}, not --scenario {scenario!r}")
    return spec


@snapshots_app.command("run")
def run(
    store: Path = typer.Option(..., "--store", help="Snapshot store (HDF5); created if missing, else resumed."),
    param: list[str] = typer.Option(..., "--param", help="Free parameter NAME=LOW:HIGH[:log] (repeatable)."),
    n: int = typer.Option(..., "--n", help="Number of samples (a power of two for Sobol')."),
    seed: int = typer.Option(..., "--seed", help="Seed of the design (recorded in the store)."),
    scenario: str = typer.Option(None, "--scenario", help="Scenario name, e.g. diagonal_compression."),
    spec: Path = typer.Option(None, "--spec", help="Scenario spec file (TOML or JSON)."),
    sampling: SamplingMethod = typer.Option(SamplingMethod(field_info(Design)["method"]["default"]), "--sampling",
                                            help="Design (lhs-ese: SMT's optimised Latin hypercube)."),
    workers: int = typer.Option(None, "--workers", help="Local worker processes; 1 runs in this process without Dask (default: one per core)."),
    scheduler: str = typer.Option(None, "--scheduler", help="Existing Dask scheduler, e.g. tcp://HOST:8786."),
    fields: bool = typer.Option(False, "--fields", help="Also store full displacement fields."),
    retry_failed: bool = typer.Option(False, "--retry-failed", help="Rerun rows whose FE run failed."),
    chunk_size: int = typer.Option(None, "--chunk-size", help="Rows per task (default: adapted to the work, at most 32)."),
    yes: bool = typer.Option(False, "--yes", "-y", help=f"Start a job of more than {CONFIRM_ROWS} runs or "
                             f"{CONFIRM_FE_HOURS:g} h of estimated FE work without asking (required without "
                             "a terminal)."),
    verbose: bool = typer.Option(False, "--verbose", "-v"),
):
    """Run a scenario at N sampled parameter vectors into a snapshot store.

    Rerunning the same command resumes an interrupted job: finished rows are kept, never rewritten.
    A larger --n on a Sobol' store appends rows that continue the same sequence.
    Any other change of arguments against an existing store is refused.
    """
    configure_logging(verbose)
    from fe.scenarios import build_scenario
    from fe.scenarios.nonlinear import NonlinearScenario

    from podkrig.offline.results import OfflineResult
    from podkrig.offline.runner import measured_run_seconds, rows_to_run, run_snapshots
    from podkrig.parameters import ParameterSpace, parse_params
    from podkrig.reports.offline import failure_lines, rows_text
    from podkrig.offline.store import store_bytes_per_row

    with user_errors():
        if workers is not None and scheduler is not None:
            raise ValueError("give either --workers (a local cluster) or --scheduler (an existing one), not both")
        if workers is not None:
            check_workers(workers, "--workers")  # the runner's own bounds, named by the option
        if chunk_size is not None:
            check_chunk_size(chunk_size, "--chunk-size")
        bounds = parse_params(param)
        sc = build_scenario(_scenario_spec(scenario, spec))
        space = ParameterSpace.from_scenario(sc, bounds)
        size = check_rows(n, store_bytes_per_row(space.n_params, len(sc.load_levels), len(sc.sensor_names),
                                                  sc.mesh.n_nodes, fields))
        design = settings_from_options(Design, {"n": ("--n", n), "seed": ("--seed", seed),
                                                "method": ("--sampling", sampling.value)})
        todo = rows_to_run(store, n, retry_failed)
        job = [(todo, sc.n_dofs, isinstance(sc, NonlinearScenario), measured_run_seconds(store))]
        confirm_large_job(*fe_job_estimate(job, size if todo else 0), yes)
        try:
            with Progress("snapshots", rate="snapshots/s") as progress:
                summary = run_snapshots(
                    store, sc, space, **design.run_arguments(), fields=fields, workers=workers, scheduler=scheduler,
                    retry_failed=retry_failed, chunk_size=chunk_size,
                    progress=lambda completed, total: progress.update("snapshots", completed, total),
                )
        except KeyboardInterrupt:
            typer.echo(f"interrupted: finished rows are kept in {store}; rerun the same command to resume", err=True)
            raise typer.Exit(code=130) from None
        result = OfflineResult.from_store(store, summary)
    rate = summary.snapshots_per_second
    typer.echo(
        f"{summary.action} {store}: {rows_text(result)}; ran {summary.ran} in {summary.seconds:.1f} s "
        f"({rate if math.isfinite(rate) else 0:.1f} snapshots/s, {result.executor})"
    )
    if result.failed:
        for line in failure_lines(result.failure):
            typer.echo(line, err=True)
        typer.echo(
            f"{result.failed} rows failed: see 'podkrig snapshots info {store}'; rerun with --retry-failed "
            "to run them again", err=True,
        )


@snapshots_app.command("info")
def info(
    path: Path = typer.Argument(..., help="Snapshot store."),
    format: TextFormat = typer.Option(TextFormat.text, "--format", help="Output format: text or json."),
):
    """Describe a snapshot store: provenance, scenario, parameters, sensors, row status, failed runs."""
    from podkrig.offline.failures import failure_report
    from podkrig.offline.store import SnapshotStore
    from podkrig.reports.offline import failure_lines

    with user_errors():
        if format not in ("text", "json"):
            raise ValueError(f"--format must be text or json; got {format!r}")
        with SnapshotStore.open(path) as store:
            d = store.info()
            failure = failure_report(store) if d["rows"]["failed"] else None
        d["failure"] = None if failure is None else failure.to_dict()
    if format == "json":
        typer.echo(json.dumps(d, indent=2, ensure_ascii=False))
        return
    rows = d["rows"]
    sw = d["software"]
    spec = dict(d["scenario_spec"])
    lines = [
        f"snapshot store {d['path']} ({d['file_size_bytes'] / 1e6:.2f} MB, schema {d['schema_version']})",
        (f"created      {d['created']} with podkrig {sw['podkrig']} (scipy {sw['scipy']}, "
         f"numpy {sw['numpy']}, h5py {sw['h5py']}, HDF5 {sw['hdf5']}, Python {sw['python']})"),
        f"rows         {rows['total']}: {rows['done']} done, {rows['failed']} failed, {rows['pending']} pending",
        f"design       {d['sampling']['method']}, seed {d['sampling']['seed']}",
        f"scenario     {spec.pop('scenario')} ({d['n_dofs']} dofs, {d['n_nodes']} nodes)",
        f"  fixed      {json.dumps(spec.pop('parameters'), ensure_ascii=False) or '{}'}",
        f"  options    {json.dumps(spec, ensure_ascii=False)}",
        "parameters",
    ]
    for p in d["parameter_space"]["parameters"]:
        lines.append(f"  {p['name']:<10} {p['lower']:g} .. {p['upper']:g} {p['unit']}  ({p['scale']})")
    lines.append(f"load levels  {', '.join(f'{v:g}' for v in d['load_levels'])} {d['load_unit']}")
    lines.append(f"sensors      readings in {d['reading_unit']}")
    for name in d["sensor_names"]:
        lines.append(f"  {name:<10} {json.dumps(d['sensor_definitions'][name], ensure_ascii=False)}")
    lines.append(f"fields       {'yes (n_loads, n_nodes, 2) mm' if d['fields'] else 'no'}")
    wall = d["wall_time_s"]
    if wall["mean"] is not None:
        cpu = d["cpu_time_s"]["mean"]
        lines.append(f"FE time      {wall['total']:.1f} s in total, {1000 * wall['mean']:.1f} ms per run"
                     + (f" ({1000 * cpu:.1f} ms CPU)" if cpu is not None else ""))
    lines.append(f"run args     {json.dumps(d['run_arguments'])}")
    for event in d["history"]:
        source = f", {event['source']}" if "source" in event else ""
        lines.append(f"history      {event['time']} {event['event']} ({event['rows']} rows{source})")
    lines.append(f"content      {d['content_hash']}")
    if d["solver_settings"]:
        lines.append(f"solver       {json.dumps(d['solver_settings'])}")
    for line in failure_lines(failure) if failure is not None else ():
        lines.append(f"failures     {line}")
    for row in d["failures"]:
        lines.append(f"failed row {row['row']}: {row['error']}")
    typer.echo("\n".join(lines))


@snapshots_app.command("verify")
def verify(
    path: Path = typer.Argument(..., help="Snapshot store."),
    rehash: bool = typer.Option(False, "--rehash", help="Add checksums to a store written by an older podkrig "
                                                      "(its current content is taken as correct)."),
    format: str = typer.Option("text", "--format", help="Output format: text or json."),
):
    """Check every row of a store against its checksums; exit code 1 names the damaged rows."""
    from podkrig.offline.store import SnapshotStore

    with user_errors():
        if format not in ("text", "json"):
            raise ValueError(f"--format must be text or json; got {format!r}")
        if rehash:
            with SnapshotStore.open(path, "r+") as store:
                store.rehash()
            typer.echo(f"added checksums to {path} ({store.n_rows} rows)")
            return
        try:
            with SnapshotStore.open(path) as store:
                report = store.verify()
        except StoreError as e:  # damaged metadata or a row read at opening
            if format == "json":
                typer.echo(json.dumps({"path": str(path), "ok": False, "error": str(e)}, indent=2))
            else:
                typer.echo(f"error: {e}", err=True)
            raise typer.Exit(code=1) from None
    if format == "json":
        typer.echo(json.dumps(report.to_dict(), indent=2))
    elif not report.checksummed:
        typer.echo(f"{path}: no checksums: written by an older podkrig, damage cannot be detected; "
                   f"run 'podkrig snapshots verify --rehash {path}' on a store you trust", err=True)
    elif report.ok:
        extra = (f"; rows {report.unsealed_rows} were being written when a job stopped and are resealed "
                 "by the next run") if report.unsealed_rows else ""
        typer.echo(f"{path}: {report.rows} rows match their checksums{extra}")
    else:
        if not report.metadata_ok:
            typer.echo(f"{path}: the datasets' attributes (units, names) do not match their checksum", err=True)
        for name, rows in report.bad_rows.items():
            shown = ", ".join(map(str, rows[:50])) + (f" and {len(rows) - 50} more" if len(rows) > 50 else "")
            typer.echo(f"{path}: dataset {name!r}: rows {shown} do not match their checksums", err=True)
        typer.echo("the store was damaged after it was written: rebuild the damaged rows' store or restore a copy",
                   err=True)
    if not report.ok:
        raise typer.Exit(code=1)


@snapshots_app.command("export")
def export(
    path: Path = typer.Argument(..., help="Snapshot store."),
    csv_path: Path = typer.Option(..., "--csv", help="CSV file to write."),
):
    """Export a store as CSV: row, status, one column per parameter, one per SENSOR@LOAD (mm)."""
    from podkrig.offline.store import STATUS_NAMES, SnapshotStore

    with user_errors():
        with SnapshotStore.open(path) as store:
            X = store.parameters(physical=True, only_done=False)
            Y = store.readings(only_done=False)
            status = store.status()
            header = ["row", "status", *store.space.names]
            header += [f"{s}@{level:g}" for level in store.load_levels for s in store.sensor_names]
        try:
            with open(csv_path, "w", newline="") as fh:
                writer = csv.writer(fh)
                writer.writerow(header)
                for i in range(len(X)):
                    values = Y[i].ravel()  # C order: load-major, as the header
                    writer.writerow([i, STATUS_NAMES[int(status[i])], *map(repr, X[i].tolist()),
                                     *("" if math.isnan(v) else repr(v) for v in values.tolist())])
        except OSError as e:
            raise ValueError(f"cannot write {csv_path}: {e.strerror}") from e
    typer.echo(f"wrote {csv_path}: {len(X)} rows x {len(header)} columns (parameters in their units, readings in mm)")


def register(app):
    """Add the ``snapshots`` sub-app to the ``podkrig`` app."""
    app.add_typer(snapshots_app, name="snapshots")
