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
import os
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

from podkrig.config import Seed, finite as _finite, settings as _settings, type_name
from podkrig.config import allowed as _allowed, choice as _choice, settings_error as study_error
from podkrig.config import field_info
from podkrig.diagnosis.settings import DiagnosisSettings
from podkrig.display import Displayed, summary
from podkrig.offline.settings import ROWS_ALLOWED as _ROWS_ALLOWED
from podkrig.offline.settings import SAMPLING_METHODS, Design, SamplingSettings, TrainingDesign
from podkrig.offline.settings import training_rows as _training_rows
from podkrig.io.measurement_log import REPEATS, ImportSettings, zero_phase
from podkrig.limits import quote
from podkrig.online.rigid_body import RIGID_BODY_CHOICES
from podkrig.online.settings import (
    REGION_METHODS,
    CalibrationSettings,
    Confidence,
    Generations,
    Instrument,
    InversionSettings,
    ModelFormError,
    NoiseAbs,
    NoiseRel,
    NoiseSettings,
    PopulationSize,
    RegionSamples,
    RegionSettings,
    SensitivitySettings,
    Starts,
    check_ga_budget,
    check_noise,
)
from podkrig.parameters import SCALES, ParameterSpace
from podkrig.reports.jupyter import study_html
from podkrig.surrogate.settings import BACKENDS, BETA_MODES, CRITERIA, VARIOGRAMS, SurrogateSettings

__all__ = [
    "BACKENDS", "BETA_MODES", "CRITERIA", "REGION_METHODS", "SAMPLING_METHODS", "VARIOGRAMS",
    "CalibrationTest", "Design", "DiagnosisSettings", "InversionTable", "MeasurementSettings",
    "NONLINEAR_FE_RUNS", "OUTSIDE", "SensitivityTable", "Study", "SurrogateSettings", "TrainingDesign", "ValidationModel", "path_in_folder",
    "study_error", "type_name",
]



def _raise():
    raise ValueError("out of range")


# ---------------------------------------------------------------------------------------------
# measurement

#: the defaults of reading a measurement log (:class:`~podkrig.io.measurement_log.ImportSettings`)
_IMPORT = ImportSettings()

_FILE_ALLOWED = ("a CSV (.csv, .txt) or Excel (.xlsx) log, relative to the study file: a load column and one "
                 "column per sensor, units in the headers (e.g. 'load [kN]', 'D1 [µm]'; mm without one)")


#: What a path in a study file may be (:func:`path_in_folder`).
OUTSIDE = "a path inside the study file's folder, or an absolute path if the file is elsewhere on purpose"


def path_in_folder(folder, value):
    """The path ``value`` of a study file in ``folder`` (normalised, symbolic links kept), or None
    when a relative ``value`` leads out of the folder (``../../x``); an absolute ``value`` is a
    file elsewhere on purpose and is returned as it is."""
    inside = os.path.normpath(Path(folder).absolute())
    given = os.path.normpath(Path(inside) / value)  # an absolute value stays itself
    if not Path(value).is_absolute() and os.path.commonpath([inside, given]) != inside:
        return None
    return Path(given)


def _measurement_file(value, info):
    """The measurement file, resolved against the study file's folder (validation context
    ``{"folder": Path}``; the working folder without one)."""
    if not isinstance(value, str | Path):
        raise study_error(f"must be a string; got {type_name(value)} {quote(value)}")
    folder = (info.context or {}).get("folder", Path.cwd())
    given = path_in_folder(folder, value)
    if given is None:
        raise study_error(f"{quote(str(value))} leads outside the study file's folder "
                          f"({os.path.normpath(Path(folder).absolute() / value)}); nothing was read", allowed=OUTSIDE)
    try:
        full = given.resolve()
        exists = full.is_file()
    except (OSError, ValueError) as e:
        raise study_error(f"not a usable path ({e})", allowed=_FILE_ALLOWED) from None
    if not exists:
        raise study_error(f"no measurement file at {full}", allowed=_FILE_ALLOWED)
    return full


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

    Noise: ``noise_abs``, ``noise_rel`` or ``instrument``, the fields of
    :class:`~podkrig.online.settings.NoiseSettings` (:attr:`noise`). Reading: see
    :class:`~podkrig.io.measurement_log.ImportSettings`. ``range_check`` stops a study whose
    readings lie far outside every FE run of the probe (before the training snapshots) and of the
    training design (a unit or sign error); false also skips the probe runs. ``rigid_body``:
    removal of the rigid-body motion of absolute displacement readings from data and model
    (:mod:`podkrig.online.rigid_body`; "auto": each DIC grid and the ``rigid_groups``).
    ``model_form_error``: the FE model's own discretisation error added to C_D in the inversion
    (thesis eq. 2.10): "none", "estimated" (per reading from the mesh refined twice, at a first
    optimum, by the calibration stage: :func:`~podkrig.online.calibrate.model_form_errors`) or a
    relative tolerance ε (:mod:`podkrig.online.model_error`). Validating a table
    needs the study file's folder in the context (``{"folder": Path}``); constructing one in
    code takes an existing file.
    """

    file: Annotated[Path, BeforeValidator(_measurement_file)]
    noise_rel: NoiseRel = None
    noise_abs: NoiseAbs = None
    instrument: Instrument = None
    load_column: Annotated[StrictStr, AfterValidator(lambda v: v if v.strip() else _raise()),
                           _allowed("the name of the load column (without its unit)")] = _IMPORT.load_column
    repeats: _choice(REPEATS) = _IMPORT.repeats
    load_tolerance: Annotated[StrictFloat, AfterValidator(_finite),
                              _allowed("a number >= 0 (the scenario's load unit)", ge=0)] = _IMPORT.load_tolerance
    zero: Annotated[Any, AfterValidator(_zero)] = None
    phase_column: Annotated[StrictStr, AfterValidator(lambda v: v if v.strip() else _raise()),
                            _allowed("the name of the phase column (read for zero = \"end of PHASE\")")] = (
        _IMPORT.phase_column)
    load_range: Annotated[Any, AfterValidator(lambda v: None if v is None else _load_range(v))] = None
    delimiter: _choice((",", ";", "\t"), '",", ";" or "\\t" (default: detected)') | None = None
    decimal: _choice((".", ","), '"." or "," (default: detected)') | None = None
    sheet: Annotated[StrictStr, _allowed("a worksheet name of the .xlsx file")] | None = None
    range_check: StrictBool = True
    rigid_body: _choice(RIGID_BODY_CHOICES, _RIGID_BODY_ALLOWED) = "auto"
    rigid_groups: Annotated[Any, AfterValidator(lambda v: None if v is None else _rigid_groups(v))] = None
    model_form_error: ModelFormError = field_info(CalibrationSettings)["model_form_error"]["default"]

    def __post_init__(self):
        if self.rigid_body == "keep" and self.rigid_groups:
            raise study_error("rigid_groups name sensors whose rigid-body motion is removed, and rigid_body = \"keep\" "
                              "removes none; drop one of them", "rigid_groups", _RIGID_BODY_ALLOWED)
        check_noise(self.noise_abs, self.noise_rel, self.instrument)
        if self.delimiter == "," and self.decimal == ",":
            raise study_error("a comma cannot be both the delimiter and the decimal mark", "decimal")

    def import_settings(self):
        """The :class:`~podkrig.io.measurement_log.ImportSettings` of these settings."""
        return ImportSettings(load_column=self.load_column, repeats=self.repeats, load_tolerance=self.load_tolerance,
                              zero=self.zero, phase_column=self.phase_column, load_range=self.load_range,
                              delimiter=self.delimiter,
                              decimal=self.decimal, sheet=self.sheet)

    @property
    def noise(self):
        """The :class:`~podkrig.online.settings.NoiseSettings` of these settings."""
        return NoiseSettings(noise_abs=self.noise_abs, noise_rel=self.noise_rel, instrument=self.instrument)


# ---------------------------------------------------------------------------------------------
# inversion and diagnosis


def _default(cls, name):
    return field_info(cls)[name]["default"]


@_settings
class InversionTable:
    """The ``[inversion]`` table: the calibration's settings, flat (the fields and defaults of
    :class:`~podkrig.online.settings.InversionSettings`, ``region_``-prefixed those of
    :class:`~podkrig.online.settings.RegionSettings`, and those of
    :class:`~podkrig.online.settings.CalibrationSettings`; the model-form error is each test's
    ``[measurement] model_form_error``)."""

    seed: Seed = _default(InversionSettings, "seed")
    population_size: PopulationSize = _default(InversionSettings, "population_size")
    generations: Generations = _default(InversionSettings, "generations")
    n_starts: Starts = _default(InversionSettings, "n_starts")
    confidence: Confidence = _default(CalibrationSettings, "confidence")
    region_method: _choice(REGION_METHODS) = _default(RegionSettings, "method")
    region_samples: RegionSamples = _default(RegionSettings, "samples")
    fe_check: StrictBool = _default(CalibrationSettings, "fe_check")
    mcmc_steps: Annotated[StrictInt, _allowed("an integer >= 0 (MCMC steps; 0: no posterior)", ge=0)] = _default(
        CalibrationSettings, "mcmc_steps")

    def __post_init__(self):
        check_ga_budget(self.population_size, self.generations)

    def calibration(self, model_form_error="none"):
        """The :class:`~podkrig.online.settings.CalibrationSettings` of this table with the tests'
        ``model_form_error`` (one value, or a table test → value)."""
        return CalibrationSettings(
            inversion=InversionSettings(seed=self.seed, population_size=self.population_size,
                                        generations=self.generations, n_starts=self.n_starts),
            region=RegionSettings(method=self.region_method, samples=self.region_samples),
            confidence=self.confidence, fe_check=self.fe_check, mcmc_steps=self.mcmc_steps,
            model_form_error=model_form_error)


@_settings
class SensitivityTable(SensitivitySettings):
    """The ``[sensitivity]`` table: :class:`~podkrig.online.settings.SensitivitySettings` (after the
    calibration: Sobol' indices of every reading and of the misfit with the calibration's
    model-form error, and the free parameters proposed for fixing in the next calibration because
    nothing is sensitive to them), on by default."""

    enabled: StrictBool = True


# ---------------------------------------------------------------------------------------------
# the file's shape (scenario-dependent parts are checked by the checker)

_NAME_ALLOWED = "letters, digits, '_' and '-' (it names files), other than 'calibration'"


def _outputs(value):
    if value is not None and (not isinstance(value, list) or not value
                              or not all(isinstance(o, str) and o for o in value)):
        raise study_error(f"must be a non-empty array of 'SENSOR@LOAD' (or 'SENSOR': at the last level) strings; "
                          f"got {value!r}", allowed="e.g. [\"top_ux@40\", \"D1@40\"] or [\"F_peak\", \"d_peak\"]")
    return None if value is None else tuple(value)


_QUANTILES_ALLOWED = "an array of distinct levels in (0, 1), ascending, e.g. [0.05, 0.95]"


def _quantiles(value):
    if (not isinstance(value, list) or not value or not all(isinstance(q, float) and 0 < q < 1 for q in value)
            or value != sorted(set(value))):
        raise study_error(f"must be {_QUANTILES_ALLOWED}; got {value!r}", allowed=_QUANTILES_ALLOWED)
    return tuple(value)


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
    fe_runs: Annotated[StrictInt | None, _allowed(
        "an integer in [0, 256]: FE runs of the validation scenario at region members, for the share that fails "
        "(default 16 for a nonlinear scenario, 0 for a linear one)", ge=0, le=256)] = None
    quantiles: Annotated[Any, AfterValidator(_quantiles), _allowed(_QUANTILES_ALLOWED)] = (0.05, 0.95)


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
    inversion: InversionTable = dataclasses.field(default_factory=InversionTable)
    validation: Annotated[list[ValidationEntry],
                          Field(json_schema_extra={"array": "an array of tables ([[validation]])"})] = (
        dataclasses.field(default_factory=list))
    diagnosis: DiagnosisSettings = dataclasses.field(default_factory=DiagnosisSettings)
    sensitivity: SensitivityTable = dataclasses.field(default_factory=SensitivityTable)

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


#: FE runs at region members of a nonlinear validation scenario unless its table says (``fe_runs``)
NONLINEAR_FE_RUNS = 16


@dataclasses.dataclass(frozen=True)
class ValidationModel:
    """A validation scenario for RVC: its spec, design, reported outputs (``SENSOR@LOAD``, or
    ``SENSOR`` at the last level; None: every sensor at the last level), the FE runs at region
    members that measure the share of failed runs, and the quantile levels reported."""

    name: str
    spec: object  # fe.ScenarioSpec
    design: Design
    outputs: tuple | None = None
    fe_runs: int = 0
    quantiles: tuple = (0.05, 0.95)


@dataclasses.dataclass(frozen=True, repr=False)
class Study(Displayed):
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
    inversion : InversionTable
    validation : tuple of ValidationModel
    diagnosis : DiagnosisSettings
    sensitivity : SensitivityTable
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
    inversion: InversionTable
    validation: tuple
    diagnosis: DiagnosisSettings
    sensitivity: SensitivityTable = SensitivityTable()
    tests: tuple = ()

    def _repr_lines(self):
        """Each test's scenario and designs, then one line per free parameter (repr)."""
        tests = self.calibration_tests
        lines = [f"Study {self.name!r}: {len(tests)} test{'s' if len(tests) > 1 else ''}, "
                 f"{len(self.free_parameters)} free parameters, diagnosis {'on' if self.diagnosis.enabled else 'off'}",
                 f"  file: {self.path}"]
        lines += [f"  {'' if t.name is None else f'test {t.name}: '}scenario {t.spec.scenario}, {t.train.n} training "
                  f"and {t.held_out.n} held-out FE runs" for t in tests]
        return lines + [f"  {p.name} in [{summary(p.lower)}, {summary(p.upper)}] {p.unit} ({p.scale})"
                        for p in self.free_parameters]

    @property
    def free_parameters(self):
        """Every free parameter of the study, shared and each test's own, in order (tuple of
        :class:`~podkrig.parameters.Parameter`)."""
        found = {}
        for test in self.calibration_tests:
            for p in test.space.parameters:
                found.setdefault(p.name, p)
        return tuple(found.values())

    def _repr_html_(self):
        """The scenario, designs, free and fixed parameters as HTML tables, for Jupyter
        (:func:`podkrig.reports.jupyter.study_html`)."""
        return study_html(self)

    def calibration_settings(self):
        """The :class:`~podkrig.online.settings.CalibrationSettings` of the study: its
        ``[inversion]`` table with each test's ``[measurement] model_form_error``."""
        tests = self.calibration_tests
        if not self.tests:
            return self.inversion.calibration(tests[0].measurement.model_form_error)
        return self.inversion.calibration({t.name: t.measurement.model_form_error for t in tests})

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
