"""The misfit of thesis eq. (2.13) against closed forms and its χ² statistics."""

from types import SimpleNamespace

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fe.sensors import PointDisplacement, absolute_displacements
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.misfit import Misfit
from podkrig.online.rigid_body import rigid_body_modes

rng = np.random.default_rng(3)
A = rng.normal(size=(6, 2))  # a linear "model": 3 loads × 2 sensors from 2 parameters


def linear_model(std=None):
    def model(X):
        mean = X @ A.T
        return mean, None if std is None else np.broadcast_to(std, mean.shape)

    return model


def measurement(values):
    return Measurement(values.reshape(3, 2), ("a", "b"), np.array([1.0, 2.0, 3.0]))


def test_gaussian_misfit_matches_closed_form_with_prior():
    m_true = np.array([1.0, -2.0])
    d = A @ m_true + 0.01
    meas = measurement(d)
    sigma = 0.05
    prior_mean, prior_cov = np.array([0.5, -1.0]), np.diag([4.0, 9.0])
    f = Misfit(linear_model(), meas, NoiseModel(sigma=sigma), np.arange(6), prior_mean, prior_cov)
    X = rng.normal(size=(5, 2))
    r = X @ A.T - d
    expected = 0.5 * (np.sum(r**2, axis=1) / sigma**2 + np.sum((X - prior_mean) ** 2 / np.diag(prior_cov), axis=1))
    assert_allclose(f(X), expected, rtol=1e-12)


def test_full_covariance_equals_diagonal_when_diagonal_and_model_error_adds():
    d = A @ np.array([0.3, 0.7])
    meas = measurement(d)
    model_std = 0.02
    diag = Misfit(linear_model(model_std), meas, NoiseModel(sigma=0.03), np.arange(6))
    full = Misfit(linear_model(model_std), meas, NoiseModel(covariance=np.diag(np.full(6, 0.03**2))), np.arange(6))
    X = rng.normal(size=(4, 2))
    assert_allclose(full(X), diag(X), rtol=1e-12)
    # C_D = C_d + C_T: the modelling variance widens the fit (smaller misfit), exactly
    no_model_error = Misfit(linear_model(model_std), meas, NoiseModel(sigma=0.03), np.arange(6), model_error=False)
    r = X @ A.T - d
    assert_allclose(diag(X), 0.5 * np.sum(r**2, axis=1) / (0.03**2 + model_std**2), rtol=1e-12)
    assert np.all(diag(X) < no_model_error(X))


def test_chi2_of_noisy_data_at_the_truth_has_n_obs_degrees_of_freedom():
    """Over many noise realisations, χ² at the true parameters has mean n_obs and variance 2 n_obs."""
    m_true = np.array([1.0, 2.0])
    clean = A @ m_true
    sigma = 0.01
    gen = np.random.default_rng(11)
    chi2 = []
    for _ in range(4000):
        meas = measurement(clean + sigma * gen.normal(size=6))
        chi2.append(Misfit(linear_model(), meas, NoiseModel(sigma=sigma), np.arange(6)).chi2(m_true[None])[0])
    chi2 = np.array(chi2)
    # standard errors with 4000 draws: mean ±0.055, variance ±0.3 → 4-sigma bounds
    assert abs(chi2.mean() - 6) < 0.25
    assert abs(chi2.var() - 12) < 1.5


def test_relative_misfit_and_subset_indices():
    d = np.array([1.0, 2.0, 4.0, 8.0, 16.0, 32.0])  # model output: 3 loads × sensors (a, b)
    meas = Measurement(np.array([[2.0], [8.0]]), ("b",), np.array([1.0, 2.0]))
    idx = meas.output_indices(("a", "b"), (1.0, 2.0, 3.0))
    assert idx.tolist() == [1, 3]

    def model(X):
        return np.tile(d, (len(X), 1)) * X[:, :1], None

    f = Misfit(model, meas, NoiseModel(sigma=1.0), idx, kind="relative")
    assert_allclose(f(np.array([[1.1, 0.0]])), 0.5 * 2 * 0.1**2, rtol=1e-12)
    with pytest.raises(ValueError, match=r"misfit kind .*'gaussian' or 'relative'; got 'l1'"):
        Misfit(model, meas, NoiseModel(sigma=1.0), idx, kind="l1")


def test_permuted_and_prefix_subsets_with_model_error_match_the_closed_form():
    """Observed entries in another order than the model's (same count) or only the first load
    level (a prefix) pick the right model outputs and their modelling std, row by row."""
    m_true = np.array([0.4, -0.3])
    d = A @ m_true
    X = rng.normal(size=(3, 2))
    std = 0.01 + 0.02 * np.abs(X @ A.T)  # a different C_T per row and per output

    def model(Xs):
        return Xs @ A.T, 0.01 + 0.02 * np.abs(Xs @ A.T)

    sigma = 0.03
    for sensors, loads, cols in [(("b", "a"), [1.0, 2.0, 3.0], [1, 0, 3, 2, 5, 4]), (("a", "b"), [1.0], [0, 1])]:
        rows = np.array(cols).reshape(len(loads), 2)
        meas = Measurement(d[rows], sensors, np.array(loads))
        idx = meas.output_indices(("a", "b"), (1.0, 2.0, 3.0))
        assert idx.tolist() == cols
        f = Misfit(model, meas, NoiseModel(sigma=sigma), idx)
        r = (X @ A.T)[:, cols] - d[cols]
        assert_allclose(f(X), 0.5 * np.sum(r**2 / (sigma**2 + std[:, cols] ** 2), axis=1), rtol=1e-12)


def test_frozen_model_error_for_one_row_all_observed_without_copy_and_small_relative_data():
    """A broadcast (frozen) C_T evaluated for a single parameter vector; when every output is
    observed in model order the predictions are not copied; relative residuals divide by |d| even
    for readings below 1 mm; without a prior the prior residuals are empty."""
    d = A @ np.array([0.3, 0.7])
    meas = measurement(d)
    f = Misfit(linear_model(0.02), meas, NoiseModel(sigma=0.03), np.arange(6))
    X = rng.normal(size=(1, 2))
    r = X @ A.T - d
    assert_allclose(f(X), 0.5 * np.sum(r**2, axis=1) / (0.03**2 + 0.02**2), rtol=1e-12)
    out = np.zeros((1, 6))
    g = Misfit(lambda Xs: (out, None), meas, NoiseModel(sigma=1.0), np.arange(6))
    assert g.predict(X)[0] is out
    assert g.prior_residuals(X).shape == (1, 0)
    small = Measurement(np.array([[0.05, -0.2]]), ("a", "b"), np.array([1.0]))
    rel = Misfit(lambda Xs: (np.tile([0.06, -0.3], (len(Xs), 1)), None), small, NoiseModel(sigma=1.0),
                 np.arange(2), kind="relative")
    assert_allclose(rel.whitened_residuals(X), [[0.2, -0.5]], rtol=1e-12)
    for prior in ({"prior_mean": np.zeros(2)}, {"prior_cov": np.eye(2)}):
        with pytest.raises(ValueError, match=r"prior needs both prior_mean and prior_cov"):
            Misfit(linear_model(), meas, NoiseModel(sigma=1.0), np.arange(6), **prior)


def test_model_form_error_adds_its_variance_per_reading_to_the_noise():
    """C_D = C_d + C_T,surrogate + diag(e²) (thesis eq. 2.10), per reading, for a diagonal and a full
    noise covariance alike; the noise σ reported stays the noise's own (the FE check compares with it);
    e = 0 is allowed for a reading, e < 0 and an observation of the wrong length are refused with the counts."""
    d = A @ np.array([0.3, 0.7])
    meas = measurement(d)
    e = np.linspace(0.01, 0.06, 6)
    model_std = 0.02
    X = rng.normal(size=(4, 2))
    r = X @ A.T - d
    expected = 0.5 * np.sum(r**2 / (0.03**2 + model_std**2 + e**2), axis=1)
    diag = Misfit(linear_model(model_std), meas, NoiseModel(sigma=0.03), np.arange(6), form_error=e)
    full = Misfit(linear_model(model_std), meas, NoiseModel(covariance=np.diag(np.full(6, 0.03**2))), np.arange(6),
                  form_error=e)
    assert_allclose(diag(X), expected, rtol=1e-12)
    assert_allclose(full(X), expected, rtol=1e-12)
    assert_allclose(diag.noise_std, 0.03)
    # a reading without model-form error (e = 0) is allowed: σ² + σ_T² alone there
    e0 = np.where(np.arange(6) < 2, 0.0, e)
    with_zero = Misfit(linear_model(model_std), meas, NoiseModel(sigma=0.03), np.arange(6), form_error=e0)
    assert_allclose(with_zero(X), 0.5 * np.sum(r**2 / (0.03**2 + model_std**2 + e0**2), axis=1), rtol=1e-12)
    with pytest.raises(ValueError, match=r"observation gives 5 entries.*measurement has 6"):
        Misfit(linear_model(), meas, NoiseModel(sigma=0.03), np.arange(5))
    with pytest.raises(ValueError, match="form_error must be 6 finite"):
        Misfit(linear_model(), meas, NoiseModel(sigma=0.03), np.arange(6), form_error=e[:5])
    with pytest.raises(ValueError, match="form_error must be 6"):
        Misfit(linear_model(), meas, NoiseModel(sigma=0.03), np.arange(6), form_error=-e)


def test_integer_parameter_vectors_are_evaluated_as_real_numbers():
    """ω at the integer point (2, 4) equals ω at (2.0, 4.0) (rtol 1e-15) for a model with a negative
    power of a parameter (a compliance 1/E): the parameters reach the model as floats, as integer
    arrays cannot be raised to a negative integer power in numpy."""
    meas = Measurement(np.array([[0.4, 0.3]]), ("a", "b"), np.array([1.0]))

    def compliance(X):
        return np.column_stack([X[:, 0] ** -1, X[:, 1] ** -1]), None

    f = Misfit(compliance, meas, NoiseModel(sigma=0.1), np.arange(2))
    expected = 0.5 * ((0.5 - 0.4) ** 2 + (0.25 - 0.3) ** 2) / 0.1**2
    assert_allclose(f([[2, 4]]), [expected], rtol=1e-15)
    assert_allclose(f(np.array([2, 4])), f(np.array([[2.0, 4.0]])), rtol=1e-15)


def test_per_row_model_std_broadcast_along_the_outputs_weights_each_row_by_its_own():
    """A model whose std is one value per parameter vector, broadcast along the outputs (a view with
    a zero column stride), gives each row its own C_T: ω_i = ½ Σ r²/(σ² + s_i²) (closed form, rtol
    1e-12); only a std shared by all rows (zero row stride) may be taken from the first row."""
    d = A @ np.array([0.3, 0.7])
    meas = measurement(d)
    X = rng.normal(size=(3, 2))
    s_row = np.array([0.01, 0.05, 0.2])

    def model(Xs):
        mean = Xs @ A.T
        return mean, np.broadcast_to(s_row[: len(Xs), None], mean.shape)

    f = Misfit(model, meas, NoiseModel(sigma=0.03), np.arange(6))
    r = X @ A.T - d
    assert_allclose(f(X), 0.5 * np.sum(r**2, axis=1) / (0.03**2 + s_row**2), rtol=1e-12)


def test_whiten_takes_integer_residuals_and_leaves_its_input_alone():
    """Raw residuals given as integers (mm) are whitened as reals: r/σ (rtol 1e-15), and the caller's
    array is not modified in place."""
    meas = measurement(A @ np.array([0.3, 0.7]))
    f = Misfit(linear_model(), meas, NoiseModel(sigma=0.5), np.arange(6))
    r = np.array([[1, 2, 0, -1, 3, 0]])
    assert_allclose(f.whiten(r), r / 0.5, rtol=1e-15)
    assert r.tolist() == [[1, 2, 0, -1, 3, 0]]
    with pytest.raises(ValueError, match=r"rigid-body modes are for 4 entries.*measurement has 6"):
        Misfit(linear_model(), meas, NoiseModel(sigma=0.5), np.arange(6), rigid_body=SimpleNamespace(n_obs=4))


def test_relative_misfit_removes_the_rigid_motion_before_dividing_by_the_data():
    """Relative residuals with rigid-body removal are P (g − d)/|d| (module docstring), with P the
    projector of the four point displacements' rigid modes (rtol 1e-12)."""
    sensors = (PointDisplacement("P1", (0.0, 0.0), "x"), PointDisplacement("P2", (100.0, 0.0), "y"),
               PointDisplacement("P3", (0.0, 100.0), "x"), PointDisplacement("P4", (100.0, 100.0), "y"))
    names = tuple(n for sensor in sensors for n in sensor.channel_names)
    d = np.array([0.2, -0.4, 0.5, 0.8])
    meas = Measurement(d[None], names, [1.0])
    modes = rigid_body_modes(meas, absolute_displacements(sensors), "remove")
    g = np.array([0.25, -0.3, 0.45, 1.0])
    f = Misfit(lambda X: (np.tile(g, (len(X), 1)), None), meas, NoiseModel(sigma=1.0), np.arange(4),
               kind="relative", rigid_body=modes)
    expected = modes.projector() @ (g - d) / np.abs(d)
    assert np.abs(expected).max() > 0.01  # the removal leaves a residual to compare
    assert_allclose(f.whitened_residuals(np.zeros((1, 1))), [expected], rtol=1e-12, atol=1e-15)


def test_an_integer_noise_covariance_takes_the_model_variance():
    """A full noise covariance given with integer entries (mm², here 4 I + a coupling 1 between the
    first two readings) plus the model's predictive variance: χ² = rᵀ (C_d + s² I)⁻¹ r (rtol 1e-12)."""
    d = A @ np.array([0.3, 0.7])
    meas = measurement(d)
    C = 4 * np.eye(6, dtype=int)
    C[0, 1] = C[1, 0] = 1
    X = rng.normal(size=(2, 2))
    r = X @ A.T - d
    f = Misfit(linear_model(0.5), meas, NoiseModel(covariance=C), np.arange(6))
    CD = C + 0.25 * np.eye(6)
    assert_allclose(f.chi2(X), np.einsum("ij,ij->i", r, np.linalg.solve(CD, r.T).T), rtol=1e-12)
