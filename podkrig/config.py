"""The machinery of settings objects: frozen, validated, each field with its default, unit and
allowed values in one place.

Every stage owns its settings next to the code that consumes them (``InversionSettings`` beside
the inversion, ``SurrogateSettings`` beside the surrogate, ...). Each is a frozen pydantic
dataclass made with :func:`settings` (:mod:`pydantic.dataclasses`, so :func:`dataclasses.asdict`
and :func:`dataclasses.replace` work on it as on a plain dataclass; an unknown key is an error).
A field states its type (strict: no coercion from strings or booleans), its range and, through
:func:`allowed`, the words a user who got it wrong is shown and its unit. Rules that tie two
fields together raise :func:`settings_error`.

The front doors read these declarations instead of restating them: the study file's checker
(:mod:`podkrig.study.schema`) validates TOML tables into them and words a failure with the file,
the line and the key; the CLI builds them from its options and takes its choices from
:func:`choices`; a stage's cache key is :func:`dataclasses.asdict` of the settings it consumed.

Examples
--------
>>> from typing import Annotated
>>> from pydantic import StrictInt
>>> @settings
... class Demo:
...     generations: Annotated[StrictInt, allowed("an integer >= 1", unit="-", ge=1)] = 100
...     method: choice(("a", "b")) = "a"
>>> Demo().generations
100
>>> choices(Demo, "method")
('a', 'b')
>>> field_info(Demo)["generations"]["allowed"]
'an integer >= 1'
"""

import dataclasses
import math
import typing
from typing import Annotated

from pydantic import AfterValidator, ConfigDict, Field, StrictInt, StrictStr, ValidationError
from pydantic.dataclasses import dataclass as pydantic_dataclass
from pydantic_core import PydanticCustomError

__all__ = ["Seed", "allowed", "choice", "choices", "field_info", "finite", "limit", "make_settings", "settings",
           "settings_error", "type_name"]

#: a frozen pydantic dataclass that refuses unknown keys
settings = pydantic_dataclass(frozen=True, config=ConfigDict(extra="forbid"))


def type_name(value):
    """The TOML name of a value's type, for messages ("integer", "table", …)."""
    return {bool: "boolean", int: "integer", float: "number", str: "string", dict: "table",
            list: "array"}.get(type(value), type(value).__name__)


def settings_error(message, key=None, allowed=None):
    """An error of a rule that ties fields together, for a front door to place and word.

    Parameters
    ----------
    message : str
        What is wrong (e.g. "give either energy or modes, not both").
    key : str, tuple or None
        Key path, relative to the settings being validated, that the message names (None: the
        settings object or the field being validated).
    allowed : str or None
        What is allowed, in words.
    """
    key = () if key is None else ((key,) if isinstance(key, str) else tuple(key))
    return PydanticCustomError("settings", "{message}", {"message": message, "key": key, "allowed": allowed})


def allowed(text, unit=None, **constraints):
    """Field constraints (pydantic's ``ge``, ``lt``, ...) with the words a user is shown when they
    are broken and the field's unit (None: a choice, a count or a flag)."""
    extra = {"allowed": text}
    if unit is not None:
        extra["unit"] = unit
    return Field(json_schema_extra=extra, **constraints)


class _OneOf:
    """The validator of a :func:`choice` (it carries the choices for :func:`choices`)."""

    def __init__(self, options):
        self.options = tuple(options)

    def __call__(self, value):
        if value not in self.options:
            raise ValueError("not one of the allowed values")
        return value


def choice(options, text=None):
    """A string field that takes one of ``options`` (the user is shown ``text``, by default the
    options joined by commas)."""
    one_of = _OneOf(options)
    return Annotated[StrictStr, AfterValidator(one_of), allowed(text or ", ".join(one_of.options))]


def finite(value):
    """A validator refusing NaN and ±inf."""
    if not math.isfinite(value):
        raise ValueError("not finite")
    return value


def limit(check, allowed_text):
    """A validator running one of the shared checks of :mod:`podkrig.limits` (the same bounds in the
    study file, the CLI and the Python API), its message — with the memory estimate — as the error."""
    def validate(value):
        try:
            check(value)
        except ValueError as e:
            raise settings_error(str(e), allowed=allowed_text) from None
        return value

    return AfterValidator(validate)


#: a seed: an integer >= 0
Seed = Annotated[StrictInt, allowed("an integer >= 0", ge=0)]


def _metadata(annotation):
    """The metadata objects of an ``Annotated`` type (also inside ``X | None``)."""
    found = []
    for arg in (annotation, *typing.get_args(annotation)):
        found += list(getattr(arg, "__metadata__", ()))
    return found


def field_info(cls):
    """Every field of settings class ``cls``: ``{name: {"default", "unit", "allowed", "choices"}}``
    (``default`` is :data:`dataclasses.MISSING` for a required field; ``choices`` None unless the
    field is a :func:`choice`)."""
    info = {}
    hints = typing.get_type_hints(cls, include_extras=True)
    for f in dataclasses.fields(cls):
        extra, options = {}, None
        for m in _metadata(hints[f.name]):
            extra.update(getattr(m, "json_schema_extra", None) or {})
            validator = getattr(m, "func", None)
            if isinstance(validator, _OneOf):
                options = validator.options
        default = f.default if f.default is not dataclasses.MISSING else (
            f.default_factory() if f.default_factory is not dataclasses.MISSING else dataclasses.MISSING)
        info[f.name] = {"default": default, "unit": extra.get("unit"), "allowed": extra.get("allowed"),
                        "choices": options}
    return info


def make_settings(cls, values, names=None):
    """Settings ``cls`` built from ``values`` (a dict; a value None keeps the field's default), a
    refused value named as the user gave it: ``NAME VALUE: what is wrong; allowed: ...``.

    The one wording of a refused value for the doors that take settings one by one (a library
    function's keywords, the command line's options): ``names`` maps a field to the name the
    caller knows it by (``{"n_candidates": "--candidates"}``); a field not in it is named as is.

    Raises
    ------
    ValueError
        With the name, the value and the allowed values (the field's :func:`allowed` text).
    """
    names = names or {}
    given = {k: v for k, v in values.items() if v is not None}
    try:
        return cls(**given)
    except ValidationError as e:
        error = e.errors(include_url=False)[0]
        ctx = error.get("ctx") or {}
        if error["type"] == "settings":
            key, what, allowed_text = (ctx["key"] or error["loc"] or ("",))[0], ctx["message"], ctx["allowed"]
        else:
            key = error["loc"][0]
            what = "out of range" if error["type"] not in _TYPE_ERRORS else f"must be {_TYPE_ERRORS[error['type']]}"
            allowed_text = field_info(cls)[key]["allowed"]
        value = given.get(key)
        raise ValueError(f"{names.get(key, key)}{'' if value is None else f' {value!r}'}: {what}"
                         + (f"; allowed: {allowed_text}" if allowed_text else "")) from None


#: pydantic's type errors, in words
_TYPE_ERRORS = {"int_type": "an integer", "float_type": "a number", "bool_type": "true or false",
                "string_type": "a string"}


def choices(cls, name):
    """The allowed values of the :func:`choice` field ``name`` of settings class ``cls`` (for a
    CLI's enum or a front end's menu)."""
    options = field_info(cls)[name]["choices"]
    if options is None:
        raise ValueError(f"{cls.__name__}.{name} is not a choice field")
    return options
