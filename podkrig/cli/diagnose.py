"""``podkrig diagnose``: does the calibrated model explain the data, and if not, which physical
effect is missing?"""

import json
from pathlib import Path

import typer

from podkrig.cli._common import (
    RIGID_BODY_HELP,
    RIGID_GROUP_HELP,
    RigidBody,
    TextFormat,
    configure_logging,
    parse_rigid_groups,
    settings_from_options,
    user_errors,
)
from podkrig.cli._terminal import Progress
from podkrig.cli.invert import _NOISE_ABS, _NOISE_COV, _NOISE_REL, noise_model
from podkrig.cli.simulate import load_spec, parse_assignment
from podkrig.config import field_info
from podkrig.diagnosis.settings import DiagnosisSettings

_DIAGNOSIS = field_info(DiagnosisSettings)


def register(app):
    @app.command()
    def diagnose(
        scenario: str = typer.Option(..., "--scenario", help="Scenario name, e.g. diagonal_compression."),
        data: Path = typer.Option(..., "--data", help="Measurement CSV: load, then one column per sensor (mm)."),
        param: list[str] = typer.Option([], "--param", help="Free parameter of the base model NAME=LOW:HIGH[:log] (repeatable)."),
        spec: Path = typer.Option(None, "--spec", help="Scenario spec file (TOML or JSON): options, sensors, fixed values."),
        set_: list[str] = typer.Option([], "--set", help="Value of a non-free parameter NAME=VALUE (repeatable)."),
        noise_abs: list[str] = _NOISE_ABS,
        noise_rel: float = _NOISE_REL,
        noise_cov: Path = _NOISE_COV,
        candidates: str = typer.Option(None, "--candidates", help="Comma-separated candidate causes (default: all but nonlinearity_onset, which costs 10-20 nonlinear runs)."),
        alpha: float = typer.Option(_DIAGNOSIS["alpha"]["default"], "--alpha",
                                    help="Significance level of the tests (multiplicity-corrected)."),
        model_tolerance: float = typer.Option(
            _DIAGNOSIS["model_tolerance"]["default"], "--model-tolerance",
            help="A fixed relative model-form tolerance added to the noise (0.01 = 1 % of each reading), instead of "
                 "the default: each reading's discretisation error estimated from a mesh refined twice."),
        max_causes: int = typer.Option(_DIAGNOSIS["max_causes"]["default"], "--max-causes",
                                       help="Most causes named in turn (forward selection)."),
        rigid_body: RigidBody = typer.Option(RigidBody.auto, "--rigid-body", help=RIGID_BODY_HELP),
        rigid_group: list[str] = typer.Option([], "--rigid-group", help=RIGID_GROUP_HELP),
        seed: int = typer.Option(_DIAGNOSIS["seed"]["default"], "--seed", help="Seed of the surrogate design and the GA."),
        n_train: int = typer.Option(_DIAGNOSIS["n_train"]["default"], "--n-train",
                                    help="FE snapshots of the base surrogate."),
        report: Path = typer.Option(None, "--report", help="Write an HTML report with figures to this folder."),
        format: TextFormat = typer.Option(TextFormat.text, "--format", help="Output: text or json."),
        range_check: bool = typer.Option(True, "--range-check/--no-range-check",
                                         help="Refuse readings far outside every training run of the base surrogate "
                                              "(20× larger or smaller, or of the opposite sign: a unit or sign error)."),
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """Calibrate the base model, test whether it explains the data within the noise, name the
        missing physical effects among the candidate causes (in turn, each refitted with the ones
        before), fit the extended model and measure the gain."""
        configure_logging(verbose)
        with user_errors():
            from fe.scenarios import build_scenario

            from podkrig.diagnosis import diagnose as run_diagnosis
            from podkrig.io.measurement_log import read_measurement
            from podkrig.parameters import ParameterSpace, parse_params

            if format not in ("text", "json"):
                raise ValueError(f"--format must be text or json; got {format!r}")
            settings = settings_from_options(DiagnosisSettings, {
                "seed": ("--seed", seed), "max_causes": ("--max-causes", max_causes), "alpha": ("--alpha", float(alpha)),
                "model_tolerance": ("--model-tolerance", None if model_tolerance is None else float(model_tolerance)),
                "n_train": ("--n-train", n_train)})
            sc = build_scenario(load_spec(scenario, spec))
            space = ParameterSpace.from_scenario(sc, parse_params(param))
            fixed = dict(parse_assignment(t, "--set") for t in set_)
            both = sorted(set(fixed) & set(space.names))
            if both:
                raise ValueError(f"parameter(s) {both} are both free (--param) and fixed (--set); choose one")
            measurement = read_measurement(data, sc.sensor_names, sc.load_levels, sc.load_unit,
                                           sensor_units=sc.sensor_units)
            noise, noise_text = noise_model(noise_abs, noise_rel, noise_cov, sensor_names=measurement.sensor_names,
                                            sensor_units=measurement.sensor_units,
                                            model_sensors=sc.sensor_names)
            names = None if candidates is None else [c.strip() for c in candidates.split(",") if c.strip()]
            with Progress("diagnosis") as progress:
                result = run_diagnosis(sc, measurement, noise, space, settings, fixed=fixed, candidates=names,
                                       progress=progress, rigid_body=str(rigid_body),
                                       rigid_groups=parse_rigid_groups(rigid_group), range_check=range_check)
            out = result.to_dict()
            if report is not None:
                from podkrig.reports.diagnosis import write_diagnosis_report

                out["report"] = str(write_diagnosis_report(result, report, noise_text=noise_text))
            if format == "json":
                typer.echo(json.dumps(out, indent=1))
            else:
                _print_text(out)


def _print_text(out):
    from podkrig.reports.diagnosis import chi2_level_text  # the report's words; imported with the report code

    a = out["adequacy"]
    typer.echo(f"verdict: {out['verdict']}  (χ²/dof = {a['chi2_dof']:.2f}, p = {a['p_value']:.3g}; α = {out['alpha']:g}, {chi2_level_text()})")
    typer.echo(f"  χ² includes: {a['basis']}; residuals {out['residual_convention']}")
    typer.echo("base fit: " + ", ".join(f"{k} = {v:.4g}" for k, v in out["base"]["parameters"].items()))
    if out["cause"] is not None:
        for k, c in enumerate(out["causes"], 1):
            unit = "" if c["unit"] == "-" else f" {c['unit']}"
            typer.echo(f"cause {k}: {c['cause']} at {c['location']}: {c['parameter']} = {c['value']:.4g}{unit} "
                       f"(neutral {c['neutral']:g}{unit})")
        for alt in out["detail"]["alternatives"]:
            typer.echo(f"  equally supported as cause 1: {alt['cause']} at {alt['location']}")
        g = out["gain"]
        for k, st in enumerate(g["steps"], 1):
            dropped = f"; {st['dropped']} dropped (no longer significant)" if st["dropped"] else ""
            typer.echo(f"  step {k}: + {st['cause']}: χ² {st['chi2_before']:.1f} -> {st['chi2_after']:.1f} "
                       f"(corrected p {st['p_corrected']:.3g}, {st['effect_left']:.1f}σ left after refitting){dropped}")
        if not out["extended"]["fully_explained"]:
            typer.echo(f"warning: the extended model still does not explain the data (χ²/dof = "
                       f"{out['extended']['chi2_dof']:.2f}): an effect outside the candidate library may be missing.")
        typer.echo(f"gain: χ²/dof {g['chi2_dof_before']:.2f} -> {g['chi2_dof_after']:.2f}, AIC −{g['aic_drop']:.1f}, "
                   f"BIC −{g['bic_drop']:.1f}")
        if "held_out" in g:
            h = g["held_out"]
            typer.echo(f"held out ({h['held_out']}): RMS residual {h['rms_before']:.2f}σ -> {h['rms_after']:.2f}σ")
    elif out["verdict"] == "inadequate":
        typer.echo("cause: none of the candidate causes explains the residual")
    typer.echo("candidates (corrected p):")
    for c in out["candidates"]:
        if c["applicable"]:
            vis = "" if c["visible"] else "  [not visible to these sensors]"
            sig = "" if c["p_corrected"] < out["alpha"] else "  (not significant)"
            typer.echo(f"  {c['name']:22s} {c['p_corrected']:9.3g}  {c['location']}{vis}{sig}")
        else:
            typer.echo(f"  {c['name']:22s} not applicable: {c['reason']}")
    typer.echo(f"{out['n_fe_runs']} FE runs in {out['seconds']:.1f} s")
    if "report" in out:
        typer.echo(f"report: {out['report']}")
