"""Settings of a study file, declared once: types, ranges, allowed values and defaults.

The tables of the stages' own settings are the stages' classes (``[sampling]``:
:class:`~podkrig.offline.settings.SamplingSettings`, ``[surrogate]``:
:class:`~podkrig.surrogate.settings.SurrogateSettings`); the others are declared here. Each table
of the study file is a frozen pydantic dataclass (:mod:`pydantic.dataclasses`, so
:func:`dataclasses.asdict` and ``dataclasses.replace`` work on them as on plain dataclasses).
A field states its type (strict: TOML's own types, no coercion from strings or booleans), its
range or allowed values and, in ``json_schema_extra["allowed"]``, the words the checker
(:mod:`podkrig.study.schema`) shows a user who got it wrong. Rules that tie two keys together
raise :func:`study_error`, which the checker turns into the same message form.

The tables whose keys depend on the scenario (``[scenario]``, the parameter names of
``[parameters]`` and ``[fixed]``, their physical ranges) are checked by the checker against the
FE scenario registry; here only their shape is declared.
"""

import dataclasses
import math
import re
from pathlib import Path
from typing import Annotated, Any

from pydantic import (
    AfterValidator,
    BeforeValidator,
    Field,
    StrictBool,
    StrictFloat,
    StrictInt,
    StrictStr,
)

from podkrig import limits
from podkrig.config import Seed, finite as _finite, limit as _limit, settings as _settings, type_name
from podkrig.config import allowed as _allowed, choice as _choice, settings_error as study_error
from podkrig.offline.settings import ROWS_ALLOWED as _ROWS_ALLOWED
from podkrig.offline.settings import SAMPLING_METHODS, Design, SamplingSettings, TrainingDesign
from podkrig.offline.settings import training_rows as _training_rows
from podkrig.online.measurement import INSTRUMENTS, NoiseModel, instrument_noise
from podkrig.io.measurement_log import REPEATS, ImportSettings, zero_phase
from podkrig.online.model_error import parse_model_form_error
from podkrig.online.rigid_body import RIGID_BODY_CHOICES
from podkrig.parameters import SCALES, ParameterSpace
from podkrig.surrogate.settings import BACKENDS, BETA_MODES, CRITERIA, VARIOGRAMS, SurrogateSettings

__all__ = [
    "BACKENDS", "BETA_MODES", "CRITERIA", "REGION_METHODS", "SAMPLING_METHODS", "VARIOGRAMS",
    "CalibrationTest", "Design", "DiagnosisSettings", "InversionSettings", "MeasurementSettings",
    "SensitivitySettings", "Study", "SurrogateSettings", "TrainingDesign", "ValidationModel", "study_error",
    "type_name",
]

REGION_METHODS = ("likelihood-ratio", "noise-mc")


def _raise():
    raise ValueError("out of range")


# ---------------------------------------------------------------------------------------------
# measurement

_NOISE_ALLOWED = ("noise_abs = σ_res > 0 mm (a number, or a table sensor = σ) and/or noise_rel = δ in (0, 1) "
                  "(σ² = σ_res² + (δ d)²), or instrument = " + " | ".join(f'"{k}"' for k in INSTRUMENTS)
                  + " (or a table sensor = instrument)")
_FILE_ALLOWED = ("a CSV (.csv, .txt) or Excel (.xlsx) log, relative to the study file: a load column and one "
                 "column per sensor, units in the headers (e.g. 'load [kN]', 'D1 [µm]'; mm without one)")


def _measurement_file(value, info):
    """The measurement file, resolved against the study file's folder (validation context
    ``{"folder": Path}``; the working folder without one)."""
    if not isinstance(value, str | Path):
        raise study_error(f"must be a string; got {type_name(value)} {value!r}")
    folder = (info.context or {}).get("folder", Path.cwd())
    try:
        full = (Path(folder) / value).resolve()
        exists = full.is_file()
    except (OSError, ValueError) as e:
        raise study_error(f"not a usable path ({e})", allowed=_FILE_ALLOWED) from None
    if not exists:
        raise study_error(f"no measurement file at {full}", allowed=_FILE_ALLOWED)
    return full


def _noise_abs(value):
    if isinstance(value, dict):
        if not value:
            raise study_error("empty table", allowed=_NOISE_ALLOWED)
        for sensor, sigma in value.items():
            if isinstance(sigma, bool) or not isinstance(sigma, int | float):
                raise study_error(f"must be a number; got {type_name(sigma)} {sigma!r}", sensor, "σ > 0 mm")
            if not sigma > 0 or not math.isfinite(sigma):
                raise study_error(f"{sigma!r} is out of range", sensor, "σ > 0 mm")
        return {k: float(v) for k, v in value.items()}
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise study_error(f"must be a number; got {type_name(value)} {value!r}", allowed=_NOISE_ALLOWED)
    if not value > 0 or not math.isfinite(value):
        raise study_error(f"{value!r} is out of range", allowed=_NOISE_ALLOWED)
    return float(value)


def _instrument(value):
    names = " | ".join(f'"{k}"' for k in INSTRUMENTS)
    if isinstance(value, str):
        if value not in INSTRUMENTS:
            raise study_error(f"{value!r} is not a known instrument", allowed=names)
        return value
    if isinstance(value, dict) and value:
        for sensor, kind in value.items():
            if not isinstance(kind, str) or kind not in INSTRUMENTS:
                raise study_error(f"{kind!r} is not a known instrument", sensor, names)
        return dict(value)
    raise study_error(f"must be an instrument name or a table sensor = instrument; got {type_name(value)} {value!r}",
                      allowed=names)


def _zero(value):
    if value is None or value == "first" or (isinstance(value, int | float) and not isinstance(value, bool)
                                             and math.isfinite(value)):
        return None if value is None else value if value == "first" else float(value)
    if value == "none":
        return None
    if zero_phase(value) is not None:
        return value
    raise study_error(f"{value!r} is not a zero reference", allowed='"first", "none" or a load (number, the '
                      'scenario\'s load unit), or "end of PHASE" (the last row of that phase in the phase_column)')


_RIGID_GROUPS_ALLOWED = ('a table group = ["sensor", ...] of point displacement sensors (kind = "point") whose '
                         'rigid-body motion is fitted and removed together, e.g. rigid_groups = { top = ["P1", "P2"] }')
_RIGID_BODY_ALLOWED = ('"auto" (remove the rigid-body motion of each DIC grid and of the rigid_groups), "remove" (also '
                       'of all other point displacement sensors, together) or "keep" (remove nothing)')


def _rigid_groups(value):
    if not isinstance(value, dict) or not value:
        raise study_error(f"must be a non-empty table; got {type_name(value)} {value!r}", allowed=_RIGID_GROUPS_ALLOWED)
    for group, names in value.items():
        if not (isinstance(names, list) and names and all(isinstance(n, str) for n in names)):
            raise study_error(f"must be a non-empty array of sensor names; got {type_name(names)} {names!r}", group,
                              _RIGID_GROUPS_ALLOWED)
    return {k: tuple(v) for k, v in value.items()}


_MODEL_FORM_ERROR_ALLOWED = ('"none", "estimated" or a number in [0, 0.5) (a relative tolerance, e.g. 0.01 for 1 % '
                             'of each reading)')


def _model_form_error(value):
    if isinstance(value, bool) or not isinstance(value, str | int | float):
        raise study_error(f"got {type_name(value)} {value!r}", allowed=_MODEL_FORM_ERROR_ALLOWED)
    try:
        parsed = parse_model_form_error(value)
    except ValueError:
        raise study_error(f"got {value!r}", allowed=_MODEL_FORM_ERROR_ALLOWED) from None
    return "none" if parsed is None else parsed


def _load_range(value):
    if (isinstance(value, list) and len(value) == 2
            and all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value)
            and value[0] <= value[1]):
        return (float(value[0]), float(value[1]))
    raise study_error(f"{value!r} is not a load range", allowed="[lower, upper] with lower <= upper (the "
                      "scenario's load unit)")


@_settings
class MeasurementSettings:
    """The measurement log (absolute path), how to read it and its noise model.

    Noise: ``noise_abs`` σ_res in mm (one for all sensors, or one per sensor) and/or ``noise_rel``
    δ, combined as σ_i² = σ_res,i² + (δ d_i)²; or ``instrument`` (one name, or one per sensor) with
    the typical σ_res and δ of :data:`~podkrig.online.measurement.INSTRUMENTS`. Reading: see
    :class:`~podkrig.io.measurement_log.ImportSettings`. ``range_check`` stops a study whose
    readings lie far outside every FE run of the probe (before the training snapshots) and of the
    training design (a unit or sign error); false also skips the probe runs. ``rigid_body``:
    removal of the rigid-body motion of absolute displacement readings from data and model
    (:mod:`podkrig.online.rigid_body`; "auto": each DIC grid and the ``rigid_groups``).
    ``model_form_error``: the FE model's own discretisation error added to C_D in the inversion
    (thesis eq. 2.10): "none", "estimated" (per reading from the mesh refined twice, at a first
    optimum: the ``model_form_error`` stage) or a relative tolerance ε
    (:mod:`podkrig.online.model_error`). Validating a table
    needs the study file's folder in the context (``{"folder": Path}``); constructing one in
    code takes an existing file.
    """

    file: Annotated[Path, BeforeValidator(_measurement_file)]
    noise_rel: Annotated[StrictFloat, _allowed(_NOISE_ALLOWED, gt=0, lt=1)] | None = None
    noise_abs: Annotated[Any, AfterValidator(lambda v: None if v is None else _noise_abs(v))] = None
    instrument: Annotated[Any, AfterValidator(lambda v: None if v is None else _instrument(v))] = None
    load_column: Annotated[StrictStr, AfterValidator(lambda v: v if v.strip() else _raise()),
                           _allowed("the name of the load column (without its unit)")] = "load"
    repeats: _choice(REPEATS) = "average"
    load_tolerance: Annotated[StrictFloat, AfterValidator(_finite),
                              _allowed("a number >= 0 (the scenario's load unit)", ge=0)] = 0.0
    zero: Annotated[Any, AfterValidator(_zero)] = None
    phase_column: Annotated[StrictStr, AfterValidator(lambda v: v if v.strip() else _raise()),
                            _allowed("the name of the phase column (read for zero = \"end of PHASE\")")] = "phase"
    load_range: Annotated[Any, AfterValidator(lambda v: None if v is None else _load_range(v))] = None
    delimiter: _choice((",", ";", "\t"), '",", ";" or "\\t" (default: detected)') | None = None
    decimal: _choice((".", ","), '"." or "," (default: detected)') | None = None
    sheet: Annotated[StrictStr, _allowed("a worksheet name of the .xlsx file")] | None = None
    range_check: StrictBool = True
    rigid_body: _choice(RIGID_BODY_CHOICES, _RIGID_BODY_ALLOWED) = "auto"
    rigid_groups: Annotated[Any, AfterValidator(lambda v: None if v is None else _rigid_groups(v))] = None
    model_form_error: Annotated[Any, AfterValidator(_model_form_error)] = "none"

    def __post_init__(self):
        if self.rigid_body == "keep" and self.rigid_groups:
            raise study_error("rigid_groups name sensors whose rigid-body motion is removed, and rigid_body = \"keep\" "
                              "removes none; drop one of them", "rigid_groups", _RIGID_BODY_ALLOWED)
        if self.instrument is not None:
            other = [k for k in ("noise_abs", "noise_rel") if getattr(self, k) is not None]
            if other:
                raise study_error(f"give either instrument or {other[0]}, not both", "instrument", _NOISE_ALLOWED)
        elif self.noise_rel is None and self.noise_abs is None:
            raise study_error("give a noise model", None, _NOISE_ALLOWED)
        if self.delimiter == "," and self.decimal == ",":
            raise study_error("a comma cannot be both the delimiter and the decimal mark", "decimal")

    def import_settings(self):
        """The :class:`~podkrig.io.measurement_log.ImportSettings` of these settings."""
        return ImportSettings(load_column=self.load_column, repeats=self.repeats, load_tolerance=self.load_tolerance,
                              zero=self.zero, phase_column=self.phase_column, load_range=self.load_range,
                              delimiter=self.delimiter,
                              decimal=self.decimal, sheet=self.sheet)

    def noise_model(self, sensor_names=None):
        """The :class:`~podkrig.online.measurement.NoiseModel` of these settings (``sensor_names``:
        the measured sensors, needed for ``instrument``)."""
        if self.instrument is not None:
            if sensor_names is None:
                raise ValueError("an instrument noise model needs the measured sensor names")
            return instrument_noise(self.instrument, sensor_names)
        return NoiseModel(sigma=self.noise_abs, delta=self.noise_rel)

    def noise_levels(self):
        """``(δ, σ_res)``: the smallest relative and absolute noise levels of these settings (None
        where absent), for comparisons with the surrogate's error."""
        if self.instrument is None:
            return self.noise_rel, self.noise_abs
        kinds = {self.instrument} if isinstance(self.instrument, str) else set(self.instrument.values())
        rel = min(INSTRUMENTS[k]["delta"] for k in kinds)
        return (rel or None), min(INSTRUMENTS[k]["sigma_res_mm"] for k in kinds)

    def noise_text(self):
        """The noise model in words, with units."""
        if self.instrument is not None:
            kinds = {self.instrument} if isinstance(self.instrument, str) else set(self.instrument.values())
            return "instruments: " + "; ".join(INSTRUMENTS[k]["text"] for k in sorted(kinds))
        return NoiseModel(sigma=self.noise_abs, delta=self.noise_rel).describe()


# ---------------------------------------------------------------------------------------------
# inversion and diagnosis


_REGION_ALLOWED = (f"an integer in [{limits.REGION_SAMPLES_MIN}, {limits.REGION_SAMPLES_MAX}] (surrogate "
                   "evaluations per sampling round)")


@_settings
class InversionSettings:
    """GA inversion and region of equivalence settings (see :func:`podkrig.online.invert.invert`)."""

    seed: Seed = 0
    population_size: Annotated[StrictInt, _allowed(f"an integer in [4, {limits.MAX_POPULATION}]", ge=4),
                               _limit(limits.check_population, f"an integer in [4, {limits.MAX_POPULATION}]")] = 100
    generations: Annotated[StrictInt, _allowed("an integer >= 1", ge=1)] = 100
    n_starts: Annotated[StrictInt, _allowed(f"an integer in [1, {limits.MAX_STARTS}] (least-squares polishes)", ge=1),
                        _limit(limits.check_starts, f"an integer in [1, {limits.MAX_STARTS}]")] = 6
    confidence: Annotated[StrictFloat, _allowed("a number in (0, 1), e.g. 0.95", gt=0, lt=1)] = 0.95
    region_method: _choice(REGION_METHODS) = "likelihood-ratio"
    region_samples: Annotated[StrictInt, _allowed(_REGION_ALLOWED, ge=1024),
                              _limit(lambda n: limits.check_region_samples(n, "region_samples"),
                                     _REGION_ALLOWED)] = 2**17
    fe_check: StrictBool = True

    def __post_init__(self):
        try:
            limits.check_generations(self.generations, self.population_size)
        except ValueError as e:
            raise study_error(str(e), "generations", "population_size × (generations + 1) at most "
                              f"{limits.MAX_GA_EVALUATIONS}") from None


def _power_of_two(value):
    if value & (value - 1):
        raise ValueError("not a power of two")
    return value


@_settings
class SensitivitySettings:
    """Global sensitivity before the inversion (:mod:`podkrig.online.sensitivity`): Sobol' indices of
    every reading and of the misfit on the surrogate(s), ``n`` base samples (``n (d + 2)``
    evaluations), and the free parameters proposed for fixing because nothing is sensitive to them."""

    enabled: StrictBool = True
    n: Annotated[StrictInt, AfterValidator(_power_of_two),
                 _allowed("a power of two in [256, 65536] (base samples)", ge=256, le=65536)] = 2**12
    seed: Seed = 0


@_settings
class DiagnosisSettings:
    """Model diagnosis on or off, its seed, the most causes it names in turn, and an optional fixed
    relative model-form tolerance (by default each reading's discretisation error is estimated
    from the scenario on a mesh refined twice: :mod:`podkrig.online.model_error`)."""

    enabled: StrictBool = False
    seed: Seed = 0
    max_causes: Annotated[StrictInt, _allowed("an integer in [1, 10]", ge=1, le=10)] = 3
    model_tolerance: Annotated[StrictFloat | StrictInt | None,
                               _allowed("a number in [0, 0.5), e.g. 0.01 for 1 % of each reading", ge=0, lt=0.5)] = None


# ---------------------------------------------------------------------------------------------
# the file's shape (scenario-dependent parts are checked by the checker)

_NAME_ALLOWED = "letters, digits, '_' and '-' (it names files), other than 'calibration'"


def _outputs(value):
    if value is not None and (not isinstance(value, list) or not value
                              or not all(isinstance(o, str) and "@" in o for o in value)):
        raise study_error(f"must be a non-empty array of 'SENSOR@LOAD' strings; got {value!r}",
                          allowed="e.g. [\"top_ux@40\", \"D1@40\"]")
    return None if value is None else tuple(value)


@_settings
class ValidationEntry:
    """One ``[[validation]]`` table as written (the scenario is resolved by the checker)."""

    name: Annotated[StrictStr, AfterValidator(
        lambda v: v if re.fullmatch(r"[A-Za-z0-9_-]+", v) and v != "calibration" else _raise()),
        _allowed(_NAME_ALLOWED)]
    scenario: Any
    n: Annotated[StrictInt, _allowed(_ROWS_ALLOWED.format(4), ge=4), _training_rows]
    seed: Seed
    method: _choice(SAMPLING_METHODS) = "sobol"
    outputs: Annotated[Any, AfterValidator(_outputs)] = None


@_settings
class Bounds:
    """Bounds of a free parameter in its unit, and its scale (ranges checked by the checker)."""

    lower: StrictFloat
    upper: StrictFloat
    scale: _choice(SCALES, " or ".join(SCALES)) = "linear"


@_settings
class TestDesigns:
    """A ``[test.sampling]`` table: a test's own training and held-out designs (default: ``[sampling]``'s)."""

    train: TrainingDesign | None = None
    held_out: Design | None = None


@_settings
class TestEntry:
    """One ``[[test]]`` table of a joint calibration as written: its scenario, measurement and noise,
    its own (nuisance) free parameters and fixed values, and optionally its own designs."""

    name: Annotated[StrictStr, AfterValidator(
        lambda v: v if re.fullmatch(r"[A-Za-z0-9_-]+", v) and v != "calibration" else _raise()),
        _allowed(_NAME_ALLOWED)]
    scenario: Any
    measurement: MeasurementSettings
    parameters: Annotated[dict[str, Bounds], Field(json_schema_extra={"table": "a table"})] = dataclasses.field(
        default_factory=dict)
    fixed: Annotated[dict[str, StrictFloat],
                     Field(json_schema_extra={"table": "a table of parameter = value"})] = dataclasses.field(
        default_factory=dict)
    sampling: TestDesigns = dataclasses.field(default_factory=TestDesigns)


_REQUIRED = ("required top-level keys: measurement, parameters, sampling, scenario; or, for a joint calibration, "
             "parameters, sampling and two or more [[test]] tables each with name, scenario and [test.measurement]")


@_settings
class StudyFile:
    """The study file as written: every table's shape (see :mod:`podkrig.study.schema`). One test
    (``scenario`` and ``[measurement]`` at the top level) or a joint calibration (``[[test]]``
    tables, each with its scenario and measurement, sharing ``[parameters]``)."""

    parameters: Annotated[dict[str, Bounds], Field(json_schema_extra={"table": "a table"})]
    sampling: SamplingSettings
    scenario: Any = None
    measurement: MeasurementSettings | None = None
    test: Annotated[list[TestEntry], Field(json_schema_extra={"array": "an array of tables ([[test]])"})] = (
        dataclasses.field(default_factory=list))
    name: Annotated[StrictStr, AfterValidator(lambda v: v if v.strip() else _raise()),
                    _allowed("a non-empty string")] | None = None
    fixed: Annotated[dict[str, StrictFloat],
                     Field(json_schema_extra={"table": "a table of parameter = value"})] = dataclasses.field(
        default_factory=dict)
    surrogate: SurrogateSettings = dataclasses.field(default_factory=SurrogateSettings)
    inversion: InversionSettings = dataclasses.field(default_factory=InversionSettings)
    validation: Annotated[list[ValidationEntry],
                          Field(json_schema_extra={"array": "an array of tables ([[validation]])"})] = (
        dataclasses.field(default_factory=list))
    diagnosis: DiagnosisSettings = dataclasses.field(default_factory=DiagnosisSettings)
    sensitivity: SensitivitySettings = dataclasses.field(default_factory=SensitivitySettings)

    def __post_init__(self):
        if self.test:
            for key in ("scenario", "measurement"):
                if getattr(self, key) is not None:
                    raise study_error("a joint calibration gives each [[test]] its own scenario and measurement; "
                                      f"move the top-level {key} into the [[test]] tables", key)
            if len(self.test) < 2:
                raise study_error("one [[test]] table: a joint calibration needs two or more tests (for one test, "
                                  "write scenario and [measurement] at the top level)", "test")
            names = [t.name for t in self.test]
            twice = sorted({n for n in names if names.count(n) > 1})
            if twice:
                second = len(names) - 1 - names[::-1].index(twice[0])
                raise study_error(f"{twice[0]!r} names two tests", ("test", second, "name"),
                                  "distinct names")
            return
        for key in ("scenario", "measurement"):
            if getattr(self, key) is None:
                raise study_error(f"missing key {key!r}", (), _REQUIRED)


# ---------------------------------------------------------------------------------------------
# the study the pipeline consumes


@dataclasses.dataclass(frozen=True)
class ValidationModel:
    """A validation scenario for RVC: its spec, design and reported outputs (``SENSOR@LOAD``)."""

    name: str
    spec: object  # fe.ScenarioSpec
    design: Design
    outputs: tuple | None = None


@dataclasses.dataclass(frozen=True)
class Study:
    """A validated study file.

    Attributes
    ----------
    path : Path
        The study file.
    name : str
    spec : fe.ScenarioSpec
        The calibration scenario, normalised (every option explicit) with the fixed parameters
        in its ``parameters``.
    space : ParameterSpace
        The free parameters (bounds in their units, scales).
    fixed : dict of str to float
        Parameters held at a value, in their units.
    train, held_out : Design
    workers : int or None
        FE worker processes (``None`` when ``scheduler`` is given).
    scheduler : str or None
        Address of a Dask scheduler for the offline stage.
    surrogate : SurrogateSettings
    measurement : MeasurementSettings
    inversion : InversionSettings
    validation : tuple of ValidationModel
    diagnosis : DiagnosisSettings
    sensitivity : SensitivitySettings
    tests : tuple of CalibrationTest
        The tests of a joint calibration (``[[test]]`` tables); empty for a study of one test, whose
        scenario, designs and measurement are :attr:`spec`, :attr:`train`, :attr:`held_out` and
        :attr:`measurement` (then ``None`` in a joint calibration). :attr:`space` holds the shared
        parameters; each test's own are in its ``space``.
    """

    path: Path
    name: str
    spec: object
    space: ParameterSpace
    fixed: dict
    train: Design
    held_out: Design
    workers: int | None
    scheduler: str | None
    surrogate: SurrogateSettings
    measurement: MeasurementSettings
    inversion: InversionSettings
    validation: tuple
    diagnosis: DiagnosisSettings
    sensitivity: SensitivitySettings = SensitivitySettings()
    tests: tuple = ()

    @property
    def calibration_tests(self):
        """The tests the calibration fits, as :class:`CalibrationTest` objects: the ``[[test]]``
        tables, or the one test of a single-test study (``name`` None: stages and files keep their
        single-test names)."""
        if self.tests:
            return self.tests
        return (CalibrationTest(None, self.spec, self.space, dict(self.fixed), self.train, self.held_out,
                                self.measurement),)


@dataclasses.dataclass(frozen=True)
class CalibrationTest:
    """One test of a calibration: its scenario, free parameters, designs and measurement.

    Attributes
    ----------
    name : str or None
        The ``[[test]]`` name; None for the one test of a single-test study.
    spec : fe.ScenarioSpec
        With the study's fixed values it knows and the test's own.
    space : ParameterSpace
        The free parameters this test depends on: the shared ones its scenario has, then its own.
    fixed : dict of str to float
    train, held_out : Design
    measurement : MeasurementSettings
    """

    name: str | None
    spec: object
    space: ParameterSpace
    fixed: dict
    train: Design
    held_out: Design
    measurement: MeasurementSettings

    def stage(self, stage):
        """The stage name of this test's ``stage`` (``"offline"`` → ``"offline.NAME"``)."""
        return stage if self.name is None else f"{stage}.{self.name}"

    def file(self, filename):
        """Where this test's output ``filename`` goes, relative to the study's output folder."""
        return filename if self.name is None else f"{self.name}/{filename}"

    def title(self, title):
        """A stage title naming the test."""
        return title if self.name is None else f"{title} — test {self.name}"
