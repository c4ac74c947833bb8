"""Surrogate validation on analytic snapshots (issue 12): relative errors, coverage, the exact POD /
interpolation split of held-out errors, closed-form leave-one-out errors against explicit refits, the
report's round trip and the comparison of kriging settings. Fast: no FE runs."""

import json
import logging
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from podkrig.parameters import Parameter, ParameterSpace
from podkrig.surrogate.kriging import DEFAULT_BETA, OrdinaryKriging
from podkrig.surrogate.pod import POD
from podkrig.surrogate.podkriging import PODKriging
from podkrig.surrogate.validation import (HeldOutReport, compare_settings, coverage, held_out_errors, loo_errors,
                                          relative_errors, summarize)

# orthonormal directions of a 4-output snapshot: mean along E0, modes along E1 and E2, E3 off the span
E = np.eye(4)


def _snapshots(X, off_span=0.0):
    """Snapshots of shape (n, 2, 2): a mean 3 e0 plus smooth coefficients along e1 and e2 (an
    affine 2-D space) and ``off_span`` times e3, orthogonal to it."""
    x, z = X[:, 0], X[:, 1]
    Y = 3.0 * E[0] + np.outer(np.sin(2 * x) + z, E[1]) + np.outer(x * z, E[2]) + np.outer(
        np.broadcast_to(off_span, x.shape), E[3])
    return Y.reshape(len(X), 2, 2)


def _grid(n):
    g = (np.arange(n) + 0.5) / n
    return np.array([(a, b) for a in g for b in g])


@pytest.fixture(scope="module")
def fitted():
    """POD-kriging of 25 grid samples with fixed hyperparameters (no optimiser: fast, and the
    explicit refits below use the very same ones)."""
    X = _grid(5)
    kr = OrdinaryKriging(variogram="exponential", beta=1.5, ranges=0.6, optimizer=None, nugget=0.0)
    return PODKriging(pod=POD(n_modes=2), kriging=kr).fit(X, _snapshots(X)), X


def test_relative_errors_hand_values_over_all_outputs_of_a_snapshot():
    """Norms run over every output of a snapshot ((n, 2, 2) -> 4 values), per sample: the defect
    guarded is a norm per row or over the whole batch. A zero snapshot predicted exactly has error
    0 (not nan), predicted wrongly inf, without a RuntimeWarning. Exact arithmetic: tolerance 1e-15."""
    Y = np.array([[[3.0, 0.0], [0.0, 4.0]], [[1.0, 0.0], [0.0, 0.0]], [[0.0, 0.0], [0.0, 0.0]],
                  [[0.0, 0.0], [0.0, 0.0]]])
    P = Y.copy()
    P[0, 0, 1] += 1.0  # |err| 1 over |y| 5
    P[1] += [[0.0, 3.0], [4.0, 0.0]]  # |err| 5 over |y| 1
    P[3, 1, 1] = 2.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the zero snapshots raise no division warning
        assert_allclose(relative_errors(P, Y), [0.2, 5.0, 0.0, np.inf], rtol=1e-15)
    with pytest.raises(ValueError, match=r"differ in shape.*\(4, 2, 2\) vs \(4, 4\)"):
        relative_errors(P, Y.reshape(4, 4))


def test_coverage_counts_the_interval_edge_and_uses_k_two_by_default():
    """|error| == k sigma is covered (the documented closed interval); the default k is 2. Errors of
    exactly 1, 2 and 3 sigma (binary-exact values) give 2/3 with the default, 1/3 with k = 1, 1
    with k = 3: exact shares."""
    truth = np.zeros(3)
    sigma = np.full(3, 0.5)
    pred = np.array([0.5, -1.0, 1.5])
    assert coverage(pred, truth, sigma) == 2 / 3
    assert coverage(pred, truth, sigma, k=1.0) == 1 / 3
    assert coverage(pred, truth, sigma, k=3.0) == 1.0
    with pytest.raises(ValueError, match=r"non-empty shape; got \(0,\), \(0,\), \(0,\)"):
        coverage([], [], [])
    with pytest.raises(ValueError, match=r"got \(2,\), \(2,\), \(3,\)"):
        coverage([1.0, 2.0], [1.0, 2.0], [1.0, 1.0, 1.0])


def test_summarize_hand_values():
    """Median, 95th percentile (numpy's linear interpolation: 4 + 0.8 x 1 for 1..5), max and mean;
    plain floats (JSON-able)."""
    s = summarize([5.0, 1.0, 4.0, 2.0, 3.0])
    assert s == pytest.approx({"median": 3.0, "p95": 4.8, "max": 5.0, "mean": 3.0}, abs=1e-12)
    assert all(type(v) is float for v in s.values())


def _report(loo):
    rng = np.random.default_rng(3)
    return HeldOutReport(rng.random(3), rng.random(3), rng.random(3), 0.625, rng.random((3, 2)),
                         rng.random((3, 4)), rng.random((3, 4)), rng.random((3, 4)), 25, 2, loo,
                         {"fit": {"method": "exact"}, "fit_description": "exact"})


@pytest.mark.parametrize("loo", [None, np.array([0.1, 0.2, 0.3, 0.4])])
def test_report_round_trips_exactly_through_json(loo):
    """to_dict -> JSON -> from_dict gives back every array bit for bit (floats survive JSON
    exactly), the counts, the coverage, the leave-one-out errors (or their absence) and the extra
    fit record; the defect guarded is a field dropped or renamed on the way to the study file."""
    rep = _report(loo)
    back = HeldOutReport.from_dict(json.loads(json.dumps(rep.to_dict())))
    for name in HeldOutReport._ARRAYS:
        assert_array_equal(getattr(back, name), getattr(rep, name))
        assert getattr(back, name).dtype == float
    assert (back.coverage_2sigma, back.n_train, back.n_modes, back.n_held_out) == (0.625, 25, 2, 3)
    assert back.extra == rep.extra
    if loo is None:
        assert back.loo_error is None
    else:
        assert_array_equal(back.loo_error, loo)
    assert back.summary() == rep.summary()


def test_report_from_a_minimal_dict():
    """A dict without the optional ``loo_error`` and ``extra`` keys (an older file) reads back with
    no leave-one-out errors and an empty extra record."""
    d = _report(None).to_dict()
    del d["loo_error"], d["extra"]
    back = HeldOutReport.from_dict(d)
    assert back.loo_error is None and back.extra == {}


def test_summary_fields():
    """The summary has the counts as ints, the four statistics of every error, the coverage, the
    leave-one-out statistics only when computed, and the extra record merged at top level."""
    rep = _report(np.array([0.1, 0.2, 0.3, 0.4]))
    s = rep.summary()
    assert (s["n_train"], s["n_held_out"], s["n_modes"], s["coverage_2sigma"]) == (25, 3, 2, 0.625)
    for name in ("rel_error", "pod_error", "interp_error"):
        assert s[name] == summarize(getattr(rep, name))
    assert s["loo_error"]["max"] == 0.4 and s["fit"] == {"method": "exact"} and s["fit_description"] == "exact"
    assert "loo_error" not in _report(None).summary()
    json.dumps(s)


def test_held_out_error_split_is_exact_for_a_known_off_span_part(fitted, caplog):
    """Held-out snapshots = an in-span part + t e3 with e3 orthogonal to the mean and to the
    training span: the POD error is exactly |t| / |y| and the interpolation error |y - t e3 - y_hat|
    / |y| (P y = y - t e3), and rel^2 = pod^2 + interp^2 (Pythagoras). The defect guarded is a wrong
    projection or norm in the split. The log line states the count, median error and coverage. Rounding of the SVD basis: 1e-12."""
    sur, X = fitted
    Xh = np.array([[0.33, 0.71], [0.62, 0.18], [0.9, 0.45]])
    t = np.array([0.2, -0.5, 0.0])
    Yh = _snapshots(Xh, t)
    with caplog.at_level(logging.INFO, logger="podkrig.surrogate.validation"):
        rep = held_out_errors(sur, Xh, Yh)
    Yf = Yh.reshape(3, 4)
    norm = np.linalg.norm(Yf, axis=1)
    pred, std = sur.predict(Xh, return_std=True)
    assert_allclose(rep.pod_error, np.abs(t) / norm, atol=1e-12)
    assert_allclose(rep.interp_error, np.linalg.norm(Yf - np.outer(t, E[3]) - pred, axis=1) / norm, rtol=1e-12)
    assert_allclose(rep.rel_error**2, rep.pod_error**2 + rep.interp_error**2, rtol=1e-10)
    assert_allclose(rep.rel_error, np.linalg.norm(pred - Yf, axis=1) / norm, rtol=1e-12)
    assert np.all(rep.interp_error > 0)
    assert_array_equal(rep.X, Xh)
    assert_array_equal(rep.Y_true, Yf)
    assert_array_equal(rep.Y_pred, pred)
    assert_array_equal(rep.Y_std, std)
    assert rep.coverage_2sigma == coverage(pred, Yf, std, k=2.0)
    assert (rep.n_train, rep.n_modes, rep.n_held_out) == (25, 2, 3)
    assert_array_equal(rep.loo_error, loo_errors(sur))
    assert rep.extra == {"fit": sur.kriging_.fit_method_.to_dict(), "fit_description": sur.kriging_.fit_method_.describe()}
    assert rep.extra["fit"]["method"] == "exact"
    assert held_out_errors(sur, Xh, Yh, with_loo=False).loo_error is None
    assert held_out_errors(sur, Xh[:1], Yh[:1]).n_held_out == 1  # one held-out run is enough
    (record,) = caplog.records
    assert record.levelno == logging.INFO and record.name.startswith("podkrig.surrogate")
    assert record.args == (3, np.median(rep.rel_error), rep.coverage_2sigma)  # samples, median error, coverage


def test_held_out_errors_refuses_mismatched_snapshots(fitted):
    """Snapshots of another output shape, another count than the parameters, or none at all: a
    message with the shapes / counts and what to use."""
    sur, X = fitted
    with pytest.raises(ValueError, match=r"shape \(4,\) per sample.*predicts \(2, 2\)"):
        held_out_errors(sur, X[:2], np.zeros((2, 4)))
    with pytest.raises(ValueError, match=r"held-out parameter vectors.*got 3 and 2"):
        held_out_errors(sur, X[:3], np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match=r"got 0 and 0"):
        held_out_errors(sur, X[:0], np.zeros((0, 2, 2)))


def _stub(pred, proj, std=None, kriging=None, norms=None):
    """A duck-typed fitted surrogate with given predictions and projections (for the edge cases
    a real fit cannot produce on demand)."""
    pred = np.asarray(pred, float)
    return SimpleNamespace(
        output_shape_=(pred.shape[1],), X_=np.zeros((7, 1)),
        predict=lambda X, return_std: (pred, np.ones_like(pred) if std is None else std),
        project=lambda Y: np.asarray(proj, float), pod_=SimpleNamespace(n_modes_=1),
        kriging_=kriging if kriging is not None else SimpleNamespace(), **(norms or {}))


def test_held_out_errors_of_a_zero_snapshot_and_of_a_foreign_backend():
    """A zero held-out snapshot predicted exactly has all three errors 0 (not nan), a snapshot of
    norm 0.5 its plain ratios (hand values 0.1, 0.05, 0.05: binary rounding only, 1e-14); a backend
    without leave-one-out residuals or fit record (SMT, scikit-learn) gives no leave-one-out
    errors and an empty extra record."""
    Y = np.array([[0.0, 0.0], [3.0, 4.0], [0.3, 0.4]])
    sur = _stub(pred=[[0.0, 0.0], [3.0, 4.5], [0.3, 0.45]], proj=[[0.0, 0.0], [3.0, 4.25], [0.3, 0.425]])
    rep = held_out_errors(sur, np.zeros((3, 1)), Y)
    assert_allclose(rep.rel_error, [0.0, 0.1, 0.1], rtol=1e-14)
    assert_allclose(rep.pod_error, [0.0, 0.05, 0.05], rtol=1e-14)
    assert_allclose(rep.interp_error, [0.0, 0.05, 0.05], rtol=1e-14)
    assert rep.loo_error is None and rep.extra == {} and rep.n_train == 7 and rep.n_modes == 1
    assert loo_errors(sur) is None


def test_loo_errors_combine_residuals_and_truncation_by_pythagoras():
    """error_i = sqrt(sum_k e_ik^2 + r_i^2) / |y_i| with kriging residuals e and truncation
    residual r; a zero training snapshot gives 0 (divided by inf, not nan). Hand values:
    sqrt(9 + 16 + 0)/5 = 1, sqrt(0 + 0 + 4)/8 = 0.25, sqrt(0.09 + 0.16 + 0)/0.5 = 1 (a snapshot of
    norm below 1 divided by its own norm). Rounding only: 1e-15."""
    kr = SimpleNamespace(loo_residuals_=np.array([[3.0, 4.0], [0.0, 0.0], [0.0, 0.0], [0.3, 0.4]]))
    sur = _stub([[0.0]], [[0.0]], kriging=kr, norms={"train_norm_": np.array([5.0, 8.0, 0.0, 0.5]),
                                                     "train_residual_norm_": np.array([0.0, 2.0, 0.0, 0.0])})
    assert_allclose(loo_errors(sur), [1.0, 0.25, 0.0, 1.0], rtol=1e-15)


def test_loo_errors_equal_explicit_refits(fitted):
    """The closed-form leave-one-out error of each training snapshot equals the error of the
    surrogate refitted without it, at the same hyperparameters and with the POD basis of all samples
    (the documented definition): the kriging of each POD coefficient is refitted on the other 24
    samples and the snapshot rebuilt. Off-span parts are added to the training snapshots so that
    the truncation term is not zero. Both are exact algebra of one small system: 1e-8 relative."""
    X = _grid(5)
    Y = _snapshots(X, 0.05 * np.cos(5 * X[:, 0]))
    kr = OrdinaryKriging(variogram="exponential", beta=1.5, ranges=0.6, optimizer=None)
    sur = PODKriging(pod=POD(n_modes=2), kriging=kr).fit(X, Y)
    Yf = Y.reshape(len(X), -1)
    A = sur.pod_.transform(Yf)
    expected = []
    for i in range(len(X)):
        keep = np.arange(len(X)) != i
        ok = OrdinaryKriging(variogram="exponential", beta=1.5, ranges=0.6, optimizer=None).fit(sur.U_[keep], A[keep])
        y_hat = sur.pod_.inverse_transform(ok.predict(sur.U_[i:i + 1]))[0]
        expected.append(np.linalg.norm(Yf[i] - y_hat) / np.linalg.norm(Yf[i]))
    got = loo_errors(sur)
    assert_allclose(got, expected, rtol=1e-8)
    assert np.all(got > 0)


def test_compare_settings_labels_and_errors(fitted):
    """One entry per setting, labelled ``variogram, beta=...`` with the defaults (exponential,
    DEFAULT_BETA) filled in; each holds the held-out relative errors of the surrogate fitted with
    that setting, the given POD and space (one mode: errors of a 1-mode fit, larger than the
    default POD's two; a log scale: other errors). Same fits in the same order: 1e-12."""
    _, X = fitted
    Y = _snapshots(X)
    Xh = np.array([[0.33, 0.71], [0.62, 0.18]])
    Yh = _snapshots(Xh)
    settings = [{"variogram": "exponential", "beta": 1.5, "ranges": 0.6, "optimizer": None},
                {"ranges": 0.6, "optimizer": None, "beta": 1.2},
                {"variogram": "exponential", "ranges": 0.3}]
    out = compare_settings(X, Y, Xh, Yh, settings, pod=POD(n_modes=1))
    assert list(out) == ["exponential, beta=1.5", "exponential, beta=1.2", f"exponential, beta={DEFAULT_BETA}"]
    for s, errors in zip(settings, out.values()):
        sur = PODKriging(pod=POD(n_modes=1), kriging=OrdinaryKriging(**s)).fit(X, Y)
        assert_allclose(errors, relative_errors(sur.predict(Xh), Yh.reshape(2, -1)), rtol=1e-12)
        assert errors.shape == (2,)
    assert not np.allclose(out["exponential, beta=1.5"], out["exponential, beta=1.2"], rtol=1e-3)
    # the space reaches the fit: a log scale of x0 on [0.05, 1] moves the samples in the unit cube
    space = ParameterSpace((Parameter("x0", 0.05, 1.0, scale="log"), Parameter("x1", 0.0, 1.0)))
    logged = compare_settings(X, Y, Xh, Yh, settings[:1], space=space, pod=POD(n_modes=1))
    sur = PODKriging(pod=POD(n_modes=1), kriging=OrdinaryKriging(**settings[0]), space=space).fit(X, Y)
    assert_allclose(logged["exponential, beta=1.5"], relative_errors(sur.predict(Xh), Yh.reshape(2, -1)), rtol=1e-12)
    assert not np.allclose(logged["exponential, beta=1.5"], out["exponential, beta=1.5"], rtol=1e-3)
    # the variogram reaches the label and the fit (power model: off the tensor grid, where a sum of
    # one-dimensional power variograms is singular)
    Xj = X + 0.03 * np.column_stack([np.sin(7 * X[:, 1]), np.cos(5 * X[:, 0])])
    power = {"variogram": "power", "beta": 1.5, "ranges": 0.6, "optimizer": None}
    got = compare_settings(Xj, _snapshots(Xj), Xh, Yh, [power], pod=POD(n_modes=1))
    sur = PODKriging(pod=POD(n_modes=1), kriging=OrdinaryKriging(**power)).fit(Xj, _snapshots(Xj))
    assert list(got) == ["power, beta=1.5"]
    assert_allclose(got["power, beta=1.5"], relative_errors(sur.predict(Xh), Yh.reshape(2, -1)), rtol=1e-12)
    # the POD reaches the fit: the default POD keeps both modes, the errors drop
    both = compare_settings(X, Y, Xh, Yh, settings[:1])
    assert np.all(both["exponential, beta=1.5"] < out["exponential, beta=1.5"])
