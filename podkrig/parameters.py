"""Parameter spaces: the free model parameters, their bounds and scales, and the map to the unit cube.

Algorithms (Sobol' sampling, kriging, the genetic algorithm) work in the unit hypercube
:math:`[0, 1]^d`; a :class:`ParameterSpace` maps between it and physical values. A parameter on a
``"log"`` scale is mapped linearly in :math:`\\log_{10}`, so that each decade of a stiffness that
spans 10–1000 N/mm³ gets the same share of the samples.

Conventions: ``X`` (physical) and ``U`` (unit cube) have shape ``(n_samples, n_params)``, one row
per sample, columns in the order of :attr:`ParameterSpace.names`; units are those of the scenario
(N, mm, MPa; interface stiffness N/mm³).

Example
-------
>>> from podkrig.parameters import Parameter, ParameterSpace
>>> space = ParameterSpace((Parameter("E_b", 5000.0, 20000.0, unit="MPa"),
...                         Parameter("kN_bj", 10.0, 1000.0, scale="log", unit="N/mm³")))
>>> space.from_unit([[0.5, 0.5]]).tolist()
[[12500.0, 100.0]]
>>> space.to_unit([[12500.0, 100.0]]).tolist()
[[0.5, 0.5]]
"""

import json
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from fe.exceptions import SpecError

logger = logging.getLogger(__name__)

SCALES = ("linear", "log")


@dataclass(frozen=True)
class Parameter:
    """A free model parameter with bounds and a sampling scale.

    Parameters
    ----------
    name : str
        Parameter name as the scenario knows it, e.g. ``"kN_bj"``.
    lower, upper : float
        Bounds in the parameter's unit, ``lower < upper``; both > 0 on a log scale.
    scale : {"linear", "log"}
        ``"log"`` maps :math:`\\log_{10} x` linearly to the unit interval.
    unit : str
        Physical unit, e.g. ``"MPa"``; ``"-"`` for dimensionless parameters.

    Raises
    ------
    ValueError
        Empty name, non-finite or unordered bounds, unknown scale, non-positive log bounds.
    """

    name: str
    lower: float
    upper: float
    scale: str = "linear"
    unit: str = "-"

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"parameter name must be a non-empty string; got {self.name!r}")
        for which in ("lower", "upper"):
            value = getattr(self, which)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise TypeError(f"{which} bound of {self.name!r} must be a number; got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"{which} bound of {self.name!r} must be finite; got {value!r}")
            object.__setattr__(self, which, float(value))
        if self.scale not in SCALES:
            raise ValueError(f"scale of {self.name!r} must be one of {SCALES}; got {self.scale!r}")
        if not self.lower < self.upper:
            raise ValueError(
                f"bounds of {self.name!r} must satisfy lower < upper; "
                f"got ({self.lower:g}, {self.upper:g}) {self.unit}"
            )
        if self.scale == "log" and self.lower <= 0:
            raise ValueError(
                f"log-scale bounds of {self.name!r} must be > 0; got ({self.lower:g}, {self.upper:g}) "
                f"{self.unit}; use scale 'linear' or a positive lower bound"
            )

    def to_dict(self):
        """Plain JSON-able dict ``{"name", "lower", "upper", "scale", "unit"}``."""
        return {"name": self.name, "lower": self.lower, "upper": self.upper, "scale": self.scale, "unit": self.unit}


@dataclass(frozen=True)
class ParameterSpace:
    """An ordered set of free parameters; maps samples between physical values and the unit cube.

    Parameters
    ----------
    parameters : sequence of Parameter
        At least one; names must be distinct. Stored as a tuple.

    Notes
    -----
    For a parameter with bounds :math:`[a, b]`, the unit coordinate of a value :math:`x` is

    .. math::

        u = \\frac{x - a}{b - a} \\quad \\text{(linear)}, \\qquad
        u = \\frac{\\log_{10} x - \\log_{10} a}{\\log_{10} b - \\log_{10} a} \\quad \\text{(log)}.

    Values outside the bounds map outside :math:`[0, 1]` (no clipping).
    """

    parameters: tuple

    def __post_init__(self):
        params = tuple(self.parameters)
        if not params:
            raise ValueError("a parameter space needs at least one parameter; got none")
        for p in params:
            if not isinstance(p, Parameter):
                raise TypeError(f"parameters must be Parameter objects; got {type(p).__name__}")
        names = [p.name for p in params]
        duplicated = sorted({n for n in names if names.count(n) > 1})
        if duplicated:
            raise ValueError(f"parameter names must be distinct; {duplicated} given more than once")
        object.__setattr__(self, "parameters", params)

    def __len__(self):
        return len(self.parameters)

    @property
    def n_params(self):
        """Number of free parameters ``d``."""
        return len(self.parameters)

    @property
    def names(self):
        """Parameter names, tuple of str of length ``n_params``."""
        return tuple(p.name for p in self.parameters)

    @property
    def units(self):
        """Parameter units, tuple of str of length ``n_params``."""
        return tuple(p.unit for p in self.parameters)

    @property
    def scales(self):
        """Parameter scales (``"linear"`` or ``"log"``), tuple of length ``n_params``."""
        return tuple(p.scale for p in self.parameters)

    @property
    def lower(self):
        """Lower bounds, ndarray of shape (n_params,), in each parameter's unit."""
        return np.array([p.lower for p in self.parameters])

    @property
    def upper(self):
        """Upper bounds, ndarray of shape (n_params,), in each parameter's unit."""
        return np.array([p.upper for p in self.parameters])

    def _log_mask(self):
        return np.array([p.scale == "log" for p in self.parameters])

    def _check_samples(self, A, what):
        A = np.asarray(A, dtype=float)
        if A.ndim not in (1, 2) or A.shape[-1] != self.n_params:
            raise ValueError(
                f"{what} must have shape (n_samples, {self.n_params}) for parameters {list(self.names)}; "
                f"got shape {A.shape}"
            )
        return A

    def to_unit(self, X):
        """Map physical values to the unit cube.

        Parameters
        ----------
        X : array_like of shape (n_samples, n_params) or (n_params,)
            Physical values, each column in its parameter's unit.

        Returns
        -------
        U : ndarray of the same shape
            Unit-cube coordinates (``[0, 1]`` inside the bounds).

        Raises
        ------
        ValueError
            Wrong shape, or a non-positive value of a log-scale parameter.
        """
        X = self._check_samples(X, "X")
        log = self._log_mask()
        lo, hi = self.lower, self.upper
        if log.any():
            bad = X[..., log] <= 0
            if np.any(bad):
                name = str(np.array(self.names)[log][np.nonzero(bad)[-1][0]])
                raise ValueError(f"log-scale parameter {name!r} needs values > 0; got {X[..., log][bad][0]:g}")
            X = X.copy()
            X[..., log] = np.log10(X[..., log])
            lo, hi = lo.copy(), hi.copy()
            lo[log], hi[log] = np.log10(lo[log]), np.log10(hi[log])
        return (X - lo) / (hi - lo)

    def from_unit(self, U):
        """Map unit-cube coordinates to physical values.

        Parameters
        ----------
        U : array_like of shape (n_samples, n_params) or (n_params,)
            Unit-cube coordinates.

        Returns
        -------
        X : ndarray of the same shape
            Physical values, each column in its parameter's unit; inside the bounds (exactly)
            where ``U`` is in [0, 1].
        """
        U = self._check_samples(U, "U")
        log = self._log_mask()
        lo, hi = self.lower, self.upper
        lo[log], hi[log] = np.log10(lo[log]), np.log10(hi[log])
        X = lo + U * (hi - lo)
        if log.any():
            X[..., log] = 10.0 ** X[..., log]
            # pin the ends exactly: 10**log10(b) can differ from b by an ulp
            X[..., log] = np.where(U[..., log] == 0.0, self.lower[log], X[..., log])
            X[..., log] = np.where(U[..., log] == 1.0, self.upper[log], X[..., log])
        # coordinates in [0, 1] land inside the bounds exactly (lo + U (hi - lo) and 10**x can
        # round an ulp past them), so the surrogate's exact box check accepts them
        inside = (U >= 0.0) & (U <= 1.0)
        X = np.where(inside, np.clip(X, self.lower, self.upper), X)
        return X

    def as_params(self, x):
        """One sample as a ``{name: value}`` dict for :meth:`fe.Scenario.run`.

        Parameters
        ----------
        x : array_like of shape (n_params,)
            Physical values.
        """
        x = np.asarray(x, dtype=float)
        if x.shape != (self.n_params,):
            raise ValueError(f"x must have shape ({self.n_params},); got {x.shape}")
        return dict(zip(self.names, x.tolist()))

    def to_dict(self):
        """Plain JSON-able dict ``{"parameters": [Parameter.to_dict(), ...]}``."""
        return {"parameters": [p.to_dict() for p in self.parameters]}

    def to_json(self):
        """:meth:`to_dict` as a JSON string."""
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, d):
        """Rebuild from :meth:`to_dict` output.

        Raises
        ------
        TypeError
            ``d`` is not a dict with a ``parameters`` list of dicts.
        ValueError
            Missing or unknown keys, or invalid parameters.
        """
        if not isinstance(d, Mapping) or not isinstance(d.get("parameters"), list):
            raise TypeError(f"a parameter space dict needs a 'parameters' list; got {d!r}")
        params = []
        for item in d["parameters"]:
            if not isinstance(item, Mapping):
                raise TypeError(f"each parameter must be a dict; got {item!r}")
            unknown = sorted(set(item) - {"name", "lower", "upper", "scale", "unit"})
            missing = sorted({"name", "lower", "upper"} - set(item))
            if unknown or missing:
                raise ValueError(f"parameter entry {item!r}: missing keys {missing}, unknown keys {unknown}")
            params.append(Parameter(**item))
        return cls(tuple(params))

    @classmethod
    def from_scenario(cls, scenario, bounds):
        """A space over some of a scenario's parameters, with units and limits from the scenario.

        Parameters
        ----------
        scenario : fe.Scenario
            The scenario whose parameters are freed (its ``parameters`` dict of
            :class:`fe.ParameterInfo` gives units and physical limits).
        bounds : mapping of str to tuple
            ``name -> (lower, upper)`` or ``(lower, upper, scale)``; order is kept.

        Returns
        -------
        ParameterSpace

        Raises
        ------
        ValueError
            Unknown parameter name, malformed or unordered bounds, non-positive log bounds,
            or a bound outside the parameter's physical range.
        fe.exceptions.ConstraintError
            A constraint between the scenario's parameters (``scenario.constraints``) fails somewhere
            in the box of these bounds and the scenario's fixed values; the message names the
            constraint, the box's worst corner and the bound that would make it admissible
            (:meth:`fe.Scenario.check_box`).
        """
        known = scenario.parameters
        if not bounds:
            raise ValueError(f"no free parameters given; choose some of {list(known)}")
        params = []
        for name, spec in bounds.items():
            if name not in known:
                raise ValueError(
                    f"unknown parameter {name!r} for scenario {scenario.name!r}; known: {list(known)}"
                )
            if not isinstance(spec, (tuple, list)) or len(spec) not in (2, 3):
                raise ValueError(f"bounds of {name!r} must be (lower, upper) or (lower, upper, scale); got {spec!r}")
            info = known[name]
            p = Parameter(name, spec[0], spec[1], spec[2] if len(spec) == 3 else "linear", info.unit)
            for which, value in (("lower", p.lower), ("upper", p.upper)):
                try:
                    info.check(value)
                except SpecError:
                    raise ValueError(
                        f"{which} bound of {name!r} = {value:g} {info.unit} is outside its physical range "
                        f"{info.admissible_range()} ({info.description}); choose bounds inside it"
                    ) from None
            params.append(p)
        space = cls(tuple(params))
        scenario.check_box({p.name: (p.lower, p.upper, p.scale) for p in space.parameters})
        return space


def parse_param(text):
    """Parse a command-line parameter range ``"NAME=LOW:HIGH[:SCALE]"``.

    Parameters
    ----------
    text : str
        E.g. ``"kN_bj=10:1000:log"`` or ``"E_b=5000:20000"`` (scale defaults to linear).

    Returns
    -------
    name : str
    bounds : tuple
        ``(lower, upper, scale)``, ready for :meth:`ParameterSpace.from_scenario`.

    Raises
    ------
    ValueError
        A malformed string; the message quotes it and shows the expected form.

    Examples
    --------
    >>> parse_param("kN_bj=10:1000:log")
    ('kN_bj', (10.0, 1000.0, 'log'))
    """
    form = "expected NAME=LOW:HIGH or NAME=LOW:HIGH:log, e.g. kN_bj=10:1000:log"
    name, sep, rest = str(text).partition("=")
    name = name.strip()
    if not sep or not name:
        raise ValueError(f"--param {text!r}: {form}")
    parts = rest.split(":")
    if len(parts) not in (2, 3):
        raise ValueError(f"--param {text!r}: {form}")
    values = []
    for which, part in zip(("LOW", "HIGH"), parts[:2]):
        try:
            v = float(part)
        except ValueError:
            raise ValueError(f"--param {text!r}: {which} {part!r} is not a number; {form}") from None
        if not math.isfinite(v):
            raise ValueError(f"--param {text!r}: {which} must be finite; got {part!r}")
        values.append(v)
    scale = parts[2].strip() if len(parts) == 3 else "linear"
    if scale not in SCALES:
        raise ValueError(f"--param {text!r}: scale {scale!r} must be one of {SCALES}")
    return name, (values[0], values[1], scale)


def parse_params(texts):
    """Parse several ``NAME=LOW:HIGH[:SCALE]`` strings into a ``{name: (lower, upper, scale)}`` dict.

    Raises
    ------
    ValueError
        A malformed string, no strings at all, or a parameter given twice.
    """
    bounds = {}
    for text in texts:
        name, b = parse_param(text)
        if name in bounds:
            raise ValueError(f"--param {text!r}: parameter {name!r} is given more than once")
        bounds[name] = b
    if not bounds:
        raise ValueError("no free parameters: give at least one --param NAME=LOW:HIGH[:log]")
    return bounds
