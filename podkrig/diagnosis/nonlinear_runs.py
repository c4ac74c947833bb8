"""Nonlinear counterparts of the linear scenarios, read at the linear scenario's force levels
(the FE work behind the ``nonlinearity_onset`` candidate).

A linear wall scenario (``diagonal_compression``, ``shear_compression``) has a nonlinear twin with
the same mesh, sensors and elastic parameters (:mod:`fe.scenarios.walls_nonlinear`). The twin is
*displacement controlled* (the diagonal test: indirect control on the shoes' mean diagonal
shortening; the shear wall: the top beam's horizontal displacement), so its readings at the linear
scenario's force levels (kN) are **interpolated linearly on the converged force–readings path**
between the two steps that bracket each force (the first crossing). Its control target is chosen
from an elastic probe: ``TARGET_FACTOR`` (1.2) × the elastic control displacement at the top
force, doubled (at most twice) while a softer cracked response still rises below the top force
there; a run has at most ``RUN_STEPS`` increments, ``50 RUN_STEPS`` Newton iterations and
``RUN_CPU_SECONDS`` of CPU time (the wall clock is only the solver's hang guard).

Joint strengths are varied by one **strength scale** ``s`` on the nonlinear scenario's defaults:
``ft_bj``, ``c_bj`` and ``fc`` times ``s``, the fracture energies ``GfI_bj``, ``GfII_bj``,
``Gfc`` times ``s²`` (INFERRED choice, ``docs/references.md``; option "energies ∝ s²": it keeps ``ft²/G_f^I`` and hence the
local-uniqueness margin ``k_n > ft²/G_f^I`` of the defaults, so every ``s`` is admissible;
friction, dilatancy and the units' mid-plane strength ``ft_bb`` stay at their defaults).

The **elastic onset strength** ``S(F)``: the smallest ``s`` for which the elastic joint tractions
at force ``F`` stay inside the Lourenço–Rots surface of the joints, from an elastic run (``s`` = 10³)
whose interface states give the tractions at every Lobatto point: tension cut-off ``σ ≤ s f_t``,
Coulomb friction ``|τ| + σ tanφ ≤ s c``, cap ``σ² + C_s τ² ≤ (s f_c)²`` (σ < 0). With the strengths
scaled together every criterion is homogeneous of degree one in ``s``, so ``S`` is the largest of
the ratios over the bed- and head-joint points; joints with ``s < S(F)`` begin to crack or slide
below ``F`` (an elastic estimate: the path redistributes stresses once the first point yields).
"""

import dataclasses
import logging

import numpy as np

from fe import SCENARIOS, build_scenario
from fe.mesh.mesh import INTERFACE_KINDS

logger = logging.getLogger(__name__)

#: the nonlinear twin of each linear scenario that has one
NONLINEAR_COUNTERPARTS = {"diagonal_compression": "diagonal_compression_nl",
                          "shear_compression": "shear_compression_nl"}
#: strengths scaled by s, fracture energies by s² (see the module docstring)
SCALED_STRENGTHS = ("ft_bj", "c_bj", "fc")
SCALED_ENERGIES = ("GfI_bj", "GfII_bj", "Gfc")
#: strength scale of the elastic reference run: no joint yields at any realistic load
ELASTIC_SCALE = 1e3
#: budget of one nonlinear run: CPU time of the process (s, ``PathSettings.max_cpu_seconds``: it
#: does not shrink when the machine is busy, as wall time would) and attempted increments (a run
#: that has not reached the top force by then counts as a panel that cannot carry it; the elastic
#: path takes ~30); Newton iterations are capped at 50 per increment of the budget
RUN_CPU_SECONDS = 60.0
RUN_STEPS = 80
#: first control target, × the elastic control displacement at the top force
TARGET_FACTOR = 1.2


def counterpart_reason(scenario):
    """Why ``scenario`` has no nonlinear twin here (str), or None."""
    name = scenario.name
    if name not in NONLINEAR_COUNTERPARTS:
        return (f"the {name} scenario has no nonlinear counterpart (nonlinear twins exist for "
                f"{sorted(NONLINEAR_COUNTERPARTS)})")
    if scenario.spec.to_dict().get("continuum"):
        return "a continuum panel (continuum = true) has no joints to crack"
    if np.any(np.diff(scenario.load_levels) <= 0) or scenario.load_levels[0] <= 0:
        return "the load levels must be positive and ascending for an onset level to be defined"
    return None


def counterpart_spec(scenario, target):
    """Spec of the nonlinear twin of ``scenario`` with control target ``target`` (mm), and the
    linear spec's options the twin does not have (dropped: the twin then differs from the linear
    model there, which the departure ``R_nl − R_el`` of the twin's own runs does not see)."""
    spec = dict(scenario.spec.to_dict())
    spec["scenario"] = NONLINEAR_COUNTERPARTS[spec["scenario"]]
    spec.pop("parameters", None)  # values are passed to every run explicitly
    if spec.get("support") == "rigid":  # the twins' supports are the rigid contact: nothing differs
        spec.pop("support")
        spec.pop("support_stiffness", None)
    known = {f.name for f in dataclasses.fields(SCENARIOS[spec["scenario"]].Options)}
    dropped = sorted(k for k in spec if k != "scenario" and k not in known)
    spec = {k: v for k, v in spec.items() if k not in dropped}
    spec["load_levels"] = [float(target)]
    if spec["scenario"] == "shear_compression_nl":
        spec["top"] = "constant_force"  # the linear wall's tied top beam carries a constant N
    return spec, dropped


def scaled_strengths(nl_scenario, s):
    """The nonlinear twin's strength parameters at strength scale ``s`` (dict)."""
    d = nl_scenario.resolve()
    out = {k: s * d[k] for k in SCALED_STRENGTHS}
    out.update({k: s * s * d[k] for k in SCALED_ENERGIES})
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class ForcePath:
    """A nonlinear run read at force levels.

    Attributes
    ----------
    readings : ndarray (n_levels, n_channels)
        Readings at the force levels, mm (the path's last state where a force was not reached).
    reached : ndarray of bool (n_levels,)
    peak : float
        Largest force on the path, kN.
    seconds : float
    states : list or None
        Interface states of the control phase's steps (elastic reference only).
    loads : ndarray
        Force at each step of the control phase, kN (with the state before it first).
    """

    readings: np.ndarray
    reached: np.ndarray
    peak: float
    seconds: float
    states: list | None
    loads: np.ndarray


def readings_at_forces(path, phase, forces):
    """Readings of a :class:`~fe.solvers.nonlinear.PathResult` at ``forces`` (kN), interpolated
    linearly between the two steps of control phase ``phase`` that bracket each force's first
    crossing; the state before the phase (zero load) starts the branch."""
    mask = path.of_phase(phase)
    first = int(np.flatnonzero(mask)[0]) if mask.any() else len(path.load)
    R = np.asarray(path.readings)[mask]
    F = np.asarray(path.load)[mask]
    R0 = np.asarray(path.readings)[first - 1] if first > 0 else np.zeros(R.shape[1] if R.ndim == 2 else 0)
    R = np.vstack([R0[None], R]) if len(R) else R0[None]
    F = np.concatenate([[0.0], F])
    out = np.empty((len(forces), R.shape[1]))
    reached = np.zeros(len(forces), bool)
    for k, f in enumerate(forces):
        hit = np.flatnonzero(F >= f)
        if not len(hit):
            out[k] = R[-1]
            continue
        i = int(hit[0])
        reached[k] = True
        if i == 0 or F[i] == f:
            out[k] = R[i]
        else:
            a = (f - F[i - 1]) / (F[i] - F[i - 1])
            out[k] = (1 - a) * R[i - 1] + a * R[i]
    return out, reached, F


class NonlinearTwin:
    """The nonlinear twin of a linear scenario, run at given elastic values and strength scales.

    ``runs`` counts nonlinear runs, ``seconds`` their wall time.
    """

    def __init__(self, scenario):
        self.linear = scenario
        self.forces = np.asarray(scenario.load_levels, float)
        self.runs, self.seconds = 0, 0.0
        self._twins, self._probes = {}, {}
        #: options of the linear spec the twin does not have (see :func:`counterpart_spec`)
        self.dropped_options = []
        #: the twin with target 1 mm: mesh, model and parameters shared by every target
        self.reference = self._twin(1.0)

    def _twin(self, target):
        key = round(float(target), 9)
        if key not in self._twins:
            spec, self.dropped_options = counterpart_spec(self.linear, key)
            self._twins[key] = build_scenario(spec)
        return self._twins[key]

    def elastic_values(self, values):
        """The twin's parameters among ``values`` (the linear scenario's elastic ones)."""
        names = {p.name for p in self.reference.PARAMETERS}
        return {k: v for k, v in values.items() if k in names}

    def _run(self, target, values, s, record_states=False):
        nl = self._twin(target)
        params = {**self.elastic_values(values), **scaled_strengths(nl, s)}
        settings = nl.options.path_settings(record_states=record_states)
        settings = dataclasses.replace(settings, max_cpu_seconds=RUN_CPU_SECONDS, max_steps=RUN_STEPS,
                                       max_total_iterations=50 * RUN_STEPS)
        r = nl.run(params, settings=settings)
        self.runs += 1
        self.seconds += r.path.seconds
        logger.debug("%s: s = %.4g, target %.3g mm: %s after %d steps, %.2f s", nl.name, s, target, r.status,
                     len(r.path.load), r.path.seconds)
        return nl, r

    def control_per_kN(self, values):
        """Elastic control displacement per kN of force (mm/kN), from a short elastic probe."""
        key = tuple(sorted(values.items()))
        if key not in self._probes:
            nl, r = self._run(0.02 if self.linear.name == "diagonal_compression" else 0.1, values, ELASTIC_SCALE)
            phase = r.path.phase[-1]
            mask = r.path.of_phase(phase)
            F, u = np.asarray(r.path.load)[mask], np.asarray(r.path.path)[mask] * nl.control_sign
            if len(F) < 2:
                raise RuntimeError(f"{nl.name}: the elastic probe did not converge ({r.message})")
            self._probes[key] = float((u[-1] - u[0]) / (F[-1] - F[0]))
        return self._probes[key]

    def run(self, values, s, record_states=False):
        """The twin at elastic ``values`` and strength scale ``s``, read at the force levels (a
        :class:`ForcePath`); the control target grows (×2, twice at most) until the top force is
        reached or the path ends before its target (the panel's peak is below the top force)."""
        target = TARGET_FACTOR * self.control_per_kN(values) * self.forces[-1]
        for attempt in range(3):
            _, r = self._run(target, values, s, record_states)
            phase = r.path.phase[-1] if len(r.path.phase) else ""
            R, reached, F = readings_at_forces(r.path, phase, self.forces)
            if reached.all() or r.status != "converged" or attempt == 2 or F[-1] < F.max():
                break  # reached, failed, or past the panel's peak below the top force
            target *= 2.0
        mask = r.path.of_phase(phase)
        states = [st for st, m in zip(r.path.states, mask) if m] if r.path.states is not None else None
        return ForcePath(R, reached, float(F.max()), r.path.seconds, states, F[1:])


def onset_strength(twin, values, elastic):
    """Elastic onset strength scale ``S`` at every step of an elastic run (``elastic``, a
    :class:`ForcePath` with states), ``(n_steps,)``, and the per-point ratios at each step
    ``(n_steps, n_points)`` (joints only; unit mid-planes 0). See the module docstring."""
    nl = twin.reference
    d = nl.resolve(twin.elastic_values(values))
    model = nl.model
    kinds = np.repeat(nl.mesh.interface_kind[model.interface_elements], model.n_points_per_element)
    bed, head = INTERFACE_KINDS.index("bed"), INTERFACE_KINDS.index("head")
    kn = np.where(kinds == head, d["r_hj"] * d["kN_bj"], d["kN_bj"])
    ks = np.where(kinds == head, d["r_hj"] * d["kV_bj"], d["kV_bj"])
    joint = (kinds == bed) | (kinds == head)
    ratios = []
    for st in elastic.states:
        sig = kn * st["opening"].astype(float)  # tension positive
        tau = np.abs(ks * st["slip"].astype(float))
        r = np.maximum.reduce([sig / d["ft_bj"], (tau + sig * d["tanphi_bj"]) / d["c_bj"],
                               np.where(sig < 0, np.sqrt(sig**2 + d["Cs"] * tau**2), 0.0) / d["fc"]])
        ratios.append(np.where(joint, r, 0.0))
    ratios = np.array(ratios)
    return ratios.max(axis=1), ratios


def critical_joints(twin, ratios, step, share=0.9, limit=4):
    """Where the joints first reach the criterion at a step: up to ``limit`` joints (kind and the
    coordinates of their most loaded point, mm) whose ratio is within ``share`` of the largest."""
    nl = twin.reference
    model = nl.model
    r = ratios[step]
    xy = model.point_coordinates()
    kinds = np.repeat(nl.mesh.interface_kind[model.interface_elements], model.n_points_per_element)
    order = np.argsort(-r)
    out, seen = [], set()
    for p in order:
        if r[p] < share * r[order[0]] or len(out) >= limit:
            break
        element = p // model.n_points_per_element
        if element in seen:
            continue
        seen.add(element)
        out.append({"kind": INTERFACE_KINDS[kinds[p]], "x": round(float(xy[p, 0]), 1), "y": round(float(xy[p, 1]), 1)})
    return out
