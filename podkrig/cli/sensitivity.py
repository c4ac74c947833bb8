"""``podkrig sensitivity``: which parameters can the test inform? Sobol' indices on the surrogate."""

import json
from pathlib import Path

import typer

from podkrig.cli._common import TableFormat, configure_logging, settings_from_options, user_errors
from podkrig.cli.invert import RANGE_CHECK
from podkrig.cli.simulate import parse_assignment
from podkrig.online.settings import SENSITIVITY, SensitivitySettings


def register(app):
    @app.command()
    def sensitivity(
        surrogate: Path = typer.Argument(..., help="Surrogate file (podkrig surrogate build)."),
        free: list[str] = typer.Option([], "--free", help="Free parameters (comma-separated or repeated); default all."),
        fix: list[str] = typer.Option([], "--fix", help="Fixed parameter NAME=VALUE (repeatable)."),
        data: Path = typer.Option(None, "--data", help="Measurement CSV: also the indices of the misfit ω (needs a noise model)."),
        noise_abs: list[str] = typer.Option([], "--noise-abs", help="σ in mm, or NAME=SIGMA per sensor (with --data)."),
        noise_rel: float = typer.Option(None, "--noise-rel", help="Relative noise δ (with --data)."),
        n: int = typer.Option(SENSITIVITY.n, "--n", help="Base samples (a power of two in [256, 65536]); "
                              "n (d + 2) surrogate evaluations."),
        seed: int = typer.Option(SENSITIVITY.seed, "--seed", help="Seed of the Sobol' matrices and the bootstrap."),
        confidence: float = typer.Option(SENSITIVITY.confidence, "--confidence",
                                         help="Level of the bootstrap intervals."),
        out: Path = typer.Option(Path("out/sensitivity"), "--out", help="Output folder (sensitivity.json, sensitivity.png)."),
        format: TableFormat = typer.Option(TableFormat.table, "--format", help="table or json."),
        range_check: bool = RANGE_CHECK,
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """First-order and total Sobol' indices of every reading (and of the misfit with --data) over the
        box of the free parameters, on the surrogate, and the parameters to fix because no reading is
        sensitive to them (total index < 0.01 everywhere)."""
        configure_logging(verbose)
        # imported here: see podkrig.cli (the surrogate and online stacks and matplotlib take seconds)
        from rich.markup import escape
        from rich.table import Table

        from podkrig.cli._terminal import console as command_console
        from podkrig.cli.invert import build_problem
        from podkrig.online.problem import SurrogateModel
        from podkrig.online.sensitivity import NEGLIGIBLE_TOTAL_INDEX, misfit_sensitivity, reading_sensitivity
        from podkrig.reports.sensitivity import index_notes, plot_sensitivity
        from podkrig.io.surrogate_file import load_surrogate

        with user_errors():
            free_names = tuple(x.strip() for item in free for x in item.split(",") if x.strip()) or None
            fixed = dict(parse_assignment(t, "--fix") for t in fix)
            model = SurrogateModel(load_surrogate(surrogate))
            options = settings_from_options(SensitivitySettings, {"n": ("--n", n), "seed": ("--seed", seed),
                                                                  "confidence": ("--confidence", confidence)}).options()
            readings = reading_sensitivity(model, free=free_names, fixed=fixed, **options)
            misfit = None
            if data is not None:
                problem, _, _ = build_problem(surrogate, data, noise_abs, noise_rel, None, list(free), list(fix),
                                              range_check=range_check)
                misfit = misfit_sensitivity(problem, **options)
            elif noise_abs or noise_rel is not None:
                raise ValueError("a noise model needs --data (the misfit's indices); without it only the readings' are computed")
            out.mkdir(parents=True, exist_ok=True)
            fixable = set(readings.negligible()) & set(misfit.negligible() if misfit else readings.parameters)
            result = {"readings": readings.to_dict(), "misfit": None if misfit is None else misfit.to_dict(),
                      "propose_fixing": sorted(fixable)}
            (out / "sensitivity.json").write_text(json.dumps(result, indent=2))
            plot_sensitivity(readings, out / "sensitivity.png", misfit=misfit)

        if format == TableFormat.json:
            typer.echo(json.dumps(result, indent=2))
            return
        console = command_console()
        table = Table(title=f"Sobol' indices over the box ({readings.n_evaluations} surrogate evaluations, "
                            f"{readings.seconds:.1f} s; largest over {len(readings.outputs)} readings)")
        T = readings.total
        rows = []
        for j, name in enumerate(readings.parameters):
            k = max(range(len(readings.outputs)), key=lambda i: -1.0 if readings.variance[i] <= 0 else T[i, j])
            row = [name, f"{T[k, j]:.3f} [{readings.total_low[k, j]:.3f}, {readings.total_high[k, j]:.3f}]",
                   f"{readings.first[k, j]:.3f}", readings.outputs[k]]
            shown = [(T[k, j], readings.total_low[k, j], readings.total_high[k, j]),
                     (readings.first[k, j], readings.first_low[k, j], readings.first_high[k, j])]
            if misfit:
                row.append(f"{misfit.total[0, j]:.3f} [{misfit.total_low[0, j]:.3f}, {misfit.total_high[0, j]:.3f}]")
                shown.append((misfit.total[0, j], misfit.total_low[0, j], misfit.total_high[0, j]))
            rows.append(row + [index_notes(*shown)])
        columns = ["parameter", "total (max)", "first order (same reading)", "reading"] + (["misfit total"] if misfit else [])
        if any(row[-1] for row in rows):  # a note column only when an index is negative
            columns.append("note")
        for col in columns:
            table.add_column(col, justify="left" if col in ("reading", "note") else "right")
        for row in rows:
            table.add_row(*(escape(cell) for cell in row[:len(columns)]))
        console.print(table)
        fixing = result["propose_fixing"]
        if fixing:
            console.print(f"propose fixing {', '.join(fixing)}: total index < {NEGLIGIBLE_TOTAL_INDEX:g} for every reading"
                          + (" and for the misfit" if misfit else "") + " (the test cannot inform it)", markup=False)
        else:
            console.print(f"every parameter explains at least {NEGLIGIBLE_TOTAL_INDEX:g} of some reading's variance", markup=False)
        console.print(f"wrote {out}/sensitivity.json and sensitivity.png", markup=False)

    return sensitivity
