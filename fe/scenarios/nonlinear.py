"""Nonlinear mesoscale scenarios: masonry tests up to failure with cracking, sliding and crushing joints.

Units stay elastic (expanded continua); bed joints, head joints and unit mid-planes are nonlinear
interfaces (:class:`fe.interfaces.CompositeInterface`): bed and head joints with the full
Lourenço–Rots law (head joints with ``r_hj`` times the bed-joint stiffness and the same
strengths), unit mid-planes with a tension cut-off only (``ft_bb``, ``GfI_bb``; no friction or cap:
potential-crack interfaces, INFERRED, see ``docs/references.md`` "INFERRED choices"). The run
follows the load path with :class:`fe.solvers.nonlinear.PathFollower`; the response holds the readings at the
prescribed levels of the control displacement (``load_levels``, mm), the load there, and the peak.

The load is a reading like the gauges: the sensor :attr:`NonlinearScenario.force_sensor` (``F``, kN)
is the reaction of the controlled degree of freedom — the force the actuator's load cell measures,
positive in the direction of the control (a push, a pull, a compression) — appended after the gauges,
so that a surrogate, a measurement file and an inversion treat a force–displacement curve as data.
"""

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..admissibility import ParameterConstraint
from ..elements.interface import RULES
from ..exceptions import SpecError
from ..interfaces import (
    CompositeInterface,
    HyperbolicInterface,
    MixedInterface,
    composite_properties,
    hyperbolic_properties,
)
from ..interfaces.composite import INEQUALITIES as COMPOSITE_INEQUALITIES
from ..interfaces.hyperbolic import CAP_SHAPES
from ..interfaces.hyperbolic import INEQUALITIES as HYPERBOLIC_INEQUALITIES
from ..materials import plane_stress_coefficients
from ..mesh.mesh import INTERFACE_KINDS
from ..nonlinear_model import NonlinearModel
from ..response import NonlinearResponse
from ..solvers.nonlinear import PathFollower, PathSettings, Phase
from .base import ParameterInfo, Scenario
from .masonry import MASONRY_PARAMETERS, WallOptions, masonry_parts

_BIG = 1e9

#: Strength parameters of the nonlinear model (DESIGN.md); defaults: the TU Eindhoven "Set A" of
#: Lourenço (1994) as quoted by a third-party J4D script (k, f_t, G_f^I, c, tanφ, G_f^II; the rest INFERRED).
STRENGTH_PARAMETERS = (
    ParameterInfo("ft_bj", 0.25, "MPa", 0.0, _BIG, "tensile (bond) strength of the joints", lower_open=True),
    ParameterInfo("c_bj", 0.35, "MPa", 0.0, _BIG, "cohesion of the joints", lower_open=True),
    ParameterInfo("tanphi_bj", 0.75, "-", 0.0, 10.0, "initial friction coefficient of the joints"),
    ParameterInfo("tanphir_bj", 0.75, "-", 0.0, 10.0, "residual friction coefficient of the joints"),
    ParameterInfo("GfI_bj", 0.018, "N/mm", 0.0, _BIG, "mode-I fracture energy of the joints", lower_open=True),
    ParameterInfo("GfII_bj", 0.125, "N/mm", 0.0, _BIG, "mode-II fracture energy of the joints", lower_open=True),
    ParameterInfo("tanpsi_bj", 0.0, "-", 0.0, 10.0, "dilatancy coefficient of the joints"),
    ParameterInfo("fc", 10.5, "MPa", 0.0, _BIG, "compressive strength of the joint cap (masonry)", lower_open=True),
    ParameterInfo("Cs", 9.0, "-", 0.0, 1000.0, "shear contribution to the compressive cap"),
    ParameterInfo("Gfc", 5.0, "N/mm", 0.0, _BIG, "compressive fracture energy of the cap", lower_open=True),
    ParameterInfo("kappa_p", 0.09, "mm", 0.0, 100.0, "plastic relative displacement at the cap's peak",
                  lower_open=True),
    ParameterInfo("ft_bb", 2.0, "MPa", 0.0, _BIG, "tensile strength of the units (mid-plane cracks)", lower_open=True),
    ParameterInfo("GfI_bb", 0.08, "N/mm", 0.0, _BIG, "mode-I fracture energy of the units", lower_open=True),
)


@dataclass(frozen=True)
class NonlinearOptions(WallOptions):
    """Options of the nonlinear scenarios: :class:`~fe.scenarios.masonry.WallOptions` (whose
    ``load_levels`` are here levels of the control displacement, mm, ascending) plus the
    path-following settings: the initial and largest increment of the control displacement (mm),
    the joint ``law`` (``"composite"``: Lourenço–Rots with cap; ``"hyperbolic"``: the thesis'
    eq. 2.4 surface, unit mid-planes keep the tension cut-off), the hyperbolic law's compressive
    ``hyperbolic_cap`` (``"none"``, the default; ``"ellipse"`` or ``"hyperbola"``: the INFERRED (``docs/references.md``)
    shapes of :mod:`fe.interfaces.hyperbolic`, with ``fc``, ``Cs``, ``Gfc``, ``kappa_p``),
    the budget (``max_steps`` attempted increments, ``max_total_iterations`` Newton iterations,
    ``max_cpu_seconds`` CPU time of the process; ``max_seconds`` is a generous wall-clock guard
    against a hung run, not a budget: see :mod:`fe.solvers.nonlinear`), ``max_iterations`` per
    increment before it is cut back, the relative force ``tolerance``, and the interfaces'
    ``integration`` rule (``"lobatto"``: Newton–Cotes at the node pairs, the default, recommended
    for interfaces because Gauss points with stiff dummy interfaces give traction oscillations,
    Vignollet, May & de Borst 2015; ``"gauss"``: Gauss–Legendre points, a consistent interface stiffness).
    ``peak_readings`` adds the peak as two readings, ``F_peak`` (kN) and ``d_peak`` (the control
    displacement there, mm), the same at every level (a measurement gives each once, at any control
    value of its log). The budget, ``max_iterations`` and ``tolerance`` default to
    :class:`~fe.solvers.nonlinear.PathSettings`' (defined there only)."""

    increment: float = 0.01
    max_increment: float = 0.05
    max_steps: int = PathSettings.max_steps
    max_iterations: int = PathSettings.max_iterations
    max_total_iterations: int = PathSettings.max_total_iterations
    max_cpu_seconds: float = PathSettings.max_cpu_seconds
    max_seconds: float = PathSettings.max_seconds
    tolerance: float = PathSettings.tolerance
    law: str = "composite"
    hyperbolic_cap: str = "none"
    integration: str = "lobatto"
    peak_readings: bool = False

    def __post_init__(self):
        super().__post_init__()
        if self.integration not in RULES:
            raise ValueError(f"integration must be one of {RULES} (interface integration rule); "
                             f"got {self.integration!r}")
        if self.law not in ("composite", "hyperbolic"):
            raise ValueError(f"law must be 'composite' (Lourenço–Rots) or 'hyperbolic' (thesis eq. 2.4); got {self.law!r}")
        if self.hyperbolic_cap not in ("none",) + CAP_SHAPES:
            raise ValueError(f"hyperbolic_cap must be 'none' or one of {CAP_SHAPES}; got {self.hyperbolic_cap!r}")
        if self.hyperbolic_cap != "none" and self.law != "hyperbolic":
            raise ValueError(f"hyperbolic_cap={self.hyperbolic_cap!r} needs law='hyperbolic' (the composite law "
                             "always has its elliptical cap)")
        if list(self.load_levels) != sorted(self.load_levels) or self.load_levels[0] <= 0:
            raise ValueError(f"load_levels (control displacements, mm) must be positive and ascending; "
                             f"got {self.load_levels}")
        if not 0 < self.increment <= self.max_increment:
            raise ValueError(f"need 0 < increment <= max_increment (mm); got {self.increment}, {self.max_increment}")

    def path_settings(self, record_states=False):
        return PathSettings(max_steps=self.max_steps, max_iterations=self.max_iterations,
                            max_total_iterations=self.max_total_iterations, max_cpu_seconds=self.max_cpu_seconds,
                            max_seconds=self.max_seconds,
                            tolerance=self.tolerance, max_increment_fraction=self.max_increment / self.increment,
                            record_states=record_states)


#: Stiffness defaults of the TU Eindhoven walls' "Set A" (Lourenço & Rots 1997, as used for J4D–J7D):
#: units E_b = 16 700 MPa, ν = 0.15; bed joints kN = 82, kV = 36 N/mm³. With the strengths of
#: :data:`STRENGTH_PARAMETERS` (also Set A) they are the one default set of the Eindhoven wall and the
#: small specimens. Unit mid-planes keep the walls' 10⁵ N/mm³ (a moderate dummy stiffness).
SET_A_STIFFNESS = {"E_b": 16700.0, "nu_b": 0.15, "kN_bj": 82.0, "kV_bj": 36.0}


def nonlinear_parameters(defaults=None):
    """Masonry stiffness parameters plus :data:`STRENGTH_PARAMETERS`, with scenario defaults."""
    defaults = defaults or {}
    return tuple(dataclasses.replace(p, default=defaults.get(p.name, p.default))
                 for p in MASONRY_PARAMETERS + STRENGTH_PARAMETERS)


_JOINT_STRENGTHS = {"ft": ("ft_bj",), "GfI": ("GfI_bj",), "c": ("c_bj",), "tanphi0": ("tanphi_bj",),
                    "tanphir": ("tanphir_bj",), "GfII": ("GfII_bj",), "tanpsi": ("tanpsi_bj",)}
_CAP = {"fc": ("fc",), "Cs": ("Cs",), "Gfc": ("Gfc",), "kappa_p": ("kappa_p",)}
#: Interface family → (its name in words, law property → the parameters whose product it is): the
#: one map from parameters to interface properties, used to build each run's property rows and to
#: read the laws' inequalities in parameter names (:meth:`NonlinearScenario.parameter_constraints`).
FAMILIES = {
    "bed": ("bed joints", {"kn": ("kN_bj",), "ks": ("kV_bj",), **_JOINT_STRENGTHS, **_CAP}),
    "head": ("head joints", {"kn": ("r_hj", "kN_bj"), "ks": ("r_hj", "kV_bj"), **_JOINT_STRENGTHS, **_CAP}),
    "brick": ("unit mid-planes", {"kn": ("kN_bb",), "ks": ("kV_bb",), "ft": ("ft_bb",), "GfI": ("GfI_bb",)}),
}


def family_properties(family, values, exclude=()):
    """The interface properties of ``family`` (a key of :data:`FAMILIES`) for the parameter values
    ``values``, a dict of property → value (without the properties in ``exclude``)."""
    return {prop: math.prod(values[n] for n in names) for prop, names in FAMILIES[family][1].items()
            if prop not in exclude}


def _where(family):
    return FAMILIES[family][0]


def interface_properties(mesh, elements, values, points_per_element):
    """Per-point property rows of the composite law, ``(n_points, N_PROPS)``.

    Raises
    ------
    SpecError
        A family's parameters are not admissible (the message names the parameters and why).
    """
    try:
        rows = {k: composite_properties(**family_properties(k, values), where=_where(k)) for k in FAMILIES}
    except ValueError as e:
        raise SpecError(str(e)) from e
    kinds = mesh.interface_kind[elements]
    table = np.stack([rows[k] for k in INTERFACE_KINDS])
    return np.repeat(table[kinds], points_per_element, axis=0)


class NonlinearScenario(Scenario):
    """Base of the nonlinear scenarios (see the module docstring).

    Subclasses set ``mesh``, ``sensors``, ``model`` (a :class:`~fe.nonlinear_model.NonlinearModel`)
    in ``_build`` and define :meth:`phases` (the loading phases for a parameter dict) and
    ``control_sign`` (+1: the control displacement is the positive direction of its dof).

    Attributes
    ----------
    force_sensor : str or None
        The name of the load reading (the reaction of the control, ``force_unit``, after the
        gauges; the flat-jack shear test's ``p_V1``, V1's gauge pressure in MPa), or None where the
        load is no reading (the steps of ``flat_jack_elastic_nl``).
    """

    load_unit = "mm"
    load_response = "path"  # interpolate along the control displacement, never past the last level
    force_unit = "kN"
    force_sensor = "F"
    control_sign = 1.0
    #: control value (mm) up to which the curve is mesh-objective (the scenario's mesh-convergence
    #: study, ``scripts/mesh_convergence.py``); None: the whole studied range
    mesh_objective_limit = None

    def __init__(self, spec=None, solver="auto"):
        super().__init__(spec, solver)
        given = getattr(self.options, "sensors", None) or {}  # the spec's own sensors (the defaults never clash)
        taken = [n for n in self._load_readings() if n in given]
        if taken:
            raise SpecError(f"{self.name}: sensor name {taken[0]!r} is a load reading (the reaction of the control "
                            "or its peak); give the gauge another name")

    def _load_readings(self):
        """Name → (unit, definition) of the readings of the load after the gauges: :attr:`force_sensor`
        and, with the option ``peak_readings``, the peak load and its control displacement."""
        if not self.force_sensor:
            return {}
        out = {self.force_sensor: (self.force_unit, {"kind": "force", "unit": self.force_unit,
                                                     "at": "the control (its reaction, positive along the control)"})}
        if getattr(self.options, "peak_readings", False):
            out["F_peak"] = (self.force_unit, {"kind": "peak", "unit": self.force_unit,
                                               "reads": "the largest load of the curve (the same at every level)"})
            out["d_peak"] = (self.load_unit, {"kind": "peak", "unit": self.load_unit,
                                              "reads": "the control displacement at the peak load"})
        return out

    @property
    def sensor_names(self):
        """The gauges' channels, then :attr:`force_sensor` (when there is one), then ``F_peak`` and
        ``d_peak`` with the option ``peak_readings``."""
        return tuple(self.model.channel_names) + tuple(self._load_readings())

    @property
    def sensor_units(self):
        """Sensor name → unit of its readings: mm, and ``force_unit`` for the load readings."""
        units = dict.fromkeys(self.model.channel_names, "mm")
        units.update({n: u for n, (u, _) in self._load_readings().items()})
        return units

    def sensor_definitions(self):
        """Sensor name → definition dict (mm); the load readings as ``{"kind": "force" or "peak", "unit": …}``."""
        out = super().sensor_definitions()
        out.update({n: d for n, (_, d) in self._load_readings().items()})
        return out

    @classmethod
    def parameter_constraints(cls, options):
        """The inequalities of the interface laws, read in parameter names: the composite law's
        (:data:`fe.interfaces.composite.INEQUALITIES`) for every family of :data:`FAMILIES`, and
        with ``law = "hyperbolic"`` the hyperbolic law's (:data:`fe.interfaces.hyperbolic.INEQUALITIES`,
        the cap's only with a cap) for the joints. An inequality applies to a family that maps all
        its properties to parameters (the unit mid-planes have no friction surface: their ``c`` is
        infinite, which drops the inequalities carrying it). One :class:`ParameterConstraint` per
        distinct statement: bed and head joints share their strengths."""
        laws = [(k, COMPOSITE_INEQUALITIES, ()) for k in FAMILIES]
        if options.law == "hyperbolic":
            exclude = tuple(_CAP) if options.hyperbolic_cap == "none" else ()
            laws += [(k, HYPERBOLIC_INEQUALITIES, exclude) for k in ("bed", "head")]
        found = {}  # (key, parameters of each property) -> (inequality, [families], names)
        for family, inequalities, exclude in laws:
            words, names = FAMILIES[family]
            for inequality in inequalities:
                if not all(p in names and p not in exclude for p in inequality.properties):
                    continue
                mapped = {p: n for p, n in names.items() if p not in exclude}
                key = (inequality.key, inequality.formula({p: "·".join(mapped[p]) for p in inequality.properties}))
                entry = found.setdefault(key, (inequality, [], mapped))
                if words not in entry[1]:
                    entry[1].append(words)
        return tuple(ParameterConstraint(inequality, " and ".join(families).replace(" joints and ", " and "),
                                         mapped)
                     for inequality, families, mapped in found.values())

    def theta(self, values):
        return np.array(plane_stress_coefficients(values["E_b"], values["nu_b"]))

    def _nonlinear_model(self, transform):
        o = self.options
        parts = masonry_parts(self.mesh, o.thickness)[:2]
        elements = np.arange(len(self.mesh.interfaces))
        return NonlinearModel(self.mesh, parts, elements, o.thickness, transform, self.sensors,
                              solver=self._solver_name, integration=o.integration)

    def phases(self, values):
        raise NotImplementedError

    def extra_outputs(self, path, at):
        """Further per-level quantities ``name → (n_levels,)`` (default none)."""
        return {}

    def run(self, params=None, *, field=False, settings=None):
        """Follow the load path; returns a :class:`~fe.response.NonlinearResponse`.

        ``settings`` (a :class:`PathSettings`) overrides the options' path settings.
        """
        values = self.resolve(params)
        phases = self.phases(values)
        path = self.path_follower(values, settings, field).run(phases)
        return self._response(path, phases[-1].name, field)

    def path_follower(self, values, settings=None, field=False):
        """A :class:`PathFollower` on the model with the units and the interface law of ``values``
        (a full parameter dict); ``settings`` overrides the options' path settings, ``field``
        records the states."""
        model = self.model
        model.set_units(self.theta(values))
        props = self._property_rows(values)
        law = CompositeInterface(props)
        if self.options.law == "hyperbolic":
            law = self._hyperbolic_law(values, props)
        settings = settings or self.options.path_settings(record_states=field)
        if field and not settings.record_states:
            settings = dataclasses.replace(settings, record_states=True)
        return PathFollower(model, law, settings)

    def _property_rows(self, values):
        """Per-point property rows of the composite law for the parameter values ``values``,
        ``(n_points, N_PROPS)`` (a scenario that varies a joint's properties overrides this)."""
        model = self.model
        return interface_properties(self.mesh, model.interface_elements, values, model.n_points_per_element)

    def _hyperbolic_law(self, values, composite_props):
        """Joints with the hyperbolic law (and its cap when asked for), unit mid-planes with the
        composite tension cut-off."""
        kinds = np.repeat(self.mesh.interface_kind[self.model.interface_elements], self.model.n_points_per_element)
        joints = np.flatnonzero(kinds != INTERFACE_KINDS.index("brick"))
        cracks = np.flatnonzero(kinds == INTERFACE_KINDS.index("brick"))
        cap = self.options.hyperbolic_cap
        exclude = tuple(_CAP) if cap == "none" else ()
        shape = {} if cap == "none" else {"cap_shape": cap}
        try:
            bed, head = (hyperbolic_properties(**family_properties(k, values, exclude), **shape,
                                               where=f"{_where(k)}, hyperbolic law") for k in ("bed", "head"))
        except ValueError as e:
            raise SpecError(str(e)) from e
        rows = np.where((kinds[joints] == INTERFACE_KINDS.index("bed"))[:, None], bed, head)
        return MixedInterface([HyperbolicInterface(rows), CompositeInterface(composite_props[cracks])],
                              [joints, cracks])

    def _response(self, path, control_phase, field, columns=None):
        """The response at the load levels of ``control_phase``; ``columns`` (name → ``(n_levels,)``)
        holds the values of load readings other than the force and the peak (a scenario's own)."""
        levels = self.load_levels
        mask = path.of_phase(control_phase)
        disp = self.control_sign * path.path[mask] if mask.any() else np.zeros(0)
        load = path.load[mask]
        readings = np.full((len(levels), len(self.model.channel_names)), np.nan)
        loads = np.full(len(levels), np.nan)
        at = np.full(len(levels), -1)
        idx = np.flatnonzero(mask)
        for k, level in enumerate(levels):
            # the first step that reaches the level (exact in displacement control; linear
            # interpolation where a snap-back detour under indirect control jumped over it)
            hit = np.flatnonzero(disp >= level - 1e-9 * max(level, 1.0))
            if not len(hit):
                continue
            i = hit[0]
            at[k] = idx[i]
            if abs(disp[i] - level) <= 1e-9 * max(level, 1.0) or i == 0:
                readings[k], loads[k] = path.readings[idx[i]], load[i]
            else:
                a = (level - disp[i - 1]) / (disp[i] - disp[i - 1])
                readings[k] = (1 - a) * path.readings[idx[i - 1]] + a * path.readings[idx[i]]
                loads[k] = (1 - a) * load[i - 1] + a * load[i]
        peak = int(np.argmax(load)) if len(load) else None
        peak_load = float(load[peak]) if peak is not None else float("nan")
        peak_displacement = float(disp[peak]) if peak is not None else float("nan")
        refined = getattr(path, "peaks", {}).get(control_phase)
        if refined is not None:
            # the load maximum refined to the solver's peak_tolerance (fe.solvers.nonlinear.Peak)
            peak_load, peak_displacement = refined.load, self.control_sign * refined.path
        u = None
        if field and path.displacements is not None:
            u = np.full((len(levels), self.mesh.n_nodes, 2), np.nan)
            for k in range(len(levels)):
                if at[k] >= 0:
                    u[k] = path.displacements[at[k]]
        extra_columns = {"F_peak": np.full(len(levels), peak_load), "d_peak": np.full(len(levels), peak_displacement),
                         **(columns or {})}
        load_columns = [loads if n == self.force_sensor else extra_columns[n] for n in self._load_readings()]
        if load_columns:
            readings = np.column_stack([readings, *load_columns])
        return NonlinearResponse(
            readings, self.sensor_names, levels, self.load_unit, u, loads=loads, force_unit=self.force_unit,
            peak_load=peak_load, peak_displacement=peak_displacement,
            status=path.status, limit=path.limit, message=path.message,
            reached=float(disp[-1]) if len(disp) else 0.0,
            extra=self.extra_outputs(path, at), path=path, mesh_objective_limit=self.mesh_objective_limit)

    def _control_phase(self, name, dof, f_const, held=(), f_scale=1e-3):
        o = self.options
        s = self.control_sign
        return Phase(name, "dof", target=s * o.load_levels[-1], increment=o.increment, f_const=f_const,
                     dof=dof, held=tuple(held), levels=tuple(s * v for v in o.load_levels), load_scale=s * f_scale)


def reduced_dof(transform, dof):
    """The reduced unknown of a full dof (its tie master's column); error when the dof is fixed."""
    row = transform.getrow(int(dof))
    if row.nnz != 1:
        raise ValueError(f"dof {dof} is fixed: it has no reduced unknown")
    return int(row.indices[0])
