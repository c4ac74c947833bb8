"""Inverse analysis against a batched forward model (normally the POD-kriging surrogate).

An :class:`InverseProblem` combines a model, a measurement, a noise model and a choice of free
parameters (the others fixed); :func:`invert` minimises the misfit ω(m) of thesis eq. (2.13) with
the genetic algorithm (:mod:`podkrig.ga`, thesis ch. 3) and polishes the best individual by
bounded least squares on the whitened residuals (the GA finds the basin, Gauss–Newton finishes
it). Parameters are searched in the unit cube of the free parameter space (log-scaled
parameters are searched in log10).

A *model* is any object with ``space`` (a :class:`~podkrig.parameters.ParameterSpace` over all
its inputs), ``sensor_names``, ``load_levels`` and ``predict(X, return_std=True) -> (mean, std)``
with ``X`` ``(n, n_params)`` physical and ``mean``, ``std`` ``(n, n_loads * n_sensors)`` mm
(load-major). The POD-kriging surrogate is one; :class:`FEModel` wraps a scenario so that the
same inversion can run with the FE model in the loop.
"""

import dataclasses
import logging
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from podkrig._qmc import scrambled_sobol
from podkrig.parallel import one_blas_thread
from podkrig.online.misfit import Misfit
from podkrig.parameters import ParameterSpace

logger = logging.getLogger(__name__)


class FEModel:
    """A scenario seen as a batched model (one FE run per row; no predictive variance).

    Parameters
    ----------
    scenario : fe.Scenario
    space : ParameterSpace
        Free parameters; the scenario's other parameters keep their defaults.
    """

    def __init__(self, scenario, space):
        self.scenario = scenario
        self.space = space
        self.sensor_names = tuple(scenario.sensor_names)
        self.load_levels = np.asarray(scenario.load_levels, dtype=float)
        self.n_runs = 0

    def predict(self, X, return_std=False):
        X = np.atleast_2d(X)
        Y = np.stack([self.scenario.run(self.space.as_params(x)).readings.ravel() for x in X])
        self.n_runs += len(X)
        return (Y, None) if return_std else Y


class SurrogateModel:
    """A fitted :class:`~podkrig.surrogate.PODKriging` (built from a store) as an inversion model.

    Exposes ``space``, ``sensor_names``, ``load_levels``, ``load_unit`` and ``scenario_spec`` from
    the surrogate's provenance, and its batched ``predict``.
    """

    def __init__(self, surrogate):
        prov = surrogate.provenance_
        missing = [k for k in ("sensor_names", "load_levels", "scenario_spec") if k not in prov]
        if missing or surrogate.space is None:
            raise ValueError(
                f"the surrogate lacks {missing or ['a parameter space']}: build it from a snapshot store "
                "with 'podkrig surrogate build' so that it knows its sensors and load levels"
            )
        if prov.get("output", "readings") != "readings":
            raise ValueError("this surrogate predicts displacement fields; inversion needs a surrogate of the sensor readings")
        self.surrogate = surrogate
        self.space = surrogate.space
        self.sensor_names = tuple(prov["sensor_names"])
        self.load_levels = np.asarray(prov["load_levels"], dtype=float)
        self.load_unit = prov.get("load_unit", "kN")
        self.scenario_spec = prov["scenario_spec"]

    def predict(self, X, return_std=False):
        return self.surrogate.predict(X, return_std=return_std)

    def predict_unit(self, U, return_std=False):
        """``predict`` at unit-cube coordinates of ``space`` (no round trip through physical units)."""
        return self.surrogate.predict_unit(U, return_std=return_std)

    def scenario(self, solver="auto"):
        """The FE scenario the surrogate was trained on (rebuilt from its spec)."""
        from fe.scenarios import build_scenario

        return build_scenario(self.scenario_spec, solver=solver)


@dataclass(frozen=True, eq=False)
class InverseProblem:
    """A calibration problem: model + measurement + noise over the free parameters.

    Parameters
    ----------
    model : object
        See the module docstring.
    measurement : Measurement
    noise : NoiseModel
    free : sequence of str, optional
        Free parameter names (default: all of ``model.space``).
    fixed : dict of str to float, optional
        Values of the non-free parameters of ``model.space``; each must lie inside the model's
        trained box. Every non-free parameter must be given one.
    prior_mean, prior_cov : optional
        Gaussian prior over the free parameters (thesis eq. 2.11).
    kind : {"gaussian", "relative"}
        Misfit kind (see :class:`~podkrig.misfit.Misfit`).
    model_error : bool
        Include the model's predictive variance in ``C_D`` (thesis eq. 2.10).
    """

    model: object
    measurement: object
    noise: object
    free: tuple | None = None
    fixed: dict = field(default_factory=dict)
    prior_mean: np.ndarray | None = None
    prior_cov: np.ndarray | None = None
    kind: str = "gaussian"
    model_error: bool = True
    frozen_model_std: np.ndarray | None = None

    def __post_init__(self):
        space = self.model.space
        names = list(space.names)
        free = tuple(names if self.free is None else self.free)
        unknown = [n for n in free if n not in names] + [n for n in self.fixed if n not in names]
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown}; the model's parameters are {names}")
        both = sorted(set(free) & set(self.fixed))
        if both:
            raise ValueError(f"parameter(s) {both} are both free and fixed; choose one")
        if not free:
            raise ValueError("no free parameters: free at least one of " + ", ".join(names))
        missing = [n for n in names if n not in free and n not in self.fixed]
        if missing:
            raise ValueError(f"parameter(s) {missing} are neither free nor fixed: give each a value (--fix NAME=VALUE)")
        for n, v in self.fixed.items():
            p = space.parameters[names.index(n)]
            if not p.lower <= v <= p.upper:
                raise ValueError(
                    f"fixed value {n} = {v:g} {p.unit} lies outside the model's trained range "
                    f"[{p.lower:g}, {p.upper:g}] {p.unit}"
                )
        object.__setattr__(self, "free", free)
        object.__setattr__(self, "free_space", ParameterSpace(tuple(space.parameters[names.index(n)] for n in free)))
        index = np.array([names.index(n) for n in free])
        template = np.zeros(len(names))
        for n, v in self.fixed.items():
            template[names.index(n)] = v
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "_template", template)
        indices = self.measurement.output_indices(self.model.sensor_names, self.model.load_levels)
        misfit = Misfit(
            self._predict, self.measurement, self.noise, indices, self.prior_mean, self.prior_cov,
            kind=self.kind, model_error=self.model_error,
        )
        object.__setattr__(self, "misfit", misfit)

    @property
    def n_free(self):
        return len(self.free)

    @property
    def n_obs(self):
        return self.misfit.n_obs

    def full(self, X):
        """Free parameter vectors ``(n, n_free)`` → full model inputs ``(n, n_params)``."""
        X = np.atleast_2d(X)
        full = np.tile(self._template, (len(X), 1))
        full[:, self._index] = X
        return full

    def _predict(self, X):
        if self.frozen_model_std is None:
            return self.model.predict(self.full(X), return_std=True)
        mean = self.model.predict(self.full(X))
        return mean, np.broadcast_to(self.frozen_model_std, mean.shape)

    def freeze_model_error(self, x):
        """The same problem with the model's predictive std frozen at ``x`` (free, physical).

        Only the model mean is then evaluated (several times cheaper for kriging). Used for dense
        sampling near the optimum, where the surrogate variance C_T changes little.
        """
        _, std = self.model.predict(self.full(np.atleast_2d(x)), return_std=True)
        return dataclasses.replace(self, frozen_model_std=np.asarray(std[0]))

    def omega(self, X):
        """ω at free parameter vectors ``(n, n_free)`` (physical), ``(n,)``."""
        return self.misfit(X)

    def omega_unit(self, U):
        """ω at unit-cube coordinates of the free space, ``(n,)``."""
        return self.misfit(self.free_space.from_unit(np.atleast_2d(U)))

    def _residuals_batch(self, U):
        """Whitened data residuals and prior residuals at unit-cube points, ``(n, n_obs [+ n_free])``."""
        X = self.free_space.from_unit(np.atleast_2d(U))
        return np.hstack([self.misfit.whitened_residuals(X), self.misfit.prior_residuals(X)])

    def residuals_unit(self, u):
        """Whitened residuals (and prior residuals) at one unit-cube point, ``(n_obs [+ n_free],)``."""
        return self._residuals_batch(u)[0]

    def jacobian_unit(self, u, step=1e-5):
        """Jacobian of the residuals of :meth:`residuals_unit` w.r.t. unit coordinates (central
        differences, one-sided at the box faces), ``(n_residuals, n_free)``; one batched model call."""
        u = np.asarray(u, dtype=float)
        p = len(u)
        U = np.repeat(u[None], 2 * p, axis=0)
        idx = np.arange(p)
        U[2 * idx, idx] = np.minimum(u + step, 1.0)  # one-sided at the box faces: never extrapolate
        U[2 * idx + 1, idx] = np.maximum(u - step, 0.0)
        W = self._residuals_batch(U)
        h = U[2 * idx, idx] - U[2 * idx + 1, idx]
        return ((W[0::2] - W[1::2]) / h[:, None]).T

    def polish(self, x0, max_nfev=200):
        """Bounded least squares on the whitened residuals from ``x0`` (physical); returns
        ``(x, n_evaluations)``."""
        u0 = np.clip(self.free_space.to_unit(np.atleast_2d(x0))[0], 0.0, 1.0)
        sol = optimize.least_squares(self.residuals_unit, u0, jac=self.jacobian_unit, bounds=(0.0, 1.0),
                                     x_scale=1.0, max_nfev=max_nfev, method="trf")
        return self.free_space.from_unit(sol.x[None])[0], int(sol.nfev + 2 * len(u0) * sol.njev)


@dataclass(frozen=True, eq=False)
class InverseResult:
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
        n_obs − n_free.
    n_evaluations : int
        Model evaluations (GA and polish).
    seconds : float
    ga : GAResult
    """

    problem: InverseProblem
    x: np.ndarray
    parameters: dict
    misfit: float
    chi2: float
    dof: int
    n_evaluations: int
    seconds: float
    ga: object

    @property
    def chi2_dof(self):
        """χ² per degree of freedom (≈ 1 when the model explains the data within the noise)."""
        return self.chi2 / max(self.dof, 1)

    def predicted(self):
        """Model prediction at the observed entries, ``(n_loads_obs, n_sensors_obs)`` mm, and its std."""
        mean, std = self.problem.misfit.predict(self.x[None])
        shape = self.problem.measurement.values.shape
        return mean[0].reshape(shape), None if std is None else std[0].reshape(shape)


def invert(problem, *, rng=0, population_size=100, generations=100, polish=True, n_starts=6, **ga_options):
    """Identify the free parameters: GA on ω(m), then a least-squares polish.

    Parameters
    ----------
    problem : InverseProblem
    rng : int or numpy.random.Generator
        Seed of the GA (recorded in the GA result).
    population_size, generations : int
        GA budget: ``population_size × (generations + 1)`` evaluations at most
        (100 × 100 by default, well under a second on the surrogate).
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
    from podkrig.ga import minimize

    t0 = time.perf_counter()
    with one_blas_thread(), warnings.catch_warnings():  # small BLAS calls: see podkrig.parallel
        # running the GA to its generation budget is the plan here: the polish finishes the job
        warnings.filterwarnings("ignore", message="GA stopped on its budget", category=RuntimeWarning)
        ga = minimize(
            problem.omega, problem.free_space, rng=rng, population_size=population_size,
            max_generations=generations, **ga_options,
        )
        x, n_eval = np.asarray(ga.x, dtype=float), ga.nfev
        if polish:
            x, n_eval = _polish_from_starts(problem, ga, x, n_eval, rng, n_starts)
    omega = float(problem.omega(x[None])[0])
    chi2 = float(problem.misfit.chi2(x[None])[0])
    params = dict(zip(problem.model.space.names, problem.full(x[None])[0].tolist()))
    seconds = time.perf_counter() - t0
    logger.info("inversion: omega=%.4g chi2/dof=%.3g in %.3f s (%d evaluations)", omega, chi2 / max(problem.n_obs - problem.n_free, 1), seconds, n_eval)
    return InverseResult(problem, x, params, omega, chi2, problem.n_obs - problem.n_free, n_eval, seconds, ga)


def _polish_from_starts(problem, ga, x, n_eval, rng, n_starts):
    """Least-squares polishes from the GA's best and from distinct points of a Sobol' screen;
    returns the best point and the updated evaluation count."""
    best_omega = ga.fun
    screen = problem.free_space.from_unit(scrambled_sobol(1024, problem.n_free, rng_seed(rng)))
    screen_omega = problem.omega(screen)
    n_eval += len(screen)
    starts = np.vstack([x[None], _distinct_starts(problem, screen, screen_omega, n_starts - 1)])
    for x0 in starts:
        x_pol, n_pol = problem.polish(x0)
        n_eval += n_pol
        omega_pol = problem.omega(x_pol[None])[0]
        if omega_pol < best_omega:
            x, best_omega = x_pol, omega_pol
    return x, n_eval


def rng_seed(rng):
    """An integer seed derived from ``rng`` (int or Generator) for a scrambled Sobol' engine."""
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(2**31))
    return rng


def _distinct_starts(problem, X, omega, k, min_distance=0.15):
    """The best of ``X`` and up to ``k - 1`` more of the best, each at least ``min_distance``
    (unit cube, max norm) from those already chosen; physical units."""
    order = np.argsort(omega, kind="stable")
    U = problem.free_space.to_unit(X[order])
    chosen = [0]
    for i in range(1, len(U)):
        if len(chosen) >= k:
            break
        if np.min(np.max(np.abs(U[chosen] - U[i]), axis=1)) >= min_distance:
            chosen.append(i)
    return X[order][chosen]


def fe_check(result, scenario):
    """One FE run at the optimum: the surrogate-vs-FE difference at the observed entries.

    Parameters
    ----------
    result : InverseResult
    scenario : fe.Scenario
        The scenario the surrogate was trained on.

    Returns
    -------
    dict
        ``max_abs_diff`` (mm), ``max_diff_over_noise`` (largest |FE − surrogate| / σ_noise),
        ``rel_diff`` (‖FE − surrogate‖ / ‖FE‖), ``chi2_dof_fe`` (χ²/dof of the FE prediction
        against the data, noise only), ``fe_readings`` and ``ok`` (difference within the noise).
    """
    problem = result.problem
    fe = scenario.run(result.parameters).readings.ravel()
    idx = problem.misfit.output_indices
    fe_obs = fe[idx]
    mean, _ = problem.misfit.predict(result.x[None])
    diff = fe_obs - mean[0]
    sd = problem.misfit.noise_std
    resid = (fe_obs - problem.measurement.data) / sd
    return {
        "max_abs_diff": float(np.max(np.abs(diff))),
        "max_diff_over_noise": float(np.max(np.abs(diff) / sd)),
        "rel_diff": float(np.linalg.norm(diff) / np.linalg.norm(fe_obs)),
        "chi2_dof_fe": float(resid @ resid / max(result.dof, 1)),
        "fe_readings": fe_obs.tolist(),
        "ok": bool(np.max(np.abs(diff) / sd) <= 1.0),
    }
