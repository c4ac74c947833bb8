"""Run a study stage by stage, caching each stage by a hash of its inputs.

Stages, in order (FE work first, then the online stages)::

    offline                  training snapshots (FE)                  train.h5
    held_out                 held-out snapshots (FE)                  held_out.h5
    validation_model.NAME    snapshots and surrogate of a validation  validation_NAME.h5, validation_NAME_surrogate.h5
                             scenario (FE), one stage per model
    surrogate                POD + kriging fit                        surrogate.h5, report/energy.png, report/modes.png
    held_out_validation      surrogate errors on the held-out runs    report/predicted_vs_fe.png
    inversion                GA + polish, FE check at the optimum     report/fit.png, residuals.png, ga_*.png
    region                   region of equivalence, identifiability   region.npz, report/region.png
    rvc                      response variability over the region     report/rvc.png
    diagnosis                model diagnosis ([diagnosis] enabled)    report/diagnosis/ (its own page)

Each stage writes ``DIR/stages/STAGE.json``, a manifest with the hash of its inputs (settings,
and the SHA-256 of the files it reads: upstream outputs, the measurement CSV), the SHA-256 of
every file it wrote, its JSON results and its wall time. A stage whose manifest has the same
input hash and whose files are unchanged is *cached*: it is not run again. So a rerun with
nothing changed does no FE work, and a new measurement file reruns only the online stages
(inversion, region, RVC, diagnosis). An interrupted FE stage resumes from its store (finished rows are kept); a
store written for another design is rebuilt.

Finally the report ``DIR/report/index.html`` is written from the manifests (always; it is cheap)
and ``DIR/summary.json`` gathers every stage's results.
"""

import dataclasses
import datetime
import hashlib
import json
import logging
import os
import shutil
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from podkrig import __version__
from podkrig.exceptions import StoreError, StoreInUseError

logger = logging.getLogger(__name__)

MANIFEST_VERSION = 1


class Progress:
    """Callbacks of :func:`run_study` (the default does nothing; the CLI draws progress bars)."""

    def stage_started(self, name, title, total=None):
        """A stage starts; ``total`` FE runs for FE stages (None for others)."""

    def advance(self, completed, total):
        """``completed`` of ``total`` FE runs of the running stage are done."""

    def stage_finished(self, record):
        """A stage finished or was found cached (:class:`StageRecord`)."""


@dataclass(frozen=True)
class StageRecord:
    """What happened to one stage in a run.

    Attributes
    ----------
    name, title : str
    cached : bool
        True when the stage's previous results were reused.
    seconds : float
        Wall time of this run of the stage, s (about 0 when cached).
    fe_runs : int
        FE runs done by this run of the stage (0 when cached).
    manifest : dict
        The stage manifest (``result`` holds its numbers).
    """

    name: str
    title: str
    cached: bool
    seconds: float
    fe_runs: int
    manifest: dict

    @property
    def result(self):
        return self.manifest["result"]


@dataclass(frozen=True)
class StudyResult:
    """Outcome of :func:`run_study`.

    Attributes
    ----------
    study : Study
    out : Path
        The output folder.
    stages : tuple of StageRecord
        In the order they ran.
    warnings : list of dict
        Every warning of the study: ``{"section", "what", "what_to_do"}`` in plain words
        (``section`` is the report section it belongs to).
    report : Path
        ``out/report/index.html``.
    seconds : float
        Wall time of the run, s.
    """

    study: object
    out: Path
    stages: tuple
    warnings: list
    report: Path
    seconds: float

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


def _jsonable(v):
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.integer, np.floating, np.bool_)):
        return v.item()
    if isinstance(v, Path):
        return str(v)
    raise TypeError(f"not JSON-able: {type(v).__name__}")


def input_hash(name, inputs):
    """SHA-256 of a stage's name, the package version and its inputs (canonical JSON)."""
    text = json.dumps({"stage": name, "podkrig": __version__, "manifest": MANIFEST_VERSION, "inputs": inputs},
                      sort_keys=True, default=_jsonable)
    return hashlib.sha256(text.encode()).hexdigest()


def file_sha256(path):
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _now():
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


class _Run:
    """State of one :func:`run_study` call: the study, the output folder and the stage records."""

    def __init__(self, study, out, progress):
        self.study = study
        self.out = Path(out)
        self.figures = self.out / "report"
        self.progress = progress
        self.records = []
        self._scenario = None

    def scenario(self):
        """The calibration scenario, built once (only when a stage needs the FE model)."""
        if self._scenario is None:
            from fe.scenarios import build_scenario

            self._scenario = build_scenario(self.study.spec)
        return self._scenario

    def outputs(self, name):
        """Output files (relative paths) → SHA-256 of a finished stage."""
        return self.manifest(name)["outputs"]

    def manifest(self, name):
        for record in self.records:
            if record.name == name:
                return record.manifest
        raise KeyError(name)

    def stage(self, name, title, inputs, compute, total=None):
        """Run ``compute() -> (result, outputs, fe_runs)`` unless the stage is cached.

        ``result`` is a JSON-able dict, ``outputs`` the files written (paths relative to the
        output folder). Returns the stage manifest.
        """
        path = self.out / "stages" / f"{name}.json"
        digest = input_hash(name, inputs)
        manifest = _read_manifest(path)
        if manifest is not None and manifest.get("input_hash") == digest and self._unchanged(manifest["outputs"]):
            record = StageRecord(name, title, True, 0.0, 0, manifest)
        else:
            self.progress.stage_started(name, title, total)
            t0 = time.perf_counter()
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                result, outputs, fe_runs = compute()
            seconds = time.perf_counter() - t0
            # warnings of the numerics (e.g. a Sobol' size that is not a power of two) become notes in the report
            notes = sorted({str(w.message) for w in caught if issubclass(w.category, (UserWarning, RuntimeWarning))})
            result = dict(result, notes=result.get("notes", []) + notes)
            manifest = {
                "stage": name, "title": title, "input_hash": digest, "inputs": inputs,
                "outputs": {str(p): file_sha256(self.out / p) for p in outputs},
                "result": result, "seconds": seconds, "fe_runs": fe_runs, "finished": _now(),
                "podkrig": __version__,
            }
            _write_json(path, manifest)
            record = StageRecord(name, title, False, seconds, fe_runs, manifest)
        self.records.append(record)
        self.progress.stage_finished(record)
        return manifest

    def _unchanged(self, outputs):
        return all((self.out / p).is_file() and file_sha256(self.out / p) == sha for p, sha in outputs.items())


def _read_manifest(path):
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _write_json(path, data):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True, default=_jsonable, ensure_ascii=False), encoding="utf-8")
    tmp.replace(path)


# ---------------------------------------------------------------------------------------------
# the stages


def run_study(study, out, *, progress=None):
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

    Returns
    -------
    StudyResult

    Raises
    ------
    ValueError, PodkrigError, fe.FEError
        A measurement file that does not match the scenario, a store that cannot be used, too
        few finished FE runs for a surrogate, ...; finished stages stay cached.
    """
    t0 = time.perf_counter()
    run = _Run(study, out, progress or Progress())
    run.out.mkdir(parents=True, exist_ok=True)
    run.figures.mkdir(parents=True, exist_ok=True)
    _offline(run, "offline", "Training snapshots (FE)", "train.h5", study.train)
    _offline(run, "held_out", "Held-out snapshots (FE)", "held_out.h5", study.held_out)
    for model in study.validation:
        _validation_model(run, model)
    _surrogate(run)
    _held_out_validation(run)
    _inversion(run)
    _region(run)
    _rvc(run)
    if study.diagnosis.enabled:
        _diagnosis(run)
    found = _warnings(run)
    from podkrig.reports.study import write_study_report

    report = write_study_report(run.figures / "index.html", study, run.records, found)
    _write_json(run.out / "summary.json", {
        "study": str(study.path), "name": study.name, "podkrig": __version__, "finished": _now(),
        "stages": {r.name: {"cached": r.cached, "seconds": r.seconds, "fe_runs": r.fe_runs, **r.result}
                   for r in run.records},
        "warnings": found,
    })
    return StudyResult(study, run.out, tuple(run.records), found, report, time.perf_counter() - t0)


def _run_store(run, path, spec, space, design):
    """Fill the store at ``path``: resume it, or build a new one next to a store that cannot be used
    (written for another design, damaged), which is kept under a timestamped name — never deleted."""
    from podkrig.offline.runner import prepare_store, run_snapshots
    from podkrig.offline.store import move_aside

    kwargs = {"n": design.n, "seed": design.seed, "sampling": design.method}
    notes = []
    try:
        prepare_store(path, spec, space, **kwargs)
    except StoreInUseError:  # another run is filling it: never touch it
        raise
    except StoreError as e:
        if not path.exists():
            raise
        kept = move_aside(path)
        notes.append(f"{path.name} could not be used ({e}); it was kept as {kept.name} and a new store was built")
        logger.warning("%s could not be used (%s); kept it as %s and building a new store", path, e, kept)
    summary = run_snapshots(path, spec, space, workers=run.study.workers, scheduler=run.study.scheduler,
                            progress=run.progress.advance, **kwargs)
    return summary, notes


def _store_result(path, summary, notes):
    from podkrig.offline.store import SnapshotStore

    with SnapshotStore.open(path) as store:
        wall = store.wall_times()
        failures = [f"row {i}: {e}" for i, e in store.errors().items()][:5] if summary.failed else []
        n_dofs = store.n_dofs
    ran = wall[np.isfinite(wall)]
    return {
        "total": summary.total, "done": summary.done, "failed": summary.failed, "pending": summary.pending,
        "executor": summary.executor, "n_dofs": n_dofs,
        "fe_ms_per_run": float(1000 * ran.mean()) if len(ran) else None,
        "fe_seconds_total": float(ran.sum()),
        "failures": failures, "notes": notes,
    }


def _offline(run, name, title, filename, design):
    study = run.study
    inputs = {"spec": study.spec.to_dict(), "space": study.space.to_dict(), "design": dataclasses.asdict(design)}

    def compute():
        path = run.out / filename
        summary, notes = _run_store(run, path, run.scenario(), study.space, design)
        return _store_result(path, summary, notes), [filename], summary.ran

    run.stage(name, title, inputs, compute, total=design.n)


def _templates(settings):
    """POD and kriging templates of the surrogate settings."""
    from podkrig.surrogate.kriging import OrdinaryKriging
    from podkrig.surrogate.pod import POD
    from podkrig.surrogate.podkriging import DEFAULT_ENERGY

    pod = POD(n_modes=settings.modes) if settings.modes is not None else POD(energy=settings.energy or DEFAULT_ENERGY)
    kriging = OrdinaryKriging(variogram=settings.variogram, beta=settings.beta, criterion=settings.criterion,
                              nugget=settings.nugget)
    return pod, kriging


def _fit(store_path, settings, out_path):
    """Fit and save a surrogate on a store; returns it and its training time (s)."""
    from podkrig.offline.store import SnapshotStore
    from podkrig.surrogate.podkriging import fit_from_store

    pod, kriging = _templates(settings)
    t0 = time.perf_counter()
    with SnapshotStore.open(store_path) as store:
        sur = fit_from_store(store, pod=pod, kriging=kriging)
    seconds = time.perf_counter() - t0
    sur.provenance_["training_seconds"] = seconds
    sur.save(out_path)
    return sur, seconds


def _surrogate_result(sur, seconds):
    return {
        "n_train": len(sur.X_), "n_modes": int(sur.n_modes_),
        "retained_energy": float(sur.pod_.retained_energy_),
        "beta": [float(b) for b in sur.kriging_.beta_],
        "training_seconds": seconds,
    }


def _validation_model(run, model):
    study = run.study
    name = f"validation_model.{model.name}"
    store, surrogate = f"validation_{model.name}.h5", f"validation_{model.name}_surrogate.h5"
    inputs = {"spec": model.spec.to_dict(), "space": study.space.to_dict(), "design": dataclasses.asdict(model.design),
              "surrogate": dataclasses.asdict(study.surrogate)}

    def compute():
        summary, notes = _run_store(run, run.out / store, model.spec, study.space, model.design)
        result = _store_result(run.out / store, summary, notes)
        sur, seconds = _fit(run.out / store, study.surrogate, run.out / surrogate)
        result.update(scenario=model.spec.scenario, surrogate=_surrogate_result(sur, seconds))
        return result, [store, surrogate], summary.ran

    run.stage(name, f"Validation model '{model.name}' (FE + surrogate)", inputs, compute, total=model.design.n)


def _surrogate(run):
    from podkrig.reports import surrogate as figs

    settings = run.study.surrogate
    inputs = {"settings": dataclasses.asdict(settings), "train": run.outputs("offline")}

    def compute():
        sur, seconds = _fit(run.out / "train.h5", settings, run.out / "surrogate.h5")
        prov = sur.provenance_
        figs.plot_energy(sur.pod_, run.figures / "energy.png")
        figs.plot_reading_modes(sur.pod_, prov["sensor_names"], prov["load_levels"], prov["load_unit"],
                                run.figures / "modes.png")
        return _surrogate_result(sur, seconds), ["surrogate.h5", "report/energy.png", "report/modes.png"], 0

    run.stage("surrogate", "Surrogate fit (POD + kriging)", inputs, compute)


def _held_out_validation(run):
    from podkrig.reports import surrogate as figs
    from podkrig.offline.store import SnapshotStore
    from podkrig.surrogate.podkriging import PODKriging, training_data
    from podkrig.surrogate.validation import held_out_errors

    inputs = {"surrogate": run.outputs("surrogate"), "held_out": run.outputs("held_out")}

    def compute():
        sur = PODKriging.load(run.out / "surrogate.h5")
        with SnapshotStore.open(run.out / "held_out.h5") as store:
            X, Y = training_data(store)
        rep = held_out_errors(sur, X, Y)
        figs.plot_predicted_vs_fe(rep, run.figures / "predicted_vs_fe.png")
        result = rep.summary()
        result["rms_abs_error_mm"] = float(np.sqrt(np.mean((rep.Y_pred - rep.Y_true) ** 2)))
        result["max_abs_error_mm"] = float(np.max(np.abs(rep.Y_pred - rep.Y_true)))
        return result, ["report/predicted_vs_fe.png"], 0

    run.stage("held_out_validation", "Surrogate check on held-out runs", inputs, compute)


def _problem(run):
    """The inverse problem of the study on its surrogate: (problem, model)."""
    from podkrig.online.inverse import InverseProblem, SurrogateModel
    from podkrig.online.measurement_csv import read_measurement_csv
    from podkrig.surrogate.podkriging import PODKriging

    model = SurrogateModel(PODKriging.load(run.out / "surrogate.h5"))
    m = run.study.measurement
    data = read_measurement_csv(m.file, model.sensor_names, model.load_levels, model.load_unit)
    return InverseProblem(model, data, m.noise_model()), model


def _online_inputs(run):
    """Inputs shared by the online stages: the surrogate, the measurement file and the noise."""
    m = run.study.measurement
    return {"surrogate": run.outputs("surrogate"), "measurement": file_sha256(m.file),
            "noise": {"rel": m.noise_rel, "abs": m.noise_abs}}


def _inversion(run):
    from podkrig.online.inverse import fe_check, invert
    from podkrig.reports import inverse as figs

    s = run.study.inversion
    inputs = {**_online_inputs(run), "ga": {"seed": s.seed, "population_size": s.population_size,
                                            "generations": s.generations, "n_starts": s.n_starts},
              "fe_check": s.fe_check}

    def compute():
        problem, model = _problem(run)
        result = invert(problem, rng=s.seed, population_size=s.population_size, generations=s.generations,
                        n_starts=s.n_starts)
        fe = fe_check(result, run.scenario()) if s.fe_check else None
        unit = model.load_unit
        figs.plot_fit(result, run.figures / "fit.png", load_unit=unit)
        figs.plot_residuals(result, run.figures / "residuals.png", load_unit=unit)
        figs.plot_ga_history(result.ga, run.figures / "ga_history.png")
        figs.plot_ga_parameters(result.ga, run.figures / "ga_parameters.png")
        space = problem.free_space
        u = space.to_unit(result.x[None])[0]
        meas = problem.measurement
        out = {
            "x": result.x.tolist(),
            "parameters": {n: float(v) for n, v in zip(problem.free, result.x)},
            "units": dict(zip(space.names, space.units)),
            # within 0.5 % of its (scaled) search range from a bound
            "at_bound": [n for n, uj in zip(space.names, u) if uj < 0.005 or uj > 0.995],
            "misfit": result.misfit, "chi2": result.chi2, "dof": result.dof, "chi2_dof": result.chi2_dof,
            "n_evaluations": result.n_evaluations, "seconds": result.seconds,
            "measurement": {"file": str(meas.source), "sensors": list(meas.sensor_names),
                            "load_levels": meas.load_levels.tolist(), "load_unit": unit, "n_obs": problem.n_obs},
            "fe_check": None if fe is None else {k: v for k, v in fe.items() if k != "fe_readings"},
        }
        files = ["report/fit.png", "report/residuals.png", "report/ga_history.png", "report/ga_parameters.png"]
        return out, files, int(fe is not None)

    run.stage("inversion", "Inversion (GA + FE check)", inputs, compute)


def _region(run):
    from podkrig.reports import inverse as figs
    from podkrig.online.uncertainty import likelihood_ratio_region, noise_monte_carlo_region

    s = run.study.inversion
    inv = run.manifest("inversion")
    inputs = {"inversion": inv["input_hash"], "x": inv["result"]["x"], "confidence": s.confidence,
              "method": s.region_method, "samples": s.region_samples, "seed": s.seed}

    def compute():
        problem, _ = _problem(run)
        x = np.asarray(inv["result"]["x"])
        if s.region_method == "noise-mc":
            region = noise_monte_carlo_region(problem, x, confidence=s.confidence, rng=s.seed)
        else:
            region = likelihood_ratio_region(problem, x, confidence=s.confidence, n_samples=s.region_samples,
                                             rng=s.seed)
        np.savez(run.out / "region.npz", samples=region.samples, omega=region.omega)
        figs.plot_region(region, run.figures / "region.png", best=x, space=problem.free_space)
        out = {
            "method": region.method, "confidence": region.confidence, "threshold": region.threshold,
            "intervals": {k: list(v) for k, v in region.intervals.items()},
            "names": list(region.names), "units": list(region.units),
            "n_members": len(region.samples), "n_evaluated": int(region.n_evaluated), "seconds": region.seconds,
            "identifiability": region.identifiability(problem.free_space),
        }
        return out, ["region.npz", "report/region.png"], 0

    run.stage("region", "Region of equivalence", inputs, compute)


def _rvc(run):
    from podkrig.online.inverse import SurrogateModel
    from podkrig.reports import inverse as figs
    from podkrig.surrogate.podkriging import PODKriging
    from podkrig.online.uncertainty import Region, rvc

    study = run.study
    reg = run.manifest("region")
    inputs = {"region": run.outputs("region"), "calibration": run.outputs("surrogate"), "seed": study.inversion.seed,
              "validation": {m.name: {"surrogate": run.outputs(f"validation_model.{m.name}"),
                                      "outputs": list(m.outputs) if m.outputs else None} for m in study.validation}}

    def compute():
        r = reg["result"]
        with np.load(run.out / "region.npz") as f:
            region = Region(r["method"], r["confidence"], f["samples"], f["omega"], r["threshold"],
                            {k: tuple(v) for k, v in r["intervals"].items()}, tuple(r["names"]), tuple(r["units"]),
                            r["n_evaluated"], r["seconds"])
        seed = study.inversion.seed
        results = {"calibration": rvc(region, SurrogateModel(PODKriging.load(run.out / "surrogate.h5")), rng=seed)}
        for m in study.validation:
            model = SurrogateModel(PODKriging.load(run.out / f"validation_{m.name}_surrogate.h5"))
            results[m.name] = rvc(region, model, outputs=list(m.outputs) if m.outputs else None, rng=seed)
        figs.plot_rvc(results, run.figures / "rvc.png")
        out = {"models": {k: {kk: vv for kk, vv in v.items() if kk != "values"} for k, v in results.items()}}
        return out, ["report/rvc.png"], 0

    run.stage("rvc", "Response variability (RVC)", inputs, compute)


def _diagnosis(run):
    from podkrig.diagnosis import diagnose
    from podkrig.reports.diagnosis import write_diagnosis_report

    study = run.study
    inputs = {**_online_inputs(run), "seed": study.diagnosis.seed}

    def compute():
        problem, model = _problem(run)
        folder = run.figures / "diagnosis"
        shutil.rmtree(folder, ignore_errors=True)  # figures of an earlier diagnosis
        result = diagnose(run.scenario(), problem.measurement, problem.noise, study.space, fixed=study.fixed,
                          surrogate=model.surrogate, rng=study.diagnosis.seed,
                          progress=lambda stage, done, total: run.progress.advance(done, total))
        write_diagnosis_report(result, folder, noise_text=study.measurement.noise_text())
        files = sorted(str(p.relative_to(run.out)) for p in folder.iterdir())
        return result.to_dict(), files, result.n_fe_runs

    run.stage("diagnosis", "Model diagnosis", inputs, compute, total=1)


# ---------------------------------------------------------------------------------------------
# warnings in plain words


def _warnings(run):
    """Every warning of the study as ``{"section", "what", "what_to_do"}``, in stage order."""
    study = run.study
    found = []

    def warn(section, what, what_to_do):
        found.append({"section": section, "what": what, "what_to_do": what_to_do})

    for record in run.records:
        r = record.result
        if r.get("failed"):  # the FE stages
            warn("offline",
                 f"{r['failed']} of {r['total']} FE runs failed in stage '{record.title}' ({'; '.join(r['failures'])}).",
                 "the surrogate was trained without them; read the errors (e.g. a parameter range that makes the "
                 "model singular) and narrow the bounds, or inspect the store with 'podkrig snapshots info'.")
    held = run.manifest("held_out_validation")["result"]
    more = "add training snapshots ([sampling] train.n, e.g. double it) or narrow the parameter bounds, and run again."
    m = study.measurement
    if m.noise_rel is not None and held["rel_error"]["median"] > m.noise_rel:
        warn("held-out",
             f"the surrogate's median error on the held-out FE runs ({100 * held['rel_error']['median']:.2f} %) "
             f"exceeds the measurement noise ({100 * m.noise_rel:g} %): the identification is limited by the surrogate.",
             more)
    elif m.noise_abs is not None:
        sigma = min(m.noise_abs.values()) if isinstance(m.noise_abs, dict) else m.noise_abs
        if held["rms_abs_error_mm"] > sigma:
            warn("held-out",
                 f"the surrogate's RMS error on the held-out FE runs ({held['rms_abs_error_mm']:.3g} mm) exceeds the "
                 f"measurement noise (σ = {sigma:g} mm): the identification is limited by the surrogate.",
                 more)
    if held["coverage_2sigma"] < 0.8:
        warn("held-out",
             f"only {100 * held['coverage_2sigma']:.0f} % of the held-out FE readings lie within ±2σ of the "
             "surrogate: its error bars are too narrow, so the region of equivalence may be too small.",
             "add training snapshots, or set a small [surrogate] nugget (e.g. 1e-6).")
    inv = run.manifest("inversion")["result"]
    fe = inv["fe_check"]
    if fe is not None and not fe["ok"]:
        warn("inversion",
             f"at the optimum the surrogate differs from the FE model by up to {fe['max_diff_over_noise']:.2f}× the "
             f"noise ({fe['max_abs_diff']:.3g} mm): the identification is limited by the surrogate, not by the data.",
             "add training snapshots or narrow the bounds around the identified values, and run again.")
    for name in inv["at_bound"]:
        warn("inversion",
             f"the best fit of {name} ({inv['parameters'][name]:.4g}{_unit(inv['units'][name])}) lies on a bound "
             "of its search range: the data may prefer a value outside it.",
             f"widen the bounds of {name} in [parameters] and run again.")
    if inv["chi2_dof"] > 2.0:
        warn("inversion",
             f"χ²/dof = {inv['chi2_dof']:.2f}: the calibrated model does not reproduce the data within the stated "
             "noise.",
             "check the noise level; if it is right, a physical effect is missing from the model: "
             + ("the model diagnosis below names it." if study.diagnosis.enabled else
                "switch on the model diagnosis ([diagnosis] enabled = true) to name it."))
    region = run.manifest("region")["result"]
    for name, v in region["identifiability"].items():
        if not v["identifiable"]:
            lo, hi = region["intervals"][name]
            warn("region",
                 f"{name} is not pinned down by these data: values from {lo:.4g} to {hi:.4g}"
                 f"{_unit(inv['units'][name])} ({100 * v['share']:.0f} % of its search range) fit equally well.",
                 f"fix {name} from other tests ([fixed]), add sensors sensitive to it, or report it as unidentified.")
    if study.diagnosis.enabled:
        d = run.manifest("diagnosis")["result"]
        if d["verdict"] != "adequate" and d["cause"] is None:
            warn("diagnosis",
                 f"the calibrated model does not explain the data (χ²/dof = {d['base']['chi2_dof']:.2f}) and no "
                 "candidate cause in the library explains the residual.",
                 "check the noise level and the measurement file; read the residual pattern in the diagnosis report "
                 "for an effect outside the library (nonlinearity, another test set-up).")
        elif d["verdict"] != "adequate":
            where = f" at {d['detail']['location']}" if d["detail"] else ""
            gain = (f" (χ²/dof {d['gain']['chi2_dof_before']:.2f} → {d['gain']['chi2_dof_after']:.2f} with it)"
                    if d["gain"] else "")
            warn("diagnosis",
                 f"the calibrated model leaves out a physical effect: the diagnosis names {d['cause']}{where}{gain}.",
                 "read the diagnosis report; add the effect to the model (or repair the named sensor or set-up) "
                 "and calibrate again: the parameters identified without it are biased.")
    return found


def _unit(unit):
    """`` unit`` to append to a number, or nothing for a dimensionless one."""
    return f" {unit}" if unit and unit != "-" else ""
