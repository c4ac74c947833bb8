"""The calibration stage: every step of the online stage, in one place.

:func:`calibrate` takes an inverse problem (one test's
:class:`~podkrig.online.problem.InverseProblem` or a
:class:`~podkrig.online.joint.JointProblem` of several) and
:class:`~podkrig.online.settings.CalibrationSettings`, and runs, in order:

1. the **model-form error** in C_D (thesis eq. 2.10) when asked: a relative tolerance ε
   (``e_i = ε |d_i|``), or *estimated* — invert once, run each test's scenario at that optimum on
   its mesh and on the mesh refined twice, turn the difference into each reading's error by
   Richardson's factor (:func:`~podkrig.online.model_error.discretisation_error`);
2. the **inversion**: GA on the surrogate and least-squares polish
   (:func:`~podkrig.online.invert.invert`), with the model-form error;
3. the **region of equivalence** at the optimum (:mod:`podkrig.online.region`, either method);
4. the **FE check** at the optimum, one FE run per test (:func:`~podkrig.online.invert.fe_check`);
5. the **posterior** by MCMC (``mcmc_steps`` > 0, :func:`~podkrig.online.posterior.sample_posterior`);
6. the **RVC** of each test's calibration model and of the validation models over the region
   (:func:`~podkrig.online.propagation.rvc`): mean, CV and quantiles of each output, and for a
   validation model with ``fe_runs`` its FE runs at region members with the share that failed;
7. the **findings** of the measurement check, the inversion and the region
   (:mod:`podkrig.online.findings`).

``podkrig invert``, ``podkrig rvc``, the study pipeline's calibration stage and the diagnosis call
it (or, for the model-form error alone, :func:`model_form_errors`); none of them orders these
steps itself. It returns a :class:`CalibrationResult` with ``to_dict`` / ``from_dict``.
"""

import dataclasses
import logging
import time
from dataclasses import dataclass

import numpy as np

from podkrig.display import Displayed, summary
from podkrig.online.data_check import check_readings, surrogate_training_outputs
from podkrig.offline.failures import FailureRegion
from podkrig.online.findings import Finding, failure_findings, inversion_findings, measurement_findings, of_test
from podkrig.online.invert import InverseResult, fe_check, invert
from podkrig.online.joint import JointProblem
from podkrig.online.model_error import DEFAULT_RATE, ModelError, discretisation_error, tolerance_error
from podkrig.online.posterior import Posterior, sample_posterior
from podkrig.online.propagation import RVCModel, RVCResult, rvc
from podkrig.online.region import Region, likelihood_ratio_region, noise_monte_carlo_region
from podkrig.online.settings import CalibrationSettings

logger = logging.getLogger(__name__)

__all__ = ["CalibrationResult", "calibrate", "model_form_error", "model_form_errors", "problems_by_test", "with_model_form_errors"]


@dataclass(frozen=True, eq=False, repr=False)
class CalibrationResult(Displayed):
    """Outcome of :func:`calibrate`.

    Attributes
    ----------
    inversion : InverseResult
        The optimum (with each test's view in a joint calibration) and its FE check(s); its
        :attr:`~InverseResult.problem` carries the model-form error the region used.
    region : Region
        The region of equivalence (its members are not part of :meth:`to_dict`).
    posterior : Posterior or None
        MCMC posterior (``mcmc_steps`` > 0).
    rvc : dict of str to RVCResult
        ``calibration`` (or ``calibration.TEST`` per test of a joint calibration) and each
        validation model by name.
    findings : list of Finding
        Codes and values (:mod:`podkrig.online.findings`; their words are
        :func:`podkrig.reports.findings.words`) of the measurement check (when asked), the
        inversion and the region, in report order; in a joint calibration each test's own carry
        its name (``test``).
    settings : CalibrationSettings
    seconds : float
        Wall time of the whole calibration, s.
    n_fe_runs : int
        FE runs made (model-form error, FE checks, validation runs at region members).
    model_form_errors : dict
        Test name (None for one test) → the :class:`~podkrig.online.model_error.ModelError` in its
        C_D, for the tests that have one.
    responses : dict
        Test name (None for one test) → the FE response of its FE check (with the displacement
        field when asked); not part of :meth:`to_dict`.
    """

    inversion: InverseResult
    region: Region
    posterior: Posterior | None
    rvc: dict
    findings: list
    settings: CalibrationSettings
    seconds: float
    n_fe_runs: int = 0
    model_form_errors: dict = dataclasses.field(default_factory=dict)
    responses: dict = dataclasses.field(default_factory=dict)

    def _repr_lines(self):
        """The optimum with its interval, the fit and the findings (repr)."""
        inv, region = self.inversion, self.region
        return [f"CalibrationResult: χ²/dof {summary(inv.chi2_dof)} (dof {inv.dof}), region {len(region.samples)} "
                f"members ({100 * region.confidence:.0f} %), {len(self.findings)} findings, {self.n_fe_runs} FE runs, "
                f"{summary(self.seconds)} s",
                *(f"  {n} = {summary(float(v))} {u} in [{summary(float(region.intervals[n][0]))}, "
                  f"{summary(float(region.intervals[n][1]))}]" if n in region.intervals
                  else f"  {n} = {summary(float(v))} {u}"
                  for n, u, v in zip(inv.free, inv.units, inv.x))]

    def to_dict(self, *, members=False):
        """JSON-able: ``inversion`` (:meth:`InverseResult.to_dict`), ``region``
        (:meth:`Region.to_dict`; its members and the posterior's samples only with ``members``),
        ``posterior`` (or None), ``rvc`` (name → :meth:`RVCResult.to_dict`), ``findings``,
        ``settings``, ``seconds``, ``n_fe_runs``, ``model_form_errors`` (test name, or
        ``calibration`` for one test → :meth:`ModelError.to_dict`)."""
        return {
            "inversion": self.inversion.to_dict(),
            "region": self.region.to_dict(members=members),
            "posterior": None if self.posterior is None else self.posterior.to_dict(members=members),
            "rvc": {name: r.to_dict() for name, r in self.rvc.items()},
            "findings": [f.to_dict() for f in self.findings],
            "settings": dataclasses.asdict(self.settings),
            "seconds": self.seconds,
            "n_fe_runs": self.n_fe_runs,
            "model_form_errors": {"calibration" if name is None else name: e.to_dict()
                                  for name, e in self.model_form_errors.items()},
        }

    @classmethod
    def from_dict(cls, d, *, samples=None, omega=None, problem=None):
        """Read back :meth:`to_dict`: the region's members from ``d`` (``members=True``) or from
        ``samples`` and ``omega`` (e.g. the study's ``region.npz``); ``problem``: the
        inversion's problem, when at hand."""
        return cls(
            InverseResult.from_dict(d["inversion"], problem=problem),
            Region.from_dict(d["region"], samples=samples, omega=omega),
            None if d["posterior"] is None else Posterior.from_dict(d["posterior"]),
            {name: RVCResult.from_dict(r) for name, r in d["rvc"].items()},
            [Finding.from_dict(f) for f in d["findings"]],
            CalibrationSettings(**d["settings"]),
            float(d["seconds"]),
            int(d["n_fe_runs"]),
            {None if name == "calibration" else name: ModelError.from_dict(e)
             for name, e in d["model_form_errors"].items()},
        )

    @property
    def tests(self):
        """Each test's own view of the optimum, ``{test name or None: InverseResult}``."""
        return self.inversion.tests or {None: self.inversion}


def problems_by_test(problem):
    """A calibration problem's problem per test: ``{test name: InverseProblem}`` of a
    :class:`JointProblem`, ``{None: problem}`` for one test."""
    return getattr(problem, "problems", {None: problem})


def _scenario_of(scenarios, name, problem):
    """The FE scenario of test ``name``: from ``scenarios`` (one scenario, a mapping by test name
    or a callable of the name) or built from the surrogate's provenance."""
    if scenarios is None:
        return problem.model.scenario()
    if hasattr(scenarios, "run"):
        return scenarios
    if callable(scenarios):
        return scenarios(name)
    return scenarios[name]


def model_form_error(scenario, values, measurement, asked, *, rigid_body=None, observation=None, rate=DEFAULT_RATE,
                     fallback=None):
    """One test's model-form error (:class:`~podkrig.online.model_error.ModelError`, thesis eq.
    2.10): ``asked`` "estimated" runs ``scenario`` at ``values`` on its mesh and on the mesh refined
    twice (:func:`~podkrig.online.model_error.discretisation_error`, with ``rigid_body``,
    ``observation`` and the convergence ``rate``); a number ε is the tolerance ``e_i = ε |d_i|``.
    ``fallback``: a tolerance to use, with a warning, when the scenario's mesh cannot be refined
    (default: the error propagates)."""
    if asked != "estimated":
        return tolerance_error(measurement, float(asked))
    try:
        return discretisation_error(scenario, values, measurement, rate=rate, rigid_body=rigid_body,
                                    observation=observation)
    except ValueError as e:
        if fallback is None:
            raise
        logger.warning("%s; using a model-form tolerance of %g %%", e, 100 * fallback)
        return tolerance_error(measurement, fallback, note=str(e))


def model_form_errors(problem, settings, first=None, *, scenarios=None):
    """Each test's model-form error (:func:`model_form_error`) as ``settings.model_form_error``
    asks: ``{test name or None: ModelError}`` (absent where none).

    "estimated" needs ``first``, an inversion of ``problem`` without it (the optimum where the
    scenario runs on its mesh and the mesh refined twice); ε needs nothing but the data.
    """
    errors = {}
    for name, p in problems_by_test(problem).items():
        asked = settings.form_error(name)
        if asked is None:
            continue
        scenario = values = None
        if asked == "estimated":
            scenario = _scenario_of(scenarios, name, p)
            values = (first if name is None else first.tests[name]).parameters
        errors[name] = model_form_error(scenario, values, p.measurement, asked, rigid_body=p.misfit.rigid_body,
                                        observation=p.misfit.observation)
    return errors


def with_model_form_errors(problem, errors):
    """``problem`` with the model-form errors ``{test: ModelError}`` in its tests' C_D."""
    if not errors:
        return problem
    if isinstance(problem, JointProblem):
        return JointProblem({name: dataclasses.replace(p, model_form_error=errors[name]) if name in errors else p
                             for name, p in problem.problems.items()})
    return dataclasses.replace(problem, model_form_error=errors[None])


def _region(problem, x, settings):
    s, seed = settings.region, settings.inversion.seed
    if s.method == "noise-mc":
        return noise_monte_carlo_region(problem, x, confidence=settings.confidence, rng=seed)
    return likelihood_ratio_region(problem, x, confidence=settings.confidence, n_samples=s.samples, rng=seed)



def _near_failure(problem, result):
    """The ``near-failure`` finding of one test: its best fit against the classifier of the failed
    runs of the store its surrogate was trained on (none for an FE model, or a store without one)."""
    prov = getattr(getattr(problem.model, "surrogate", None), "provenance_", None) or {}
    if not prov.get("failure_region"):
        return []
    region = FailureRegion.from_dict(prov["failure_region"])
    space = problem.model.space
    if tuple(space.names) != region.names:
        return []
    x = np.array([[result.parameters[n] for n in space.names]])
    return failure_findings(region, prov["failed_share"], space.to_unit(x)[0])


def calibrate(problem, settings=None, *, scenarios=None, validation=None, outputs=None, check_measurement=True,
              keep_field=False, calibration_rvc=True, progress=None, range_check=True):
    """Calibrate: model-form error, inversion, region, FE check, posterior, RVC and findings.

    Parameters
    ----------
    problem : InverseProblem or JointProblem
        Without a model-form error (``settings.model_form_error`` adds it).
    settings : CalibrationSettings, optional
        Default: ``CalibrationSettings()``.
    scenarios : fe.Scenario, mapping or callable, optional
        The FE scenario of each test (for the FE check and an estimated model-form error): one
        scenario (one test), ``{test name: scenario}`` or ``scenario(test name)``; default: built
        from each surrogate's provenance.
    validation : dict of str to RVCModel, (model, outputs) or (model, outputs, fixed), optional
        Validation models for the RVC by name: a
        :class:`~podkrig.online.propagation.RVCModel` (a batched model such as a
        :class:`~podkrig.online.problem.SurrogateModel`, its reported outputs, values of its own
        parameters, its quantile levels, and its FE scenario with ``fe_runs`` FE runs at region
        members for the failed share), or the tuple of its first two or three fields. Parameters
        a validation model has and the calibration does not identify take the calibration's
        values (or, where it has none, those ``fixed``).
    outputs : sequence of str, optional
        Outputs of the calibration model's RVC (one test; default every sensor at the last load).
    check_measurement : bool
        Include the findings of each test's measurement check (a caller that checked the data
        before, as the study does, leaves them out).
    keep_field : bool
        Keep the displacement field of each FE-check run in :attr:`CalibrationResult.responses`.
    calibration_rvc : bool
        Also the RVC of each test's calibration model (the validation models' always).
    progress : callable, optional
        ``progress(step, done, total)`` after each step.
    range_check : bool
        First compare each test's readings with its surrogate's training runs
        (:func:`~podkrig.online.data_check.check_readings`; a model without training runs, such
        as an FE model, is not compared): the measurement check of every door, which a caller
        that compared them already (the study, with its probe and training runs) leaves out.

    Returns
    -------
    CalibrationResult

    Raises
    ------
    MeasurementCheckError
        With ``range_check``: a sensor's readings 20× larger or smaller than every training run,
        or of the opposite sign (a unit or sign error), before any inversion.
    """
    settings = CalibrationSettings() if settings is None else settings
    if range_check:
        for p in problems_by_test(problem).values():
            surrogate = getattr(p.model, "surrogate", None)
            if getattr(surrogate, "U_", None) is not None:
                check_readings(p.measurement, p.noise, p.model.sensor_names, p.model.load_levels,
                               p.model.load_response, surrogate_training_outputs(surrogate), runs="surrogate")
    say = progress or (lambda *a: None)
    t0 = time.perf_counter()
    ga = settings.inversion.options()
    n_fe = 0
    # 1–2. the model-form error (an estimate needs a first optimum), then the inversion with it
    # the scenarios of an estimate are built before the first inversion (as they always were: a
    # scenario built after the GA may differ in the last bits of its FE readings)
    refined = {name: _scenario_of(scenarios, name, p) for name, p in problems_by_test(problem).items()
               if settings.form_error(name) == "estimated"}
    first = invert(problem, **ga) if refined else None
    errors = model_form_errors(problem, settings, first, scenarios=refined)
    n_fe += 2 * len(refined)
    problem = with_model_form_errors(problem, errors)
    per_test = problems_by_test(problem)
    say("inversion", 1, 5)
    result = invert(problem, **ga)
    # 3. region of equivalence (with the model-form error)
    region = _region(problem, result.x, settings)
    say("region", 2, 5)
    # 4. FE check at the optimum, per test
    responses = {}
    if settings.fe_check:
        for name, p in per_test.items():
            one = result if name is None else result.tests[name]
            scenario = _scenario_of(scenarios, name, p)
            response = scenario.run(one.parameters, field=True) if keep_field else scenario.run(one.parameters)
            responses[name] = response
            one = dataclasses.replace(one, fe_check=fe_check(one, scenario, response))
            result = one if name is None else result.with_test(name, one)
            n_fe += 1
    say("FE check", 3, 5)
    # 5. posterior
    posterior = None
    if settings.mcmc_steps:
        posterior = sample_posterior(problem, result.x, n_steps=settings.mcmc_steps, confidence=settings.confidence,
                                     rng=settings.inversion.seed)
    say("posterior", 4, 5)
    # 6. RVC of the calibration model(s) and the validation models
    seed = settings.inversion.seed
    rvcs = {}
    for name, p in per_test.items() if calibration_rvc else ():
        key = "calibration" if name is None else f"calibration.{name}"
        rvcs[key] = rvc(region, p.model, fixed=p.fixed, outputs=list(outputs) if outputs and name is None else None,
                        rng=seed)
    best = result.parameters
    for name, entry in (validation or {}).items():
        v = entry if isinstance(entry, RVCModel) else RVCModel(*entry)
        fixed = {**(v.fixed or {}),
                 **{n: best[n] for n in v.model.space.names if n not in region.names and n in best}}
        missing = [n for n in v.model.space.names if n not in region.names and n not in fixed]
        if missing:
            raise ValueError(f"validation model {name!r} varies {missing}, which the calibration neither identifies "
                             "nor fixes")
        rvcs[name] = rvc(region, v.model, fixed=fixed, outputs=list(v.outputs) if v.outputs else None, rng=seed,
                         quantiles=v.quantiles, scenario=v.scenario, fe_runs=v.fe_runs)
        n_fe += rvcs[name].runs.n_runs if rvcs[name].runs is not None else 0
    say("RVC", 5, 5)
    # 7. findings
    found = []
    if check_measurement:
        for name, p in per_test.items():
            found += of_test(name, measurement_findings(p.measurement.check_summary(p.model.sensor_names, p.noise)))
    found += inversion_findings(result, region)
    for name in result.tests:
        found += of_test(name, inversion_findings(result.tests[name], per_test=True))
    for name, p in per_test.items():
        found += of_test(name, _near_failure(p, result if name is None else result.tests[name]))
    return CalibrationResult(result, region, posterior, rvcs, found, settings, time.perf_counter() - t0, n_fe,
                             errors, responses)
