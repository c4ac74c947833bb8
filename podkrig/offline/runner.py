"""The offline runner: fills a snapshot store with FE responses, serially or on Dask, resumably.

:func:`run_snapshots` creates (or reopens) a :class:`~podkrig.offline.store.SnapshotStore` for a scenario,
a parameter space and a seeded design, then runs the scenario on every pending row. Executors:

- ``workers=1``: in this process, no Dask;
- ``workers=K`` (default: one per core): a :class:`distributed.LocalCluster` of ``K`` worker
  processes with one thread each and ``OMP_NUM_THREADS = MKL_NUM_THREADS = OPENBLAS_NUM_THREADS = 1``;
- ``scheduler="tcp://HOST:PORT"``: the workers of an existing Dask cluster (``dask scheduler`` /
  ``dask worker``, dask-jobqueue, Kubernetes); each needs the same podkrig version installed.

Rows travel in chunks of a few rows per task (``chunk_size``, default adapted to the work) so that
Dask's per-task overhead (~1 ms) is amortised over FE runs of ~20 ms. A worker rebuilds the
scenario from its JSON spec once and caches it for later chunks; only this process writes the
file, batch by batch as chunks complete (:func:`distributed.as_completed`), flushing each batch.

Resuming. Rows are fixed at creation and identified by index; a rerun with the same arguments runs
only the pending rows (and, with ``retry_failed=True``, the failed ones) and never rewrites a done
row, so an interruption (Ctrl-C, SIGKILL of the job, a dying worker) costs at most the rows in
flight. A rerun whose scenario spec, parameter space, seed, sampling method, ``fields`` flag or
podkrig version differs from the store's is refused with a list of the differences. The one
exception: **growing** ``n`` of a Sobol' store appends rows that continue the same scrambled
sequence (points ``n_old .. n-1``), then runs them.

A nonlinear scenario's solver settings (increments, budgets, tolerance: :data:`~podkrig.offline.store.SOLVER_SETTINGS`)
are part of its spec, so a store records them and a rerun with another one is refused naming it.
A failed FE run (any exception from ``Scenario.run``) becomes a ``failed`` row with its error
text; a nonlinear run that stops early (budget or non-convergence) becomes a ``failed`` row, a
*partial row*, whose error starts with ``NotConverged`` and its reach (the budget limit that ended
it and the control value reached, :func:`~podkrig.offline.store.partial_error`) and which keeps
the readings of the levels it reached; infrastructure failures (a task that cannot run, a worker with another podkrig version,
workers that keep dying) stop the run with a :class:`~podkrig.exceptions.PodkrigError` after
keeping every finished row.

Example
-------
>>> from fe.scenarios import build_scenario
>>> from podkrig.parameters import ParameterSpace
>>> from podkrig.offline.runner import run_snapshots
>>> sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
>>> space = ParameterSpace.from_scenario(sc, {"kN_bj": (10, 1000, "log")})
>>> summary = run_snapshots("snapshots/demo.h5", sc, space, n=16, seed=0, workers=1)
>>> summary.done
16

Why one module of ~650 lines (half documentation): the resumable run loop and its two executors
(serial and Dask) share the batching, retry and failure-recording rules; the store and its file
safety are :mod:`.store` and :mod:`.files`.
"""

import dataclasses
import json
import logging
import math
import os
import threading
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from podkrig import __version__
from podkrig.exceptions import PodkrigError, StoreError
from podkrig.limits import check_chunk_size, check_workers
from podkrig.offline.files import acquire_lock, release_lock
from podkrig.offline.sampling import METHODS, sample
from podkrig.offline.store import DONE, FAILED, SOLVER_SETTINGS, SnapshotStore, partial_error
from podkrig.parallel import close_local_cluster
from podkrig.parameters import ParameterSpace

logger = logging.getLogger(__name__)

#: Environment of local Dask worker processes: one BLAS/MKL/OpenMP thread each.
ONE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
#: Dask settings of the local clusters the runner starts. The workers' statistical profiler samples
#: the running task every 10 ms, slowing FE runs noticeably on a busy core; housekeeping ticks are
#: relaxed from 20-500 ms to 1-5 s. Together they cut the cluster's idle load from ~0.1 core to ~0.01.
LOCAL_DASK_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.worker.memory.monitor-interval": "1s",
}
MAX_CHUNK = 32
#: Wall time to start a local cluster of the runner's kind and get its first results, s: the
#: worker processes start, import podkrig and build the scenario. Measured 2026-11-24 with
#: ``scripts/bench_local_cluster.py`` on the shared 2-core machine (load 2.4): 2 workers, median
#: 5.9 s (3.8-10.2 s over 3 starts), shut-down 0.55 s. A job of ``n`` runs of ``t`` s each pays for
#: a cluster of K workers only when ``n t (1 − 1/K) > LOCAL_CLUSTER_STARTUP_S``: with K = 2 that
#: is n ≳ 1 750 runs of the coarse diagonal test (6.8 ms/run) and n ≳ 210 runs of the demo mesh
#: (57 ms/run; end to end 8 runs: 0.46 s serial vs 7.4 s on the cluster, 64 runs: 1.9 vs 7.5 s).
#: Below it, :func:`run_pending` runs serially and says so in :attr:`RunSummary.executor`.
LOCAL_CLUSTER_STARTUP_S = 6.0
#: Serial time a cluster would have saved, s, from which a job run serially despite ``workers > 1``
#: says why (:attr:`RunSummary.executor` ``"serial: ..."``, a note of the study's stage): below
#: it the job is over before the reason could matter, and the executor is plain ``"serial"``.
SERIAL_REASON_MIN_SAVING_S = 2.0
#: Wall time of FE work between two writes of a serial run, s: its chunks start at one row and
#: then hold as many rows as take about this long, so that an interruption loses at most that much
#: finished work (one row of a nonlinear wall, 2-10 s; 32 rows of a linear test of milliseconds).
SERIAL_WRITE_SECONDS = 2.0

_SCENARIO_CACHE = {}  # (spec JSON, thread id) -> Scenario: each worker thread builds a scenario once
_SCENARIO_CACHE_SIZE = 8
_THREADS_LIMITED = False
_CACHE_LOCK = threading.Lock()


@dataclass(frozen=True)
class RunSummary:
    """Outcome of one :func:`run_snapshots` / :func:`run_pending` call.

    Attributes
    ----------
    path : Path
        The store.
    total, done, failed, pending : int
        Row counts of the store after the call.
    ran, failed_now : int
        Rows run by this call, and how many of them failed.
    seconds : float
        Wall time of the call, s (includes starting a local cluster).
    executor : str
        ``"serial"``, ``"local Dask cluster, K workers"`` or ``"Dask scheduler ADDR, K workers"``.
    action : str
        What happened to the store first: ``"created"``, ``"resumed"`` or ``"extended"``.
    """

    path: Path
    total: int
    done: int
    failed: int
    pending: int
    ran: int
    failed_now: int
    seconds: float
    executor: str
    action: str = "resumed"

    @property
    def snapshots_per_second(self):
        """Rows run by this call per second of wall time, 1/s."""
        return self.ran / self.seconds if self.seconds > 0 else float("nan")


@dataclass(frozen=True)
class ChunkResult:
    """Results of one chunk of rows, computed on a worker and written by the client.

    Attributes
    ----------
    rows : ndarray of shape (k,)
    status : ndarray of shape (k,) int8
        :data:`~podkrig.offline.store.DONE` or :data:`~podkrig.offline.store.FAILED`.
    readings : ndarray of shape (k, n_loads, n_sensors)
        mm; NaN for failed rows.
    errors : tuple of str
        ``"ExceptionType: message"`` for failed rows, ``""`` otherwise.
    wall_times : ndarray of shape (k,)
        Wall time per FE run, s.
    cpu_times : ndarray of shape (k,)
        CPU time per FE run (of the running thread), s.
    fields : ndarray of shape (k, n_loads, n_nodes, 2) or None
        mm.
    version : str
        podkrig version of the worker.
    """

    rows: np.ndarray
    status: np.ndarray
    readings: np.ndarray
    errors: tuple
    wall_times: np.ndarray
    cpu_times: np.ndarray
    fields: np.ndarray | None
    version: str


def limit_threads_to_one():
    """Limit this process to one BLAS/MKL/OpenMP thread (environment and loaded thread pools).

    Call it before any scenario is built in the process: MKL PARDISO keeps the thread count of its
    analysis phase, and changing it between analysis and factorisation can crash the process.
    """
    global _THREADS_LIMITED
    if not _THREADS_LIMITED:
        from threadpoolctl import threadpool_limits

        os.environ.update(ONE_THREAD_ENV)  # for libraries loaded later (they read it at load time)
        threadpool_limits(limits=1)  # for thread pools already loaded
        _THREADS_LIMITED = True


def cached_scenario(spec_json, limit_threads=False):
    """The scenario of a JSON spec, built once per process and thread.

    A scenario holds its solver's factorisation, so it is not shared between threads: a Dask
    worker with several threads builds one per thread.

    Parameters
    ----------
    spec_json : str
        ``ScenarioSpec.to_json()``.
    limit_threads : bool
        Call :func:`limit_threads_to_one` before the first build in this process; set on Dask
        workers, whose processes share the cores.
    """
    key = (spec_json, threading.get_ident())
    sc = _SCENARIO_CACHE.get(key)
    if sc is None:
        from fe.scenarios import ScenarioSpec, build_scenario

        with _CACHE_LOCK:
            if limit_threads and not _SCENARIO_CACHE:
                limit_threads_to_one()
        sc = build_scenario(ScenarioSpec.from_dict(json.loads(spec_json)))
        _cache(key, sc)
    return sc


def _cache(key, scenario):
    with _CACHE_LOCK:
        while len(_SCENARIO_CACHE) >= _SCENARIO_CACHE_SIZE:
            _SCENARIO_CACHE.pop(next(iter(_SCENARIO_CACHE)))
        _SCENARIO_CACHE[key] = scenario


def run_chunk(spec_json, names, rows, X, field=False, limit_threads=False):
    """Run the scenario at several parameter vectors (the task a worker executes).

    Parameters
    ----------
    spec_json : str
        Scenario spec as JSON.
    names : tuple of str
        Free parameter names, length ``n_params``.
    rows : ndarray of shape (k,)
        Store row of each vector.
    X : ndarray of shape (k, n_params)
        Physical parameter values.
    field : bool
        Also return displacement fields.
    limit_threads : bool
        See :func:`cached_scenario`.

    Returns
    -------
    ChunkResult
    """
    sc = cached_scenario(spec_json, limit_threads)
    k = len(rows)
    readings = np.full((k, len(sc.load_levels), len(sc.sensor_names)), np.nan)
    fields = np.full((k, len(sc.load_levels), sc.mesh.n_nodes, 2), np.nan) if field else None
    status = np.full(k, DONE, dtype=np.int8)
    errors = [""] * k
    wall = np.empty(k)
    cpu = np.empty(k)
    for j, x in enumerate(np.asarray(X, dtype=float)):
        t0, c0 = time.perf_counter(), time.thread_time()
        try:
            response = sc.run(dict(zip(names, x.tolist())), field=field)
            readings[j] = response.readings
            if field:
                fields[j] = response.field
            if getattr(response, "status", "converged") != "converged":
                # a nonlinear run that stopped early: a failed row with its reason and partial readings
                status[j] = FAILED
                errors[j] = partial_error(response.status, response.limit, response.reached, sc.load_unit,
                                          response.message)

        except Exception as e:  # noqa: BLE001 - any FE failure is a failed row, never a crash
            status[j] = FAILED
            errors[j] = f"{type(e).__name__}: {e}"
        wall[j], cpu[j] = time.perf_counter() - t0, time.thread_time() - c0
    return ChunkResult(np.asarray(rows), status, readings, tuple(errors), wall, cpu, fields, __version__)


def _scenario_of(spec):
    from fe.scenarios import Scenario, build_scenario

    return spec if isinstance(spec, Scenario) else build_scenario(spec)


def _check_space(scenario, space):
    checked = ParameterSpace.from_scenario(scenario, {p.name: (p.lower, p.upper, p.scale) for p in space.parameters})
    for p, q in zip(space.parameters, checked.parameters):
        if p.unit != q.unit:
            raise ValueError(
                f"parameter {p.name!r} has unit {p.unit!r} but scenario {scenario.name!r} uses {q.unit!r}"
            )


def _differences(store, scenario, space, n, seed, sampling, fields):
    """Human-readable differences between a store and the arguments of a rerun."""
    diffs = []
    old = store.spec.to_dict()
    new = json.loads(scenario.spec.to_json())
    for key in sorted(set(old) | set(new)):
        if old.get(key) != new.get(key):
            what = "solver setting" if key in SOLVER_SETTINGS else "scenario spec"
            diffs.append(f"{what} {key!r}: {old.get(key)!r} (store) vs {new.get(key)!r} (now)")
    if store.space.names != space.names:
        diffs.append(f"free parameters: {list(store.space.names)} (store) vs {list(space.names)} (now)")
    else:
        for p, q in zip(store.space.parameters, space.parameters):
            if p != q:
                diffs.append(
                    f"parameter {p.name!r}: {p.lower:g}:{p.upper:g}:{p.scale} {p.unit} (store) vs "
                    f"{q.lower:g}:{q.upper:g}:{q.scale} {q.unit} (now)"
                )
    for name, was, now in (("sampling", store.sampling, sampling), ("seed", store.seed, seed),
                           ("fields", store.has_fields, bool(fields))):
        if was != now:
            diffs.append(f"{name}: {was!r} (store) vs {now!r} (now)")
    if n < store.n_rows:
        diffs.append(f"n: the store has {store.n_rows} rows, n={n} asks for fewer (rows are never removed)")
    elif n > store.n_rows and store.sampling != "sobol":
        diffs.append(
            f"n: {store.n_rows} (store) vs {n} (now); only a 'sobol' store can grow, a "
            f"{store.sampling!r} design cannot be extended"
        )
    if store.software.get("podkrig") != __version__:
        diffs.append(f"podkrig version: {store.software.get('podkrig')} (store) vs {__version__} (now)")
    return diffs


def prepare_store(path, spec, space, *, n, seed, sampling="sobol", fields=False):
    """Create the store, or check that an existing one matches these arguments (and grow it).

    Parameters
    ----------
    path : str or Path
    spec : fe.ScenarioSpec, dict, str or fe.Scenario
        The scenario (a built one is used as is).
    space : ParameterSpace
        Free parameters; names and bounds are checked against the scenario.
    n : int
        Number of rows (samples), >= 1.
    seed : int
        Seed of the design, >= 0.
    sampling : {"sobol", "lhs", "random"}
    fields : bool
        Also store full displacement fields.

    Returns
    -------
    action : {"created", "resumed", "extended"}

    Raises
    ------
    StoreError
        An existing file that is not a usable store, or a store written with other arguments
        (the message lists what differs).
    ValueError
        Invalid arguments.
    """
    path = Path(path)
    if sampling not in METHODS:
        raise ValueError(f"sampling must be one of {METHODS}; got {sampling!r}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1; got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0; got {seed!r}")
    scenario = _scenario_of(spec)
    _check_space(scenario, space)
    if not path.exists():
        U = sample(sampling, n, space.n_params, seed)
        SnapshotStore.create(path, scenario, space, U, sampling=sampling, seed=seed, fields=fields).close()
        return "created"
    with SnapshotStore.open(path, "r") as store:
        diffs = _differences(store, scenario, space, n, seed, sampling, fields)
        n_old = store.n_rows
        U_old = store.parameters(physical=False, only_done=False)
    if diffs:
        raise StoreError(
            f"{path} was written with other arguments: " + "; ".join(diffs)
            + ". Rerun with the store's arguments (see 'podkrig snapshots info') or choose another store"
        )
    if n == n_old:
        return "resumed"
    if not np.array_equal(sample("sobol", n_old, space.n_params, seed), U_old):
        raise StoreError(
            f"{path}: this installation draws a different Sobol' sequence for seed {seed} than the one "
            "that wrote the store (another scipy version?); the sequence cannot be continued"
        )
    SnapshotStore.extend(path, sample("sobol", n - n_old, space.n_params, seed, skip=n_old),
                         source=f"sobol, seed {seed}, points {n_old}..{n - 1}")
    return "extended"


def rows_to_run(path, n, retry_failed=False):
    """FE runs that :func:`run_snapshots` with these arguments would do: all ``n`` for a new store,
    else the pending (and, with ``retry_failed``, failed) rows plus the rows an extension to ``n``
    adds; 0 for a file that is no usable store (the run itself says what is wrong with it)."""
    path = Path(path)
    if not path.exists():
        return n
    try:
        with SnapshotStore.open(path) as store:
            c = store.counts()
    except PodkrigError:
        return 0
    return c["pending"] + (c["failed"] if retry_failed else 0) + max(n - c["total"], 0)


def measured_run_seconds(path):
    """Mean CPU time (s) of the FE runs a store already holds, converged, partial or failed alike
    (what the next runs of the same scenario will cost on average); None for a missing or unusable
    store or one with no run timed yet."""
    path = Path(path)
    if not path.exists():
        return None
    try:
        with SnapshotStore.open(path) as store:
            cpu = store.cpu_times()
    except PodkrigError:
        return None
    cpu = cpu[np.isfinite(cpu)]
    return float(cpu.mean()) if len(cpu) else None


def run_snapshots(path, spec, space, *, n, seed, sampling="sobol", fields=False, workers=None,
                  scheduler=None, retry_failed=False, chunk_size=None, progress=None):
    """Create or resume a snapshot store and run the scenario on its pending rows.

    Parameters
    ----------
    path : str or Path
        The store (created if missing).
    spec : fe.ScenarioSpec, dict, str or fe.Scenario
    space : ParameterSpace
    n : int
        Number of samples; growing it on a Sobol' store appends rows continuing the sequence.
    seed : int
        Seed of the design.
    sampling : {"sobol", "lhs", "random"}
    fields : bool
        Also store full displacement fields (n_loads, n_nodes, 2) per row.
    workers : int, optional
        ``1``: in this process; ``K > 1``: a local Dask cluster of ``K`` processes; default: one
        worker per core (``os.cpu_count()``).
    scheduler : str, optional
        Address of an existing Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"``; excludes ``workers``.
    retry_failed : bool
        Also rerun rows whose FE run failed before.
    chunk_size : int, optional
        Rows per task; default ``ceil(rows / (4 * workers))`` clipped to [1, 32] (serially:
        as many rows as take about :data:`SERIAL_WRITE_SECONDS`, within the same limits).
    progress : callable, optional
        ``progress(completed, total)`` after each written batch (rows of this call).

    Returns
    -------
    RunSummary

    Raises
    ------
    StoreError
        See :func:`prepare_store`.
    PodkrigError
        A task failed outside the FE run, a worker has another podkrig version, or workers kept
        dying; every finished row is kept and a rerun resumes.
    """
    t0 = time.perf_counter()
    _check_executor(workers, scheduler, chunk_size)  # before the store exists: a bad call leaves nothing
    scenario = _scenario_of(spec)
    acquire_lock(path)  # one writer from the first check to the last row: no other run interleaves
    try:
        action = prepare_store(path, scenario, space, n=n, seed=seed, sampling=sampling, fields=fields)
        summary = run_pending(path, workers=workers, scheduler=scheduler, retry_failed=retry_failed,
                              chunk_size=chunk_size, progress=progress, scenario=scenario)
    finally:
        release_lock(path)
    return dataclasses.replace(summary, seconds=time.perf_counter() - t0, action=action)


def _check_executor(workers, scheduler, chunk_size):
    if scheduler is not None and workers is not None:
        raise ValueError("give either workers (a local cluster) or scheduler (an existing one), not both")
    if workers is not None:
        check_workers(workers)
    if chunk_size is not None:
        check_chunk_size(chunk_size)


def run_pending(path, *, workers=None, scheduler=None, retry_failed=False, chunk_size=None,
                progress=None, scenario=None):
    """Run the pending rows of an existing store with its own scenario spec and parameters.

    Parameters are as in :func:`run_snapshots`; ``scenario`` may pass the already built scenario
    of the store's spec (used in this process for ``workers=1``).

    Returns
    -------
    RunSummary
    """
    t0 = time.perf_counter()
    _check_executor(workers, scheduler, chunk_size)
    if workers is None and scheduler is None:
        workers = os.cpu_count() or 1
    path = Path(path)
    with SnapshotStore.open(path, "r+") as store:
        spec_json = store.spec.to_json()
        if scenario is not None and scenario.spec.to_json() == spec_json:
            _cache((spec_json, threading.get_ident()), scenario)
        status = store.status()
        todo = np.flatnonzero((status != DONE) if retry_failed else (status != DONE) & (status != FAILED))
        X = store.parameters(physical=True, only_done=False)[todo]
        n_todo = len(todo)
        executor = "serial"
        n_failed = completed = 0
        client = cluster = results = None
        try:
            if len(todo) and scheduler is None and workers > 1:
                probe, executor = _serial_if_small(spec_json, store, todo, X, workers)
                if probe is not None:  # the first row ran here, to time an FE run
                    _write(store, probe)
                    completed, n_failed = len(probe.rows), int((probe.status == FAILED).sum())
                    if progress is not None:
                        progress(completed, n_todo)
                    todo, X = todo[len(probe.rows):], X[len(probe.rows):]
                    if executor.startswith("serial"):
                        workers = 1
                        logger.info("%s", executor)  # the caller shows it (RunSummary.executor)
            if len(todo) and scheduler is None and workers == 1:
                results = _serial(spec_json, store, todo, X, chunk_size)
            elif len(todo):
                client, cluster, executor, n_workers = _dask_client(workers, scheduler)
                results = _dask(client, spec_json, store, todo, X, chunk_size, n_workers)
            logger.info("%s: running %d rows on %s", path, len(todo), executor)
            for res in results or ():
                _write(store, res)
                completed += len(res.rows)
                n_failed += int((res.status == FAILED).sum())
                if progress is not None:
                    progress(completed, n_todo)
        finally:  # also on Ctrl-C: cancel what is left, stop a local cluster
            if results is not None:
                results.close()
            if cluster is not None:  # a local cluster: in order, without its shutdown noise
                close_local_cluster(client, cluster)
            elif client is not None:  # an existing scheduler stays up; its workers are not ours
                client.close()
        counts = store.counts()
    return RunSummary(path, counts["total"], counts["done"], counts["failed"], counts["pending"],
                      n_todo, n_failed, time.perf_counter() - t0, executor)


def _write(store, res):
    if res.version != __version__:
        raise PodkrigError(
            f"a Dask worker runs podkrig {res.version}, this client {__version__}; install "
            "the same podkrig version on every worker and rerun (finished rows are kept)"
        )
    store.write_results(res.rows, res.status, res.readings, res.errors, res.wall_times, res.fields, res.cpu_times)


def _serial_if_small(spec_json, store, todo, X, workers):
    """Run the first two pending rows here to time an FE run, and decide whether a local cluster of
    ``workers`` pays for the rest: the serial time saved, ``n t (1 − 1/K)``, must exceed
    :data:`LOCAL_CLUSTER_STARTUP_S`. Returns (the first row's :class:`ChunkResult`, the executor
    text: ``"serial: ..."`` with the reason when the saving is at least
    :data:`SERIAL_REASON_MIN_SAVING_S`, ``"serial"`` below, or the local cluster's); (None, "")
    when the cluster start-up is set to 0 (always use the cluster)."""
    if LOCAL_CLUSTER_STARTUP_S <= 0:
        return None, ""
    # two rows: the first FE run in a process also pays one-off set-up (caches, JIT compilation)
    probe = run_chunk(spec_json, store.space.names, todo[:2], X[:2], store.has_fields)
    t = float(np.min(probe.wall_times))
    rest = len(todo) - len(probe.rows)
    saved = rest * t * (1 - 1 / workers)
    if saved < SERIAL_REASON_MIN_SAVING_S:
        return probe, "serial"
    if saved < LOCAL_CLUSTER_STARTUP_S:
        return probe, (f"serial: {workers} workers asked, but {len(todo)} runs × {1000 * t:.0f} ms per run would save "
                       f"{saved:.1f} s on {workers} processes, less than a local cluster takes to start "
                       f"(≈ {LOCAL_CLUSTER_STARTUP_S:g} s)")
    return probe, f"local Dask cluster, {workers} workers"


def _chunks(todo, X, chunk_size, n_workers):
    size = chunk_size or max(1, min(MAX_CHUNK, math.ceil(len(todo) / (4 * n_workers))))
    for start in range(0, len(todo), size):
        yield todo[start:start + size], X[start:start + size]


def _serial(spec_json, store, todo, X, chunk_size):
    """Chunks run in this process: ``chunk_size`` rows each, or by default chunks sized by the
    previous chunk's time per row to take :data:`SERIAL_WRITE_SECONDS` (starting at one row, at most
    the Dask default's size), so that each is written before much finished work could be lost."""
    if chunk_size is not None:
        for rows, Xc in _chunks(todo, X, chunk_size, 1):
            yield run_chunk(spec_json, store.space.names, rows, Xc, store.has_fields)
        return
    cap = max(1, min(MAX_CHUNK, math.ceil(len(todo) / 4)))
    start, size = 0, 1
    while start < len(todo):
        t0 = time.perf_counter()
        res = run_chunk(spec_json, store.space.names, todo[start:start + size], X[start:start + size],
                        store.has_fields)
        per_row = (time.perf_counter() - t0) / len(res.rows)
        start += len(res.rows)
        yield res
        size = int(np.clip(SERIAL_WRITE_SECONDS // max(per_row, 1e-9), 1, cap))


#: top-level loggers of this project (:func:`import_distributed` re-enables them)
PROJECT_LOGGERS = ("podkrig", "fe")
#: loggers of Dask and its dependencies, quiet (WARNING and above) unless podkrig logs at DEBUG
DASK_LOGGERS = ("distributed", "dask", "tornado", "bokeh")


def import_distributed():
    """Import :mod:`distributed` (≈ 0.6 s, so only when a Dask executor is used) and repair what its
    import does to logging in this process.

    - Importing ``distributed`` configures logging from the Dask config; with a dict-schema
      ``logging`` config (``version: 1``) that is :func:`logging.config.dictConfig`, which
      *disables every logger that exists then* — podkrig's and fe's warnings would vanish for the
      rest of the process. Every disabled ``podkrig.*`` / ``fe.*`` logger is enabled again.
    - Dask's own loggers print INFO lines (cluster start, worker registration, ...): they are set
      to WARNING unless podkrig logs at DEBUG (``--verbose``).

    Returns the module.
    """
    import distributed  # local: ≈ 0.6 s of imports (measured 2026-11-24) that a serial run never needs

    for name, logger in list(logging.root.manager.loggerDict.items()):
        if isinstance(logger, logging.Logger) and name.split(".")[0] in PROJECT_LOGGERS:
            logger.disabled = False
    if not logging.getLogger("podkrig").isEnabledFor(logging.DEBUG):
        for name in DASK_LOGGERS:
            if logging.getLogger(name).getEffectiveLevel() < logging.WARNING:
                logging.getLogger(name).setLevel(logging.WARNING)
    return distributed


def _dask_client(workers, scheduler):
    Client = import_distributed().Client

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="30s")
        except OSError as e:
            raise PodkrigError(
                f"cannot connect to the Dask scheduler at {scheduler!r} ({e}); is 'dask scheduler' "
                "running there and reachable?"
            ) from e
        n_workers = len(client.scheduler_info().get("workers", {}))
        if n_workers == 0:
            logger.warning("the Dask scheduler at %s has no workers yet; tasks wait for one", scheduler)
        return client, None, f"Dask scheduler {scheduler}, {n_workers} workers", max(n_workers, 1)
    return (*start_local_cluster(workers), f"local Dask cluster, {workers} workers", workers)


def start_local_cluster(workers):
    """A local Dask cluster as the runner uses it, and a client connected to it.

    ``workers`` processes with one thread each, :data:`ONE_THREAD_ENV` in their environment,
    :data:`LOCAL_DASK_CONFIG`, no dashboard (the scheduler's HTTP endpoint takes a free port).

    Returns
    -------
    client : distributed.Client
    cluster : distributed.LocalCluster
    """
    import dask

    distributed = import_distributed()
    verbose = logging.getLogger("podkrig").isEnabledFor(logging.DEBUG)
    with dask.config.set(LOCAL_DASK_CONFIG):  # read by the scheduler and passed on to the workers
        cluster = distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
            scheduler_kwargs={"dashboard_address": ":0"}, env=ONE_THREAD_ENV,
            silence_logs=logging.INFO if verbose else logging.WARNING,
        )
        return distributed.Client(cluster), cluster


def _dask(client, spec_json, store, todo, X, chunk_size, n_workers):
    as_completed = import_distributed().as_completed

    names = store.space.names
    tag = uuid.uuid4().hex[:8]
    pending = []
    try:
        for rows, Xc in _chunks(todo, X, chunk_size, n_workers):
            pending.append(client.submit(
                run_chunk, spec_json, names, rows, Xc, store.has_fields, True,
                key=f"podkrig-rows-{tag}-{rows[0]}-{rows[-1]}", pure=False,
            ))
        for future in as_completed(list(pending)):
            pending.remove(future)
            try:
                result = future.result()
            except Exception as e:  # KilledWorker, a broken environment on a worker, ...
                raise PodkrigError(
                    f"a Dask task failed outside the FE run ({type(e).__name__}: {e}); finished rows "
                    "are kept in the store, rerun the same command to resume"
                ) from e
            future.release()
            yield result
    finally:
        if pending:
            client.cancel(pending)
