"""The study file (TOML): what a whole calibration study needs, read and validated in one place.

A study names the virtual test, the free parameters with their bounds and scales, the fixed
ones, the sampling designs (training and held-out), the surrogate settings, the measurement and
its noise model, the inversion settings, the validation scenarios (for RVC) and whether to run
the model diagnosis. Every value is checked when the file is read: an unknown key, a wrong type
or an out-of-range value raises :class:`StudyError` naming the file, the line, the key and the
allowed values.

Three modules share the work: :mod:`podkrig.study.settings` declares every table (types, ranges,
allowed values, defaults) as pydantic dataclasses; :mod:`podkrig.study.toml_lines` finds the line
of each key (Python's :mod:`tomllib` keeps none); this module validates a file against the
declarations, checks what depends on the scenario (its options, parameter names and physical
ranges) against the FE scenario registry, and words every failure the same way:
``FILE, line N: KEY: what is wrong; allowed: what is allowed`` (with "did you mean" for a
misspelt key).

File layout (units: N, mm, MPa; interface stiffness N/mm³; loads in the scenario's unit)::

    name = "panel_A"                        # optional; default: the file name

    [scenario]                              # a scenario spec inline; or  scenario = "NAME"
    scenario = "diagonal_compression"       #                         or  scenario = "spec.toml"
    nx = 6

    [parameters]                            # free parameters: bounds in their unit, scale
    E_b   = { lower = 5000.0, upper = 20000.0 }
    kN_bj = { lower = 10.0, upper = 1000.0, scale = "log" }

    [fixed]                                 # parameters held at a value (default: the scenario's)
    nu_b = 0.15

    [sampling]
    train    = { n = 128, seed = 0 }                      # method: sobol (default), lhs, random, lhs-ese
    held_out = { n = 32, seed = 1, method = "random" }
    workers  = 1                            # FE processes (1: in this process); or scheduler = "tcp://HOST:PORT"

    [surrogate]
    beta = "fit-shared"                     # a number in (0, 2], "fit" or "fit-shared"
    backend = "podkrig"                     # or "smt-krg", "smt-kpls", "sklearn-gpr"

    [measurement]
    file = "measured.csv"                   # relative to the study file (.csv or .xlsx; units in headers)
    instrument = "lvdt"                     # or noise_abs = 0.001 (mm) and/or noise_rel = 0.01
    # load_column, repeats, load_tolerance, zero, phase_column, load_range, delimiter, decimal,
    # sheet, range_check: see docs/measurements.md

    [inversion]
    seed = 0

    [[validation]]                          # validation models for RVC (any number)
    name = "shear_wall"
    scenario = "shear_compression"
    n = 64
    seed = 2
    # outputs = ["top_ux@40"]               # SENSOR@LOAD, or SENSOR at the last level (default: all there)
    # fe_runs = 16                          # FE runs at region members: the share that fails (nonlinear default 16)
    # quantiles = [0.05, 0.95]              # levels of the distribution reported

    [diagnosis]
    enabled = false

Example
-------
>>> study = load_study("examples/diagonal_compression.toml")
>>> study.space.names
('E_b', 'kN_bj', 'kV_bj', 'r_hj')
"""


import dataclasses
import difflib
import math
import os
import tomllib
import typing
from pathlib import Path

from pydantic import TypeAdapter, ValidationError

from fe.exceptions import ConstraintError, FEError, SpecError
from fe.scenarios import SCENARIOS, ScenarioSpec, build_scenario
from fe.scenarios.nonlinear import NonlinearScenario
from podkrig.exceptions import PodkrigError
from podkrig.limits import MAX_STUDY_FILE_BYTES, quote, read_bounded
from podkrig.online.propagation import output_columns
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.study.settings import (
    NONLINEAR_FE_RUNS,
    OUTSIDE,
    CalibrationTest,
    Study,
    StudyFile,
    TrainingDesign,
    ValidationModel,
    path_in_folder,
    type_name,
)
from podkrig.study.toml_lines import key_lines, show_key

__all__ = ["Study", "StudyError", "key_lines", "load_study"]

_STUDY_FILE = TypeAdapter(StudyFile)
_EXPECTED = {"int_type": "an integer", "float_type": "a number", "bool_type": "true or false",
             "string_type": "a string"}
_TABLE_ERRORS = ("dataclass_type", "dataclass_exact_type", "dict_type", "model_type")


class StudyError(PodkrigError, ValueError):
    """An invalid study file; the message names the file, the line, the key and what is allowed."""


# ---------------------------------------------------------------------------------------------
# the declarations along a key path


def _unwrap(tp):
    """``tp`` without ``Annotated`` and ``| None``; and the metadata met on the way."""
    metadata = []
    while True:
        if typing.get_origin(tp) is typing.Annotated:
            metadata.extend(tp.__metadata__)
            tp = typing.get_args(tp)[0]
        elif typing.get_origin(tp) in (typing.Union, type(int | None)):
            args = [a for a in typing.get_args(tp) if a is not type(None)]
            if len(args) != 1:
                return tp, metadata
            tp = args[0]
        else:
            return tp, metadata


def _declaration(loc):
    """The declared type at ``loc`` (a pydantic error location) and its schema extras
    (``allowed``, ``table``, ``array`` words)."""
    tp, extra = StudyFile, {}
    for part in loc:
        tp, _ = _unwrap(tp)
        fields = getattr(tp, "__pydantic_fields__", None)
        if fields is not None and isinstance(part, str) and part in fields:
            info = fields[part]
            tp, extra = info.annotation, dict(info.json_schema_extra or {})
            for m in info.metadata:
                extra.update(getattr(m, "json_schema_extra", None) or {})
        elif typing.get_origin(tp) is dict:
            tp, extra = typing.get_args(tp)[1], {}
        elif typing.get_origin(tp) is list:
            tp, extra = typing.get_args(tp)[0], {}
        else:
            return None, extra
    tp, metadata = _unwrap(tp)
    for m in metadata:
        extra.update(getattr(m, "json_schema_extra", None) or {})
    return tp, extra


def _keys_of(loc):
    """The keys declared for the table at ``loc``, in declaration order."""
    tp, _ = _declaration(loc)
    return tuple(getattr(tp, "__pydantic_fields__", {}))


# ---------------------------------------------------------------------------------------------
# wording


class _Reader:
    """Words failures of a study file with its file name and the line of the key."""

    def __init__(self, path, text):
        self.path = Path(path)
        self.lines = key_lines(text)

    def line(self, path):
        path = tuple(path)
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return None

    def fail(self, path, message, allowed=None):
        line = self.line(path)
        where = f"{self.path}, line {line}" if line else f"{self.path}"
        key = show_key(path)
        text = f"{where}: {key}: {message}" if key else f"{where}: {message}"
        if allowed:
            text += f"; allowed: {allowed}"
        raise StudyError(text)

    def unknown_key(self, path, key, allowed):
        close = difflib.get_close_matches(key, allowed, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        if key == "sensors" and not path and "scenario" in allowed:  # sensors belong to the scenario
            hint = (" (sensors belong to the scenario: write [[scenario.sensors]] with a name = \"...\" in each, "
                    "or a [scenario.sensors] table of named sensors; docs/scenarios.md)")
        where = f"in [{show_key(path)}]" if path else "at the top level"
        self.fail((*path, key), f"unknown key{hint}", f"keys {where}: {', '.join(sorted(allowed))}")

    def table(self, value, path, allowed):
        """Check that ``value`` is a table with only ``allowed`` keys (for tables whose keys
        depend on the scenario; the others are declared in :mod:`podkrig.study.settings`)."""
        if not isinstance(value, dict):
            self.fail(path, f"must be a table; got {type_name(value)} {quote(value)}")
        for key in value:
            if key not in allowed:
                self.unknown_key(path, key, allowed)
        return value

    def explain(self, error: ValidationError):
        """Raise the :class:`StudyError` of the first failure of a validation against the
        declarations: unknown keys first, then missing ones, then values, in file order."""
        errors = error.errors(include_url=False)
        rank = {"unexpected_keyword_argument": 0, "missing": 1}
        e = min(errors, key=lambda e: rank.get(e["type"], 2))
        loc, kind, value = tuple(e["loc"]), e["type"], e.get("input")
        _, extra = _declaration(loc)
        if kind == "unexpected_keyword_argument":
            self.unknown_key(loc[:-1], loc[-1], _keys_of(loc[:-1]))
        if kind == "missing":
            parent = loc[:-1]
            if parent:
                allowed = f"keys in [{show_key(parent)}]: {', '.join(sorted(_keys_of(parent)))}"
            else:
                required = [f.name for f in dataclasses.fields(StudyFile)
                            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
                allowed = f"required top-level keys: {', '.join(required)}"
            self.fail(parent, f"missing key {loc[-1]!r}", allowed)
        if kind == "settings":
            ctx = e["ctx"]
            self.fail((*loc, *ctx["key"]), ctx["message"], ctx["allowed"])
        if kind in _EXPECTED:
            self.fail(loc, f"must be {_EXPECTED[kind]}; got {type_name(value)} {quote(value)}", extra.get("allowed"))
        if kind in _TABLE_ERRORS:
            self.fail(loc, f"must be {extra.get('table', 'a table')}; got {type_name(value)} {quote(value)}")
        if kind == "list_type":
            self.fail(loc, f"must be {extra.get('array', 'an array')}; got {type_name(value)}")
        self.fail(loc, f"{quote(value)} is out of range", extra.get("allowed"))


# ---------------------------------------------------------------------------------------------
# reading and checking


def _check_numbers(r, value, path=()):
    """Refuse a non-finite number (TOML's ``inf``, ``nan``) or an integer too large for 64 bits
    anywhere in the file, with its line and key, before any declaration sees it."""
    if isinstance(value, dict):
        for k, v in value.items():
            _check_numbers(r, v, (*path, k))
    elif isinstance(value, list):
        for v in value:
            _check_numbers(r, v, path)
    elif isinstance(value, bool):
        return
    elif (isinstance(value, float) and not math.isfinite(value)) or (isinstance(value, int) and abs(value) >= 2**63):
        shown = repr(value) if len(repr(value)) < 30 else f"a number of {len(repr(value))} digits"
        r.fail(path, f"{shown} is not a finite number of ordinary size")


def load_study(path):
    """Read and validate a study file.

    Parameters
    ----------
    path : str or Path
        A TOML file. Relative paths inside it (scenario spec files, the measurement) are relative
        to its folder.

    Returns
    -------
    Study

    Raises
    ------
    StudyError
        Unreadable or invalid TOML, an unknown key, a wrong type or an out-of-range value; the
        message names the file, the line, the key and the allowed values.
    """
    path = Path(path)
    try:
        text = read_bounded(path, MAX_STUDY_FILE_BYTES, "study file", "is this the study file?").decode("utf-8")
    except OSError as e:
        raise StudyError(f"cannot read study file {path}: {e.strerror}") from e
    except UnicodeDecodeError as e:
        raise StudyError(f"{path}: not UTF-8 text at byte {e.start}; save it as UTF-8") from None
    except ValueError as e:
        raise StudyError(str(e)) from None
    try:
        data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError) as e:
        raise StudyError(f"{path}: not valid TOML: {e if isinstance(e, tomllib.TOMLDecodeError) else 'nested too deeply'}") from None
    r = _Reader(path, text)
    _check_numbers(r, data)
    try:
        f = _STUDY_FILE.validate_python(data, context={"folder": path.parent})
    except ValidationError as e:
        r.explain(e)

    s = f.sampling
    common = {"path": path.resolve(), "name": path.stem if f.name is None else f.name, "fixed": dict(f.fixed),
              "train": s.train, "held_out": s.held_out, "workers": s.workers, "scheduler": s.scheduler,
              "surrogate": f.surrogate, "inversion": f.inversion, "diagnosis": f.diagnosis,
              "sensitivity": f.sensitivity}
    if f.test:
        space, tests = _tests(r, data, f, path.parent)
        return Study(spec=None, space=space, measurement=None, tests=tests,
                     validation=_validation(r, f.validation, path.parent, f.fixed, space), **common)
    spec = _scenario(r, f.scenario, ("scenario",), path.parent, f.fixed)
    space = _parameters(r, data["parameters"], f.parameters, spec)
    both = sorted(set(space.names) & set(f.fixed))
    if both:
        r.fail(("fixed", both[0]), "is also a free parameter in [parameters]; choose one")
    _constraints(r, spec, space, {**{n: ("fixed", n) for n in f.fixed}, **{n: ("parameters", n) for n in space.names}})
    return Study(spec=spec, space=space, measurement=f.measurement,
                 validation=_validation(r, f.validation, path.parent, f.fixed, space), **common)


def _tests(r, data, f, folder):
    """The shared parameter space and the :class:`CalibrationTest` of each ``[[test]]`` table."""
    known = {}  # parameter name -> ParameterInfo, over every test's scenario
    specs = []
    for k, t in enumerate(f.test):
        where = ("test", k, "scenario")
        # the study's fixed values apply to the tests whose scenario has them; the test's own override
        own = {n: ("test", k, "fixed") for n in t.fixed}
        spec = _scenario(r, t.scenario, where, folder, t.fixed, own)  # which scenario, so which [fixed] apply
        info = {p.name for p in SCENARIOS[spec.scenario].PARAMETERS}
        shared_fixed = {n: v for n, v in f.fixed.items() if n in info and n not in t.fixed}
        spec = _scenario(r, t.scenario, where, folder, {**shared_fixed, **t.fixed}, own)
        specs.append(spec)
        known.update({p.name: p for p in SCENARIOS[spec.scenario].PARAMETERS})
    for n in f.fixed:
        if n not in known:
            r.fail(("fixed", n), "is a parameter of none of the tests' scenarios", ", ".join(known))
    shared = _parameters(r, data["parameters"], f.parameters, None, known)
    both = sorted(set(shared.names) & set(f.fixed))
    if both:
        r.fail(("fixed", both[0]), "is also a free parameter in [parameters]; choose one")
    tests = []
    for k, (t, spec) in enumerate(zip(f.test, specs)):
        where = ("test", k)
        info = {p.name for p in SCENARIOS[spec.scenario].PARAMETERS}
        for n in t.parameters:
            if n in shared.names:
                r.fail((*where, "parameters", n), "is already a shared parameter in [parameters]; give it once")
        own = _parameters(r, data["test"][k].get("parameters", {}), t.parameters, spec, allow_empty=True,
                          path=(*where, "parameters"))
        mine = [p for p in shared.parameters if p.name in info] + list(own.parameters if own else ())
        for n in t.fixed:
            if any(p.name == n for p in mine):
                r.fail((*where, "fixed", n), "is also a free parameter of this test; choose one")
        if not mine:
            r.fail((*where, "scenario"), f"scenario {spec.scenario} has none of the free parameters "
                   f"{list(shared.names)}: it cannot inform the calibration")
        space = ParameterSpace(tuple(mine))
        keys = {n: ("parameters", n) if n in shared.names else (*where, "parameters", n) for n in space.names}
        keys.update({n: (*where, "fixed", n) if n in t.fixed else ("fixed", n) for n in spec.parameters})
        _constraints(r, spec, space, keys, where, f"test {t.name!r}: ")
        d = t.sampling
        tests.append(CalibrationTest(t.name, spec, space,
                                     {**{n: v for n, v in f.fixed.items() if n in info}, **t.fixed},
                                     d.train or f.sampling.train, d.held_out or f.sampling.held_out, t.measurement))
    return shared, tuple(tests)


def _scenario(r, value, path, folder, fixed, fixed_paths=None):
    """The scenario spec of ``value`` (a name, a spec file or an inline table), normalised (every
    option explicit), with ``fixed`` among its parameters (a mistake in one is reported under its
    table in ``fixed_paths``, name → key path; default the top-level ``[fixed]``)."""
    names = ", ".join(sorted(SCENARIOS))
    allowed = f"a scenario name ({names}), a spec file (.toml or .json) or an inline table"
    source = None
    if isinstance(value, str):
        if value in SCENARIOS:
            value = {"scenario": value}
        else:
            source = path_in_folder(folder, value)
            if source is None:
                r.fail(path, f"{quote(value)} leads outside the study file's folder "
                             f"({os.path.normpath(folder.absolute() / value)}); nothing was read", OUTSIDE)
            if not source.is_file():
                r.fail(path, f"{value!r} is neither a scenario name nor a spec file (looked for {source})", allowed)
            try:
                value = ScenarioSpec.from_file(source).to_dict()
            except FEError as e:
                r.fail(path, str(e))
    if not isinstance(value, dict):
        r.fail(path, f"must be a scenario name, a file name or a table; got {type_name(value)} {quote(value)}", allowed)
    name = value.get("scenario")
    if not isinstance(name, str) or name not in SCENARIOS:  # a list is unhashable: check the type first
        r.fail((*path, "scenario"), "missing key 'scenario'" if name is None else f"unknown scenario {name!r}", names)
    cls = SCENARIOS[name]
    info = {p.name: p for p in cls.PARAMETERS}
    options = {k: v for k, v in value.items() if k not in ("scenario", "parameters")}
    if source is None:  # keys of a spec file are checked by the FE package, naming that file
        r.table(value, path, ("scenario", "parameters", *(f.name for f in dataclasses.fields(cls.Options))))
        r.table(value.get("parameters", {}), (*path, "parameters"), tuple(info))
    params = value.get("parameters", {})
    merged = {}
    for k, v in {**params, **fixed}.items():
        where = (*(fixed_paths or {}).get(k, ("fixed",)), k) if k in fixed else (*path, "parameters", k)
        if k not in info:
            r.fail(where, f"unknown parameter of {name}", ", ".join(info))
        if k in fixed and k in params and float(params[k]) != fixed[k]:
            r.fail(where, f"= {fixed[k]:g} contradicts {params[k]:g} in the scenario's parameters; give it once")
        if not _admissible(info[k], v):
            r.fail(where, f"= {v!r} is outside its physical range", f"{info[k].admissible_range()} ({info[k].description})")
        merged[k] = float(v)
    try:
        parsed = cls._parse_options(options)  # the scenario's own option checks (types, values)
    except FEError as e:
        r.fail(path, f"{e}" + (f" (in {source})" if source else ""))
    return ScenarioSpec(name, dataclasses.asdict(parsed), merged)


def _parameters(r, raw, bounds, spec, known=None, *, allow_empty=False, path=("parameters",)):
    """Free parameters: names known to the scenario (or in ``known``, name → ParameterInfo, for the
    shared parameters of a joint calibration), bounds within their physical range. Returns None for
    an empty table when ``allow_empty``."""
    info = known if spec is None else {p.name: p for p in SCENARIOS[spec.scenario].PARAMETERS}
    owner = spec.scenario if spec is not None else "any test's scenario"
    if not bounds:
        if allow_empty:
            return None
        r.fail(path, "no free parameters", f"some of {', '.join(info)}, e.g. kN_bj = {{ lower = 10.0, upper = 1000.0, scale = \"log\" }}")
    params = []
    for name, b in bounds.items():
        where = (*path, name)
        if name not in info:
            r.fail(where, f"unknown parameter of {owner}", ", ".join(info))
        p = info[name]
        for key in ("lower", "upper"):
            if not _admissible(p, getattr(b, key)):
                r.fail((*where, key), f"{raw[name][key]!r} is out of range", f"{p.admissible_range()} ({p.description})")
        lo, hi = b.lower, b.upper
        if not lo < hi:
            r.fail((*where, "upper"), f"must exceed lower = {lo:g} {p.unit}".rstrip(" -"), f"upper > {lo:g}")
        if b.scale == "log" and lo <= 0:
            r.fail((*where, "lower"), "must be > 0 on a log scale", "lower > 0, or scale = \"linear\"")
        params.append(Parameter(name, lo, hi, b.scale, p.unit))
    return ParameterSpace(tuple(params))


def _constraints(r, spec, space, keys, default=("parameters",), label=""):
    """The scenario's constraints between parameters over the sampling box of ``space`` and the
    spec's fixed values (:meth:`fe.Scenario.check_spec_box`), before any FE run; a failure is
    reported, after ``label``, at the key (``keys``: parameter → key path; else ``default``) of the
    first parameter of the violated constraint that is sampled, else fixed."""
    try:
        SCENARIOS[spec.scenario].check_spec_box(spec, {p.name: (p.lower, p.upper, p.scale) for p in space.parameters})
    except ConstraintError as e:
        involved = e.violations[0].constraint.parameters
        named = [n for n in involved if n in space.names] + [n for n in involved if n in keys]
        r.fail(keys.get(named[0], default) if named else default, f"{label}{e}")


def _admissible(info, value):
    """Whether ``value`` lies in the physical range of the parameter ``info`` (fe.ParameterInfo)."""
    try:
        info.check(value)
    except SpecError:
        return False
    return True


def _validation(r, entries, folder, fixed, space):
    """The validation models of the ``[[validation]]`` tables (declared shape already checked)."""
    models, seen = [], set()
    for k, item in enumerate(entries):
        path = ("validation", k)
        if item.name in seen:
            r.fail((*path, "name"), f"{item.name!r} names two validation models", "distinct names")
        seen.add(item.name)
        spec = _scenario(r, item.scenario, (*path, "scenario"), folder, {})
        known = {p.name for p in SCENARIOS[spec.scenario].PARAMETERS}
        missing = [n for n in space.names if n not in known]
        if missing:
            r.fail((*path, "scenario"), f"scenario {spec.scenario} has no parameter(s) {missing} to propagate")
        # the validation model is made of the calibrated material: the fixed values hold there too
        spec = ScenarioSpec(spec.scenario, spec.options, {**spec.parameters, **{k: v for k, v in fixed.items() if k in known}})
        _constraints(r, spec, space, {}, (*path, "scenario"), f"validation model {item.name!r}: ")
        if item.outputs is not None:  # before any FE run: the outputs are the scenario's
            try:
                output_columns(build_scenario(spec), item.outputs)
            except (ValueError, FEError) as e:
                r.fail((*path, "outputs"), str(e))
        design = TrainingDesign(n=item.n, seed=item.seed, method=item.method)
        # a linear FE run cannot fail: FE runs at region members only measure a nonlinear model's failures
        fe_runs = item.fe_runs
        if fe_runs is None:
            fe_runs = NONLINEAR_FE_RUNS if issubclass(SCENARIOS[spec.scenario], NonlinearScenario) else 0
        models.append(ValidationModel(item.name, spec, design, item.outputs, fe_runs, item.quantiles))
    return tuple(models)
