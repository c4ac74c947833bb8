"""POD: known orthonormal bases, truncation by energy or count, round trips, method agreement."""

import logging
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig.exceptions import NotFittedError
from podkrig.surrogate.pod import POD


def _data(rng, n=40, m=30, rank=5, center=True):
    """Snapshots mean + A @ Phi with a known orthonormal Phi (rank, m) and decaying coefficients."""
    r = np.random.default_rng(rng)
    Phi = np.linalg.qr(r.standard_normal((m, rank)))[0].T
    A = r.standard_normal((n, rank)) * (10.0 ** -np.arange(rank))[None, :]
    A -= A.mean(axis=0)
    mean = r.standard_normal(m) if center else np.zeros(m)
    return mean + A @ Phi, Phi, mean


@pytest.mark.parametrize("method", ["svd", "snapshots"])
def test_recovers_known_basis(method):
    Y, Phi, _ = _data(0)
    pod = POD(energy=1.0, method=method).fit(Y)
    assert pod.n_modes_ == 5
    # orthonormal rows; rounding-level tolerance (the method of snapshots squares the condition
    # number, so its smallest mode (1e-4 of the first) is accurate to ~1e-8 only)
    assert_allclose(pod.modes_ @ pod.modes_.T, np.eye(5), rtol=0, atol=1e-12 if method == "svd" else 1e-8)
    # same subspace: the known basis projects onto the modes without residual
    resid = Phi - (Phi @ pod.modes_.T) @ pod.modes_
    assert_allclose(resid, 0.0, rtol=0, atol=1e-8)
    assert_allclose(pod.mean_, Y.mean(axis=0), rtol=0, atol=1e-14)
    assert_allclose(pod.inverse_transform(pod.transform(Y)), Y, rtol=0, atol=1e-10)
    assert_allclose(pod.projection_error(Y), 0.0, rtol=0, atol=1e-10)


def test_svd_and_snapshots_agree():
    Y, _, _ = _data(1, n=20, m=200, rank=4)
    a, b = POD(n_modes=4, method="svd").fit(Y), POD(n_modes=4, method="snapshots").fit(Y)
    assert b.method_ == "snapshots" and POD(n_modes=4).fit(Y).method_ == "snapshots"  # auto: m > 4n
    assert_allclose(a.singular_values_[:4], b.singular_values_[:4], rtol=1e-10, atol=0)
    assert_allclose(a.modes_, b.modes_, rtol=0, atol=1e-7)  # signs are fixed deterministically


def test_energy_truncation_keeps_fewest_modes():
    Y, _, _ = _data(2, rank=5)
    full = POD().fit(Y)
    for energy in (0.5, 0.99, 0.9999, 0.999999):
        pod = POD(energy=energy).fit(Y)
        k = pod.n_modes_
        assert full.energy_[k - 1] >= energy - 1e-12
        assert k == 1 or full.energy_[k - 2] < energy
    assert POD(n_modes=2).fit(Y).n_modes_ == 2


def test_truncation_residual_variance():
    Y, _, _ = _data(3, rank=5)
    pod = POD(n_modes=3).fit(Y)
    R = Y - pod.project(Y)
    assert_allclose(pod.residual_variance_, np.mean(R**2, axis=0), rtol=1e-10, atol=1e-30)
    # discarded energy = sum of the discarded singular values squared
    assert_allclose(np.sum(R**2), np.sum(pod.singular_values_[3:] ** 2), rtol=1e-8, atol=0)


def test_input_not_modified_and_uncentred():
    Y, _, _ = _data(4)
    before = Y.copy()
    POD(energy=0.99).fit(Y)
    assert np.array_equal(Y, before)
    pod = POD(center=False).fit(Y)
    assert np.all(pod.mean_ == 0) and pod.n_modes_ == 6  # the mean becomes a sixth direction


@pytest.mark.parametrize(
    "kwargs, data, message",
    [
        ({"n_modes": 2, "energy": 0.9}, None, "either n_modes or energy"),
        ({"energy": 1.5}, None, "0 < energy <= 1"),
        ({"n_modes": 0}, None, "n_modes .*integer >= 1"),
        ({"n_modes": True}, None, "n_modes .*integer >= 1"),
        ({"energy": 0.0}, None, r"< energy <= 1; got 0.0.*energy=0.9999"),
        ({"n_modes": 9}, None, "exceeds the numerical rank 5"),
        ({"method": "qr"}, None, "method must be one of"),
        ({}, np.ones((5, 3)), "all snapshots are identical"),
        ({}, np.full((4, 3), np.nan), r"Y must be finite.*drop failed FE runs"),
        ({}, np.ones(3), r"Y must have shape .*got shape \(3,\)"),
        ({}, np.ones((1, 3)), "at least 2 snapshots; got 1"),
        ({"method": "snapshots"}, np.ones((5, 30)), r"all snapshots are identical"),
    ],
)
def test_errors(kwargs, data, message):
    Y = _data(5)[0] if data is None else data
    with pytest.raises(ValueError, match=message):
        POD(**kwargs).fit(Y)


def test_not_fitted():
    with pytest.raises(NotFittedError, match=r"POD instance is not fitted.*fit\(Y\)"):
        POD().transform(np.ones((2, 3)))


def test_projection_error_against_a_hand_computed_basis():
    """Uncentred rows 3 e1 and e2 give modes e1 (σ = 3) and e2 (σ = 1); one mode keeps e1, so the
    error of (1, 2, 2) is |(0, 2, 2)| = √8 and of e2 is 1 (absolute; relative divides by |y|)."""
    pod = POD(n_modes=1, center=False).fit(np.array([[3.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    Y = np.array([[3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 2.0, 2.0], [0.0, 0.0, 0.0]])
    assert_allclose(pod.projection_error(Y, relative=False), [0.0, 1.0, np.sqrt(8.0), 0.0], rtol=1e-12, atol=1e-15)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the zero snapshot is 0 / 0: 0 without an invalid-value warning
        assert_allclose(pod.projection_error(Y), [0.0, 1.0, np.sqrt(8.0) / 3.0, 0.0], rtol=1e-12, atol=1e-15)
    # centred, mean (1, 1, 0) and mode e1: the zero snapshot has error |(0, -1, 0)| = 1 and norm 0,
    # so its relative error is inf, without a divide-by-zero warning
    centred = POD().fit(np.array([[2.0, 1.0, 0.0], [0.0, 1.0, 0.0]]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rel = centred.projection_error(np.zeros((1, 3)))
    assert rel.tolist() == [np.inf]
    assert_allclose(centred.projection_error(np.zeros((1, 3)), relative=False), [1.0], rtol=1e-12)


def test_settings_round_trip_and_the_auto_method_threshold():
    """``get_params`` rebuilds an equal POD; "auto" takes the method of snapshots only when
    n_outputs > 4 n_samples; one mode and two snapshots are valid."""
    pod = POD(n_modes=1, center=False, method="svd")
    assert pod.get_params() == {"n_modes": 1, "energy": None, "center": False, "method": "svd", "blocks": None}
    assert POD(**POD(energy=0.5).get_params()).get_params()["energy"] == 0.5
    Y, _, _ = _data(6, n=5, m=20, rank=2)
    assert POD().fit(Y).method_ == "svd"  # m = 4 n
    assert POD().fit(np.hstack([Y, Y[:, :1]])).method_ == "snapshots"  # m = 4 n + 1
    two = POD(n_modes=1, method="snapshots").fit(Y[:2])
    assert two.n_modes_ == 1 and two.n_samples_ == 2


def test_snapshots_method_keeps_the_rank_for_small_readings_without_warnings():
    """Readings of ~1e-5 mm with singular values 1 : 1e-3 (rank 2): the method of snapshots keeps
    exactly 2 modes (the Gram matrix's rounding-level eigenvalues, ~1e-8 of σ₁ after the square
    root, are dropped by the 1e-7 cut) and its clipped square root raises no warning."""
    r = np.random.default_rng(7)
    Phi = np.linalg.qr(r.standard_normal((200, 2)))[0].T
    A = r.standard_normal((20, 2)) * np.array([1.0, 1e-3])
    Y = 1e-5 * (A @ Phi)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pod = POD(method="snapshots").fit(Y)
    assert pod.n_modes_ == 2
    ref = POD(method="svd").fit(Y)
    assert_allclose(pod.singular_values_, ref.singular_values_[:2], rtol=1e-6)


def test_wrong_widths_are_named():
    Y, _, _ = _data(8)
    pod = POD(n_modes=5).fit(Y)
    with pytest.raises(ValueError, match=r"Y must have shape \(n_samples, 30\).*got \(2, 29\)"):
        pod.transform(Y[:2, :29])
    with pytest.raises(ValueError, match=r"A must have shape \(n_samples, 5\).*got \(2, 4\)"):
        pod.inverse_transform(np.zeros((2, 4)))


def test_energy_curve_and_truncation_by_energy_on_a_hand_basis(caplog):
    """Singular values 3 and 1: energies 9/10 and 1; energy=0.9 keeps exactly one mode (the 1e-12
    tolerance absorbs rounding of the sum), anything above keeps both; fit logs its summary."""
    Y = np.array([[3.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    with caplog.at_level(logging.INFO, logger="podkrig.surrogate.pod"):
        pod = POD(energy=0.9, center=False, method="svd").fit(Y)
    assert_allclose(pod.singular_values_, [3.0, 1.0], rtol=1e-14)
    assert_allclose(pod.energy_, [0.9, 1.0], rtol=1e-14)
    assert pod.n_modes_ == 1 and pod.retained_energy_ == pytest.approx(0.9, rel=1e-14)
    assert POD(energy=0.9 + 1e-9, center=False).fit(Y).n_modes_ == 2
    (record,) = caplog.records
    assert (record.name, record.levelno) == ("podkrig.surrogate.pod", logging.INFO)
    assert record.args[:5] == ("svd", 2, 3, 2, 1) and record.args[5] == pytest.approx(0.9, rel=1e-14)  # method,
    # snapshots, outputs, rank, modes kept, energy kept



def test_single_precision_snapshots_are_decomposed_and_measured_in_double_precision():
    """Snapshots stored as float32 (e.g. a float32 HDF5 dataset) are upcast before the SVD: the modes
    are float64 and orthonormal to rounding (1e-12; a float32 decomposition reaches only ~1e-7), the
    singular values equal those of the same numbers given as float64 (rtol 1e-12), and the relative
    projection error divides by the float64 norm (equal to the float64 input's within 1e-12)."""
    Y, _, _ = _data(9, n=12, m=30, rank=3)
    Y32 = Y.astype(np.float32)
    pod = POD(n_modes=2).fit(Y32)
    ref = POD(n_modes=2).fit(Y32.astype(float))
    assert pod.modes_.dtype == np.float64
    assert_allclose(pod.modes_ @ pod.modes_.T, np.eye(2), rtol=0, atol=1e-12)
    assert_allclose(pod.singular_values_, ref.singular_values_, rtol=1e-12)
    assert_allclose(pod.projection_error(Y32), ref.projection_error(Y32.astype(float)), rtol=1e-12)
