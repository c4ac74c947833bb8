"""Settings of the online stage, declared once: the noise model, the inversion, the region of
equivalence and the calibration that composes them.

Each class is a frozen settings object of :mod:`podkrig.config`: every field has its default,
its unit and its allowed values here and nowhere else. The study file's checker validates its
``[measurement]`` and ``[inversion]`` tables with the field types below, ``podkrig invert``
builds these objects from its options and takes its choices from :func:`podkrig.config.choices`,
and the calibration stage (:func:`podkrig.online.calibrate.calibrate`) consumes them; its cache
key is :func:`dataclasses.asdict` of them.

Examples
--------
>>> s = CalibrationSettings(region=RegionSettings(method="noise-mc"), mcmc_steps=2000)
>>> s.inversion.generations, s.confidence, s.region.method
(100, 0.95, 'noise-mc')
>>> NoiseSettings(noise_abs=0.001, noise_rel=0.01).describe()
'σ² = σ_res² + (δ d)², σ_res = 0.001 mm, δ = 1 % of each reading'
"""

import dataclasses
from typing import Annotated, Any

from pydantic import AfterValidator, StrictBool, StrictFloat, StrictInt

from podkrig import limits
from podkrig.config import Seed, allowed, choice, field_info, limit, settings, settings_error, type_name
from podkrig.online.measurement import (DELTA_RANGE, INSTRUMENTS, SIGMA_RANGE_MM, NoiseModel, instrument_noise,
                                         instrument_unit)
from podkrig.online.model_error import parse_model_form_error

__all__ = [
    "CONFIDENCE", "GA", "REGION_METHODS", "REGION_SAMPLES", "SENSITIVITY", "CalibrationSettings", "InversionSettings",
    "NoiseSettings", "RegionSettings", "SensitivitySettings",
    "check_ga_budget", "check_noise",
]

# ---------------------------------------------------------------------------------------------
# noise

_SIGMA_LO, _SIGMA_HI = SIGMA_RANGE_MM
_DELTA_LO, _DELTA_HI = DELTA_RANGE
#: σ_res in words, mm (:data:`~podkrig.online.measurement.SIGMA_RANGE_MM`)
SIGMA_ALLOWED = f"σ_res in [{_SIGMA_LO:g}, {_SIGMA_HI:g}] mm"
#: what a noise model may be, in words (shown with every noise error)
NOISE_ALLOWED = (f"noise_abs = {SIGMA_ALLOWED} (a number, or a table sensor = σ) and/or noise_rel = δ in "
                 f"[{_DELTA_LO:g}, {_DELTA_HI:g}) (σ² = σ_res² + (δ d)²), or instrument = "
                 + " | ".join(f'"{k}"' for k in INSTRUMENTS) + " (or a table sensor = instrument)")


def _noise_abs(value):
    if value is None:
        return None
    if isinstance(value, dict):
        if not value:
            raise settings_error("empty table", allowed=NOISE_ALLOWED)
        for sensor, sigma in value.items():
            if isinstance(sigma, bool) or not isinstance(sigma, int | float):
                raise settings_error(f"must be a number; got {type_name(sigma)} {sigma!r}", sensor, SIGMA_ALLOWED)
            if not _SIGMA_LO <= sigma <= _SIGMA_HI:
                raise settings_error(f"{sigma!r} is out of range", sensor, SIGMA_ALLOWED)
        return {k: float(v) for k, v in value.items()}
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise settings_error(f"must be a number; got {type_name(value)} {value!r}", allowed=NOISE_ALLOWED)
    if not _SIGMA_LO <= value <= _SIGMA_HI:
        raise settings_error(f"{value!r} is out of range", allowed=NOISE_ALLOWED)
    return float(value)


def _instrument(value):
    if value is None:
        return None
    names = " | ".join(f'"{k}"' for k in INSTRUMENTS)
    if isinstance(value, str):
        if value not in INSTRUMENTS:
            raise settings_error(f"{value!r} is not a known instrument", allowed=names)
        return value
    if isinstance(value, dict) and value:
        for sensor, kind in value.items():
            if not isinstance(kind, str) or kind not in INSTRUMENTS:
                raise settings_error(f"{kind!r} is not a known instrument", sensor, names)
        return dict(value)
    raise settings_error(f"must be an instrument name or a table sensor = instrument; got {type_name(value)} "
                         f"{value!r}", allowed=names)


#: σ_res, mm: one number for every sensor or a table sensor → σ_res
NoiseAbs = Annotated[Any, AfterValidator(_noise_abs), allowed(NOISE_ALLOWED, unit="mm")]
#: δ, relative to each reading
NoiseRel = Annotated[StrictFloat, allowed(NOISE_ALLOWED, unit="-", ge=_DELTA_LO, lt=_DELTA_HI)] | None
#: an instrument of :data:`~podkrig.online.measurement.INSTRUMENTS`, or a table sensor → instrument
Instrument = Annotated[Any, AfterValidator(_instrument), allowed(NOISE_ALLOWED)]


def check_noise(noise_abs, noise_rel, instrument):
    """The rule tying the noise fields together: an instrument, or σ_res and/or δ (a
    :func:`~podkrig.config.settings_error` otherwise)."""
    if instrument is not None:
        other = [k for k, v in (("noise_abs", noise_abs), ("noise_rel", noise_rel)) if v is not None]
        if other:
            raise settings_error(f"give either instrument or {other[0]}, not both", "instrument", NOISE_ALLOWED)
    elif noise_rel is None and noise_abs is None:
        raise settings_error("give a noise model", None, NOISE_ALLOWED)


@settings
class NoiseSettings:
    """The measurement noise of a test: ``noise_abs`` σ_res (mm; one for all sensors, or one per
    sensor) and/or ``noise_rel`` δ, combined as σ_i² = σ_res,i² + (δ d_i)²; or ``instrument`` (one
    name, or one per sensor) with the typical σ_res and δ of
    :data:`~podkrig.online.measurement.INSTRUMENTS`."""

    noise_abs: NoiseAbs = None
    noise_rel: NoiseRel = None
    instrument: Instrument = None

    def __post_init__(self):
        check_noise(self.noise_abs, self.noise_rel, self.instrument)

    def noise_model(self, sensor_names=None, sensor_units=None):
        """The :class:`~podkrig.online.measurement.NoiseModel` (``sensor_names``: the measured
        sensors, needed for ``instrument``; ``sensor_units``: their units, mm or kN for a load
        reading, see :func:`~podkrig.online.measurement.instrument_noise`)."""
        if self.instrument is not None:
            if sensor_names is None:
                raise ValueError("an instrument noise model needs the measured sensor names")
            return instrument_noise(self.instrument, sensor_names, sensor_units)
        return NoiseModel(sigma=self.noise_abs, delta=self.noise_rel)

    def unknown_sensors(self, sensor_names):
        """The per-sensor entries naming no sensor of ``sensor_names`` (the model's): a list of
        ``(field, sensor)``, e.g. ``[("noise_abs", "D9")]`` — the front door words them with its
        file and key or its option."""
        known = set(sensor_names)
        return [(name, key) for name in ("noise_abs", "instrument") if isinstance(getattr(self, name), dict)
                for key in getattr(self, name) if key not in known]

    def _kinds(self):
        return {self.instrument} if isinstance(self.instrument, str) else set(self.instrument.values())

    def describe(self):
        """The noise model in words, with units."""
        if self.instrument is not None:
            return "instruments: " + "; ".join(INSTRUMENTS[k]["text"] for k in sorted(self._kinds()))
        return NoiseModel(sigma=self.noise_abs, delta=self.noise_rel).describe()

    def levels(self):
        """``(δ, σ_res)``: the smallest relative and absolute noise levels (None where absent), for
        comparisons with the surrogate's error."""
        if self.instrument is None:
            return self.noise_rel, self.noise_abs
        kinds = self._kinds()
        rel = min(INSTRUMENTS[k]["delta"] for k in kinds)
        mm = [INSTRUMENTS[k]["sigma_res_mm"] for k in kinds if instrument_unit(k) == "mm"]  # not a load cell's kN
        return (rel or None), (min(mm) if mm else None)


# ---------------------------------------------------------------------------------------------
# inversion, region, calibration

#: region of equivalence methods: the likelihood-ratio bound on ω, or noise Monte Carlo (re-identify
#: noisy copies of the best-fit prediction) — :mod:`podkrig.online.region`
REGION_METHODS = ("likelihood-ratio", "noise-mc")

_POPULATION_ALLOWED = f"an integer in [4, {limits.MAX_POPULATION}]"
_STARTS_ALLOWED = f"an integer in [1, {limits.MAX_STARTS}]"
_REGION_ALLOWED = (f"an integer in [{limits.REGION_SAMPLES_MIN}, {limits.REGION_SAMPLES_MAX}] (surrogate "
                   "evaluations per sampling round)")
_MODEL_FORM_ERROR_ALLOWED = ('"none", "estimated" or a number in [0, 0.5) (a relative tolerance, e.g. 0.01 for 1 % '
                             'of each reading)')

PopulationSize = Annotated[StrictInt, allowed(_POPULATION_ALLOWED, ge=4),
                           limit(limits.check_population, _POPULATION_ALLOWED)]
Generations = Annotated[StrictInt, allowed("an integer >= 1", ge=1)]
Starts = Annotated[StrictInt, allowed(f"{_STARTS_ALLOWED} (least-squares polishes)", ge=1),
                   limit(limits.check_starts, _STARTS_ALLOWED)]
Confidence = Annotated[StrictFloat, allowed("a number in (0, 1), e.g. 0.95", unit="-", gt=0, lt=1)]
RegionSamples = Annotated[StrictInt, allowed(_REGION_ALLOWED, ge=limits.REGION_SAMPLES_MIN),
                          limit(lambda n: limits.check_region_samples(n, "region_samples"), _REGION_ALLOWED)]


def _model_form_error(value):
    if isinstance(value, dict):  # per test of a joint calibration
        return {str(k): _model_form_error(v) for k, v in value.items()}
    if isinstance(value, bool) or not isinstance(value, str | int | float):
        raise settings_error(f"got {type_name(value)} {value!r}", allowed=_MODEL_FORM_ERROR_ALLOWED)
    try:
        parsed = parse_model_form_error(value)
    except ValueError:
        raise settings_error(f"got {value!r}", allowed=_MODEL_FORM_ERROR_ALLOWED) from None
    return "none" if parsed is None else parsed


#: the model-form error of C_D (thesis eq. 2.10): "none", "estimated" or a relative tolerance ε
ModelFormError = Annotated[Any, AfterValidator(_model_form_error), allowed(_MODEL_FORM_ERROR_ALLOWED)]


def check_ga_budget(population_size, generations):
    """The rule tying the GA's size together: population_size × (generations + 1) evaluations at
    most :data:`~podkrig.limits.MAX_GA_EVALUATIONS` (a :func:`~podkrig.config.settings_error`)."""
    try:
        limits.check_generations(generations, population_size)
    except ValueError as e:
        raise settings_error(str(e), "generations", "population_size × (generations + 1) at most "
                             f"{limits.MAX_GA_EVALUATIONS}") from None


@settings
class InversionSettings:
    """The GA on the surrogate and the least-squares polish (:func:`podkrig.online.invert.invert`);
    ``seed`` seeds the whole calibration (GA, Sobol' screen, region sampling, posterior, RVC)."""

    seed: Seed = 0
    population_size: PopulationSize = 100
    generations: Generations = 100
    n_starts: Starts = 6

    def __post_init__(self):
        check_ga_budget(self.population_size, self.generations)

    def options(self):
        """The keywords of :func:`~podkrig.online.invert.invert`."""
        return {"rng": self.seed, "population_size": self.population_size, "generations": self.generations,
                "n_starts": self.n_starts}


@settings
class RegionSettings:
    """The region of equivalence (:mod:`podkrig.online.region`): ``method`` and, for the likelihood
    ratio, the surrogate evaluations per sampling round."""

    method: choice(REGION_METHODS) = "likelihood-ratio"
    samples: RegionSamples = 2**17


@settings
class CalibrationSettings:
    """Everything :func:`~podkrig.online.calibrate.calibrate` does: the inversion, the region of
    equivalence at ``confidence`` (also of the posterior's credible intervals), the FE check at the
    optimum, the model-form error in C_D (thesis eq. 2.10: "none", "estimated" — each reading's
    discretisation error from the mesh refined twice at a first optimum, then inverted again — or
    a relative tolerance ε; a table test → value in a joint calibration) and the MCMC posterior
    (``mcmc_steps`` > 0)."""

    inversion: InversionSettings = dataclasses.field(default_factory=InversionSettings)
    region: RegionSettings = dataclasses.field(default_factory=RegionSettings)
    confidence: Confidence = 0.95
    fe_check: StrictBool = True
    model_form_error: ModelFormError = "none"
    mcmc_steps: Annotated[StrictInt, allowed("an integer >= 0 (MCMC steps; 0: no posterior)", ge=0)] = 0

    def form_error(self, test=None):
        """The model-form error of one test (``test`` of a joint calibration, None for one test):
        None, "estimated" or ε."""
        value = self.model_form_error
        if isinstance(value, dict):
            value = value.get(str(test), "none")
        return None if value == "none" else value


def _power_of_two(value):
    if value & (value - 1):
        raise ValueError("not a power of two")
    return value


@settings
class SensitivitySettings:
    """Global sensitivity on the surrogate (:mod:`podkrig.online.sensitivity`): Sobol' indices of
    every reading and of the misfit from ``n`` base samples (``n (d + 2)`` surrogate evaluations),
    the seed of the scrambled Sobol' matrices and of the bootstrap, and the level of the
    bootstrap intervals."""

    n: Annotated[StrictInt, AfterValidator(_power_of_two),
                 allowed("a power of two in [256, 65536] (base samples)", ge=256, le=65536)] = 2**12
    seed: Seed = 0
    confidence: Confidence = 0.95

    def options(self):
        """The keywords of :func:`~podkrig.online.sensitivity.sobol_indices`."""
        return {"n": self.n, "rng": self.seed, "confidence": self.confidence}


def _default(cls, name):
    return field_info(cls)[name]["default"]


#: the defaults, for the keywords of the library functions that take them one by one
#: (:func:`~podkrig.online.invert.invert`, the region functions, the posterior)
CONFIDENCE = _default(CalibrationSettings, "confidence")
REGION_SAMPLES = _default(RegionSettings, "samples")
GA = {name: info["default"] for name, info in field_info(InversionSettings).items()}
#: the defaults of :func:`~podkrig.online.sensitivity.sobol_indices`
SENSITIVITY = SensitivitySettings()
