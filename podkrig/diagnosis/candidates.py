"""The library of candidate causes: physical effects a base model leaves out.

Each :class:`Candidate` is a named effect with one extra parameter per *location* (a joint
segment, a sensor and fault kind, a kind of load misalignment) and a neutral value at which it is
off. The effect is computed by the FE model directly, reusing its stiffness parts and pattern:

=====================  =====================================  ===========================================
candidate              extra parameter (neutral)               residual signature
=====================  =====================================  ===========================================
head_joint_stiffness   r_hj, head/bed stiffness ratio (base)   gauges across head joints, diagonals; ∝ load
weak_joint             f, stiffness factor of one joint        gauges crossing or near that joint, a
                       segment's kN and kV (1)                 local pattern; ∝ load
support_compliance     c_s = 1/k_s, compliance of the          absolute displacements and gauges near the
                       supports, mm³/N (0: rigid)              supports; ∝ load
gauge_fault            gain g (0) or offset o, mm (0)          one sensor only: ∝ its reading (gain) or
                                                               constant over the load levels (offset)
load_eccentricity      offset e of the load line, mm (0),      antisymmetric about the intended load line;
                       or its rotation φ, degrees (0)          ∝ load
unit_stiffness         E_b, MPa (base)                         gauges on units, diagonals; ∝ load
=====================  =====================================  ===========================================

Candidates say *what they change* (:meth:`Candidate.effect` returns an :class:`Effect`: parameter
values, stiffness increments, support springs, extra load patterns, reading corrections), so that
several causes found in turn combine into one FE model (:meth:`FEContext.readings_with`, one
factorisation per evaluation).

``head_joint_stiffness`` and ``unit_stiffness`` are candidates only when the base model keeps
``r_hj`` / ``E_b`` fixed; ``support_compliance`` and ``load_eccentricity`` only for scenarios
with supports / a load line (:class:`fe.Scenario`'s ``supported_nodes``,
``load_perturbations``).
"""

import abc
from dataclasses import dataclass, field

import numpy as np

from fe.mesh.mesh import INTERFACE_KINDS
from fe.supports import spring_supported_model, support_areas


@dataclass(frozen=True)
class Location:
    """One place (or instance) of a candidate cause.

    Attributes
    ----------
    key : str
        Unique within the candidate, e.g. ``"bed 12|17"`` or ``"HJ_H gain"``.
    label : str
        In words, for reports.
    detail : dict
        JSON-able description (kind, coordinates in mm, sensor, ...).
    """

    key: str
    label: str
    detail: dict = field(default_factory=dict)


@dataclass(frozen=True)
class EffectParameter:
    """The extra parameter of a candidate at one location.

    ``neutral`` switches the effect off; ``reference`` is a moderate value whose effect serves as
    the screening signature; ``scale`` is how the fit moves through ``[lower, upper]``
    (``"linear"`` or ``"log"``). ``one_sided``: the neutral value is a bound (e.g. a joint can only
    be weaker), which halves the null distribution of the likelihood-ratio statistic.
    """

    name: str
    unit: str
    neutral: float
    lower: float
    upper: float
    reference: float
    scale: str = "linear"
    one_sided: bool = False

    @property
    def off(self):
        """The value in ``[lower, upper]`` where the effect is off (or nearest to off)."""
        return min(max(self.neutral, self.lower), self.upper)

    def to_fit(self, c):
        """Physical value → fit coordinate in [0, 1]."""
        if self.scale == "log":
            return (np.log(c) - np.log(self.lower)) / (np.log(self.upper) - np.log(self.lower))
        return (c - self.lower) / (self.upper - self.lower)

    def from_fit(self, t):
        """Fit coordinate in [0, 1] → physical value."""
        if self.scale == "log":
            return float(np.exp(np.log(self.lower) + t * (np.log(self.upper) - np.log(self.lower))))
        return float(self.lower + t * (self.upper - self.lower))


@dataclass(frozen=True)
class Effect:
    """What a candidate cause changes in the FE model, so that several causes combine.

    Attributes
    ----------
    values : dict of str to float
        Parameter values that replace the model's (e.g. ``{"r_hj": 0.4}``).
    increments : tuple of (float, tuple)
        Stiffness increments ``(coefficient, key)``: ``key = ("joint", segment, "normal" | "shear")``
        is a joint segment's part of the bed/head-joint stiffness, resolved on whichever model
        (rigid or spring supports) the combination solves.
    compliance : float or None
        Support compliance ``1/k_s``, mm³/N: the model with its supports on springs
        (:func:`fe.supports.spring_supported_model`); None keeps them rigid.
    load_scale : float
        Factor on the readings of the scenario's own load patterns (a rotated load line: cos φ).
    extra_loads : tuple of (str, callable, float)
        ``(key, patterns, weight)``: readings of extra nodal load patterns ``patterns()``
        ``(n_dofs, n_patterns)`` added with ``weight``, under the same load coefficients.
    corrections : tuple of callable
        ``R -> R`` on the readings ``(n_loads, n_sensors)`` after the solve (sensor faults), in order.
    """

    values: dict = field(default_factory=dict)
    increments: tuple = ()
    compliance: float | None = None
    load_scale: float = 1.0
    extra_loads: tuple = ()
    corrections: tuple = ()


class FEContext:
    """The base model's FE scenario with the pieces the candidates share, built lazily and cached.

    Parameters
    ----------
    scenario : fe.Scenario
    free : sequence of str
        The base model's free parameters.
    values : dict of str to float
        Every parameter's value in the base model (the fixed ones stay at these).
    offset_scale : float
        Range of a sensor offset, mm (the largest measured |reading|).
    """

    def __init__(self, scenario, free, values, offset_scale=1.0):
        self.scenario = scenario
        self.free = tuple(free)
        self.values = dict(values)
        self.offset_scale = float(offset_scale)
        self.n_runs = 0
        self._cache = {}

    @property
    def sensor_names(self):
        return tuple(self.scenario.sensor_names)

    def readings(self, values, increments=()):
        """FE readings ``(n_loads, n_sensors)`` mm with optional stiffness increments (the last
        plain run is remembered: candidates that post-process readings reuse it)."""
        sc = self.scenario
        key = tuple(sorted(values.items()))
        if not increments and self._cache.get("last_key") == key:
            return self._cache["last_readings"].copy()
        self.n_runs += 1
        q = sc.model.solve(sc.theta(values), increments)
        R = sc.load_coefficients_at(values) @ sc.model.readings(q)
        if not increments:
            self._cache["last_key"], self._cache["last_readings"] = key, R.copy()
        return R

    def readings_with(self, values, terms):
        """FE readings ``(n_loads, n_sensors)`` mm of the model with several causes switched on.

        ``terms`` is a sequence of ``(candidate, location, c)``; their :class:`Effect` objects are
        combined: parameter values first (so that, e.g., a weak head-joint segment scales with a
        head-joint ratio found before it), then stiffness increments, support springs, extra load
        patterns and reading corrections. One factorisation. Without terms: :meth:`readings`.
        """
        if not terms:
            return self.readings(values)
        values = dict(values)
        for cand, loc, c in terms:  # parameter values first: later effects see them
            values.update(cand.effect(self, values, loc, c).values)
        effects = [cand.effect(self, values, loc, c) for cand, loc, c in terms]
        sc = self.scenario
        if not any(e.increments or e.compliance is not None or e.extra_loads for e in effects):
            R = np.prod([e.load_scale for e in effects]) * self.readings(values)  # the cached plain run
            for e in effects:
                for correct in e.corrections:
                    R = correct(R)
            return R
        compliances = [e.compliance for e in effects if e.compliance is not None]
        if len(compliances) > 1:
            raise ValueError("two support-compliance effects cannot be combined")
        model, theta = sc.model, sc.theta(values)
        if compliances:
            model, theta = self.spring_model(), np.append(theta, 1.0 / compliances[0])
        increments = [(coef, self._increment(model, key)) for e in effects for coef, key in e.increments]
        extra = [(key, patterns, w) for e in effects for key, patterns, w in e.extra_loads]
        rhs = np.hstack([model.rhs] + [self._reduced_loads(model, key, patterns) for key, patterns, _ in extra])
        self.n_runs += 1
        r = model.readings(model.solve(theta, increments, rhs))
        n_pat = sc.model.rhs.shape[1]
        C = sc.load_coefficients_at(values)
        R = np.prod([e.load_scale for e in effects]) * (C @ r[:n_pat])
        for k, (_, _, w) in enumerate(extra):
            R = R + w * (C @ r[n_pat * (k + 1):n_pat * (k + 2)])
        for e in effects:
            for correct in e.corrections:
                R = correct(R)
        return R

    def _increment(self, model, key):
        """The :class:`~fe.assembly.StiffnessIncrement` of ``key`` (see :class:`Effect`) on ``model``."""
        cache_key = (id(model),) + tuple(key)
        if cache_key not in self._cache:
            _, segment, which = key
            kind, elements, _ = self.joint_segments()[segment]
            within = np.searchsorted(self.scenario.joint_part_elements(kind), elements)  # within the part
            self._cache[cache_key] = model.part_increment(f"{kind}_{which}", within)
        return self._cache[cache_key]

    def _reduced_loads(self, model, key, patterns):
        cache_key = (id(model), "loads", key)
        if cache_key not in self._cache:
            self._cache[cache_key] = model.reduce_loads(patterns())
        return self._cache[cache_key]

    def spring_model(self):
        if "springs" not in self._cache:
            self._cache["springs"] = spring_supported_model(self.scenario)
        return self._cache["springs"]

    def joint_segments(self):
        """Bed- and head-joint segments (unit pairs) of the mesh: list of (kind, elements, detail)."""
        if "segments" not in self._cache:
            self._cache["segments"] = _joint_segments(self.scenario)
        return self._cache["segments"]

    def joint_increments(self, index):
        """Normal and shear stiffness increments of joint segment ``index`` (unit coefficients)."""
        return tuple(self._increment(self.scenario.model, ("joint", index, which)) for which in ("normal", "shear"))


def span(axis, bounds, unit="mm"):
    """``"x 910–1040 mm"`` for a coordinate range, ``"y 1105 mm"`` when both ends agree (to the
    printed precision): a joint segment along x sits at one y."""
    lo, hi = (f"{v:g}" for v in bounds)
    return f"{axis} {lo} {unit}" if lo == hi else f"{axis} {lo}–{hi} {unit}"


def _joint_segments(scenario):
    """Group the bed/head interface elements of the scenario's joint parts by the pair of units
    they join (interfaces outside those parts, e.g. a flat-jack slot, belong to no segment)."""
    mesh = scenario.mesh
    units = mesh.block_unit[mesh.interface_blocks]
    in_parts = np.zeros(len(mesh.interfaces), bool)
    for name in ("bed", "head"):
        in_parts[scenario.joint_part_elements(name)] = True
    segments = {}
    for i, (kind, (a, b)) in enumerate(zip(mesh.interface_kind, units)):
        name = INTERFACE_KINDS[kind]
        if name in ("bed", "head") and in_parts[i]:
            segments.setdefault((name, min(a, b), max(a, b)), []).append(i)
    out = []
    for (kind, a, b), elements in sorted(segments.items(), key=lambda kv: (kv[0][0], kv[0][1], kv[0][2])):
        xy = mesh.nodes[mesh.interfaces[elements]].reshape(-1, 2)
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        detail = {
            "kind": kind, "units": [int(a), int(b)],
            "x": [round(float(lo[0]), 3), round(float(hi[0]), 3)], "y": [round(float(lo[1]), 3), round(float(hi[1]), 3)],
        }
        out.append((kind, np.array(elements), detail))
    return out


class Candidate(abc.ABC):
    """A candidate cause. Subclasses set ``name``, ``description`` (physical meaning) and
    ``signature`` (the residual pattern it produces) and implement :meth:`locations`,
    :meth:`parameter` and :meth:`effect`."""

    name = ""
    description = ""
    signature = ""
    #: whether the effect combines with other causes through an :class:`Effect`; a candidate that
    #: runs another model (e.g. the nonlinear solver) overrides :meth:`readings` and sets False
    composable = True

    def not_applicable(self, ctx):
        """Why the candidate does not apply to this base model (str), or None."""
        return

    @abc.abstractmethod
    def locations(self, ctx):
        """The candidate's locations for this scenario, list of :class:`Location`."""

    @abc.abstractmethod
    def parameter(self, ctx, location):
        """The :class:`EffectParameter` at ``location``."""

    @abc.abstractmethod
    def effect(self, ctx, values, location, c):
        """The :class:`Effect` at ``location`` with parameter value ``c``, base parameters ``values``."""

    def readings(self, ctx, values, location, c, found=()):
        """FE readings ``(n_loads, n_sensors)`` mm with base parameters ``values`` (full dict), the
        causes ``found`` before (``(candidate, location, value)``) and this one at ``location``
        with parameter value ``c``."""
        return ctx.readings_with(values, [*found, (self, location, c)])


class HeadJointStiffness(Candidate):
    name = "head_joint_stiffness"
    description = ("Head joints with a stiffness r_hj times that of the bed joints (partly filled or "
                   "shrunk head joints), where the base model keeps r_hj fixed.")
    signature = "Gauges across head joints and the diagonals, growing in proportion to the load."

    def not_applicable(self, ctx):
        if "r_hj" in ctx.free:
            return "r_hj is a free parameter of the base model"
        if "r_hj" not in ctx.values:
            return "the scenario has no head-joint stiffness ratio"
        return None

    def locations(self, ctx):
        return [Location("all head joints", "all head joints", {"parameter": "r_hj"})]

    def parameter(self, ctx, location):
        r0 = ctx.values["r_hj"]
        return EffectParameter("r_hj", "-", r0, min(0.02, r0), max(5.0, r0), 0.5 * r0, scale="log")

    def effect(self, ctx, values, location, c):
        return Effect(values={"r_hj": c})


class UnitStiffness(Candidate):
    name = "unit_stiffness"
    description = "Units with a Young's modulus E_b different from the value the base model fixes."
    signature = "Gauges inside units and the diagonals, growing in proportion to the load."

    def not_applicable(self, ctx):
        if "E_b" in ctx.free:
            return "E_b is a free parameter of the base model"
        return None

    def locations(self, ctx):
        return [Location("all units", "all units", {"parameter": "E_b"})]

    def parameter(self, ctx, location):
        e0 = ctx.values["E_b"]
        return EffectParameter("E_b", "MPa", e0, e0 / 4.0, 4.0 * e0, 0.7 * e0, scale="log")

    def effect(self, ctx, values, location, c):
        return Effect(values={"E_b": c})


class WeakJoint(Candidate):
    name = "weak_joint"
    description = ("One bed- or head-joint segment (between two units) with its normal and shear "
                   "stiffness reduced by a factor f (poor filling, debonding, a local defect).")
    signature = ("A local pattern: gauges crossing or next to that joint move most, far sensors "
                 "little; in proportion to the load.")

    def locations(self, ctx):
        out = []
        for i, (kind, _, d) in enumerate(ctx.joint_segments()):
            label = f"{kind} joint between units {d['units'][0]} and {d['units'][1]}, {span('x', d['x'])}, {span('y', d['y'])}"
            out.append(Location(f"{kind} {d['units'][0]}|{d['units'][1]}", label, {**d, "segment": i}))
        return out

    def parameter(self, ctx, location):
        # the screening signature of a nearly open joint also measures the candidate's visibility
        return EffectParameter("f", "-", 1.0, 1e-3, 1.0, 0.01, scale="log", one_sided=True)

    def effect(self, ctx, values, location, c):
        i = location.detail["segment"]
        r = values.get("r_hj", 1.0) if location.detail["kind"] == "head" else 1.0
        return Effect(increments=(((c - 1.0) * r * values["kN_bj"], ("joint", i, "normal")),
                                  ((c - 1.0) * r * values["kV_bj"], ("joint", i, "shear"))))


class SupportCompliance(Candidate):
    name = "support_compliance"
    description = ("Compliant supports (bedding mortar, gypsum or pads under the support shoes, a "
                   "flexible rig): distributed springs of compliance c_s = 1/k_s instead of fixed nodes.")
    signature = ("Absolute displacements and gauges near the supports; relative gauges far from "
                 "them barely move; in proportion to the load.")

    def not_applicable(self, ctx):
        sc = ctx.scenario
        nodes = getattr(sc, "supported_nodes", ())
        if len(nodes) == 0:
            return "the scenario has no supports"
        if not np.any(support_areas(sc.mesh, nodes, sc.options.thickness) > 0):
            return "the scenario's supports hold single nodes (no supported edge to put springs on)"
        return None

    def locations(self, ctx):
        return [Location("supports", "all supports", {"nodes": len(ctx.scenario.supported_nodes)})]

    def parameter(self, ctx, location):
        # compliance 1 mm³/N is a 10 mm layer of a 10 MPa material: a soft pad
        # (fitted in log scale from 1e-5 mm³/N, a support 10⁴ times stiffer than a mortar joint)
        return EffectParameter("c_s", "mm³/N", 0.0, 1e-5, 1.0, 0.02, scale="log", one_sided=True)

    def effect(self, ctx, values, location, c):
        return Effect(compliance=c if c > 0.0 else None)


class GaugeFault(Candidate):
    name = "gauge_fault"
    description = ("One sensor with a gain error (mis-calibrated, slipping or misaligned transducer: "
                   "reading × (1 + g)) or an offset (wrong zero: reading + o).")
    signature = ("One sensor only: in proportion to its own reading (gain) or the same at every load "
                 "level (offset); every other sensor fits.")

    def locations(self, ctx):
        return [Location(f"{s} {kind}", f"sensor {s}, {kind}", {"sensor": s, "fault": kind})
                for s in ctx.sensor_names for kind in ("gain", "offset")]

    def parameter(self, ctx, location):
        if location.detail["fault"] == "gain":
            return EffectParameter("g", "-", 0.0, -0.5, 0.5, 0.1)
        scale = ctx.offset_scale
        return EffectParameter("o", "mm", 0.0, -scale, scale, 0.1 * scale)

    def effect(self, ctx, values, location, c):
        column, fault = ctx.sensor_names.index(location.detail["sensor"]), location.detail["fault"]
        return Effect(corrections=(lambda R: apply_gauge_fault(R, column, fault, c),))


def apply_gauge_fault(R, column, fault, value):
    """Readings ``R`` ``(n_loads, n_sensors)`` with a gain (``R·(1+g)``) or offset (``R + o``) on one column."""
    R = np.array(R, dtype=float)
    if fault == "gain":
        R[:, column] *= 1.0 + value
    else:
        R[:, column] += value
    return R


class LoadEccentricity(Candidate):
    name = "load_eccentricity"
    description = ("The load applied off its intended line: the resultant offset by e along the "
                   "loading shoes, or the load direction rotated by φ (a misaligned actuator).")
    signature = ("Antisymmetric about the intended load line: sensors on one side lengthen, on the "
                 "other shorten; in proportion to the load.")

    #: largest load-line rotation tried, degree (a visibly misaligned actuator; a choice)
    max_rotation = 15.0

    def not_applicable(self, ctx):
        if not ctx.scenario.load_perturbations():
            return f"the {ctx.scenario.name} scenario defines no load line that could be off"
        return None

    def locations(self, ctx):
        return [Location(p.name, p.description, {"kind": p.name})
                for p in ctx.scenario.load_perturbations().values()]

    def parameter(self, ctx, location):
        p = ctx.scenario.load_perturbations()[location.detail["kind"]]
        if p.kind == "shift":
            return EffectParameter("e", p.unit, 0.0, -p.limit, p.limit, 0.5 * p.limit)
        return EffectParameter("phi", "degree", 0.0, -self.max_rotation, self.max_rotation, 5.0)

    def effect(self, ctx, values, location, c):
        p = ctx.scenario.load_perturbations()[location.detail["kind"]]
        if p.kind == "shift":
            return Effect(extra_loads=((p.name, p.patterns, c),))
        phi = np.radians(c)
        return Effect(load_scale=np.cos(phi), extra_loads=((p.name, p.patterns, np.sin(phi)),))


#: every candidate cause, by name
CANDIDATES = {c.name: c for c in (HeadJointStiffness(), WeakJoint(), SupportCompliance(), GaugeFault(),
                                  LoadEccentricity(), UnitStiffness())}
