"""The :class:`Scenario` base class: a virtual test mapping model parameters to a :class:`Response`."""

import abc
import dataclasses
import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from ..admissibility import check_box
from ..exceptions import SpecError
from ..response import Response
from .spec import ScenarioSpec

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class ParameterInfo:
    """A model parameter: default, unit and physical limits.

    ``lower``/``upper`` bound the physically admissible values; ``lower_open``/``upper_open``
    exclude the bound itself (e.g. a stiffness must be > 0).
    """

    name: str
    default: float
    unit: str
    lower: float
    upper: float
    description: str
    lower_open: bool = False
    upper_open: bool = False

    def admissible_range(self):
        lo = "(" if self.lower_open else "["
        hi = ")" if self.upper_open else "]"
        return f"{lo}{self.lower:g}, {self.upper:g}{hi}{' ' + self.unit if self.unit != '-' else ''}"

    def check(self, value, source="parameters"):
        """Return ``value`` as float, or raise :class:`SpecError` naming the parameter and range."""
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
            raise SpecError(f"{source}: parameter {self.name!r} must be a number; got {value!r}")
        v = float(value)
        bad = (
            not math.isfinite(v)
            or v < self.lower
            or v > self.upper
            or (self.lower_open and v == self.lower)
            or (self.upper_open and v == self.upper)
        )
        if bad:
            raise SpecError(
                f"{source}: parameter {self.name!r} = {v:g} is outside its physical range "
                f"{self.admissible_range()} ({self.description})"
            )
        return v


class Scenario(abc.ABC):
    """A complete virtual test: geometry, mesh, supports, loading, sensors.

    Subclasses define ``name``, ``Options`` (a frozen dataclass of options with defaults),
    ``PARAMETERS`` (tuple of :class:`ParameterInfo`), ``load_unit`` and ``_build()`` which sets
    ``self.mesh``, ``self.sensors``, ``self.model`` (a :class:`fe.model.LinearModel`) and
    ``self.load_coefficients`` ``(n_loads, n_patterns)``, ``self.supported_nodes`` (nodes held
    fixed in x and y; a scenario with shoe supports also sets ``support_model``, a
    :class:`fe.supports.SupportModel`, whose springs hold no node) and ``self.tie_groups`` (dof groups moving together), plus ``theta(values)``.
    A scenario whose load can be off its intended position says how in
    ``load_perturbations()`` (:class:`fe.loads.LoadPerturbation`).

    ``Scenario(spec).run(params)`` is pure: it writes no files.
    """

    name = None
    #: One line in plain text saying what the test is (``podkrig scenarios`` lists it).
    summary = None
    Options = None
    PARAMETERS = ()
    load_unit = "kN"
    #: How readings depend on the load level: "affine" (a linear model: r(P) = a + b P exactly,
    #: so any load can be evaluated from two levels), "path" (nonlinear: interpolate along the
    #: control variable inside the modelled range) or "discrete" (levels are steps, e.g. flat jack).
    load_response = "affine"

    def __init__(self, spec=None, solver="auto"):
        if spec is None:
            spec = ScenarioSpec(self.name)
        if isinstance(spec, dict):
            spec = ScenarioSpec.from_dict(spec)
        if spec.scenario != self.name:
            raise SpecError(f"spec is for scenario {spec.scenario!r}, not {self.name!r}")
        self.options = self._parse_options(spec.options)
        known = {p.name: p for p in self.PARAMETERS}
        defaults = {}
        for k, v in spec.parameters.items():
            if k not in known:
                raise SpecError(
                    f"{self.name}: unknown parameter {k!r} in the spec; known: {sorted(known)}"
                )
            defaults[k] = known[k].check(v, source=f"{self.name} spec")
        self.parameters = {
            p.name: dataclasses.replace(p, default=defaults.get(p.name, p.default)) for p in self.PARAMETERS
        }
        self.spec = ScenarioSpec(self.name, dataclasses.asdict(self.options), dict(defaults))
        self._solver_name = solver
        self._build()

    @classmethod
    def _parse_options(cls, options):
        fields = {f.name: f for f in dataclasses.fields(cls.Options)}
        unknown = sorted(set(options) - set(fields))
        if unknown:
            raise SpecError(
                f"{cls.name}: unknown option(s) {unknown}; allowed options: {sorted(fields)}"
            )
        values = {}
        for k, v in options.items():
            default = getattr(cls.Options(), k)
            if isinstance(default, tuple) and isinstance(v, list):
                v = tuple(v)
            if isinstance(default, float) and isinstance(v, int) and not isinstance(v, bool):
                v = float(v)
            if default is not None and not isinstance(v, type(default)):
                raise SpecError(
                    f"{cls.name}: option {k!r} must be of type {type(default).__name__}; got {v!r}"
                )
            values[k] = v
        try:
            return cls.Options(**values)
        except (ValueError, TypeError) as e:
            raise SpecError(f"{cls.name}: {e}") from e

    @property
    def parameter_names(self):
        return tuple(self.parameters)

    @property
    def load_levels(self):
        """Load levels, ``(n_loads,)`` in ``load_unit``."""
        return np.asarray(self.options.load_levels, dtype=float)

    @property
    def sensor_names(self):
        return self.model.channel_names

    @property
    def n_dofs(self):
        return self.model.n_dofs

    @property
    def sensor_units(self):
        """Sensor name → unit of its readings (mm: every sensor of a linear scenario is a displacement)."""
        return dict.fromkeys(self.sensor_names, "mm")

    def sensor_definitions(self):
        """Sensor name → definition dict (mm)."""
        return {s.name: s.to_dict() for s in self.sensors}

    @classmethod
    def parameter_constraints(cls, options):
        """Constraints between parameters for the options ``options`` (an ``Options`` instance):
        a tuple of :class:`fe.admissibility.ParameterConstraint`; none for a linear scenario, whose
        parameters are independent (each has its physical range)."""
        return ()

    @classmethod
    def check_spec_box(cls, spec, bounds=None):
        """:meth:`check_box` from a spec (:class:`ScenarioSpec` of this scenario: its options and
        fixed parameter values), without building the scenario (no mesh).

        Raises
        ------
        SpecError
            Invalid options.
        ConstraintError
            As :meth:`check_box`.
        """
        parameters = {p.name: dataclasses.replace(p, default=spec.parameters.get(p.name, p.default))
                      for p in cls.PARAMETERS}
        check_box(cls.parameter_constraints(cls._parse_options(spec.options)), parameters, bounds, where=cls.name)

    @property
    def constraints(self):
        """This scenario's constraints between parameters (:meth:`parameter_constraints`)."""
        return self.parameter_constraints(self.options)

    def check_box(self, bounds=None):
        """Check the constraints over a sampling box before any FE run.

        Parameters
        ----------
        bounds : mapping of str to tuple, optional
            ``name → (lower, upper)`` or ``(lower, upper, scale)`` of the sampled parameters (each
            in its unit); the others at this scenario's values (defaults and the spec's fixed values).

        Raises
        ------
        ConstraintError
            A constraint fails somewhere in the box: the message names it, its worst corner (exact:
            see :mod:`fe.admissibility`) and the bound or value that would make the box admissible.
        """
        check_box(self.constraints, self.parameters, bounds, where=self.name)

    def resolve(self, params=None):
        """Every parameter's value: defaults updated by ``params``; validated, alone (physical
        range) and together (:attr:`constraints`).

        Raises
        ------
        SpecError
            Unknown parameter name or value outside its physical range.
        ConstraintError
            Values that violate a constraint (the message says which value would satisfy it).
        """
        values = {k: p.default for k, p in self.parameters.items()}
        for k, v in (params or {}).items():
            if k not in self.parameters:
                raise SpecError(
                    f"{self.name}: unknown parameter {k!r}; parameters are {list(self.parameters)}"
                )
            values[k] = self.parameters[k].check(v)
        point = {k: dataclasses.replace(p, default=values[k]) for k, p in self.parameters.items()}
        check_box(self.constraints, point, where=self.name)
        return values

    @abc.abstractmethod
    def _build(self):
        """Set ``mesh``, ``sensors``, ``model`` and ``load_coefficients`` from ``self.options``."""

    @abc.abstractmethod
    def theta(self, values):
        """Coefficients of the stiffness parts for a full parameter dict, ``(n_parts,)``."""

    def load_coefficients_at(self, values):
        """Multipliers of the model's load patterns (``model.rhs`` columns) at every load level for
        the full parameter dict ``values``, ``(n_loads, n_patterns)``: readings are
        ``load_coefficients_at(values) @ model.readings(model.solve(theta(values)))``. The loads of
        the wall tests do not depend on the parameters: ``load_coefficients`` itself."""
        return self.load_coefficients

    def joint_part_elements(self, kind):
        """The interface elements (indices into ``mesh.interfaces``) of the stiffness parts
        ``f"{kind}_normal"`` and ``f"{kind}_shear"``, in part order: every interface of that kind
        (``"bed"``, ``"head"``, ``"brick"``) for the wall tests."""
        return np.flatnonzero(self.mesh.interfaces_of_kind(kind))

    def derived(self):
        """Values derived from the options that differ from what they asked for (e.g. a rigid
        support's length snapped to element edges), ``dict``; none by default."""
        return {}

    def load_perturbations(self):
        """Ways the applied load can depart from its intended position: a dict of name to
        :class:`fe.loads.LoadPerturbation`; empty by default."""
        return {}

    def run(self, params=None, *, field=False):
        """Run the virtual test.

        Parameters
        ----------
        params : dict of str to float, optional
            Parameter values; the others keep their defaults.
        field : bool
            Also return the nodal displacement field.

        Returns
        -------
        Response
        """
        t0 = time.perf_counter()
        values = self.resolve(params)
        q = self.model.solve(self.theta(values))
        readings = self.load_coefficients @ self.model.readings(q)
        u = None
        if field:
            u = np.einsum("lp,pnc->lnc", self.load_coefficients, self.model.displacements(q))
        logger.debug("%s run in %.4f s", self.name, time.perf_counter() - t0)
        return Response(readings, self.sensor_names, self.load_levels, self.load_unit, u)
