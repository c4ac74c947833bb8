"""Thread rules of podkrig.parallel: cores available (affinity, cgroup quota), threads per batch,
scoped numba settings, and the serial entry point of the kriging kernels for small batches."""

import os
import threading

import numba
import numpy as np
import pytest

from podkrig import parallel
from podkrig.surrogate.kriging import _kernels


@pytest.mark.parametrize(
    "text, cores",
    [("max 100000\n", None), ("150000 100000\n", 1.5), ("200000 100000", 2.0), ("50000 100000", 0.5), ("", None)],
)
def test_cgroup_v2_cpu_max(tmp_path, text, cores):
    (tmp_path / "cpu.max").write_text(text)
    assert parallel.cgroup_cpu_limit(tmp_path) == cores


@pytest.mark.parametrize("folder", ["cpu", "cpu,cpuacct", "."])
@pytest.mark.parametrize("quota, period, cores", [("-1", "100000", None), ("300000", "100000", 3.0), ("25000", "100000", 0.25)])
def test_cgroup_v1_cfs_quota(tmp_path, folder, quota, period, cores):
    d = tmp_path / folder
    d.mkdir(exist_ok=True)
    (d / "cpu.cfs_quota_us").write_text(quota + "\n")
    (d / "cpu.cfs_period_us").write_text(period + "\n")
    assert parallel.cgroup_cpu_limit(tmp_path) == cores


def test_no_cgroup_files_or_garbage_mean_no_quota(tmp_path):
    assert parallel.cgroup_cpu_limit(tmp_path) is None
    (tmp_path / "cpu.cfs_quota_us").write_text("lots\n")
    (tmp_path / "cpu.cfs_period_us").write_text("100000\n")
    assert parallel.cgroup_cpu_limit(tmp_path) is None


@pytest.mark.parametrize("affinity, quota, cores", [(4, None, 4), (4, 1.5, 2), (8, 0.25, 1), (2, 16.0, 2), (1, None, 1)])
def test_cores_are_the_smaller_of_affinity_and_quota_rounded_up(affinity, quota, cores):
    assert parallel.cores_from(affinity, quota) == cores


def test_available_cores_within_affinity():
    assert 1 <= parallel.available_cores() <= len(os.sched_getaffinity(0))


def test_threads_for_keeps_small_work_on_one_thread(monkeypatch):
    monkeypatch.setattr(parallel, "max_numba_threads", lambda: 4)
    w = parallel.MIN_WORK_PER_THREAD
    assert parallel.threads_for(0) == 1
    assert parallel.threads_for(1.99 * w) == 1
    assert parallel.threads_for(2 * w) == 2
    assert parallel.threads_for(3.5 * w) == 3
    assert parallel.threads_for(100 * w) == 4  # never above the cores available
    assert parallel.threads_for(1.0, min_work_per_thread=0) == 4  # 0: split every call


def test_chunks_cover_several_per_thread():
    assert parallel.chunk_size(100, 2) == 32  # minimum
    assert parallel.chunk_size(2**16, 2) == 2**16 // (2 * parallel.CHUNKS_PER_THREAD)
    assert parallel.chunk_size(1001, 2, minimum=1) == 63  # rounded up: 16 chunks cover 1001 points


def test_numba_threads_scope_is_restored_and_thread_local():
    before = numba.get_num_threads()
    with pytest.raises(RuntimeError), parallel.numba_threads(1):
        assert numba.get_num_threads() == 1
        assert numba.get_parallel_chunksize() == 1
        raise RuntimeError("inside")
    assert numba.get_num_threads() == before
    assert numba.get_parallel_chunksize() == 0
    seen = {}

    def other():  # another Python thread does not see this thread's scope
        seen["threads"] = numba.get_num_threads()

    with parallel.numba_threads(1):
        t = threading.Thread(target=other)
        t.start()
        t.join()
    assert seen["threads"] == numba.config.NUMBA_NUM_THREADS


def test_small_batch_runs_on_one_thread_with_the_same_result(monkeypatch):
    """A GA-sized batch runs on one numba thread in one chunk, a region-sized batch on all threads
    in several chunks per thread; the result of the small batch is bitwise that of a forced
    two-thread run, and both agree with the literal NumPy formula."""
    rng = np.random.default_rng(3)
    Xt, theta, beta = rng.random((200, 4)), rng.random((3, 4)) * 2, np.array([1.9995, 1.9991, 1.7])
    alpha, mu = rng.standard_normal((3, 200)), rng.standard_normal(3)
    calls = []
    kernel = _kernels._predict_mean_parallel

    def spy(*args):
        calls.append((numba.get_num_threads(), args[-1]))  # threads in effect, chunk
        return kernel(*args)

    monkeypatch.setattr(_kernels, "_predict_mean_parallel", spy)
    monkeypatch.setattr(parallel, "max_numba_threads", lambda: 2)
    small = rng.random((100, 4))
    auto = _kernels.predict_mean(small, Xt, theta, beta, 0, alpha, mu, use_numba=True)
    assert calls == [(1, 100)]
    forced = _kernels.predict_mean(small, Xt, theta, beta, 0, alpha, mu, use_numba=True, threads=2)
    assert calls[-1] == (2, 32)
    np.testing.assert_array_equal(auto, forced)
    n_large = int(2 * parallel.MIN_WORK_PER_THREAD / (200 * 3)) + 1
    _kernels.predict_mean(rng.random((n_large, 4)), Xt, theta, beta, 0, alpha, mu, use_numba=True)
    assert calls[-1] == (2, parallel.chunk_size(n_large, 2))
    # rounding of exp/log (~1e-14 relative) in sums of 200 terms of size |alpha| <= 4: bound 1e-10
    ref = _kernels.predict_mean_numpy(small, Xt, theta, beta, 0, alpha, mu)
    np.testing.assert_allclose(auto, ref, rtol=0, atol=1e-10)
