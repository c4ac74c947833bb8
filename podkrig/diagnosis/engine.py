"""Model diagnosis: does the calibrated model explain the data within the noise, and if not, why?

:func:`diagnose` runs five steps on a scenario, a measurement and its noise model:

1. **Calibrate the base model** surrogate first: a POD-kriging surrogate over the free parameters
   (built here from a Sobol' design unless one is given), GA inversion with least-squares polish
   (:func:`podkrig.online.invert.invert`), then a least-squares polish with the FE model itself so that
   the adequacy test is not blurred by surrogate error. The data covariance is
   ``C_D = C_d + C_T`` (thesis eq. 2.10), with the model-form part ``C_T`` *estimated* per
   reading from the scenario on a mesh refined twice (:mod:`podkrig.online.model_error`), or a
   fixed relative tolerance the user gives.
2. **Adequacy**: χ² of the whitened residuals ``r = L⁻¹(d − g(m*))`` (``C_D = L Lᵀ``) against
   χ²(n_obs − n_free), and the residual structure across sensors and load levels.
3. **Score every candidate cause** (:mod:`podkrig.diagnosis.candidates`) at every location:
   screening by the share of the residual its signature ``s`` (whitened effect of a moderate
   strength) explains beyond the span of the current model's Jacobian ``J``,
   ``Δχ²_lin = (sᵀ P r)² / (sᵀ P s)``, ``P = I − J J⁺``; then a nonlinear FE refit, with the base
   parameters, the causes already found and the candidate's parameter free, of the best-screened
   locations. The likelihood-ratio statistic ``Δχ² = χ²_current − χ²_ext`` is χ²(1) under the
   null (a ½χ²(0) + ½χ²(1) mixture when the neutral value is a bound), and its p-value is
   multiplied by the number of candidates times the candidate's number of locations (Bonferroni),
   so that trying 200 joint segments does not manufacture a finding. A cause is named only when
   the effect *left after refitting* (``max |P L⁻¹ Δg|``, the part of its change of the readings
   the current parameters cannot absorb) is at least ``MIN_EFFECT`` σ.
4. **Several causes in turn** (forward selection): the best significant candidate joins the model,
   and the scoring runs again against the extended model, until no candidate is significant or
   ``max_causes`` are in. After each addition a backward check refits without each earlier cause
   and drops one that is no longer significant (it stood in for the later ones). Candidates
   rank by evidence: effects that survive refitting first, then by corrected p-value, then Δχ².
   *Inadequate* when the χ² test of the base model is significant at ``alpha / 10``, some
   cause is named, or some candidate's corrected likelihood-ratio test is significant at the same
   ``alpha / 10`` although its effect is too small to name (an omnibus χ² over hundreds of degrees of freedom
   dilutes an effect that one candidate's one-parameter test sees clearly; the verdict has the
   power of the candidates' own tests). Candidates whose fit as the first cause is within a likelihood ratio of 20 of
   the best are reported as alternatives the data cannot tell apart.
5. **Gain**: χ²/dof and misfit before and after (per step and overall), AIC/BIC, and the error on
   the highest load level predicted by both models fitted without it.

All FE work reuses the scenario's factorisation pattern; a diagnosis of the default diagonal test
is a few hundred FE solves.
"""

import logging
import time
from typing import NamedTuple

import numpy as np
from scipy import linalg, optimize, stats

from fe.sensors import absolute_displacements
from podkrig.diagnosis.candidates import CANDIDATES, DEFAULT_CANDIDATES, FEContext
from podkrig.diagnosis.settings import DiagnosisSettings
from podkrig.online.calibrate import model_form_error
from podkrig.online.data_check import check_readings, surrogate_training_outputs
from podkrig.online.model_error import DEFAULT_RATE, FALLBACK_TOLERANCE
from podkrig.diagnosis.results import (
    CHI2_ALPHA_SHARE,
    Alternative,
    CandidateScore,
    Cause,
    DiagnosisResult,
    Fit,
    Step,
)
from podkrig._qmc import rng_seed
from podkrig.offline.sampling import sobol
from podkrig.online.invert import invert
from podkrig.online.settings import InversionSettings
from podkrig.online.problem import InverseProblem, SurrogateModel
from podkrig.online.rigid_body import project_out, rigid_body_modes
from podkrig.surrogate.kriging import OrdinaryKriging
from podkrig.surrogate.podkriging import PODKriging

logger = logging.getLogger(__name__)

#: likelihood ratio within which two explanations count as equally supported
EQUIVALENCE_RATIO = 20.0
#: smallest effect (largest change of a reading, in σ) that names a cause: smaller, diffuse
#: "effects" fitted over many readings are model-form error, not a physical finding
MIN_EFFECT = 2.0
#: candidates with at most this many locations get their visibility from both ends of the range
_EXACT_VISIBILITY = 20


def build_base_surrogate(scenario, space, values, n_train=64, rng=0):
    """A POD-kriging surrogate of the scenario's readings over ``space`` (others at ``values``):
    ``n_train`` Sobol' FE runs, exponent fitted on the dominant mode (``beta="fit-shared"``);
    ``rng`` (int or Generator) scrambles the Sobol' design: an integer is its seed."""
    X = space.from_unit(sobol(n_train, space.n_params, rng_seed(rng)))
    Y = np.stack([scenario.run({**values, **space.as_params(x)}).readings for x in X])
    sur = PODKriging(kriging=OrdinaryKriging(beta="fit-shared"), space=space).fit(X, Y)
    sur.provenance_.update({  # what an inversion model needs to know (as fit_from_store records it)
        "scenario_spec": scenario.spec.to_dict(), "sensor_names": list(scenario.sensor_names),
        "load_levels": scenario.load_levels.tolist(), "load_unit": scenario.load_unit, "output": "readings",
        "sensor_units": [scenario.sensor_units[n] for n in scenario.sensor_names],
        "n_train": n_train,
    })
    return sur


class _Fitter:
    """Least-squares fits of base and extended FE models to a subset of the observed entries.

    ``rigid_body`` (:class:`~podkrig.online.rigid_body.RigidBodyModes` of all observed entries, or
    None): rigid-body motions removed from data and model alike — the whitened residual with the
    whitened rigid modes projected out, ``(I − Q Qᵀ) L⁻¹ (g − d)``, whose χ² has
    ``n_removed`` fewer degrees of freedom.
    """

    def __init__(self, ctx, space, measurement, noise, rows, model_error=None, rigid_body=None):
        self.ctx, self.space = ctx, space
        sc = ctx.scenario
        idx = measurement.output_indices(sc.sensor_names, sc.load_levels)
        C = data_covariance(measurement, noise, model_error)
        self.rows = np.asarray(rows)
        self.idx = idx[self.rows]
        self.d = measurement.data[self.rows]
        self.L = np.linalg.cholesky(C[np.ix_(self.rows, self.rows)])
        self.rigid = None if rigid_body is None else rigid_body.subset(self.rows)
        self.n_removed = 0 if self.rigid is None else self.rigid.n_removed
        self._Q = self.rigid.whitened_basis(self.L) if self.n_removed else None

    def whiten(self, R):
        """``L⁻¹ (g − d)`` of full readings ``R`` at the fitted entries (rigid motion projected out)."""
        return project_out(self._Q, linalg.solve_triangular(self.L, R.ravel()[self.idx] - self.d, lower=True))

    def observed(self, R):
        """Full readings ``R`` at the fitted entries, rigid motion removed, mm."""
        v = R.ravel()[self.idx]
        return v if self.rigid is None else self.rigid.remove(v)

    def values(self, u):
        return {**self.ctx.values, **self.space.as_params(self.space.from_unit(np.clip(u, 0, 1)[None])[0])}

    def fit(self, u0, terms=(), t0=(), max_nfev=60):
        """Least-squares fit from unit coordinates ``u0`` of the base parameters, with the causes
        ``terms`` (:class:`Term`, in the order found) switched on from
        fit coordinates ``t0``; returns a :class:`Fit` whose ``effects`` follow ``terms``."""
        p, terms = len(u0), list(terms)

        def effect_values(z):
            return [term.parameter.from_fit(float(np.clip(t, 0, 1))) for term, t in zip(terms, z[p:])]

        def readings(z):
            values = self.values(z[:p])
            if not terms:
                return self.ctx.readings(values)
            cs = effect_values(z)
            found = [(term.candidate, term.location, c) for term, c in zip(terms[:-1], cs[:-1])]
            return terms[-1].candidate.readings(self.ctx, values, terms[-1].location, cs[-1], found=found)

        def residual(z):
            return self.whiten(readings(z))

        z0 = np.clip(np.append(np.asarray(u0, dtype=float), np.asarray(t0, dtype=float)), 0.0, 1.0)
        sol = optimize.least_squares(residual, z0, bounds=(0.0, 1.0), method="trf", jac="2-point",
                                     diff_step=1e-6, x_scale=1.0, max_nfev=max_nfev)
        z = sol.x
        values = self.values(z[:p])
        return Fit(
            values=values, free={n: values[n] for n in self.space.names}, effects=tuple(effect_values(z)),
            chi2=float(sol.fun @ sol.fun), n_obs=len(self.rows), n_params=len(z),
            readings=readings(z), jacobian=sol.jac, n_removed=self.n_removed,
        )


def data_covariance(measurement, noise, model_error=None):
    """``C_D = C_d + C_T`` (thesis eq. 2.10), mm², with the model-form part
    ``C_T = diag(e_i²)``: ``model_error`` ``(n_obs,)`` mm is the standard deviation of each
    reading's model-form error (estimated discretisation error, or a fixed tolerance ``ε |d_i|``:
    :func:`podkrig.online.model_error.tolerance_error`)."""
    C = noise.covariance_matrix(measurement)
    if model_error is not None:
        C = C + np.diag(np.asarray(model_error, dtype=float) ** 2)
    return C


def diagnose(scenario, measurement, noise, space, settings=None, *, fixed=None, surrogate=None, candidates=None,
             model_error_rate=DEFAULT_RATE, refit_locations=3, progress=None, rigid_body="auto", rigid_groups=None,
             range_check=True):
    """Diagnose a calibrated FE model against measured data, naming missing causes in turn.

    Parameters
    ----------
    scenario : fe.Scenario
        The virtual test; parameters not in ``space`` stay at its defaults (or ``fixed``).
    measurement : Measurement
        Measured readings (a subset of the scenario's sensors and load levels), mm.
    noise : NoiseModel
    space : ParameterSpace
        The base model's free parameters with bounds and scales.
    settings : DiagnosisSettings, optional
        ``alpha``: significance level of the (multiplicity-corrected) candidate tests (the χ² test
        runs at ``alpha * CHI2_ALPHA_SHARE``); ``model_tolerance``: a fixed relative model-form
        tolerance ε, ``C_T = diag((ε d)²)`` (thesis eq. 2.10), the user's override — by default
        (None) each reading's model-form error is *estimated* from the scenario on a mesh refined
        twice at the calibrated values (:func:`podkrig.online.calibrate.model_form_error`);
        ``max_causes``: most causes named in turn (forward selection: each round refits the base
        parameters with the causes already found and adds the most significant candidate, until
        nothing is significant or the model is adequate); ``seed``: of the surrogate design and the
        GA; ``n_train``: Sobol' FE runs of the base surrogate when none is given. Default:
        ``DiagnosisSettings()``.
    fixed : dict of str to float, optional
        Values of non-free parameters that differ from the scenario's defaults.
    surrogate : PODKriging, optional
        A surrogate of the scenario's readings over ``space``, with its provenance (from
        :func:`build_base_surrogate` or a store; built here when not given:
        ``settings.n_train`` Sobol' FE runs, about a second for the default test). Its space may
        hold parameters besides ``space``'s (a study's surrogate when some of its parameters are
        held at a value): those are fixed at their value in ``fixed`` (else the scenario's
        default), which must lie in the surrogate's trained range.
    candidates : sequence of str, optional
        Names from :data:`~podkrig.diagnosis.candidates.CANDIDATES` (default:
        :data:`~podkrig.diagnosis.candidates.DEFAULT_CANDIDATES`, all but ``nonlinearity_onset``,
        whose strength scan costs 10–20 nonlinear runs).
    model_error_rate : float
        Convergence rate p assumed by the Richardson factor ``2^p / (2^p − 1)`` of the estimate.
    refit_locations : int
        Locations per candidate refitted with the FE model after screening.
    progress : callable, optional
        ``progress(stage, done, total)``.
    rigid_body : {"auto", "remove", "keep"}
        Rigid-body motions removed from data and model (:mod:`podkrig.online.rigid_body`): "auto"
        of each DIC grid (and of ``rigid_groups``), "remove" also of the other point displacement
        sensors together, "keep" none. χ² dof lose 3 per group and load level.
    rigid_groups : dict of str to sequence of str, optional
        Group name → point displacement sensors whose rigid motion is fitted together.
    range_check : bool
        Refuse readings far outside every training run of the base surrogate (a unit or sign
        error: :func:`~podkrig.online.data_check.check_readings`), before the calibration.

    Returns
    -------
    DiagnosisResult

    Raises
    ------
    MeasurementCheckError
        With ``range_check``: the readings of a sensor 20× larger or smaller than every training
        run, or of the opposite sign.
    """
    if not measurement.complete or measurement.reference_load is not None:
        raise ValueError(f"{measurement.source}: the diagnosis needs every sensor read at each load level (no "
                         "missing cells, no zero reference); invert such a log with 'podkrig invert' instead")
    t_start = time.perf_counter()
    say = progress or (lambda *a: None)
    names = list(candidates or DEFAULT_CANDIDATES)
    unknown = [n for n in names if n not in CANDIDATES]
    if unknown:
        raise ValueError(f"unknown candidate cause(s) {unknown}; known: {list(CANDIDATES)}")
    settings = DiagnosisSettings() if settings is None else settings
    alpha, max_causes, rng = settings.alpha, settings.max_causes, settings.seed
    values0 = scenario.resolve(fixed)
    ctx = FEContext(scenario, space.names, values0, offset_scale=np.max(np.abs(measurement.values)),
                    bounds={n: (float(lo), float(hi)) for n, lo, hi in zip(space.names, space.lower, space.upper)})
    rigid = rigid_body_modes(measurement, absolute_displacements(scenario.sensors), rigid_body, rigid_groups)

    # 1. base calibration: surrogate first, FE last (with the model-form error at the surrogate's optimum)
    say("calibration", 0, 4)
    if surrogate is None:
        surrogate = build_base_surrogate(scenario, space, values0, n_train=settings.n_train, rng=rng)
        ctx.n_runs += settings.n_train
    if range_check:  # the measurement check of every door (unit slips; a reversed gauge is a candidate here)
        check_readings(measurement, noise, scenario.sensor_names, scenario.load_levels, "discrete",
                       surrogate_training_outputs(surrogate), runs="surrogate", signs=False)
    say("calibration", 1, 4)
    model = SurrogateModel(surrogate)
    held = {n: float(values0[n]) for n in model.space.names if n not in space.names}
    problem = InverseProblem(model, measurement, noise, rigid_body=rigid, free=tuple(space.names), fixed=held)
    inv = invert(problem, **InversionSettings(seed=rng).options())
    say("calibration", 2, 4)
    asked = "estimated" if settings.model_tolerance is None else settings.model_tolerance
    model_error = model_form_error(scenario, {**values0, **dict(zip(space.names, map(float, inv.x)))}, measurement,
                                   asked, rigid_body=rigid, rate=model_error_rate, fallback=FALLBACK_TOLERANCE)
    ctx.n_runs += 2 if model_error.method == "two meshes" else 0
    error_std = model_error.std
    say("calibration", 3, 4)
    fitter = _Fitter(ctx, space, measurement, noise, np.arange(measurement.n_obs), error_std, rigid)
    noise_std = np.sqrt(np.diag(data_covariance(measurement, noise, error_std)))
    base = fitter.fit(space.to_unit(inv.x[None])[0])
    ctx.base_values = dict(base.values)  # the reference of candidates that precompute (nonlinearity_onset)
    say("calibration", 4, 4)
    p_chi2 = float(stats.chi2.sf(base.chi2, base.dof))
    structure = residual_structure(fitter.whiten(base.readings), measurement, noise_std)

    # 2. forward selection: score every candidate against the current model, add the best, repeat
    n_applicable = max(sum(CANDIDATES[n].not_applicable(ctx) is None for n in names), 1)
    terms, steps, current, first_round = [], [], base, None
    while len(terms) < max_causes:
        scores = _score_round(names, ctx, fitter, current, terms, space, n_applicable, alpha, refit_locations,
                              noise_std, say, len(steps))
        first_round = first_round if first_round is not None else scores
        ranked = [s for s in scores if s.applicable]
        best = ranked[0] if ranked else None
        if best is None or not (best.p_corrected < alpha and best.effect_left >= MIN_EFFECT):
            break
        before = current
        terms = terms + [Term(CANDIDATES[best.name], best.location, best.parameter, best.log_correction)]
        current = best.fit
        dropped = None
        if len(terms) > 1:
            terms, current, dropped = _drop_redundant(fitter, space, terms, current, alpha)
        steps.append(Step(score=best, chi2_before=before.chi2, chi2_after=current.chi2,
                          p_value_after=float(stats.chi2.sf(current.chi2, current.dof)), dropped=dropped))
    ranked = first_round or []
    inapplicable = []
    cause_found = bool(terms)
    # the gate has the power of the candidates' own tests: "adequate" only when the χ² test passes and
    # no candidate's multiplicity-corrected likelihood-ratio test is significant at the same level
    # (alpha * CHI2_ALPHA_SHARE): one too small or diffuse to name still means the model misses something
    significant = any(s.applicable and s.p_corrected < alpha * CHI2_ALPHA_SHARE for s in (first_round or []))
    verdict = "inadequate" if (p_chi2 < alpha * CHI2_ALPHA_SHARE or cause_found or significant) else "adequate"
    best = steps[0].score if steps else None
    alternatives = _alternatives(best, first_round, alpha) if steps else []
    extended = current if cause_found else None
    extended_p = None if extended is None else float(stats.chi2.sf(extended.chi2, extended.dof))
    held_out = None
    if extended is not None and len(measurement.load_levels) >= 3:
        say("held-out check", 0, 1)
        held_out = _held_out(ctx, space, measurement, noise, base, extended, terms, error_std, rigid)
    seconds = time.perf_counter() - t_start
    causes = [t[0].name for t in terms]
    logger.info("diagnosis: %s (%s) in %.1f s, %d FE runs", verdict, causes, seconds, ctx.n_runs)
    return DiagnosisResult(
        scenario=scenario, measurement=measurement, noise_std=noise_std, alpha=alpha, base=base,
        extended=extended, chi2_p_value=p_chi2, verdict=verdict, cause=causes[0] if causes else None,
        best=best, alternatives=alternatives, candidates=ranked + inapplicable, structure=structure,
        held_out=held_out, seconds=seconds, n_fe_runs=ctx.n_runs, extended_p_value=extended_p,
        surrogate_fit={"chi2_dof": float(inv.chi2_dof), "parameters": {k: float(v) for k, v in zip(space.names, inv.x)},
                       "basis": inv.chi2_basis + " (the diagnosis's own starting surrogate)"},
        model_error=model_error, steps=steps, rigid_body=rigid_body, rigid_groups=rigid_groups,
        causes=[Cause(t[0].name, t[1], t[2], float(v)) for t, v in zip(terms, current.effects)] if cause_found else [],
    )


class Term(NamedTuple):
    """A cause in the model: candidate, location, its :class:`EffectParameter`, and the log of its
    multiplicity correction (candidates × locations) used when it was found."""

    candidate: object
    location: object
    parameter: object
    log_correction: float


class _Screen:
    """Whitened residual of the current fit and the projector off the span of its Jacobian."""

    def __init__(self, fitter, current):
        self.fitter = fitter
        self.r = -fitter.whiten(current.readings)  # data − model, whitened
        self._Q, _ = np.linalg.qr(current.jacobian)
        self.Pr = self.project(self.r)

    def project(self, v):
        """``P v = v − Q Qᵀ v``: the part of ``v`` the current model's parameters cannot absorb."""
        return v - self._Q @ (self._Q.T @ v)

    def signature(self, readings):
        """Projected whitened change of the readings from the current fit, ``P s``."""
        return self.project(self.fitter.whiten(readings) + self.r)


def _found_at(terms, fit):
    """``(candidate, location, value)`` of the causes in ``terms`` at their values in ``fit``."""
    return [(t.candidate, t.location, c) for t, c in zip(terms, fit.effects)]


def _score_round(names, ctx, fitter, current, terms, space, n_applicable, alpha, refit_locations, noise_std, say,
                 round_index):
    """Score every candidate against the current model (base plus ``terms``), ranked by evidence:
    effects that survive refitting first, then by corrected p-value, then by Δχ²."""
    screen = _Screen(fitter, current)
    u_cur = space.to_unit(np.array([[current.free[n] for n in space.names]]))[0]
    t_cur = [t.parameter.to_fit(c) for t, c in zip(terms, current.effects)]
    found_keys = {(t.candidate.name, t.location.key) for t in terms}
    scores = []
    for k, name in enumerate(names):
        cand = CANDIDATES[name]
        reason = cand.not_applicable(ctx)
        every = [] if reason else cand.locations(ctx)
        locations = [loc for loc in every if (name, loc.key) not in found_keys
                     and not any(t.candidate is cand and cand.overlaps(loc, t.location) for t in terms)]
        if reason is None and not locations:
            reason = "already in the model"
        if reason is not None:
            scores.append(CandidateScore(name, cand.description, cand.signature, 0, False, reason))
            continue
        say(f"screening {name}" + (f" (cause {round_index + 1})" if round_index else ""), k, len(names))
        scores.append(_score_candidate(cand, locations, ctx, fitter, screen, current, terms, u_cur, t_cur,
                                       np.log(n_applicable * len(every)), alpha, refit_locations, noise_std))
    ranked = sorted([s for s in scores if s.applicable],
                    key=lambda s: (s.effect_left < MIN_EFFECT, s.log10_p_corrected, -s.delta_chi2))
    return ranked + [s for s in scores if not s.applicable]


def _score_candidate(cand, locations, ctx, fitter, screen, current, terms, u_cur, t_cur, log_correction, alpha,
                     refit_locations, noise_std):
    """Screen every location of a candidate against the current model, refit the best few with the
    base parameters and the causes already found free, and return its :class:`CandidateScore`."""
    found = _found_at(terms, current)
    score = CandidateScore(cand.name, cand.description, cand.signature, len(locations), True)
    score.log_correction = float(log_correction)
    screened = []
    max_effect = 0.0
    for loc in locations:
        par = cand.parameter(ctx, loc)
        Ps = screen.signature(cand.readings(ctx, current.values, loc, par.reference, found=found))
        ss = float(Ps @ Ps)
        sr = float(Ps @ screen.Pr)
        delta = sr * sr / ss if (ss > 0 and (sr > 0 or not par.one_sided)) else 0.0
        screened.append((delta, loc, par))
        # visibility: the largest χ² change the effect can make beyond the current parameters' span
        # (for candidates with many locations the reference strength is near the extreme)
        max_effect = max(max_effect, ss)
        if len(locations) <= _EXACT_VISIBILITY:
            for extreme in (par.lower, par.upper):
                if extreme != par.neutral:
                    Pe = screen.signature(cand.readings(ctx, current.values, loc, extreme, found=found))
                    max_effect = max(max_effect, float(Pe @ Pe))
    screened.sort(key=lambda t: -t[0])
    score.max_delta_chi2 = max_effect
    score.visible = max_effect >= stats.chi2.isf(alpha * np.exp(-log_correction), 1)
    best = None
    for delta_lin, loc, par in screened[:refit_locations]:
        fit = _refit(fitter, terms, Term(cand, loc, par, log_correction), u_cur, t_cur)
        entry = (loc, par, delta_lin, fit, max(current.chi2 - fit.chi2, 0.0))
        score.refitted.append(entry)
        if best is None or fit.chi2 < best[3].chi2:
            best = entry
    loc, par, delta_lin, fit, delta = best
    score.location, score.parameter, score.screening_delta_chi2, score.fit, score.delta_chi2 = best
    score.log10_p_corrected, score.p_value, score.p_corrected = _log10_p(delta, par, log_correction)
    # the effect's size: in full (the fitted cause against the same fit with the cause off), and
    # what is left of it beyond what the current model's parameters absorb (the guard)
    off = cand.readings(ctx, fit.values, loc, par.off, found=_found_at(terms, fit))
    diff = fitter.observed(fit.readings - off)
    score.effect_size = float(np.max(np.abs(diff) / noise_std))
    score.effect_left = float(np.max(np.abs(screen.project(fitter.whiten(fit.readings) - fitter.whiten(off)))))
    return score


def _log10_p(delta, par, log_correction):
    """(log10 corrected p, p, corrected p) of a likelihood-ratio statistic ``delta`` (χ²(1), or the
    ½χ²(0) + ½χ²(1) mixture when the neutral value is a bound), Bonferroni-corrected by
    ``exp(log_correction)``. In logs: strong effects underflow the p-values, and the ranking must
    still tell them apart."""
    log_p = float(stats.chi2.logsf(delta, 1)) if delta > 0 else 0.0
    if par.one_sided and delta > 0:
        log_p += np.log(0.5)
    log_p_corrected = min(0.0, log_p + log_correction)
    return log_p_corrected / np.log(10.0), float(np.exp(log_p)), float(np.exp(log_p_corrected))


def _refit(fitter, terms, term, u_cur, t_cur):
    """Extended FE fit: least squares over the base parameters, the causes already found and the new
    one together, from the current optimum and the best of a few strengths of the new effect. When
    the current optimum sits on a face of the box (the model strained by a missing effect), also
    from the box centre."""
    starts = [np.asarray(u_cur, dtype=float)]
    if np.any(np.minimum(u_cur, 1.0 - u_cur) < 1e-3):
        starts.append(np.full(len(u_cur), 0.5))
    found = [(t.candidate, t.location, t.parameter.from_fit(v)) for t, v in zip(terms, t_cur)]
    best = None
    for u0 in starts:
        values = fitter.values(u0)
        grid = np.linspace(0.0, 1.0, 9)
        chi2 = [float(np.sum(fitter.whiten(term.candidate.readings(fitter.ctx, values, term.location,
                                                                   term.parameter.from_fit(t), found=found)) ** 2))
                for t in grid]
        fit = fitter.fit(u0, [*terms, term], [*t_cur, grid[int(np.argmin(chi2))]])
        if best is None or fit.chi2 < best.chi2:
            best = fit
    return best


def _drop_redundant(fitter, space, terms, current, alpha):
    """Backward check after a cause is added: refit without each earlier cause; the least
    significant one whose likelihood-ratio test (corrected as when it was found) is no longer
    significant at ``alpha`` is dropped (a first cause that only stood in for the later ones).
    Returns ``(terms, fit, dropped name or None)``."""
    u = space.to_unit(np.array([[current.free[n] for n in space.names]]))[0]
    t = [term.parameter.to_fit(c) for term, c in zip(terms, current.effects)]
    weakest = None
    for j in range(len(terms) - 1):
        keep = [k for k in range(len(terms)) if k != j]
        fit = fitter.fit(u, [terms[k] for k in keep], [t[k] for k in keep])
        log10_p, _, p_corr = _log10_p(max(fit.chi2 - current.chi2, 0.0), terms[j].parameter, terms[j].log_correction)
        if p_corr >= alpha and (weakest is None or log10_p > weakest[0]):
            weakest = (log10_p, j, keep, fit)
    if weakest is None:
        return terms, current, None
    _, j, keep, fit = weakest
    return [terms[k] for k in keep], fit, terms[j].candidate.name


def _alternatives(best, scores, alpha):
    """Explanations of the first cause within a likelihood ratio of ``EQUIVALENCE_RATIO``."""
    limit = 2.0 * np.log(EQUIVALENCE_RATIO)
    out = []
    for s in scores:
        if s is best or not s.applicable:
            continue
        for loc, par, _, fit, delta in s.refitted:
            if fit.chi2 - best.fit.chi2 < limit and s.p_corrected < alpha:
                out.append(Alternative(s.name, loc, delta))
                break
    for loc, par, _, fit, delta in best.refitted:
        if loc is not best.location and fit.chi2 - best.fit.chi2 < limit:
            out.append(Alternative(best.name, loc, delta))
    return out


def _held_out(ctx, space, measurement, noise, base, extended, terms, error_std, rigid_body=None):
    """Fit base and extended models without the highest load level; error there (whitened RMS and mm)."""
    sc = ctx.scenario
    n_s = len(measurement.sensor_names)
    top = int(np.argmax(measurement.load_levels))
    rows_all = np.arange(measurement.n_obs).reshape(-1, n_s)
    train = np.delete(rows_all, top, axis=0).ravel()
    test = rows_all[top]
    fit_train = _Fitter(ctx, space, measurement, noise, train, error_std, rigid_body)
    test_fitter = _Fitter(ctx, space, measurement, noise, test, error_std, rigid_body)
    u_base = space.to_unit(np.array([[base.free[n] for n in space.names]]))[0]
    b = fit_train.fit(u_base)
    u_ext = space.to_unit(np.array([[extended.free[n] for n in space.names]]))[0]
    e = fit_train.fit(u_ext, terms, [t.parameter.to_fit(c) for t, c in zip(terms, extended.effects)])
    wb, we = test_fitter.whiten(b.readings), test_fitter.whiten(e.readings)
    idx = measurement.output_indices(sc.sensor_names, sc.load_levels)[test]
    d = measurement.data[test]
    return {
        "held_out": f"load level {measurement.load_levels[top]:g} {sc.load_unit}",
        "rms_before": float(np.sqrt(np.mean(wb**2))), "rms_after": float(np.sqrt(np.mean(we**2))),
        "max_abs_mm_before": float(np.max(np.abs(b.readings.ravel()[idx] - d))),
        "max_abs_mm_after": float(np.max(np.abs(e.readings.ravel()[idx] - d))),
    }


def residual_structure(w, measurement, noise_std):
    """Where the whitened residuals ``w`` ``(n_obs,)`` sit: per sensor and per load level.

    Returns a dict with, per sensor, its share of χ², its standardised residuals (data − model)/σ,
    and the correlation of the residual with the load level (growth with load); per load level its
    share of χ²; and the sensor with the largest share.
    """
    n_l, n_s = measurement.values.shape
    W = -np.asarray(w).reshape(n_l, n_s)  # data − model
    total = float(np.sum(W**2)) or 1.0
    loads = measurement.load_levels
    per_sensor = {}
    for j, s in enumerate(measurement.sensor_names):
        col = W[:, j]
        corr = float(np.corrcoef(loads, col)[0, 1]) if n_l >= 3 and np.std(col) > 0 else None
        per_sensor[s] = {"chi2_share": float(np.sum(col**2) / total), "standardised": col.tolist(),
                         "growth_with_load": corr}
    per_load = {f"{lv:g}": float(np.sum(W[i] ** 2) / total) for i, lv in enumerate(loads)}
    worst = max(per_sensor, key=lambda s: per_sensor[s]["chi2_share"])
    return {"per_sensor": per_sensor, "per_load": per_load, "largest_share": worst}
