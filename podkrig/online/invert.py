"""Identify the free parameters of an :class:`~podkrig.online.problem.InverseProblem`.

:func:`invert` minimises the misfit ω(m) of thesis eq. (2.13) with the genetic algorithm
(:mod:`podkrig.ga`, thesis ch. 3) and polishes the best individual, and the best distinct
points of a Sobol' screen, by bounded least squares on the whitened residuals (the GA finds the
basin, Gauss–Newton finishes it). :func:`fe_check` runs the FE model once at the optimum to
measure how far the surrogate is from it there. Both return objects with ``to_dict`` /
``from_dict`` (:class:`InverseResult`, :class:`FECheck`).
"""

import dataclasses
import logging
import time
from dataclasses import dataclass

import numpy as np

from podkrig._qmc import rng_seed, scrambled_sobol
from podkrig.display import Displayed, summary
from podkrig.parallel import one_blas_thread
from podkrig.ga import GeneticAlgorithm
from podkrig.limits import check_generations, check_population, check_starts
from podkrig.online.findings import RESIDUAL_CONVENTION, at_bound, chi2_basis, fe_check_ok
from podkrig.online.settings import GA

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False, repr=False)
class FECheck(Displayed):
    """One FE run at the optimum compared with the surrogate, at the observed entries.

    Attributes
    ----------
    max_abs_diff : float
        max |FE − surrogate| over the compared entries, in the unit of the entry where it occurs
        (mm; kN for a load reading): in a test with readings of several units read
        :attr:`max_abs_diff_by_unit` instead.
    max_diff_over_noise : float
        Largest |FE − surrogate| / σ_noise (-).
    rel_diff : float
        ‖FE − surrogate‖ / ‖FE‖ (-).
    chi2_dof_fe : float
        χ²/dof of the FE prediction against the data, noise only (-).
    ok : bool
        The difference is within the noise (:data:`~podkrig.online.findings.FE_CHECK_LIMIT`).
    fe_readings : ndarray of shape (n_obs,) or None
        FE readings at the observed entries, mm (not part of :meth:`to_dict`).
    stopped : str or None
        How a nonlinear FE run at the optimum stopped early — its status, the budget limit that
        ended it and the control value reached, e.g. ``"budget_exhausted: iterations, reached
        0.04 mm"`` — or None when it reached every level. The differences are then over the
        entries it reached, χ²/dof is NaN, and the check fails.
    max_abs_diff_by_unit : dict of str to float or None
        Unit of the readings (mm, kN) → max |FE − surrogate| over the compared entries of that
        unit; None for a result read back from a dict written without it.
    """

    max_abs_diff: float
    max_diff_over_noise: float
    rel_diff: float
    chi2_dof_fe: float
    ok: bool
    fe_readings: np.ndarray | None = None
    stopped: str | None = None
    max_abs_diff_by_unit: dict | None = None

    def to_dict(self):
        """The numbers, without the FE readings (JSON-able)."""
        return {"max_abs_diff": self.max_abs_diff, "max_diff_over_noise": self.max_diff_over_noise,
                "rel_diff": self.rel_diff, "chi2_dof_fe": self.chi2_dof_fe,
                "chi2_dof_fe_basis": chi2_basis("fe_check"), "ok": self.ok, "stopped": self.stopped,
                "max_abs_diff_by_unit": self.max_abs_diff_by_unit}

    @classmethod
    def from_dict(cls, d):
        by_unit = d.get("max_abs_diff_by_unit")
        return cls(float(d["max_abs_diff"]), float(d["max_diff_over_noise"]), float(d["rel_diff"]),
                   float(d["chi2_dof_fe"]), bool(d["ok"]), stopped=d.get("stopped"),
                   max_abs_diff_by_unit=None if by_unit is None else {u: float(v) for u, v in by_unit.items()})


@dataclass(frozen=True, eq=False, repr=False)
class InverseResult(Displayed):
    """Outcome of :func:`invert`.

    Attributes
    ----------
    x : ndarray of shape (n_free,)
        Best free parameters, physical units.
    parameters : dict of str to float
        Every model parameter at the optimum (free and fixed).
    misfit : float
        ω(m*) (thesis eq. 2.13).
    chi2 : float
        Data term (g − d)ᵀ C_D⁻¹ (g − d) at m*.
    dof : int
        n_obs − n_removed − n_free (n_removed: rigid-body dof removed, 3 per DIC grid and load level).
    n_evaluations : int
        Model evaluations (GA and polish).
    seconds : float
    free, units : tuple of str
        Names and units of the free parameters.
    at_bound : tuple of str
        Free parameters whose best fit lies on a bound of the search range
        (:func:`~podkrig.online.findings.at_bound`).
    measurement : dict
        ``file``, ``sensors``, ``load_levels``, ``load_unit``, ``n_obs`` of the data.
    problem : InverseProblem or None
        None for a result read back with :meth:`from_dict`.
    ga : GAResult or None
    fe_check : FECheck or None
        Set by :meth:`with_fe_check`.
    basis : str or None
        What :attr:`chi2` includes, as read back by :meth:`from_dict`; None: from the problem
        (:attr:`chi2_basis`).
    tests : dict of str to InverseResult
        For a joint calibration (:class:`~podkrig.online.joint.JointProblem`): each test's own view
        of the optimum — its parameters, χ² over its readings, its dof (n_obs of the test − the free
        parameters it depends on) and its FE check; empty for one test.
    """

    x: np.ndarray
    parameters: dict
    misfit: float
    chi2: float
    dof: int
    n_evaluations: int
    seconds: float
    free: tuple
    units: tuple
    at_bound: tuple
    measurement: dict
    problem: object = None
    ga: object = None
    fe_check: FECheck | None = None
    basis: str | None = None
    tests: dict = dataclasses.field(default_factory=dict)

    @property
    def chi2_dof(self):
        """χ² per degree of freedom (≈ 1 when the model explains the data within the noise)."""
        return self.chi2 / max(self.dof, 1)

    def _repr_lines(self):
        """The optimum, its χ²/dof and FE check, one line per free parameter (repr)."""
        fe = "" if self.fe_check is None else f", FE check χ²/dof {summary(self.fe_check.chi2_dof_fe)}"
        bound = {n: " (on a bound)" for n in self.at_bound}
        return [f"InverseResult: {len(self.free)} free parameters, χ²/dof {summary(self.chi2_dof)} (dof {self.dof})"
                f"{fe}, ω {summary(self.misfit)}, {self.n_evaluations} evaluations, {summary(self.seconds)} s",
                *(f"  {n} = {summary(float(v))} {u}{bound.get(n, '')}".rstrip()
                  for n, u, v in zip(self.free, self.units, self.x))]

    @property
    def chi2_basis(self):
        """What :attr:`chi2` measures: the model (surrogate) and what C_D holds
        (:data:`~podkrig.online.findings.CHI2_BASIS`)."""
        if self.basis is not None:
            return self.basis
        model_error = True if self.problem is None else bool(self.problem.model_error)
        form_error = getattr(self.problem, "model_form_error", None)
        return chi2_basis("surrogate" if model_error else "surrogate-noise",
                          form_error=None if form_error is None else form_error.describe())

    @property
    def free_parameters(self):
        """The free parameters at the optimum, ``{name: value}`` physical units."""
        return {n: float(v) for n, v in zip(self.free, self.x)}

    def predicted(self):
        """Model prediction at the observed entries, ``(n_loads_obs, n_sensors_obs)`` mm, and its std
        (NaN where a reading is missing)."""
        if self.problem is None:
            raise ValueError("this result was read back from a dict and has no problem: predictions need the model")
        if self.tests:
            raise ValueError(f"a joint calibration predicts per test: use result.tests[name].predicted() for one of "
                             f"{list(self.tests)}")
        mean, std = self.problem.misfit.predict(self.x[None])
        grid = self.problem.measurement.grid
        return grid(mean[0]), None if std is None else grid(std[0])

    def with_fe_check(self, scenario, response=None):
        """This result with :func:`fe_check` against ``scenario`` attached (one FE run, or none
        when ``response``, the scenario's response at :attr:`parameters`, is given)."""
        return dataclasses.replace(self, fe_check=fe_check(self, scenario, response))

    def with_test(self, name, result):
        """This joint result with the view of test ``name`` replaced (e.g. by one with its FE check)."""
        if name not in self.tests:
            raise KeyError(f"no test {name!r}; tests: {list(self.tests)}")
        return dataclasses.replace(self, tests={**self.tests, name: result})

    def to_dict(self):
        """JSON-able numbers: ``free`` (the free parameters' names in the order of ``x``), ``x``,
        ``parameters`` (free, by name), ``fixed``, ``units``, ``at_bound``, ``misfit``,
        ``chi2``, ``dof``, ``chi2_dof``, ``chi2_basis`` (what the χ² includes),
        ``residual_convention``, ``n_evaluations``, ``seconds``, ``measurement``, ``fe_check``."""
        return {
            "free": list(self.free),
            "x": self.x.tolist(),
            "parameters": self.free_parameters,
            "fixed": {n: float(v) for n, v in self.parameters.items() if n not in self.free},
            "units": dict(zip(self.free, self.units)),
            "at_bound": list(self.at_bound),
            "misfit": self.misfit, "chi2": self.chi2, "dof": self.dof, "chi2_dof": self.chi2_dof,
            "chi2_basis": self.chi2_basis, "residual_convention": RESIDUAL_CONVENTION,
            "n_evaluations": self.n_evaluations, "seconds": self.seconds,
            "measurement": self.measurement,
            "fe_check": None if self.fe_check is None else self.fe_check.to_dict(),
            **({"tests": {name: t.to_dict() for name, t in self.tests.items()}} if self.tests else {}),
        }

    @classmethod
    def from_dict(cls, d, *, problem=None, ga=None):
        """Read back :meth:`to_dict` (``problem`` and ``ga`` may be attached again).

        ``x`` is rebuilt from the named ``parameters`` in the order ``free``: a JSON writer that
        sorts keys (the study's manifests and ``summary.json``) reorders ``parameters`` but not
        ``x``. A dict written before ``free`` was recorded takes the order of ``problem`` when given
        (else the dict's).
        """
        named = d["parameters"]
        if "free" in d:
            free = tuple(d["free"])
        elif problem is not None and set(problem.free) == set(named):
            free = tuple(problem.free)
        else:
            free = tuple(named)
        return cls(
            np.array([named[n] for n in free], dtype=float), {**d.get("fixed", {}), **named}, float(d["misfit"]),
            float(d["chi2"]),
            int(d["dof"]), int(d["n_evaluations"]), float(d["seconds"]), free, tuple(d["units"][n] for n in free),
            tuple(d["at_bound"]), dict(d["measurement"]), problem, ga,
            None if d.get("fe_check") is None else FECheck.from_dict(d["fe_check"]), d.get("chi2_basis"),
            {name: cls.from_dict(t) for name, t in d.get("tests", {}).items()},
        )

    @classmethod
    def at(cls, problem, x, *, n_evaluations=0, seconds=0.0, ga=None):
        """The result of ``problem`` at free values ``x`` ``(n_free,)`` (physical): misfit, χ², dof,
        bounds touched, the data summary and, for a joint problem, each test's view."""
        x = np.asarray(x, dtype=float)
        space = problem.free_space
        tests = {name: cls.at(part, x_part) for name, (part, x_part) in problem.parts(x).items()}
        return cls(x, problem.parameters_at(x), float(problem.omega(x[None])[0]), float(problem.chi2(x[None])[0]),
                   problem.n_obs - problem.n_removed - problem.n_free, n_evaluations, seconds, tuple(problem.free), tuple(space.units),
                   tuple(at_bound(space.names, space.to_unit(x[None])[0])), problem.measurement_summary(), problem,
                   ga, tests=tests)


def invert(problem, *, rng=0, population_size=GA["population_size"], generations=GA["generations"], polish=True,
           n_starts=GA["n_starts"], **ga_options):
    """Identify the free parameters: GA on ω(m), then least-squares polishes.

    Parameters
    ----------
    problem : InverseProblem or JointProblem
    rng : int or numpy.random.Generator
        Seed of the GA (recorded in the GA result).
    population_size, generations : int
        GA budget: ``population_size × (generations + 1)`` evaluations at most
        (100 × 100 by default, well under a second on the surrogate). The GA runs to this
        budget by design (the polish finishes the job), so a budget stop is no warning here.
    polish : bool
        Finish with bounded least squares (recommended).
    n_starts : int
        Least-squares polishes from the GA's best and from the ``n_starts - 1`` best mutually
        distant points (at least 0.15 apart in the unit cube) of a 1024-point Sobol' screen of
        the box; the lowest misfit wins. Misfits of masonry
        tests have spurious basins on the faces of the box (where the surrogate variance is
        large), into which a GA run can converge; these polishes recover the global one for a
        few thousand cheap surrogate evaluations.
    **ga_options
        Further options of :class:`podkrig.ga.GeneticAlgorithm`.

    Returns
    -------
    InverseResult
    """
    check_starts(n_starts)
    check_population(population_size)
    check_generations(generations, population_size, len(problem.free_space.names))
    t0 = time.perf_counter()
    with one_blas_thread():  # small BLAS calls: see podkrig.parallel
        # the steppable GA, not podkrig.ga.minimize: minimize warns when a run stops on its budget,
        # and running to the generation budget is the plan here
        ga = GeneticAlgorithm(problem.omega, problem.free_space, rng=rng, population_size=population_size,
                              max_generations=generations, unit_fun=problem.omega_unit, **ga_options).run()
        x, n_eval = np.asarray(ga.x, dtype=float), ga.nfev
        if polish:
            x, n_eval = _polish_from_starts(problem, ga, x, n_eval, rng, n_starts)
    result = InverseResult.at(problem, x, n_evaluations=n_eval, seconds=time.perf_counter() - t0, ga=ga)
    logger.info("inversion: omega=%.4g chi2/dof=%.3g in %.3f s (%d evaluations)", result.misfit, result.chi2_dof,
                result.seconds, n_eval)
    return result


def _polish_from_starts(problem, ga, x, n_eval, rng, n_starts):
    """Least-squares polishes from the GA's best and from distinct points of a Sobol' screen;
    returns the best point and the updated evaluation count."""
    best_omega = ga.fun
    space = problem.free_space
    starts = space.to_unit(x[None])  # polish_unit moves a start on (or an ulp past) a face inside
    if n_starts > 1:
        screen = scrambled_sobol(1024, problem.n_free, rng_seed(rng))
        screen_omega = problem.omega_unit(screen)
        n_eval += len(screen)
        starts = np.vstack([starts, _distinct_starts(screen, screen_omega, n_starts - 1)])
    for u0 in starts:
        u_pol, n_pol = problem.polish_unit(u0)
        n_eval += n_pol
        omega_pol = problem.omega_unit(u_pol[None])[0]
        if omega_pol < best_omega:
            x, best_omega = space.from_unit(u_pol[None])[0], omega_pol
    return x, n_eval


def _distinct_starts(U, omega, k, min_distance=0.15):
    """The best of the unit-cube points ``U`` and up to ``k - 1`` more of the best, each at least
    ``min_distance`` (max norm) from those already chosen."""
    U = U[np.argsort(omega, kind="stable")]
    chosen = [0]
    for i in range(1, len(U)):
        if len(chosen) >= k:
            break
        if np.min(np.max(np.abs(U[chosen] - U[i]), axis=1)) >= min_distance:
            chosen.append(i)
    return U[chosen]


def fe_check(result, scenario, response=None):
    """One FE run at the optimum: the surrogate-vs-FE difference at the observed entries.

    Parameters
    ----------
    result : InverseResult
    scenario : fe.Scenario
        The scenario the surrogate was trained on.
    response : fe.Response, optional
        ``scenario.run(result.parameters)`` when the caller ran it already (e.g. with the
        displacement field for a figure); default: run it here.

    Returns
    -------
    FECheck
    """
    problem = result.problem
    if response is None:
        response = scenario.run(result.parameters)
    fe = response.readings.ravel()
    fe_obs = problem.misfit.observation.apply(fe[None])[0]
    mean, _ = problem.misfit.predict(result.x[None])
    status = getattr(response, "status", "converged")
    stopped = None
    if status != "converged":  # a nonlinear run that stopped early: compare the entries it reached
        limit = f": {response.limit}" if response.limit else ""
        stopped = f"{status}{limit}, reached {response.reached:.6g} {scenario.load_unit}"
    reached = np.isfinite(fe_obs)
    diff = (fe_obs - mean[0])[reached]
    sd = np.broadcast_to(problem.misfit.noise_std, fe_obs.shape)[reached]
    noise_only = problem.misfit if problem.misfit.form_error is None else dataclasses.replace(problem.misfit,
                                                                                              form_error=None)
    resid = noise_only.whiten(fe_obs - problem.measurement.data)[0]  # noise only, rigid motion removed
    over_noise = float(np.max(np.abs(diff) / sd)) if len(diff) else float("nan")
    meas = problem.measurement
    units = np.broadcast_to(np.array(meas.sensor_units, dtype=object), meas.values.shape)[meas.mask][reached]
    by_unit = {str(u): float(np.max(np.abs(diff[units == u]))) for u in dict.fromkeys(units)}
    return FECheck(
        max_abs_diff=float(np.max(np.abs(diff))) if len(diff) else float("nan"),
        max_diff_over_noise=over_noise,
        rel_diff=float(np.linalg.norm(diff) / np.linalg.norm(fe_obs[reached])) if len(diff) else float("nan"),
        chi2_dof_fe=float(resid @ resid / max(result.dof, 1)),
        ok=stopped is None and fe_check_ok(over_noise),
        fe_readings=fe_obs,
        stopped=stopped,
        max_abs_diff_by_unit=by_unit,
    )


__all__ = ["FECheck", "InverseResult", "fe_check", "invert"]
