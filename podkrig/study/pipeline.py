"""Run a study stage by stage, caching each stage by a hash of its inputs.

The stages are in :mod:`podkrig.study.stages`, the cache engine (manifests, input hashes,
output checks) in :mod:`podkrig.study.cache`, and which results deserve a warning is the
findings policy of :mod:`podkrig.online.findings` (worded by :mod:`podkrig.reports.findings`). A stage whose manifest has the same input
hash and whose files are unchanged is *cached*: it is not run again. So a rerun with nothing
changed does no FE work, and a new measurement file reruns only the online stages (calibration,
sensitivity, diagnosis). An interrupted FE stage resumes from its store (finished rows are kept);
a store written for another design is rebuilt.

Finally the report ``DIR/report/index.html`` is written from the manifests (always; it is cheap)
and ``DIR/summary.json`` gathers every stage's results and the findings.
"""

import time
from dataclasses import dataclass
from pathlib import Path

from podkrig import __version__
from podkrig.display import Displayed, summary
from podkrig.locks import folder_lock
from podkrig.online.findings import (
    CHI2_BASIS,
    RESIDUAL_CONVENTION,
    diagnosis_findings,
    held_out_findings,
    measurement_findings,
    of_test,
    offline_findings,
    sensitivity_findings,
)
from podkrig.reports.findings import words
from podkrig.reports.study import study_summary_html, write_study_report
from podkrig.study import stages
from podkrig.study.cache import Progress, StageRecord, now, write_json


@dataclass(frozen=True, repr=False)
class StudyResult(Displayed):
    """Outcome of :func:`run_study`.

    Attributes
    ----------
    study : Study
    out : Path
        The output folder.
    stages : tuple of StageRecord
        In the order they ran.
    warnings : list of FindingText
        Every warning of the study in plain words, in stage order (the findings policy,
        :mod:`podkrig.online.findings`, worded for a study by :mod:`podkrig.reports.findings`;
        ``section`` is the report section it belongs to).
    report : Path
        ``out/report/index.html``.
    seconds : float
        Wall time of the run, s.
    finished : str
        When the run finished (ISO 8601, UTC).
    """

    study: object
    out: Path
    stages: tuple
    warnings: list
    report: Path
    seconds: float
    finished: str = ""

    def to_dict(self):
        """JSON-able: what ``summary.json`` holds — the study file and name, the package version,
        when it finished, the conventions of the residuals and χ², each stage's record and result
        by name, and the warnings."""
        return {
            "study": str(self.study.path), "name": self.study.name, "podkrig": __version__, "finished": self.finished,
            "conventions": {"residuals": RESIDUAL_CONVENTION, "chi2": CHI2_BASIS},
            "stages": {r.name: {"cached": r.cached, "seconds": r.seconds, "fe_runs": r.fe_runs, **r.result}
                       for r in self.stages},
            "warnings": [f.to_dict() for f in self.warnings],
        }

    def stage(self, name):
        """The :class:`StageRecord` called ``name``."""
        for record in self.stages:
            if record.name == name:
                return record
        raise KeyError(f"no stage {name!r}; stages: {[r.name for r in self.stages]}")

    @property
    def fe_runs(self):
        """FE runs done by this run, all stages."""
        return sum(r.fe_runs for r in self.stages)

    def _repr_lines(self):
        """The study, its stages (run or cached), FE runs, warnings and the report (repr)."""
        ran = [r.name for r in self.stages if not r.cached]
        return [f"StudyResult {self.study.name!r}: {len(self.stages)} stages ({len(ran)} run, "
                f"{len(self.stages) - len(ran)} cached), {self.fe_runs} FE runs, {len(self.warnings)} warnings, "
                f"{summary(self.seconds)} s",
                f"  out: {self.out}", f"  report: {self.report}",
                *(f"  warning: {summary(w.message, 100)}" for w in self.warnings)]

    #: report figures shown inline by :meth:`_repr_html_`, in this order (those that exist)
    INLINE_FIGURES = ("fit.png", "residuals.png", "region.png", "deformed.png")

    @property
    def calibration(self):
        """The calibration (:class:`~podkrig.online.calibrate.CalibrationResult`), read back from its
        manifest and ``region.npz``."""
        return stages.calibration_result(self.out, self.stage("calibration").result)

    def diagnoses(self):
        """Each test's diagnosis result dict (None when the diagnosis is off), by test name."""
        results = {r.name: r.result for r in self.stages}
        return {t.name: results.get(t.stage("diagnosis")) for t in self.study.calibration_tests}

    def _repr_html_(self):
        """The study's identified parameters, its χ²/dof with what each includes, its warnings and
        the main figures (inline PNG), for Jupyter; the full report is ``self.report``."""
        return study_summary_html(self.study.name, self.calibration, self.diagnoses(), self.warnings, self.report,
                                  self.INLINE_FIGURES)


def run_study(study, out, *, progress=None, confirm=None):
    """Run every stage of a study, reusing cached stages, and write the report.

    Parameters
    ----------
    study : Study
        From :func:`podkrig.study.load_study`.
    out : str or Path
        Output folder (created): stores, surrogates, manifests (``stages/``), the report
        (``report/index.html``) and ``summary.json``.
    progress : Progress, optional
        Receives stage and FE-run progress.
    confirm : callable, optional
        ``confirm(text, large)`` before any FE work with the study's FE work in words and whether it
        is above the thresholds of :mod:`podkrig.limits` (the CLI asks, or refuses without ``--yes``);
        it raises to stop.

    Returns
    -------
    StudyResult

    Raises
    ------
    InUseError
        Another run (process or thread) holds the output folder: the message names its PID and the
        folder, and nothing in the folder was changed. The lock (``out/.podkrig.lock``) is released
        when this call returns or raises.
    ValueError, PodkrigError, fe.FEError
        A measurement file that does not match the scenario, a store that cannot be used, too
        few finished FE runs for a surrogate, ...; finished stages stay cached.
    """
    t0 = time.perf_counter()
    with folder_lock(out):  # one run per folder: a second one is refused here, before it reads or writes
        return _run_locked(study, out, progress, confirm, t0)


def _run_locked(study, out, progress, confirm, t0):
    """:func:`run_study` with the output folder's lock held."""
    run = stages.StudyRun(study, out, progress or Progress())
    if confirm is not None:  # before anything but the lock is written
        confirm(*stages.fe_work(run))
    run.out.mkdir(parents=True, exist_ok=True)
    run.figures.mkdir(parents=True, exist_ok=True)
    tests = study.calibration_tests
    for test in tests:  # before any FE work: a bad file stops here
        stages.measurement_check(run, test)
    for test in tests:  # a few FE runs spanning each box (cached): a unit or sign error stops here,
        stages.probe(run, test)  # before the training snapshots
        stages.range_check(run, test, "probe")
    for test in tests:
        stages.offline(run, test, "offline", "Training snapshots (FE)", "train.h5", test.train)
        stages.range_check(run, test, "train")  # the whole design seen: before the held-out runs and the surrogate
        stages.offline(run, test, "held_out", "Held-out snapshots (FE)", "held_out.h5", test.held_out)
    for model in study.validation:
        stages.validation_model(run, model)
    for test in tests:
        stages.surrogate(run, test)
        stages.held_out_validation(run, test)
    stages.calibration(run)
    calibration = stages.load_calibration(run)
    if study.sensitivity.enabled:  # with the calibration's model-form error
        stages.sensitivity(run, calibration.model_form_errors)
    if study.diagnosis.enabled:
        for test in tests:
            stages.diagnosis(run, test)
    found = words(study_findings(run, calibration), "study", diagnosis_enabled=study.diagnosis.enabled)
    report = write_study_report(run.figures / "index.html", study, run.records, calibration, found)
    result = StudyResult(study, run.out, tuple(run.records), found, report, time.perf_counter() - t0, now())
    write_json(run.out / "summary.json", result.to_dict())
    return result


def study_findings(run, calibration):
    """Every finding of the study, in stage order (:mod:`podkrig.online.findings`), from the
    stage manifests and the ``calibration`` read back (so cached stages give the same findings), as
    codes and values (:class:`~podkrig.online.findings.Finding`). In a joint calibration each
    test's findings name the test."""
    study = run.study
    tests = study.calibration_tests
    found = []
    for t in tests:
        found += of_test(t.name, measurement_findings(run.manifest(t.stage("measurement"))["result"]))
    for record in run.records:
        if "failed" in record.result:  # the FE stages
            found += offline_findings(record.title, record.result)
    for t in tests:
        noise_rel, noise_abs = t.measurement.noise.levels()
        found += of_test(t.name, held_out_findings(run.manifest(t.stage("held_out_validation"))["result"],
                                             noise_rel=noise_rel, noise_abs=noise_abs))
    if study.sensitivity.enabled:
        found += sensitivity_findings(run.manifest("sensitivity")["result"])
    found += calibration.findings
    if study.diagnosis.enabled:
        for t in tests:
            found += of_test(t.name, diagnosis_findings(run.manifest(t.stage("diagnosis"))["result"]))
    return found


__all__ = ["Progress", "StageRecord", "StudyResult", "run_study", "study_findings"]
