"""The stages of a study, each run through the stage cache (:mod:`podkrig.study.cache`).

Stages, in order (the measurement check, FE work, then the online stages)::

    measurement              the log read and checked against the     (no files)
                             scenario: sensors, loads, dof, noise —
                             before any FE work
    probe                    a few FE runs spanning the parameter     probe.npz
                             box ([measurement] range_check): the
                             readings' range checked against them
                             before the training snapshots
    offline                  training snapshots (FE)                  train.h5
    held_out                 held-out snapshots (FE)                  held_out.h5
    validation_model.NAME    snapshots and surrogate of a validation  validation_NAME.h5, validation_NAME_surrogate.h5
                             scenario (FE), one stage per model (a
                             capacity model's: without the runs that
                             have no load maximum)
    surrogate                POD + kriging fit                        surrogate.h5, report/energy.png, report/modes.png
    held_out_validation      surrogate errors on the held-out runs    report/predicted_vs_fe.png
    calibration              :func:`~podkrig.online.calibrate.calibrate`: region.npz, report/fit.png, residuals.png,
                             model-form error (when asked), GA +      ga_*.png, deformed.png (with the FE
                             polish, region of equivalence, FE check, check), region.png, rvc.png,
                             posterior, RVC of the calibration and    rvc_NAME.png per validation model
                             validation models (their FE runs at
                             region members: the failed share)
    sensitivity              Sobol' indices of readings and misfit    report/sensitivity.png
                             ([sensitivity] enabled; with the
                             calibration's model-form error)
    diagnosis                model diagnosis ([diagnosis] enabled)    report/diagnosis/ (its own page)

In a joint calibration (``[[test]]`` tables) the per-test stages are named ``STAGE.TEST`` and write
under ``TEST/`` and ``report/TEST/``; the calibration and the sensitivity are one stage each.

Each stage function takes the :class:`StudyRun` and records one manifest; the calibration stores
:meth:`CalibrationResult.to_dict`, read back with :func:`load_calibration`. The run parses each
measurement log once, loads each surrogate once and builds each test's inverse problem once
(:class:`StudyRun`).
"""

import dataclasses
import logging
import shutil

import numpy as np

from fe.scenarios import build_scenario
from fe.scenarios.nonlinear import NonlinearScenario
from fe.sensors import absolute_displacements
from podkrig.diagnosis import diagnose
from podkrig.exceptions import StoreError, StoreInUseError
from podkrig.io.measurement_log import read_measurement
from podkrig.io.surrogate_file import load_surrogate, save_surrogate
from podkrig.limits import fe_job_estimate, quote
from podkrig.offline.failures import no_peak_rows
from podkrig.offline.files import move_aside
from podkrig.offline.results import OfflineResult
from podkrig.offline.runner import measured_run_seconds, prepare_store, rows_to_run, run_snapshots
from podkrig.offline.store import SnapshotStore
from podkrig.online.calibrate import CalibrationResult, calibrate, problems_by_test, with_model_form_errors
from podkrig.online.data_check import MeasurementCheckError, check_readings
from podkrig.online.joint import JointProblem
from podkrig.online.propagation import QUANTILES, RVCModel
from podkrig.online.problem import InverseProblem, SurrogateModel, check_dof, fix_from_scenario
from podkrig.online.rigid_body import rigid_body_modes
from podkrig.online.sensitivity import (
    NEGLIGIBLE_TOTAL_INDEX,
    misfit_sensitivity,
    reading_sensitivity,
)
from podkrig.reports import inverse as inverse_figures
from podkrig.reports import surrogate as surrogate_figures
from podkrig.reports.diagnosis import write_diagnosis_report
from podkrig.reports.fields import plot_deformed_field
from podkrig.reports.findings import refusal
from podkrig.reports.sensitivity import plot_sensitivity
from podkrig.study.cache import StageCache, file_sha256, read_arrays
from podkrig.surrogate.podkriging import training_data
from podkrig.surrogate.results import HeldOutResult, SurrogateFitResult, ValidationModelResult
from podkrig.surrogate.settings import fit_surrogate
from podkrig.surrogate.validation import compare_layouts, held_out_errors

logger = logging.getLogger(__name__)
#: Estimated bytes per stored row of a study's stores (readings, parameters, status, 512 B of error
#: text, times), for the size shown before a large job.
STUDY_BYTES_PER_ROW = 1024


class StudyRun(StageCache):
    """The stage cache of one :func:`~podkrig.study.run_study` call, with its study and the
    report folder (``out/report``) where stages draw their figures."""

    def __init__(self, study, out, progress):
        super().__init__(out, progress)
        self.study = study
        self.figures = self.out / "report"
        self._scenarios = {}
        self._measurements = {}
        self._surrogates = {}
        self._problems = {}

    def scenario(self, test):
        """The scenario of a calibration test, built once (only when a stage needs the FE model)."""
        if test.name not in self._scenarios:
            self._scenarios[test.name] = build_scenario(test.spec)
        return self._scenarios[test.name]

    def measurement(self, test, sensor_names=None, load_levels=None, load_unit=None, load_response=None):
        """A test's measurement log read once for its scenario's sensors and loads (or those given):
        (Measurement, NoiseModel)."""
        sc = self.scenario(test)
        sensor_units = sc.sensor_units  # mm, and kN for a nonlinear scenario's load reading
        if sensor_names is None:
            sensor_names, load_levels, load_unit = sc.sensor_names, sc.load_levels, sc.load_unit
            load_response = getattr(sc, "load_response", "discrete")
        key = (test.name, tuple(sensor_names), tuple(np.asarray(load_levels, dtype=float).tolist()), load_unit,
               load_response)
        if key not in self._measurements:
            self._measurements[key] = read_study_measurement(test, sensor_names, load_levels, load_unit,
                                                             load_response, sensor_units)
        return self._measurements[key]

    def surrogate(self, path):
        """The :class:`~podkrig.online.problem.SurrogateModel` of a surrogate file of this run
        (relative to its folder), loaded once (after the stage that writes it)."""
        if path not in self._surrogates:
            self._surrogates[path] = SurrogateModel(load_surrogate(self.out / path))
        return self._surrogates[path]

    def problem(self, test):
        """The inverse problem of one test on its surrogate, without a model-form error (the
        calibration adds it), built once."""
        if test.name not in self._problems:
            model = self.surrogate(test.file("surrogate.h5"))
            data, noise = self.measurement(test, model.sensor_names, model.load_levels, model.load_unit,
                                           model.load_response)
            free, fixed = fix_from_scenario(model)
            m = test.measurement
            self._problems[test.name] = InverseProblem(model, data, noise, free=free, fixed=fixed,
                                                       rigid_body=m.rigid_body, rigid_groups=m.rigid_groups)
        return self._problems[test.name]

    def calibration_problem(self):
        """The study's calibration problem: the one test's :class:`InverseProblem`, or the
        :class:`~podkrig.online.joint.JointProblem` of every ``[[test]]``."""
        tests = self.study.calibration_tests
        if not self.study.tests:
            return self.problem(tests[0])
        return JointProblem({t.name: self.problem(t) for t in tests})

    def figure(self, test, filename):
        """Path of a report figure of ``test`` (``report/NAME/filename`` in a joint calibration)."""
        path = self.figures / test.file(filename)
        path.parent.mkdir(parents=True, exist_ok=True)
        return path


def fe_work(run):
    """The FE work this run of the study would do, in words, and whether it is large enough to ask
    first (:func:`podkrig.limits.fe_job_estimate`): the probe runs unless cached, and every design's
    runs not in its store yet (training, held-out, validation models), each at its scenario's mesh size
    or, once the store holds runs, at their mean CPU time, and the ``fe_runs`` of a validation model at region members (in the calibration) while its store
    is not complete.

    Returns
    -------
    text : str
    large : bool
    """
    study = run.study
    # scenarios built only for the jobs with runs left; the tests' through the run's cache
    jobs = [(run.out / t.file(f), lambda t=t: run.scenario(t), d) for t in study.calibration_tests
            for f, d in (("train.h5", t.train), ("held_out.h5", t.held_out))]
    jobs += [(run.out / f"validation_{m.name}.h5", lambda m=m: build_scenario(m.spec), m.design, m.fe_runs)
             for m in study.validation]
    work, stored = [], 0
    for t in study.calibration_tests:
        if t.measurement.range_check and not run.is_cached(t.stage("probe"), _probe_inputs(t)):
            sc = run.scenario(t)
            nonlinear = isinstance(sc, NonlinearScenario)
            work.append((len(probe_points(t.space.n_params, nonlinear)), sc.n_dofs, nonlinear))
    for path, scenario, design, *at_region in jobs:
        todo = rows_to_run(path, design.n)
        if todo:
            sc = scenario()
            work.append((todo + sum(at_region), sc.n_dofs, isinstance(sc, NonlinearScenario),
                         measured_run_seconds(path)))
            stored += STUDY_BYTES_PER_ROW * design.n
    return fe_job_estimate(work, stored)


def _run_store(run, path, spec, space, design):
    """Fill the store at ``path``: resume it, or build a new one next to a store that cannot be used
    (written for another design, damaged), which is kept under a timestamped name — never deleted.
    A store another run is filling is never touched (:class:`StoreInUseError` propagates)."""
    kwargs = design.run_arguments()
    notes = []
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        prepare_store(path, spec, space, **kwargs)
    except StoreInUseError:
        raise
    except StoreError as e:
        if not path.exists():
            raise
        kept = move_aside(path)
        notes.append(f"{path.name} could not be used ({e}); it was kept as {kept.name} and a new store was built")
        logger.warning("%s could not be used (%s); kept it as %s and building a new store", path, e, kept)
    summary = run_snapshots(path, spec, space, workers=run.study.workers, scheduler=run.study.scheduler,
                            progress=run.progress.advance, **kwargs)
    if summary.executor.startswith("serial:"):  # workers > 1 asked, the job too small for a cluster
        notes.append(summary.executor)
    return summary, notes


def read_study_measurement(test, sensor_names, load_levels, load_unit, load_response, sensor_units=None):
    """A test's measurement log read for a model: (Measurement, NoiseModel); ``sensor_units``:
    sensor → unit (mm, kN for a load reading; default all mm)."""
    m = test.measurement
    try:
        data = read_measurement(m.file, sensor_names, load_levels, load_unit, load_response, m.import_settings(),
                                sensor_units)
    except MeasurementCheckError as e:
        raise ValueError(refusal(e, "study")) from None
    return data, m.noise.noise_model(data.sensor_names, data.sensor_units)


def measurement_check(run, test):
    """Read and check a test's measurement against its scenario before any FE work: every column,
    unit and load; the degrees of freedom; the noise model (:meth:`Measurement.check_summary`)."""
    study = run.study
    m = test.measurement
    settings = {**dataclasses.asdict(m), "file": str(m.file)}  # JSON-able (the report shows the inputs)
    inputs = {"spec": test.spec.to_dict(), "free": list(test.space.names), "measurement": file_sha256(m.file),
              "settings": settings, "diagnosis": study.diagnosis.enabled}

    def compute():
        sc = run.scenario(test)
        response = getattr(sc, "load_response", "discrete")
        unknown = m.noise.unknown_sensors(sc.sensor_names)
        if unknown:
            field, sensor = unknown[0]
            table = "[measurement]" if test.name is None else f"[test.measurement] of test {test.name!r}"
            raise ValueError(f"{study.path}: {table} {field}: {quote(sensor)} is not a sensor of scenario "
                             f"{sc.name}; its sensors: {', '.join(sc.sensor_names)}")
        data, noise = run.measurement(test)
        rigid = rigid_body_modes(data, absolute_displacements(sc.sensors), m.rigid_body, m.rigid_groups)
        check_dof(data.n_obs, test.space.names, str(m.file), 0 if rigid is None else rigid.n_removed)
        if study.diagnosis.enabled:
            exact = np.all(np.any(np.isclose(data.load_levels[:, None], sc.load_levels[None, :], rtol=1e-9,
                                             atol=1e-12), axis=1))
            if not (exact and data.complete and data.reference_load is None):
                raise ValueError(
                    f"{m.file}: [diagnosis] needs every sensor read at the scenario's load levels "
                    f"{sc.load_levels.tolist()} {sc.load_unit} (no missing cells, no zero reference); this log has "
                    f"{len(data.load_levels)} loads from {data.load_levels.min():g} to {data.load_levels.max():g} "
                    f"{sc.load_unit}{'' if data.complete else ' and missing readings'}. Set [diagnosis] "
                    "enabled = false, or give the readings at the levels")
        summary = data.check_summary(sc.sensor_names, noise)
        summary.update(load_response=response, load_unit=sc.load_unit, n_free=test.space.n_params,
                       dof=data.n_obs - test.space.n_params, noise=m.noise.describe())
        for note in data.notes:
            logger.info("%s: %s", m.file.name, note)
        return summary, [], 0

    run.stage(test.stage("measurement"), test.title("Measurement check (before FE work)"), inputs, compute)


def probe_points(n_params, nonlinear):
    """Unit-cube points of the probe: the FE runs made before the training snapshots to check the
    measurement's range (:func:`range_check`).

    The box centre; for a linear scenario (an FE run takes milliseconds) also each parameter at
    its lower and at its upper bound with the others at the centre — the extremes of the response
    along every parameter, 2d + 1 runs for d free parameters (7 for 3); for a nonlinear scenario (a
    run takes 30–90 s at the default mesh) the centre alone, and the check after the training
    snapshots sees the whole design.

    Returns
    -------
    ndarray of shape (n_runs, n_params)
    """
    U = np.full((1, n_params), 0.5)
    if nonlinear:
        return U
    ends = np.full((2 * n_params, n_params), 0.5)
    k = np.arange(n_params)
    ends[2 * k, k], ends[2 * k + 1, k] = 0.0, 1.0
    return np.vstack([U, ends])


def _probe_inputs(test):
    return {"spec": test.spec.to_dict(), "space": test.space.to_dict()}


def _strings(values):
    """A NumPy array of text (read back without pickle)."""
    return np.array([str(v) for v in values], dtype=str)


def probe(run, test):
    """The probe FE runs (:func:`probe_points`) of a test's scenario into ``probe.npz`` (``X
    (n_runs, n_params)`` physical values, ``readings (n_runs, n_levels, n_sensors)`` mm, NaN where a
    run failed or stopped early; the columns named by ``names`` and ``units``, the readings by
    ``sensor_names``, ``load_levels`` and ``load_unit``): the number of runs and of those not used
    (failed, or a nonlinear run stopped early — as failed rows of a store are not). Skipped with ``[measurement]
    range_check = false``; cached by the scenario and the parameter box, so a new measurement file
    reruns no FE."""
    if not test.measurement.range_check:
        return
    sc = run.scenario(test)
    U = probe_points(test.space.n_params, isinstance(sc, NonlinearScenario))
    filename = test.file("probe.npz")

    def compute():
        X = test.space.from_unit(U)
        Y = np.full((len(X), len(sc.load_levels), len(sc.sensor_names)), np.nan)
        notes = []
        for i, x in enumerate(X):
            params = test.space.as_params(x)
            try:
                response = sc.run(params)
            except Exception as e:  # noqa: BLE001 - a failed FE run leaves the probe smaller, never a crash
                notes.append(f"probe run {i + 1} at {params} failed ({type(e).__name__}: {e}); not used")
            else:
                Y[i] = response.readings  # a nonlinear run stopped early: NaN past the last level reached
                if getattr(response, "status", "converged") != "converged":
                    notes.append(f"probe run {i + 1} at {params} stopped early ({response.status}); not used")
            run.progress.advance(i + 1, len(X))
        (run.out / filename).parent.mkdir(parents=True, exist_ok=True)
        np.savez(run.out / filename, X=X, readings=Y, names=_strings(test.space.names),
                 units=_strings(test.space.units), sensor_names=_strings(sc.sensor_names),
                 load_levels=np.asarray(sc.load_levels, float), load_unit=np.str_(sc.load_unit))
        n_failed = int(np.sum(~np.all(np.isfinite(Y.reshape(len(X), -1)), axis=1)))
        return {"n_runs": len(X), "n_failed": n_failed, "notes": notes}, [filename], len(X)

    run.stage(test.stage("probe"), test.title("Probe FE runs (measurement range check)"), _probe_inputs(test),
              compute, total=len(U))


def range_check(run, test, source):
    """Stop when a sensor's readings lie far outside every FE run of a test (a unit or sign error):
    :func:`~podkrig.online.data_check.check_readings` against the probe runs (``source = "probe"``,
    before the training snapshots) or against the training design (``source = "train"``, right after its
    snapshots: the whole box). Nothing with ``[measurement] range_check = false``.

    Raises
    ------
    ValueError
        Naming the file, the FE runs compared with, each sensor and its factor
        (:func:`podkrig.online.data_check.check_readings`, worded by
        :func:`podkrig.reports.findings.refusal`).
    """
    if not test.measurement.range_check:
        return
    sc = run.scenario(test)
    if source == "probe":
        Y = read_arrays(run.out / test.file("probe.npz"))["readings"]
        Y = Y[np.all(np.isfinite(Y.reshape(len(Y), -1)), axis=1)]  # complete runs, as only_done of a store
        sensor_names, levels, unit = list(sc.sensor_names), sc.load_levels, sc.load_unit
    else:
        with SnapshotStore.open(run.out / test.file("train.h5")) as store:
            Y = store.readings(only_done=True)
            sensor_names, levels, unit = list(store.sensor_names), store.load_levels, store.load_unit
    if not len(Y):
        return
    response = getattr(sc, "load_response", "discrete")
    data, noise = run.measurement(test, sensor_names, levels, unit, response)
    try:
        check_readings(data, noise, sensor_names, levels, response, Y, runs=source if source == "probe" else "training")
    except MeasurementCheckError as e:
        raise ValueError(refusal(e, "study")) from None


def offline(run, test, name, title, filename, design):
    """FE snapshots of a test's design into ``filename`` (training or held-out):
    :meth:`OfflineResult.to_dict`."""
    inputs = {"spec": test.spec.to_dict(), "space": test.space.to_dict(), "design": dataclasses.asdict(design)}
    filename = test.file(filename)

    def compute():
        path = run.out / filename
        summary, notes = _run_store(run, path, run.scenario(test), test.space, design)
        return OfflineResult.from_store(path, summary, notes).to_dict(), [filename], summary.ran

    run.stage(test.stage(name), test.title(title), inputs, compute, total=design.n)


#: why a validation surrogate of capacity leaves runs out (:func:`~podkrig.offline.failures.no_peak_rows`)
NO_PEAK_WHY = "no load maximum within the control range (the peak in the last control interval): no capacity"


def _fit(store_path, settings, out_path, capacity=False):
    """Fit and save a surrogate of ``settings`` on a store; returns it. ``capacity``: a surrogate
    of the peak readings, which leaves out the runs without a load maximum."""
    with SnapshotStore.open(store_path) as store:
        exclude = no_peak_rows(store) if capacity else ()
        sur = fit_surrogate(store, settings, exclude=exclude, why=NO_PEAK_WHY if exclude else "")
    save_surrogate(sur, out_path)
    return sur


def validation_model(run, model):
    """Snapshots and surrogate of a validation scenario: :meth:`ValidationModelResult.to_dict`."""
    study = run.study
    name = f"validation_model.{model.name}"
    store, surrogate = f"validation_{model.name}.h5", f"validation_{model.name}_surrogate.h5"
    capacity = bool(model.spec.options.get("peak_readings", False))
    inputs = {"spec": model.spec.to_dict(), "space": study.space.to_dict(), "design": dataclasses.asdict(model.design),
              "surrogate": dataclasses.asdict(study.surrogate), **({"exclude": "no load maximum"} if capacity else {})}

    def compute():
        summary, notes = _run_store(run, run.out / store, model.spec, study.space, model.design)
        sur = _fit(run.out / store, study.surrogate, run.out / surrogate, capacity=capacity)
        result = ValidationModelResult(OfflineResult.from_store(run.out / store, summary, notes), model.spec.scenario,
                                       SurrogateFitResult.from_surrogate(sur))
        return result.to_dict(), [store, surrogate], summary.ran

    run.stage(name, f"Validation model '{model.name}' (FE + surrogate)", inputs, compute, total=model.design.n)


def surrogate(run, test):
    """POD + kriging fit on a test's training store: :meth:`SurrogateFitResult.to_dict` (sizes, retained
    energy, exponents, training time)."""
    settings = run.study.surrogate
    inputs = {"settings": dataclasses.asdict(settings), "train": run.outputs(test.stage("offline"))}

    def compute():
        sur = _fit(run.out / test.file("train.h5"), settings, run.out / test.file("surrogate.h5"))
        prov = sur.provenance_
        surrogate_figures.plot_energy(sur.pod_, run.figure(test, "energy.png"))
        surrogate_figures.plot_reading_modes(sur.pod_, prov["sensor_names"], prov["load_levels"], prov["load_unit"],
                                             run.figure(test, "modes.png"))
        files = [test.file("surrogate.h5")] + [f"report/{test.file(f)}" for f in ("energy.png", "modes.png")]
        return SurrogateFitResult.from_surrogate(sur).to_dict(), files, 0

    run.stage(test.stage("surrogate"), test.title("Surrogate fit (POD + kriging)"), inputs, compute)


def held_out_validation(run, test):
    """A test's surrogate against its held-out FE runs: :meth:`HeldOutResult.to_dict`
    (:meth:`HeldOutReport.summary` plus RMS and max errors, mm). For a nonlinear test with more than
    one control level, also both POD layouts on its training snapshots (``layout``, the surrogate's,
    and ``layouts``, :func:`~podkrig.surrogate.validation.compare_layouts`: one fit more, of the other
    layout); the study's surrogate stays the one of its ``[surrogate] pod``."""
    inputs = {"surrogate": run.outputs(test.stage("surrogate")), "held_out": run.outputs(test.stage("held_out"))}
    sc = run.scenario(test)
    compare = isinstance(sc, NonlinearScenario) and len(sc.load_levels) > 1
    if compare:  # the other layout is fitted on the training store
        inputs["layouts_train"] = run.outputs(test.stage("offline"))

    def compute():
        sur = run.surrogate(test.file("surrogate.h5")).surrogate
        with SnapshotStore.open(run.out / test.file("held_out.h5")) as store:
            X, Y = training_data(store)
        rep = held_out_errors(sur, X, Y)
        surrogate_figures.plot_predicted_vs_fe(rep, run.figure(test, "predicted_vs_fe.png"))
        layouts = {}
        if compare:
            with SnapshotStore.open(run.out / test.file("train.h5")) as store:
                X_train, Y_train = training_data(store)
            layouts = {"layout": sur.layout, "layouts": compare_layouts(sur, X_train, Y_train, X, Y)}
        return (HeldOutResult.from_report(rep, **layouts).to_dict(), [f"report/{test.file('predicted_vs_fe.png')}"],
                0)

    run.stage(test.stage("held_out_validation"), test.title("Surrogate check on held-out runs"), inputs, compute)


def _online_inputs(run):
    """Inputs shared by the online stages: each test's surrogate, measurement file and noise."""
    inputs = {}
    for t in run.study.calibration_tests:
        m = t.measurement
        one = {"surrogate": run.outputs(t.stage("surrogate")), "measurement": file_sha256(m.file),
               "noise": dataclasses.asdict(m.noise),
               "import": dataclasses.asdict(m.import_settings()),
               "rigid_body": {"option": m.rigid_body, "groups": m.rigid_groups},
               **({} if m.model_form_error == "none" else {"model_form_error": m.model_form_error})}
        if t.name is None:
            return one
        inputs[t.name] = one
    return {"tests": inputs}


def calibration(run):
    """The calibration (:func:`~podkrig.online.calibrate.calibrate`): model-form error when asked,
    inversion, region of equivalence, FE check, posterior, RVC of the calibration and validation
    models, findings; its :meth:`CalibrationResult.to_dict` with each test's model-form error
    under ``model_form_errors``, the region's members in ``region.npz``, and its figures."""
    study = run.study
    tests = {t.name: t for t in study.calibration_tests}
    settings = study.calibration_settings()
    inputs = {**_online_inputs(run), "settings": dataclasses.asdict(settings), "rvc": {"quantiles": list(QUANTILES)},
              "validation": {m.name: {"surrogate": run.outputs(f"validation_model.{m.name}"),
                                      "outputs": list(m.outputs) if m.outputs else None, "fe_runs": m.fe_runs,
                                      "quantiles": list(m.quantiles)} for m in study.validation}}

    def compute():
        problem = run.calibration_problem()
        validation = {m.name: RVCModel(run.surrogate(f"validation_{m.name}_surrogate.h5"), m.outputs,
                                       scenario=build_scenario(m.spec) if m.fe_runs else None, fe_runs=m.fe_runs,
                                       quantiles=m.quantiles)
                      for m in study.validation}
        # the readings were compared with the probe and training runs by range_check already
        result = calibrate(problem, settings, scenarios=lambda name: run.scenario(tests[name]), validation=validation,
                           check_measurement=False, range_check=False, keep_field=True,
                           progress=lambda step, done, total: run.progress.advance(done, total))
        region = result.region
        save_region(run.out / "region.npz", region)
        files = ["region.npz"] + _draw_calibration(run, result)
        return result.to_dict(), files, result.n_fe_runs

    run.stage("calibration", "Calibration (inversion, FE check, region, RVC)", inputs, compute)


def _draw_calibration(run, result):
    """The calibration's figures from its result: each test's fit, residuals and deformed specimen
    (with the FE check), the GA's history and parameters, the region and the RVC; report files."""
    files = []
    for test in run.study.calibration_tests:
        one = result.tests[test.name]
        unit = one.problem.model.load_unit
        steps = getattr(run.scenario(test), "steps", None) if unit == "step" else None  # flat jack: vs pressure
        inverse_figures.plot_fit(one, run.figure(test, "fit.png"), load_unit=unit, steps=steps)
        inverse_figures.plot_residuals(one, run.figure(test, "residuals.png"), load_unit=unit, steps=steps)
        drawn = ["fit.png", "residuals.png"]
        response = result.responses.get(test.name)
        if getattr(response, "field", None) is not None:
            plot_deformed_field(run.scenario(test), response.field, run.figure(test, "deformed.png"),
                                title="FE model at the best fit" + ("" if test.name is None else f" — test {test.name}"))
            drawn.append("deformed.png")
        files += [f"report/{test.file(f)}" for f in drawn]
    inv = result.inversion
    inverse_figures.plot_ga_history(inv, run.figures / "ga_history.png")
    inverse_figures.plot_ga_parameters(inv, run.figures / "ga_parameters.png")
    inverse_figures.plot_region(result.region, run.figures / "region.png", best=inv.x, posterior=result.posterior,
                                space=inv.problem.free_space)
    inverse_figures.plot_rvc(result.rvc, run.figures / "rvc.png")
    drawn = inverse_figures.plot_rvc_distributions(result.rvc, run.figures)
    return files + ["report/ga_history.png", "report/ga_parameters.png", "report/region.png", "report/rvc.png",
                    *(f"report/{f}" for f in drawn.values())]


def save_region(path, region):
    """The members of a :class:`~podkrig.online.region.Region` into ``path`` (``.npz``): ``samples``
    ``(n_members, n_free)`` in the units ``units`` of the parameters ``names`` (one per column) and
    their misfit ``omega`` ``(n_members,)``."""
    np.savez(path, samples=region.samples, omega=region.omega, names=_strings(region.names),
             units=_strings(region.units))


def region_members(path, names):
    """``samples, omega`` of a region file written by :func:`save_region` for the parameters
    ``names`` (a file written before the columns were named has no ``names``: read as it is),
    read within the cap of :func:`~podkrig.study.cache.read_arrays`.

    Raises
    ------
    ValueError
        The file names other parameters (it belongs to another study).
    """
    f = read_arrays(path)
    if "names" in f and f["names"].tolist() != list(names):
        raise ValueError(f"{path} holds the region of the parameters {f['names'].tolist()}, not of this calibration's "
                         f"{list(names)}: run the study again into this folder, or give another --out")
    return f["samples"], f["omega"]


def load_calibration(run):
    """The calibration stage's :class:`~podkrig.online.calibrate.CalibrationResult` (its manifest,
    and ``region.npz`` for the region's members)."""
    return calibration_result(run.out, run.manifest("calibration")["result"])


def calibration_result(out, result):
    """The :class:`~podkrig.online.calibrate.CalibrationResult` of the calibration stage's
    manifest ``result`` with the region's members from ``out/region.npz``."""
    samples, omega = region_members(out / "region.npz", result["region"]["names"])
    return CalibrationResult.from_dict(result, samples=samples, omega=omega)


def sensitivity(run, errors):
    """Sobol' indices on the surrogate(s): every reading of each test and the misfit of the
    calibration with its model-form error (``errors``: :attr:`CalibrationResult.model_form_errors`),
    and the free parameters proposed for fixing (total index below
    :data:`~podkrig.online.sensitivity.NEGLIGIBLE_TOTAL_INDEX` for every reading and the misfit)."""
    s = run.study.sensitivity
    estimate = {"model_form_error": {str(n): e.std.tolist() for n, e in errors.items()}} if errors else {}
    inputs = {**_online_inputs(run), **estimate, "settings": s.options(), "threshold": NEGLIGIBLE_TOTAL_INDEX}

    def compute():
        options = s.options()
        problem = with_model_form_errors(run.calibration_problem(), errors)
        misfit = misfit_sensitivity(problem, **options)
        readings, files = {}, []
        per_test = problems_by_test(problem)
        for test in run.study.calibration_tests:
            one = reading_sensitivity(per_test[test.name].model, **options)
            readings[str(test.name or "calibration")] = one
            plot_sensitivity(one, run.figure(test, "sensitivity.png"),
                             misfit=misfit if not run.study.tests else None)
            files.append(f"report/{test.file('sensitivity.png')}")
        fixable = set(misfit.negligible())
        for one in readings.values():  # a parameter a test does not have cannot make it sensitive
            fixable &= set(one.negligible()) | (set(misfit.parameters) - set(one.parameters))
        result = {"readings": {k: v.to_dict() for k, v in readings.items()}, "misfit": misfit.to_dict(),
                  "threshold": NEGLIGIBLE_TOTAL_INDEX,
                  "propose_fixing": [p for p in misfit.parameters if p in fixable]}
        return result, files, 0

    run.stage("sensitivity", "Global sensitivity (Sobol' indices)", inputs, compute)


def diagnosis(run, test):
    """The model diagnosis of a test on its FE model (its own report page): :meth:`DiagnosisResult.to_dict`."""
    study = run.study
    inputs = {**_online_inputs(run), "settings": dataclasses.asdict(study.diagnosis)}

    def compute():
        problem = run.problem(test)
        folder = run.figures / test.file("diagnosis")
        shutil.rmtree(folder, ignore_errors=True)  # figures of an earlier diagnosis
        result = diagnose(run.scenario(test), problem.measurement, problem.noise, test.space, study.diagnosis,
                          fixed=test.fixed, surrogate=problem.model.surrogate,
                          rigid_body=test.measurement.rigid_body, rigid_groups=test.measurement.rigid_groups,
                          range_check=False,  # checked against these training runs already (range_check)
                          progress=lambda stage, done, total: run.progress.advance(done, total))
        write_diagnosis_report(result, folder, noise_text=test.measurement.noise.describe())
        files = sorted(str(p.relative_to(run.out)) for p in folder.iterdir())
        return result.to_dict(), files, result.n_fe_runs

    run.stage(test.stage("diagnosis"), test.title("Model diagnosis"), inputs, compute, total=1)
