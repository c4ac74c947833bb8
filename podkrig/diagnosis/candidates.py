"""The library of candidate causes: physical effects a base model leaves out.

Each :class:`Candidate` is a named effect with one extra parameter per *location* (a joint
segment, a sensor and fault kind, a kind of load misalignment) and a neutral value at which it is
off. The effect is computed by the FE model directly, reusing its stiffness parts and pattern:

=====================  =====================================  ===========================================
candidate              extra parameter (neutral)               residual signature
=====================  =====================================  ===========================================
head_joint_stiffness   r_hj, head/bed stiffness ratio (base)   gauges across head joints, diagonals; ∝ load
weak_joint             f, stiffness factor of one joint        gauges crossing or near that joint, a
                       segment's or one whole bed joint's kN   local pattern; ∝ load
                       and kV (1)
support_compliance     c_s = 1/k_s, compliance of the          absolute displacements and gauges near the
                       supports, mm³/N (0: rigid)              supports; ∝ load
gauge_fault            gain g (0) or offset o, mm (0)          one sensor only: ∝ its reading (gain) or
                                                               constant over the load levels (offset)
load_eccentricity      offset e of the load line, mm (0),      antisymmetric about the intended load line;
                       or its rotation φ, degrees (0)          ∝ load
unit_stiffness         E_b, MPa (base)                         gauges on units, diagonals; ∝ load
gauge_slip             step c of one sensor from level k, mm   one sensor only: unchanged below level k,
                       (0)                                     the same offset from k on
jack_efficiency        Km of all jacks or one jack (fixed)     that jack's response scaled by one factor
slot_contact           length ℓ without jack contact at a      near that slot end, against the jack
                       slot end or both, mm (0)                pressure; ∝ pressure
nonlinearity_onset     joint tensile strength ft_bj, MPa,      nothing below the onset level k, then a
                       per onset level k (just above k's       departure growing faster than the load
                       range: no departure)                    (cracking/sliding joints)
weak_joint_strength    s, bond-strength factor (ft, c) of      the force curve of a specimen test: a
                       one bed joint of a specimen (1)         lower, broader peak, a slower softening
dilatancy              tanψ of the joints (the fixed value,    the joints open as they slide: gauges
                       0 by default)                           across a joint grow with the slip
=====================  =====================================  ===========================================

Candidates say *what they change* (:meth:`Candidate.effect` returns an :class:`Effect`: parameter
values, stiffness increments, support springs, extra load patterns, reading corrections), so that
several causes found in turn combine into one FE model (:meth:`FEContext.readings_with`, one
factorisation per evaluation).

``head_joint_stiffness`` and ``unit_stiffness`` are candidates only when the base model keeps
``r_hj`` / ``E_b`` fixed; ``support_compliance`` and ``load_eccentricity`` only for scenarios
with supports / a load line (:class:`fe.Scenario`'s ``supported_nodes``,
``load_perturbations``); ``jack_efficiency`` and ``slot_contact`` only for the flat-jack scenario
(``jack_efficiency`` when ``Km`` is fixed); ``nonlinearity_onset`` only for scenarios with a
nonlinear twin (:mod:`podkrig.diagnosis.nonlinear_runs`), and only when named (it is
``expensive``: not in :data:`DEFAULT_CANDIDATES`).

On a nonlinear scenario (curve data: force–displacement curves of a strength test) every FE
evaluation is a path-following run (:meth:`FEContext.readings`), and only the candidates that act
through parameter values, scenario options and reading corrections apply: ``weak_joint``,
``support_compliance`` and ``load_eccentricity`` act on the linear model's stiffness parts, springs
and load patterns and say so. ``weak_joint_strength`` applies to scenarios with the option
``joint_strength_factors`` (``triplet_shear``), ``dilatancy`` to those with ``tanpsi_bj`` when the
base model keeps it fixed.
"""

import abc
from dataclasses import dataclass, field

import numpy as np

from fe.mesh.mesh import INTERFACE_KINDS
from fe.scenarios import build_scenario
from fe.supports import spring_supported_model, support_areas
from podkrig.diagnosis.nonlinear_runs import (
    ELASTIC_SCALE,
    NonlinearTwin,
    counterpart_reason,
    critical_joints,
    onset_strength,
)


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
    options : dict of str to object
        Scenario options that replace the base scenario's (a nonlinear scenario only: the scenario
        is rebuilt with them, :meth:`FEContext.scenario_with`), e.g. a joint's strength factor.
    extra_loads : tuple of (hashable, callable, float)
        ``(key, patterns, weight)``: readings of extra nodal load patterns ``patterns()``
        ``(n_dofs, n_patterns)`` (as many as the scenario's own) added with ``weight``, under the
        same load coefficients; their reduced form is cached by ``key`` (None: not cached).
    corrections : tuple of callable
        ``R -> R`` on the readings ``(n_loads, n_sensors)`` after the solve (sensor faults), in order.
    """

    values: dict = field(default_factory=dict)
    increments: tuple = ()
    compliance: float | None = None
    load_scale: float = 1.0
    options: dict = field(default_factory=dict)
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
    bounds : dict of str to (float, float), optional
        The free parameters' ranges (candidates whose admissible range depends on them read it).
    """

    #: nonlinear scenarios rebuilt with other options, kept per context (most recent last)
    _MAX_VARIANTS = 16

    def __init__(self, scenario, free, values, offset_scale=1.0, bounds=None):
        self.scenario = scenario
        self.free = tuple(free)
        self.values = dict(values)
        self.offset_scale = float(offset_scale)
        self.bounds = dict(bounds or {})
        #: a nonlinear scenario (curve data): every evaluation is a path-following run
        self.nonlinear = getattr(scenario, "load_response", "affine") == "path"
        self.n_runs = 0
        #: the calibrated base model's values once known (the diagnosis sets them after its base
        #: fit): candidates too expensive to recompute at every trial value precompute there
        self.base_values = None
        self._cache = {}

    @property
    def reference_values(self):
        """:attr:`base_values` when set, else :attr:`values`."""
        return dict(self.base_values) if self.base_values is not None else dict(self.values)

    @property
    def sensor_names(self):
        return tuple(self.scenario.sensor_names)

    def readings(self, values, increments=(), options=None):
        """FE readings ``(n_loads, n_sensors)`` mm with optional stiffness increments (the last
        plain run is remembered: candidates that post-process readings reuse it).

        A nonlinear scenario runs its load path (with the scenario ``options`` replaced, when
        given; no stiffness increments): a level the run does not reach (the specimen failed
        before it) reads 0, a large misfit rather than a gap in the fit.
        """
        sc = self.scenario
        key = (tuple(sorted(values.items())), tuple(sorted((options or {}).items())))
        if not increments and self._cache.get("last_key") == key:
            return self._cache["last_readings"].copy()
        self.n_runs += 1
        if self.nonlinear:
            if increments:
                raise ValueError(f"{sc.name} is nonlinear: stiffness increments act on a linear model only")
            R = np.nan_to_num(self.scenario_with(options).run(values).readings, nan=0.0)
        else:
            if options:
                raise ValueError(f"{sc.name} is linear: options {sorted(options)} act on nonlinear scenarios only")
            q = sc.model.solve(sc.theta(values), increments)
            R = sc.load_coefficients_at(values) @ sc.model.readings(q)
        if not increments:
            self._cache["last_key"], self._cache["last_readings"] = key, R.copy()
        return R

    def scenario_with(self, options=None):
        """The scenario with ``options`` replaced (the scenario itself when None or empty), built
        once per distinct options and kept (the most recent :attr:`_MAX_VARIANTS`)."""
        if not options:
            return self.scenario
        key = ("variant", tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in options.items())))
        variants = self._cache.setdefault("variants", {})
        if key not in variants:
            if len(variants) >= self._MAX_VARIANTS:
                variants.pop(next(iter(variants)))
            variants[key] = build_scenario({**self.scenario.spec.to_dict(), **options})
        return variants[key]

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
        options = {k: v for e in effects for k, v in e.options.items()}
        sc = self.scenario
        if not any(e.increments or e.compliance is not None or e.extra_loads for e in effects):
            R = np.prod([e.load_scale for e in effects]) * self.readings(values, options=options)  # cached plain run
            for e in effects:
                for correct in e.corrections:
                    R = correct(R)
            return R
        if options or self.nonlinear:
            raise ValueError(f"{sc.name}: stiffness increments, springs and load patterns act on a linear model, "
                             "scenario options on a nonlinear one; they cannot be combined")
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
        """``Tᵀ f`` of ``patterns()`` on ``model``, cached by ``key`` (None: not cached)."""
        if key is None:
            return model.reduce_loads(patterns())
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


def linear_model_reason(ctx):
    """Why a candidate acting on the linear model's stiffness parts, springs or load patterns does
    not apply to ``ctx`` (str), or None."""
    if ctx.nonlinear:
        return (f"it acts on the linear FE model's stiffness, supports or load patterns; {ctx.scenario.name} "
                "is a nonlinear (curve) scenario")
    return None


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
    #: True for candidates that need many FE runs of another kind (nonlinear): left out of a
    #: diagnosis unless named (see :data:`DEFAULT_CANDIDATES`)
    expensive = False

    def not_applicable(self, ctx):
        """Why the candidate does not apply to this base model (str), or None."""
        return

    def overlaps(self, location, other):
        """Whether ``location`` acts on part of what ``other`` (a location of this candidate already
        in the model) acts on: such a location is not tried beside it."""
        return False

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
        if not np.any(ctx.scenario.mesh.interface_kind == INTERFACE_KINDS.index("head")):
            return f"the {ctx.scenario.name} scenario has no head joints"
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
    description = ("One joint segment (between two units) or one whole bed joint (every segment at one "
                   "height, course to course across the wall) with its normal and shear stiffness "
                   "reduced by a factor f (poor filling, debonding, a local defect, a weak course).")
    signature = ("A local pattern: gauges crossing or next to that joint move most, far sensors "
                 "little; in proportion to the load. A whole bed joint: every sensor across that "
                 "height.")

    def not_applicable(self, ctx):
        return linear_model_reason(ctx)

    def locations(self, ctx):
        out, beds = [], {}
        for i, (kind, _, d) in enumerate(ctx.joint_segments()):
            label = f"{kind} joint between units {d['units'][0]} and {d['units'][1]}, {span('x', d['x'])}, {span('y', d['y'])}"
            out.append(Location(f"{kind} {d['units'][0]}|{d['units'][1]}", label, {**d, "segment": i}))
            if kind == "bed":
                beds.setdefault(round(float(d["y"][0]), 6), []).append((i, d))
        if any(len(segments) > 1 for segments in beds.values()):  # whole bed joints, after the segments
            for y, segments in sorted(beds.items()):
                x = [min(d["x"][0] for _, d in segments), max(d["x"][1] for _, d in segments)]
                out.append(Location(f"bed joint y {y:g}", f"the whole bed joint at y {y:g} mm, {span('x', x)}",
                                    {"kind": "bed", "x": x, "y": [y, y], "segments": [i for i, _ in segments]}))
        return out

    def parameter(self, ctx, location):
        # the screening signature of a nearly open joint also measures the candidate's visibility
        return EffectParameter("f", "-", 1.0, 1e-3, 1.0, 0.01, scale="log", one_sided=True)

    def overlaps(self, location, other):
        # a segment of a whole bed joint already in the model, or the whole joint of one of its segments
        return bool(set(_segments(location)) & set(_segments(other)))

    def effect(self, ctx, values, location, c):
        d = location.detail
        r = values.get("r_hj", 1.0) if d["kind"] == "head" else 1.0
        increments = []
        for i in _segments(location):
            increments += [((c - 1.0) * r * values["kN_bj"], ("joint", i, "normal")),
                           ((c - 1.0) * r * values["kV_bj"], ("joint", i, "shear"))]
        return Effect(increments=tuple(increments))


def _segments(location):
    """Joint segments (indices into :meth:`FEContext.joint_segments`) of a :class:`WeakJoint` location."""
    return location.detail.get("segments", [location.detail.get("segment")])


class SupportCompliance(Candidate):
    name = "support_compliance"
    description = ("Compliant supports (bedding mortar, gypsum or pads under the support shoes, a "
                   "flexible rig): distributed springs of compliance c_s = 1/k_s instead of fixed nodes.")
    signature = ("Absolute displacements and gauges near the supports; relative gauges far from "
                 "them barely move; in proportion to the load.")

    def not_applicable(self, ctx):
        sc = ctx.scenario
        if ctx.nonlinear:
            return linear_model_reason(ctx)
        if getattr(sc.options, "support", None) == "springs":
            return "the scenario's supports are springs already (support = 'springs'): their stiffness is an option"
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
        if ctx.nonlinear:
            return linear_model_reason(ctx)
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


class GaugeSlip(Candidate):
    name = "gauge_slip"
    description = ("A sensor that slipped (an anchor or clamp moved, a transducer knocked) between two "
                   "consecutive load levels: from level k on its reading is offset by c.")
    signature = ("One sensor only: unchanged up to level k−1, then the same offset c at level k and "
                 "every higher level; every other sensor fits.")

    def locations(self, ctx):
        sc = ctx.scenario
        levels = sc.load_levels
        return [Location(f"{s} from {levels[k]:g}",
                         f"sensor {s} slipped between {levels[k - 1]:g} and {levels[k]:g} {sc.load_unit}",
                         {"sensor": s, "level": int(k), "load": float(levels[k]), "unit": sc.load_unit})
                for s in ctx.sensor_names for k in range(1, len(levels))]

    def parameter(self, ctx, location):
        scale = ctx.offset_scale
        return EffectParameter("c", "mm", 0.0, -scale, scale, 0.1 * scale)

    def effect(self, ctx, values, location, c):
        column, level = ctx.sensor_names.index(location.detail["sensor"]), location.detail["level"]
        return Effect(corrections=(lambda R: apply_gauge_slip(R, column, level, c),))


def apply_gauge_slip(R, column, level, value):
    """Readings ``R`` ``(n_loads, n_sensors)`` with ``value`` (mm) added to one column from row
    ``level`` on (a slip between load levels ``level − 1`` and ``level``)."""
    R = np.array(R, dtype=float)
    R[level:, column] += value
    return R


def _flat_jack_reason(ctx):
    sc = ctx.scenario
    if sc.name != "flat_jack":
        return f"the {sc.name} scenario has no flat jacks"
    if sc.options.release != "nominal":
        return "a flat jack with release = 'exact' has no fixed load patterns to act on"
    return None


def _jack_locations(ctx):
    """'all jacks' and, with several jacks, each one (jack indices in ``detail['jacks']``)."""
    slots = ctx.scenario.slots
    out = [Location("all jacks", "every jack (one efficiency for all)", {"jacks": list(range(len(slots)))})]
    if len(slots) > 1:
        out += [Location(f"jack {s.name}", f"jack {s.name} ({s.orientation} slot at {s.at:g} mm)", {"jacks": [i]})
                for i, s in enumerate(slots)]
    return out


class JackEfficiency(Candidate):
    name = "jack_efficiency"
    description = ("A flat jack whose efficiency Km (effective / gauge pressure) differs from the value "
                   "the base model fixes (calibration off, a worn or deformed jack): the jack's load "
                   "scales by Km / Km₀.")
    signature = ("Every reading's response to that jack's pressure steps scales by one factor: "
                 "largest where that jack's pressure changes, none from the in-situ release.")

    def not_applicable(self, ctx):
        reason = _flat_jack_reason(ctx)
        if reason is not None:
            return reason
        if "Km" in ctx.free:
            return "Km is a free parameter of the base model"
        return None

    def locations(self, ctx):
        return _jack_locations(ctx)

    def parameter(self, ctx, location):
        k0 = ctx.values["Km"]
        # Km of a sound jack is 0.7–0.95 (calibrations per ASTM C1196/RILEM MDT.D.4); 0.4–1.2 covers a bad one
        return EffectParameter("Km", "-", k0, min(0.4, k0), max(1.2, k0), 0.8 * k0)

    def effect(self, ctx, values, location, c):
        jacks = location.detail["jacks"]
        if len(jacks) == len(ctx.scenario.slots):  # every jack: the model's own Km
            return Effect(values={"Km": c})
        # one jack: its own load pattern (column 1 + j) once more, weighted by c / Km − 1
        columns = [1 + j for j in jacks]
        patterns = ctx.scenario.model.load_patterns

        def jack_patterns():
            out = np.zeros_like(patterns)
            out[:, columns] = patterns[:, columns]
            return out

        return Effect(extra_loads=((("jack", location.key), jack_patterns, c / values["Km"] - 1.0),))


class SlotContact(Candidate):
    """Jack pressure lost over part of the slot.

    INFERRED choices (named options, ``docs/references.md``): the lost contact sits at an end of the jack's loaded length
    ``Ka × slot length`` (``"start"``: the end at the slot's smaller coordinate, ``"end"``: the
    other, ``"both"``: the same length ℓ at both ends, i.e. a jack shorter than the slot or a slot
    not cut to full depth at its ends); the pressure there is zero (no partial contact) and the
    rest of the jack carries the gauge pressure × Km unchanged, so the jack's resultant drops by
    ``Km p ℓ t`` per lost end (t the wall thickness). The parameter is ℓ in mm, up to 90 % of the
    jack length.
    """

    name = "slot_contact"
    description = ("A flat jack that does not bear on the whole slot: no contact over a length ℓ at one "
                   "end or both (a jack shorter than the slot, a slot cut short or uneven, a crumbled end), "
                   "so its resultant is Km p (L − ℓ) t instead of Km p L t.")
    signature = ("Near the slot end that lost contact the slot closes as if unloaded; the readings there "
                 "move against the jack's pressure, in proportion to it; far sensors barely change.")

    #: the largest contact loss, share of the jack length (a choice)
    max_share = 0.9

    def not_applicable(self, ctx):
        return _flat_jack_reason(ctx)

    def locations(self, ctx):
        out = []
        for i, s in enumerate(ctx.scenario.slots):
            axis = "x" if s.axis == 0 else "y"
            lo, hi = s.jack_interval
            for side, where in (("start", f"its {axis} = {lo:g} mm end"), ("end", f"its {axis} = {hi:g} mm end"),
                                ("both", "both ends")):
                out.append(Location(f"{s.name} {side}", f"jack {s.name}: no contact at {where}",
                                    {"jack": i, "slot": s.name, "side": side, "axis": axis, "interval": [lo, hi]}))
        return out

    def parameter(self, ctx, location):
        lo, hi = location.detail["interval"]
        upper = self.max_share * (hi - lo) / (2.0 if location.detail["side"] == "both" else 1.0)
        return EffectParameter("l", "mm", 0.0, 0.0, upper, 0.3 * upper, one_sided=True)

    def lost_pattern(self, scenario, location, loss):
        """Nodal forces (N) of a unit jack pressure over the part(s) of the jack that lost contact."""
        lo, hi = location.detail["interval"]
        slot, side = location.detail["slot"], location.detail["side"]
        f = np.zeros(scenario.mesh.n_dofs)
        if side in ("start", "both"):
            f += scenario.jack_pattern(slot, (lo, lo + loss))
        if side in ("end", "both"):
            f += scenario.jack_pattern(slot, (hi - loss, hi))
        return f

    def effect(self, ctx, values, location, c):
        if c <= 0.0:
            return Effect()
        sc = ctx.scenario
        n_dofs, n_patterns = sc.model.load_patterns.shape

        def lost_patterns():  # the lost pressure under the jack's load coefficient (column 1 + jack)
            out = np.zeros((n_dofs, n_patterns))
            out[:, 1 + location.detail["jack"]] = self.lost_pattern(sc, location, c)
            return out

        return Effect(extra_loads=((None, lost_patterns, -1.0),))  # None: not cached (ℓ varies in the fit)


class NonlinearityOnset(Candidate):
    """Joints that began to crack or slide: the linear model fails from some load level on.

    How it is computed (see :mod:`podkrig.diagnosis.nonlinear_runs` for the nonlinear twin, the
    strength scale ``s`` and the elastic onset strength ``S(F)``):

    1. At the reference values (the calibrated base model's, :attr:`FEContext.base_values`) an
       elastic twin run gives ``S`` at the top force, ``S_n``; a **strength scan** runs the twin at
       ``s_j = S_n ρ^j`` (``ρ = scan_ratio``) downwards until every load level departs visibly, or
       the panel no longer carries the top force (then ``failure_bisections`` bisections in
       ``log s`` towards that strength, where the departure grows fastest), or ``max_scan`` runs.
       Each run gives the **departure** ``D(s) = R_nl(s) − R_el`` of the readings at the linear scenario's force
       levels (interpolated on the force–readings path: the twins are displacement controlled).
    2. A level *departs visibly* when some reading there moves by more than ``visible`` × the
       largest elastic reading (INFERRED option, ``docs/references.md``; 1 %: the noise of the trials, about the spread
       of two sound discretisations).
       The **location** is the first departing level ``k`` (the onset level): the scan strengths
       whose first departing level is ``k`` form its range, disjoint from the other levels'. Its
       label names the load level and the joints where the elastic tractions first reach the
       criterion at that level.
    3. The **parameter** is the joints' tensile strength ``ft_bj = s ft₀`` (MPa; ``c``, ``f_c`` and
       the fracture energies follow the strength scale), over the location's range and up to the
       next scan strength above it, which is the neutral value (the effect is off there by
       definition: readings bit-identical to the linear model's). ``D`` is interpolated linearly in ``log s`` between scan
       strengths and blended to zero at the neutral end (the blend is an approximation for
       ``k`` below the top level, where the next strength already departs at higher levels).
    4. Readings are ``R_lin(values) + D(s)``: the base parameters move the linear model while the
       departure stays that of the reference values (the cheaper fit parametrisation: a 1-D scan
       of the strength with the base parameters held at the linear fit), so the ~60 evaluations
       per refit cost no nonlinear run.

    Cost: 1 elastic probe + 1 elastic reference + up to ``max_scan`` nonlinear runs once per
    diagnosis (per set of reference values).
    """

    name = "nonlinearity_onset"
    description = ("Joints that began to crack or slide under the higher loads: the data from some load "
                   "level on depart from the calibrated linear model as the nonlinear joint model "
                   "(Lourenço–Rots: tension cut-off, Coulomb friction, cap) with reduced strengths predicts.")
    signature = ("Nothing below the onset level; from it on a departure growing faster than the load, "
                 "largest at sensors across the joints that crack or slide first (the tensile diagonal, "
                 "joints near the loaded corners).")

    expensive = True
    #: ratio of consecutive scan strengths, largest number of scan runs, visibility threshold
    scan_ratio = 0.9
    max_scan = 24
    #: bisections of the strength between the last scan strength whose panel carries the top force
    #: and the first that does not (the departure grows fastest just before failure)
    failure_bisections = 3
    visible = 0.01

    def not_applicable(self, ctx):
        reason = counterpart_reason(ctx.scenario)
        if reason is None and not self.locations(ctx):
            top = ctx.scenario.load_levels[-1]
            reason = (f"no joint strength makes the readings depart by {100 * self.visible:g} % of the largest "
                      f"reading before the panel fails below the top load {top:g} {ctx.scenario.load_unit} "
                      "(the scan at the base model's values)")
        return reason

    def _scan(self, ctx):
        """The strength scan at the reference values (cached in the context)."""
        ref = ctx.reference_values
        key = ("onset scan", tuple(sorted(ref.items())))
        if key in ctx._cache:
            return ctx._cache[key]
        if "onset twin" not in ctx._cache:
            ctx._cache["onset twin"] = NonlinearTwin(ctx.scenario)
        twin = ctx._cache["onset twin"]
        runs_before = twin.runs
        elastic = twin.run(ref, ELASTIC_SCALE, record_states=True)
        S_steps, ratios = onset_strength(twin, ref, elastic)
        S_env = np.maximum.accumulate(S_steps)
        forces = twin.forces
        S_levels = np.interp(forces, elastic.loads, S_env)
        level_steps = [int(np.argmin(np.abs(elastic.loads - f))) for f in forces]
        tol = self.visible * float(np.max(np.abs(elastic.readings)))
        strengths, departures, first = [], [], []
        n = len(forces)
        s, failed, bisections = float(S_levels[-1]), None, 0
        while len(strengths) + bisections < self.max_scan:
            run = twin.run(ref, s)
            if run.reached.all():
                D = run.readings - elastic.readings
                visible = np.flatnonzero(np.max(np.abs(D), axis=1) > tol)
                k = int(visible[0]) if len(visible) else n
                k = min(k, first[-1]) if first else k  # weaker joints never depart later
                strengths.append(s)
                departures.append(D)
                first.append(k)
                if k == 0:
                    break
            else:  # the panel no longer carries the top force: refine towards that strength
                failed = s
            bisections += failed is not None
            if failed is None:
                s *= self.scan_ratio
            elif bisections > self.failure_bisections or not strengths:  # the failing run counts too
                break
            else:
                s = float(np.sqrt(strengths[-1] * failed))
        ft0 = twin.reference.resolve()["ft_bj"]
        scan = {"strengths": np.array(strengths), "departures": np.array(departures), "first": np.array(first),
                "ratios": ratios, "level_steps": level_steps, "ft0": ft0, "twin": twin,
                "S_levels": S_levels}
        ctx._cache[key] = scan
        ctx.n_runs += twin.runs - runs_before
        return scan

    def locations(self, ctx):
        scan = self._scan(ctx)
        sc = ctx.scenario
        levels, unit = sc.load_levels, sc.load_unit
        out = []
        for k in sorted(set(scan["first"].tolist()) - {len(levels)}):
            nodes = np.flatnonzero(scan["first"] == k)
            upper = nodes[0] - 1  # the next stronger scan strength (neutral end)
            if upper < 0:
                continue
            joints = critical_joints(scan["twin"], scan["ratios"], scan["level_steps"][k])
            where = "; ".join(f"{j['kind']} joint at ({j['x']:g}, {j['y']:g}) mm" for j in joints)
            below = f"{levels[k - 1]:g}" if k > 0 else "0"
            out.append(Location(
                f"from {levels[k]:g} {unit}",
                f"joints crack or slide from load level {levels[k]:g} {unit} on (linear up to {below} {unit}); "
                f"first at {where}",
                {"level": k, "load": float(levels[k]), "unit": unit, "joints": joints,
                 "twin": scan["twin"].reference.name, "twin_ignores": list(scan["twin"].dropped_options),
                 "nodes": [int(i) for i in nodes], "neutral_node": int(upper)}))
        return out

    def parameter(self, ctx, location):
        scan = self._scan(ctx)
        s, ft0 = scan["strengths"], scan["ft0"]
        nodes = location.detail["nodes"]
        upper, lower = ft0 * s[location.detail["neutral_node"]], ft0 * s[nodes[-1]]
        return EffectParameter("ft_bj", "MPa", upper, lower, upper, float(np.sqrt(lower * upper)),
                               scale="log", one_sided=True)

    def departure(self, ctx, location, ft):
        """Departure of the readings from the linear model ``(n_loads, n_sensors)`` mm at the joints'
        tensile strength ``ft`` (MPa), interpolated in the scan (zero at the neutral end)."""
        scan = self._scan(ctx)
        nodes = location.detail["nodes"]
        x = np.log(scan["strengths"][[location.detail["neutral_node"]] + nodes])[::-1]  # ascending
        D = np.concatenate([np.zeros_like(scan["departures"][:1]), scan["departures"][nodes]])[::-1]
        t = float(np.clip(np.log(ft / scan["ft0"]), x[0], x[-1]))
        i = int(np.clip(np.searchsorted(x, t) - 1, 0, len(x) - 2))
        a = (t - x[i]) / (x[i + 1] - x[i])
        return (1.0 - a) * D[i] + a * D[i + 1]

    def effect(self, ctx, values, location, c):
        """The departure from the linear model, added to the readings (computed at the reference
        values and superposed on whatever other causes the model holds: a first-order combination)."""
        if c >= self.parameter(ctx, location).neutral * (1.0 - 1e-12):  # off (to the fit coordinate's round-off)
            return Effect()
        departure = self.departure(ctx, location, c)
        return Effect(corrections=(lambda R: R + departure,))


class WeakJointStrength(Candidate):
    """One bed joint of a specimen with a weaker bond than the other(s): its tensile strength and
    cohesion × s (the scenario option ``joint_strength_factors``, e.g. of ``triplet_shear``).

    The joints of a triplet shear side by side under one slip, so the force is the sum of the two
    joints' shear resistances: the weaker joint peaks first and softens while the other still
    rises, so the peak lies between ``2 A (s c + σ tanφ)`` and ``A ((1 + s) c + 2 σ tanφ)``, below
    the sound triplet's, and the softening is slower (``GfII`` unchanged over a smaller c) towards
    the same residual friction. A lower cohesion of both joints absorbs most of this: what it
    cannot is the shape of the peak and of the softening (docs/diagnosis.md says when that shows).
    """

    name = "weak_joint_strength"
    description = ("One bed joint of the specimen weaker than the other: its bond (tensile strength f_t and "
                   "cohesion c) × s (poor filling or curing, a joint disturbed when the specimen was "
                   "handled); friction, fracture energies and stiffness as the other joint's.")
    signature = ("The force curve only: a lower peak, governed by the weaker joint and broader than one "
                 "joint law gives, and a slower softening towards the same residual friction.")

    #: the weakest bond tried, as a share of the other joint's (a choice: a joint at a fifth of
    #: the other's strength is a broken specimen, not a weaker joint)
    min_factor = 0.2

    def not_applicable(self, ctx):
        factors = getattr(ctx.scenario.options, "joint_strength_factors", None)
        if factors is None:
            return f"the {ctx.scenario.name} scenario has no per-joint strength factors (joint_strength_factors)"
        if tuple(factors) != (1.0,) * len(factors):
            return f"the base model sets joint_strength_factors = {list(factors)} already"
        return None

    def locations(self, ctx):
        sc = ctx.scenario
        n = len(sc.options.joint_strength_factors)
        names = ("lower", "upper") if n == 2 else tuple(f"joint {k + 1}" for k in range(n))
        width, h = float(sc.mesh.width), float(sc.options.unit_height)  # joint k between courses k and k + 1
        return [Location(f"{name} bed joint", f"the {name} bed joint weaker than the other",
                         {"joint": k, "of": n, "x": [0.0, width], "y": [(k + 1) * h, (k + 1) * h]})
                for k, name in enumerate(names)]

    def parameter(self, ctx, location):
        return EffectParameter("s", "-", 1.0, self.min_factor, 1.0, 0.7, one_sided=True)

    def overlaps(self, location, other):
        # both joints weaker is a lower strength of the joints (the base parameters), not this cause
        return True

    def effect(self, ctx, values, location, c):
        if c >= 1.0:
            return Effect()
        factors = [1.0] * location.detail["of"]
        factors[location.detail["joint"]] = float(c)
        return Effect(options={"joint_strength_factors": tuple(factors)})


class Dilatancy(Candidate):
    """Joints that open as they slide (dilatancy tanψ), where the base model keeps ``tanpsi_bj``
    at a fixed value (0 by default: no dilatancy).

    The range is ``[tanψ₀, min(tanφ0, tanφr)]``, both friction coefficients at the lowest value
    the base model gives them (their lower bounds when free): the interface laws admit no more
    dilatancy than friction (the composite law's ``tanψ ≤ tanφ0``; the hyperbolic law's
    ``tanψ ≤ min(tanφ0, tanφr)``, the stricter of the two, here for both).
    """

    name = "dilatancy"
    description = ("Joints that dilate as they slide (tanψ > 0): the rough, interlocked mortar–unit "
                   "interface lifts over itself, where the base model keeps tanψ fixed (0: no dilatancy).")
    signature = ("Gauges across a sliding joint open in proportion to the slip after the peak; under a "
                 "held normal stress the force barely changes.")

    def not_applicable(self, ctx):
        if "tanpsi_bj" not in ctx.values:
            return f"the {ctx.scenario.name} scenario has no dilatancy parameter (tanpsi_bj)"
        if "tanpsi_bj" in ctx.free:
            return "tanpsi_bj is a free parameter of the base model"
        if self._upper(ctx) <= ctx.values["tanpsi_bj"]:
            return "the friction coefficients admit no more dilatancy than the base model's tanpsi_bj"
        return None

    def _upper(self, ctx):
        def lowest(name):
            return ctx.bounds[name][0] if name in ctx.bounds else ctx.values[name]

        return min(lowest("tanphi_bj"), lowest("tanphir_bj"))

    def locations(self, ctx):
        return [Location("all joints", "all joints", {"parameter": "tanpsi_bj"})]

    def parameter(self, ctx, location):
        t0, upper = ctx.values["tanpsi_bj"], self._upper(ctx)
        return EffectParameter("tanpsi_bj", "-", t0, t0, upper, t0 + 0.2 * (upper - t0), one_sided=True)

    def effect(self, ctx, values, location, c):
        return Effect(values={"tanpsi_bj": c})


#: every candidate cause, by name
CANDIDATES = {c.name: c for c in (HeadJointStiffness(), WeakJoint(), SupportCompliance(), GaugeFault(),
                                  LoadEccentricity(), UnitStiffness(), GaugeSlip(), JackEfficiency(),
                                  SlotContact(), NonlinearityOnset(), WeakJointStrength(), Dilatancy())}
#: the candidates a diagnosis tries unless told otherwise: all but the expensive ones
DEFAULT_CANDIDATES = tuple(name for name, c in CANDIDATES.items() if not c.expensive)
