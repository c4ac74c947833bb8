"""The inverse problem: a batched forward model, a measurement, a noise model and free parameters.

An :class:`InverseProblem` combines a model, a measurement, a noise model and a choice of free
parameters (the others fixed); its misfit ω(m) is thesis eq. (2.13). Parameters are searched in
the unit cube of the free parameter space (log-scaled parameters in log10).

A *model* is any object with ``space`` (a :class:`~podkrig.parameters.ParameterSpace` over all
its inputs), ``sensor_names``, ``load_levels`` and ``predict(X, return_std=True) -> (mean, std)``
with ``X`` ``(n, n_params)`` physical and ``mean``, ``std`` ``(n, n_loads * n_sensors)`` mm
(load-major). The POD-kriging surrogate is one (:class:`SurrogateModel`); :class:`FEModel` wraps
a scenario so that the same inversion can run with the FE model in the loop.
:func:`fix_from_scenario` completes a choice of free and fixed parameters from the scenario the
model was trained on.
"""

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from fe.scenarios import SCENARIOS, ScenarioSpec, build_scenario
from fe.sensors import absolute_displacements
from podkrig.online.misfit import Misfit
from podkrig.online.model_error import ModelError
from podkrig.online.rigid_body import RigidBodyModes, may_remove, rigid_body_modes
from podkrig.parameters import ParameterSpace

#: distance of the polish's start from the faces of the unit cube (see UnitCubeLeastSquares.polish_unit)
FACE_MARGIN = 1e-6


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
        self.load_unit = scenario.load_unit
        self.load_response = getattr(scenario, "load_response", "discrete")
        self.sensors = tuple(scenario.sensors)
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
        #: sensor name → unit of its readings (mm; kN for a nonlinear scenario's load reading)
        self.sensor_units = dict(zip(self.sensor_names, prov.get("sensor_units") or ("mm",) * len(self.sensor_names)))
        self.load_levels = np.asarray(prov["load_levels"], dtype=float)
        self.load_unit = prov.get("load_unit", "kN")
        self.scenario_spec = prov["scenario_spec"]
        name = self.scenario_spec.get("scenario") if isinstance(self.scenario_spec, dict) else None
        self.load_response = getattr(SCENARIOS.get(name), "load_response", "discrete")

    def predict(self, X, return_std=False):
        return self.surrogate.predict(X, return_std=return_std)

    @functools.cached_property
    def sensors(self):
        """The sensors of the scenario the surrogate was trained on (rebuilt from its spec, about
        0.5 s for the default diagonal test: only asked for when rigid-body motions may be removed)."""
        return tuple(self.scenario().sensors)

    def predict_unit(self, U, return_std=False):
        """``predict`` at unit-cube coordinates of ``space`` (no round trip through physical units)."""
        return self.surrogate.predict_unit(U, return_std=return_std)

    def scenario(self, solver="auto"):
        """The FE scenario the surrogate was trained on (rebuilt from its spec)."""
        return build_scenario(self.scenario_spec, solver=solver)


class UnitCubeLeastSquares:
    """Least squares on whitened residuals in the unit cube of ``free_space``: the Jacobian and the
    bounded polish shared by :class:`InverseProblem` and :class:`~podkrig.online.joint.JointProblem`.
    A subclass gives ``free_space`` and ``_residuals_batch(U)`` (whitened residuals, and prior
    residuals if any, at unit-cube points ``(n, n_free)`` → ``(n, n_residuals)``)."""

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
        u, nfev = self.polish_unit(np.clip(self.free_space.to_unit(np.atleast_2d(x0))[0], 0.0, 1.0), max_nfev)
        return self.free_space.from_unit(u[None])[0], nfev

    def polish_unit(self, u0, max_nfev=200):
        """:meth:`polish` in the unit cube of the free space: from ``u0`` ``(n_free,)`` in [0, 1];
        returns ``(u, n_evaluations)``. The start is moved ``FACE_MARGIN`` inside the cube: started
        exactly on a face (a GA optimum clipped to the box), scipy's 'trf' takes one step of about
        1e-10, meets its tolerance and stops there (found by mutation testing)."""
        u0 = np.clip(np.asarray(u0, dtype=float), FACE_MARGIN, 1.0 - FACE_MARGIN)
        sol = optimize.least_squares(self.residuals_unit, u0, jac=self.jacobian_unit, bounds=(0.0, 1.0),
                                     x_scale=1.0, max_nfev=max_nfev, method="trf")
        return sol.x, int(sol.nfev + 2 * len(u0) * sol.njev)


@dataclass(frozen=True, eq=False)
class InverseProblem(UnitCubeLeastSquares):
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
        Misfit kind (see :class:`~podkrig.online.misfit.Misfit`).
    model_error : bool
        Include the model's predictive variance in ``C_D`` (thesis eq. 2.10).
    rigid_body : {"auto", "remove", "keep"} or RigidBodyModes
        Removal of the rigid-body motion of absolute displacement readings from data and model
        (:mod:`podkrig.online.rigid_body`): "auto" for each DIC grid (and ``rigid_groups``),
        "remove" also for the other point displacement sensors together, "keep" none; or modes
        built already (None: none). The χ² then loses :attr:`n_removed` degrees of freedom.
    rigid_groups : dict of str to sequence of str, optional
        Group name → point displacement sensors whose rigid motion is fitted together.
    model_form_error : ModelError, optional
        The FE model's own model-form (discretisation) error of each observed entry
        (:mod:`podkrig.online.model_error`), added to ``C_D`` as ``diag(e²)`` (thesis eq. 2.10);
        None: none. :func:`~podkrig.online.calibrate.calibrate` estimates it.

    Notes
    -----
    Constructing a problem checks the parameter choice and that the model can be evaluated at the
    measured sensors and loads, and nothing more; the misfit (noise covariance, rigid-body modes,
    which may rebuild the scenario for its sensor positions) is built when first used.
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
    rigid_body: object = "auto"
    rigid_groups: dict | None = None
    model_form_error: ModelError | None = None

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
        object.__setattr__(self, "free", free)  # normalised: None means every parameter
        # data the model cannot be evaluated at (a sensor or load it does not have) are refused
        # here; the observation operator is an index map, cheap to build
        self.observation

    # the derived state is built on first use: constructing a problem (and each copy made by
    # dataclasses.replace, e.g. a noisy copy) only checks its arguments; the misfit may need the
    # sensor positions of the scenario (rigid-body removal), which a surrogate rebuilds from its spec

    @functools.cached_property
    def free_space(self):
        """The free parameters' :class:`~podkrig.parameters.ParameterSpace` (the search box)."""
        space = self.model.space
        return ParameterSpace(tuple(space.parameters[space.names.index(n)] for n in self.free))

    @functools.cached_property
    def _index(self):
        """Positions of the free parameters in the model's parameter vector."""
        return np.array([self.model.space.names.index(n) for n in self.free])

    @functools.cached_property
    def _template(self):
        """A full physical parameter vector with the fixed values in place (zeros where free)."""
        names = list(self.model.space.names)
        template = np.zeros(len(names))
        for n, v in self.fixed.items():
            template[names.index(n)] = v
        return template

    @functools.cached_property
    def _template_unit(self):
        """:attr:`_template` in the model's unit coordinates (the fixed parameters scaled once)."""
        return unit_template(self.model.space, self._index, self.fixed)

    @functools.cached_property
    def observation(self):
        """How the observed entries follow from the model's output
        (:meth:`~podkrig.online.measurement.Measurement.observation`)."""
        return self.measurement.observation(self.model.sensor_names, self.model.load_levels,
                                            getattr(self.model, "load_response", "discrete"),
                                            getattr(self.model, "load_unit", ""))

    @functools.cached_property
    def misfit(self):
        """The :class:`~podkrig.online.misfit.Misfit` ω(m) at physical free parameters."""
        rigid = self.rigid_body
        if not (rigid is None or isinstance(rigid, RigidBodyModes)):
            rigid = (rigid_body_modes(self.measurement, absolute_displacements(_model_sensors(self.model, rigid)),
                                      rigid, self.rigid_groups)
                     if may_remove(self.measurement.sensor_names, rigid, self.rigid_groups) else None)
        return Misfit(
            self._predict, self.measurement, self.noise, self.observation, self.prior_mean, self.prior_cov,
            kind=self.kind, model_error=self.model_error, rigid_body=rigid,
            form_error=None if self.model_form_error is None else self.model_form_error.std,
        )

    @functools.cached_property
    def _unit_misfit(self):
        """The misfit at unit-cube coordinates of the free space, or None.

        The free space is made of the model's own parameters, so free unit coordinates are the
        model's unit coordinates: a model with ``predict_unit`` (the surrogate) gets them without a
        round trip through physical units. None for a model without it, or with a prior (the prior
        is over physical values)."""
        if hasattr(self.model, "predict_unit") and self.prior_mean is None:
            return dataclasses.replace(self.misfit, model=self._predict_unit)
        return None

    @property
    def n_free(self):
        return len(self.free)

    @property
    def n_obs(self):
        return self.misfit.n_obs

    @property
    def n_removed(self):
        """Degrees of freedom taken by removed rigid-body motions (3 per DIC grid and load level)."""
        return self.misfit.n_removed

    def full(self, X):
        """Free parameter vectors ``(n, n_free)`` → full model inputs ``(n, n_params)``."""
        X = np.atleast_2d(X)
        full = np.tile(self._template, (len(X), 1))
        full[:, self._index] = X
        return full

    # without model_error the misfit drops the std: only the mean is evaluated (for kriging
    # O(n d) per point against the variance's O(n²): 20-30x fewer CPU seconds at n = 4 096)
    def _predict(self, X):
        if self.model_error and self.frozen_model_std is None:
            return self.model.predict(self.full(X), return_std=True)
        mean = self.model.predict(self.full(X))
        return mean, (np.broadcast_to(self.frozen_model_std, mean.shape) if self.model_error else None)

    def _predict_unit(self, U):
        full = np.tile(self._template_unit, (len(U), 1))
        full[:, self._index] = U
        if self.model_error and self.frozen_model_std is None:
            return self.model.predict_unit(full, return_std=True)
        mean = self.model.predict_unit(full)
        return mean, (np.broadcast_to(self.frozen_model_std, mean.shape) if self.model_error else None)

    def freeze_model_error(self, x):
        """The same problem with the model's predictive std frozen at ``x`` (free, physical).

        Only the model mean is then evaluated (several times cheaper for kriging). Used for dense
        sampling near the optimum, where the surrogate variance C_T changes little. A model without
        predictive variance (the FE model) has nothing to freeze: the problem is returned as it is.
        """
        _, std = self.model.predict(self.full(np.atleast_2d(x)), return_std=True)
        if std is None:
            return self
        return dataclasses.replace(self, frozen_model_std=np.asarray(std[0]))

    def omega(self, X):
        """ω at free parameter vectors ``(n, n_free)`` (physical), ``(n,)``."""
        return self.misfit(X)

    def omega_unit(self, U):
        """ω at unit-cube coordinates of the free space, ``(n,)``.

        Equal to :meth:`omega` at ``free_space.from_unit(U)`` to rounding; a model with
        ``predict_unit`` is evaluated at ``U`` directly (no prior: the prior is over physical values).
        """
        U = np.atleast_2d(np.asarray(U, dtype=float))
        if self._unit_misfit is not None:
            return self._unit_misfit(U)
        return self.misfit(self.free_space.from_unit(U))

    def chi2(self, X):
        """Data term (g − d)ᵀ C_D⁻¹ (g − d) at free parameter vectors ``(n, n_free)`` (physical), ``(n,)``."""
        return self.misfit.chi2(X)

    def parameters_at(self, x):
        """Every model parameter (free and fixed) at free values ``x`` ``(n_free,)``, ``{name: value}``."""
        return dict(zip(self.model.space.names, self.full(np.atleast_2d(x))[0].tolist()))

    def parts(self, x):
        """The tests of a joint problem at ``x``; none for one test (see :class:`~podkrig.online.joint.JointProblem`)."""
        return {}

    def measurement_summary(self):
        """``file``, ``sensors``, ``load_levels``, ``load_unit`` and ``n_obs`` of the data (JSON-able)."""
        meas = self.measurement
        rigid = self.misfit.rigid_body
        return {"file": str(meas.source), "sensors": list(meas.sensor_names),
                "load_levels": meas.load_levels.tolist(), "load_unit": getattr(self.model, "load_unit", "kN"),
                "n_obs": self.n_obs, **({} if rigid is None else {"rigid_body": rigid.to_dict()}),
                **({} if self.model_form_error is None else {"model_form_error": self.model_form_error.summary(meas)})}

    def with_noisy_data(self, x, rng):
        """The same problem with data g(x) + e, e ~ N(0, C_d) (a noise Monte Carlo copy; ``x`` free, physical)."""
        meas = self.measurement
        mean, _ = self.misfit.predict(np.atleast_2d(x))
        L = np.linalg.cholesky(self.noise.covariance_matrix(meas))
        copy = meas.with_data(mean[0] + L @ rng.standard_normal(len(mean[0])), source=meas.source + " (noisy copy)")
        return dataclasses.replace(self, measurement=copy)

    def _residuals_batch(self, U):
        """Whitened data residuals and prior residuals at unit-cube points, ``(n, n_obs [+ n_free])``."""
        U = np.atleast_2d(np.asarray(U, dtype=float))
        if self._unit_misfit is not None:
            return self._unit_misfit.whitened_residuals(U)
        X = self.free_space.from_unit(U)
        return np.hstack([self.misfit.whitened_residuals(X), self.misfit.prior_residuals(X)])

def _model_sensors(model, option):
    """The sensors of ``model`` (their positions say which readings are absolute displacements)."""
    sensors = getattr(model, "sensors", None)
    if sensors is None:
        raise ValueError(f"rigid_body = {option!r} needs the positions of the model's sensors, and this model "
                         f"({type(model).__name__}) has no 'sensors'; give rigid_body = 'keep' or RigidBodyModes")
    return sensors


def check_dof(n_obs, free, source="measurement", removed=0):
    """Refuse a calibration without degrees of freedom: ``n_obs − n_removed − n_free ≤ 0`` fits
    the data exactly whatever the model (χ²/dof is then undefined; ``removed``: the dof
    taken by removed rigid-body motions, :mod:`podkrig.online.rigid_body`). A prior-regularised
    problem built in code may have fewer; the study pipeline and the command line call this.

    Raises
    ------
    ValueError
        With both counts and what to do.
    """
    free = tuple(free)
    dof = int(n_obs) - int(removed) - len(free)
    if dof <= 0:
        rigid = f" − {removed} (rigid-body motions removed)" if removed else ""
        raise ValueError(
            f"{source}: {n_obs} reading(s) cannot identify {len(free)} free parameter(s) ({', '.join(free)}): "
            f"degrees of freedom n_obs{' − n_removed' if removed else ''} − n_free = {n_obs}{rigid} − {len(free)} = "
            f"{dof} ≤ 0. Add readings (more sensors or load levels) or fix parameters")
    return dof


def unit_template(space, free_index, fixed):
    """Unit-cube coordinates ``(n_params,)`` of a full parameter vector of ``space`` with the
    ``fixed`` values (name → value, physical) in place; the entries at ``free_index`` are
    placeholders for the free coordinates. Raises when a parameter is neither free nor fixed."""
    names = list(space.names)
    physical = np.array([p.lower for p in space.parameters], dtype=float)  # placeholders for the free
    for n, v in fixed.items():
        physical[names.index(n)] = v
    missing = [n for i, n in enumerate(names) if i not in set(np.asarray(free_index).tolist()) and n not in fixed]
    if missing:
        raise ValueError(f"parameter(s) {missing} are neither free nor fixed: give each a value (--fix NAME=VALUE)")
    return space.to_unit(physical[None])[0]


def fix_from_scenario(model, free=None, fixed=None):
    """Complete a choice of free and fixed parameters of ``model``.

    When ``fixed`` is given without ``free``, every other parameter is free. When ``free`` is
    given (or implied), each parameter that is neither free nor fixed keeps the value of the
    scenario the model was trained on (its spec's value, else the scenario's default), provided
    that value lies inside the model's trained box; a parameter left without a value is reported
    by :class:`InverseProblem`.

    Parameters
    ----------
    model : SurrogateModel or object
        A model with ``space`` and, to fill values, ``scenario_spec`` (a scenario spec dict).
    free : sequence of str, optional
        Free parameter names; default all of ``model.space`` not in ``fixed``.
    fixed : dict of str to float, optional
        Values of fixed parameters, in their units.

    Returns
    -------
    free : tuple of str or None
        None means every parameter of the model is free.
    fixed : dict of str to float
        ``fixed`` plus the values taken from the scenario.
    """
    fixed = dict(fixed or {})
    free = None if free is None else tuple(free)
    if free is None and fixed:
        free = tuple(n for n in model.space.names if n not in fixed)
    spec = getattr(model, "scenario_spec", None)
    if free is None or spec is None:
        return free, fixed
    spec = ScenarioSpec.from_dict(spec)
    defaults = {p.name: spec.parameters.get(p.name, p.default) for p in SCENARIOS[spec.scenario].PARAMETERS}
    for p in model.space.parameters:
        if p.name not in free and p.name not in fixed and p.lower <= defaults.get(p.name, np.nan) <= p.upper:
            fixed[p.name] = defaults[p.name]
    return free, fixed


__all__ = ["FEModel", "InverseProblem", "SurrogateModel", "UnitCubeLeastSquares", "check_dof", "fix_from_scenario"]
