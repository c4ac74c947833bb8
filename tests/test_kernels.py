"""The Python layer of the prediction kernels (``surrogate/kriging/_kernels.py``): the numba switch a
user sets, the NumPy twins in chunks, and the plan's reach when points lie outside the training box
on one side only (issue 12: mutation survivors)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig.offline.sampling import sobol, uniform
from podkrig.surrogate.kriging import OrdinaryKriging, _kernels

needs_numba = pytest.mark.skipif(_kernels.njit is None, reason="numba not installed")


@pytest.mark.parametrize("value, enabled", [("", True), ("0", True), ("no", True), ("1", False), ("true", False),
                                            (" True ", False), ("YES", False), ("yes", False)])
def test_the_environment_switch_and_the_explicit_setting(monkeypatch, value, enabled):
    """``PODKRIG_DISABLE_NUMBA`` = 1 / true / yes (any case, spaces ignored) turns the numba kernels
    off unless a setting says otherwise; an explicit ``use_numba`` always wins. Defects: another
    variable name, a spelling not recognised, the explicit setting ignored."""
    monkeypatch.setenv("PODKRIG_DISABLE_NUMBA", value)
    assert _kernels.numba_enabled() is enabled and _kernels.numba_enabled(None) is enabled
    assert _kernels.numba_enabled(True) is True and _kernels.numba_enabled(False) is False
    monkeypatch.delenv("PODKRIG_DISABLE_NUMBA")
    assert _kernels.numba_enabled() is True  # not set: on


@needs_numba
@pytest.mark.parametrize("use_numba", [False, True])
def test_the_estimators_setting_chooses_the_kernels(monkeypatch, use_numba):
    """``OrdinaryKriging(use_numba=False)`` predicts means and variances with the NumPy twins, and
    ``True`` with the numba kernels, whatever the environment says. Defects: the setting not passed
    down (the environment decides), or overridden when numba is installed."""
    monkeypatch.setenv("PODKRIG_DISABLE_NUMBA", "0" if not use_numba else "1")
    calls = []
    for name in ("predict_mean_numpy", "cross_covariance_numpy"):
        real = getattr(_kernels, name)
        monkeypatch.setattr(_kernels, name, lambda *a, _real=real, _name=name: calls.append(_name) or _real(*a))
    X = sobol(16, 2, seed=0)
    fitted = OrdinaryKriging(beta=1.5, use_numba=use_numba).fit(X, np.sin(3 * X[:, 0]) + X[:, 1])
    fitted.predict(uniform(5, 2, seed=1))
    fitted.predict(uniform(5, 2, seed=1), return_std=True)
    assert calls == ([] if use_numba else ["predict_mean_numpy", "predict_mean_numpy", "cross_covariance_numpy"])


@needs_numba
def test_the_numpy_twins_cover_every_point_in_chunks(monkeypatch):
    """With more prediction points than a chunk (7 here, 30 points: chunks of 7, 7, 7, 7, 2) the
    NumPy twins give every point the numba kernels' value. Defects: chunks stepping over the
    dimensions instead of the points, or stopping after the first."""
    monkeypatch.setattr(_kernels, "_CHUNK", 7)
    rng = np.random.default_rng(3)
    Xp, Xt = rng.random((30, 3)), rng.random((12, 3))
    beta, theta = np.array([1.5, 1.9]), rng.uniform(0.5, 4.0, (2, 3))
    alpha, mu = rng.random((2, 12)), np.array([0.3, -1.0])
    for kind in (0, 1):
        ref = _kernels.predict_mean(Xp, Xt, theta, beta, kind, alpha, mu, use_numba=True)
        assert_allclose(_kernels.predict_mean_numpy(Xp, Xt, theta, beta, kind, alpha, mu), ref, rtol=1e-13)
        K = _kernels.predict_mean_and_covariance(Xp, Xt, theta, beta, kind, alpha, mu, use_numba=True)[1]
        for j in range(2):
            # kind 1 is -s itself: an absolute bound of the kernels' expansion (see test_kriging.py)
            assert_allclose(_kernels.cross_covariance_numpy(Xp, Xt, theta[j], beta[j], kind), K[j], rtol=1e-13,
                            atol=1e-15 * np.abs(K[j]).max())


def test_the_reach_of_a_batch_counts_both_sides_of_the_training_box():
    """The largest coordinate difference the plan must cover: points beyond the training box on
    one side only (below by 0.9 here, above by 0.05) reach 1.9 across it, the largest of either
    direction; a batch inside the unit cube reaches at most 1 (exactly 1 with points on opposite
    faces);
    an empty batch plans for the unit cube; differences are taken per coordinate. Defects: one
    direction left out, coordinates mixed, the empty case changed."""
    Xt = np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.2]])
    assert _kernels._delta_max(np.array([[-0.9, 0.5], [1.05, 0.5]]), Xt) == pytest.approx(1.9, rel=1e-15)
    assert _kernels._delta_max(np.array([[0.5, 1.05], [0.5, 0.3]]), Xt) == pytest.approx(1.05, rel=1e-15)
    assert _kernels._delta_max(np.array([[0.0, 1.0], [0.6, 0.5]]), Xt) == 1.0
    assert _kernels._delta_max(np.array([[0.5, 0.5]]), Xt) == 0.5
    assert _kernels._delta_max(np.array([[0.5, 0.5]]), np.array([[0.5, 0.5]])) == 0.0
    assert _kernels._delta_max(np.empty((0, 2)), Xt) == 1.0
    # per coordinate, not across coordinates (a box far from the origin in one of them)
    assert _kernels._delta_max(np.array([[0.5, 10.5]]), np.array([[0.0, 10.0], [1.0, 11.0]])) == 0.5
