"""``podkrig invert`` and ``podkrig rvc``: identify parameters from measured data, with uncertainty."""

import io
import json
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from podkrig.cli._common import (
    RIGID_BODY_HELP,
    RIGID_GROUP_HELP,
    RegionMethod,
    RigidBody,
    TableFormat,
    configure_logging,
    parse_rigid_groups,
    print_findings,
    settings_from_options,
    user_errors,
)
from podkrig.cli._terminal import console as command_console
from podkrig.cli.simulate import parse_assignment
from podkrig.config import field_info
from podkrig.io.measurement_log import REPEATS, ImportSettings, read_measurement, zero_phase
from podkrig.io.surrogate_file import load_surrogate
from podkrig.limits import MAX_JSON_BYTES, check_region_samples, quote, read_bounded
from podkrig.online.calibrate import calibrate
from podkrig.online.data_check import check_readings, surrogate_training_outputs
from podkrig.online.findings import chi2_basis
from podkrig.online.measurement import INSTRUMENTS, NoiseModel
from podkrig.online.model_error import parse_model_form_error
from podkrig.online.nested import nested_analyses
from podkrig.online.problem import InverseProblem, SurrogateModel, check_dof, fix_from_scenario
from podkrig.online.settings import CalibrationSettings, InversionSettings, NoiseSettings, RegionSettings
from podkrig.reports.findings import fe_difference, words
from podkrig.reports.html import num
from podkrig.reports.inverse import write_inversion_report

_CALIBRATION = field_info(CalibrationSettings)
_REGION = field_info(RegionSettings)
_GA = field_info(InversionSettings)
_IMPORT = ImportSettings()  # the defaults of reading a measurement log


def noise_model(noise_abs, noise_rel, noise_cov, instrument=None, sensor_names=None, model_sensors=None,
                sensor_units=None):
    """The NoiseModel of the CLI options and the noise in words: --noise-abs (σ_res) and/or
    --noise-rel (δ), combined as σ² = σ_res² + (δ d)², or --instrument (needs the measured
    ``sensor_names``) — :class:`~podkrig.online.settings.NoiseSettings` — or --noise-cov (a full
    covariance, mm²). ``model_sensors``: the model's sensors, which a --noise-abs NAME=SIGMA must
    name; ``sensor_units``: the measured sensors' units (mm; kN for a load reading, which an
    --instrument for all gives the load cell)."""
    given = [bool(noise_abs) or noise_rel is not None, noise_cov is not None, instrument is not None]
    if sum(given) != 1:
        raise ValueError("give one noise model: --noise-abs SIGMA_MM (or NAME=SIGMA_MM per sensor) and/or "
                         "--noise-rel DELTA, or --noise-cov FILE, or --instrument "
                         + "|".join(INSTRUMENTS))
    if noise_cov is not None:
        try:
            text = read_bounded(noise_cov, MAX_JSON_BYTES, "noise covariance file").decode("utf-8")
            C = np.loadtxt(io.StringIO(text), delimiter=",", ndmin=2)
        except (OSError, ValueError) as e:
            raise ValueError(f"--noise-cov {noise_cov}: cannot read a comma-separated matrix (mm²): {e}") from None
        return NoiseModel(covariance=C), f"covariance from {noise_cov}"
    sigma = None
    if noise_abs:
        if len(noise_abs) == 1 and "=" not in noise_abs[0]:
            try:
                sigma = float(noise_abs[0])
            except ValueError:
                raise ValueError(f"--noise-abs {noise_abs[0]!r}: expected a number (mm) or NAME=SIGMA") from None
        else:
            sigma = dict(parse_assignment(t, "--noise-abs") for t in noise_abs)
    noise = settings_from_options(NoiseSettings, {"noise_abs": ("--noise-abs", sigma), "noise_rel": ("--noise-rel", noise_rel),
                                                  "instrument": ("--instrument", instrument)})
    unknown = noise.unknown_sensors(model_sensors) if model_sensors is not None else []
    if unknown:
        name = unknown[0][1]
        raise ValueError(f"--noise-abs: {quote(name)} (NAME=SIGMA) is not a sensor of the model; its sensors: "
                         f"{', '.join(model_sensors)}")
    return noise.noise_model(sensor_names, sensor_units), noise.describe()


def calibration_settings(*, seed=None, population_size=None, generations=None, n_starts=None, confidence=None,
                         region_method=None, region_samples=None, fe_check=None, mcmc_steps=None,
                         model_form_error=None):
    """The :class:`~podkrig.online.settings.CalibrationSettings` of the CLI options (a refused value
    names its option; an option not given, None, keeps the settings' default)."""
    if region_samples is not None:
        check_region_samples(region_samples)
    inversion = settings_from_options(InversionSettings, {
        "seed": ("--seed", seed), "population_size": ("--population-size", population_size),
        "generations": ("--generations", generations), "n_starts": ("--n-starts", n_starts)})
    region = settings_from_options(RegionSettings, {
        "method": ("--region-method", None if region_method is None else str(region_method)),
        "samples": ("--region-samples", region_samples)})
    return settings_from_options(CalibrationSettings, {
        "inversion": ("", inversion), "region": ("", region),
        "confidence": ("--confidence", None if confidence is None else float(confidence)),
        "fe_check": ("--fe-check", fe_check), "mcmc_steps": ("--mcmc-steps", mcmc_steps),
        "model_form_error": ("--model-form-error", parse_model_form_error(model_form_error))})


def parse_load_range(text):
    """``"10,40"`` → ``(10.0, 40.0)`` (the scenario's load unit)."""
    if text is None:
        return None
    parts = text.split(",")
    try:
        lo, hi = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"--load-range {text!r}: expected LOWER,UPPER (two numbers, the scenario's load unit)") from None
    return (lo, hi)


def parse_zero(text):
    """``--zero``: ``first``, ``none``, ``"end of PHASE"`` or a load."""
    if text is None or text == "none":
        return None
    if text == "first" or zero_phase(text) is not None:
        return text
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"--zero {text!r}: expected first, none or a load (number, the scenario's load unit), or "
                         "'end of PHASE' (the last row of that phase in the --phase-column)") from None


def import_settings(**options):
    """The :class:`~podkrig.io.measurement_log.ImportSettings` of the options of the same names
    (``load_tolerance`` is ``--load-tolerance``); a refused value is named by its option."""
    try:
        return ImportSettings(**options)
    except ValueError as e:
        field, _, rest = str(e).partition(" ")
        if field not in options:
            raise
        raise ValueError(f"--{field.replace('_', '-')} {options[field]!r}: {rest}") from None


def build_problem(surrogate_path, data, noise_abs, noise_rel, noise_cov, free, fix, import_settings=None,
                  instrument=None, check=True, rigid_body="auto", rigid_groups=None, range_check=True):
    """Load the surrogate and data, and set up the inverse problem; returns (problem, model, noise text).

    The measurement check of every door: the log's loads (by the reader) and, with
    ``range_check``, its readings against the surrogate's training runs
    (:mod:`podkrig.online.data_check`). ``check``: refuse dof ≤ 0
    (:func:`~podkrig.online.problem.check_dof`); ``rigid_body``, ``rigid_groups``: see
    :class:`~podkrig.online.problem.InverseProblem`."""
    model = SurrogateModel(load_surrogate(surrogate_path))
    measurement = read_measurement(data, model.sensor_names, model.load_levels, model.load_unit,
                                   model.load_response, import_settings, model.sensor_units)
    noise, noise_text = noise_model(noise_abs, noise_rel, noise_cov, instrument, measurement.sensor_names,
                                    sensor_units=measurement.sensor_units,
                                    model_sensors=model.sensor_names)
    if range_check:
        check_readings(measurement, noise, model.sensor_names, model.load_levels, model.load_response,
                       surrogate_training_outputs(model.surrogate), runs="surrogate")
    free_names = None
    if free:
        free_names = tuple(n.strip() for item in free for n in item.split(",") if n.strip())
    free_names, fixed = fix_from_scenario(model, free_names, dict(parse_assignment(t, "--fix") for t in fix))
    problem = InverseProblem(model, measurement, noise, free=free_names, fixed=fixed, rigid_body=str(rigid_body),
                             rigid_groups=rigid_groups)
    if check:
        check_dof(measurement.n_obs, problem.free, str(data), problem.n_removed)
    return problem, model, noise_text


MODEL_FORM_ERROR_HELP = ("The FE model's own discretisation error in C_D (thesis eq. 2.10): none (default), "
                         "estimated (per reading from the scenario's mesh refined twice, at a first optimum; "
                         "then inverted again) or a relative tolerance, e.g. 0.01 for 1 % of each reading.")
_NOISE_ABS = typer.Option([], "--noise-abs", help="Absolute noise (resolution floor) σ_res in mm, for all sensors, "
                          "or NAME=SIGMA per sensor (repeatable); with --noise-rel: σ² = σ_res² + (δ d)².")
_NOISE_REL = typer.Option(None, "--noise-rel", help="Relative noise δ (σ_i = δ |d_i|, or combined with --noise-abs).")
_NOISE_COV = typer.Option(None, "--noise-cov", help="Noise covariance matrix (CSV, mm², load-major order of the data).")
_SEED_OPTION = typer.Option(_GA["seed"]["default"], "--seed",
                            help="Seed of the GA, the region sampling, the posterior and the RVC.")
_CONFIDENCE_OPTION = typer.Option(_CALIBRATION["confidence"]["default"], "--confidence",
                                  help="Confidence of the region of equivalence (and of the posterior's intervals).")
#: the measurement's readings against the surrogate's training runs (the study file's
#: ``[measurement] range_check``)
RANGE_CHECK = typer.Option(True, "--range-check/--no-range-check",
                           help="Refuse readings far outside every training run of the surrogate (20× larger or "
                                "smaller, or of the opposite sign: a unit or sign error).")
_INSTRUMENT = typer.Option(None, "--instrument", help="Noise of a typical instrument for every sensor: "
                           + ", ".join(INSTRUMENTS) + " (σ² = σ_res² + (δ d)², values in the docs).")


def register(app):
    @app.command()
    def invert(
        surrogate: Path = typer.Argument(..., help="Surrogate file written by 'podkrig surrogate build'."),
        data: Path = typer.Option(..., "--data", help="Measurement log (.csv or .xlsx): a load column and one column "
                                  "per sensor, units in the headers ('load [kN]', 'D1 [µm]'; mm without)."),
        noise_abs: list[str] = _NOISE_ABS,
        noise_rel: float = _NOISE_REL,
        noise_cov: Path = _NOISE_COV,
        instrument: str = _INSTRUMENT,
        load_column: str = typer.Option(_IMPORT.load_column, "--load-column",
                                        help="Name of the load column (without its unit)."),
        repeats: str = typer.Option(_IMPORT.repeats, "--repeats",
                                    help="Several readings at one load step: average or keep."),
        load_tolerance: float = typer.Option(_IMPORT.load_tolerance, "--load-tolerance",
                                             help="Rows within this of a step's first load form one step (load unit)."),
        zero: str = typer.Option(None, "--zero", help="Gauges zeroed at: first (row), a load, 'end of PHASE', or none "
                                                      "(default)."),
        phase_column: str = typer.Option(_IMPORT.phase_column, "--phase-column",
                                         help="Column naming each row's phase (for --zero 'end of PHASE')."),
        load_range: str = typer.Option(None, "--load-range", help="LOWER,UPPER: use only these loads (load unit)."),
        delimiter: str = typer.Option(None, "--delimiter", help="CSV delimiter (default: detected)."),
        decimal: str = typer.Option(None, "--decimal", help="Decimal mark . or , (default: detected)."),
        sheet: str = typer.Option(None, "--sheet", help="Worksheet of an .xlsx file (default: the first)."),
        free: list[str] = typer.Option([], "--free", help="Free parameters (comma-separated or repeated); default all."),
        fix: list[str] = typer.Option([], "--fix", help="Fixed parameter NAME=VALUE (repeatable)."),
        rigid_body: RigidBody = typer.Option(RigidBody.auto, "--rigid-body", help=RIGID_BODY_HELP),
        rigid_group: list[str] = typer.Option([], "--rigid-group", help=RIGID_GROUP_HELP),
        model_form_error: str = typer.Option(_CALIBRATION["model_form_error"]["default"], "--model-form-error",
                                             help=MODEL_FORM_ERROR_HELP),
        report: Path = typer.Option(None, "--report", help="Write an HTML report (index.html + figures) to this folder."),
        format: TableFormat = typer.Option(TableFormat.table, "--format", help="table or json."),
        seed: int = _SEED_OPTION,
        population_size: int = typer.Option(_GA["population_size"]["default"], "--population-size",
                                            help="GA population size."),
        generations: int = typer.Option(_GA["generations"]["default"], "--generations", help="GA generations."),
        n_starts: int = typer.Option(_GA["n_starts"]["default"], "--n-starts",
                                     help="Least-squares polishes (from the GA's best and a Sobol' screen)."),
        confidence: float = _CONFIDENCE_OPTION,
        region_samples: int = typer.Option(_REGION["samples"]["default"], "--region-samples",
                                           help="Surrogate evaluations per region sampling round."),
        region_method: RegionMethod = typer.Option(_REGION["method"]["default"], "--region-method",
                                                   help="Region of equivalence: likelihood-ratio (χ² bound) or noise-mc "
                                                        "(re-identify noisy copies)."),
        mcmc_steps: int = typer.Option(_CALIBRATION["mcmc_steps"]["default"], "--mcmc-steps",
                                       help="Also sample the Bayesian posterior by MCMC (steps; 0 = off)."),
        fe_check: bool = typer.Option(_CALIBRATION["fe_check"]["default"], "--fe-check/--no-fe-check",
                                      help="Run the FE model once at the optimum."),
        range_check: bool = RANGE_CHECK,
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """Identify the free parameters from measured readings against a surrogate."""
        configure_logging(verbose)
        with user_errors():
            if format not in ("table", "json"):
                raise ValueError(f"--format must be table or json; got {format!r}")
            settings = calibration_settings(seed=seed, population_size=population_size, generations=generations,
                                            n_starts=n_starts, confidence=confidence, region_method=region_method,
                                            region_samples=region_samples, fe_check=fe_check, mcmc_steps=mcmc_steps,
                                            model_form_error=model_form_error)
            if repeats not in REPEATS:
                raise ValueError(f"--repeats must be one of {', '.join(REPEATS)}; got {repeats!r}")
            reading = import_settings(load_column=load_column, repeats=repeats, load_tolerance=load_tolerance,
                                      zero=parse_zero(zero), phase_column=phase_column,
                                      load_range=parse_load_range(load_range),
                                      delimiter={"tab": "\t", "\\t": "\t"}.get(delimiter, delimiter),
                                      decimal=decimal, sheet=sheet)
            problem, model, noise_text = build_problem(surrogate, data, noise_abs, noise_rel, noise_cov, free, fix,
                                                       reading, instrument, rigid_body=rigid_body,
                                                       rigid_groups=parse_rigid_groups(rigid_group),
                                                       range_check=False)
            out = calibrate(problem, settings, range_check=range_check)  # the library's measurement check
            if report is not None:
                write_inversion_report(report, out, load_unit=model.load_unit, noise_text=noise_text, rvc=False)
        if format == "json":
            typer.echo(json.dumps({**out.to_dict(), "warnings": [t.to_dict() for t in words(out.findings, "cli")]},
                                  indent=2))
            return
        _print_table(out, report)

    @app.command()
    def rvc(
        surrogate: Path = typer.Argument(..., help="Calibration surrogate."),
        data: Path = typer.Option(..., "--data", help="Measurement CSV."),
        validation: list[Path] = typer.Option([], "--validation", help="Surrogate of a validation scenario (repeatable)."),
        output: list[str] = typer.Option([], "--output", help="Output SENSOR@LOAD to report (repeatable); default: every sensor at the last load."),
        noise_abs: list[str] = _NOISE_ABS,
        noise_rel: float = _NOISE_REL,
        noise_cov: Path = _NOISE_COV,
        free: list[str] = typer.Option([], "--free"),
        fix: list[str] = typer.Option([], "--fix"),
        report: Path = typer.Option(None, "--report"),
        format: TableFormat = typer.Option(TableFormat.table, "--format"),
        seed: int = _SEED_OPTION,
        confidence: float = _CONFIDENCE_OPTION,
        range_check: bool = RANGE_CHECK,
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """Response variability (RVC) of the calibration and validation models over the region of equivalence."""
        configure_logging(verbose)
        with user_errors():
            settings = calibration_settings(seed=seed, confidence=confidence, fe_check=False)
            problem, model, noise_text = build_problem(surrogate, data, noise_abs, noise_rel, noise_cov, free, fix,
                                                       range_check=False)
            models = {Path(path).stem: (SurrogateModel(load_surrogate(path)), None) for path in validation}
            out = calibrate(problem, settings, validation=models, outputs=list(output) or None, range_check=range_check)
            results = out.rvc
            if report is not None:
                write_inversion_report(report, out, load_unit=model.load_unit, noise_text=noise_text)
        if format == "json":
            typer.echo(json.dumps({k: v.to_dict() for k, v in results.items()}, indent=2))
            return
        table = Table(title=f"RVC over the region of equivalence ({len(out.region.samples)} members)")
        levels = next(iter(results.values())).quantile_levels
        for col in ("model", "output", "unit", "mean", "CV (%)", *(f"{100 * q:g} % quantile" for q in levels),
                    "(max−min)/mean (%)"):
            table.add_column(col, justify="right")
        for name, res in results.items():
            for k, o in enumerate(res.outputs):
                table.add_row(name, o, res.units[k], f"{res.mean[k]:.5g}", f"{100 * res.cv[k]:.3f}",
                              *(f"{q:.5g}" for q in res.quantiles[:, k]), f"{100 * res.range_ratio[k]:.3f}")
        command_console().print(table)

    @app.command()
    def overparam(
        surrogate: Path = typer.Argument(..., help="Calibration surrogate."),
        data: Path = typer.Option(..., "--data", help="Measurement CSV."),
        sets: list[str] = typer.Option(..., "--set", help="A set of free parameters, comma-separated (repeat: one per analysis)."),
        validation: list[Path] = typer.Option([], "--validation", help="Surrogate of a validation scenario (repeatable)."),
        noise_abs: list[str] = _NOISE_ABS,
        noise_rel: float = _NOISE_REL,
        noise_cov: Path = _NOISE_COV,
        format: TableFormat = typer.Option(TableFormat.table, "--format"),
        seed: int = _SEED_OPTION,
        confidence: float = _CONFIDENCE_OPTION,
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """Nested analyses: compare sets of free parameters by misfit, AIC/BIC, interval widths and validation RVC."""
        configure_logging(verbose)
        with user_errors():
            free_sets = [tuple(n.strip() for n in s.split(",") if n.strip()) for s in sets]

            def make(free):  # the readings are checked by the library's calibration of each analysis
                return build_problem(surrogate, data, noise_abs, noise_rel, noise_cov, [",".join(free)], [],
                                     range_check=False)[0]

            # a validation model's parameters that an analysis does not free take the calibration's values
            vals = {Path(p).stem: (SurrogateModel(load_surrogate(p)), {}) for p in validation}
            settings = calibration_settings(seed=seed, confidence=confidence)
            rows = nested_analyses(make, free_sets, confidence=settings.confidence, rng=settings.inversion.seed,
                                   validation=vals or None)
        if format == "json":
            typer.echo(json.dumps(rows.to_dict()["analyses"], indent=2))
            return
        table = Table(title="nested analyses (lower AIC/BIC is better; a parameter the data cannot pin down is flagged)")
        for col in ("free parameters", "χ²/dof", "AIC", "BIC", "not identified", *[f"max CV {v} (%)" for v in vals]):
            table.add_column(col, justify="right")
        for r in rows:
            table.add_row(", ".join(r.free), f"{r.chi2_dof:.3g}", f"{r.aic:.4g}", f"{r.bic:.4g}",
                          ", ".join(r.unidentified) or "—", *[f"{100 * r.rvc[v]:.3g}" for v in vals])
        command_console().print(table)

    return invert, rvc, overparam


def parameters_table(calibration, title):
    """The identified parameters of a calibration as a rich table (best fit, region of
    equivalence, identified) — the terminal view of ``podkrig invert`` and ``podkrig run``."""
    r, region = calibration.inversion, calibration.region
    units = dict(zip(r.free, r.units))
    table = Table(title=escape(title))
    for col in ("parameter", "unit", "best fit", f"{100 * region.confidence:.0f} % region of equivalence",
                "identified"):
        table.add_column(col, justify="right")
    for j, name in enumerate(r.free):
        lo, hi = region.intervals[name]
        table.add_row(name, units[name], num(r.x[j], 5), escape(f"[{num(lo)}, {num(hi)}]"),
                      "yes" if region.identifiability[name]["identifiable"] else "NO")
    return table


def _print_table(out, report):
    r = out.inversion
    console = command_console()
    console.print(parameters_table(out, f"identified parameters (χ²/dof = {r.chi2_dof:.3g}, ω = {r.misfit:.4g}, "
                                        f"{r.n_evaluations} evaluations, {r.seconds:.2f} s); χ² includes: "
                                        f"{r.chi2_basis}"))
    if r.fe_check is not None:
        console.print(escape(f"FE check at the optimum: max |FE − surrogate| = "
                             f"{fe_difference(r.fe_check.max_abs_diff_by_unit, r.fe_check.max_abs_diff)} "
                             f"({r.fe_check.max_diff_over_noise:.2f}× the noise); χ²/dof of the FE model = "
                             f"{r.fe_check.chi2_dof_fe:.3g} ({chi2_basis('fe_check')})"))
    print_findings(console, words(out.findings, "cli"))
    if report is not None:
        console.print(escape(f"report: {report / 'index.html'}"))
