"""``podkrig run STUDY.toml`` and ``podkrig demo``: a whole calibration study, every stage cached."""

from pathlib import Path

import typer

from podkrig.cli._common import configure_logging, confirm_large_job, print_findings, user_errors
from podkrig.limits import CONFIRM_FE_HOURS, CONFIRM_ROWS, check_name, check_output_folder

DEMO_STUDY = "diagonal_compression.toml"


def examples_dir():
    """The ``examples/`` folder of the source tree podkrig runs from."""
    return Path(__file__).resolve().parents[2] / "examples"


def _stage_progress():
    """A :class:`podkrig.study.pipeline.Progress` showing each stage on stderr
    (:class:`~podkrig.cli._terminal.Progress`: a bar on a terminal, a line at least every 20 s
    elsewhere) and one line per finished stage."""
    from podkrig.cli._terminal import Progress
    from podkrig.study.pipeline import Progress as StageProgress

    class CommandProgress(StageProgress):
        def __init__(self):
            self.display = Progress("study").__enter__()
            self.title = "study"

        def stage_started(self, name, title, total=None):
            self.title = title
            self.display.update(title, 0, total)

        def advance(self, completed, total):
            self.display.update(self.title, completed, total)

        def stage_finished(self, record):
            if record.cached:
                self.display.finish(f"· {record.title}: cached")
                return
            fe = f", {record.fe_runs} FE runs" if record.fe_runs else ""
            self.display.finish(f"✓ {record.title}: {record.seconds:.1f} s{fe}")
            for note in record.result.get("notes", ()):  # e.g. a small job run serially, and why
                self.display.print(f"  {note}")

        def stop(self):
            self.display.stop()

    return CommandProgress()


SKIP_DIAGNOSIS_HELP = ("Leave the model diagnosis out of this run (most of the demo's FE runs), as 'enabled = "
                       "false' in the study's diagnosis table would; a later run without this option adds the "
                       "diagnosis, every other stage cached.")


def _run(study_path, out, yes=False, skip_diagnosis=False):
    """Load, run and summarise a study (inside the CLI's error handling); ``skip_diagnosis``: with
    the study's diagnosis switched off."""
    import dataclasses

    from podkrig.study import load_study, run_study

    study = load_study(study_path)
    if skip_diagnosis:
        study = dataclasses.replace(study, diagnosis=dataclasses.replace(study.diagnosis, enabled=False))
    if out is None:  # the study's name becomes a folder: a name, never a path
        out = Path("out") / check_name(study.name, f"the study name in {study_path}")
    check_output_folder(out)
    progress = _stage_progress()
    try:
        result = run_study(study, out, progress=progress,
                           confirm=lambda text, large: confirm_large_job(text, large, yes))
    except KeyboardInterrupt:
        typer.echo(f"interrupted: finished stages and FE runs are kept in {out}; rerun the same command to resume",
                   err=True)
        raise typer.Exit(code=130) from None
    finally:
        progress.stop()
    _print_summary(result)


def _print_summary(result):
    from rich.markup import escape
    from rich.table import Table

    from podkrig.cli._terminal import console as command_console
    from podkrig.cli.invert import parameters_table
    from podkrig.online.findings import RESIDUAL_CONVENTION
    from podkrig.reports.findings import fe_difference
    from podkrig.reports.study import capacity_rows, chi2_rows

    console = command_console()
    calibration = result.calibration
    inv = calibration.inversion
    console.print(parameters_table(calibration, f"{result.study.name}: identified parameters (χ²/dof of the surrogate "
                                                f"fit = {inv.chi2_dof:.3g})"))
    numbers = Table(title="checks")
    for col in ("quantity", "value"):
        numbers.add_column(col, justify="right")
    study = result.study
    for t in study.calibration_tests:
        label = "" if t.name is None else f"test {t.name}: "
        held = result.stage(t.stage("held_out_validation")).result
        numbers.add_row(f"{label}surrogate median error on held-out FE runs", f"{100 * held['rel_error']['median']:.3g} %")
        fe = calibration.tests[t.name].fe_check
        if fe is not None:
            numbers.add_row(f"{label}max |FE − surrogate| at the best fit",
                            f"{fe_difference(fe.max_abs_diff_by_unit, fe.max_abs_diff)} ({fe.max_diff_over_noise:.2f} σ)")
    for model, r in calibration.rvc.items():
        numbers.add_row(f"largest output CV over the region, {model}", f"{100 * max(r.cv):.3g} %")
        for text, value, note in capacity_rows(r):
            numbers.add_row(escape(f"{model}: {text}"), escape(f"{value} ({note})"))
    if study.diagnosis.enabled:
        for t in study.calibration_tests:
            d = result.stage(t.stage("diagnosis")).result
            numbers.add_row("model diagnosis" + ("" if t.name is None else f", test {t.name}"),
                            escape(d["verdict"] + (f": {d['cause']}" if d["cause"] else "")))
    console.print(numbers)
    fits = Table(title=escape(f"χ²/dof: about 1 when a model explains the data within its C_D; residuals "
                              f"{RESIDUAL_CONVENTION}"))
    for col, justify in (("model", "right"), ("χ²/dof", "right"), ("χ² includes", "left")):
        fits.add_column(col, justify=justify)
    for model, value, basis, _ in chi2_rows(calibration, result.diagnoses()):
        fits.add_row(escape(model), value, escape(basis))
    console.print(fits)
    stages = Table(title="stages")
    for col in ("stage", "this run", "time (s)", "FE runs"):
        stages.add_column(col, justify="right")
    for r in result.stages:
        stages.add_row(escape(r.title), "cached" if r.cached else "ran", f"{r.seconds:.1f}", str(r.fe_runs))
    console.print(stages)
    print_findings(console, result.warnings)
    console.print(escape(f"{result.fe_runs} FE runs in {result.seconds:.1f} s; report: {result.report}"))


def register(app):
    @app.command()
    def run(
        study: Path = typer.Argument(..., help="Study file (TOML): scenario, parameters, sampling, surrogate, "
                                               "measurement, inversion, validation models."),
        out: Path = typer.Option(None, "--out", help="Output folder (default: out/NAME with the study's name)."),
        yes: bool = typer.Option(False, "--yes", "-y", help=f"Start more than {CONFIRM_ROWS} FE runs or "
                                 f"{CONFIRM_FE_HOURS:g} h of estimated FE work without asking (required "
                                 "without a terminal)."),
        skip_diagnosis: bool = typer.Option(False, "--skip-diagnosis", help=SKIP_DIAGNOSIS_HELP),
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """Run a whole study: FE snapshots, surrogate, held-out check, inversion, region of equivalence, RVC, diagnosis.

        Every stage is cached by a hash of its inputs: a rerun with nothing changed does no FE work, and a
        new measurement file reruns only the online stages. Writes OUT/report/index.html.
        """
        configure_logging(verbose)
        with user_errors():
            _run(study, out, yes, skip_diagnosis)

    @app.command()
    def demo(
        out: Path = typer.Option(Path("out/demo"), "--out", help="Output folder."),
        skip_diagnosis: bool = typer.Option(False, "--skip-diagnosis", help=SKIP_DIAGNOSIS_HELP),
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """Run the bundled default study: a diagonal compression test with pseudo-measured data.

        The study is examples/diagonal_compression.toml (see examples/README.md); writes
        OUT/report/index.html. About a minute on two cores the first time, seconds when cached; the
        model diagnosis is about 950 of its 1 300 FE runs (--skip-diagnosis leaves it out).
        """
        configure_logging(verbose)
        with user_errors():
            study = examples_dir() / DEMO_STUDY
            if not study.is_file():
                raise FileNotFoundError(
                    f"the demo study {study} is missing: 'podkrig demo' runs from a source checkout "
                    "(git clone, then pip install -e .); or run your own study with 'podkrig run STUDY.toml'"
                )
            _run(study, out, skip_diagnosis=skip_diagnosis)
