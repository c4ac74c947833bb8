"""Hidden-effect trials: pseudo-experimental data with a candidate cause switched on, for testing
and benchmarking the diagnosis (the code under test never sees the cause, location or strength).

Noise is the realistic level of the diagnosis issue: σ = 1 % of the largest reading, at least
1 µm, independent on every reading. The *identifiable* size of an effect is the largest
|residual| / σ left when the base model (free parameters only) is fitted to the noise-free data
with the effect, σ from the covariance the diagnosis uses (noise plus its model-form error):
what the base parameters can absorb is not evidence of anything. With two hidden effects
(:func:`make_two_cause_trial`), each one's identifiable size is what is left of it after
refitting the base parameters *and the other effect*.
"""

from dataclasses import dataclass

import numpy as np

from fe.sensors import absolute_displacements
from podkrig.diagnosis.candidates import CANDIDATES, FEContext
from podkrig.diagnosis.engine import Term, _Fitter
from podkrig.online.model_error import discretisation_error, tolerance_error
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.rigid_body import rigid_body_modes


@dataclass(frozen=True, eq=False)
class Trial:
    """One pseudo-experiment.

    Attributes
    ----------
    cause : str or None
        The hidden candidate (None: a negative control).
    location : Location or None
    value : float or None
        The candidate's parameter, in its unit.
    truth : dict of str to float
        The base parameters used.
    measurement : Measurement
    noise : NoiseModel
    sigma : float
        Noise standard deviation, mm.
    raw_effect : float
        Largest change of a reading caused by the effect, in σ.
    identifiable_effect : float
        Largest |residual| / σ of the base model refitted to the noise-free data (σ from the noise
        and the model-form error the diagnosis uses).
    """

    cause: str | None
    location: object
    value: float | None
    truth: dict
    measurement: Measurement
    noise: NoiseModel
    sigma: float
    raw_effect: float
    identifiable_effect: float


def noise_sigma(readings):
    """σ = 1 % of the largest |reading|, at least 1 µm (mm)."""
    return max(0.01 * float(np.max(np.abs(readings))), 1e-3)


def draw_strength(cause, location, parameter, rng):
    """A random effect strength for ``cause`` (physical units of its parameter), away from neutral."""
    p = parameter
    if cause == "weak_joint":
        return float(np.exp(rng.uniform(np.log(1e-3), np.log(0.5))))
    if cause in ("head_joint_stiffness", "unit_stiffness"):  # 1.25–20 × softer or stiffer, inside the fit range
        lo, hi = (0.05, 0.7) if cause == "head_joint_stiffness" else (0.3, 0.8)
        factor = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
        return float(np.clip(p.neutral * (factor if rng.random() < 0.5 else 1.0 / factor), p.lower, p.upper))
    if cause == "support_compliance":
        return float(np.exp(rng.uniform(np.log(1e-3), np.log(p.upper))))  # mm³/N
    if cause == "slot_contact":  # 20–100 % of the largest contact loss
        return float(rng.uniform(0.2, 1.0) * p.upper)
    if cause == "nonlinearity_onset":  # joint strength anywhere in the onset level's range
        return float(np.exp(rng.uniform(np.log(p.lower), np.log(p.upper))))
    sign = rng.choice([-1.0, 1.0])
    if cause == "gauge_fault":  # gain 2–30 %; offset 1–15 % of the largest reading (1–15 σ)
        lo, hi = (0.02, 0.3) if location.detail["fault"] == "gain" else (0.01 * p.upper, 0.15 * p.upper)
        return float(sign * rng.uniform(lo, hi))
    if cause == "gauge_slip":  # a step of 1–15 % of the largest reading (1–15 σ)
        return float(sign * rng.uniform(0.01, 0.15) * p.upper)
    if cause == "jack_efficiency":  # Km 10–35 % off the assumed value, inside the fit range
        return float(np.clip(p.neutral * (1.0 + sign * rng.uniform(0.1, 0.35)), p.lower, p.upper))
    # load-line offset and rotation: 10–100 % of the admissible range
    return float(sign * rng.uniform(0.1, 1.0) * p.upper)


def model_error(scenario, values, measurement, model_tolerance=None, rigid=None):
    """The model-form error the diagnosis will use on ``measurement`` (estimated when
    ``model_tolerance`` is None, as :func:`podkrig.diagnosis.diagnose` does, with the rigid-body
    modes ``rigid`` removed from the two meshes' difference)."""
    if model_tolerance is None:
        return discretisation_error(scenario, values, measurement, rigid_body=rigid).std
    return tolerance_error(measurement, model_tolerance).std


def _context(scenario, space, truth):
    """``(values, ctx, clean)``: the resolved ``truth``, the candidates' FE context at it (its
    offset scale set from the clean readings, as :func:`~podkrig.diagnosis.diagnose` sets it from
    the data) and the clean readings."""
    values = scenario.resolve(truth)
    ctx = FEContext(scenario, space.names, values)
    clean = ctx.readings(values)
    ctx.offset_scale = float(np.max(np.abs(clean)))
    return values, ctx, clean


def _exact_fitter(ctx, scenario, space, values, effect, noise, model_tolerance, rigid_body, with_model_error=True):
    """The diagnosis's fitter on the noise-free ``effect`` readings (with the model-form error the
    diagnosis will use, unless ``with_model_error`` is False) and the truth's unit-cube point: what
    the identifiable size of an effect is measured with."""
    exact = Measurement(effect, scenario.sensor_names, scenario.load_levels, "noise-free")
    rigid = rigid_body_modes(exact, absolute_displacements(scenario.sensors), rigid_body)
    error = model_error(scenario, values, exact, model_tolerance, rigid) if with_model_error else None
    fitter = _Fitter(ctx, space, exact, noise, np.arange(exact.n_obs), error, rigid)
    return fitter, space.to_unit(np.array([[values[n] for n in space.names]]))[0]


def _draw(ctx, cause, location, value, rng):
    """``(candidate, location, parameter, value)`` of ``cause``, the location drawn at random when
    None and the value by :func:`draw_strength` when None."""
    cand = CANDIDATES[cause]
    if location is None:
        locations = cand.locations(ctx)
        location = locations[int(rng.integers(len(locations)))]
    par = cand.parameter(ctx, location)
    if value is None:
        value = draw_strength(cause, location, par, rng)
    return cand, location, par, float(value)


def make_trial(scenario, space, truth, cause=None, location=None, value=None, *, rng, model_tolerance=None,
               rigid_body="auto"):
    """Pseudo-data from ``truth`` with an optional effect, plus noise; see :class:`Trial`.

    ``location`` is a :class:`Location` of ``cause`` (drawn at random when None) and ``value`` its
    parameter (drawn by :func:`draw_strength` when None). ``model_tolerance`` and ``rigid_body``
    as the diagnosis will be given them (None: estimated; "auto": the rigid-body motion of a DIC
    grid removed), for the identifiable size.
    """
    values, ctx, clean = _context(scenario, space, truth)
    if cause is not None:
        cand, location, _, value = _draw(ctx, cause, location, value, rng)
        effect = cand.readings(ctx, values, location, value)
    else:
        effect = clean
    sigma = noise_sigma(effect)
    noise = NoiseModel(sigma=sigma)
    fitter, u = _exact_fitter(ctx, scenario, space, values, effect, noise, model_tolerance, rigid_body,
                              with_model_error=cause is not None)
    identifiable = float(np.max(np.abs(fitter.whiten(fitter.fit(u).readings)))) if cause else 0.0
    data = effect + sigma * rng.standard_normal(effect.shape)
    measurement = Measurement(data, scenario.sensor_names, scenario.load_levels, f"pseudo-data ({cause or 'no effect'})")
    raw = float(np.max(np.abs(effect - clean)) / sigma)
    return Trial(cause, location, value, dict(truth), measurement, noise, sigma, raw, identifiable)


@dataclass(frozen=True, eq=False)
class TwoCauseTrial:
    """A pseudo-experiment with two hidden effects: ``causes`` are ``(name, location, value)``, and
    ``identifiable`` the size (σ) left of each after refitting the base parameters and the other."""

    causes: tuple
    truth: dict
    measurement: Measurement
    noise: NoiseModel
    sigma: float
    identifiable: tuple


def make_two_cause_trial(scenario, space, truth, causes, *, rng, sigma=None, model_tolerance=None, rigid_body="auto"):
    """Pseudo-data from ``truth`` with two effects ``causes`` = ``(name, location or None, value or
    None)`` each (drawn as in :func:`make_trial` when None), plus noise σ (default
    :func:`noise_sigma`); ``rigid_body`` as the diagnosis will be given it."""
    values, ctx, _ = _context(scenario, space, truth)
    drawn = [_draw(ctx, name, location, value, rng) for name, location, value in causes]
    effect = ctx.readings_with(values, [(c, loc, v) for c, loc, _, v in drawn])
    sigma = noise_sigma(effect) if sigma is None else float(sigma)
    noise = NoiseModel(sigma=sigma)
    fitter, u = _exact_fitter(ctx, scenario, space, values, effect, noise, model_tolerance, rigid_body)
    identifiable = []
    for k in range(2):  # refit the base parameters and the other effect, from the truth
        cand, loc, par, v = drawn[1 - k]
        fit = fitter.fit(u, [Term(cand, loc, par, 0.0)], [par.to_fit(v)])
        identifiable.append(float(np.max(np.abs(fitter.whiten(fit.readings)))))
    data = effect + sigma * rng.standard_normal(effect.shape)
    names = " + ".join(c.name for c, *_ in drawn)
    measurement = Measurement(data, scenario.sensor_names, scenario.load_levels, f"pseudo-data ({names})")
    return TwoCauseTrial(tuple((c.name, loc, v) for c, loc, _, v in drawn), dict(truth), measurement, noise, sigma,
                         tuple(identifiable))


def bed_joint_locations(ctx, y):
    """Every segment of the bed joint at height ``y`` (mm) as :data:`weak_joint` locations: the
    whole joint, course to course across the wall."""
    cand = CANDIDATES["weak_joint"]
    segments = [loc for loc in cand.locations(ctx) if "segment" in loc.detail and loc.detail["kind"] == "bed"]
    out = [loc for loc in segments if np.isclose(loc.detail["y"][0], y)]
    if not out:
        heights = sorted({loc.detail["y"][0] for loc in segments})
        raise ValueError(f"no bed joint at y = {y:g} mm; bed joints at {heights}")
    return out


def make_whole_joint_trial(scenario, space, truth, y, factor, *, rng, model_tolerance=None, rigid_body="auto"):
    """Pseudo-data from ``truth`` with a *whole* bed joint weakened: every segment of the bed joint
    at height ``y`` (mm) with its normal and shear stiffness times ``factor``, plus noise
    (:func:`noise_sigma`), built segment by segment (not through the candidate's whole-bed-joint
    location, which the diagnosis should find): the structural cause is the joint, and a
    one-sensor fault is a wrong answer. ``identifiable_effect`` is the largest |residual| / σ left
    after refitting the base parameters to the noise-free data."""
    values, ctx, clean = _context(scenario, space, truth)
    cand = CANDIDATES["weak_joint"]
    effect = ctx.readings_with(values, [(cand, loc, float(factor)) for loc in bed_joint_locations(ctx, y)])
    sigma = noise_sigma(effect)
    noise = NoiseModel(sigma=sigma)
    fitter, u = _exact_fitter(ctx, scenario, space, values, effect, noise, model_tolerance, rigid_body)
    identifiable = float(np.max(np.abs(fitter.whiten(fitter.fit(u).readings))))
    data = effect + sigma * rng.standard_normal(effect.shape)
    measurement = Measurement(data, scenario.sensor_names, scenario.load_levels,
                              f"pseudo-data (bed joint at y = {y:g} mm × {factor:g})")
    return Trial("weak_joint", None, float(factor), dict(truth), measurement, noise, sigma,
                 float(np.max(np.abs(effect - clean)) / sigma), identifiable)
