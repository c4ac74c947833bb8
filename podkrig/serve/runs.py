"""Calibration runs of ``podkrig serve``: the calibration stage in a worker thread, and its history.

A run calls :func:`podkrig.online.calibrate.calibrate` — the one calibration stage every front door
calls — on the session's problem with the parameters frozen on the page fixed at their values, the
noise model and GA settings of the page validated by the library's own settings classes
(:class:`~podkrig.online.settings.NoiseSettings`, :class:`~podkrig.online.settings.InversionSettings`);
the model diagnosis, when asked, is that of the same calibration (the frozen parameters held at
their values). Runs execute one at a time in a worker thread; at most :data:`MAX_PENDING_RUNS`
wait or run at once (a further one is refused with 409, so a script cannot queue hours of work).
:func:`result_view` turns a :class:`~podkrig.online.calibrate.CalibrationResult` into what the page
shows: the parameters with their intervals and identifiability in words, the region of equivalence
(at most :data:`MAX_REGION_MEMBERS` members for the pair plot), the FE check and the findings.
"""

import dataclasses
import itertools
import logging
import re
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from fe.scenarios import build_scenario
from podkrig.config import make_settings
from podkrig.diagnosis import diagnose
from podkrig.online.calibrate import calibrate, problems_by_test
from podkrig.online.joint import JointProblem
from podkrig.online.propagation import RVCModel
from podkrig.online.settings import InversionSettings, NoiseSettings
from podkrig.reports.findings import identifiability_text, words
from podkrig.serve.session import RequestError, check_keys
from podkrig.study.cache import now

logger = logging.getLogger(__name__)

#: members of the region of equivalence sent to the page (a deterministic subset of a larger region)
MAX_REGION_MEMBERS = 2000
#: calibrations running or waiting at once (the page runs one at a time; two pages, a few)
MAX_PENDING_RUNS = 4
#: the keys of a ``POST /api/calibrate`` body
CALIBRATE_KEYS = ("frozen", "noise", "inversion", "diagnosis")


def region_members(region, limit=MAX_REGION_MEMBERS):
    """``(samples, omega)`` of a region, at most ``limit`` members (a seeded subset, in order)."""
    samples, omega = region.samples, region.omega
    if samples is None:
        return np.empty((0, len(region.names))), np.empty(0)
    if len(samples) > limit:
        keep = np.sort(np.random.default_rng(0).choice(len(samples), limit, replace=False))
        samples, omega = samples[keep], omega[keep]
    return samples, omega


def result_view(result, diagnosis=None):
    """The page's view of a :class:`~podkrig.online.calibrate.CalibrationResult`: ``parameters``
    (value, interval, identified, the verdict in words), ``chi2_dof``, ``dof``, ``seconds``,
    ``n_fe_runs``, ``region`` (names, units, members, their ω and the best fit), ``fe_check`` (one
    entry per test checked), ``findings`` (code, level and message with its remedy) and
    ``diagnosis`` (per test, a diagnosis result's dict with ``held``: the parameters it held at the
    page's values; or None)."""
    inv, region = result.inversion, result.region
    verdicts = region.identifiability
    parameters = []
    for name, unit, value in zip(inv.free, inv.units, inv.x):
        interval = region.intervals.get(name)
        verdict = verdicts.get(name)
        parameters.append({
            "name": name, "unit": unit, "value": float(value),
            "interval": None if interval is None else [float(v) for v in interval],
            "identified": None if verdict is None else bool(verdict["identifiable"]),
            "words": "" if verdict is None or interval is None else identifiability_text(name, interval, unit, verdict),
        })
    samples, omega = region_members(region)
    checks = []
    for test, one in result.tests.items():
        fe = one.fe_check
        if fe is None:
            continue
        d = fe.to_dict()
        units = list((d.get("max_abs_diff_by_unit") or {"mm": None}))
        checks.append({"test": test, "max_diff": d["max_abs_diff"], "unit": units[0] if len(units) == 1 else "mm",
                       **d})
    return {
        "parameters": parameters, "chi2": float(inv.chi2), "chi2_dof": float(inv.chi2_dof), "dof": int(inv.dof),
        "seconds": float(result.seconds), "n_fe_runs": int(result.n_fe_runs),
        "region": {"names": list(region.names), "units": list(region.units), "samples": samples.tolist(),
                   "omega": omega.tolist(), "n_members": int(len(region.samples) if region.samples is not None else 0),
                   "confidence": float(region.confidence), "best": [float(v) for v in inv.x]},
        "fe_check": checks,
        "findings": [{"code": f.code, "level": f.level, "message": f"{f.message} {f.remedy}".strip()}
                     for f in words(result.findings, "study")],
        "diagnosis": diagnosis,
    }


def settings_from(cls, values, field):
    """Settings ``cls`` from a request's object ``values`` (None: the defaults), refused with the
    settings' own message (:func:`podkrig.config.make_settings`) and the key it names
    (``field.KEY``).

    Raises
    ------
    RequestError
        Not an object, an unknown key (naming the allowed ones), a value the settings refuse.
    """
    if values is None:
        values = {}
    if not isinstance(values, dict):
        raise RequestError(f"{field} must be an object; got {type(values).__name__}", field)
    keys = [f.name for f in dataclasses.fields(cls)]
    unknown = [k for k in values if k not in keys]
    if unknown:
        raise RequestError(f"{field}: unknown key {unknown[0]!r}; the keys are {', '.join(keys)}",
                           f"{field}.{unknown[0]}")
    try:
        return make_settings(cls, values)
    except ValueError as e:
        message = str(e)
        key = re.match(r"[A-Za-z_]*", message).group(0)
        if key in keys:
            where = f"{field}.{key}"
        else:  # a rule tying the fields together, named by none of them
            where, message = field, f"{field}{message}" if message.startswith(":") else f"{field}: {message}"
        raise RequestError(message, where) from None


@dataclasses.dataclass(eq=False)
class Run:
    """One calibration of the session: its request, its state and its result."""

    id: str
    frozen: dict
    settings: dict
    started: str
    t0: float
    status: str = "running"
    progress: dict = dataclasses.field(default_factory=lambda: {"step": "queued", "done": 0, "total": 5})
    seconds: float | None = None
    error: str | None = None
    result: object = None
    view: dict | None = None

    def row(self):
        """The run's line of ``GET /api/runs``."""
        return {"id": self.id, "status": self.status, "started": self.started, "seconds": self.seconds,
                "frozen": self.frozen, "chi2_dof": None if self.view is None else self.view["chi2_dof"]}

    def to_dict(self):
        """``GET /api/runs/{id}``."""
        return {"id": self.id, "status": self.status, "progress": dict(self.progress), "frozen": self.frozen,
                "settings": self.settings, "started": self.started, "seconds": self.seconds, "error": self.error,
                "result": self.view}


class Runs:
    """The calibration runs of a session, in one worker thread (a run waits for the one before):
    :meth:`start`, :meth:`get`, :meth:`rows`, :meth:`summary`."""

    def __init__(self, session):
        self.session = session
        self._runs = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="podkrig-calibrate")

    def prepare(self, body):
        """The problem with the ``frozen`` parameters fixed and the ``noise`` of each test, and the
        calibration settings with the ``inversion`` of the request (the study's otherwise), all
        checked here: ``(problem, settings, frozen, diagnosis, noise)`` (``noise``: each test's
        noise settings as a dict, the page's or the study's).

        Raises
        ------
        RequestError
            An unknown or out-of-range frozen parameter, every parameter frozen, settings the
            library refuses (its message and the key), an unknown test.
        """
        check_keys(body, CALIBRATE_KEYS, "calibrate")
        session = self.session
        problem = session.problem  # 409 before the offline stage
        frozen = body.get("frozen") or {}
        if not isinstance(frozen, dict):
            raise RequestError(f"frozen must be an object name → value; got {type(frozen).__name__}", "frozen")
        names = list(session.space.names)
        x = session.values({**frozen}, field="frozen")
        frozen = {n: float(x[names.index(n)]) for n in frozen}
        if len(frozen) == len(names):
            raise RequestError(f"every parameter is frozen ({', '.join(names)}): free at least one to calibrate",
                               "frozen")
        noise = body.get("noise") or {}
        if not isinstance(noise, dict):
            raise RequestError(f"noise must be an object test name → noise settings; got {type(noise).__name__}",
                               "noise")
        tests = {}
        for key, values in noise.items():
            test = session.test(key) if key in {t.name or "" for t in session.tests} else None
            if test is None:
                raise RequestError(f"noise: no test {key!r}; the tests are {[t.name or '' for t in session.tests]}",
                                   f"noise.{key}")
            tests[test.name] = settings_from(NoiseSettings, values, f"noise.{key}" if key else "noise")
        inversion = settings_from(InversionSettings, body.get("inversion"), "inversion") \
            if body.get("inversion") is not None else session.study.calibration_settings().inversion
        diagnosis = body.get("diagnosis", False)
        if not isinstance(diagnosis, bool):
            raise RequestError(f"diagnosis must be true or false; got {diagnosis!r}", "diagnosis")
        parts = {}
        for name, p in problems_by_test(problem).items():
            changes = {}
            own = [n for n in frozen if n in p.free]
            if own:
                changes.update(free=tuple(n for n in p.free if n not in own),
                               fixed={**p.fixed, **{n: frozen[n] for n in own}})
            if name in tests:
                s = tests[name]
                meas = p.measurement
                unknown = s.unknown_sensors(p.model.sensor_names)
                if unknown:
                    key, sensor = unknown[0]
                    raise RequestError(f"{key}: {sensor!r} is not a sensor of this test; its sensors: "
                                       f"{', '.join(p.model.sensor_names)}", f"noise.{name or ''}.{key}")
                changes["noise"] = s.noise_model(meas.sensor_names, meas.sensor_units)
            try:
                parts[name] = dataclasses.replace(p, **changes) if changes else p
            except ValueError as e:
                raise RequestError(str(e) + ("" if name is None else f" (test {name!r})"), "frozen") from None
        problem = JointProblem(parts) if isinstance(problem, JointProblem) else parts[None]
        settings = dataclasses.replace(session.study.calibration_settings(), inversion=inversion)
        noise_view = {t.name or "": dataclasses.asdict(tests.get(t.name, t.measurement.noise)) for t in session.tests}
        return problem, settings, frozen, diagnosis, noise_view

    def start(self, body):
        """``POST /api/calibrate``: check the request (:meth:`prepare`) and queue the run; its id.

        Raises
        ------
        RequestError
            As :meth:`prepare`; 409 when :data:`MAX_PENDING_RUNS` runs are running or waiting.
        """
        problem, settings, frozen, diagnosis, noise = self.prepare(body)
        with self._lock:
            pending = [r.id for r in self._runs.values() if r.status == "running"]
            if len(pending) >= MAX_PENDING_RUNS:
                raise RequestError(f"{len(pending)} calibrations are running or waiting ({', '.join(pending)}): "
                                   f"start another when run {pending[0]} is done", None, 409)
            rid = f"r{next(self._ids)}"
            run = Run(rid, frozen, {"calibration": dataclasses.asdict(settings), "noise": noise,
                                    "diagnosis": diagnosis}, now(), time.perf_counter())
            self._runs[rid] = run
        self._pool.submit(self._calibrate, run, problem, settings, diagnosis)
        return rid

    def _calibrate(self, run, problem, settings, diagnosis):
        session = self.session
        study = session.study
        tests = {t.name: t for t in study.calibration_tests}
        study_run = session.study_run()

        def progress(step, done, total):
            run.progress = {"step": step, "done": done, "total": total}

        try:
            run.t0 = time.perf_counter()
            validation = {m.name: RVCModel(study_run.surrogate(f"validation_{m.name}_surrogate.h5"), m.outputs,
                                           scenario=build_scenario(m.spec) if m.fe_runs else None, fe_runs=m.fe_runs,
                                           quantiles=m.quantiles)
                          for m in study.validation}
            result = calibrate(problem, settings, scenarios=lambda name: study_run.scenario(tests[name]),
                               validation=validation, check_measurement=bool(session.uploaded),
                               range_check=bool(session.uploaded), progress=progress)
            found = None
            if diagnosis:
                found = {}
                for name, p in problems_by_test(problem).items():
                    t = tests[name]
                    run.progress = {"step": f"diagnosis{'' if name is None else ' ' + name}", "done": 0, "total": 1}
                    # the diagnosis of this calibration: the frozen parameters held at their values
                    d = diagnose(study_run.scenario(t), p.measurement, p.noise, p.free_space, study.diagnosis,
                                 fixed={**t.fixed, **p.fixed}, surrogate=p.model.surrogate,
                                 rigid_body=t.measurement.rigid_body,
                                 rigid_groups=t.measurement.rigid_groups, range_check=False,
                                 progress=lambda stage, done, total: progress(f"diagnosis: {stage}", done, total))
                    held = {n: float(d.base.values[n]) for n in p.fixed}  # as the diagnosis's FE fit ran them
                    found[name or ""] = {**d.to_dict(), "held": held}
            run.result = result
            run.view = result_view(result, found)
            run.status = "done"
        except Exception as e:  # noqa: BLE001 - the page shows why the calibration failed
            logger.warning("calibration %s failed: %s", run.id, e)
            run.error = str(e) if isinstance(e, ValueError) else f"{type(e).__name__}: {e}"
            run.status = "failed"
        finally:
            run.seconds = time.perf_counter() - run.t0

    def get(self, rid):
        """The run ``rid``.

        Raises
        ------
        RequestError
            404 naming the runs of the session.
        """
        run = self._runs.get(rid)
        if run is None:
            raise RequestError(f"no run {rid!r} in this session; runs: {list(self._runs) or 'none yet'}", "run", 404)
        return run

    def rows(self):
        """``GET /api/runs``: every run of the session, oldest first."""
        return [r.row() for r in self._runs.values()]

    def summary(self, rid):
        """``GET /api/runs/{id}/summary.json``: the run's :meth:`CalibrationResult.to_dict` with its
        warnings in words, as ``podkrig invert --format json`` writes it.

        Raises
        ------
        RequestError
            404 for an unknown run; 409 for a run not done.
        """
        run = self.get(rid)
        if run.status != "done":
            raise RequestError(f"run {rid} is {run.status}: its summary exists once it is done", "run", 409)
        result = run.result
        return {**result.to_dict(), "warnings": [t.to_dict() for t in words(result.findings, "cli")]}

    def close(self):
        self._pool.shutdown(wait=False, cancel_futures=True)


__all__ = ["CALIBRATE_KEYS", "MAX_PENDING_RUNS", "MAX_REGION_MEMBERS", "Run", "Runs", "region_members",
           "result_view", "settings_from"]
