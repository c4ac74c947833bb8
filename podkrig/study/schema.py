"""The study file (TOML): what a whole calibration study needs, read and validated in one place.

A study names the virtual test, the free parameters with their bounds and scales, the fixed
ones, the sampling designs (training and held-out), the surrogate settings, the measurement and
its noise model, the inversion settings, the validation scenarios (for RVC) and whether to run
the model diagnosis. Every value is checked when the file is read: an unknown key, a wrong type
or an out-of-range value raises :class:`StudyError` naming the file, the line, the key and the
allowed values. Python's :mod:`tomllib` keeps no line numbers, so :func:`key_lines` finds them by
scanning the file text for the key (table headers, ``key = value`` lines, keys of inline tables).

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
    train    = { n = 128, seed = 0 }                      # method: sobol (default), lhs, random
    held_out = { n = 32, seed = 1, method = "random" }
    workers  = 1                            # FE processes (1: in this process); or scheduler = "tcp://HOST:PORT"

    [surrogate]
    beta = "fit-shared"                     # a number in (0, 2], "fit" or "fit-shared"

    [measurement]
    file = "measured.csv"                   # relative to the study file
    noise_rel = 0.01                        # or noise_abs = 0.002 (mm), or { D1 = 0.002, ... }

    [inversion]
    seed = 0

    [[validation]]                          # validation models for RVC (any number)
    name = "shear_wall"
    scenario = "shear_compression"
    n = 64
    seed = 2

    [diagnosis]
    enabled = false

Example
-------
>>> study = load_study("examples/diagonal_compression.toml")      # doctest: +SKIP
>>> study.space.names                                               # doctest: +SKIP
('E_b', 'kN_bj', 'kV_bj', 'r_hj')
"""

import dataclasses
import difflib
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from podkrig.exceptions import PodkrigError
from podkrig.parameters import SCALES, Parameter, ParameterSpace
from podkrig.offline.sampling import METHODS

VARIOGRAMS = ("exponential", "power")
CRITERIA = ("ml", "loo")
BETA_MODES = ("fit", "fit-shared")
REGION_METHODS = ("likelihood-ratio", "noise-mc")


class StudyError(PodkrigError, ValueError):
    """An invalid study file; the message names the file, the line, the key and what is allowed."""


# ---------------------------------------------------------------------------------------------
# settings objects


@dataclass(frozen=True)
class Design:
    """A seeded sampling design: ``n`` points by ``method`` with ``seed``."""

    n: int
    seed: int
    method: str = "sobol"


@dataclass(frozen=True)
class SurrogateSettings:
    """POD truncation (``energy`` or ``modes``) and kriging settings (see ``podkrig surrogate build``)."""

    energy: float | None = None
    modes: int | None = None
    variogram: str = "exponential"
    beta: float | str = "fit-shared"
    criterion: str = "ml"
    nugget: float = 0.0


@dataclass(frozen=True)
class MeasurementSettings:
    """The measurement CSV (absolute path) and its noise model.

    ``noise_rel`` is a relative level δ (σ_i = δ |d_i|); ``noise_abs`` an absolute σ in mm, one
    for all sensors (float) or one per sensor (dict). Exactly one of them is set.
    """

    file: Path
    noise_rel: float | None = None
    noise_abs: float | dict | None = None

    def noise_model(self):
        """The :class:`~podkrig.measurement.NoiseModel` of these settings."""
        from podkrig.online.measurement import NoiseModel

        if self.noise_rel is not None:
            return NoiseModel(delta=self.noise_rel)
        return NoiseModel(sigma=self.noise_abs)

    def noise_text(self):
        """The noise model in words, with units."""
        if self.noise_rel is not None:
            return f"relative, δ = {self.noise_rel:g} (σ = {100 * self.noise_rel:g} % of each reading)"
        if isinstance(self.noise_abs, dict):
            return "absolute σ per sensor: " + ", ".join(f"{k} {v:g} mm" for k, v in self.noise_abs.items())
        return f"absolute, σ = {self.noise_abs:g} mm"


@dataclass(frozen=True)
class InversionSettings:
    """GA inversion and region of equivalence settings (see :func:`podkrig.inverse.invert`)."""

    seed: int = 0
    population_size: int = 100
    generations: int = 100
    n_starts: int = 6
    confidence: float = 0.95
    region_method: str = "likelihood-ratio"
    region_samples: int = 2**17
    fe_check: bool = True


@dataclass(frozen=True)
class ValidationModel:
    """A validation scenario for RVC: its spec, design and reported outputs (``SENSOR@LOAD``)."""

    name: str
    spec: object  # fe.ScenarioSpec
    design: Design
    outputs: tuple | None = None


@dataclass(frozen=True)
class DiagnosisSettings:
    """Model diagnosis on or off, and its seed."""

    enabled: bool = False
    seed: int = 0


@dataclass(frozen=True)
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


# ---------------------------------------------------------------------------------------------
# line numbers of keys

_BARE = r"[A-Za-z0-9_-]+"
_QUOTED = r'"(?:[^"\\]|\\.)*"|\'[^\']*\''
_KEY = rf"(?:{_BARE}|{_QUOTED})(?:\s*\.\s*(?:{_BARE}|{_QUOTED}))*"
_KEY_LINE = re.compile(rf"^\s*({_KEY})\s*=(.*)$")
_HEADER = re.compile(rf"^\s*(\[\[?)\s*({_KEY})\s*\]\]?\s*(?:#.*)?$")
_TOKEN = re.compile(rf"{_QUOTED}|[{{}}\[\],=]|{_BARE}|\S")


def _split_key(text):
    parts = re.findall(rf"{_BARE}|{_QUOTED}", text)
    return tuple(p[1:-1] if p[0] in "\"'" else p for p in parts)


def _inline_keys(rest, base, lineno, lines):
    """Record the keys of inline tables in ``rest`` (the text after ``key =``) under ``base``."""
    stack = []  # per open bracket: ("table", its key path or None) or ("array", None)
    value_path = base  # key path of the value being read; None inside arrays (not recorded)
    parts = None  # parts of the key being read inside an inline table
    for tok in _TOKEN.findall(rest):
        if parts is not None:
            if tok == "=":
                table = stack[-1][1]
                value_path = None if table is None else table + tuple(parts)
                if value_path is not None:
                    lines.setdefault(value_path, lineno)
                parts = None
            elif tok == "}":  # an empty inline table
                stack.pop()
                parts = None
            elif tok != ".":
                parts.append(tok[1:-1] if tok[0] in "\"'" else tok)
        elif tok == "#":
            break
        elif tok == "{":
            stack.append(("table", value_path))
            parts = []
        elif tok == "[":
            stack.append(("array", None))
            value_path = None
        elif tok in ("]", "}") and stack:
            stack.pop()
            value_path = None
        elif tok == "," and stack and stack[-1][0] == "table":
            parts = []


def key_lines(text):
    """Line (1-based) of every key and table of a TOML text.

    Parameters
    ----------
    text : str

    Returns
    -------
    dict of tuple to int
        Key path → line. Paths are tuples of keys; the ``k``-th ``[[name]]`` table is
        ``("name", k)`` (k from 0). Keys of inline tables share their line. Keys inside
        multi-line arrays are not listed (their array's key is).
    """
    lines = {}
    table = ()
    arrays = {}
    in_string = None
    for lineno, line in enumerate(text.splitlines(), start=1):
        if in_string:
            if in_string in line:
                in_string = None
            continue
        m = _HEADER.match(line)
        if m:
            path = _split_key(m.group(2))
            if m.group(1) == "[[":
                k = arrays.get(path, 0)
                arrays[path] = k + 1
                lines.setdefault(path, lineno)
                path = (*path, k)
            table = path
            lines.setdefault(table, lineno)
            continue
        m = _KEY_LINE.match(line)
        if not m:
            continue
        path = table + _split_key(m.group(1))
        for k in range(len(table) + 1, len(path) + 1):  # a dotted key defines its prefixes too
            lines.setdefault(path[:k], lineno)
        rest = m.group(2)
        for quote in ('"""', "'''"):
            if rest.count(quote) % 2 == 1:
                in_string = quote
        if not in_string:
            _inline_keys(rest, path, lineno, lines)
    return lines


# ---------------------------------------------------------------------------------------------
# reading and checking


def _show(path):
    """A key path as the user writes it: ``sampling.train.n``, ``validation[2].n`` (1-based)."""
    out = ""
    for p in path:
        if isinstance(p, int):
            out += f"[{p + 1}]"
        else:
            out += ("." if out else "") + (p if re.fullmatch(_BARE, p) else f'"{p}"')
    return out


class _Reader:
    """Checks values of a parsed study and raises :class:`StudyError` with file and line."""

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
        key = _show(path)
        text = f"{where}: {key}: {message}" if key else f"{where}: {message}"
        if allowed:
            text += f"; allowed: {allowed}"
        raise StudyError(text)

    def table(self, value, path, allowed, required=()):
        """Check that ``value`` is a table with only ``allowed`` keys and every ``required`` one."""
        if not isinstance(value, dict):
            self.fail(path, f"must be a table; got {_type(value)} {value!r}")
        for key in value:
            if key not in allowed:
                close = difflib.get_close_matches(key, allowed, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                where = f"in [{_show(path)}]" if path else "at the top level"
                self.fail((*path, key), f"unknown key{hint}", f"keys {where}: {', '.join(sorted(allowed))}")
        for key in required:
            if key not in value:
                where = f"keys in [{_show(path)}]" if path else "required top-level keys"
                self.fail(path, f"missing key {key!r}", f"{where}: {', '.join(required if not path else sorted(allowed))}")
        return value

    def get(self, table, key, path, kind, default=None, check=None, allowed=None):
        """``table[key]`` checked for type ``kind`` ("int", "float", "bool", "str") and by
        ``check(value) -> bool``; ``default`` when missing (``...`` = required)."""
        full = (*path, key)
        if key not in table:
            if default is ...:
                self.fail(path, f"missing key {key!r}", allowed)
            return default
        v = table[key]
        ok = {
            "int": isinstance(v, int) and not isinstance(v, bool),
            "float": isinstance(v, (int, float)) and not isinstance(v, bool),
            "bool": isinstance(v, bool),
            "str": isinstance(v, str),
        }[kind]
        if not ok:
            expected = {"int": "an integer", "float": "a number", "bool": "true or false", "str": "a string"}[kind]
            self.fail(full, f"must be {expected}; got {_type(v)} {v!r}", allowed)
        if (kind == "float" and not _finite(v)) or (kind == "int" and abs(v) >= 2**63):
            shown = repr(v) if len(repr(v)) < 30 else f"a number of {len(repr(v))} digits"
            self.fail(full, f"{shown} is not a finite number of ordinary size", allowed)
        if check is not None and not check(float(v) if kind == "float" else v):
            self.fail(full, f"{v!r} is out of range", allowed)
        return float(v) if kind == "float" else v


def _finite(v):
    """Finite as a float (an integer too large for one is not)."""
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False


def _type(v):
    return {bool: "boolean", int: "integer", float: "number", str: "string", dict: "table",
            list: "array"}.get(type(v), type(v).__name__)


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
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise StudyError(f"cannot read study file {path}: {e.strerror}") from e
    except UnicodeDecodeError as e:
        raise StudyError(f"{path}: not UTF-8 text at byte {e.start}; save it as UTF-8") from None
    try:
        data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError) as e:
        raise StudyError(f"{path}: not valid TOML: {e if isinstance(e, tomllib.TOMLDecodeError) else 'nested too deeply'}") from None
    r = _Reader(path, text)
    top = ("name", "scenario", "parameters", "fixed", "sampling", "surrogate", "measurement", "inversion",
           "validation", "diagnosis")
    r.table(data, (), top, required=("scenario", "parameters", "sampling", "measurement"))
    name = r.get(data, "name", (), "str", path.stem, lambda v: bool(v.strip()), "a non-empty string")

    fixed = _fixed(r, data)
    spec = _scenario(r, data["scenario"], ("scenario",), path.parent, fixed)
    space = _parameters(r, data["parameters"], spec)
    both = sorted(set(space.names) & set(fixed))
    if both:
        r.fail(("fixed", both[0]), "is also a free parameter in [parameters]; choose one")

    sampling = r.table(data["sampling"], ("sampling",), ("train", "held_out", "workers", "scheduler"),
                       required=("train", "held_out"))
    train = _design(r, sampling["train"], ("sampling", "train"), min_n=4)
    held_out = _design(r, sampling["held_out"], ("sampling", "held_out"), min_n=1)
    scheduler = r.get(sampling, "scheduler", ("sampling",), "str", None, lambda v: "://" in v,
                      "a Dask scheduler address such as 'tcp://10.0.0.5:8786'")
    workers = r.get(sampling, "workers", ("sampling",), "int", None if scheduler else 1, lambda v: v >= 1,
                    "an integer >= 1 (FE processes; 1 runs them in this process)")
    if scheduler is not None and "workers" in sampling:
        r.fail(("sampling", "workers"), "give either workers (local processes) or scheduler (a Dask cluster), not both")

    return Study(
        path=path.resolve(), name=name, spec=spec, space=space, fixed=fixed, train=train, held_out=held_out,
        workers=workers, scheduler=scheduler,
        surrogate=_surrogate(r, data.get("surrogate", {})),
        measurement=_measurement(r, data["measurement"], path.parent),
        inversion=_inversion(r, data.get("inversion", {})),
        validation=_validation(r, data.get("validation", []), path.parent, fixed, space),
        diagnosis=_diagnosis(r, data.get("diagnosis", {})),
    )


def _fixed(r, data):
    fixed = data.get("fixed", {})
    if not isinstance(fixed, dict):
        r.fail(("fixed",), f"must be a table of parameter = value; got {_type(fixed)} {fixed!r}")
    return {k: r.get(fixed, k, ("fixed",), "float") for k in fixed}


def _scenario(r, value, path, folder, fixed):
    """The scenario spec of ``value`` (a name, a spec file or an inline table), normalised (every
    option explicit), with ``fixed`` among its parameters."""
    from fe.exceptions import FEError
    from fe.scenarios import SCENARIOS, ScenarioSpec

    names = ", ".join(sorted(SCENARIOS))
    allowed = f"a scenario name ({names}), a spec file (.toml or .json) or an inline table"
    source = None
    if isinstance(value, str):
        if value in SCENARIOS:
            value = {"scenario": value}
        else:
            source = folder / value
            if not source.is_file():
                r.fail(path, f"{value!r} is neither a scenario name nor a spec file (looked for {source})", allowed)
            try:
                value = ScenarioSpec.from_file(source).to_dict()
            except FEError as e:
                r.fail(path, str(e))
    if not isinstance(value, dict):
        r.fail(path, f"must be a scenario name, a file name or a table; got {_type(value)} {value!r}", allowed)
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
        where = ("fixed", k) if k in fixed else (*path, "parameters", k)
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


def _parameters(r, value, spec):
    from fe.scenarios import SCENARIOS

    path = ("parameters",)
    info = {p.name: p for p in SCENARIOS[spec.scenario].PARAMETERS}
    table = r.table(value, path, tuple(value) if isinstance(value, dict) else ())
    if not table:
        r.fail(path, "no free parameters", f"some of {', '.join(info)}, e.g. kN_bj = {{ lower = 10.0, upper = 1000.0, scale = \"log\" }}")
    params = []
    for name, b in table.items():
        where = (*path, name)
        if name not in info:
            r.fail(where, f"unknown parameter of {spec.scenario}", ", ".join(info))
        r.table(b, where, ("lower", "upper", "scale"), required=("lower", "upper"))
        p = info[name]
        rng = f"{p.admissible_range()} ({p.description})"
        lo = r.get(b, "lower", where, "float", ..., lambda v, p=p: _admissible(p, v), rng)
        hi = r.get(b, "upper", where, "float", ..., lambda v, p=p: _admissible(p, v), rng)
        scale = r.get(b, "scale", where, "str", "linear", lambda v: v in SCALES, " or ".join(SCALES))
        if not lo < hi:
            r.fail((*where, "upper"), f"must exceed lower = {lo:g} {p.unit}".rstrip(" -"), f"upper > {lo:g}")
        if scale == "log" and lo <= 0:
            r.fail((*where, "lower"), "must be > 0 on a log scale", "lower > 0, or scale = \"linear\"")
        params.append(Parameter(name, lo, hi, scale, p.unit))
    return ParameterSpace(tuple(params))


def _admissible(info, value):
    """Whether ``value`` lies in the physical range of the parameter ``info`` (fe.ParameterInfo)."""
    from fe.exceptions import SpecError

    try:
        info.check(value)
    except SpecError:
        return False
    return True


def _design(r, value, path, min_n):
    r.table(value, path, ("n", "seed", "method"), required=("n", "seed"))
    n = r.get(value, "n", path, "int", ..., lambda v: v >= min_n, f"an integer >= {min_n} (FE runs)")
    seed = r.get(value, "seed", path, "int", ..., lambda v: v >= 0, "an integer >= 0")
    method = r.get(value, "method", path, "str", "sobol", lambda v: v in METHODS, ", ".join(METHODS))
    return Design(n, seed, method)


def _surrogate(r, value):
    path = ("surrogate",)
    r.table(value, path, ("energy", "modes", "variogram", "beta", "criterion", "nugget"))
    energy = r.get(value, "energy", path, "float", None, lambda v: 0 < v <= 1, "a number in (0, 1], e.g. 0.99999999")
    modes = r.get(value, "modes", path, "int", None, lambda v: v >= 1, "an integer >= 1")
    if energy is not None and modes is not None:
        r.fail((*path, "modes"), "give either energy or modes, not both")
    variogram = r.get(value, "variogram", path, "str", "exponential", lambda v: v in VARIOGRAMS, ", ".join(VARIOGRAMS))
    beta_allowed = "a number in (0, 2] (below 2 for the power variogram), \"fit\" or \"fit-shared\""
    beta = value.get("beta", "fit-shared")
    if isinstance(beta, str):
        if beta not in BETA_MODES:
            r.fail((*path, "beta"), f"{beta!r} is not a known exponent setting", beta_allowed)
    else:
        beta = r.get(value, "beta", path, "float", None,
                     lambda v: 0 < v <= 2 and (variogram != "power" or v < 2), beta_allowed)
    criterion = r.get(value, "criterion", path, "str", "ml", lambda v: v in CRITERIA, ", ".join(CRITERIA))
    nugget = r.get(value, "nugget", path, "float", 0.0, lambda v: v >= 0, "a number >= 0 (relative to the sill)")
    return SurrogateSettings(energy, modes, variogram, beta, criterion, nugget)


def _measurement(r, value, folder):
    path = ("measurement",)
    r.table(value, path, ("file", "noise_rel", "noise_abs"), required=("file",))
    file = r.get(value, "file", path, "str", ...)
    full = (folder / file).resolve()
    if not full.is_file():
        r.fail((*path, "file"), f"no measurement file at {full}",
               "a CSV file (first column 'load', then one column per sensor, mm), relative to the study file")
    noise_allowed = "exactly one of noise_rel = δ in (0, 1) or noise_abs = σ > 0 mm (a number, or a table sensor = σ)"
    given = [k for k in ("noise_rel", "noise_abs") if k in value]
    if len(given) != 1:
        r.fail(path if not given else (*path, given[1]), "give exactly one noise model", noise_allowed)
    rel = r.get(value, "noise_rel", path, "float", None, lambda v: 0 < v < 1, noise_allowed)
    noise_abs = value.get("noise_abs")
    if isinstance(noise_abs, dict):
        where = (*path, "noise_abs")
        noise_abs = {k: r.get(noise_abs, k, where, "float", ..., lambda v: v > 0, "σ > 0 mm") for k in noise_abs}
        if not noise_abs:
            r.fail(where, "empty table", noise_allowed)
    elif noise_abs is not None:
        noise_abs = r.get(value, "noise_abs", path, "float", None, lambda v: v > 0, noise_allowed)
    return MeasurementSettings(full, rel, noise_abs)


def _inversion(r, value):
    path = ("inversion",)
    d = InversionSettings()
    r.table(value, path, [f.name for f in dataclasses.fields(InversionSettings)])
    return InversionSettings(
        seed=r.get(value, "seed", path, "int", d.seed, lambda v: v >= 0, "an integer >= 0"),
        population_size=r.get(value, "population_size", path, "int", d.population_size, lambda v: v >= 4,
                              "an integer >= 4"),
        generations=r.get(value, "generations", path, "int", d.generations, lambda v: v >= 1, "an integer >= 1"),
        n_starts=r.get(value, "n_starts", path, "int", d.n_starts, lambda v: v >= 1,
                       "an integer >= 1 (least-squares polishes)"),
        confidence=r.get(value, "confidence", path, "float", d.confidence, lambda v: 0 < v < 1,
                         "a number in (0, 1), e.g. 0.95"),
        region_method=r.get(value, "region_method", path, "str", d.region_method, lambda v: v in REGION_METHODS,
                            ", ".join(REGION_METHODS)),
        region_samples=r.get(value, "region_samples", path, "int", d.region_samples, lambda v: v >= 1024,
                             "an integer >= 1024 (surrogate evaluations per sampling round)"),
        fe_check=r.get(value, "fe_check", path, "bool", d.fe_check),
    )


def _validation(r, value, folder, fixed, space):
    from fe.scenarios import SCENARIOS, ScenarioSpec

    if not isinstance(value, list):
        r.fail(("validation",), f"must be an array of tables ([[validation]]); got {_type(value)}")
    models, seen = [], set()
    for k, item in enumerate(value):
        path = ("validation", k)
        r.table(item, path, ("name", "scenario", "n", "seed", "method", "outputs"), required=("name", "scenario", "n", "seed"))
        name = r.get(item, "name", path, "str", ...,
                     lambda v: re.fullmatch(r"[A-Za-z0-9_-]+", v) is not None and v != "calibration",
                     "letters, digits, '_' and '-' (it names files), other than 'calibration'")
        if name in seen:
            r.fail((*path, "name"), f"{name!r} names two validation models", "distinct names")
        seen.add(name)
        spec = _scenario(r, item["scenario"], (*path, "scenario"), folder, {})
        known = {p.name for p in SCENARIOS[spec.scenario].PARAMETERS}
        missing = [n for n in space.names if n not in known]
        if missing:
            r.fail((*path, "scenario"), f"scenario {spec.scenario} has no parameter(s) {missing} to propagate")
        # the validation model is made of the calibrated material: the fixed values hold there too
        spec = ScenarioSpec(spec.scenario, spec.options, {**spec.parameters, **{k: v for k, v in fixed.items() if k in known}})
        design = _design(r, {key: item[key] for key in ("n", "seed", "method") if key in item}, path, min_n=4)
        outputs = item.get("outputs")
        if outputs is not None:
            if not isinstance(outputs, list) or not outputs or not all(isinstance(o, str) and "@" in o for o in outputs):
                r.fail((*path, "outputs"), f"must be a non-empty array of 'SENSOR@LOAD' strings; got {outputs!r}",
                       "e.g. [\"top_ux@40\", \"D1@40\"]")
            outputs = tuple(outputs)
        models.append(ValidationModel(name, spec, design, outputs))
    return tuple(models)


def _diagnosis(r, value):
    path = ("diagnosis",)
    r.table(value, path, ("enabled", "seed"))
    return DiagnosisSettings(
        enabled=r.get(value, "enabled", path, "bool", False),
        seed=r.get(value, "seed", path, "int", 0, lambda v: v >= 0, "an integer >= 0"),
    )
