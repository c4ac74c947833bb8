"""The estimator's bookkeeping a user reads: ``set_params``, the fit record (``FitMethod``) and its
report line, the subset draw, the log records, the errors of a singular system and of bad training
data (their type and the fragments a user needs); the hyperparameter search judged by what it finds
(the criterion's optimum, within the bounds, reproducible), with an injected optimiser; constant
outputs; the hyperparameter record; the blocks of the variance pass."""

import logging
import re
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.optimize import differential_evolution

from podkrig.offline.sampling import sobol, uniform
from podkrig.surrogate.kriging import FitMethod, KrigingHyperparameters, OrdinaryKriging, l_bfgs_b, ordinary


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
    with pytest.raises(ValueError, match="'nuget'") as err:
        ok.set_params(nuget=1e-8)
    assert all(repr(name) in str(err.value) for name in ok.get_params())  # the valid names, to pick from
    assert ok.nugget == 1e-8 and not hasattr(ok, "nuget")


def test_fit_record_reads_as_one_line_for_reports():
    """Defects: the exact fit described as a subset fit, output ranges left at x1 counted as
    shortened, the clause on shortened ranges shown when none was (or with other text)."""
    exact = FitMethod("exact", 64, 64).describe()
    assert "64 samples" in exact and "exact" in exact and "subset" not in exact and "\n" not in exact
    plain = FitMethod("subset", 2048, 512, 7, (1.0, 1.0)).describe()
    assert all(part in plain for part in ("subset of 512", "2048 samples", "seed 7")) and "shortened" not in plain
    shrunk = FitMethod("subset", 2048, 512, 7, (1.0, 0.8, 0.64)).describe()
    assert shrunk.startswith(plain) and "2 output(s) shortened" in shrunk and "x0.64" in shrunk


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
    *_, record = caplog.records  # the subset's own exact fit logs first
    assert (record.name, record.levelno) == (ordinary.__name__, logging.INFO)
    assert record.args == (16, 64, n_eval, 64, 3, 2)  # subset, samples, evaluations, samples, dims, outputs
    assert "16 of 64 samples" in record.getMessage()  # formatted without error


def test_a_system_of_all_samples_that_stays_singular_names_the_sizes_and_the_remedies(monkeypatch):
    """The very smooth response of ``test_kriging_scale.py``, whose subset ranges make the system of
    all 60 samples singular, with the shortening allowed one step only: the error names the sample
    count, the output, the subset size and the two remedies. Defects: the record of the subset (used
    in the message) wrong or missing."""
    rng = np.random.default_rng(0)
    X = rng.random((60, 3))
    Y = np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1] ** 2, X[:, 0] * X[:, 2]])
    monkeypatch.setattr(ordinary, "RANGE_SHRINK_STEPS", 1)
    with pytest.raises(ValueError, match="all 60 samples is singular") as raised:
        OrdinaryKriging(fit_subset=20).fit(X, Y)
    for fragment in ("20 of them", "x0.8", "nugget=1e-8", "fit_subset=None"):  # subset, shortening, remedies
        assert fragment in str(raised.value)


@pytest.mark.parametrize("optimizer", ["l-bfgs-b", None])
def test_nearly_coincident_samples_make_a_singular_system_and_the_message_says_where(optimizer):
    """Two samples 1e-12 apart (not identical, so the duplicate check lets them through): their
    correlation rounds to 1, the system is singular at every range, and the error gives the ranges
    tried, the cause, the distance of the closest samples and the remedies. Defects: the distance,
    the ranges or the cause missing or wrong."""
    X = sobol(16, 2, seed=0)
    X[9] = X[5] + np.array([1e-12, 0.0])  # not the first pair of the pairwise distances
    y = np.sin(3 * X[:, 0]) + X[:, 1]
    cause = "every starting point" if optimizer else "reciprocal condition number"
    with pytest.raises(ValueError, match=r"ranges \(0\.3, 0\.3\)") as raised:
        OrdinaryKriging(beta=1.5, ranges=0.3, optimizer=optimizer, fit_subset=None).fit(X, y)
    for fragment in ("output 0", cause, "1e-12 apart", "nugget=1e-8"):  # the cause, the distance, the remedy
        assert fragment in str(raised.value)


def test_a_search_that_fails_from_every_start_names_the_starting_ranges_only():
    """Every optimiser run ends on a singular system (an injected optimiser that returns the
    criterion's failure value): the message quotes the starting ranges, not the exponent searched
    with them. Defect: the exponent shown as a range."""
    X = sobol(16, 2, seed=0)
    failing = OrdinaryKriging(beta="fit", ranges=[0.3, 0.6], optimizer=lambda objective, x0, bounds: (x0, ordinary.FAIL))
    with pytest.raises(ValueError, match=r"ranges \(0\.3, 0\.6\) \(") as raised:
        failing.fit(X, np.sin(3 * X[:, 0]) + X[:, 1])
    assert "output 0" in str(raised.value) and "every starting point" in str(raised.value)
    assert "1.8" not in str(raised.value)


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


@pytest.mark.parametrize("settings, fragments", [
    ({"optimizer": "bfgs"}, ("optimizer", "'bfgs'", "'l-bfgs-b'", "callable")),
    ({"optimizer": 42}, ("optimizer", "42")),
    ({"beta": "fit", "optimizer": None}, ("beta='fit'", "optimizer='l-bfgs-b'")),
    ({"range_bounds": (0.0, 1.0)}, ("range_bounds", "0 < lower < upper", "(0.0, 1.0)")),
    ({"range_bounds": (0.5, 0.5)}, ("range_bounds", "(0.5, 0.5)")),
    ({"n_restarts": -1}, ("n_restarts", ">= 0", "-1")),
    ({"n_restarts": 1.0}, ("n_restarts", "integer", "1.0")),
    ({"n_restarts": True}, ("n_restarts", "True")),
    ({"ranges": 0.0}, ("ranges", "> 0", "0.0")),
    ({"ranges": [0.5, np.inf, 0.5]}, ("ranges", "finite", "inf")),
])
def test_bad_settings_are_refused_naming_the_setting_and_what_is_allowed(settings, fragments):
    """Each setting's check at its edge (a lower range bound of 0, equal bounds, a negative, float or
    boolean restart count, a zero or infinite range, an optimiser that is neither a name nor a
    callable): the error names the setting, the value and what is allowed. Defects: an edge
    accepted (a range of 0 divides by zero in the kernel; an empty bound interval stalls L-BFGS-B)."""
    X = sobol(16, 3, seed=0)
    with pytest.raises(ValueError, match=re.escape(fragments[0])) as err:
        OrdinaryKriging(**{"beta": 1.5, **settings}).fit(X, _f(X))
    assert all(fragment in str(err.value) for fragment in fragments), str(err.value)


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
    with pytest.raises(ordinary.NotFittedError, match=r"not fitted.*fit\(X, Y\)"):
        OrdinaryKriging().predict(X)
    Xd = np.vstack([X, X[3]])
    with pytest.raises(ValueError, match=r"rows \[3, 16\]") as raised:
        OrdinaryKriging(beta=1.5).fit(Xd, _f(Xd))
    assert "duplicate" in str(raised.value) and "nugget=1e-8" in str(raised.value)
    with pytest.raises(ValueError, match=r"fit method.*'all'"):
        FitMethod("all", 16, 16)


def _global_search(objective, x0, bounds):
    """An injected optimiser independent of L-BFGS-B: differential evolution over the whole box
    (seeded), polished by L-BFGS-B from its best member."""
    found = differential_evolution(lambda x: objective(x)[0], bounds, rng=0, tol=1e-8, popsize=12, maxiter=100)
    return found.x, found.fun


# (variogram, criterion, design seed): the exponential family's exponent ends at its upper bound 2 for
# output 0 of design 0 (the polish at the bound kept) and just below it on design 1; the power model's
# bound is 1.95; LOO has its own scale
@pytest.mark.parametrize("variogram, criterion, seed", [
    ("exponential", "ml", 0), ("exponential", "ml", 1), ("power", "ml", 0), ("exponential", "loo", 0)])
def test_the_exact_fit_finds_the_criterion_optimum_within_the_bounds(variogram, criterion, seed):
    """The multi-start L-BFGS-B search (with the polish of an exponent near its upper bound) reaches
    the optimum that a global search (differential evolution, injected as ``optimizer``) finds in the
    same bounds: within 0.01 of -2 log L, the polish's own tolerance; within 1 % of LOO's error,
    which is flat near its optimum (the two searches stop 0.05 % apart here, while a single start
    from ranges 5 ends 4× higher); ranges and exponents stay within ``range_bounds`` and the
    family's exponent bounds. Defects: a worse start kept, the polish kept when clearly worse, the
    bounds not passed to the search."""
    X = sobol(16, 3, seed=seed)
    lo, hi = 0.02, 50.0
    b_lo, b_hi = {"exponential": (0.2, 2.0), "power": (0.2, 1.95)}[variogram]
    settings = dict(variogram=variogram, beta="fit", criterion=criterion, ranges=[0.3, 0.5, 200.0], n_restarts=2,
                    range_bounds=(lo, hi), random_state=7, fit_subset=None)
    fitted = OrdinaryKriging(**settings).fit(X, _f(X))
    best = OrdinaryKriging(**{**settings, "optimizer": _global_search, "n_restarts": 0}).fit(X, _f(X))
    tol = 0.01 if criterion == "ml" else 1e-2 * np.abs(best.criterion_)
    assert np.all(fitted.criterion_ <= best.criterion_ + tol), (fitted.criterion_, best.criterion_)
    for est in (fitted, best):
        assert np.all((est.ranges_ >= lo * (1 - 1e-12)) & (est.ranges_ <= hi * (1 + 1e-12)))  # exp(log): rounding
        assert np.all((est.beta_ >= b_lo) & (est.beta_ <= b_hi))
        assert np.all(est.n_evaluations_ > 0) and est.n_evaluations_.dtype.kind == "i"
    if (variogram, criterion, seed) == ("exponential", "ml", 0):
        assert fitted.beta_[0] == 2.0  # the polish at the bound, kept: the fast kernel path


def test_an_injected_optimiser_gets_the_objective_the_start_and_the_bounds():
    """``optimizer(objective, x0, bounds) -> (x, f)``: the objective returns the criterion and its
    analytic gradient (checked against central differences), the bounds are the log range bounds
    (and the exponent's), every start lies within them; the default ``l_bfgs_b`` passed as a
    callable gives the default fit bit for bit, and the same ``random_state`` the same fit.
    Defects: another signature, unbounded starts, a gradient of the wrong sign or scale."""
    X = sobol(16, 3, seed=0)
    seen = []

    def recording(objective, x0, bounds):
        seen.append((objective, np.array(x0), bounds))
        return l_bfgs_b(objective, x0, bounds)

    settings = dict(beta="fit", n_restarts=2, range_bounds=(0.02, 50.0), random_state=7, fit_subset=None)
    fitted = OrdinaryKriging(**settings, optimizer=recording).fit(X, _f(X))
    default = OrdinaryKriging(**settings).fit(X, _f(X))
    for a, b in ((fitted.ranges_, default.ranges_), (fitted.beta_, default.beta_), (fitted.n_evaluations_,
                                                                                     default.n_evaluations_)):
        assert_array_equal(a, b)  # the same code path in one process
    again = OrdinaryKriging(**settings).fit(X, _f(X))
    assert_array_equal(again.predict(X[:4] * 0.9 + 0.05), default.predict(X[:4] * 0.9 + 0.05))
    box = np.array([(np.log(0.02), np.log(50.0))] * 3 + [(0.2, 2.0)])
    objective, _, bounds = seen[0]
    assert_allclose(np.asarray(bounds, dtype=float), box, rtol=0, atol=0)
    for _, x0, b in seen:
        assert np.all((x0 >= np.asarray(b)[:, 0]) & (x0 <= np.asarray(b)[:, 1]))
    x = np.array([np.log(0.4), np.log(0.7), np.log(1.3), 1.6])
    f, grad = objective(x)
    h = 1e-6
    fd = [(objective(x + h * e)[0] - objective(x - h * e)[0]) / (2 * h) for e in np.eye(4)]
    assert_allclose(grad, fd, rtol=1e-5, atol=1e-6)  # central differences, step 1e-6: truncation and rounding


def test_fixed_ranges_without_an_optimiser_and_a_shared_exponent():
    """``optimizer=None`` keeps ``ranges`` (clipped to the bounds) and the given exponent and spends
    no evaluation; ``beta="fit-shared"`` fits the exponent on output 0 (as a per-output fit of that
    output alone does) and searches only the ranges of the others, reaching their optimum at that
    exponent. Defects: the ranges not clipped, an optimisation anyway, the shared exponent re-fitted."""
    X = sobol(16, 3, seed=0)
    fixed = OrdinaryKriging(beta=1.5, ranges=[0.005, 0.5, 200.0], optimizer=None, range_bounds=(0.01, 100.0)).fit(X, _f(X))
    assert_allclose(fixed.ranges_, [[0.01, 0.5, 100.0]] * 2, rtol=1e-15)  # exp(log(a)): rounding only
    assert_array_equal(fixed.beta_, [1.5, 1.5])
    assert_array_equal(fixed.n_evaluations_, [0, 0])
    shared = OrdinaryKriging(beta="fit-shared", n_restarts=0).fit(X, _f(X))
    first = OrdinaryKriging(beta="fit", n_restarts=0).fit(X, _f(X)[:, 0])
    assert shared.beta_[1] == shared.beta_[0] == first.beta_[0]
    alone = OrdinaryKriging(beta=float(shared.beta_[0]), n_restarts=2).fit(X, _f(X)[:, 1])
    assert shared.criterion_[1] <= alone.criterion_[0] + 0.01  # the polish's tolerance, in -2 log L


def test_stored_hyperparameters_that_give_a_singular_system_are_named():
    """A surrogate file whose stored ranges make the rebuilt correlation matrix singular (after a
    subset fit the factors are rebuilt at load) names the output and LAPACK's reason, and says the
    values came from the file. Defect: a bare or empty message."""
    X = sobol(16, 3, seed=0)
    fitted = OrdinaryKriging(beta=1.5, fit_subset=8).fit(X, _f(X))
    arrays, attrs = fitted.to_arrays()
    arrays = {**arrays, "ranges": np.array(arrays["ranges"]) * [[1.0], [1e9]]}  # output 1: all samples alike
    # the pivot where the Cholesky factorisation stops depends on rounding: any
    with pytest.raises(ValueError, match=r"stored hyperparameters of output 1.*singular.*pivot \d+"):
        OrdinaryKriging.from_arrays(arrays, attrs, fitted.get_params())


def test_the_hyperparameter_record_checks_every_array_and_keeps_private_read_only_copies():
    """``KrigingHyperparameters``: float copies the caller cannot change afterwards (the fitted
    surrogate must not move when a user edits an array they passed), read-only, one row per output
    with the number of outputs set by ``beta``; each wrong array named with its expected and actual
    shape; an unknown variogram refused. Defects: a view kept instead of a copy, an array left
    writable or integer, a check skipped or a message naming the wrong array."""
    ranges, beta, mu, sigma2 = np.array([[0.5, 0.2], [0.3, 0.4]]), [2, 1], np.array([1.0, 2.0]), np.array([0.1, 0.2])
    hp = KrigingHyperparameters("exponential", 0, ranges, beta, mu, sigma2)
    ranges[0, 0], mu[0], sigma2[0] = 9.0, 9.0, 9.0
    assert (hp.ranges[0, 0], hp.mu[0], hp.sigma2[0]) == (0.5, 1.0, 0.1)
    assert hp.beta.dtype == np.float64 and type(hp.nugget) is float and hp.n_outputs == 2
    assert not any(getattr(hp, k).flags.writeable for k in ("ranges", "beta", "mu", "sigma2"))
    assert_array_equal(hp.theta, [[0.5 ** -2, 0.2 ** -2], [0.3 ** -1, 0.4 ** -1]])
    good = {"ranges": ranges, "beta": beta, "mu": mu, "sigma2": sigma2}
    for name, bad, dims, shape in [("ranges", [0.5, 0.2], 2, (2,)), ("ranges", [[0.5, 0.2]], 2, (1, 2)),
                                   ("mu", [1.0, 2.0, 3.0], 1, (3,)), ("mu", [[1.0], [2.0]], 1, (2, 1)),
                                   ("sigma2", [0.1], 1, (1,)), ("beta", [[2.0], [1.0]], 1, (2, 1))]:
        with pytest.raises(ValueError, match=rf"KrigingHyperparameters\.{name} must have {dims} dim") as raised:
            KrigingHyperparameters("exponential", 0.0, **{**good, name: bad})
        assert f"got shape {shape}" in str(raised.value) and "2 rows" in str(raised.value)
    with pytest.raises(ValueError, match="variogram.*'gaussian'"):
        KrigingHyperparameters("gaussian", 0.0, **good)


def test_a_clearly_negative_variance_warns_once_with_its_value_and_is_clipped(monkeypatch):
    """Variances below -1e-6 of the sill (an ill-conditioned system) warn with the lowest value and
    the remedy, attributed to the caller of ``predict``; rounding-level negatives (here half that)
    are clipped silently; the means are untouched. Outputs of 1e-3 (a sill ~1e-7, as for readings
    in m) pin the threshold as relative to the sill. Defects: the warning lost, raised for
    rounding noise, the threshold not relative, or the variance returned negative."""
    X = sobol(16, 3, seed=0)
    fitted = OrdinaryKriging(beta=1.5).fit(X, 1e-3 * _f(X))
    Xp = sobol(8, 3, seed=1)
    mean = fitted.predict(Xp)
    sill = fitted.sigma2_[:, None]
    assert sill.max() < 1e-5
    for factor, warns in ((-0.5e-6, False), (-2e-6, True)):
        monkeypatch.setattr(fitted, "_variance_from_covariance", lambda K, f=factor: np.broadcast_to(f * sill, K.shape[:2]))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            m, std = fitted.predict(Xp, return_std=True)
        assert_array_equal(m, mean)
        assert np.all(std == 0.0)
        if warns:
            (warning,) = caught
            assert f"{-2e-6 * sill.max():.3g}" in str(warning.message) and "nugget" in str(warning.message)
            assert warning.category is UserWarning and warning.filename == __file__
        else:
            assert caught == []


@pytest.mark.parametrize("block_bytes, blocks", [(3 * 8 * 16 * 2, [3, 3, 3, 1]), (5 * 8 * 16 * 2 - 1, [4, 4, 2]),
                                                 (100, [1] * 10), (2**30, [10]), (100, [1])])
def test_variances_are_formed_in_blocks_within_the_memory_bound(monkeypatch, block_bytes, blocks):
    """The cross-covariances of a variance pass, ``(n_outputs, block, n)`` doubles, stay within
    ``VARIANCE_BLOCK_BYTES`` (at least one point per block), each point in exactly one block, and
    the result does not depend on the blocking. Defects: a block sized on the dimensions instead of
    the samples, rounded up, or past the bound; blocks that overlap, repeat or run empty."""
    X = sobol(16, 3, seed=0)
    fitted = OrdinaryKriging(beta=1.5).fit(X, _f(X))
    Xp = uniform(sum(blocks), 3, seed=1)
    reference = fitted.predict(Xp, return_std=True)
    sizes, real = [], ordinary._kernels.predict_mean_and_covariance

    def spy(points, *args, **kwargs):
        sizes.append(len(points))
        return real(points, *args, **kwargs)

    monkeypatch.setattr(ordinary, "VARIANCE_BLOCK_BYTES", block_bytes)
    monkeypatch.setattr(ordinary._kernels, "predict_mean_and_covariance", spy)
    mean, std = fitted.predict(Xp, return_std=True)
    assert sizes == blocks
    assert_array_equal(mean, reference[0])  # the kernel works point by point: any blocking, the same bits
    # the triangular product (BLAS) may block its columns differently for another count: rounding only
    assert_allclose(std, reference[1], rtol=1e-12)


def test_fit_refuses_bad_training_data_naming_what_is_wrong():
    """Each refusal of ``OrdinaryKriging.fit`` whole; the unit cube's faces are accepted (up to
    1e-9 of rounding). Defects: a check skipped or weakened (one of two conditions), the unit
    cube's bound moved, a message emptied or quoting the wrong size."""
    X = sobol(16, 3, seed=0)
    y = _f(X)
    nan_x, inf_y = X.copy(), y.copy()
    nan_x[3, 1], inf_y[5, 0] = np.nan, np.inf
    cases = [
        (X[0], y, ("X must have shape", "(3,)")),
        (X, y[:, :, None], ("Y must have shape", "(16, 2, 1)")),
        (X, y[:15], ("Y must have shape (16,)", "(15, 2)")),
        (X, y[:15, 0], ("Y must have shape (16,)", "(15, 1)")),
        (X[:2], y[:2], ("at least 3 samples", "got 2")),
        (nan_x, y, ("must be finite", "NaN")),
        (X, inf_y, ("must be finite", "inf")),
        (X - 1e-6 - X.min(), y, ("unit cube", f"[{-1e-6:g}, ", "ParameterSpace.to_unit")),
        (X + 1 + 1e-6 - X.max(), y, ("unit cube", f", {1 + 1e-6:g}]", "ParameterSpace.to_unit")),
    ]
    for Xbad, ybad, fragments in cases:
        with pytest.raises(ValueError, match=re.escape(fragments[0])) as raised:
            OrdinaryKriging(beta=1.5).fit(Xbad, ybad)
        assert all(fragment in str(raised.value) for fragment in fragments), str(raised.value)
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.5]])
    for shift in (0.0, 1e-10):  # on the faces, and rounding beyond them
        inside = np.clip(corners + shift * np.sign(corners - 0.5), -1.0, 2.0)
        assert OrdinaryKriging(beta=1.5).fit(inside, inside.sum(axis=1)).n_features_in_ == 2


def test_fit_keeps_its_own_float_copy_of_the_inputs():
    """The training inputs are the estimator's own float copy: changing the caller's array after
    the fit changes nothing, and integer inputs (the unit square's corners) fit as their floats.
    Defects: the caller's array kept by reference, or integers kept as integers."""
    X = sobol(16, 3, seed=0)
    fitted = OrdinaryKriging(beta=1.5).fit(X, _f(X))
    Xp, kept = uniform(5, 3, seed=4), X.copy()
    before = fitted.predict(Xp)
    X[:] = X[::-1]
    assert_array_equal(fitted.X_, kept)
    assert_array_equal(fitted.predict(Xp), before)
    corners = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])
    as_int = OrdinaryKriging(beta=1.5, ranges=0.7, optimizer=None).fit(corners, np.array([0, 1, 1, 3]))
    as_float = OrdinaryKriging(beta=1.5, ranges=0.7, optimizer=None).fit(corners.astype(float), np.array([0.0, 1, 1, 3]))
    assert as_int.X_.dtype == np.float64
    for a, b in zip(as_int.predict(Xp[:, :2], return_std=True), as_float.predict(Xp[:, :2], return_std=True)):
        assert_array_equal(a, b)


def test_a_constant_output_is_reproduced_without_a_search_and_with_zero_variance(caplog):
    """An output constant up to rounding (1e-14 of its size, here 1000 + 1e-12 wiggles) is not
    optimised (its ranges stay at the start, no evaluations) and has zero variance, so it is
    predicted as itself with zero spread; with ``beta="fit-shared"`` a constant first output
    shares its starting exponent (1.8) with the others, whose ranges are still searched. The log
    record states the sizes and the evaluations spent. Defects: the search run on a constant (its
    criterion is singular), the rounding tolerance scaled the wrong way, the shared exponent lost."""
    X = sobol(16, 3, seed=0)
    wiggle = 1e-12 * np.where(np.arange(16) % 2, 1.0, -1.0)
    Y = np.column_stack([1000.0 + wiggle, _f(X)[:, 0]])
    with caplog.at_level(logging.INFO, logger=ordinary.__name__):
        fitted = OrdinaryKriging(beta="fit-shared", ranges=0.3, n_restarts=0).fit(X, Y)
    assert fitted.n_evaluations_[0] == 0 and fitted.n_evaluations_[1] > 0
    assert_allclose(fitted.ranges_[0], 0.3, rtol=1e-15)
    assert_array_equal(fitted.beta_, [1.8, 1.8])
    assert fitted.sigma2_[0] == 0.0 and fitted.sigma2_[1] > 0
    mean, std = fitted.predict(uniform(5, 3, seed=4), return_std=True)
    assert_allclose(mean[:, 0], 1000.0, rtol=1e-14)
    assert np.all(std[:, 0] == 0.0) and np.all(std[:, 1] > 0)
    (record,) = caplog.records
    assert (record.name, record.levelno) == (ordinary.__name__, logging.INFO)
    assert record.args == (16, 3, 2, int(fitted.n_evaluations_.sum()))  # samples, dims, outputs, evaluations


def test_the_documented_defaults_and_every_setting_given_are_kept():
    """The defaults the class docstring documents (and ``podkrig surrogate build`` and the study file
    rely on), and every setting a user passes stored as given. Defects: a default changed silently
    (e.g. one more random restart: slower fits, other hyperparameters), a setting dropped."""
    assert OrdinaryKriging().get_params() == {
        "variogram": "exponential", "beta": "fit-shared", "ranges": 0.5, "nugget": 0.0, "criterion": "ml",
        "optimizer": "l-bfgs-b", "n_restarts": 1, "range_bounds": (0.01, 100.0), "random_state": 0,
        "use_numba": None, "fit_subset": "auto"}
    given = {"variogram": "power", "beta": 1.2, "ranges": [0.2, 0.3], "nugget": 1e-8, "criterion": "loo",
             "optimizer": None, "n_restarts": 3, "range_bounds": (0.1, 10.0), "random_state": 5, "use_numba": False,
             "fit_subset": 64}
    assert OrdinaryKriging(**given).get_params() == given


@pytest.mark.parametrize("variogram, fit_subset", [("exponential", None), ("exponential", 8), ("power", None), ("power", 8)])
def test_every_fit_round_trips_through_its_arrays(variogram, fit_subset):
    """Exact and subset fits of both families are rebuilt from ``to_arrays`` with the same means
    and standard deviations; only the exponential family's subset fit leaves its factors out of the
    arrays (rebuilt at load, bit for bit). Defects: the power model's projected precision dropped
    or rebuilt as an exponential-family factor."""
    X = sobol(16, 3, seed=0)
    fitted = OrdinaryKriging(variogram=variogram, beta=1.5, fit_subset=fit_subset).fit(X, _f(X))
    arrays, attrs = fitted.to_arrays()
    assert ("L" in arrays) == (variogram == "power" or fit_subset is None)
    back = OrdinaryKriging.from_arrays(arrays, attrs, fitted.get_params())
    Xp = uniform(6, 3, seed=2)
    for a, b in zip(back.predict(Xp, return_std=True), fitted.predict(Xp, return_std=True)):
        assert_array_equal(a, b)


def test_a_grid_design_with_repeated_coordinates_fits_its_exponent_cleanly():
    """On a grid, many sample pairs share a coordinate (|Δx_k| = 0): the exponent's gradient takes
    log|Δx_k| there as 0 (its term A^β log A vanishes), with no division-by-zero warning and a
    finite criterion. Defect: log 0 = -inf reaching the gradient (NaN)."""
    g = np.linspace(0.0, 1.0, 5)
    X = np.array([(a, b) for a in g for b in g])
    y = np.sin(3 * X[:, 0]) + X[:, 1] ** 2
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fitted = OrdinaryKriging(beta="fit").fit(X, y)
    assert np.isfinite(fitted.criterion_).all() and 0.2 <= fitted.beta_[0] <= 2.0


def test_a_surrogate_fitted_with_an_injected_optimiser_is_written_with_its_name(tmp_path):
    """A callable optimiser cannot be stored: the surrogate file records its name, the loaded
    surrogate predicts as the fitted one, and refitting the loaded settings asks for an optimiser
    the estimator knows. Defects: writing the file fails on the callable, or a refit silently uses
    another optimiser."""
    from podkrig.io.surrogate_file import load_surrogate, save_surrogate
    from podkrig.surrogate.podkriging import PODKriging

    def custom_search(objective, x0, bounds):
        return l_bfgs_b(objective, x0, bounds)

    X = sobol(16, 3, seed=0)
    fitted = PODKriging(kriging=OrdinaryKriging(optimizer=custom_search)).fit(X, _f(X))
    save_surrogate(fitted, tmp_path / "s.h5")
    loaded = load_surrogate(tmp_path / "s.h5")
    assert "custom_search" in loaded.kriging.optimizer
    Xp = uniform(5, 3, seed=2)
    assert_array_equal(loaded.predict(Xp), fitted.predict(Xp))  # same process, same arrays
    with pytest.raises(ValueError, match="optimizer .*'l-bfgs-b', a callable or None"):
        OrdinaryKriging(**loaded.kriging.get_params()).fit(X, _f(X))


def _kinked(X, rough=False):
    """Two outputs with kinks; the second is nearly smooth (its likelihood's optimum a long ridge
    towards the exponent 2) unless ``rough``."""
    second = np.abs(X[:, 1] - 0.55) + np.abs(X[:, 2] - 0.3) * X[:, 0] if rough else \
        np.abs(X[:, 1] - 0.6) ** 1.2 + X[:, 2] * X[:, 0]
    return np.column_stack([np.abs(X[:, 0] - 0.4) + np.sin(5 * X[:, 1]) * X[:, 2], second])


@pytest.mark.parametrize("beta", ["fit", "fit-shared"])
@pytest.mark.parametrize("factor", [8.0, 2.0**-10])
def test_the_maximum_likelihood_fit_does_not_depend_on_the_unit_of_the_data(beta, factor):
    """The concentrated likelihood of c y is that of y plus m log c², a constant: the fit searches
    the output divided by its standard deviation, so a factor that is a power of two (exact in
    floating point) gives bitwise the same ranges and exponents, and σ², the mean, the weights and
    the predictions scaled by it exactly. Defect: the search run on the data as given, whose
    constant moved L-BFGS-B's relative stopping test (ftol × |f|) along the ridge of the second
    output: its ranges and exponent then depended on the unit (×8: σ 3.7 → 9.3)."""
    X = sobol(64, 3, seed=0)
    a = OrdinaryKriging(beta=beta).fit(X, _kinked(X))
    b = OrdinaryKriging(beta=beta).fit(X, factor * _kinked(X))
    ha, hb = a.hyperparameters_, b.hyperparameters_
    assert_array_equal(hb.ranges, ha.ranges)
    assert_array_equal(hb.beta, ha.beta)
    # products with a power of two are exact: rtol 1e-15 only spells out the comparison
    assert_allclose(hb.sigma2, factor**2 * ha.sigma2, rtol=1e-15)
    assert_allclose(hb.mu, factor * ha.mu, rtol=1e-15)
    assert_allclose(b.alpha_, factor * a.alpha_, rtol=1e-15)
    assert_allclose(b.criterion_, a.criterion_ + 64 * np.log(factor**2), rtol=1e-12)  # -2 log L of the data given
    U = uniform(20, 3, seed=2)
    mean_a, std_a = a.predict(U, return_std=True)
    mean_b, std_b = b.predict(U, return_std=True)
    assert_allclose(mean_b, factor * mean_a, rtol=1e-15)
    assert_allclose(std_b, factor * std_a, rtol=1e-15)


@pytest.mark.parametrize("beta", ["fit", "fit-shared"])
def test_the_fit_of_data_in_another_unit_agrees_to_the_search_tolerance(beta):
    """Data ×7.3 (not a power of two: the scaled outputs differ from the originals by rounding):
    ranges, exponents and σ/7.3 agree within 1e-5 relative, the stopping tolerance of L-BFGS-B
    on these well-posed likelihoods (both exponents below 2, every range inside its bounds)."""
    X = sobol(64, 3, seed=0)
    Y = _kinked(X, rough=True)
    a = OrdinaryKriging(beta=beta).fit(X, Y)
    b = OrdinaryKriging(beta=beta).fit(X, 7.3 * Y)
    ha, hb = a.hyperparameters_, b.hyperparameters_
    assert np.all(ha.beta < 1.995) and np.all(ha.ranges < 10)  # the premise: an interior optimum
    assert_allclose(hb.ranges, ha.ranges, rtol=1e-5)
    assert_allclose(hb.beta, ha.beta, rtol=1e-5)
    assert_allclose(np.sqrt(hb.sigma2) / 7.3, np.sqrt(ha.sigma2), rtol=1e-5)


def test_a_constant_output_is_constant_at_any_scale():
    """An output constant to rounding is recognised relative to its own size, whatever its unit.
    Defect: an absolute floor (spread ≤ 1e-14 × max(1, |y|)) that took a varying output of size
    1e-15 for a constant one, and would not for the same data in another unit."""
    X = sobol(16, 3, seed=0)
    small = 1e-15 * _f(X)[:, 0]
    fitted = OrdinaryKriging(beta=1.8, n_restarts=0).fit(X, np.column_stack([small, 1e-15 + 0 * small]))
    assert fitted.sigma2_[0] > 0 and fitted.n_evaluations_[0] > 0  # varying: searched
    assert fitted.sigma2_[1] == 0.0 and fitted.n_evaluations_[1] == 0  # constant: not
