"""Readings and parameter sensitivities of every candidate sensor from one FE solve per point.

The linear mesoscale model has a stiffness affine in its parts and loads linear in the load level
(:mod:`fe.assembly`, :mod:`fe.model`):

.. math::

    \\mathbf K(\\mathbf m)\\, \\mathbf q = \\mathbf f, \\qquad
    \\mathbf K(\\mathbf m) = \\sum_q θ_q(\\mathbf m)\\, \\mathbf K_q, \\qquad
    \\frac{\\partial \\mathbf q}{\\partial m_j}
      = -\\mathbf K^{-1} \\Big(\\sum_q \\frac{\\partial θ_q}{\\partial m_j} \\mathbf K_q\\Big) \\mathbf q .

So one factorisation per parameter point gives the displacement field and, with ``n_params`` more
back-substitutions on the same factors, its exact parameter derivatives. Every candidate's reading
is a linear operator on the field (``H`` of :func:`fe.sensors.sensor_operator`), so readings and
sensitivities of *all* candidates cost one sparse product: no FE run per candidate or per layout.

Loads may scale with parameters (the flat jack: jack pressure × ``Km``, release × ``σ0``): the
scenario's ``load_coefficients_at(values)`` gives the multipliers ``C(m)`` of the load patterns, and
the readings ``C(m) H q`` get the term ``(∂C/∂m) H q`` (central differences; exact for loads linear
in the parameters). The first point's readings of the scenario's own sensors are checked against
``scenario.run`` (one more factorisation): a scenario whose run is not this combination (the flat
jack with ``release = "exact"``) is an error pointing to :class:`CandidateFEModel`.

``∂θ/∂m`` comes from central differences of the scenario's ``theta`` (exact to round-off for the
masonry scenarios, whose θ is linear in each parameter). Sensitivities are returned with
respect to the *unit* coordinates ``u`` of the parameter space (log-scaled parameters in log10),
which is the scaling the criteria use: ``∂m/∂u = b − a`` (linear) or ``m ln(b/a)`` (log).
"""

import logging
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from fe.sensors import sensor_operator
from podkrig._qmc import rng_seed
from podkrig.offline.sampling import sobol

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Sensitivities:
    """Readings and sensitivities of the candidate sensors at a set of parameter points.

    Attributes
    ----------
    X : ndarray of shape (n_points, n_params)
        Parameter points (free parameters), physical units.
    readings : ndarray of shape (n_points, n_loads, n_channels)
        Readings of every candidate channel, mm.
    jacobian : ndarray of shape (n_points, n_loads, n_channels, n_params)
        ``∂ reading / ∂ u_j``, mm per unit coordinate of the free space.
    channel_sensor : ndarray of shape (n_channels,)
        Index of the candidate each channel belongs to.
    channel_names : tuple of str
    candidates : CandidateSet
    space : ParameterSpace
        The free parameters.
    fixed : dict of str to float
        Values of the scenario's other parameters (the rest keep the scenario defaults).
    load_levels : ndarray of shape (n_loads,)
    load_unit : str
    seconds : float
        Wall time of the computation, s.
    """

    X: np.ndarray
    readings: np.ndarray
    jacobian: np.ndarray
    channel_sensor: np.ndarray
    channel_names: tuple
    candidates: object
    space: object
    fixed: dict
    load_levels: np.ndarray
    load_unit: str
    seconds: float

    @property
    def n_points(self):
        return self.X.shape[0]

    @property
    def n_params(self):
        return self.X.shape[1]

    def channels_of(self, indices):
        """Channel indices of the candidates ``indices`` (in candidate order)."""
        indices = np.atleast_1d(np.asarray(indices, dtype=np.intp))
        return np.concatenate([np.flatnonzero(self.channel_sensor == i) for i in indices])


def prior_points(space, n, rng=0):
    """``n`` scrambled Sobol' points of the free parameters' box (unit → physical), ``(n, n_params)``;
    ``rng`` (int or Generator) scrambles them: an integer is the design's seed."""
    return space.from_unit(sobol(n, space.n_params, rng_seed(rng)))


def _central_differences(f, values, names, rel_step=1e-6):
    """``∂f/∂m_j`` of a function of the full parameter dict by central differences (relative step
    ``rel_step``), ``(n_free, *f.shape)``; exact to round-off for ``f`` linear in each parameter
    (the masonry θ, the flat jack's load multipliers)."""
    out = []
    for name in names:
        m = values[name]
        h = rel_step * max(abs(m), 1e-12)
        plus, minus = dict(values), dict(values)
        plus[name], minus[name] = m + h, m - h
        out.append((np.asarray(f(plus), dtype=float) - np.asarray(f(minus), dtype=float)) / (2 * h))
    return np.array(out)


def _dm_du(space, x):
    """``∂m/∂u`` of each free parameter at ``x`` (physical), ``(n_params,)``."""
    lo, hi = space.lower, space.upper
    log = np.array([s == "log" for s in space.scales])
    return np.where(log, x * np.log(hi / np.where(log, lo, 1.0)), hi - lo)


def candidate_sensitivities(scenario, space, candidates, X, *, fixed=None, progress=None):
    """Readings and unit-coordinate sensitivities of all candidates at the points ``X``.

    Parameters
    ----------
    scenario : fe.scenarios.Scenario
        A linear scenario with an affine stiffness (``scenario.model.stiffness``).
    space : ParameterSpace
        Free parameters (names of the scenario's parameters) with bounds and scales.
    candidates : CandidateSet
    X : array_like of shape (n_points, n_params)
        Parameter points, physical units.
    fixed : dict of str to float, optional
        Values of other scenario parameters.
    progress : callable, optional
        ``progress(done, total)`` after each point.

    Returns
    -------
    Sensitivities

    Raises
    ------
    ValueError
        A scenario without an affine linear model, or whose loads depend on the parameters (checked
        at the first point); unknown parameter names.
    """
    model = getattr(scenario, "model", None)
    if model is None or not hasattr(model, "stiffness"):
        raise ExactSensitivitiesUnavailable(
            f"scenario {scenario.name!r} has no affine linear model, which exact sensitivities need; use "
            "differences of FE runs (place_sensors(..., model='fe'), podkrig sensors --sensitivities fe) or a "
            "surrogate of the candidates")
    X = np.atleast_2d(np.asarray(X, dtype=float))
    names = space.names
    unknown = [n for n in list(names) + list(fixed or {}) if n not in scenario.parameters]
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown} of {scenario.name}; known: {list(scenario.parameters)}")
    t0 = time.perf_counter()
    H, channel_names = sensor_operator(scenario.mesh, candidates.sensors)
    obs = (H @ model.transform).tocsr()
    channel_sensor = np.repeat(np.arange(len(candidates)), [len(s.channel_names) for s in candidates.sensors])
    stiff = model.stiffness
    n_pat, p = model.rhs.shape[1], len(names)
    n_loads = len(scenario.load_levels)
    readings = np.empty((len(X), n_loads, len(channel_names)))
    jac = np.empty((len(X), n_loads, len(channel_names), p))
    for k, x in enumerate(X):
        values = scenario.resolve({**(fixed or {}), **dict(zip(names, x.tolist()))})
        theta = scenario.theta(values)
        dtheta = _central_differences(scenario.theta, values, names)  # (p, n_parts)
        C, dC = _load_coefficients(scenario, values, names)  # (n_loads, n_pat), (p, n_loads, n_pat)
        model.solver.factorize(stiff.values(theta))
        Q = model.solver.solve(model.rhs).reshape(model.n_dofs, n_pat)
        R = np.empty((model.n_dofs, p * n_pat))
        for j in range(p):
            dK = sp.csr_matrix((dtheta[j] @ stiff.data, stiff.indices, stiff.indptr), shape=(stiff.n, stiff.n))
            R[:, j * n_pat:(j + 1) * n_pat] = -(dK @ Q)
        dQ = model.solver.solve(R).reshape(model.n_dofs, p * n_pat)
        obs_Q = np.asarray(obs @ Q)  # (channel, pattern)
        readings[k] = C @ obs_Q.T
        if k == 0:
            _check_affine_readings(scenario, values, C, Q)
        dR = np.asarray(obs @ dQ).reshape(len(channel_names), p, n_pat)  # channel, param, pattern
        # d(C q)/dm = C dq/dm + dC/dm q: the second term for loads that scale with a parameter
        jac[k] = (np.einsum("lp,cjp->lcj", C, dR) + np.einsum("jlp,cp->lcj", dC, obs_Q)) * _dm_du(space, x)
        if progress is not None:
            progress(k + 1, len(X))
    seconds = time.perf_counter() - t0
    logger.info("sensitivities of %d candidates at %d points in %.2f s", len(candidates), len(X), seconds)
    return Sensitivities(X, readings, jac, channel_sensor, tuple(channel_names), candidates, space,
                         dict(fixed or {}), np.asarray(scenario.load_levels, float), scenario.load_unit, seconds)


class ExactSensitivitiesUnavailable(ValueError):
    """The scenario has no affine linear model on fixed load patterns: exact sensitivities cannot
    represent it; :class:`CandidateFEModel` with :func:`model_sensitivities` can."""


def _load_coefficients(scenario, values, names):
    """The load multipliers at ``values`` ``(n_loads, n_patterns)`` and their derivatives
    ``(n_free, n_loads, n_patterns)`` (zero for the wall tests; exact to round-off for the flat
    jack's, linear in Km and σ0)."""
    try:
        C = np.asarray(scenario.load_coefficients_at(values), dtype=float)
    except NotImplementedError as e:
        raise ExactSensitivitiesUnavailable(f"scenario {scenario.name!r}: {e}; use differences of FE runs "
                                            "(podkrig sensors --sensitivities fe; place_sensors(..., model='fe'))") from None
    return C, _central_differences(scenario.load_coefficients_at, values, names).reshape((len(names),) + C.shape)


def _check_affine_readings(scenario, values, C, Q, rtol=1e-6):
    """Raise when the affine readings of the scenario's own sensors at ``values`` differ from
    ``scenario.run(values)`` (a scenario whose ``run`` is not the load patterns' combination)."""
    if not scenario.sensors:
        return
    H, _ = sensor_operator(scenario.mesh, scenario.sensors)
    affine = C @ np.asarray((H @ scenario.model.transform) @ Q).T
    exact = scenario.run(values).readings
    scale = max(float(np.abs(exact).max()), 1e-300)
    if np.abs(affine - exact).max() > rtol * scale:
        raise ExactSensitivitiesUnavailable(
            f"scenario {scenario.name!r}: its readings are not the combination of its load patterns that exact "
            "sensitivities assume; use differences of FE runs instead (podkrig sensors --sensitivities fe or "
            "auto; place_sensors(..., model='fe')), or a surrogate of the candidates (model=..., see "
            "podkrig.sensors.sensitivity.model_sensitivities)")


class CandidateFEModel:
    """The readings of every candidate from FE runs of the scenario, as a batched model for
    :func:`model_sensitivities`: one ``scenario.run(..., field=True)`` per row, each candidate read
    off the displacement field by its operator ``H`` (:func:`fe.sensors.sensor_operator`).

    The path for scenarios that exact sensitivities cannot represent: loads that scale with a
    parameter (the flat jack's ``Km`` and ``σ0``) and nonlinear scenarios. Costs
    ``1 + 2 n_params`` FE runs per parameter point (central differences).

    Parameters
    ----------
    scenario : fe.scenarios.Scenario
        Any scenario whose ``run`` returns the displacement field.
    space : ParameterSpace
        Free parameters (names of the scenario's parameters).
    candidates : CandidateSet
    fixed : dict of str to float, optional
        Values of other scenario parameters.
    """

    def __init__(self, scenario, space, candidates, fixed=None):
        unknown = [n for n in list(space.names) + list(fixed or {}) if n not in scenario.parameters]
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown} of {scenario.name}; known: {list(scenario.parameters)}")
        self.scenario, self.space, self.fixed = scenario, space, dict(fixed or {})
        self._H, self.sensor_names = sensor_operator(scenario.mesh, candidates.sensors)
        self.load_levels = np.asarray(scenario.load_levels, dtype=float)
        self.load_unit = scenario.load_unit
        self.n_runs = 0

    def predict(self, X):
        """Readings ``(n, n_loads * n_channels)`` mm at the parameter rows ``X`` (physical)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        out = np.empty((len(X), len(self.load_levels) * len(self.sensor_names)))
        for i, x in enumerate(X):
            field = self.scenario.run({**self.fixed, **dict(zip(self.space.names, x.tolist()))}, field=True).field
            out[i] = (self._H @ field.reshape(len(field), -1).T).T.ravel()
        self.n_runs += len(X)
        return out


def model_sensitivities(model, candidates, X, *, step=1e-4, progress=None):
    """Readings and sensitivities of the candidates from any batched model of their readings — a
    POD-kriging surrogate (e.g. :class:`podkrig.online.problem.SurrogateModel` of a store whose
    scenario spec lists every candidate as a sensor) or :class:`podkrig.online.problem.FEModel` —
    by central differences in the unit cube (one-sided at the box faces). This is the path for
    scenarios without an affine linear model (nonlinear ones): no solver internals are needed.

    Parameters
    ----------
    model : object
        ``space`` (the free parameters), ``sensor_names`` (the candidates' channel names, in
        candidate order), ``load_levels`` and ``predict(X) -> (n, n_loads * n_channels)`` mm.
    candidates : CandidateSet
    X : array_like of shape (n_points, n_params)
    step : float
        Difference step in unit coordinates.
    progress : callable, optional
        ``progress(done, total)`` after each point.

    Returns
    -------
    Sensitivities
    """
    t0 = time.perf_counter()
    space = model.space
    names = tuple(n for s in candidates.sensors for n in s.channel_names)
    if tuple(model.sensor_names) != names:
        raise ValueError("the model's sensors must be the candidates' channels in candidate order "
                         f"(first expected {list(names[:3])}, got {list(model.sensor_names[:3])}): build its "
                         "snapshots with the candidates as the scenario's sensors")
    X = np.atleast_2d(np.asarray(X, dtype=float))
    p, n_l, n_ch = space.n_params, len(model.load_levels), len(names)
    readings = np.empty((len(X), n_l, n_ch))
    jac = np.empty((len(X), n_l, n_ch, p))
    for k, u in enumerate(space.to_unit(X)):
        U = np.repeat(u[None], 1 + 2 * p, axis=0)
        idx = np.arange(p)
        U[1 + 2 * idx, idx] = np.minimum(u + step, 1.0)
        U[2 + 2 * idx, idx] = np.maximum(u - step, 0.0)
        Y = np.asarray(model.predict(space.from_unit(U))).reshape(1 + 2 * p, n_l, n_ch)
        readings[k] = Y[0]
        h = U[1 + 2 * idx, idx] - U[2 + 2 * idx, idx]
        jac[k] = np.moveaxis((Y[1::2] - Y[2::2]) / h[:, None, None], 0, -1)
        if progress is not None:
            progress(k + 1, len(X))
    channel_sensor = np.repeat(np.arange(len(candidates)), [len(s.channel_names) for s in candidates.sensors])
    return Sensitivities(X, readings, jac, channel_sensor, names, candidates, space, {},
                         np.asarray(model.load_levels, float), getattr(model, "load_unit", "kN"),
                         time.perf_counter() - t0)
