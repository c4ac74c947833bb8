"""The estimator's bookkeeping a user reads: ``set_params``, the fit record (``FitMethod``) and its
report line, the subset draw, the log line of a subset fit, and the messages of a singular system
(issue 12: mutation survivors of ``surrogate/kriging/ordinary.py``)."""

import logging

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from podkrig.offline.sampling import sobol
from podkrig.surrogate.kriging import FitMethod, OrdinaryKriging, ordinary


def _f(X):
    """Two smooth outputs of three inputs in the unit cube."""
    return np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1] ** 2 + 0.3 * X[:, 2], np.exp(-X[:, 0] * X[:, 1]) * X[:, 2]])


def test_set_params_changes_the_named_settings_and_refuses_unknown_names():
    """Defects: a setting not stored (or stored under another name, or as None), ``self`` not
    returned (scikit-learn chains it), an unknown name accepted silently (a typo would then fit with
    the default) or refused without naming it and the valid names."""
    ok = OrdinaryKriging()
    assert ok.set_params(beta=1.5, nugget=1e-8) is ok
    assert (ok.beta, ok.nugget) == (1.5, 1e-8)
    assert ok.get_params()["beta"] == 1.5 and ok.get_params()["criterion"] == "ml"  # others untouched
    valid = sorted(ok.get_params())
    with pytest.raises(ValueError) as err:
        ok.set_params(nuget=1e-8)
    assert str(err.value) == f"unknown parameter 'nuget' of OrdinaryKriging; valid: {valid}"
    assert ok.nugget == 1e-8 and not hasattr(ok, "nuget")


def test_fit_record_reads_as_one_line_for_reports():
    """Defects: the exact fit described as a subset fit, output ranges left at x1 counted as
    shortened, the clause on shortened ranges shown when none was (or with other text)."""
    assert FitMethod("exact", 64, 64).describe() == "hyperparameters fitted on all 64 samples (exact)"
    plain = FitMethod("subset", 2048, 512, 7, (1.0, 1.0)).describe()
    assert plain == ("hyperparameters fitted on a random subset of 512 of the 2048 samples (seed 7), "
                     "then one factorisation of all 2048")
    shrunk = FitMethod("subset", 2048, 512, 7, (1.0, 0.8, 0.64)).describe()
    assert shrunk == plain + "; ranges of 2 output(s) shortened (down to x0.64) for conditioning"


def test_subset_is_drawn_without_replacement_with_the_estimators_seed():
    """The draw the file records (``FitMethod`` docstring: without replacement, seed ``subset_seed``,
    ``numpy.random.default_rng``), so a reader can reproduce it. Defects: another seed or an
    unseeded draw, the record not naming it."""
    X = sobol(64, 3, seed=0)
    fitted = OrdinaryKriging(beta=1.5, random_state=11, fit_subset=16).fit(X, _f(X))
    assert_array_equal(fitted.subset_index_, np.sort(np.random.default_rng(11).choice(64, 16, replace=False)))
    assert (fitted.fit_method_.subset_size, fitted.fit_method_.subset_seed) == (16, 11)


def test_subset_fit_logs_its_sizes_and_cost(caplog):
    """The log line states the subset and full sizes, the criterion evaluations spent, the
    dimensions and outputs (a user tuning ``fit_subset`` reads it). Defects: an argument missing or
    swapped (logging would print a formatting error instead of the line)."""
    X = sobol(64, 3, seed=0)
    with caplog.at_level(logging.INFO, logger=ordinary.__name__):
        fitted = OrdinaryKriging(beta=1.5, fit_subset=16).fit(X, _f(X))
    n_eval = int(fitted.n_evaluations_.sum())
    assert n_eval > 0
    assert (f"kriging fitted: hyperparameters on 16 of 64 samples ({n_eval} criterion evaluations), one "
            "factorisation of all 64 per output; 3 dims, 2 outputs") in caplog.messages


def test_a_system_of_all_samples_that_stays_singular_names_the_sizes_and_the_remedies(monkeypatch):
    """The very smooth response of ``test_kriging_scale.py``, whose subset ranges make the system of
    all 60 samples singular, with the shortening allowed one step only: the error names the sample
    count, the output, the subset size and the two remedies. Defects: the record of the subset (used
    in the message) wrong or missing."""
    rng = np.random.default_rng(0)
    X = rng.random((60, 3))
    Y = np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1] ** 2, X[:, 0] * X[:, 2]])
    monkeypatch.setattr(ordinary, "RANGE_SHRINK_STEPS", 1)
    with pytest.raises(ValueError, match=r"^the kriging system of all 60 samples is singular for output \d at the "
                                         r"hyperparameters fitted on 20 of them \(still singular with the ranges "
                                         r"shortened x0\.8\); set a small nugget \(e\.g\. nugget=1e-8\) or fit on all "
                                         r"samples \(fit_subset=None\)$"):
        OrdinaryKriging(fit_subset=20).fit(X, Y)


@pytest.mark.parametrize("optimizer", ["l-bfgs-b", None])
def test_nearly_coincident_samples_make_a_singular_system_and_the_message_says_where(optimizer):
    """Two samples 1e-12 apart (not identical, so the duplicate check lets them through): their
    correlation rounds to 1, the system is singular at every range, and the error gives the ranges
    tried, the cause, the distance of the closest samples and the remedies. Defects: the distance,
    the ranges or the cause missing or wrong."""
    X = sobol(16, 2, seed=0)
    X[9] = X[5] + np.array([1e-12, 0.0])  # not the first pair of the pairwise distances
    y = np.sin(3 * X[:, 0]) + X[:, 1]
    cause = "at every starting point" if optimizer else r"correlation matrix ill-conditioned \(reciprocal condition number [0-9.e-]+\)"
    with pytest.raises(ValueError, match=rf"^kriging system of output 0 is singular at ranges \(0\.3, 0\.3\) "
                                         rf"\({cause}\); the closest samples are 1e-12 apart \(unit cube\): remove "
                                         r"duplicates or set a nugget \(e\.g\. nugget=1e-8\)$"):
        OrdinaryKriging(beta=1.5, ranges=0.3, optimizer=optimizer, fit_subset=None).fit(X, y)


def test_one_dimensional_outputs_and_the_fits_nugget_survive_persistence():
    """``to_arrays``/``from_arrays``: an estimator fitted on a 1-D ``y`` predicts 1-D arrays after
    the round trip too; the stored variogram and nugget are those of the fit, and win over the
    settings passed in (which fill in only for files of schema 1 that lack them). Defects: ``y_1d``
    or the nugget not written or not read back."""
    X = sobol(16, 2, seed=0)
    y = np.sin(3 * X[:, 0]) + X[:, 1]
    fitted = OrdinaryKriging(beta=1.5, nugget=1e-6).fit(X, y)
    arrays, attrs = fitted.to_arrays()
    assert (attrs["y_1d"], attrs["variogram"], attrs["nugget"]) == (True, "exponential", 1e-6)
    back = OrdinaryKriging.from_arrays(arrays, attrs, {**fitted.get_params(), "nugget": 0.5})
    assert back.hyperparameters_.nugget == 1e-6
    Xp = sobol(8, 2, seed=1)
    mean, std = back.predict(Xp, return_std=True)
    assert mean.shape == std.shape == (8,)
    assert_array_equal(mean, fitted.predict(Xp))
    schema_1 = {k: v for k, v in attrs.items() if k not in ("variogram", "nugget")}
    assert OrdinaryKriging.from_arrays(arrays, schema_1, fitted.get_params()).hyperparameters_.nugget == 1e-6


@pytest.mark.parametrize("settings, message", [
    ({"optimizer": "bfgs"}, "optimizer must be 'l-bfgs-b' or None; got 'bfgs'"),
    ({"beta": "fit", "optimizer": None}, "beta='fit' needs an optimizer; give a fixed beta or optimizer='l-bfgs-b'"),
    ({"range_bounds": (0.0, 1.0)}, "range_bounds must satisfy 0 < lower < upper; got (0.0, 1.0)"),
    ({"range_bounds": (0.5, 0.5)}, "range_bounds must satisfy 0 < lower < upper; got (0.5, 0.5)"),
    ({"n_restarts": -1}, "n_restarts must be an integer >= 0; got -1"),
    ({"n_restarts": 1.0}, "n_restarts must be an integer >= 0; got 1.0"),
    ({"n_restarts": True}, "n_restarts must be an integer >= 0; got True"),
    ({"ranges": 0.0}, "ranges must be finite and > 0; got 0.0"),
    ({"ranges": [0.5, np.inf, 0.5]}, "ranges must be finite and > 0; got [0.5, inf, 0.5]"),
])
def test_bad_settings_are_refused_naming_the_setting_and_what_is_allowed(settings, message):
    """Each setting's check at its edge (a lower range bound of 0, equal bounds, a negative, float or
    boolean restart count, a zero or infinite range), with the whole message. Defects: an edge
    accepted (a range of 0 divides by zero in the kernel; an empty bound interval stalls L-BFGS-B) or
    a message that no longer names the setting and its allowed values."""
    X = sobol(16, 3, seed=0)
    with pytest.raises(ValueError) as err:
        OrdinaryKriging(**{"beta": 1.5, **settings}).fit(X, _f(X))
    assert str(err.value) == message


def test_settings_at_the_allowed_edges_fit():
    """No restarts, a subset of 3 samples (the smallest kriging takes), a tiny positive range bound."""
    X = sobol(16, 3, seed=0)
    fitted = OrdinaryKriging(beta=1.5, n_restarts=0, fit_subset=3, range_bounds=(1e-6, 10.0)).fit(X, _f(X))
    assert fitted.fit_method_.subset_size == 3


@pytest.mark.parametrize("variogram, beta", [("exponential", 1.5), ("power", 1.5)])
def test_variance_is_the_leave_one_out_variance_of_a_refit_without_the_point(variogram, beta):
    """An independent check of the predictive variance of both variogram families: with the ranges
    fixed, the kriging variance of the fit without sample i, at x_i, in units of its own sill, is
    the closed-form leave-one-out variance of the full fit in units of the full fit's sill,
    1 / Q_ii (Dubrule 1983); and the variance vanishes at the training points (an interpolator).
    Defects: a sign, factor or term of either variance formula (σ²[k0 + c0 − 2 q1ᵀk − kᵀQk] for the
    power model, σ²[1 − rᵀR⁻¹r + (1 − 1ᵀR⁻¹r)² / 1ᵀR⁻¹1] for the exponential family). 1e-6
    relative: the two fits factor different matrices (conditioning ~1e6 here)."""
    X = sobol(32, 2, seed=0)
    y = np.sin(3 * X[:, 0]) + X[:, 1] ** 2
    settings = dict(variogram=variogram, beta=beta, ranges=[0.4, 0.6], optimizer=None, fit_subset=None)
    full = OrdinaryKriging(**settings).fit(X, y)
    _, std_train = full.predict(X, return_std=True)
    assert np.all(std_train <= 1e-6 * np.sqrt(full.sigma2_[0]))
    for i in (0, 7, 31):
        rest = np.delete(np.arange(32), i)
        without = OrdinaryKriging(**settings).fit(X[rest], y[rest])
        _, std = without.predict(X[i:i + 1], return_std=True)
        assert std[0] ** 2 / without.sigma2_[0] == pytest.approx(full.loo_variance_[i, 0] / full.sigma2_[0], rel=1e-6)
        mean = without.predict(X[i:i + 1])[0]
        assert y[i] - mean == pytest.approx(full.loo_residuals_[i, 0], rel=1e-6)


def test_a_subset_as_large_as_the_design_is_the_exact_fit_and_messages_of_misuse():
    """``fit_subset`` at or above the sample count fits exactly (no random subset of all samples);
    predicting before fitting, duplicate samples and an unknown fit method are refused with
    messages that say what to do."""
    X = sobol(16, 3, seed=0)
    for m in (16, 100):
        assert OrdinaryKriging(beta=1.5, fit_subset=m).fit(X, _f(X)).fit_method_ == FitMethod("exact", 16, 16)
    with pytest.raises(ordinary.NotFittedError, match=r"^this OrdinaryKriging instance is not fitted yet; call "
                                                      r"fit\(X, Y\) before predict$"):
        OrdinaryKriging().predict(X)
    Xd = np.vstack([X, X[3]])
    with pytest.raises(ValueError, match=r"^duplicate samples: rows \[3, 16\] of X are identical \(.*\); the kriging "
                                         r"system is singular: remove duplicates or set a nugget \(e\.g\. nugget=1e-8\)$"):
        OrdinaryKriging(beta=1.5).fit(Xd, _f(Xd))
    with pytest.raises(ValueError, match=r"^fit method must be one of \('exact', 'subset'\); got 'all'$"):
        FitMethod("all", 16, 16)
