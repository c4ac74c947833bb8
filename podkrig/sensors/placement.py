"""The whole placement job: candidates → sensitivities → criterion → search → comparison → spec.

:func:`place_sensors` computes the candidates' sensitivities at a Sobol' set of the prior box, builds
the chosen criterion, searches the layout (greedy, QR pivoting and GA, each finished by exchange),
and compares the chosen layout with the scenario's current one and with random layouts of the same
size — by every criterion, by the linearised 95 % interval widths, and optionally by a Monte-Carlo
run of the actual inversion under noise. :meth:`PlacementResult.spec` is the scenario spec with the
chosen sensors, which ``podkrig simulate --spec``, ``podkrig snapshots run --spec`` and a study's
``[scenario]`` table accept directly (:func:`spec_toml` writes it).
"""

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from fe.scenarios import ScenarioSpec
from podkrig.display import Displayed
from podkrig.sensors.candidates import current_candidates, user_candidates
from podkrig.sensors.criteria import (
    LayoutCriterion,
    SensorNoise,
    fisher_per_candidate,
    pod_per_candidate,
)
from podkrig.sensors.montecarlo import candidate_surrogate, interior_truths, monte_carlo
from podkrig.sensors.search import PlacementProblem, choose_layout
from podkrig.sensors.sensitivity import (
    CandidateFEModel,
    ExactSensitivitiesUnavailable,
    candidate_sensitivities,
    model_sensitivities,
    prior_points,
)
from podkrig.sensors.settings import PlacementSettings

logger = logging.getLogger(__name__)

SENSITIVITY_SOURCES = ("exact", "fe", "auto")  # see place_sensors(model=...)


@dataclass(frozen=True, eq=False, repr=False)
class LayoutScore(Displayed):
    """One layout judged by every criterion (and optionally by Monte Carlo).

    Attributes
    ----------
    label : str
        ``"chosen"``, ``"current"`` or ``"random 3"``.
    indices : ndarray of shape (k,)
    names : tuple of str
    criteria : dict of str to float
        Ψ_D, Ψ_A, Ψ_E, Ψ_POD (see :mod:`podkrig.sensors.criteria`).
    linearised_width : ndarray of shape (n_params,)
        Linearised 95 % interval widths, unit coordinates (mean over the Sobol' points).
    monte_carlo : MonteCarloResult or None
    """

    label: str
    indices: np.ndarray
    names: tuple
    criteria: dict
    linearised_width: np.ndarray
    monte_carlo: object = None

    def to_dict(self):
        return {"label": self.label, "sensors": list(self.names), "criteria": dict(self.criteria),
                "linearised_width_unit": self.linearised_width.tolist(),
                "monte_carlo": None if self.monte_carlo is None else self.monte_carlo.to_dict()}


@dataclass(frozen=True, eq=False, repr=False)
class PlacementResult(Displayed):
    """Outcome of :func:`place_sensors`.

    Attributes
    ----------
    base_spec : ScenarioSpec
        The scenario spec the placement was computed for.
    space : ParameterSpace
        Free parameters.
    candidates : CandidateSet
        Candidates (the current sensors appended, flagged ``is_current``).
    criterion : str
    noise : SensorNoise
    layout : LayoutResult
    contributions : ndarray of shape (k,)
        Loss increase when each chosen sensor is removed (criterion units).
    scores : tuple of LayoutScore
        Chosen, current (if any), random layouts.
    n_points : int
        Sobol' points of the box the criteria average over.
    sensitivity_seconds : float
    specimen : dict
        ``width``, ``height`` (mm) and ``blocks`` ``[[x0, y0, x1, y1], ...]`` for figures.
    zones : tuple of Zone
        Forbidden zones (for figures; candidates were filtered by them).
    """

    base_spec: ScenarioSpec
    space: object
    candidates: object
    criterion: str
    noise: SensorNoise
    layout: object
    contributions: np.ndarray
    scores: tuple
    n_points: int
    sensitivity_seconds: float
    specimen: dict = field(repr=False, default_factory=dict)
    zones: tuple = ()

    def spec(self):
        """The base spec with the chosen sensors (``sensors`` option, name → definition)."""
        sensors = {self.candidates.sensors[i].name: self.candidates.sensors[i].to_dict() for i in self.layout.indices}
        return ScenarioSpec(self.base_spec.scenario, {**self.base_spec.options, "sensors": sensors},
                            dict(self.base_spec.parameters))

    def score(self, label):
        return next(s for s in self.scores if s.label == label)

    def to_dict(self):
        return {
            "scenario_spec": self.spec().to_dict(), "base_spec": self.base_spec.to_dict(),
            "space": self.space.to_dict(), "criterion": self.criterion, "noise": self.noise.to_dict(),
            "layout": self.layout.to_dict(), "contributions": self.contributions.tolist(),
            "scores": [s.to_dict() for s in self.scores], "n_points": self.n_points,
            "n_candidates": len(self.candidates), "sensitivity_seconds": self.sensitivity_seconds,
        }


def _score(label, indices, names, criteria, mc):
    values = {k: float(c.value(indices[None])[0]) for k, c in criteria.items()}
    return LayoutScore(label, np.asarray(indices), tuple(names), values,
                       criteria["d"].linearised_widths(indices[None])[0], mc)


def random_layouts(problem, n, rng=0, max_tries=10_000):
    """``n`` random feasible layouts of ``problem.n_free`` free sensors (plus the required ones),
    ``(n, k)``; fewer if the constraints make them too rare."""
    gen = np.random.default_rng(rng)
    out = []
    for _ in range(max_tries):
        if len(out) == n:
            break
        free = gen.choice(problem.allowed, problem.n_free, replace=False)
        layout = problem.full(free[None])
        if problem.feasible(layout)[0]:
            out.append(layout[0])
    return np.array(out, dtype=np.intp).reshape(-1, len(problem.must_include) + problem.n_free)


def place_sensors(scenario, space, candidates, settings=None, *, noise=None, fixed=None, forbidden=(), model=None,
                  progress=None):
    """Choose the sensor layout that minimises the expected identification uncertainty.

    Parameters
    ----------
    scenario : fe.scenarios.Scenario
        A linear scenario (affine stiffness).
    space : ParameterSpace
        Free parameters with bounds and scales.
    candidates : CandidateSet
        E.g. :meth:`CandidateSettings.candidates <podkrig.sensors.settings.CandidateSettings.candidates>`.
    settings : PlacementSettings, optional
        The search (``k`` or ``budget``, criterion, Sobol' points, sensors always chosen, spacing,
        whether the scenario's current sensors are candidates — choosable, each costing the mean
        cost of the candidates of its kind, else 1 — and scored, search starts, prior information),
        the comparison (random layouts, Monte-Carlo realisations and truths, surrogate points) and
        the seed of the Sobol' set, the GA, the random layouts and the Monte Carlo
        (:mod:`podkrig.sensors.settings`). Default: :class:`PlacementSettings()`, which needs a
        ``k`` or ``budget``.
    noise : SensorNoise, optional
        Default: LVDT σ = 2 µm, DIC σ = 5 µm.
    fixed : dict, optional
        Values of other scenario parameters.
    forbidden : sequence of Zone
        Forbidden zones: current sensors inside or crossing one are scored but never chosen (build
        the candidates with the same zones).
    model : object or {"exact", "fe", "auto"}, optional
        Where the sensitivities come from. ``None`` or ``"exact"``: the scenario's affine FE model
        (one factorisation per point, exact derivatives). ``"fe"``: central differences of FE runs
        of the scenario (:class:`~podkrig.sensors.sensitivity.CandidateFEModel`; for loads that
        depend on the parameters, e.g. the flat jack's ``Km``, and nonlinear scenarios), the Monte
        Carlo then on a surrogate of the runs at the criterion's points (``surrogate_points`` unused). ``"auto"``: exact where the scenario allows it, else
        ``"fe"`` (logged). Or a batched model of the candidates' readings (see
        :func:`~podkrig.sensors.sensitivity.model_sensitivities`), e.g. a surrogate of snapshots
        whose scenario spec lists every candidate (current sensors included when
        ``include_current``) as a sensor: sensitivities by differences of it, and the Monte Carlo
        runs on it.
    progress : callable, optional
        ``progress(stage, done, total)``.

    Returns
    -------
    PlacementResult
    """
    settings = PlacementSettings() if settings is None else settings
    search, comparison, seed = settings.search, settings.comparison, settings.seed
    criterion, n_points, must_include = search.criterion, search.n_points, search.must_include
    include_current, min_spacing = search.include_current, search.min_spacing
    n_monte_carlo = comparison.n_monte_carlo
    noise = noise or SensorNoise()
    current_names = tuple(s.name for s in scenario.sensors)
    if include_current:
        taken = set(candidates.names)
        clash = [n for n in current_names if n in taken]
        if clash:
            raise ValueError(f"candidate names {clash} clash with the scenario's current sensors; rename them")
        current = current_candidates(scenario)
        for kind in set(current.kinds):  # the current sensors cost what the candidates of their kind cost
            same = [c for c, k in zip(candidates.cost, candidates.kinds) if k == kind]
            if same:
                current = current.with_cost(kind, float(np.mean(same)))
        candidates = candidates + current

    def stage(name):
        return None if progress is None else (lambda done, total: progress(name, done, total))

    X = prior_points(space, n_points, seed)
    if isinstance(model, str) and model not in SENSITIVITY_SOURCES:
        raise ValueError(f"model must be a batched model or one of {SENSITIVITY_SOURCES}; got {model!r}")
    sens = None
    if model is None or model in ("exact", "auto"):
        try:
            sens = candidate_sensitivities(scenario, space, candidates, X, fixed=fixed,
                                           progress=stage("sensitivities"))
            model = None
        except ExactSensitivitiesUnavailable as e:
            if model != "auto":
                raise
            logger.warning("%s: sensitivities from differences of FE runs instead", str(e).split(";")[0])
            model = "fe"
    fe_model = model == "fe"
    if fe_model:
        model = CandidateFEModel(scenario, space, candidates, fixed)
    if sens is None:
        sens = model_sensitivities(model, candidates, X, progress=stage("sensitivities"))
    F = fisher_per_candidate(sens, noise)
    criteria = {kind: LayoutCriterion(F, kind, search.prior_information) for kind in ("d", "a", "e")}
    criteria["pod"] = LayoutCriterion(pod_per_candidate(sens, noise)[0], "pod", 1.0)
    crit = criteria[criterion]
    must = candidates.index(must_include) if must_include else ()
    barred = [i for i in np.flatnonzero(candidates.is_current)
              if not _clear_of(candidates.sensors[i], forbidden, scenario.mesh)]
    problem = PlacementProblem(crit, candidates, k=search.k, budget=search.budget, must_include=tuple(must),
                               min_spacing=min_spacing, exclude=tuple(barred))
    layout = choose_layout(problem, methods=search.methods, rng=seed)
    contributions = crit.contributions(layout.indices)

    named = [("chosen", layout.indices)]
    if include_current:
        named.append(("current", np.flatnonzero(candidates.is_current)))
    # random layouts of the chosen size under the same constraints, from the new candidates only
    rproblem = PlacementProblem(crit, candidates, k=len(layout.indices), must_include=tuple(must),
                                min_spacing=min_spacing, exclude=tuple(set(np.flatnonzero(candidates.is_current).tolist()) - set(must)))
    named += [(f"random {i + 1}", L) for i, L in enumerate(random_layouts(rproblem, comparison.n_random, seed))]

    mc_sens = surrogate = truths = None
    if n_monte_carlo and model is not None and not fe_model:
        mc_sens, surrogate, truths = sens, model, interior_truths(space, comparison.n_truths, seed + 2)
    elif n_monte_carlo:
        n_sur = comparison.surrogate_points or max(n_points, 128)
        if n_sur == n_points or fe_model:  # FE runs: the surrogate learns from the runs made already
            mc_sens = sens
        else:
            mc_sens = candidate_sensitivities(scenario, space, candidates, prior_points(space, n_sur, seed + 1),
                                              fixed=fixed, progress=stage("surrogate snapshots"))
        surrogate = candidate_surrogate(mc_sens)
        truths = interior_truths(space, comparison.n_truths, seed + 2)
    scores = []
    for i, (label, L) in enumerate(named):
        mc = None
        if n_monte_carlo:
            mc = monte_carlo(surrogate, mc_sens, L, noise, truths, n_realisations=n_monte_carlo, rng=seed + i)
            if progress is not None:
                progress("monte carlo", i + 1, len(named))
        scores.append(_score(label, L, [candidates.names[j] for j in L], criteria, mc))
    mesh = scenario.mesh
    specimen = {"width": float(mesh.width), "height": float(mesh.height), "blocks": mesh.block_bounds.tolist()}
    return PlacementResult(scenario.spec, space, candidates, criterion, noise, layout, contributions,
                           tuple(scores), n_points, sens.seconds, specimen, tuple(forbidden))


def _clear_of(sensor, zones, mesh):
    """True when ``sensor`` is admissible under the forbidden ``zones``."""
    return user_candidates(mesh, {sensor.name: sensor.to_dict()}, forbidden=zones, strict=False).sensors != ()


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if not math.isfinite(f):
            raise ValueError(f"cannot write {f} to TOML")
        return repr(f)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_key(k):
    return k if k.replace("_", "").replace("-", "").isalnum() else _toml_value(k)


def spec_toml(spec, table=None):
    """A scenario spec as TOML text: a spec file (``table=None``) for ``--spec``, or the study's
    ``[scenario]`` table (``table="scenario"``). Sensors go to a ``[sensors]`` sub-table with one
    inline table per sensor."""
    d = spec.to_dict()
    sensors = d.pop("sensors", None)
    parameters = d.pop("parameters", {})
    prefix = f"{table}." if table else ""
    lines = [f"[{table}]"] if table else []
    lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in d.items() if v is not None]
    if parameters:
        lines += ["", f"[{prefix}parameters]"] + [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in parameters.items()]
    if sensors:
        lines += ["", f"[{prefix}sensors]"] + [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in sensors.items()]
    return "\n".join(lines) + "\n"
