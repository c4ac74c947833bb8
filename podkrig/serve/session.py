"""The session of ``podkrig serve``: one study, its output folder and its calibration problem.

A :class:`Session` is opened over a finished study's output folder (its ``summary.json`` names the
study file) or over a study file (its folder is ``--out``, by default ``out/NAME`` as for
``podkrig run``). It builds the calibration problem from the folder exactly as the study's
calibration stage does (:meth:`podkrig.study.stages.StudyRun.calibration_problem`: each test's
surrogate and measurement, one :class:`~podkrig.online.joint.JointProblem` for several tests), and
answers the page's questions about it as JSON-able dicts:

* :meth:`Session.study_view` — the parameters (search box, scale, best value and interval of the
  study's calibration), the tests (sensors, load levels, free parameters), noise and GA settings;
* :meth:`Session.predict` — the surrogate's mean and σ at the measured readings of every test, the
  standardized residuals ``(d − g)/σ_total`` with ``σ_total² = σ_noise² + σ_surrogate²`` (the
  diagonal of thesis eq. 2.10's ``C_D``), each test's χ²/dof and the misfit ω (thesis eq. 2.13).
  This is the slider's path: one surrogate call per test (mean and σ; χ² and ω from the same
  prediction), about half a millisecond of CPU on the demo;
* :meth:`Session.replace_measurement` — an uploaded measurement log read by the library's reader
  (:func:`podkrig.io.measurement_log.read_measurement`) with the study's import settings and
  checked like the study's measurement stage; it replaces that test's data in this session only.
  Its messages name the file as the user named it, never the server's temporary copy. When a study
  job ends the problem is built again from the folder and every upload is read and checked again
  against the new surrogates: kept when it passes, dropped otherwise with the reason in
  :meth:`Session.uploads_view` (the page shows it beside the test).

Every value a request gives is checked here and refused with a :class:`RequestError` naming the
field, the value and what is allowed; nothing from a request is ever executed or unpickled.
"""

import dataclasses
import json
import logging
import math
import os
import reprlib
import tempfile
import threading
from pathlib import Path

import numpy as np

from podkrig.exceptions import PodkrigError
from podkrig.limits import MAX_JSON_BYTES, check_name, read_bounded
from podkrig.online.calibrate import problems_by_test
from podkrig.online.data_check import MeasurementCheckError, check_readings, surrogate_training_outputs
from podkrig.online.joint import JointProblem
from podkrig.online.problem import check_dof
from podkrig.parameters import ParameterSpace
from podkrig.reports.findings import refusal
from podkrig.study import load_study
from podkrig.study.cache import Progress, read_manifest
from podkrig.study.stages import StudyRun, calibration_result, read_study_measurement

logger = logging.getLogger(__name__)

#: the control variable of a test, by the load unit of its scenario
CONTROLS = {"kN": "load", "mm": "displacement", "step": "step", "MPa": "load"}


class RequestError(PodkrigError):
    """A request the session refuses: ``status`` is its HTTP status (422 invalid input, 404 unknown
    id, 409 the folder is busy or not ready, 413 too large, 403 forbidden) and ``field`` the key it
    names (None: the request as a whole)."""

    def __init__(self, message, field=None, status=422):
        super().__init__(message)
        self.field = field
        self.status = status


def check_keys(body, keys, what):
    """Refuse a request body with a key not in ``keys`` (a misspelt key would be ignored silently).

    Raises
    ------
    RequestError
        422 naming the key and the allowed ones; field: the key.
    """
    unknown = [k for k in body if k not in keys]
    if unknown:
        raise RequestError(f"{what}: unknown key {unknown[0]!r}; the keys are {', '.join(keys)}", unknown[0])


def is_number(value):
    """Whether ``value`` (from a JSON body) is a finite number: not a bool, a string, NaN, ±inf or an
    integer beyond a float's range (``10**400``)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def json_safe(values):
    """A 1-D float array as a JSON list, NaN (a missing reading) as None."""
    return [v if math.isfinite(v) else None for v in np.asarray(values, dtype=float).tolist()]


def study_file_of(folder):
    """The study file named by a finished study folder's ``summary.json``.

    Raises
    ------
    RequestError
        No ``summary.json`` (not a finished study folder), or its study file is gone.
    """
    folder = Path(folder)
    summary = folder / "summary.json"
    try:
        data = json.loads(read_bounded(summary, MAX_JSON_BYTES, "study summary").decode("utf-8"))
    except OSError:
        raise RequestError(f"{folder} holds no summary.json, so it is not a finished study's output folder: "
                           "give the study file instead (podkrig serve STUDY.toml --out FOLDER)", "folder") from None
    except ValueError as e:
        raise RequestError(f"{summary} cannot be read ({e}): give the study file instead "
                           "(podkrig serve STUDY.toml --out FOLDER)", "folder") from None
    path = Path(data.get("study", ""))
    if not path.is_file():
        raise RequestError(f"{summary} names the study file {path}, which does not exist: give the study file "
                           "(podkrig serve STUDY.toml --out FOLDER)", "folder")
    return path


@dataclasses.dataclass(frozen=True)
class Upload:
    """A measurement log uploaded in a session: ``path`` its temporary copy on the server, ``name``
    the file name the user gave (what every message names)."""

    path: Path
    name: str


def upload_name(name):
    """The file name of an upload as messages show it: the last part of the name the page sent
    (a browser sends no folders; anything before a ``/`` or ``\\`` is dropped), at most 100
    characters, ``upload.csv`` when nothing is left."""
    base = str(name or "").replace("\\", "/").rsplit("/", 1)[-1].strip()
    return base[:100] or "upload.csv"


class Session:
    """One study served: its folder, its study and (once the offline stage has run) its problem.

    Parameters
    ----------
    study : Study
        From :func:`podkrig.study.load_study`.
    folder : str or Path
        The study's output folder.

    Attributes
    ----------
    study : Study
    folder : Path
        Resolved.
    """

    def __init__(self, study, folder):
        self.study = study
        self.folder = Path(folder).resolve()
        self._lock = threading.Lock()
        self._run = None
        self._problem = None
        self._uploads = {}  # test name -> Upload (the log's temporary copy and the user's file name)
        self._dropped = {}  # test name -> (file name, why) of an upload the rebuilt problem refused
        self._tmp = None
        self._calibration = None  # (manifest mtime, CalibrationResult or None)

    @classmethod
    def open(cls, path, out=None):
        """A session over a study folder or a study file (``out``: its folder; default
        ``out/NAME`` with the study's name, as ``podkrig run``).

        Raises
        ------
        RequestError
            A folder that is not a finished study's, ``out`` given with a folder.
        StudyError
            The study file is invalid (its own message, with file, line and key).
        """
        path = Path(path)
        if path.is_dir():
            if out is not None:
                raise RequestError(f"--out is for a study file; {path} is a folder already", "out")
            return cls(load_study(study_file_of(path)), path)
        study = load_study(path)
        if out is None:
            out = Path("out") / check_name(study.name, f"the study name in {path}")
        return cls(study, out)

    # ------------------------------------------------------------------------------------- state

    @property
    def tests(self):
        """The study's calibration tests (one with name None, or the ``[[test]]`` tables)."""
        return self.study.calibration_tests

    @property
    def ready(self):
        """Whether every test's surrogate is in the folder (the offline stage has run)."""
        return all((self.folder / t.file("surrogate.h5")).is_file() for t in self.tests)

    @property
    def state(self):
        return "ready" if self.ready else "needs_offline"

    @property
    def uploaded(self):
        """The tests whose measurement was replaced by an upload in this session."""
        return tuple(self._uploads)

    def reload(self):
        """Forget the problem built so far (after a study job wrote new surrogates or a new
        calibration): it is built again from the folder on first use, and each upload of this
        session is read and checked again against it (kept, or dropped with the reason:
        :meth:`uploads_view`)."""
        with self._lock:
            self._run = None
            self._problem = None

    def uploads_view(self):
        """The uploads of this session per test (name, '' for a single test): ``{"file": the user's
        file name, "state": "in use" | "dropped", "message": why it was dropped, or None}``."""
        view = {name or "": {"file": u.name, "state": "in use", "message": None} for name, u in self._uploads.items()}
        for name, (file, why) in self._dropped.items():
            view.setdefault(name or "", {"file": file, "state": "dropped", "message": why})
        return view

    def study_run(self):
        """The :class:`~podkrig.study.stages.StudyRun` over the folder (built once; it caches
        scenarios, surrogates and measurements)."""
        with self._lock:
            if self._run is None:
                self._run = StudyRun(self.study, self.folder, Progress())
            return self._run

    @property
    def problem(self):
        """The calibration problem (:meth:`StudyRun.calibration_problem`, with uploaded
        measurements in place), built on first use.

        Raises
        ------
        RequestError
            409 while the offline stage has not run.
        """
        problem = self._problem
        if problem is not None:
            return problem
        if not self.ready:
            raise RequestError(f"the surrogates of study {self.study.name!r} are not in {self.folder} yet: run the "
                               "study first (a study job from the page, or podkrig run)", None, 409)
        run = self.study_run()
        with self._lock:
            if self._problem is None:
                self._problem = self._with_uploads(run.calibration_problem())
            return self._problem

    def _with_uploads(self, problem):
        """``problem`` (built from the folder) with this session's uploads read and checked again
        against it; an upload it refuses is dropped and remembered with the reason."""
        for name, upload in list(self._uploads.items()):
            try:
                problem = self._replaced(problem, self.test(name), upload)
            except RequestError as e:
                logger.warning("the upload %s of test %r is dropped: %s", upload.name, name, e)
                del self._uploads[name]
                self._dropped[name] = (upload.name, f"{upload.name} was dropped when the study's surrogates were "
                                                    f"rebuilt: {e}")
        return problem

    def warm(self):
        """Build what the first requests need before the server answers, so the page is ready as
        soon as the address is printed: the problem, the study's calibration read back, one
        prediction, and what a first calibration needs besides (each test's FE scenario for the FE
        check, the validation models' surrogates) — about 2 s of CPU on the demo."""
        self.calibration()
        if not self.ready:
            return
        self.predict({})
        run = self.study_run()
        for t in self.tests:
            run.scenario(t)
        for m in self.study.validation:
            path = f"validation_{m.name}_surrogate.h5"
            if (self.folder / path).is_file():
                run.surrogate(path)

    # -------------------------------------------------------------------------------- parameters

    @property
    def space(self):
        """The joint free parameters of the tests (union in order of first appearance, the order
        of :class:`~podkrig.online.joint.JointProblem`)."""
        params = {}
        for t in self.tests:
            for p in t.space.parameters:
                params.setdefault(p.name, p)
        return ParameterSpace(tuple(params.values()))

    def calibration(self):
        """The study's calibration (:class:`~podkrig.online.calibrate.CalibrationResult` of its
        stage manifest and ``region.npz``), or None when it has not run; read again only when the
        manifest changed (a study job wrote a new one)."""
        path = self.folder / "stages" / "calibration.json"
        try:
            stamp = path.stat().st_mtime_ns
        except OSError:
            return None
        if self._calibration is None or self._calibration[0] != stamp:
            self._calibration = (stamp, self._read_calibration(path))
        return self._calibration[1]

    def _read_calibration(self, path):
        manifest = read_manifest(path)
        if manifest is None:
            return None
        try:
            return calibration_result(self.folder, manifest["result"])
        except (KeyError, ValueError, OSError) as e:
            logger.warning("the calibration in %s cannot be read back (%s); shown as not run", self.folder, e)
            return None

    def values(self, given=None, *, field="values"):
        """Every free parameter's value, ``(n_free,)`` physical, from ``given`` (name → number);
        a parameter not given takes its default (:meth:`defaults`).

        Raises
        ------
        RequestError
            An unknown name, a value that is not a finite number, or one outside its search range
            (naming the parameter, the value and the bounds with the unit).
        """
        space = self.space
        if given is None:
            given = {}
        if not isinstance(given, dict):
            raise RequestError(f"{field} must be an object name → value; got {type(given).__name__}", field)
        unknown = [n for n in given if n not in space.names]
        if unknown:
            raise RequestError(f"unknown parameter {unknown[0]!r}; the free parameters are {list(space.names)}",
                               unknown[0])
        defaults = self.defaults()
        x = np.empty(space.n_params)
        for j, p in enumerate(space.parameters):
            v = given.get(p.name, defaults[p.name])
            if not is_number(v):
                raise RequestError(f"{p.name} must be a finite number ({p.unit}); got {reprlib.repr(v)}", p.name)
            if not p.lower <= v <= p.upper:
                raise RequestError(f"{p.name} = {v:g} {p.unit} lies outside its search range "
                                   f"[{p.lower:g}, {p.upper:g}] {p.unit}", p.name)
            x[j] = v
        return x

    def defaults(self):
        """The value each free parameter starts from: the study's best fit, else the box's midpoint
        (in the unit cube: the geometric mean of the bounds of a log-scaled parameter)."""
        space = self.space
        mid = dict(zip(space.names, space.from_unit(np.full((1, space.n_params), 0.5))[0].tolist()))
        best = self._best()
        return {n: best.get(n, mid[n]) for n in space.names}

    def _best(self):
        cal = self.calibration()
        return {} if cal is None else {n: float(v) for n, v in cal.inversion.free_parameters.items()}

    # -------------------------------------------------------------------------------- the views

    def parameters_view(self):
        """The free parameters for the page: name, unit, bounds, scale, value, best and the
        study's equivalence interval (None before a calibration)."""
        cal = self.calibration()
        best = self._best()
        intervals = {} if cal is None else cal.region.intervals
        defaults = self.defaults()
        return [{"name": p.name, "unit": p.unit, "lower": p.lower, "upper": p.upper, "scale": p.scale,
                 "value": defaults[p.name], "best": best.get(p.name),
                 "interval": [float(v) for v in intervals[p.name]] if p.name in intervals else None}
                for p in self.space.parameters]

    def tests_view(self):
        """Each test for the page: name, scenario, control variable and unit, load levels, the
        measured sensors with their units and the free parameters it depends on."""
        out = []
        per_test = problems_by_test(self.problem) if self.ready else {}
        for t in self.tests:
            p = per_test.get(t.name)
            if p is not None:
                model, meas = p.model, p.measurement
                unit, levels = model.load_unit, model.load_levels
                sensors = [{"name": s, "unit": u} for s, u in zip(meas.sensor_names, meas.sensor_units)]
            else:  # before the offline stage: the scenario tells its sensors and loads
                sc = self.study_run().scenario(t)
                unit, levels = sc.load_unit, sc.load_levels
                units = sc.sensor_units
                sensors = [{"name": s, "unit": units.get(s, "mm") if isinstance(units, dict) else "mm"}
                           for s in sc.sensor_names]
            out.append({"name": t.name, "scenario": t.spec.scenario, "control": CONTROLS.get(unit, "load"),
                        "load_unit": unit, "load_levels": np.asarray(levels, dtype=float).tolist(),
                        "sensors": sensors, "free": list(t.space.names)})
        return out

    def study_view(self, calibration=None):
        """``GET /api/study``: the study, its state, parameters, tests, last calibration (the view
        of :func:`podkrig.serve.runs.result_view`, given by the caller), noise and GA settings and
        the session's uploads (:meth:`uploads_view`)."""
        settings = self.study.calibration_settings()
        return {
            "name": self.study.name, "folder": str(self.folder), "study_file": str(self.study.path),
            "state": self.state, "parameters": self.parameters_view(), "tests": self.tests_view(),
            "calibration": calibration,
            "noise": {t.name or "": dataclasses.asdict(t.measurement.noise) for t in self.tests},
            "inversion": dataclasses.asdict(settings.inversion),
            "uploads": self.uploads_view(),  # after tests_view: the problem (re)built, its uploads checked
        }

    # -------------------------------------------------------------------------------- predict

    def predict(self, values=None):
        """``POST /api/predict``: the surrogate at the free values ``values`` (name → number,
        physical; missing ones at :meth:`defaults`) against every test's measurement.

        Returns
        -------
        dict
            ``omega`` (thesis eq. 2.13), ``chi2``, ``dof``, ``chi2_dof`` of all tests, and per test
            its ``chi2_dof`` and one series per measured sensor: ``x`` (the measured control
            levels, ``x_unit``), ``measured``, the surrogate ``mean`` and ``std`` and the
            standardized ``residual`` (d − g)/σ_total (None where a reading is missing).
        """
        problem = self.problem
        x = self.values(values)
        parts = problem.parts(x) or {None: (problem, x)}  # one test: the problem itself
        tests, chi2_all, omega = [], 0.0, 0.0
        for name, (p, xt) in parts.items():
            misfit, meas = p.misfit, p.measurement
            mean, std = misfit.predict(xt[None])  # one surrogate call: χ² and ω from the same prediction
            w = misfit.whiten(mean - meas.data, std)  # L_D⁻¹ (g − d), rigid-body motions projected out
            chi2 = float(np.sum(w**2))
            prior = misfit.prior_residuals(xt[None])
            omega += 0.5 * chi2 + 0.5 * float(np.sum(prior**2))  # thesis eq. (2.13)
            chi2_all += chi2
            mean = mean[0]
            sd = np.zeros_like(mean) if std is None else std[0]
            noise = misfit.noise_std
            if p.model_form_error is not None:
                noise = np.sqrt(noise**2 + p.model_form_error.std**2)
            total = np.sqrt(noise**2 + sd**2)  # the diagonal of C_D
            grid_mean, grid_std, grid_res = meas.grid(mean), meas.grid(sd), meas.grid((meas.data - mean) / total)
            dof = p.n_obs - p.n_removed - p.n_free
            levels, unit = json_safe(meas.load_levels), p.model.load_unit
            series = [{"sensor": s, "unit": u, "x": levels, "x_unit": unit, "measured": json_safe(meas.values[:, j]),
                       "mean": json_safe(grid_mean[:, j]), "std": json_safe(grid_std[:, j]),
                       "residual": json_safe(grid_res[:, j])}
                      for j, (s, u) in enumerate(zip(meas.sensor_names, meas.sensor_units))]
            tests.append({"name": name, "chi2": chi2, "dof": dof, "chi2_dof": chi2 / max(dof, 1), "series": series})
        dof = problem.n_obs - problem.n_removed - problem.n_free
        return {"omega": omega, "chi2": chi2_all, "dof": dof, "chi2_dof": chi2_all / max(dof, 1), "tests": tests}

    # -------------------------------------------------------------------------------- files

    def file(self, relative):
        """The file ``relative`` (a URL path) under the served folder, resolved (symbolic links
        followed).

        Raises
        ------
        RequestError
            403 for a path that resolves outside the folder (``..``, an absolute path, a link out)
            or names a hidden file (the folder's lock, temporary files); 404 for no such file.
        """
        if "\x00" in relative:
            raise RequestError(f"{relative!r} is not a path inside the served folder", "path", 403)
        parts = Path(relative).parts
        if Path(relative).is_absolute() or ".." in parts or any(p.startswith(".") for p in parts):
            raise RequestError(f"{relative!r} is not a path inside the served folder", "path", 403)
        path = (self.folder / relative).resolve()
        if not path.is_relative_to(self.folder):
            raise RequestError(f"{relative!r} leads outside the served folder", "path", 403)
        if not path.is_file():
            raise RequestError(f"no file {relative!r} in the served folder", "path", 404)
        return path

    # -------------------------------------------------------------------------------- uploads

    def test(self, name):
        """The calibration test called ``name`` ('' or None for the one test of a study without
        ``[[test]]`` tables).

        Raises
        ------
        RequestError
            404 naming the tests.
        """
        name = name or None
        for t in self.tests:
            if t.name == name:
                return t
        raise RequestError(f"no test {name!r}; the tests are {[t.name or '' for t in self.tests]}", "test", 404)

    def replace_measurement(self, test_name, data, name):
        """Read an uploaded measurement log (``data``: its bytes; ``name``: the user's file name,
        whose suffix ``.csv``, ``.tsv``, ``.txt`` or ``.xlsx`` picks the reader) for test
        ``test_name`` with the study's import settings, check it as the study's measurement stage
        does, and use it for that test in this session.

        Returns
        -------
        dict
            The test's entry of :meth:`tests_view`.

        Raises
        ------
        RequestError
            The reader's or the check's message naming the user's file (422), an unknown test
            (404), a study not ready (409).
        """
        t = self.test(test_name)
        problem = self.problem  # 409 before the offline stage
        name = upload_name(name)
        if self._tmp is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="podkrig-serve-")
        fd, path = tempfile.mkstemp(suffix=Path(name).suffix.lower(), dir=self._tmp.name)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        upload = Upload(Path(path), name)
        try:
            new = self._replaced(problem, t, upload)
        except RequestError:
            upload.path.unlink(missing_ok=True)
            raise
        with self._lock:
            if self._problem is problem:
                self._problem = new
            else:  # rebuilt meanwhile (a job ended): the upload goes into the new problem
                self._problem = self._replaced(self._problem, t, upload) if self._problem is not None else None
            old = self._uploads.get(t.name)
            self._uploads[t.name] = upload
            self._dropped.pop(t.name, None)
        if old is not None:
            old.path.unlink(missing_ok=True)
        return next(v for v in self.tests_view() if v["name"] == t.name)

    def _replaced(self, problem, t, upload):
        """``problem`` with test ``t``'s measurement read from ``upload`` (its source the user's
        file name) and checked against that test's surrogate.

        Raises
        ------
        RequestError
            422 with the reader's or the check's message, naming ``upload.name``.
        """
        path = str(upload.path)
        one = problems_by_test(problem)[t.name]
        model = one.model
        try:
            test = dataclasses.replace(t, measurement=dataclasses.replace(t.measurement, file=upload.path))
            meas, noise = read_study_measurement(test, model.sensor_names, model.load_levels, model.load_unit,
                                                 model.load_response, model.sensor_units)
            meas = dataclasses.replace(meas, source=upload.name)  # what later messages name (diagnosis, findings)
            # the readings against the surrogate's training runs (a unit or sign error), as the study
            # compares its log with its probe and training runs
            check_readings(meas, noise, model.sensor_names, model.load_levels, model.load_response,
                           surrogate_training_outputs(model.surrogate), runs="surrogate")
            new = dataclasses.replace(one, measurement=meas, noise=noise)  # refuses data the model cannot give
            check_dof(new.n_obs, new.free, upload.name, new.n_removed)
        except MeasurementCheckError as e:
            raise RequestError(refusal(e, "study").replace(path, upload.name), "measurement") from None
        except ValueError as e:
            raise RequestError(str(e).replace(path, upload.name), "measurement") from None
        if isinstance(problem, JointProblem):
            return JointProblem({**problem.problems, t.name: new})
        return new

    def close(self):
        """Remove the session's temporary files (uploaded logs)."""
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None


__all__ = ["CONTROLS", "RequestError", "Session", "Upload", "check_keys", "is_number", "json_safe", "study_file_of", "upload_name"]
