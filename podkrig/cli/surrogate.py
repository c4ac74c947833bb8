"""``podkrig surrogate``: build a POD-kriging surrogate from a snapshot store, validate it, refine it."""

import json
from pathlib import Path

import numpy as np
import typer

from fe.scenarios import build_scenario
from podkrig.cli._common import (
    FailedRows, KrigingCriterion, SamplingMethod, SurrogateBackend, TableFormat, Variogram, configure_logging,
    settings_from_options, user_errors,
)
from podkrig.config import field_info
from podkrig.io.surrogate_file import load_surrogate, save_surrogate
from podkrig.offline.settings import Design
from podkrig.offline.store import SnapshotStore
from podkrig.reports import surrogate as figs
from podkrig.surrogate.kriging import OrdinaryKriging
from podkrig.surrogate.podkriging import training_data
from podkrig.surrogate.refine import refine_surrogate
from podkrig.surrogate.results import HeldOutResult, SurrogateFitResult
from podkrig.surrogate.settings import BACKENDS, RefineSettings, SurrogateSettings, fit_surrogate
from podkrig.surrogate.validation import compare_settings, held_out_errors

surrogate_app = typer.Typer(
    name="surrogate",
    help="POD-kriging surrogate: build from a snapshot store, validate on held-out runs, refine.",
    no_args_is_help=True,
)


#: the defaults of the surrogate settings, shown in the options' help
_DEFAULTS = {name: f["default"] for name, f in field_info(SurrogateSettings).items()}
_REFINE = {name: f["default"] for name, f in field_info(RefineSettings).items()}
#: the options that set our kriging (a library backend fits its own hyperparameters)
_KRIGING_OPTIONS = {"variogram": "--variogram", "beta": "--beta", "criterion": "--criterion", "nugget": "--nugget"}


def _beta(text):
    """``--beta``: a number, or a word of the settings ("fit", "fit-shared"; checked there)."""
    if text is None:
        return None
    try:
        return float(text)
    except ValueError:
        return text


def surrogate_settings(energy, modes, backend, variogram, beta, criterion, nugget, failed_rows=None):
    """The :class:`~podkrig.surrogate.settings.SurrogateSettings` of ``podkrig surrogate build``'s
    options (None: not given, the settings' default); a kriging option with another backend than
    ours is refused, as that backend fits its own hyperparameters."""
    ours = {"variogram": variogram, "beta": _beta(beta), "criterion": criterion, "nugget": nugget}
    if backend != "podkrig":
        given = [_KRIGING_OPTIONS[k] for k, v in ours.items() if v is not None]
        if given:
            raise ValueError(f"{', '.join(given)} set(s) the podkrig kriging; backend {backend!r} fits its own "
                             "hyperparameters: drop the option(s) or use --backend podkrig")
    options = {"energy": ("--energy", energy), "modes": ("--modes", modes), "backend": ("--backend", backend),
               "failed_rows": ("--failed-rows", failed_rows)}
    options.update({k: (_KRIGING_OPTIONS[k], v) for k, v in ours.items()})
    return settings_from_options(SurrogateSettings, options)


def _describe(kriging):
    """Settings and fitted exponents of the backend, one line."""
    if isinstance(kriging, OrdinaryKriging):
        p = kriging.get_params()
        return (f"kriging: variogram {p['variogram']}, beta {p['beta']}, criterion {p['criterion']}, "
                f"nugget {p['nugget']}; fitted beta per mode " + ", ".join(f"{b:.3g}" for b in kriging.beta_))
    return kriging.describe()


@surrogate_app.command("build")
def build(
    store: Path = typer.Argument(..., help="Snapshot store (HDF5) with finished rows."),
    out: Path = typer.Option(..., "--out", help="Surrogate file to write (HDF5)."),
    energy: float = typer.Option(None, "--energy", help="Retained POD energy 1 - eps, e.g. 0.99999999 (default)."),
    modes: int = typer.Option(None, "--modes", help="Fixed number of POD modes (instead of --energy)."),
    backend: SurrogateBackend = typer.Option(SurrogateBackend(_DEFAULTS["backend"]), "--backend",
                                help=f"Regressor of the POD coefficients: {', '.join(BACKENDS)} "
                                     "(podkrig: ours; smt-krg/smt-kpls: SMT's KRG/KPLS per mode; "
                                     "sklearn-gpr: scikit-learn's GaussianProcessRegressor per mode)."),
    variogram: Variogram = typer.Option(None, "--variogram", help=f"Semivariogram: {' or '.join(Variogram)} (default "
                                                                  f"{_DEFAULTS['variogram']}) (podkrig backend)."),
    beta: str = typer.Option(None, "--beta", help=f"Exponent beta (e.g. 1.2, 1.5, 1.8), 'fit' per mode, or 'fit-shared' (fitted on the first mode, used by all); default {_DEFAULTS['beta']!r} (podkrig backend)."),
    criterion: KrigingCriterion = typer.Option(None, "--criterion", help=f"Hyperparameters by 'ml' (likelihood) or 'loo' (leave-one-out); default {_DEFAULTS['criterion']!r} (podkrig backend)."),
    nugget: float = typer.Option(None, "--nugget", help=f"Nugget relative to the sill (default {_DEFAULTS['nugget']:g}: exact interpolation) (podkrig backend)."),
    field: bool = typer.Option(False, "--field", help="Model the displacement fields instead of the readings."),
    failed_rows: FailedRows = typer.Option(FailedRows(_DEFAULTS["failed_rows"]), "--failed-rows",
                                           help="Failed rows of STORE (FE runs that raised or stopped early): 'drop' "
                                                "trains on the finished rows and names the failed ones, 'refuse' "
                                                "stops."),
    verbose: bool = typer.Option(False, "--verbose", "-v"),
):
    """Fit a POD-kriging surrogate on the finished rows of STORE and save it to --out."""
    configure_logging(verbose)
    with user_errors():
        settings = surrogate_settings(energy, modes, backend.value, variogram and variogram.value, beta,
                                      criterion and criterion.value, nugget, failed_rows.value)
        with SnapshotStore.open(store) as s:
            sur = fit_surrogate(s, settings, output="field" if field else "readings")
        save_surrogate(sur, out)
    fit = SurrogateFitResult.from_surrogate(sur)
    fitted = (f"beta per mode [{', '.join(f'{b:.3g}' for b in fit.beta)}]; {sur.kriging_.fit_method_.describe()}"
              if fit.beta is not None else f"backend {fit.backend}")
    typer.echo(
        f"{out}: {fit.n_train} snapshots, {fit.n_modes} POD modes (retained energy {fit.retained_energy:.10f}), "
        f"{fitted}, trained in {fit.training_seconds:.2f} s"
    )
    if fit.dropped_rows:
        typer.echo(figs.dropped_text(fit.dropped_rows), err=True)


@surrogate_app.command("validate")
def validate(
    file: Path = typer.Argument(..., help="Surrogate file written by 'podkrig surrogate build'."),
    held_out: Path = typer.Option(..., "--held-out", help="Snapshot store of held-out FE runs."),
    report: Path = typer.Option(None, "--report", help="Directory for index.html and the figures."),
    format: TableFormat = typer.Option(TableFormat.table, "--format", help="Output format: table or json."),
    compare: bool = typer.Option(True, "--compare/--no-compare",
                                 help="Also refit with beta 1.2/1.5/1.8/fit and the power model for the "
                                      "error histograms (needs the training store)."),
    verbose: bool = typer.Option(False, "--verbose", "-v"),
):
    """Errors of the surrogate FILE on the held-out runs; optionally an HTML report."""
    configure_logging(verbose)
    with user_errors():
        if format not in ("table", "json"):
            raise ValueError(f"--format must be table or json; got {format!r}")
        sur = load_surrogate(file)
        output = sur.provenance_.get("output", "readings")
        with SnapshotStore.open(held_out) as h:
            Xh, Yh = training_data(h, output)
            held_hash = h.content_hash()
        rep = held_out_errors(sur, Xh, Yh)
        held = HeldOutResult.from_report(rep, backend=sur.backend_, held_out_store=str(held_out),
                                         held_out_content_hash=held_hash)
        if report is not None:
            comparison = None
            src = sur.provenance_.get("source_store")
            if compare and src and Path(src).is_file():
                with SnapshotStore.open(src) as s:
                    X, Y = training_data(s, output)
                settings = [{"beta": b} for b in (1.2, 1.5, 1.8, "fit", "fit-shared")] + [{"variogram": "power", "beta": 1.5}]
                comparison = compare_settings(X, Y, Xh, Yh, settings, space=sur.space, pod=sur.pod)
            _write_report(report, sur, rep, held, comparison)
    if format == "json":
        typer.echo(json.dumps(held.to_dict(), indent=2))
        return
    r, p = held.rel_error, held.pod_error
    typer.echo(
        f"{held.n_held_out} held-out runs, {held.n_train} training, {held.n_modes} modes: "
        f"relative error median {r['median']:.3e}, p95 {r['p95']:.3e}, max {r['max']:.3e} (POD part median "
        f"{p['median']:.3e}); {100 * held.coverage_2sigma:.1f} % of outputs within ±2σ"
        + (f"; {held.fit_description}" if held.fit_description is not None else "")
        + (f"; report {report / 'index.html'}" if report is not None else "")
    )


def _write_report(directory, sur, rep, held, comparison):
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    prov = sur.provenance_
    figures = [("POD energy decay", figs.plot_energy(sur.pod_, directory / "energy.png"))]
    if prov.get("output", "readings") == "readings" and "sensor_names" in prov:
        figures.append(("First POD modes per sensor over the load levels",
                        figs.plot_reading_modes(sur.pod_, prov["sensor_names"], prov["load_levels"],
                                                prov.get("load_unit", "kN"), directory / "modes.png")))
    elif prov.get("output") == "field" and "scenario_spec" in prov:
        nodes = build_scenario(prov["scenario_spec"]).mesh.nodes
        figures.append(("First POD modes on the mesh", figs.plot_field_modes(sur.pod_, nodes, directory / "modes.png")))
    extra = None
    if comparison:
        figures.append(("Held-out relative errors per semivariogram and exponent (cf. thesis Fig. 4.4)",
                        figs.plot_error_histograms(comparison, directory / "error_histograms.png")))
        extra = {"comparison": {k: float(np.median(v)) for k, v in comparison.items()}}
    figures.append(("Surrogate against FE on the held-out runs",
                    figs.plot_predicted_vs_fe(rep, directory / "predicted_vs_fe.png",
                                              unit=prov.get("reading_unit", "mm"))))
    notes = [
        f"training store: {prov.get('source_store', '?')} ({prov.get('source_content_hash', '?')})",
        f"held-out store: {held.held_out_store} ({held.held_out_content_hash})",
        f"backend {sur.backend_}; " + _describe(sur.kriging_),
        f"package version {prov.get('package_version', '?')}",
    ]
    figs.write_html(directory, "POD-kriging surrogate: held-out validation", SurrogateFitResult.from_surrogate(sur),
                    held, figures, notes, extra)


@surrogate_app.command("refine")
def refine(
    file: Path = typer.Argument(..., help="Surrogate file; rewritten with the refitted surrogate."),
    store: Path = typer.Option(..., "--store", help="Training snapshot store; new rows are appended and run."),
    held_out: Path = typer.Option(..., "--held-out", help="Snapshot store of held-out FE runs."),
    target_error: float = typer.Option(_REFINE["target_error"], "--target-error",
                                       help="Stop at this held-out median relative error (-)."),
    budget: int = typer.Option(_REFINE["budget"], "--budget", help="At most this many new FE runs."),
    batch: int = typer.Option(_REFINE["batch"], "--batch", help="FE runs added per round."),
    candidates: int = typer.Option(_REFINE["n_candidates"], "--candidates", help="Size of the Sobol' candidate set."),
    seed: int = typer.Option(_REFINE["seed"], "--seed", help="Seed of the candidate set."),
    sampling: SamplingMethod = typer.Option(SamplingMethod(field_info(Design)["method"]["default"]), "--sampling",
                                            help="Candidate design."),
    workers: int = typer.Option(_REFINE["workers"], "--workers", help="FE workers (1: in this process)."),
    verbose: bool = typer.Option(False, "--verbose", "-v"),
):
    """Add FE runs where the surrogate is least certain until --target-error or --budget is reached."""
    configure_logging(verbose)
    with user_errors():
        r = settings_from_options(RefineSettings, {
            "target_error": ("--target-error", target_error), "budget": ("--budget", budget),
            "batch": ("--batch", batch), "n_candidates": ("--candidates", candidates), "seed": ("--seed", seed),
            "workers": ("--workers", workers), "sampling": ("--sampling", sampling.value)})
        sur = refine_surrogate(load_surrogate(file), store, held_out, target_error=r.target_error, budget=r.budget,
                               batch=r.batch, n_candidates=r.n_candidates, rng=r.seed, workers=r.workers,
                               sampling=r.sampling)
        save_surrogate(sur, file)
    result = sur.provenance_["refinement"]
    hist = result["history"]
    typer.echo(
        f"{file}: {result['added']} FE runs added in {len(hist) - 1} rounds, held-out median relative error "
        f"{hist[0]['median']:.3e} -> {hist[-1]['median']:.3e} ({result['stop_reason']})"
    )


def register(app):
    app.add_typer(surrogate_app, name="surrogate")
