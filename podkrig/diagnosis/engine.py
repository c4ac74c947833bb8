"""Model diagnosis: does the calibrated model explain the data within the noise, and if not, why?

:func:`diagnose` runs five steps on a scenario, a measurement and its noise model:

1. **Calibrate the base model** surrogate first: a POD-kriging surrogate over the free parameters
   (built here from a Sobol' design unless one is given), GA inversion with least-squares polish
   (:func:`podkrig.online.invert.invert`), then a least-squares polish with the FE model itself so that
   the adequacy test is not blurred by surrogate error.
2. **Adequacy**: χ² of the whitened residuals ``r = L⁻¹(d − g(m*))`` (``C_d = L Lᵀ``) against
   χ²(n_obs − n_free), and the residual structure across sensors and load levels.
3. **Score every candidate cause** (:mod:`podkrig.diagnosis.candidates`) at every location:
   screening by the share of the residual its signature ``s`` (whitened effect of a moderate
   strength) explains beyond the span of the base Jacobian ``J``,
   ``Δχ²_lin = (sᵀ P r)² / (sᵀ P s)``, ``P = I − J J⁺``; then a nonlinear FE refit, with the base
   parameters and the candidate's parameter free, of the best-screened locations. The
   likelihood-ratio statistic ``Δχ² = χ²_base − χ²_ext`` is χ²(1) under the null (a ½χ²(0) +
   ½χ²(1) mixture when the neutral value is a bound), and its p-value is multiplied by the number
   of candidates times the candidate's number of locations (Bonferroni), so that trying 200 joint
   segments does not manufacture a finding.
4. **Verdict and cause**: *inadequate* when the χ² test is significant at ``alpha / 10`` or the
   best corrected candidate test at ``alpha`` (the latter only for an effect that moves some
   reading by at least ``MIN_EFFECT`` σ); the cause is the candidate with the smallest corrected p-value if it
   is below ``alpha``, else none ("no candidate explains the residual"). Candidates whose
   extended fit is within a likelihood ratio of 20 of the best are reported as alternatives the
   data cannot tell apart.
5. **Gain**: χ²/dof and misfit before and after, AIC/BIC, and the error on the highest load level
   predicted by both models fitted without it.

All FE work reuses the scenario's factorisation pattern; a diagnosis of the default diagonal test
is a few hundred FE solves.
"""

import logging
import time

import numpy as np
from scipy import linalg, optimize, stats

from fe.sensors import absolute_displacements
from podkrig.diagnosis.candidates import CANDIDATES, FEContext
from podkrig.diagnosis.results import CHI2_ALPHA_SHARE, Alternative, CandidateScore, Diagnosis, Fit
from podkrig.offline.sampling import sobol
from podkrig.online.invert import invert
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


def build_base_surrogate(scenario, space, values, n_train=64, seed=0):
    """A POD-kriging surrogate of the scenario's readings over ``space`` (others at ``values``):
    ``n_train`` Sobol' FE runs, exponent fitted on the dominant mode (``beta="fit-shared"``)."""
    X = space.from_unit(sobol(n_train, space.n_params, seed))
    Y = np.stack([scenario.run({**values, **space.as_params(x)}).readings for x in X])
    sur = PODKriging(kriging=OrdinaryKriging(beta="fit-shared"), space=space).fit(X, Y)
    sur.provenance_.update({  # what an inversion model needs to know (as fit_from_store records it)
        "scenario_spec": scenario.spec.to_dict(), "sensor_names": list(scenario.sensor_names),
        "load_levels": scenario.load_levels.tolist(), "load_unit": scenario.load_unit, "output": "readings",
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

    def __init__(self, ctx, space, measurement, noise, rows, model_tolerance=0.0, rigid_body=None):
        self.ctx, self.space = ctx, space
        sc = ctx.scenario
        idx = measurement.output_indices(sc.sensor_names, sc.load_levels)
        C = data_covariance(measurement, noise, model_tolerance)
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

    def fit(self, u0, candidate=None, location=None, t0=None, max_nfev=60):
        """Fit from unit coordinates ``u0`` (and candidate fit coordinate ``t0``); returns a :class:`Fit`."""
        p = len(u0)
        par = None if candidate is None else candidate.parameter(self.ctx, location)

        def readings(z):
            values = self.values(z[:p])
            if candidate is None:
                return self.ctx.readings(values)
            return candidate.readings(self.ctx, values, location, par.from_fit(float(np.clip(z[p], 0, 1))))

        def residual(z):
            return self.whiten(readings(z))

        z0 = np.asarray(u0, dtype=float) if candidate is None else np.append(u0, t0)
        z0 = np.clip(z0, 0.0, 1.0)
        sol = optimize.least_squares(residual, z0, bounds=(0.0, 1.0), method="trf", jac="2-point",
                                     diff_step=1e-6, x_scale=1.0, max_nfev=max_nfev)
        z = sol.x
        values = self.values(z[:p])
        return Fit(
            values=values, free={n: values[n] for n in self.space.names},
            effect=None if candidate is None else par.from_fit(float(z[p])),
            chi2=float(sol.fun @ sol.fun), n_obs=len(self.rows), n_params=len(z),
            readings=readings(z), jacobian=sol.jac, n_removed=self.n_removed,
        )


def data_covariance(measurement, noise, model_tolerance=0.0):
    """``C_D = C_d + C_T`` (thesis eq. 2.10) with the modelling part ``C_T = diag((ε d_i)²)``: a
    relative model-form tolerance ε on every reading (discretisation, idealised geometry), mm²."""
    C = noise.covariance_matrix(measurement)
    if model_tolerance:
        C = C + np.diag((model_tolerance * measurement.data) ** 2)
    return C


def diagnose(scenario, measurement, noise, space, *, fixed=None, surrogate=None, candidates=None, alpha=0.01,
             model_tolerance=0.01, rng=0, n_train=64, refit_locations=3, progress=None, rigid_body="auto",
             rigid_groups=None):
    """Diagnose a calibrated FE model against measured data.

    Parameters
    ----------
    scenario : fe.Scenario
        The virtual test; parameters not in ``space`` stay at its defaults (or ``fixed``).
    measurement : Measurement
        Measured readings (a subset of the scenario's sensors and load levels), mm.
    noise : NoiseModel
    space : ParameterSpace
        The base model's free parameters with bounds and scales.
    fixed : dict of str to float, optional
        Values of non-free parameters that differ from the scenario's defaults.
    surrogate : PODKriging, optional
        A surrogate of the scenario's readings over ``space``, with its provenance (from
        :func:`build_base_surrogate` or a store; built here when not given:
        ``n_train`` Sobol' FE runs, about a second for the default test).
    candidates : sequence of str, optional
        Names from :data:`~podkrig.diagnosis.candidates.CANDIDATES` (default: all).
    alpha : float
        Significance level of the (multiplicity-corrected) candidate tests; the χ² test runs at
        ``alpha * CHI2_ALPHA_SHARE``.
    model_tolerance : float
        Relative model-form tolerance ε added to the noise, ``C_D = C_d + diag((ε d)²)``
        (thesis eq. 2.10): two sound FE discretisations of the same test differ by about 0.5 %,
        which many readings (a DIC grid) would otherwise flag as a missing effect. A cause is
        named only when its fitted effect moves some reading by at least ``MIN_EFFECT`` (2) σ.
    rng : int
        Seed of the surrogate design and the GA.
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

    Returns
    -------
    Diagnosis
    """
    if not measurement.complete or measurement.reference_load is not None:
        raise ValueError(f"{measurement.source}: the diagnosis needs every sensor read at each load level (no "
                         "missing cells, no zero reference); invert such a log with 'podkrig invert' instead")
    t_start = time.perf_counter()
    say = progress or (lambda *a: None)
    names = list(candidates or CANDIDATES)
    unknown = [n for n in names if n not in CANDIDATES]
    if unknown:
        raise ValueError(f"unknown candidate cause(s) {unknown}; known: {list(CANDIDATES)}")
    if not 0 < alpha < 0.5:
        raise ValueError(f"alpha must be in (0, 0.5); got {alpha}")
    values0 = scenario.resolve(fixed)
    ctx = FEContext(scenario, space.names, values0, offset_scale=np.max(np.abs(measurement.values)))
    if not 0 <= model_tolerance < 0.5:
        raise ValueError(f"model_tolerance must be in [0, 0.5) (a relative tolerance); got {model_tolerance}")
    rigid = rigid_body_modes(measurement, absolute_displacements(scenario.sensors), rigid_body, rigid_groups)
    fitter = _Fitter(ctx, space, measurement, noise, np.arange(measurement.n_obs), model_tolerance, rigid)
    noise_std = np.sqrt(np.diag(data_covariance(measurement, noise, model_tolerance)))

    # 1. base calibration: surrogate first, FE last
    say("calibration", 0, 3)
    if surrogate is None:
        surrogate = build_base_surrogate(scenario, space, values0, n_train=n_train, seed=rng)
        ctx.n_runs += n_train
    say("calibration", 1, 3)
    problem = InverseProblem(SurrogateModel(surrogate), measurement, noise, rigid_body=rigid)
    inv = invert(problem, rng=rng)
    say("calibration", 2, 3)
    base = fitter.fit(space.to_unit(inv.x[None])[0])
    say("calibration", 3, 3)
    dof = base.dof
    p_chi2 = float(stats.chi2.sf(base.chi2, dof))
    structure = residual_structure(fitter.whiten(base.readings), measurement, noise_std)

    # 2. screening and refits of every candidate
    u_base = space.to_unit(np.array([[base.free[n] for n in space.names]]))[0]
    screen = _Screen(fitter, base)
    n_applicable = max(sum(CANDIDATES[n].not_applicable(ctx) is None for n in names), 1)
    scores = []
    for k, name in enumerate(names):
        cand = CANDIDATES[name]
        reason = cand.not_applicable(ctx)
        if reason is not None:
            scores.append(CandidateScore(name, cand.description, cand.signature, 0, False, reason))
            continue
        say(f"screening {name}", k, len(names))
        scores.append(_score_candidate(cand, ctx, fitter, screen, base, u_base, n_applicable, alpha,
                                       refit_locations, noise_std))

    ranked = sorted([s for s in scores if s.applicable],
                    key=lambda s: (s.effect_size < MIN_EFFECT, s.log10_p_corrected, -s.delta_chi2))
    inapplicable = [s for s in scores if not s.applicable]
    best = ranked[0] if ranked else None
    candidate_hit = best is not None and best.p_corrected < alpha and best.effect_size >= MIN_EFFECT
    verdict = "inadequate" if (p_chi2 < alpha * CHI2_ALPHA_SHARE or candidate_hit) else "adequate"
    cause = best.name if (verdict == "inadequate" and candidate_hit) else None
    alternatives = []
    if cause is not None:
        limit = 2.0 * np.log(EQUIVALENCE_RATIO)
        for s in ranked[1:]:
            for loc, par, _, fit, delta in s.refitted:
                if fit.chi2 - best.fit.chi2 < limit and s.p_corrected < alpha:
                    alternatives.append(Alternative(s.name, loc, delta))
                    break
        for loc, par, _, fit, delta in best.refitted:
            if loc is not best.location and fit.chi2 - best.fit.chi2 < limit:
                alternatives.append(Alternative(best.name, loc, delta))

    extended = best.fit if cause is not None else None
    extended_p = None if extended is None else float(stats.chi2.sf(extended.chi2, extended.dof))
    held_out = None
    if extended is not None and len(measurement.load_levels) >= 3:
        say("held-out check", 0, 1)
        held_out = _held_out(ctx, space, measurement, noise, base, best, model_tolerance, rigid)
    seconds = time.perf_counter() - t_start
    logger.info("diagnosis: %s (%s) in %.1f s, %d FE runs", verdict, cause, seconds, ctx.n_runs)
    return Diagnosis(
        scenario=scenario, measurement=measurement, noise_std=noise_std, alpha=alpha, base=base,
        extended=extended, chi2_p_value=p_chi2, verdict=verdict, cause=cause, best=best if cause else None,
        alternatives=alternatives, candidates=ranked + inapplicable, structure=structure,
        held_out=held_out, seconds=seconds, n_fe_runs=ctx.n_runs, extended_p_value=extended_p,
        surrogate_fit={"chi2_dof": float(inv.chi2_dof), "parameters": {k: float(v) for k, v in zip(space.names, inv.x)},
                       "basis": inv.chi2_basis + " (the diagnosis's own starting surrogate)"},
        model_tolerance=float(model_tolerance), rigid_body=rigid_body, rigid_groups=rigid_groups,
    )


class _Screen:
    """Whitened residual of the base fit and the projector off the span of its Jacobian."""

    def __init__(self, fitter, base):
        self.fitter = fitter
        self.r = -fitter.whiten(base.readings)  # data − model, whitened
        self._Q, _ = np.linalg.qr(base.jacobian)
        self.Pr = self.project(self.r)

    def project(self, v):
        """``P v = v − Q Qᵀ v``: the part of ``v`` the base parameters cannot absorb."""
        return v - self._Q @ (self._Q.T @ v)

    def signature(self, readings):
        """Projected whitened change of the readings from the base fit, ``P s``."""
        return self.project(self.fitter.whiten(readings) + self.r)


def _score_candidate(cand, ctx, fitter, screen, base, u_base, n_applicable, alpha, refit_locations, noise_std):
    """Screen every location of a candidate, refit the best few, and return its :class:`CandidateScore`."""
    locations = cand.locations(ctx)
    score = CandidateScore(cand.name, cand.description, cand.signature, len(locations), True)
    screened = []
    max_effect = 0.0
    for loc in locations:
        par = cand.parameter(ctx, loc)
        Ps = screen.signature(cand.readings(ctx, base.values, loc, par.reference))
        ss = float(Ps @ Ps)
        sr = float(Ps @ screen.Pr)
        delta = sr * sr / ss if (ss > 0 and (sr > 0 or not par.one_sided)) else 0.0
        screened.append((delta, loc, par))
        # visibility: the largest χ² change the effect can make beyond the base parameters' span
        # (for candidates with many locations the reference strength is near the extreme)
        max_effect = max(max_effect, ss)
        if len(locations) <= _EXACT_VISIBILITY:
            for extreme in (par.lower, par.upper):
                if extreme != par.neutral:
                    Pe = screen.signature(cand.readings(ctx, base.values, loc, extreme))
                    max_effect = max(max_effect, float(Pe @ Pe))
    screened.sort(key=lambda t: -t[0])
    score.max_delta_chi2 = max_effect
    score.visible = max_effect >= stats.chi2.isf(alpha / (n_applicable * len(locations)), 1)
    best = None
    for delta_lin, loc, par in screened[:refit_locations]:
        fit = _refit(fitter, cand, loc, par, u_base, base)
        entry = (loc, par, delta_lin, fit, max(base.chi2 - fit.chi2, 0.0))
        score.refitted.append(entry)
        if best is None or fit.chi2 < best[3].chi2:
            best = entry
    loc, par, delta_lin, fit, delta = best
    score.location, score.parameter, score.screening_delta_chi2, score.fit, score.delta_chi2 = best
    # in logs: strong effects underflow the p-values, and the ranking must still tell them apart
    log_p = float(stats.chi2.logsf(delta, 1)) if delta > 0 else 0.0
    if par.one_sided and delta > 0:  # ½χ²(0) + ½χ²(1) under the null
        log_p += np.log(0.5)
    log_p_corrected = min(0.0, log_p + np.log(n_applicable * len(locations)))
    score.p_value = float(np.exp(log_p))
    score.p_corrected = float(np.exp(log_p_corrected))
    score.log10_p_corrected = log_p_corrected / np.log(10.0)
    off = cand.readings(ctx, fit.values, loc, par.off)
    score.effect_size = float(np.max(np.abs(fitter.observed(fit.readings - off)) / noise_std))
    return score


def _refit(fitter, cand, loc, par, u_base, base):
    """Extended FE fit at one location: least squares over base and effect parameters together,
    from the base optimum and the best of a few effect strengths. When the base optimum sits on a
    face of the box (the base model strained by a missing effect), also from the box centre."""
    starts = [np.asarray(u_base, dtype=float)]
    if np.any(np.minimum(u_base, 1.0 - u_base) < 1e-3):
        starts.append(np.full(len(u_base), 0.5))
    best = None
    for u0 in starts:
        values = fitter.values(u0)
        grid = np.linspace(0.0, 1.0, 9)
        chi2 = [float(np.sum(fitter.whiten(cand.readings(fitter.ctx, values, loc, par.from_fit(t))) ** 2)) for t in grid]
        fit = fitter.fit(u0, cand, loc, grid[int(np.argmin(chi2))])
        if best is None or fit.chi2 < best.chi2:
            best = fit
    return best


def _held_out(ctx, space, measurement, noise, base, best, model_tolerance, rigid_body=None):
    """Fit base and extended models without the highest load level; error there (whitened RMS and mm)."""
    sc = ctx.scenario
    n_s = len(measurement.sensor_names)
    top = int(np.argmax(measurement.load_levels))
    rows_all = np.arange(measurement.n_obs).reshape(-1, n_s)
    train = np.delete(rows_all, top, axis=0).ravel()
    test = rows_all[top]
    fit_train = _Fitter(ctx, space, measurement, noise, train, model_tolerance, rigid_body)
    test_fitter = _Fitter(ctx, space, measurement, noise, test, model_tolerance, rigid_body)
    u_base = space.to_unit(np.array([[base.free[n] for n in space.names]]))[0]
    b = fit_train.fit(u_base)
    t0 = best.parameter.to_fit(best.fit.effect)
    u_ext = space.to_unit(np.array([[best.fit.free[n] for n in space.names]]))[0]
    e = fit_train.fit(u_ext, CANDIDATES[best.name], best.location, t0)
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
