"""Scenario specs: plain data (dict / TOML / JSON) that rebuild a scenario anywhere.

A spec names the scenario, its options (geometry, mesh, load levels, sensors) and the values of
the parameters it holds fixed (overriding the defaults)::

    scenario = "diagonal_compression"
    nx = 4
    ny = 2

    [parameters]
    E_b = 12000.0

``ScenarioSpec.from_dict(spec.to_dict()) == spec`` (round trip).
"""

import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ..exceptions import SpecError
from ..files import read_bounded

#: Largest scenario spec file read, bytes: a spec is a few KiB written by hand (the same cap as a
#: podkrig study file).
MAX_SPEC_BYTES = 2**20


def _freeze(value):
    if isinstance(value, dict):
        return tuple(sorted((k, _freeze(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v) for v in value)
    return value


@dataclass(frozen=True)
class ScenarioSpec:
    """A scenario's name, its options and its fixed parameter values.

    Attributes
    ----------
    scenario : str
        Registered scenario name (see :data:`fe.scenarios.SCENARIOS`).
    options : dict
        Scenario options (validated by the scenario; unknown keys are refused).
    parameters : dict of str to float
        Values of parameters that override the scenario defaults.
    """

    scenario: str
    options: dict = field(default_factory=dict)
    parameters: dict = field(default_factory=dict)

    def __eq__(self, other):
        return isinstance(other, ScenarioSpec) and self.to_dict() == other.to_dict()

    def __hash__(self):
        return hash(_freeze(self.to_dict()))

    def to_dict(self):
        """Plain dict: ``{"scenario": ..., **options, "parameters": {...}}``."""
        d = {"scenario": self.scenario}
        d.update({k: _plain(v) for k, v in self.options.items()})
        d["parameters"] = {k: float(v) for k, v in self.parameters.items()}
        return d

    @classmethod
    def from_dict(cls, d, source="spec"):
        """Build from a plain dict (as written by :meth:`to_dict` or read from TOML/JSON)."""
        if not isinstance(d, dict):
            raise SpecError(f"{source}: a scenario spec must be a table/dict; got {type(d).__name__}")
        d = dict(d)
        name = d.pop("scenario", None)
        if not isinstance(name, str):
            raise SpecError(f"{source}: missing key 'scenario' (the scenario name, a string)")
        parameters = d.pop("parameters", {}) or {}
        if not isinstance(parameters, dict):
            raise SpecError(f"{source}: 'parameters' must be a table of name = value")
        for k, v in parameters.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise SpecError(f"{source}: parameter {k!r} must be a number; got {v!r}")
        return cls(name, d, {k: float(v) for k, v in parameters.items()})

    @classmethod
    def from_file(cls, path):
        """Read a spec from a ``.toml`` or ``.json`` file."""
        path = Path(path)
        try:
            text = read_bounded(path, MAX_SPEC_BYTES, "scenario spec", error=SpecError).decode("utf-8")
        except OSError as e:
            raise SpecError(f"cannot read scenario spec {path}: {e.strerror}") from e
        except UnicodeDecodeError as e:
            raise SpecError(f"{path}: not UTF-8 text at byte {e.start}; save it as UTF-8") from None
        try:
            d = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
        except (ValueError, tomllib.TOMLDecodeError, RecursionError) as e:
            reason = "nested too deeply" if isinstance(e, RecursionError) else e
            raise SpecError(f"{path}: not valid {'JSON' if path.suffix == '.json' else 'TOML'}: {reason}") from None
        return cls.from_dict(d, source=str(path))

    def to_json(self):
        return json.dumps(self.to_dict(), sort_keys=True)


def _plain(v):
    if isinstance(v, tuple):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    return v
