"""Who uses the cores: core detection, numba thread counts per batch, BLAS limits.

The online numerics are many small calls (a GA population of 100 points, a 24-reading misfit)
and a few large ones (a region of 10⁶ points). Splitting a small call over threads only adds a
barrier: on a machine where another process keeps one core busy, every split call waits for a
thread the operating system has parked behind that process, and an inversion took 9-12 s with two
numba threads against 0.65 s with one. The rules of this module:

- **Cores actually available** (:func:`available_cores`): the smaller of the CPU affinity of the
  process (``os.sched_getaffinity``) and the cgroup CPU quota (v2 ``cpu.max``, v1
  ``cpu.cfs_quota_us / cpu.cfs_period_us``, rounded up). Numba never gets more threads than that.
- **Small batches on one thread** (:func:`threads_for`): a call runs on several threads only when
  each thread gets at least :data:`MIN_WORK_PER_THREAD` units of work (the caller's cost estimate,
  e.g. prediction points × training points × outputs for the kriging kernels), so that a parked
  thread delays a large call by a small fraction at most. Below that, a kernel runs on one
  thread (``numba.set_num_threads(1)`` for the call: the pool is not woken; the same compiled
  code as on several threads, so results stay bitwise independent of the thread count).
- **Large batches in chunks** (:func:`chunk_size`): the points are cut into several chunks per
  thread, so a thread that runs while its peer is parked takes more of them.
- **One owner of the cores**: in the online stage numba owns the cores and BLAS gets one thread
  (:func:`one_blas_thread`): the BLAS calls there are small (triangular solves with a few hundred
  unknowns, a 24 × 24 misfit), and an idle OpenBLAS pool that spins after a call takes a core
  from the numba threads.

Thread counts set here are scoped (:func:`numba_threads`): ``numba.set_num_threads`` is
thread-local, so the scope is safe when several Python threads predict at once, and the previous
count is restored on exit, also on an exception.
"""

import logging
import math
import os
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

import numba
from threadpoolctl import ThreadpoolController

#: Work units per thread below which a call is not split. One unit is one kernel entry (one
#: prediction point × one training point × one output: ~2-4 ns on one core of the reference
#: machine), so 2e6 units are ~5 ms of work: a GA population (100 points × 256 training points ×
#: 6 outputs = 1.5e5) stays on one thread, a region batch of 65 536 points is split. Measured with
#: ``scripts/bench_inverse.py --background 1`` (BENCHMARKS.md, "Online stage under load").
MIN_WORK_PER_THREAD = 2.0e6

#: Chunks per thread of a split call (dynamic balance when one thread is slowed down).
CHUNKS_PER_THREAD = 8

logger = logging.getLogger(__name__)

_CGROUP_ROOT = Path("/sys/fs/cgroup")
_BLAS_CONTROLLER = None


def cgroup_cpu_limit(root=_CGROUP_ROOT):
    """CPU quota of the cgroup in cores (a float, e.g. 1.5), or ``None`` when unlimited/unknown.

    Parameters
    ----------
    root : path
        Mount point of the cgroup file system. Reads cgroup v2 ``cpu.max`` (``"max 100000"`` or
        ``"150000 100000"``: quota and period in µs) and else cgroup v1
        ``cpu/cpu.cfs_quota_us`` (``-1`` when unlimited) with ``cpu/cpu.cfs_period_us`` (or the
        same files directly under ``root``).
    """
    root = Path(root)
    v2 = root / "cpu.max"
    if v2.is_file():
        fields = v2.read_text().split()
        if len(fields) >= 2 and fields[0] != "max":
            return _quota(fields[0], fields[1])
        return None
    for folder in (root / "cpu", root / "cpu,cpuacct", root):
        quota, period = folder / "cpu.cfs_quota_us", folder / "cpu.cfs_period_us"
        if quota.is_file() and period.is_file():
            return _quota(quota.read_text().strip(), period.read_text().strip())
    return None


def _quota(quota, period):
    """``quota / period`` in cores, ``None`` for a negative (unlimited) or unreadable quota."""
    try:
        q, p = int(quota), int(period)
    except ValueError:
        return None
    if q <= 0 or p <= 0:
        return None
    return q / p


def affinity_cores():
    """Number of CPUs this process may run on (``os.sched_getaffinity``; ``os.cpu_count`` where
    affinity is not supported)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - macOS, Windows
        return os.cpu_count() or 1


def cores_from(affinity, quota):
    """Cores available from an affinity count and a cgroup quota in cores (``None``: no quota):
    the smaller of the two, a fractional quota rounded up, at least 1."""
    cores = affinity if quota is None else min(affinity, math.ceil(quota))
    return max(1, int(cores))


@lru_cache(maxsize=1)
def available_cores():
    """Cores actually available to the process: affinity and cgroup quota (see the module notes).
    Computed once per process."""
    return cores_from(affinity_cores(), cgroup_cpu_limit())


def max_numba_threads():
    """Most numba threads a call may use: the current numba setting of this Python thread, the
    size of numba's pool and :func:`available_cores`, whichever is smallest."""
    return max(1, min(numba.get_num_threads(), numba.config.NUMBA_NUM_THREADS, available_cores()))


def threads_for(work, min_work_per_thread=None):
    """Threads worth using for a call of ``work`` units: as many as get ``min_work_per_thread``
    units each (so 1 below ``2 × min_work_per_thread``), at most :func:`max_numba_threads`.
    ``min_work_per_thread`` defaults to :data:`MIN_WORK_PER_THREAD` (read at the call)."""
    if min_work_per_thread is None:
        min_work_per_thread = MIN_WORK_PER_THREAD
    if min_work_per_thread <= 0:
        return max_numba_threads()
    return int(max(1, min(max_numba_threads(), work // min_work_per_thread)))


def chunk_size(n_items, threads, minimum=32):
    """Items per chunk when ``n_items`` are split over ``threads``: :data:`CHUNKS_PER_THREAD`
    chunks per thread, at least ``minimum`` items each."""
    return max(minimum, -(-n_items // (threads * CHUNKS_PER_THREAD)))


@contextmanager
def numba_threads(n):
    """Run numba parallel kernels on ``n`` threads inside the block, their ``prange`` iterations
    handed out one at a time (``numba.set_parallel_chunksize(1)``: a thread that runs while its
    peer is parked takes more chunks). Both settings are thread-local and restored on exit. ``n``
    is clipped to 1..size of numba's pool."""
    before = numba.get_num_threads()
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
    chunks_before = numba.set_parallel_chunksize(1)
    try:
        yield
    finally:
        numba.set_parallel_chunksize(chunks_before)
        numba.set_num_threads(before)


def one_blas_thread():
    """Context manager limiting BLAS libraries to one thread (the online stage: see the module notes).

    The controller is built once per process: scanning the loaded libraries costs milliseconds,
    too much per prediction call. An inversion took 0.87 s with two OpenBLAS threads against
    0.57 s with one on an idle machine.
    """
    global _BLAS_CONTROLLER
    if _BLAS_CONTROLLER is None:
        _BLAS_CONTROLLER = ThreadpoolController()
    return _BLAS_CONTROLLER.limit(limits=1, user_api="blas")


#: loggers of Dask's distributed scheduler and workers and of the event loop under them: what a
#: local cluster logs while it shuts down (:func:`close_local_cluster`)
SHUTDOWN_LOGGERS = ("distributed", "tornado", "asyncio")


def _loggers_under(names):
    """The loggers ``names`` and every existing logger below them (``distributed.nanny``, ...)."""
    prefixes = tuple(f"{n}." for n in names)
    below = [lg for name, lg in list(logging.root.manager.loggerDict.items())
             if isinstance(lg, logging.Logger) and name.startswith(prefixes)]
    return [logging.getLogger(n) for n in names] + below


@contextmanager
def quiet_loggers(names=SHUTDOWN_LOGGERS):
    """Switch the loggers ``names`` and every logger below them off inside the block (each one
    itself: Dask's configuration gives some, e.g. ``tornado.application``, their own level),
    restoring each one's state on exit, also on an exception."""
    loggers = _loggers_under(names)
    before = [lg.disabled for lg in loggers]
    for lg in loggers:
        lg.disabled = True
    try:
        yield
    finally:
        for lg, was in zip(loggers, before):
            lg.disabled = was


def _silence_shutdown():
    """Run on each worker process of a local cluster just before it is closed: its
    :data:`SHUTDOWN_LOGGERS` stop writing to the stderr it shares with the client (the process
    exits right after)."""
    for lg in _loggers_under(SHUTDOWN_LOGGERS):
        lg.disabled = True


def close_local_cluster(client, cluster):
    """Shut a local Dask cluster down in order, without the noise of its shutdown.

    A correct run used to end with ``CommClosedError`` tracebacks and ``Worker process still alive
    after 4.0 seconds, killing`` warnings: on a loaded machine the worker processes exit slower than
    the nanny waits, and whichever side is closed first logs the lost connection of the others.
    The order here: the workers' own shutdown loggers are silenced (``client.run``: they share this
    process's stderr and are about to exit), the client disconnects, then the cluster closes its
    workers and scheduler — with this process's :data:`SHUTDOWN_LOGGERS` quiet only during that
    close (:func:`quiet_loggers`), so a warning of Dask before or after it still shows.

    Parameters
    ----------
    client : distributed.Client or None
        Connected to ``cluster``; None when it was never made.
    cluster : distributed.LocalCluster or None
    """
    with quiet_loggers():
        if client is not None:
            if cluster is not None:
                try:
                    client.run(_silence_shutdown)
                except Exception:  # noqa: BLE001 - a worker already gone needs no silencing
                    logger.debug("could not silence the workers before the shutdown", exc_info=True)
            client.close()
        if cluster is not None:
            cluster.close()
