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
  displacement control cannot (DIANA's arc-length remark, reference §3).

Further dofs can be ``held`` (zero increment in the phase), e.g. the vertical dof of a loading beam
fixed after pre-compression; their reactions are recorded.

Every iteration re-evaluates the interface law from the last converged state (no history is
updated before a step converges). Newton steps are damped by a backtracking line search on the
residual norm; a step that does not converge within ``max_iterations`` (or whose local return
fails, or whose residual grows a million-fold) is cut back; easy steps grow the increment. Every
run ends within its :class:`PathSettings` budget with a status and the converged part of the path.

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

from ..exceptions import SolverError

logger = logging.getLogger(__name__)

CONVERGED = "converged"
NOT_CONVERGED = "not_converged"
BUDGET = "budget_exhausted"

#: The limits of a run's budget, in the order they are checked (``PathResult.limit``): attempted
#: increments, Newton iterations, process CPU time, and the wall-clock hang guard.
LIMITS = ("steps", "iterations", "cpu", "wall")


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
    """

    max_steps: int = 600
    max_iterations: int = 12
    max_total_iterations: int = 6000
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
    elastic_iterations: int = 15
    arc_length_fallback: bool = True
    max_detour_steps: int = 200
    detour_after_failures: int = 4
    relaxed_factor: float = 10.0

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


@dataclass
class PathResult:
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
            "attempted_steps": self.attempted_steps, "total_iterations": self.total_iterations,
            "relaxed_steps": [[int(i), float(r)] for i, r in self.relaxed_steps],
            "seconds": self.seconds, "cpu_seconds": self.cpu_seconds, "settings": self.settings,
        }


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
    def _increment(self, phase, fixed, positions, diag, target):
        """Newton iterations from the converged state to path value ``target``.

        Returns (q, λ, law update, internal force, iterations) or raises SolverError on failure.
        """
        s, model = self.settings, self.model
        self._elastic_factorised = False
        q = self.q.copy()
        lam = target if phase.control == "load" else self.lam
        f_ref = phase.f_ref if phase.f_ref is not None else 0.0
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
        while True:
            self._check_budget()
            f_ext = phase.f_const + lam * f_ref
            r = fint - f_ext
            r[fixed] = 0.0
            rn = np.linalg.norm(r)
            scale = max(np.linalg.norm(fint), np.linalg.norm(f_ext), 1e-12)
            remaining = self._remaining(phase, q, target)
            logger.debug("  it %d%s: residual %.3e N (tol %.3e), remaining %.3e, sub-stepped points %d", it,
                         " (elastic)" if elastic else "", rn, s.tolerance * scale, remaining,
                         int(np.count_nonzero(upd.status == 1)))
            if it > 0 and rn <= s.tolerance * scale and abs(remaining) <= 1e-9 * max(abs(target), 1.0):
                return q, lam, upd, fint, it
            if it > 0 and np.isfinite(rn) and (best is None or rn < best[0]):
                best = (rn, q, lam, upd, data, fint, it)
                goal = s.tolerance * scale
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
            # backtracking line search on the residual norm
            eta = 1.0
            for _ in range(4 if s.line_search and not elastic else 1):
                q_try = q + eta * dq
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
        for stop in stops:
            while (stop - value) * direction > 1e-12 * max(abs(stop), 1.0):
                self._check_budget()
                step = min(inc, abs(stop - value))
                target = stop if step >= abs(stop - value) * (1 - 1e-12) else value + direction * step
                res.attempted_steps += 1
                try:
                    q, lam, upd, fint, its = self._increment(phase, fixed, positions, diag, target)
                except SolverError as e:
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
                        inc, failures, relaxed_run = phase.increment, 0, relaxed_run + 1
                        continue
                    detour_now = failures >= s.detour_after_failures or inc < inc_min
                    if detour_now and phase.control != "load" and s.arc_length_fallback:
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
                        return False
                    continue
                failures = relaxed_run = 0
                self.previous_state = self.state
                self.q, self.lam, self.state, self.tangent = q, lam, upd.state, upd.tangent
                value = self._path_value(phase, q, lam)
                if abs(value - target) <= 1e-9 * max(abs(target), 1.0):
                    value = target
                self._record(phase, fint, its, upd)
                easy = easy + 1 if its <= s.easy_iterations else 0
                if easy >= 2:
                    inc = min(inc * s.growth, inc_max)
        return True

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

    def _record(self, phase, fint, its, upd):
        res = self.result
        res.phase.append(phase.name)
        res.path.append(self._path_value(phase, self.q, self.lam))
        if phase.control == "dof":
            load = (fint[phase.dof] - phase.f_const[phase.dof]) * phase.load_scale
        else:
            load = self.lam * phase.load_scale
        res.load.append(load)
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
