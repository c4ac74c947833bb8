"""In-situ flat-jack shear test run nonlinearly: the block's top bed joint slides under the vertical jacks.

``flat_jack_shear_nl``: the panel, slots, jacks, gauges and elastic phases are those of the linear ``flat_jack``
scenario's ``chisari`` preset (:mod:`fe.scenarios.flat_jack`; a design for this project, INFERRED in the
sense of ``docs/references.md``): a 2080 × 1560 × 120 mm running-bond panel under σ0, jack H in the bed
joint y = 780 and V1, V2 at x = 845 and 1235 cutting a U round a 390 × 195 mm block held only by
its top bed joint (y = 975). Here the joints carry the nonlinear interface law of the nonlinear
walls (:mod:`fe.scenarios.nonlinear`: Lourenço–Rots composite, or the thesis' hyperbolic law with
``law = "hyperbolic"``); units stay elastic. The slot interfaces are absent (cut).

Phases (all on one path, :class:`fe.solvers.nonlinear.PathFollower`):

- ``0a``: σ0 on the top edge of the uncut panel. The panel is cut from the start, its slot faces
  loaded by the traction the removed joints carry (σ0 on the horizontal slot): the uniform state
  of the uncut panel (exactly so, see :mod:`fe.scenarios.flat_jack`). Gauges are zeroed here.
- ``0b``, ``1``, ``2``: the linear scenario's steps, one load-controlled phase each (named
  ``"1:5"`` for step 5, in phase 1): the cut (the slot-face traction released), p_H 0.1 → ``p_H``
  in 0.1 MPa steps with V1 = V2 = 0.05 MPa seating, then V1 = V2 0.10 → ``p_V2`` in 0.05 MPa steps.
  At the defaults (p_H = 1.0, p_V2 = 0.5) these are the linear scenario's steps 1–20, and while the
  joints stay elastic the readings equal its readings (:meth:`FlatJackShearNonlinear.step_readings`).
- ``3``: V2 held at ``p_V2``, V1 raised under indirect displacement control on the block's top
  joint **slip** (its mean tangential jump, positive as V1 pushes the block, mm): the path passes
  the peak (a limit point of the jack pressure) and follows the softening branch. ``load_levels``
  are levels of that slip; the load is the V1 gauge pressure p_V1 (MPa); ``delta_p_V`` = p_V1 −
  p_V2 per level. The reported peak is the critical pressure, refined to the solver's
  ``peak_tolerance`` (:class:`fe.solvers.nonlinear.Peak`).
- ``3'`` (``further_p_H``, optional): for each further p_H, unload V1 to ``p_V2`` (phase
  ``"3'(p_H=…) unload"``: indirect control on V1's opening, where load control stalls, then load
  control), take H to that p_H with the vertical jacks equal (``"3'(p_H=…) p_H"``), then phase 3
  again on the joint as the first slide left it (slip levels counted from the slip at the start of
  the repeat); its p_V1 per level is the extra output ``p_V1(p_H=…)`` and its peak in
  :meth:`FlatJackShearNonlinear.critical_pressures`.

Statics (free-body equilibrium of the block, assuming frictionless jack faces): the block's top joint carries the
normal force Km p_H Ka L_H t and the shear Km (p_V1 − p_V2) Ka h_V t, so sliding starts at
``Δp_V,crit ≈ (L_H/h_V)(c + Km p_H tanφ)/Km`` (= 2(c + p_H tanφ) for Km = 1): an average, which the
shear concentrated at the block's corners and the progressive slip move by 15–25 % (INFERRED);
the simulation is the reference, the estimate a check (:meth:`critical_pressures` gives both).

Range of the set-up: the jack H pushes the wall above it up with Km p_H. Once Km p_H passes about
0.85 MPa at σ0 = 0.30 MPa it lifts the wall beside the block off the
bed joint that continues H's line (open by 1.6 mm over 450 mm at Km p_H = 0.90 MPa at the end of
phase 2, 0.1 mm at 0.80 MPa), and in phase 3 the wall above that crack slides with the block: the
slip snaps back and the run stops ``not_converged``. The readings would no longer be those of the
block's joint; keep Km p_H below about 2 σ0 (``docs/nonlinear.md``, the flat-jack limits).

Defaults: stiffness, Km and σ0 as ``flat_jack`` (E_b = 10 000 MPa, ν_b = 0.15,
kN = 80, kV = 35 N/mm³, r_hj = 0.6), joint strengths typical of old brick masonry (f_t = 0.15, c = 0.25 MPa,
tanφ = 0.70, G_f^I = 0.012, G_f^II = 0.10 N/mm; INFERRED), the residual
friction equal to the initial one and the rest (dilatancy 0, the compressive cap, unit mid-planes)
as the walls' Set A. Units do not crack (no unit mid-plane interfaces, as ``flat_jack``); with
``brick_interfaces = true`` they may, and splitting at the jack ends can then pre-empt sliding (FRP
strengthening there is the usual remedy in the field).
"""

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..exceptions import SpecError
from ..nonlinear_model import NonlinearModel
from ..response import NonlinearResponse
from ..sensors import Gauge, sensor_operator
from .flat_jack import CHISARI_SLOTS, FLAT_JACK_PARAMETERS, LAYOUTS, FlatJack
from .masonry import masonry_parts
from .spec import ScenarioSpec
from .nonlinear import SET_A_STIFFNESS, NonlinearOptions, NonlinearScenario, Phase, nonlinear_parameters

#: defaults (INFERRED): stiffness as ``flat_jack``, joint strengths
#: of the table, residual friction = initial friction (as Set A).
FLAT_JACK_NL_DEFAULTS = {
    **SET_A_STIFFNESS, "E_b": 10000.0, "kN_bj": 80.0, "kV_bj": 35.0, "r_hj": 0.6,
    "ft_bj": 0.15, "c_bj": 0.25, "tanphi_bj": 0.70, "tanphir_bj": 0.70, "GfI_bj": 0.012, "GfII_bj": 0.10,
}

#: largest jack pressure the options accept, MPa: 50 bar, the rating of standard flat jacks (READ, Matest)
MAX_JACK_PRESSURE = 5.0


def _ramp_to(start, stop, step):
    """``start, start + step, …`` below ``stop``, then ``stop`` (MPa, rounded to 1e-10)."""
    n = int(np.floor((stop - start) / step + 1e-9))
    values = [round(start + k * step, 10) for k in range(n + 1)]
    return values if abs(values[-1] - stop) < 1e-9 else values + [round(stop, 10)]


@dataclass(frozen=True)
class FlatJackShearOptions(NonlinearOptions):
    """Options of ``flat_jack_shear_nl`` (lengths mm, pressures MPa; see the module docstring).

    Panel and mesh as ``flat_jack`` (``refine``: the twice-finer window; ``layout``: L6, L18, DIC,
    L6+DIC or L18+DIC; ``sensors`` adds gauges to the layout). ``p_H``: the horizontal jack's
    pressure reached in phase 1 and held after; ``p_V2``: the vertical jacks' pressure reached in
    phase 2, then held in V2 (and V1's start in phase 3); ``further_p_H``: the p_H of the repeats
    3'. ``load_levels``: levels of the block's top-joint slip, mm; ``increment``,
    ``max_increment``: of that slip, mm.
    """

    unit_length: float = 260.0
    unit_height: float = 65.0
    n_courses: int = 24
    units_per_course: float = 8.0
    thickness: float = 120.0
    nx: int = 2
    ny: int = 1
    brick_interfaces: bool = False
    refine: tuple = (650.0, 1430.0, 585.0, 1170.0)
    layout: str = "L18"
    p_H: float = 1.0
    p_V2: float = 0.5
    further_p_H: tuple = ()
    load_levels: tuple = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5)
    increment: float = 0.002
    max_increment: float = 0.02

    def __post_init__(self):
        super().__post_init__()
        if self.layout not in LAYOUTS or self.layout == "standard":
            raise ValueError(f"layout must be one of {[v for v in LAYOUTS if v != 'standard']}; got {self.layout!r}")
        if not 0.1 <= self.p_H <= MAX_JACK_PRESSURE:
            raise ValueError(f"p_H (horizontal jack pressure) must be in [0.1, {MAX_JACK_PRESSURE:g}] MPa; got {self.p_H}")
        if not 0.1 <= self.p_V2 <= MAX_JACK_PRESSURE:
            raise ValueError(f"p_V2 (vertical jacks' pressure after phase 2) must be in [0.1, {MAX_JACK_PRESSURE:g}] "
                             f"MPa; got {self.p_V2}")
        for p in self.further_p_H:
            if isinstance(p, bool) or not isinstance(p, (int, float)) or not 0 < p <= MAX_JACK_PRESSURE:
                raise ValueError(f"further_p_H (horizontal jack pressures of the repeats 3') must be numbers in "
                                 f"(0, {MAX_JACK_PRESSURE:g}] MPa; got {self.further_p_H}")
        object.__setattr__(self, "further_p_H", tuple(float(p) for p in self.further_p_H))

    def schedule(self):
        """Phases 0b, 1 and 2 in the form of ``flat_jack``'s ``schedule`` option."""
        return (
            {"name": "0b", "steps": [{}]},
            {"name": "1", "steps": [{"H": p, "V1": 0.05, "V2": 0.05} for p in _ramp_to(0.1, self.p_H, 0.1)]},
            {"name": "2", "steps": [{"V1": p, "V2": p} for p in _ramp_to(0.10, self.p_V2, 0.05)]},
        )


@dataclass(frozen=True)
class CriticalPressure:
    """The critical jack pressure of one shear phase (3 or a repeat 3').

    ``p_H``, ``p_V2``: held pressures; ``p_V1``: V1's gauge pressure at the peak; ``delta_p_V``
    = p_V1 − p_V2; ``slip``: the top joint's mean slip there (mm, since the start of the test);
    ``resolved``: the peak met the solver's ``peak_tolerance``; ``statics``: the estimate
    (L_H/h_V)(c + Km p_H tanφ)/Km of Δp_V,crit (MPa; for a virgin joint: ``c_bj``, ``tanphi_bj``);
    ``ratio`` = delta_p_V / statics. All pressures are gauge pressures, MPa.
    """

    phase: str
    p_H: float
    p_V2: float
    p_V1: float
    delta_p_V: float
    slip: float
    resolved: bool
    statics: float

    @property
    def ratio(self):
        return self.delta_p_V / self.statics

    def to_dict(self):
        return {**dataclasses.asdict(self), "ratio": self.ratio}


class FlatJackShearNonlinear(NonlinearScenario):
    """Flat-jack shear test: phases 0a–2 of ``flat_jack`` then sliding of the block's top bed joint
    (phase 3, and the repeats 3'); see the module docstring.

    ``linear`` is the linear ``flat_jack`` scenario of the same panel (its mesh, slots, gauges,
    steps and load patterns are this scenario's); ``steps`` its steps 0b–2."""

    name = "flat_jack_shear_nl"
    summary = ("In-situ flat-jack shear test: after the elastic flat-jack phases, one vertical jack pushes "
               "the block until its top bed joint slides, up to and past the critical jack pressure.")
    Options = FlatJackShearOptions
    PARAMETERS = nonlinear_parameters(FLAT_JACK_NL_DEFAULTS) + FLAT_JACK_PARAMETERS[-2:]  # + Km, sigma0
    force_unit = "MPa"
    force_sensor = "p_V1"  # the load is V1's gauge pressure: a reading (the pump's pressure transducer)

    def _build(self):
        o = self.options
        geometry = ("unit_length", "unit_height", "n_courses", "units_per_course", "thickness", "bond", "nx", "ny",
                    "element", "brick_interfaces", "continuum", "refine", "layout")
        options = {k: getattr(o, k) for k in geometry}
        options.update(preset="chisari", schedule=o.schedule(), sensors=o.sensors)
        try:
            self.linear = linear = FlatJack(ScenarioSpec("flat_jack", options), solver=self._solver_name)
        except SpecError as e:
            raise SpecError(str(e).replace("flat_jack:", f"{self.name}:")) from e
        self.mesh, self.sensors, self.slots, self.steps = linear.mesh, linear.sensors, linear.slots, linear.steps
        self.supported_nodes, self.tie_groups = linear.supported_nodes, linear.tie_groups
        kept = np.sort(np.concatenate([linear.joint_part_elements(k) for k in ("bed", "head", "brick")]))
        T = linear.model.transform
        self.model = NonlinearModel(self.mesh, masonry_parts(self.mesh, o.thickness)[:2], kept, o.thickness, T,
                                    self.sensors, solver=self._solver_name, integration=o.integration)
        rhs = linear.model.rhs  # reduced: release (σ0 = 1), each jack at 1 MPa, σ0 = 1 on the top
        self._release, self._top = rhs[:, 0], rhs[:, -1]
        self._jack = {s.name: rhs[:, 1 + i] for i, s in enumerate(self.slots)}
        self._top_joint = self._block_top_joint()
        self._slip = self._slip_constraint()
        V1 = next(s for s in self.slots if s.name == "V1")
        y = 0.5 * (V1.start + V1.end)  # the opening of V1's slot at mid-height, over the units beside it
        opening = Gauge("V1_opening", (V1.at - 0.375 * o.unit_length, y), (V1.at + 0.375 * o.unit_length, y))
        self._v1_opening = (sensor_operator(self.mesh, [opening])[0] @ T).toarray().ravel()

    def _load_readings(self):
        """``p_V1`` (MPa, V1's gauge pressure at each slip level of phase 3), then ``p_V1_repeat1``, … for
        the repeats 3' (their p_V1 at the same slips counted from the repeat's start), then ``F_peak``
        (the critical p_V1 of phase 3, MPa) and ``d_peak`` with the option ``peak_readings``."""
        out = {self.force_sensor: ("MPa", {"kind": "force", "unit": "MPa",
                                           "at": "jack V1: its gauge pressure, the load of phase 3"})}
        for k, p_H in enumerate(self.options.further_p_H, start=1):
            out[repeat_reading(k)] = ("MPa", {"kind": "force", "unit": "MPa",
                                                "at": f"jack V1 in the repeat 3' at p_H = {p_H:g} MPa: its gauge "
                                                      "pressure, slip counted from the repeat's start"})
        out.update({k: v for k, v in super()._load_readings().items() if k != self.force_sensor})
        return out

    # --- geometry of the block ----------------------------------------------------------------------

    def _block_top_joint(self):
        """Integration points (indices into the model's points) of the block's top bed joint."""
        H, V1 = (next(s for s in self.slots if s.name == n) for n in ("H", "V1"))
        mesh, model = self.mesh, self.model
        conn = mesh.interfaces[model.interface_elements]
        xy = mesh.nodes[conn[:, : conn.shape[1] // 2]]
        on = (np.all(np.abs(xy[:, :, 1] - V1.end) < 1e-6, axis=1) & (xy[:, :, 0].min(axis=1) >= H.start - 1e-6)
              & (xy[:, :, 0].max(axis=1) <= H.end + 1e-6))
        ppe = model.n_points_per_element
        return (np.flatnonzero(on)[:, None] * ppe + np.arange(ppe)).ravel()

    def _slip_constraint(self):
        """``c`` with ``c · q`` = the mean slip of the block's top joint (mm), positive when the block
        moves towards V2 (+x) relative to the wall above, as V1 pushes it."""
        model, pts = self.model, self._top_joint
        w = model.weights.ravel()[pts]
        c = np.asarray(model.jump_operator[2 * pts + 1].T @ w).ravel() / w.sum()
        # orientation: the units below the joint moved by +1 mm in x slide the block forwards
        mesh = self.mesh
        below = mesh.quads[mesh.nodes[mesh.quads].mean(axis=1)[:, 1] < next(s for s in self.slots if s.name == "V1").end]
        u = np.zeros((mesh.n_nodes, 2))
        u[np.unique(below), 0] = 1.0
        return c * np.sign(c @ (model.transform.T @ u.ravel()))

    def _v1_compliance(self, values):
        """Reduced displacements (mm) of the elastic cut panel under V1 at 1 MPa gauge pressure."""
        linear = self.linear
        theta = linear.theta(values)
        return linear.model.solve(theta, rhs=values["Km"] * self._jack["V1"][:, None])[:, 0]

    def top_joint_forces(self, follower):
        """Normal compression and shear force (N) that the block's top joint carries in the
        follower's current converged state: ``(N, T)``, ``T`` positive along the slip."""
        model, pts = self.model, self._top_joint
        w = model.weights.ravel()[pts]
        t = follower.state.traction[pts]
        sign = np.sign(self._slip @ (model.jump_operator[2 * pts + 1].T @ w))
        return float(-w @ t[:, 0]), float(sign * (w @ t[:, 1]))

    def jack_forces(self, values, pressures):
        """Forces of the jacks on the block (N) for gauge ``pressures`` (jack → MPa): the H jack's
        push on the block's bottom face ``Km p_H Ka L_H t`` and the net push of the vertical jacks
        ``Km (p_V1 − p_V2) Ka h_V t``; by the block's equilibrium, :meth:`top_joint_forces`."""
        s = {sl.name: sl for sl in self.slots}
        t, Km = self.options.thickness, values["Km"]
        return (Km * pressures["H"] * s["H"].Ka * s["H"].length * t,
                Km * (pressures["V1"] * s["V1"].Ka * s["V1"].length - pressures["V2"] * s["V2"].Ka * s["V2"].length) * t)

    # --- loading --------------------------------------------------------------------------------------

    def _load(self, values, pressures):
        """Reduced external load (N) with the slots cut and the gauge ``pressures`` in the jacks."""
        f = values["sigma0"] * self._top
        for name, p in pressures.items():
            f = f + values["Km"] * p * self._jack[name]
        return f

    def phases(self, values, follower=None, issued=None):
        """The loading phases, generated as the run goes (see the module docstring).

        The repeats 3' start from where ``follower`` (the :class:`PathFollower` running them; needed
        only with ``further_p_H``) is, its slip and load; ``issued`` (a list)
        collects the phases as they are generated. The path parameter λ of the elastic steps is a
        step counter (step k of the schedule ends at λ = k + 1, 0a at λ = 1) except that the last
        one ends at λ = p_V1, so that phase 3's λ is V1's gauge pressure.
        """
        issued = [] if issued is None else issued

        def emit(phase):
            issued.append(phase)
            return phase

        o = self.options
        sigma0 = values["sigma0"]
        f_pre = sigma0 * (self._top - self._release)  # the uncut panel's state: the slots carry σ0
        yield emit(Phase("0a", "load", target=1.0, increment=1.0, f_const=np.zeros_like(f_pre), f_ref=f_pre, levels=(1.0,)))
        previous, lam = f_pre, 1.0
        for k, step in enumerate(self.steps, start=1):
            now = self._load(values, step.pressures)
            target = float(k + 1) if k < len(self.steps) else step.pressures["V1"]
            f_ref = (now - previous) / (target - lam)
            yield emit(Phase(f"{step.phase}:{k}", "load", target=target, increment=abs(target - lam),
                             f_const=previous - lam * f_ref, f_ref=f_ref, levels=(target,)))
            previous, lam = now, target
        pressures = dict(self.steps[-1].pressures)
        push = values["Km"] * self._jack["V1"]
        yield emit(Phase("3", "indirect", target=o.load_levels[-1], increment=o.increment,
                         f_const=previous - pressures["V1"] * push, f_ref=push, c=self._slip, levels=o.load_levels))
        for p_H in o.further_p_H:
            # unload V1 to p_V2 at the held p_H under indirect control on the opening of V1's slot
            # (gauge G3's line: monotone in V1's pressure, where load control stalls at a reverse
            # slip of the joint), to the opening an elastic unloading would reach; then load control
            # to exactly p_V2 and on, with the vertical jacks equal, to the new p_H (λ a path
            # coordinate there: from p_V2 + 1 back to p_V2)
            name = f"3'(p_H={p_H:g})"
            lam = follower.lam
            end = issued[-1].f_const + lam * push
            opening = self._v1_opening
            target = float(opening @ follower.q - (lam - o.p_V2) * (opening @ self._v1_compliance(values)))
            yield emit(Phase(f"{name} unload", "indirect", target=target,
                             increment=0.25 * abs(target - opening @ follower.q), f_const=issued[-1].f_const,
                             f_ref=push, c=opening, levels=(target,)))
            lam, end = follower.lam, issued[-1].f_const + follower.lam * push
            pressures.update(V1=o.p_V2)
            unloaded = self._load(values, pressures)
            pressures.update(H=p_H)
            start = self._load(values, pressures)
            for label, a, b, f_a, f_b in ((f"{name} unload", lam, o.p_V2 + 1.0, end, unloaded),
                                          (f"{name} p_H", o.p_V2 + 1.0, o.p_V2, unloaded, start)):
                f_ref = (f_b - f_a) / (b - a)
                yield emit(Phase(label, "load", target=b, increment=abs(b - a) / 2, f_const=f_a - a * f_ref,
                                 f_ref=f_ref, levels=(b,)))
            s0 = float(self._slip @ follower.q)
            yield emit(Phase(name, "indirect", target=s0 + o.load_levels[-1], increment=o.increment,
                             f_const=start - o.p_V2 * push, f_ref=push, c=self._slip,
                             levels=tuple(s0 + v for v in o.load_levels)))

    def run(self, params=None, *, field=False, settings=None):
        """Follow phases 0a–3 (and 3'); returns a :class:`~fe.response.NonlinearResponse` at the slip
        levels of phase 3 (load: V1's gauge pressure, MPa) whose ``extra`` holds ``delta_p_V``
        (p_V1 − p_V2, MPa) at those levels and ``p_V1(p_H=…)`` of each repeat 3' at the same slips
        counted from the repeat's start. ``settings`` overrides the options' path settings."""
        values = self.resolve(params)
        o = self.options
        follower = self.path_follower(values, settings, field)
        issued = []
        path = follower.run(self.phases(values, follower, issued))
        repeats = {}  # the p_V1 of each repeat 3' at its slip levels (not the unloading before it)
        for ph, p_H in zip([ph for ph in issued if ph.name.startswith("3'") and ph.name.endswith(")")],
                           o.further_p_H):
            repeats[p_H] = _at_levels(path, ph.name, ph.levels[0] - o.load_levels[0], o.load_levels)
        nan = np.full(len(o.load_levels), np.nan)
        columns = {repeat_reading(k): repeats.get(p_H, nan) for k, p_H in enumerate(o.further_p_H, start=1)}
        response = self._response(path, "3", field, columns)
        extra = {"delta_p_V": response.loads - o.p_V2}
        extra.update({f"p_V1(p_H={p_H:g})": repeats.get(p_H, nan) for p_H in o.further_p_H})
        return dataclasses.replace(response, extra=extra)

    # --- results ----------------------------------------------------------------------------------------

    def step_readings(self, response):
        """Readings at the steps of phases 0b–2 relative to the end of phase 0a (gauges zeroed
        before the cut, as ``flat_jack``'s), ``(n_steps, n_channels)`` mm; NaN rows for steps not
        reached."""
        return self._step_readings(response.path)

    def _step_readings(self, path):
        """:meth:`step_readings` from the run's :class:`~fe.solvers.nonlinear.PathResult`."""
        names = np.asarray(path.phase)
        zero = path.readings[np.flatnonzero(names == "0a")[-1]] if (names == "0a").any() else np.nan
        out = np.full((len(self.steps), len(self.model.channel_names)), np.nan)
        for k, step in enumerate(self.steps, start=1):
            idx = np.flatnonzero(names == f"{step.phase}:{k}")
            if len(idx):
                out[k - 1] = path.readings[idx[-1]] - zero
        return out

    def critical_pressures(self, response, params=None):
        """The critical jack pressure of phase 3 and of each repeat 3' (:class:`CriticalPressure`),
        from the refined peaks of the run, with the statics estimate for a virgin joint."""
        values = self.resolve(params)
        o = self.options
        H, V1 = (next(s for s in self.slots if s.name == n) for n in ("H", "V1"))
        L_H, h_V, Km = H.length, V1.length * V1.Ka, values["Km"]
        out = []
        for name, p_H in [("3", o.p_H)] + [(f"3'(p_H={p:g})", p) for p in o.further_p_H]:
            peak = response.path.peaks.get(name)
            if peak is None:
                continue
            statics = L_H / h_V * (values["c_bj"] + Km * p_H * H.Ka * values["tanphi_bj"]) / Km
            out.append(CriticalPressure(name, p_H, o.p_V2, peak.load, peak.load - o.p_V2,
                                        peak.path,
                                        bool(peak.resolved), statics))
        return out


def repeat_reading(k):
    """The name of the reading of V1's gauge pressure in the ``k``-th repeat 3' (k = 1, 2, …; its
    p_H is the k-th of ``further_p_H``)."""
    return f"p_V1_repeat{k}"


def _at_levels(path, phase, origin, levels):
    """The load of ``phase`` where its path value (minus ``origin``) first reaches each level
    (linear interpolation between steps), ``(n_levels,)``; NaN where not reached."""
    mask = path.of_phase(phase)
    value, load = path.path[mask] - origin, path.load[mask]
    out = np.full(len(levels), np.nan)
    for k, level in enumerate(levels):
        hit = np.flatnonzero(value >= level - 1e-9 * max(level, 1.0))
        if not len(hit):
            continue
        i = hit[0]
        if i == 0 or value[i] == value[i - 1]:
            out[k] = load[i]
        else:
            a = (level - value[i - 1]) / (value[i] - value[i - 1])
            out[k] = (1 - a) * load[i - 1] + a * load[i]
    return out


@dataclass(frozen=True)
class FlatJackElasticOptions(FlatJackShearOptions):
    """Options of ``flat_jack_elastic_nl``: those of ``flat_jack_shear_nl`` (panel, mesh, ``layout``,
    ``p_H``, ``p_V2``, the law and the budget); its record ends with phase 2, so the shear phase's
    ``further_p_H`` is refused and its ``load_levels`` are replaced by the step numbers (as in
    ``flat_jack``)."""

    def __post_init__(self):
        super().__post_init__()
        if self.further_p_H:
            raise ValueError(f"further_p_H (repeats of the shear phase) is an option of flat_jack_shear_nl; the "
                             f"elastic record ends with phase 2; got {self.further_p_H}")


class FlatJackElasticNonlinear(FlatJackShearNonlinear):
    """The elastic phases 0b–2 of the flat-jack shear test as their own record.

    The same panel, jacks, gauges and nonlinear joints as :class:`FlatJackShearNonlinear`, run
    through phases 0a–2 only; the response holds the gauges (mm, zeroed at the end of phase 0a) at
    each step of phases 0b, 1 and 2 — load levels are step numbers 1, 2, … as in ``flat_jack`` (20
    at the defaults): :meth:`FlatJackShearNonlinear.step_readings` of the run. It is the log of the
    test's elastic phases, read with the stiffness and the jack efficiency in view; the shear
    phase's log is ``flat_jack_shear_nl``'s, and a study reads the two as two tests of the same wall
    sharing their parameters. Its joints are nonlinear because they are not quite elastic: the head
    joints beside the cut crack when it is made, and the bed joint beyond H's ends opens from p_H ≈
    0.8 MPa (16–18 µm from the linear scenario at p_H = 1.0 MPa; docs/nonlinear.md).
    """

    name = "flat_jack_elastic_nl"
    summary = ("In-situ flat-jack test, its elastic phases (the cut, the horizontal jack, the vertical jacks) "
               "with nonlinear joints: the gauges at each step, the shear phase's partner record.")
    Options = FlatJackElasticOptions
    load_unit = "step"
    load_response = "discrete"  # the steps of a test sequence
    force_sensor = None  # the jack pressures are the steps' own (FlatJack.steps), no reading

    def _load_readings(self):
        return {}

    @property
    def load_levels(self):
        """Step numbers 1, 2, … of phases 0b–2."""
        return np.arange(1.0, len(self.steps) + 1.0)

    def run(self, params=None, *, field=False, settings=None):
        """Follow phases 0a–2; returns a :class:`~fe.response.NonlinearResponse` at the step numbers
        (``loads``: the step numbers; NaN rows for steps not reached; ``reached``: the last step
        reached; ``field``: the nodal displacements at each step's end)."""
        values = self.resolve(params)
        follower = self.path_follower(values, settings, field)
        path = follower.run(ph for ph in self.phases(values) if ph.name.split(":")[0] in ("0a", "0b", "1", "2"))
        readings = self._step_readings(path)
        names = np.asarray(path.phase)
        done = [k for k, step in enumerate(self.steps, start=1) if (names == f"{step.phase}:{k}").any()]
        u = None
        if field and path.displacements is not None:
            u = np.full((len(self.steps), self.mesh.n_nodes, 2), np.nan)
            for k in done:
                u[k - 1] = path.displacements[np.flatnonzero(names == f"{self.steps[k - 1].phase}:{k}")[-1]]
        levels = self.load_levels
        return NonlinearResponse(readings, self.sensor_names, levels, self.load_unit, u, loads=levels.copy(),
                                 force_unit="step", status=path.status, limit=path.limit, message=path.message,
                                 reached=float(done[-1]) if done else 0.0, extra={}, path=path)
