"""Admissible parameter combinations: the inequalities of the interface laws, read in a scenario's
parameter names and checked over a whole sampling box.

An interface law admits only some combinations of its properties: a tension cut-off below the
Coulomb apex (``ft ≤ c / max(tanphi0, tanphir)``), a normal stiffness above the softening slope
(``kn > ft² / GfI``), and so on. Each is an :class:`Inequality` over the law's property names,
and the law's property builder (:func:`fe.interfaces.composite_properties`,
:func:`fe.interfaces.hyperbolic_properties`) checks every one of them before a run. A scenario
maps its parameters to the properties of each interface family (bed joints ``kn = kN_bj``, head
joints ``kn = r_hj·kN_bj``, ...) and exposes the resulting :class:`ParameterConstraint` objects
(``Scenario.constraints``): the same inequality objects, read in the scenario's parameter names.
What ``podkrig scenarios NAME`` states, what :func:`check_box` checks before any FE run and what
each FE run checks are one definition and cannot drift apart.

Evaluation over a box
---------------------
A sampling box is the product of the sampled parameters' intervals ``[lower, upper]``, every other
parameter at its fixed value. Every inequality of the laws is monotone in each parameter (its two
sides are products, quotients, squares, maxima and minima of positive quantities), and a function
monotone in each coordinate reaches its extremes over a box at a vertex (move one coordinate at a
time to the end that does not improve it). :func:`check_box` therefore evaluates each constraint at
the 2^k vertices of the k sampled parameters it involves (k ≤ 5, at most 32 points), which is
exact. An inequality declared ``monotone=False`` is checked on a dense grid instead (about 4096
points including the vertices, log-spaced for parameters sampled on a log scale), which is exact
only at the grid points; no such inequality exists today.

Remedies. For a violated monotone constraint, each parameter it involves is moved alone, by
bisection between its worst value in the box and the end of its physical range where the
constraint holds, to the value that makes the whole box admissible; the value is rounded to two
significant digits on the safe side (more digits when two do not suffice).

Example
-------
>>> from fe.scenarios import build_scenario
>>> sc = build_scenario("triplet_shear")
>>> [c.formula for c in sc.constraints][:2]
['tanpsi_bj ≤ tanphi_bj', 'ft_bj ≤ c_bj / max(tanphi_bj, tanphir_bj)']
>>> sc.check_box({"c_bj": (0.2, 0.6)})            # ft_bj = 0.25, tanφ = 0.75: admissible
>>> sc.check_box({"c_bj": (0.1, 0.6)})            # doctest: +ELLIPSIS
Traceback (most recent call last):
...
fe.exceptions.ConstraintError: triplet_shear: ft_bj ≤ c_bj / max(tanphi_bj, tanphir_bj) is required ...
worst corner of the sampling box: ft_bj = 0.25 MPa, c_bj = 0.1 MPa, tanphi_bj = 0.75, tanphir_bj = 0.75, ...
to make the box admissible, raise c_bj's lower bound to 0.19 MPa or set ft_bj to at most 0.13 MPa
"""

import itertools
import math
import string
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from .exceptions import ConstraintError

#: relative tolerance of a non-strict inequality (rounding of c / tanφ and the like)
RTOL = 1e-12
#: points of the dense check of a non-monotone constraint (over its sampled parameters)
DENSE_POINTS = 4096


def _always(p):
    return True


@dataclass(frozen=True)
class Inequality:
    """``lhs(p) ≤ rhs(p)`` (``<`` when ``strict``) over the properties ``p`` of an interface law.

    Parameters
    ----------
    key : str
        Short identifier, e.g. ``"tension_apex"``.
    left, right : str
        The two sides as text, properties in braces: ``"{ft}"``, ``"{c} / max({tanphi0}, {tanphir})"``.
    unit : str
        Unit of both sides (``"-"``: dimensionless).
    reason : str
        Why it is required, in words.
    lhs, rhs : callable
        ``mapping of property name to float → float``.
    strict : bool
        ``lhs < rhs`` instead of ``lhs ≤ rhs`` (the latter with relative tolerance :data:`RTOL`).
    applies : callable
        ``p → bool``; where False the inequality does not constrain (e.g. a surface switched off by
        an infinite strength).
    monotone : bool
        Each side monotone in each property (see the module docstring); False asks for a dense check.
    """

    key: str
    left: str
    right: str
    unit: str
    reason: str
    lhs: Callable
    rhs: Callable
    strict: bool = False
    applies: Callable = _always
    monotone: bool = True

    @property
    def properties(self):
        """Property names in the order they appear in ``left`` then ``right``, tuple of str."""
        names = [f for text in (self.left, self.right) for _, f, _, _ in string.Formatter().parse(text) if f]
        return tuple(dict.fromkeys(names))

    @property
    def operator(self):
        """``"<"`` for a strict inequality, else ``"≤"``."""
        return "<" if self.strict else "≤"

    def formula(self, names=None):
        """The inequality as text, properties replaced by ``names`` (property → text) if given."""
        names = {n: (names or {}).get(n, n) for n in self.properties}
        return f"{self.left.format(**names)} {self.operator} {self.right.format(**names)}"

    def evaluate(self, p):
        """``(holds, lhs, rhs)`` at the properties ``p``; a NaN side does not hold."""
        with np.errstate(all="ignore"):
            if not self.applies(p):
                return True, math.nan, math.nan
            left, right = float(self.lhs(p)), float(self.rhs(p))
        if math.isnan(left) or math.isnan(right):
            return False, left, right
        holds = left < right if self.strict else left <= right + RTOL * abs(right)
        return holds, left, right

    def check(self, p, where):
        """Raise ValueError naming ``where``, the inequality, the values and the reason unless it holds."""
        holds, left, right = self.evaluate(p)
        if not holds:
            got = ", ".join(f"{n}={p[n]:g}" for n in self.properties)
            unit = "" if self.unit == "-" else f" {self.unit}"
            raise ValueError(f"{where}: {self.formula()} is required ({self.reason}); got {got}: "
                             f"{left:.4g}{unit} {'≥' if self.strict else '>'} {right:.4g}{unit}")


@dataclass(frozen=True)
class ParameterConstraint:
    """An :class:`Inequality` of an interface family, read in a scenario's parameter names.

    Parameters
    ----------
    inequality : Inequality
    where : str
        The interface families it constrains, e.g. ``"bed and head joints"``.
    names : mapping of str to tuple of str
        Property → the parameters whose product it is, e.g. ``{"kn": ("r_hj", "kN_bj")}``, for
        every property of the family (those of the inequality must be there; the others serve its
        ``applies``).
    """

    inequality: Inequality
    where: str
    names: Mapping = field(hash=False)

    def __post_init__(self):
        missing = [n for n in self.inequality.properties if n not in self.names]
        if missing:
            raise ValueError(f"{self.where}: properties {missing} of {self.inequality.key} have no parameters")

    @property
    def parameters(self):
        """The scenario parameters it involves, in order of appearance, tuple of str."""
        return tuple(dict.fromkeys(n for prop in self.inequality.properties for n in self.names[prop]))

    @property
    def formula(self):
        """E.g. ``"ft_bj ≤ c_bj / max(tanphi_bj, tanphir_bj)"``."""
        return self.inequality.formula({prop: "·".join(self.names[prop]) for prop in self.inequality.properties})

    def describe(self):
        """The constraint in words with its unit: formula, unit, families, reason."""
        unit = "" if self.inequality.unit == "-" else f", {self.inequality.unit}"
        return f"{self.formula}{unit} ({self.where}): {self.inequality.reason}"

    def properties(self, values):
        """The family's properties from the parameter values ``values`` (name → float)."""
        return {prop: math.prod(values[n] for n in names) for prop, names in self.names.items()}

    def evaluate(self, values):
        """``(holds, lhs, rhs)`` for the parameter values ``values``."""
        return self.inequality.evaluate(self.properties(values))

    def to_dict(self):
        return {"formula": self.formula, "unit": self.inequality.unit, "where": self.where,
                "reason": self.inequality.reason, "parameters": list(self.parameters)}


@dataclass(frozen=True)
class Remedy:
    """A change of one parameter that makes a violated constraint hold over the whole box.

    ``kind``: ``"upper"``/``"lower"`` (move that bound of a sampled parameter to ``value``),
    ``"below"``/``"above"`` (move both bounds of a sampled parameter to at most / at least
    ``value``), ``"at_most"``/``"at_least"`` (set a fixed parameter to at most / at least ``value``).
    """

    parameter: str
    kind: str
    value: float
    unit: str

    def describe(self):
        u = "" if self.unit == "-" else f" {self.unit}"
        p, v = self.parameter, f"{self.value:g}{u}"
        return {"upper": f"lower {p}'s upper bound to {v}", "lower": f"raise {p}'s lower bound to {v}",
                "below": f"move both bounds of {p} to {v} or below",
                "above": f"move both bounds of {p} to {v} or above",
                "at_most": f"set {p} to at most {v}", "at_least": f"set {p} to at least {v}"}[self.kind]


@dataclass(frozen=True)
class Violation:
    """A constraint that fails somewhere in a box: its worst point and the remedies found."""

    constraint: ParameterConstraint
    point: dict
    lhs: float
    rhs: float
    sampled: tuple
    remedies: tuple
    grid_points: int = 0

    def message(self, units):
        """The violation in words: the formula, its families and reason, where in the box it fails
        (parameter values with their ``units``, name → unit, ``"-"`` for none) and the two sides."""
        c = self.constraint

        def value(n):
            u = "" if units.get(n, "-") == "-" else f" {units[n]}"
            return f"{n} = {self.point[n]:g}{u}"

        unit = "" if c.inequality.unit == "-" else f" {c.inequality.unit}"
        at = ", ".join(value(n) for n in c.parameters)
        if self.grid_points:
            where = f"worst of {self.grid_points} grid points of the sampling box (not monotone): {at}"
        else:
            where = f"worst corner of the sampling box: {at}" if self.sampled else f"fails at {at}"
        sides = f"{self.lhs:.4g}{unit} {'≥' if c.inequality.strict else '>'} {self.rhs:.4g}{unit}"
        text = f"{c.formula} is required ({c.where}: {c.inequality.reason}); {where}, where {sides}"
        if self.remedies:
            text += f"; to make {'the box' if self.sampled else 'it'} admissible, " + \
                " or ".join(r.describe() for r in self.remedies)
        else:
            text += "; no single parameter change makes it admissible: narrow the bounds of " + \
                ", ".join(self.sampled or c.parameters)
        return text


def _points(constraint, values, bounds):
    """The points of the box at which ``constraint`` is evaluated: the vertices of its sampled
    parameters (monotone), or a grid (not monotone). Returns (sampled names, list of value dicts)."""
    sampled = tuple(n for n in constraint.parameters if n in bounds)
    if constraint.inequality.monotone:
        axes = [(bounds[n][0], bounds[n][1]) for n in sampled]
    else:
        m = max(2, int(round(DENSE_POINTS ** (1.0 / max(len(sampled), 1)))))
        axes = [tuple(np.geomspace(b[0], b[1], m) if len(b) > 2 and b[2] == "log" else np.linspace(b[0], b[1], m))
                for b in (bounds[n] for n in sampled)]
    return sampled, [{**values, **dict(zip(sampled, corner))} for corner in itertools.product(*axes)]


def _worst(constraint, values, bounds):
    """``(point, lhs, rhs)`` of the most violated point of the box, or None if it holds everywhere."""
    sampled, points = _points(constraint, values, bounds)
    worst, excess = None, -math.inf
    for v in points:
        holds, left, right = constraint.evaluate(v)
        if holds:
            continue
        e = math.inf if math.isnan(left) or math.isnan(right) else (left - right) / (abs(left) + abs(right) + 1e-300)
        if worst is None or e > excess:
            worst, excess = (v, left, right), e
    return worst


def _round_safe(x, up, ok):
    """``x`` rounded to 2 significant digits towards the admissible side (up or down), more digits
    when the rounded value is not ``ok``; ``x`` itself if none is."""
    if x == 0 or not math.isfinite(x):
        return x
    for digits in range(2, 16):
        scale = 10.0 ** (math.floor(math.log10(abs(x))) - digits + 1)
        r = (math.ceil(x / scale) if up else math.floor(x / scale)) * scale
        r = float(f"{r:.{digits + 2}g}")  # drop the binary noise of the multiplication
        if ok(r):
            return r
    return x


def _bisect(ok, bad, good):
    """The value nearest ``bad`` (not ok) on the way to ``good`` (ok) where ``ok`` becomes true."""
    for _ in range(200):
        if bad > 0 and good > 0 and max(bad, good) > 4 * min(bad, good):
            mid = math.sqrt(bad * good)  # geometric across decades
        else:
            mid = 0.5 * (bad + good)
        if mid in (bad, good):
            break
        if ok(mid):
            good = mid
        else:
            bad = mid
    return good


def _remedies(constraint, values, bounds, info, worst):
    """One :class:`Remedy` per parameter that alone can make the box admissible."""
    out = []
    for n in constraint.parameters:
        p = info[n]
        w = worst[n]
        lo_end = p.lower + (1e-9 * max(abs(w - p.lower), 1e-300) if p.lower_open else 0.0)
        hi_end = p.upper - (1e-9 * max(abs(p.upper - w), 1e-300) if p.upper_open else 0.0)

        def ok(x, n=n):
            fixed_bounds = {k: b for k, b in bounds.items() if k != n}
            return _worst(constraint, {**values, n: x}, fixed_bounds) is None

        for end in sorted((lo_end, hi_end), key=lambda e: abs(e - w)):
            if end == w or not ok(end):
                continue
            x = _bisect(ok, w, end)
            if x == end:  # admissible only at the end itself (e.g. a zero stiffness drops the inequality)
                continue
            x = _round_safe(x, up=end > w, ok=lambda r: lo_end <= r <= hi_end and ok(r))
            if n not in bounds:
                kind = "at_least" if end > w else "at_most"
            else:
                lo, hi = bounds[n][:2]
                if end > w:
                    kind = "lower" if x <= hi else "above"
                else:
                    kind = "upper" if x >= lo else "below"
            out.append(Remedy(n, kind, x, p.unit))
            break
    # sampled parameters first: a bound is what the user came to change
    return tuple(sorted(out, key=lambda r: r.parameter not in bounds))


def _normalise(bounds):
    out = {}
    for name, b in bounds.items():
        lo, hi, *scale = b
        out[name] = (float(lo), float(hi), *(scale or ["linear"]))
    return out


def box_violations(constraints, parameters, bounds=None):
    """The constraints that fail somewhere in a box.

    Parameters
    ----------
    constraints : sequence of ParameterConstraint
    parameters : mapping of str to fe.ParameterInfo
        Every parameter of the scenario; ``default`` is the value of a parameter not in ``bounds``
        (the fixed value), ``unit``, ``lower``/``upper`` its physical range.
    bounds : mapping of str to tuple, optional
        ``name → (lower, upper)`` or ``(lower, upper, scale)`` of the sampled parameters, each in
        its unit; none (or empty): check the single point of the fixed values.

    Returns
    -------
    tuple of Violation
    """
    bounds = _normalise(bounds or {})
    values = {n: p.default for n, p in parameters.items()}
    out = []
    for c in constraints:
        found = _worst(c, values, bounds)
        if found is None:
            continue
        point, left, right = found
        sampled = tuple(n for n in c.parameters if n in bounds)
        dense = not c.inequality.monotone
        remedies = () if dense else _remedies(c, values, bounds, parameters, point)
        n_points = len(_points(c, values, bounds)[1]) if dense and sampled else 0
        out.append(Violation(c, {n: point[n] for n in c.parameters}, left, right, sampled, remedies, n_points))
    return tuple(out)


def check_box(constraints, parameters, bounds=None, where="parameters"):
    """Raise :class:`~fe.exceptions.ConstraintError` unless every constraint holds over the box.

    Parameters are those of :func:`box_violations`; ``where`` opens the message (the scenario).

    Raises
    ------
    ConstraintError
        Naming each violated constraint, its worst point in the box (the vertex, exact for monotone
        constraints) and the bound or value that would make the box admissible; ``violations``
        holds the :class:`Violation` objects (with their :class:`Remedy` objects).
    """
    violations = box_violations(constraints, parameters, bounds)
    if violations:
        units = {n: p.unit for n, p in parameters.items()}
        text = "; also: ".join(v.message(units) for v in violations)
        raise ConstraintError(f"{where}: {text}", violations)
