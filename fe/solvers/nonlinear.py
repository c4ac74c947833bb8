"""Path-following solver for softening problems: incremental Newton–Raphson on the consistent
tangent with load, displacement or indirect-displacement (arc-length) control.

A run is a sequence of :class:`Phase` objects (e.g. pre-compression under load control, then a
horizontal displacement ramp). In every phase the external load is ``f_const + λ f_ref`` and one
scalar *path parameter* is driven from its current value to ``target``:

- ``"load"``: the path parameter is λ itself;
- ``"dof"``: a reduced dof ``q[dof]`` (displacement control of a loading beam); its row and column
  are held out of the system and the prescribed increment enters the right-hand side; the load is
  the reaction at that dof;
- ``"indirect"``: a linear combination ``c · q`` (indirect displacement control, e.g. the sum of
  the openings of a crack or of chosen dofs) with λ unknown: the bordered Newton step solves
  ``K δq_I = −r`` and ``K δq_II = f_ref`` on one factorisation and chooses δλ so that the constraint
  holds. A monotone crack opening passes snap-backs of the load–displacement curve that
  displacement control cannot (as DIANA's manual remarks on arc-length control).

Further dofs can be ``held`` (zero increment in the phase), e.g. the vertical dof of a loading beam
fixed after pre-compression; their reactions are recorded.

Every iteration re-evaluates the interface law from the last converged state (no history is
updated before a step converges). Newton steps are damped by a backtracking line search on the
residual norm; a step that does not converge within ``max_iterations`` (or whose local return
fails, or whose residual grows a million-fold) is cut back. Every run ends within its
:class:`PathSettings` budget with a status and the converged part of the path.

Step control (``predictor``, ``step_rule``). Newton starts each increment from a prediction along
the path: ``"secant"`` (default) extrapolates the last two converged states of the phase linearly
to the new path value, ``q = q_n + a (q_n − q_{n−1})``, ``λ`` likewise, with
``a = Δ_{n+1} / Δ_n`` [1]_, and evaluates the interface law there, so that the first iteration
already uses the tangent of the cracks and slips the step is heading into; ``"tangent"`` (the
earlier behaviour) starts from the converged state with its consistent tangent. After a failed
increment the retry uses the tangent predictor. A prediction already within the force tolerance
is accepted without iterating. The next increment follows the Newton iterations of the last
ones: ``"easy_steps"`` (default) grows it by ``growth`` after two steps of at most
``easy_iterations``; ``"iterations"`` scales it by ``clip(√(easy_iterations / n), cutback,
growth)`` after a step of ``n`` iterations, the classical rule of Crisfield [2]_. On the coarse
J4D walls the secant predictor with ``"easy_steps"`` failed fewest increments and iterated least
(``scripts/bench_nonlinear_peaks.py``); the failures left are at the cracking events where
displacement control needs its detour.

Peaks (``peak_tolerance``). In every displacement- or indirectly controlled phase a load maximum
is bracketed by three consecutive converged steps a, b, c (b highest). Were the load concave
there, its maximum could exceed F_b by at most the larger secant extrapolation,
``(F_b − F_a)(v_c − v_b)/(v_b − v_a)`` or ``(F_b − F_c)(v_b − v_a)/(v_c − v_b)``. At the end of
the phase the brackets are refined in the order of that bound while it exceeds the largest load
found so far (at most ``max_peak_steps`` increments per phase), on a side path that leaves the
recorded steps, and so the readings at the output levels, untouched: from the state at the
bracket's start the bracket is re-followed in four equal increments (Newton to
``peak_newton_tolerance``), the bracket shrinks to the two sub-steps around the highest state,
and so on until the load changes by at most ``peak_tolerance`` × load between the highest state
and both its neighbours (or the bracket is narrower than the smallest increment). For a smooth
maximum the true peak then exceeds the reported one by at most a quarter of that change (a
parabola through equally spaced points), at a kink by at most the change. A refined maximum
replaces a recorded one unless lower by more than the tolerance (a recorded load carries the
error of the looser ``tolerance``). The result is ``PathResult.peaks[phase]`` (:class:`Peak`);
``Peak.resolved`` says whether the tolerance was met.

References
----------
.. [1] Kadapa, C. (2021). A simple extrapolated predictor for overcoming the starting and
   tracking issues in the arc-length method for nonlinear structural mechanics. Engineering
   Structures 234.
.. [2] Crisfield, M. A. (1991). Non-linear Finite Element Analysis of Solids and Structures,
   Vol. 1, §9.5 (automatic increments from the number of iterations). Wiley.

The budget counts what a run costs, not how busy the machine is: attempted increments
(``max_steps``), Newton iterations (``max_total_iterations``) and the CPU time of the process
(``max_cpu_seconds``, :func:`time.process_time`: every thread of the process, e.g. the sparse
solver's, so a run is charged its own work whatever else competes for the cores). A wall-clock
limit (``max_seconds``, generous by default) remains only as a guard against a hung run. A run that
stops on its budget has the status ``budget_exhausted`` and names the limit that ended it in
``PathResult.limit`` (:data:`LIMITS`).
"""

import dataclasses
import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..display import Displayed
from ..exceptions import SolverError

logger = logging.getLogger(__name__)

CONVERGED = "converged"
NOT_CONVERGED = "not_converged"
BUDGET = "budget_exhausted"

#: The limits of a run's budget, in the order they are checked (``PathResult.limit``): attempted
#: increments, Newton iterations, process CPU time, and the wall-clock hang guard.
LIMITS = ("steps", "iterations", "cpu", "wall")

#: Predictors of an increment's first Newton iterate and rules for the next increment (:class:`PathSettings`).
PREDICTORS = ("secant", "tangent")
STEP_RULES = ("easy_steps", "iterations")

#: Sub-increments per bracket refinement of a load maximum (the bracket halves per refinement).
PEAK_SUBSTEPS = 4


@dataclass(frozen=True)
class PathSettings:
    """Settings of the path-following solver (recorded with every result).

    Attributes
    ----------
    max_steps : int
        Attempted increments over the whole run (converged and cut back).
    max_iterations : int
        Newton iterations per increment before it is cut back.
    max_total_iterations : int
        Newton iterations over the whole run (the iteration budget).
    max_cpu_seconds : float
        CPU-time budget of the run, s: :func:`time.process_time` of the process (all its threads)
        since the run started; ``0`` ends a run before its first increment. What a run costs in
        CPU does not grow with the load of the machine the way its wall time does.
    max_seconds : float
        Wall-clock limit of the run, s: a guard against a hung run only, generous by default
        (12 × the default CPU budget, so that a run ends on its CPU budget first even when it
        gets a twelfth of a core). Budgets belong in ``max_cpu_seconds`` and the counts.
    tolerance : float
        Convergence: ``‖r_free‖ ≤ tolerance · max(‖f_int‖, ‖f_ext‖)``. 1e-3 by default: with 1e-4
        the J4D wall cycles between crack states near 1.8 mm (the residual floor of a point at a
        kink of the return map); typical force-norm tolerances of softening analyses are 1e-3–1e-2.
    line_search : bool
    growth, cutback : float
        Increment factors after an easy step (≤ ``easy_iterations``) and after a failed one.
    easy_iterations : int
    min_increment_fraction, max_increment_fraction : float
        Bounds of the increment relative to each phase's initial increment.
    elastic_fallback : bool
        (Off by default: initial-stiffness iterations diverge slowly on softening branches.) When Newton has not converged after ``max_iterations``, continue from its best iterate
        with up to ``elastic_iterations`` initial-stiffness iterations (one factorisation) before
        the increment is cut back.
    elastic_iterations : int
    stagnation_iterations : int
        An increment whose residual has not fallen below 1 % of its first-iteration value after
        this many Newton iterations is cut back at once (converging increments take ≤ 4).
    divergence_factor : float
        An iterate that lies farther from the converged state (largest displacement change) than
        this many times the first Newton iterate of the increment is taken as diverging: the
        increment is cut back at once, before the interface law is evaluated there. Evaluated at
        such jumps (tens to hundreds of mm on the J4D wall) the law sub-steps at many points and
        an update costs 10–30 times an ordinary one; no converging increment comes near the factor.
        0 disables the check.
    arc_length_fallback : bool
        When displacement control fails (increment cut below its minimum: a snap-back), continue
        with indirect displacement control on the opening of the cracking points until the
        controlled displacement passes the failure point (at most ``max_detour_steps`` steps).
    max_detour_steps : int
    detour_after_failures : int
    relaxed_factor : float
        When even the smallest increment and the detour fail but the best Newton iterate's
        residual is within ``relaxed_factor × tolerance``, that iterate is accepted and listed in
        ``PathResult.relaxed_steps`` (step index, relative residual); at most two in a row (no
        creeping along a limit point); 0 disables this.
        Consecutive failed increments after which the detour is tried (also when the increment
        falls below its minimum).
    record_states : bool
        Keep the interface state (opening, slip, κ2, plastic work; float32) of every converged step.
    predictor : {"secant", "tangent"}
        Start of Newton in each increment (module docstring): extrapolation of the last two
        converged states of the phase, or the converged state with its tangent.
    step_rule : {"easy_steps", "iterations"}
        Increment after a converged step: ``growth`` times the last one after two easy steps, or
        ``√(easy_iterations / iterations)`` times the last one (bounded by ``cutback`` and ``growth``).
    peak_tolerance : float
        Relative load change across the final bracket of a refined load maximum (module docstring);
        0 disables the refinement (the peak is then the largest recorded load).
    max_peak_steps : int
        Increments of all peak refinements of one phase (a cap on their cost; the peak found by
        then is reported, ``Peak.resolved`` says whether it met the tolerance).
    max_peak_levels : int
        Bracket refinements per maximum (each re-follows the bracket in four increments and halves it).
    peak_newton_tolerance : float
        Force tolerance (as ``tolerance``, which it replaces when smaller) of the increments of a
        peak refinement: the reaction of a state accepted at ``tolerance`` = 1e-3 is only known to
        about 0.1 %, too coarse to resolve a peak to ``peak_tolerance``. Where an increment of the
        refinement cannot reach it, the rest of that bracket uses ``tolerance``.
    """

    max_steps: int = 600
    max_iterations: int = 12
    max_total_iterations: int = 30000
    max_cpu_seconds: float = 300.0
    max_seconds: float = 3600.0
    tolerance: float = 1e-3
    line_search: bool = True
    growth: float = 1.5
    cutback: float = 0.5
    easy_iterations: int = 4
    min_increment_fraction: float = 1.0 / 1024.0
    max_increment_fraction: float = 4.0
    record_states: bool = False
    elastic_fallback: bool = False
    stagnation_iterations: int = 6
    divergence_factor: float = 100.0
    elastic_iterations: int = 15
    arc_length_fallback: bool = True
    max_detour_steps: int = 200
    detour_after_failures: int = 4
    relaxed_factor: float = 10.0
    predictor: str = "secant"
    step_rule: str = "easy_steps"
    peak_tolerance: float = 1e-3
    max_peak_steps: int = 32
    max_peak_levels: int = 16
    peak_newton_tolerance: float = 1e-4

    def __post_init__(self):
        for name in ("max_steps", "max_iterations", "max_total_iterations"):
            if not int(getattr(self, name)) >= 1:
                raise ValueError(f"{name} must be >= 1; got {getattr(self, name)}")
        if not self.max_cpu_seconds >= 0:
            raise ValueError(f"max_cpu_seconds (CPU-time budget) must be >= 0 s; got {self.max_cpu_seconds}")
        if not self.max_seconds > 0:
            raise ValueError(f"max_seconds (wall-clock hang guard) must be > 0 s; got {self.max_seconds}")
        if not 0 < self.tolerance < 1:
            raise ValueError(f"tolerance must be in (0, 1); got {self.tolerance}")
        if not (self.growth >= 1 and 0 < self.cutback < 1):
            raise ValueError(f"need growth >= 1 and 0 < cutback < 1; got {self.growth}, {self.cutback}")
        if not 0 < self.min_increment_fraction <= 1 <= self.max_increment_fraction:
            raise ValueError("need 0 < min_increment_fraction <= 1 <= max_increment_fraction")
        if self.predictor not in PREDICTORS:
            raise ValueError(f"predictor must be one of {PREDICTORS}; got {self.predictor!r}")
        if self.step_rule not in STEP_RULES:
            raise ValueError(f"step_rule must be one of {STEP_RULES}; got {self.step_rule!r}")
        if not 0 <= self.peak_tolerance < 0.1:
            raise ValueError(f"peak_tolerance (relative load change across a peak's bracket) must be in [0, 0.1); "
                             f"got {self.peak_tolerance}")
        if not self.divergence_factor >= 0:
            raise ValueError(f"divergence_factor must be >= 0 (0: no check); got {self.divergence_factor}")
        if not int(self.max_peak_steps) >= 0:
            raise ValueError(f"max_peak_steps must be >= 0; got {self.max_peak_steps}")

    def to_dict(self):
        return dataclasses.asdict(self)


@dataclass
class Phase:
    """One loading phase (reduced vectors, N; see the module docstring).

    Attributes
    ----------
    name : str
    control : {"load", "dof", "indirect"}
    target : float
        Final value of the path parameter (λ, mm of ``q[dof]``, or ``c · q``).
    increment : float
        Initial increment of the path parameter (positive; the direction is towards ``target``).
    f_const : ndarray (n,)
        Constant reduced load, N.
    f_ref : ndarray (n,) or None
        Reference load scaled by λ, N (load and indirect control).
    dof : int or None
        Controlled reduced dof (``"dof"`` control).
    c : ndarray (n,) or None
        Constraint vector (``"indirect"`` control).
    held : tuple of int
        Reduced dofs held at their value at the start of the phase.
    levels : tuple of float
        Values of the path parameter at which a step must end (the response levels).
    load_scale : float
        Factor from λ (or the reaction at ``dof``, N) to the reported load (e.g. 1e-3 for kN).
    """

    name: str
    control: str
    target: float
    increment: float
    f_const: np.ndarray
    f_ref: np.ndarray | None = None
    dof: int | None = None
    c: np.ndarray | None = None
    held: tuple = ()
    levels: tuple = ()
    load_scale: float = 1.0

    def __post_init__(self):
        if self.control not in ("load", "dof", "indirect"):
            raise ValueError(f"phase {self.name!r}: control must be load, dof or indirect; got {self.control!r}")
        if self.control == "dof" and self.dof is None:
            raise ValueError(f"phase {self.name!r}: displacement control needs the controlled dof")
        if self.control in ("load", "indirect") and self.f_ref is None:
            raise ValueError(f"phase {self.name!r}: {self.control} control needs a reference load f_ref")
        if self.control == "indirect" and self.c is None:
            raise ValueError(f"phase {self.name!r}: indirect control needs the constraint vector c")
        if not self.increment > 0:
            raise ValueError(f"phase {self.name!r}: increment must be > 0; got {self.increment}")


@dataclass(repr=False)
class PathResult(Displayed):
    """The converged path of a run.

    Attributes (one entry per converged step, in order; phase boundaries in ``phase``)
    ----------
    phase : list of str
    path : ndarray (n_steps,)
        Path parameter of the step's phase.
    load : ndarray (n_steps,)
        Load measure of the phase (λ or the reaction at the controlled dof) times ``load_scale``.
    readings : ndarray (n_steps, n_channels)
        Sensor readings, mm.
    held_reactions : list of ndarray
        Reactions (times ``load_scale``) at the phase's held dofs.
    dissipation : ndarray (n_steps,)
        Plastic work of all interfaces, N·mm.
    iterations : ndarray (n_steps,) int
    states : list of dict or None
        With ``record_states``: ``opening``, ``slip``, ``kappa2``, ``work`` per integration point.
    status : str
        ``converged``, ``not_converged`` or ``budget_exhausted``.
    limit : str or None
        With ``budget_exhausted``: the limit that ended the run, one of :data:`LIMITS`
        (``"steps"``, ``"iterations"``, ``"cpu"``, ``"wall"``); None otherwise.
    message : str
    total_iterations, attempted_steps : int
        Over the whole run, peak refinements included.
    failed_steps : int
        Increments of the recorded path that failed and were cut back (retried); those of the
        detour are in ``attempted_steps`` only, like the peak refinements'.
    peak_steps : int
        Converged increments of the peak refinements (not recorded in the path).
    peaks : dict of str to Peak
        Per displacement- or indirectly controlled phase that recorded a step: its largest load,
        refined to ``peak_tolerance`` (module docstring).
    relaxed_steps : list of (int, float)
        Steps accepted with a relative residual above ``tolerance`` (index, relative residual).
    seconds : float
        Wall time of the run, s.
    cpu_seconds : float
        CPU time of the process during the run, s (what ``max_cpu_seconds`` counts).
    settings : dict
    """

    phase: list = field(default_factory=list)
    path: list = field(default_factory=list)
    load: list = field(default_factory=list)
    readings: list = field(default_factory=list)
    held_reactions: list = field(default_factory=list)
    dissipation: list = field(default_factory=list)
    iterations: list = field(default_factory=list)
    states: list | None = None
    displacements: list | None = None
    status: str = CONVERGED
    limit: str | None = None
    message: str = ""
    total_iterations: int = 0
    attempted_steps: int = 0
    failed_steps: int = 0
    peak_steps: int = 0
    peaks: dict = field(default_factory=dict)
    relaxed_steps: list = field(default_factory=list)
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    settings: dict = field(default_factory=dict)

    def finish(self, n_channels):
        """Turn the per-step lists into arrays."""
        self.path = np.asarray(self.path, float)
        self.load = np.asarray(self.load, float)
        self.readings = np.asarray(self.readings, float).reshape(len(self.path), n_channels)
        self.dissipation = np.asarray(self.dissipation, float)
        self.iterations = np.asarray(self.iterations, int)
        return self

    def of_phase(self, name):
        """Boolean mask of the steps of one phase."""
        return np.array([p == name for p in self.phase], bool)

    def to_dict(self):
        return {
            "status": self.status, "limit": self.limit, "message": self.message, "steps": int(len(self.path)),
            "attempted_steps": self.attempted_steps, "failed_steps": self.failed_steps,
            "peak_steps": self.peak_steps, "total_iterations": self.total_iterations,
            "peaks": {k: v.to_dict() for k, v in self.peaks.items()},
            "relaxed_steps": [[int(i), float(r)] for i, r in self.relaxed_steps],
            "seconds": self.seconds, "cpu_seconds": self.cpu_seconds, "settings": self.settings,
        }


@dataclass(repr=False)
class Peak(Displayed):
    """The largest load of a phase, refined to a stated tolerance (module docstring).

    Attributes
    ----------
    phase : str
    path : float
        Path value (e.g. the controlled displacement, mm) of the converged state with the largest load.
    load : float
        That load (times ``load_scale``).
    readings : ndarray (n_channels,)
        Sensor readings there, mm.
    change : float
        Largest relative load change between that state and its neighbours in the final bracket
        (0 when the peak is the first or last recorded step of the phase: an end of its range).
    resolved : bool
        ``change <= tolerance``.
    tolerance : float
        ``PathSettings.peak_tolerance``.
    bracket : tuple of float
        Path values of the final bracket.
    refined : bool
        Whether the peak comes from a refinement (False: a recorded step).
    """

    phase: str
    path: float
    load: float
    readings: np.ndarray
    change: float = 0.0
    resolved: bool = True
    tolerance: float = 0.0
    bracket: tuple = ()
    refined: bool = False

    def to_dict(self):
        return {"phase": self.phase, "path": float(self.path), "load": float(self.load), "change": float(self.change),
                "resolved": bool(self.resolved), "tolerance": float(self.tolerance),
                "bracket": [float(v) for v in self.bracket], "refined": bool(self.refined)}


@dataclass
class _Snapshot:
    """A converged state of the solver (for restarting a peak refinement)."""

    q: np.ndarray
    lam: float
    state: object
    tangent: object
    previous_state: object
    value: float
    load: float
    readings: np.ndarray


class _Budget(Exception):
    """The run's budget is spent; ``limit`` is one of :data:`LIMITS`."""

    def __init__(self, message, limit):
        super().__init__(message)
        self.limit = limit


class _NotConverged(SolverError):
    """A failed increment, with its best iterate ``(residual, q, λ, update, data, f_int, its)``
    and the residual it had to reach."""

    def __init__(self, message, best, target_residual):
        super().__init__(message)
        self.best, self.target_residual = best, target_residual


class PathFollower:
    """Runs phases of a :class:`~fe.nonlinear_model.NonlinearModel` with an interface law.

    Parameters
    ----------
    model : NonlinearModel
        With the units' stiffness set (:meth:`NonlinearModel.set_units`).
    law : interface law (e.g. :class:`fe.interfaces.CompositeInterface`) with one row per point.
    settings : PathSettings
    """

    def __init__(self, model, law, settings=PathSettings()):
        self.model, self.law, self.settings = model, law, settings
        n = model.n_dofs
        self.q = np.zeros(n)
        self.lam = 0.0
        self.state = law.initial_state()
        self.tangent = None  # consistent tangent of the last converged step
        self.previous_state = None  # interface state one converged step earlier
        self.result = PathResult(settings=settings.to_dict(), states=[] if settings.record_states else None)
        self._t0 = time.perf_counter()
        self._cpu0 = time.process_time()

    # ---------------------------------------------------------------- evaluation
    def _evaluate(self, q, state0):
        upd = self.law.update(self.model.jumps(q) - state0.jump, state0)
        if upd.failed:
            return upd, None, None
        data, fint = self.model.tangent_and_force(q, upd.state.traction, upd.tangent)
        return upd, data, fint

    def _check_budget(self):
        """Raise :class:`_Budget` naming the first spent limit, in the order of :data:`LIMITS`
        (the counts first: when several are spent at once the reproducible one is named)."""
        s, r = self.settings, self.result
        if r.attempted_steps >= s.max_steps:
            raise _Budget(f"step budget of {s.max_steps} exhausted", "steps")
        if r.total_iterations >= s.max_total_iterations:
            raise _Budget(f"iteration budget of {s.max_total_iterations} exhausted", "iterations")
        if time.process_time() - self._cpu0 >= s.max_cpu_seconds:
            raise _Budget(f"CPU-time budget of {s.max_cpu_seconds:g} s exhausted", "cpu")
        if time.perf_counter() - self._t0 > s.max_seconds:
            raise _Budget(f"wall-clock limit of {s.max_seconds:g} s (hang guard) exhausted", "wall")

    # ---------------------------------------------------------------- one increment
    def _increment(self, phase, fixed, positions, diag, target, predicted=None, tolerance=None):
        """Newton iterations from the converged state to path value ``target``.

        ``predicted`` = (q, λ): the first iterate (secant predictor); None: the converged state
        with its tangent. ``tolerance`` overrides ``settings.tolerance``. Returns (q, λ, law update,
        internal force, iterations) or raises SolverError on failure.
        """
        s, model = self.settings, self.model
        tol = s.tolerance if tolerance is None else tolerance
        self._elastic_factorised = False
        f_ref = phase.f_ref if phase.f_ref is not None else 0.0
        data = None
        if predicted is not None:
            q, lam = predicted
            if phase.control == "load":
                lam = target
            upd, data, fint = self._evaluate(q, self.state)
        if data is None:  # no prediction, or its return mapping failed: the tangent predictor
            predicted = None
            q = self.q.copy()
            lam = target if phase.control == "load" else self.lam
            upd, data, fint = self._evaluate(q, self.state)
            if data is None:
                raise SolverError("interface return mapping failed")
            if self.tangent is not None:
                # predictor on the last converged (consistent) tangent, not the unloading one that the
                # law returns for a zero increment: a softening path continues to soften
                data, _ = model.tangent_and_force(q, upd.state.traction, self.tangent)
        r_start = None
        best, goal = None, None
        elastic = False  # after max_iterations Newton iterations: initial-stiffness iterations
        limit = s.max_iterations
        it = 0
        last_flowing = None  # flowing points of the last iterate (debug log)
        while True:
            self._check_budget()
            f_ext = phase.f_const + lam * f_ref
            r = fint - f_ext
            r[fixed] = 0.0
            rn = np.linalg.norm(r)
            scale = max(np.linalg.norm(fint), np.linalg.norm(f_ext), 1e-12)
            remaining = self._remaining(phase, q, target)
            if logger.isEnabledFor(logging.DEBUG):
                # points flowing plastically (κ above the converged state) and how many of them
                # switched since the last iterate: a few switching back and forth is Newton
                # cycling at a kink of the return map (loading/unloading)
                flowing = np.any(upd.state.kappa > self.state.kappa, axis=1)
                switched = -1 if last_flowing is None else int(np.count_nonzero(flowing != last_flowing))
                last_flowing = flowing
                logger.debug("  it %d%s: residual %.3e N (tol %.3e), remaining %.3e, sub-stepped points %d, "
                             "flowing points %d (%s switched since the last iterate)", it,
                             " (elastic)" if elastic else "", rn, tol * scale, remaining,
                             int(np.count_nonzero(upd.status == 1)), int(flowing.sum()),
                             "-" if switched < 0 else switched)
            if ((it > 0 or predicted is not None) and rn <= tol * scale
                    and abs(remaining) <= 1e-9 * max(abs(target), 1.0)):
                return q, lam, upd, fint, it  # a prediction within tolerance is accepted as it is
            if it > 0 and np.isfinite(rn) and (best is None or rn < best[0]):
                best = (rn, q, lam, upd, data, fint, it)
                goal = tol * scale
            if it == limit:
                if elastic or not s.elastic_fallback or best is None:
                    break
                # Newton cycles (e.g. cracks opening and closing between iterations): continue from
                # the best iterate with the elastic stiffness, factorised once, which contracts
                elastic, limit = True, limit + s.elastic_iterations
                rn, q, lam, upd, data, fint, _ = best
                continue
            if it == 1:
                r_start = max(rn, s.tolerance * scale)
            elif it > 1 and (rn > 1e6 * r_start or not np.isfinite(rn)):
                raise SolverError(f"Newton diverged (residual {rn:.3g} N)")
            elif not elastic and it >= s.stagnation_iterations and rn > 1e-2 * r_start:
                # a converging Newton iteration has gained two orders of magnitude by now: cut back
                raise _NotConverged(f"Newton stagnates (residual {rn:.3g} N after {it} iterations)", best, goal)
            it += 1
            K = self._elastic_data(q, upd) if elastic else data
            column = None
            if phase.control == "dof":
                column = np.zeros(len(q))
                column[self._column[0]] = K[self._column[1]]
            if not (elastic and self._elastic_factorised):
                K = K.copy()
                K[positions] = 0.0
                K[diag] = 1.0
                model.solver.factorize(K)
                self._elastic_factorised = elastic
            self.result.total_iterations += 1
            if phase.control == "dof":
                rhs = -r - column * remaining
                rhs[fixed] = 0.0
                rhs[phase.dof] = remaining
                dq, dlam = model.solver.solve(rhs), 0.0
            elif phase.control == "load":
                dq, dlam = model.solver.solve(-r), 0.0
            else:
                ref = phase.f_ref.copy()
                ref[fixed] = 0.0
                sol = model.solver.solve(np.column_stack([-r, ref]))
                d1, d2 = sol[:, 0], sol[:, 1]
                denom = phase.c @ d2
                if abs(denom) < 1e-300:
                    raise SolverError("indirect control: the constraint does not see the reference load")
                dlam = (remaining - phase.c @ d1) / denom
                dq = d1 + dlam * d2
            # an iterate running away from the converged state: cut back before evaluating the law there
            reach = np.max(np.abs(q + dq - self.q), initial=0.0)
            if it == 1:
                first_reach = max(reach, 1e-12)
            elif s.divergence_factor and not elastic and reach > s.divergence_factor * first_reach:
                raise _NotConverged(f"Newton diverges (iterate {reach / first_reach:.3g} times farther from the "
                                    f"converged state than the first)", best, goal)
            # backtracking line search on the residual norm
            eta = 1.0
            for _ in range(4 if s.line_search and not elastic else 1):
                q_try, used = q + eta * dq, eta
                lam_try = lam + eta * dlam
                upd_t, data_t, fint_t = self._evaluate(q_try, self.state)
                if data_t is not None:
                    r_t = fint_t - (phase.f_const + lam_try * f_ref)
                    r_t[fixed] = 0.0
                    if np.linalg.norm(r_t) <= rn or not s.line_search or it == 1:
                        break
                eta *= 0.5
            if data_t is None:
                raise SolverError(f"interface return mapping failed at {upd_t.failed} points")
            logger.debug("    line search: step %.4g of the Newton direction", used)
            q, lam, upd, data, fint = q_try, lam_try, upd_t, data_t, fint_t
        raise _NotConverged(f"no convergence in {limit} iterations (residual {rn:.3g} N)", best, goal)

    def _elastic_data(self, q, upd):
        """Tangent data with the elastic interface stiffness (the same for every iterate)."""
        data, _ = self.model.tangent_and_force(q, upd.state.traction, self.law.elastic_tangent())
        return data

    def _remaining(self, phase, q, target):
        if phase.control == "dof":
            return target - q[phase.dof]
        if phase.control == "indirect":
            return target - phase.c @ q
        return 0.0

    def _path_value(self, phase, q, lam):
        if phase.control == "dof":
            return float(q[phase.dof])
        if phase.control == "indirect":
            return float(phase.c @ q)
        return float(lam)

    # ---------------------------------------------------------------- phases
    def run(self, phases):
        """Run the phases in order; returns the :class:`PathResult` (also on failure)."""
        res = self.result
        try:
            for phase in phases:
                if not self._phase(phase):
                    break
        except _Budget as b:
            res.status, res.limit = BUDGET, b.limit
            where = f"{res.phase[-1]} at {res.path[-1]:.6g}" if res.path else "before the first step"
            res.message = f"{b}; the path reached {where}"
        res.seconds = time.perf_counter() - self._t0
        res.cpu_seconds = time.process_time() - self._cpu0
        logger.info("path: %s%s after %d steps, %d iterations, %.2f s CPU, %.2f s wall", res.status,
                    f" ({res.limit})" if res.limit else "", len(res.path), res.total_iterations, res.cpu_seconds,
                    res.seconds)
        return res.finish(len(self.model.channel_names))

    def _phase(self, phase):
        s, res, model = self.settings, self.result, self.model
        held = np.asarray(phase.held, dtype=np.int64)
        fixed = np.concatenate([held, [phase.dof]]) if phase.control == "dof" else held
        fixed = np.asarray(fixed, dtype=np.int64)
        positions, diag = model.row_positions(fixed)
        if phase.control == "dof":
            self._column = model.column_positions(phase.dof)
        system = (fixed, positions, diag)
        start = self._path_value(phase, self.q, self.lam)
        direction = 1.0 if phase.target >= start else -1.0
        stops = sorted({float(v) for v in phase.levels if (v - start) * direction > 0} | {float(phase.target)},
                       key=lambda v: (v - start) * direction)
        inc = phase.increment
        inc_min, inc_max = phase.increment * s.min_increment_fraction, phase.increment * s.max_increment_fraction
        value = start
        easy = 0
        failures = 0  # consecutive failed increments
        relaxed_run = 0  # consecutive relaxed acceptances (at most two: no creeping at a limit point)
        first = len(res.path)  # index of the phase's first recorded step
        self._chain = []  # the phase's last converged normal steps (secant predictor, peak brackets)
        self._brackets = []  # (bound of the maximum, start snapshot, end path value) of load maxima
        for stop in stops:
            while (stop - value) * direction > 1e-12 * max(abs(stop), 1.0):
                self._check_budget()
                step = min(inc, abs(stop - value))
                target = stop if step >= abs(stop - value) * (1 - 1e-12) else value + direction * step
                res.attempted_steps += 1
                try:
                    predicted = self._predict(phase, target) if failures == 0 else None
                    q, lam, upd, fint, its = self._increment(phase, *system, target, predicted)
                except SolverError as e:
                    res.failed_steps += 1
                    inc *= s.cutback
                    easy = 0
                    failures += 1
                    logger.debug("%s: increment to %.6g failed (%s); cut to %.3g", phase.name, target, e, inc)
                    best = getattr(e, "best", None)
                    if (inc < inc_min and s.relaxed_factor > 0 and best is not None and relaxed_run < 2
                            and best[0] <= s.relaxed_factor * e.target_residual):
                        # the smallest increment cycles just above the tolerance: accept its best
                        # iterate, count it, and go on (reported in the result)
                        _, q, lam, upd, _, fint, its = best
                        res.relaxed_steps.append((len(res.path), float(best[0] / e.target_residual * s.tolerance)))
                        self.previous_state = self.state
                        self.q, self.lam, self.state, self.tangent = q, lam, upd.state, upd.tangent
                        value = self._path_value(phase, q, lam)
                        self._record(phase, fint, its, upd)
                        self._chain = []
                        inc, failures, relaxed_run = phase.increment, 0, relaxed_run + 1
                        continue
                    detour_now = failures >= s.detour_after_failures or inc < inc_min
                    if detour_now and phase.control != "load" and s.arc_length_fallback:
                        self._chain = []
                        reached = self._detour(phase, held, value, direction)
                        if reached is not None:
                            value, inc, easy, failures = reached, phase.increment, 0, 0
                            continue
                        value = self._path_value(phase, self.q, self.lam)  # a failed detour may have moved
                    if inc < inc_min:
                        res.status = NOT_CONVERGED
                        res.message = (f"{phase.name}: no convergence at {phase.control} path value {value:.6g} "
                                       f"towards {target:.6g} with the increment cut to {inc / s.cutback:.3g} "
                                       f"(minimum {inc_min:.3g}); last failure: {e}")
                        self._resolve_peak(phase, system, first)
                        return False
                    continue
                failures = relaxed_run = 0
                self.previous_state = self.state
                self.q, self.lam, self.state, self.tangent = q, lam, upd.state, upd.tangent
                value = self._path_value(phase, q, lam)
                if abs(value - target) <= 1e-9 * max(abs(target), 1.0):
                    value = target
                self._record(phase, fint, its, upd)
                self._chain_step(phase, value)
                if s.step_rule == "iterations":
                    # Crisfield's rule: the increment follows the iterations the last one needed
                    factor = s.growth if its == 0 else np.sqrt(s.easy_iterations / its)
                    inc = float(np.clip(inc * min(max(factor, s.cutback), s.growth), inc_min, inc_max))
                else:
                    easy = easy + 1 if its <= s.easy_iterations else 0
                    if easy >= 2:
                        inc = min(inc * s.growth, inc_max)
        self._resolve_peak(phase, system, first)
        return True

    # ---------------------------------------------------------------- prediction and peaks
    def _snapshot(self, value):
        res = self.result
        return _Snapshot(self.q, self.lam, self.state, self.tangent, self.previous_state, value,
                         float(res.load[-1]), np.asarray(res.readings[-1]))

    def _restore(self, snap):
        self.q, self.lam, self.state = snap.q, snap.lam, snap.state
        self.tangent, self.previous_state = snap.tangent, snap.previous_state

    def _chain_step(self, phase, value):
        """Keep the last three converged steps of the phase; note a bracketed load maximum."""
        self._chain = (self._chain + [self._snapshot(value)])[-3:]
        if phase.control == "load" or self.settings.peak_tolerance <= 0 or len(self._chain) < 3:
            return
        a, b, c = self._chain
        left, right = b.value - a.value, c.value - b.value
        if b.load >= a.load and b.load > c.load and left * right > 0:
            bound = b.load + max((b.load - a.load) * right / left, (b.load - c.load) * left / right)
            self._brackets.append((bound, a, c.value))

    def _predict(self, phase, target):
        """Secant predictor (q, λ) for the increment to ``target``, or None (module docstring)."""
        if self.settings.predictor != "secant" or len(self._chain) < 2:
            return None
        a, b = self._chain[-2], self._chain[-1]
        if b.q is not self.q or b.value == a.value:
            return None
        ratio = (target - b.value) / (b.value - a.value)
        if not 0 < ratio <= 2 * self.settings.max_increment_fraction:
            return None
        q = b.q + ratio * (b.q - a.q)
        if phase.control == "dof":
            q[phase.dof] = target
        return q, b.lam + ratio * (b.lam - a.lam)

    def _resolve_peak(self, phase, system, first):
        """Refine the phase's load maxima (module docstring); sets ``result.peaks[phase.name]``."""
        res, s = self.result, self.settings
        if phase.control == "load" or len(res.path) <= first:
            return
        loads = np.asarray(res.load[first:], float)
        k = int(np.argmax(loads))
        peak = Peak(phase.name, float(res.path[first + k]), float(loads[k]), np.asarray(res.readings[first + k]),
                    tolerance=s.peak_tolerance, bracket=(float(res.path[first + k]),) * 2)
        if s.peak_tolerance > 0 and 0 < k < len(loads) - 1:
            # an interior maximum not bracketed by three normal steps (e.g. in a detour): unresolved
            peak.change = float(max(loads[k] - loads[k - 1], loads[k] - loads[k + 1]) / max(abs(loads[k]), 1e-300))
            peak.resolved = peak.change <= s.peak_tolerance
            peak.bracket = (float(res.path[first + k - 1]), float(res.path[first + k + 1]))
        end = self._snapshot(self._path_value(phase, self.q, self.lam)) if len(res.path) > first else None
        candidates = sorted(self._brackets, key=lambda b: -b[0])
        self._peak_budget = res.peak_steps + s.max_peak_steps
        try:
            for bound, start, stop in candidates:
                if bound <= peak.load or res.peak_steps >= self._peak_budget:
                    break
                found = self._refine(phase, system, start, stop)
                # a refined maximum replaces a recorded one unless lower by more than the tolerance:
                # recorded loads carry the error of the looser ``tolerance``
                if found.load > peak.load or (not peak.refined and found.resolved
                                              and found.load >= peak.load - s.peak_tolerance * abs(peak.load)):
                    peak = found
        except _Budget as b:
            logger.info("%s: peak refinement stopped (%s); the peak is the best found so far", phase.name, b)
            peak.resolved = False
        finally:
            if end is not None:
                self._restore(end)
        res.peaks[phase.name] = peak
        self._brackets = []

    def _refine(self, phase, system, start, stop):
        """Shrink the bracket [start.value, stop] around its load maximum (module docstring)."""
        s, res = self.settings, self.result
        width_min = abs(phase.increment) * s.min_increment_fraction
        lo, hi = start, stop
        best = Peak(phase.name, start.value, start.load, start.readings, change=np.inf, resolved=False,
                    tolerance=s.peak_tolerance, bracket=(start.value, stop), refined=True)
        for _ in range(s.max_peak_levels):
            followed = self._follow(phase, system, lo, hi, PEAK_SUBSTEPS)
            points = [lo] + followed
            complete = len(followed) == PEAK_SUBSTEPS
            loads = np.array([p.load for p in points])
            k = int(np.argmax(loads))
            logger.debug("%s: peak bracket %s loads %s", phase.name, [p.value for p in points], loads)
            # resolved only between two neighbours: a maximum at an end of the bracket may lie beyond
            change = np.inf
            if 0 < k < len(points) - 1:
                change = max(loads[k] - loads[k - 1], loads[k] - loads[k + 1]) / max(abs(loads[k]), 1e-300)
            # the highest state of the finest bracket, unless an earlier bracket's was higher by
            # more than the tolerance (states at the same path value differ by the Newton tolerance)
            if loads[k] >= best.load - s.peak_tolerance * abs(best.load):
                best = Peak(phase.name, points[k].value, float(loads[k]), points[k].readings, change=float(change),
                            resolved=bool(change <= s.peak_tolerance), tolerance=s.peak_tolerance,
                            bracket=(points[max(k - 1, 0)].value, points[min(k + 1, len(points) - 1)].value),
                            refined=True)
            if change <= s.peak_tolerance or len(points) < 2 or (k == len(points) - 1 and not complete):
                break  # resolved, or the maximum is where the side path could not go on (a jump)
            lo = points[max(k - 1, 0)]
            if k == len(points) - 1:  # still rising at the bracket's end: extend it by one sub-step
                hi = 2 * points[k].value - points[k - 1].value
            else:
                hi = points[k + 1].value
            if abs(hi - lo.value) < width_min:
                break
        logger.debug("%s: peak %.6g at %.6g (change %.2e, resolved %s)", phase.name, best.load, best.path,
                     best.change, best.resolved)
        return best

    def _follow(self, phase, system, start, stop, parts):
        """Converged snapshots at ``parts`` equal sub-steps from ``start`` to ``stop`` on a side
        path (not recorded); fewer when an increment fails below the smallest increment."""
        s, res = self.settings, self.result
        self._restore(start)
        self._chain = []
        out = []
        h = (stop - start.value) / parts
        value = start.value
        inc, inc_min = abs(h), abs(phase.increment) * s.min_increment_fraction / parts
        tight = min(s.tolerance, s.peak_newton_tolerance)
        for j in range(1, parts + 1):
            goal = start.value + j * h if j < parts else stop
            while abs(goal - value) > 1e-12 * max(abs(goal), 1.0):
                self._check_budget()
                if res.peak_steps >= self._peak_budget:
                    return out
                target = goal if inc >= abs(goal - value) * (1 - 1e-12) else value + np.sign(h) * inc
                res.attempted_steps += 1
                try:
                    q, lam, upd, fint, its = self._increment(phase, *system, target, self._predict(phase, target),
                                                             tolerance=tight)
                except SolverError:
                    if tight < s.tolerance:
                        # a point cycling at a kink of the return map may not reach the tighter
                        # tolerance: go on with the path's own (the peak is then known to ~tolerance)
                        tight = s.tolerance
                        continue
                    inc *= s.cutback
                    if inc < inc_min:
                        return out
                    continue
                res.peak_steps += 1
                self.previous_state = self.state
                self.q, self.lam, self.state, self.tangent = q, lam, upd.state, upd.tangent
                value = target
                snap = _Snapshot(q, lam, upd.state, upd.tangent, self.previous_state, value,
                                 self._load(phase, fint), self.model.readings(q))
                self._chain = (self._chain + [snap])[-3:]
            out.append(self._chain[-1])
        return out

    def _detour(self, phase, held, value, direction):
        """Pass a snap-back of a displacement- or indirectly controlled phase by indirect control on
        the plastic points.

        Under displacement control the controlled dof is released and loaded by λ (its reaction);
        under indirect control the phase's load pattern and λ are kept. The path parameter becomes
        the mean jump increment, along the last step's jump direction, of the interface points that
        flowed plastically in the last step (crack opening and slip alike), plus the opening or
        slip of the points within 80 % of their tension cut-off or Coulomb strength (about to
        crack: the source of a local snap-back), increased until the
        phase's path value exceeds the value where its control failed by one initial increment. Steps are recorded as steps of ``phase`` (their control value
        may go back: the snap-back). Returns the control value reached, or None.
        """
        s, model, st = self.settings, self.model, self.state
        prev = self.previous_state
        if prev is None:
            return None
        # constraint: the jump increment projected on the last step's jump direction, averaged
        # over the points that flowed plastically in the last step (opening and slip alike)
        flowed = np.any(st.kappa > prev.kappa + 1e-14, axis=1)
        d = st.jump - prev.jump
        norm = np.linalg.norm(d, axis=1)
        flowed &= norm > 0
        d[flowed] /= norm[flowed, None]
        near = self.law.near_surfaces(st, 0.8)  # (n, 2): near tension cut-off, near Coulomb
        d[~flowed & near[:, 0]] = (1.0, 0.0)
        shear = ~flowed & ~near[:, 0] & near[:, 1]
        d[shear, 0], d[shear, 1] = 0.0, np.sign(st.traction[shear, 1])
        active = flowed | near[:, 0] | shear
        if not active.any():
            return None
        d = d[active]
        w = model.weights.ravel()[active]
        idx = np.flatnonzero(active)
        Jn, Js = model.jump_operator[0::2][idx], model.jump_operator[1::2][idx]
        c = (np.asarray(Jn.T @ (w * d[:, 0])).ravel() + np.asarray(Js.T @ (w * d[:, 1])).ravel()) / w.sum()
        if phase.control == "dof":
            f_ref = np.zeros(model.n_dofs)
            f_ref[phase.dof] = direction
            lam0 = direction * (self._fint_current(phase)[phase.dof] - phase.f_const[phase.dof])
        else:  # indirect control on another constraint: keep the phase's load pattern and λ
            f_ref, lam0 = phase.f_ref, self.lam
        detour = Phase(f"{phase.name}_arc", "indirect", target=np.inf, increment=1.0, f_const=phase.f_const,
                       f_ref=f_ref, c=c, held=phase.held)
        positions, diag = model.row_positions(held)
        self.lam = lam0
        inc = max(1e-4 * abs(phase.increment), 1e-6)
        logger.debug("%s: displacement control failed at %.6g; indirect control on %d plastic points",
                     phase.name, value, int(active.sum()))
        for _ in range(s.max_detour_steps):
            self._check_budget()
            self.result.attempted_steps += 1
            target = c @ self.q + inc
            try:
                q, lam, upd, fint, its = self._increment(detour, held, positions, diag, target)
            except SolverError:
                inc *= s.cutback
                if inc < 1e-9:
                    return None
                continue
            self.previous_state = self.state
            self.q, self.lam, self.state, self.tangent = q, lam, upd.state, upd.tangent
            self._record(phase, fint, its, upd)
            if its <= s.easy_iterations:
                inc *= s.growth
            now = self._path_value(phase, q, lam)
            if (now - value) * direction > abs(phase.increment):
                return now
        return None

    def _fint_current(self, phase):
        upd = self.law.update(np.zeros((len(self.state), 2)), self.state)
        return self.model.tangent_and_force(self.q, upd.state.traction, upd.tangent)[1]

    def _load(self, phase, fint):
        """Load measure of the phase at the current state (λ or the reaction at the controlled dof)."""
        if phase.control == "dof":
            return float((fint[phase.dof] - phase.f_const[phase.dof]) * phase.load_scale)
        return float(self.lam * phase.load_scale)

    def _record(self, phase, fint, its, upd):
        res = self.result
        res.phase.append(phase.name)
        res.path.append(self._path_value(phase, self.q, self.lam))
        res.load.append(self._load(phase, fint))
        res.readings.append(self.model.readings(self.q))
        held = np.asarray(phase.held, dtype=np.int64)
        res.held_reactions.append((fint[held] - phase.f_const[held]) * phase.load_scale)
        st = self.state
        res.dissipation.append(float(np.sum(self.model.weights.ravel() * st.work)))
        res.iterations.append(its)
        if res.states is not None:
            res.states.append({
                "opening": st.jump[:, 0].astype(np.float32), "slip": st.jump[:, 1].astype(np.float32),
                "kappa2": st.kappa[:, 1].astype(np.float32), "work": st.work.astype(np.float32),
            })
            if res.displacements is None:
                res.displacements = []
            res.displacements.append(self.model.displacements(self.q).astype(np.float32))
