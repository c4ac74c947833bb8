"""The selectable surrogate backends (podkrig/surrogate/backends.py, issue 12): the registry and its
error messages, the input and setting checks, fit/predict shapes and interpolation, exact
persistence through to_arrays/from_arrays, the version record and warning, and the subset fit.

Small analytic data: 16 Sobol points in the unit square, two smooth outputs; SMT with one start
and scikit-learn without restarts, so that each fit takes a few milliseconds.
"""

import importlib.metadata
import json
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from podkrig import __version__
from podkrig.exceptions import NotFittedError
from podkrig.offline.sampling import sobol, uniform
from podkrig.surrogate.backends import (
    BACKENDS,
    SklearnGPR,
    SMTKriging,
    backend_from_arrays,
    backend_name,
    backend_version,
    make_backend,
)
from podkrig.surrogate.kriging import FitMethod, OrdinaryKriging

FAST = {"smt-krg": {"n_start": 1}, "smt-kpls": {"n_start": 1, "n_comp": 1}, "sklearn-gpr": {"n_restarts_optimizer": 0}}


def _f(X):
    """Two smooth outputs of two inputs in the unit square."""
    return np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1] ** 2, np.exp(-X[:, 0] * X[:, 1])])


@pytest.fixture(scope="module")
def data():
    X = sobol(16, 2, seed=0)
    return X, _f(X), uniform(20, 2, seed=1)


@pytest.fixture(scope="module")
def fitted(data):
    X, Y, _ = data
    return {name: make_backend(name, **kw).fit(X, Y) for name, kw in FAST.items()}


# ---------------------------------------------------------------- registry
def test_registry_names_classes_and_versions():
    """Each name builds its class with the method the name promises; backend_name inverts it and
    backend_version reports the library that computes the predictions."""
    assert list(BACKENDS) == ["podkrig", "smt-krg", "smt-kpls", "sklearn-gpr"]
    ok = make_backend("podkrig")
    assert isinstance(ok, OrdinaryKriging) and backend_name(ok) == "podkrig" and backend_version(ok) == __version__
    for name, cls, method in (("smt-krg", SMTKriging, "krg"), ("smt-kpls", SMTKriging, "kpls")):
        est = make_backend(name)
        assert type(est) is cls and est.method == method and backend_name(est) == name
        assert backend_version(est) == importlib.metadata.version("smt")
    gpr = make_backend("sklearn-gpr", nu=1.5)
    assert type(gpr) is SklearnGPR and gpr.nu == 1.5 and backend_name(gpr) == "sklearn-gpr"
    assert backend_version(gpr) == importlib.metadata.version("scikit-learn")


def test_registry_errors_name_the_value_and_the_choices():
    """A misspelt backend or setting is a ValueError naming what was given and what exists."""
    with pytest.raises(ValueError, match=r"podkrig, smt-krg, smt-kpls, sklearn-gpr; got 'smt'"):
        make_backend("smt")
    with pytest.raises(ValueError, match=r"'sklearn-gpr' .*settings: \['n_start'\]"):
        make_backend("sklearn-gpr", n_start=3)
    with pytest.raises(TypeError, match="not a surrogate backend: dict; .*podkrig, smt-krg"):
        backend_name({})
    with pytest.raises(ValueError, match="unknown surrogate backend 'gp'; .*podkrig, smt-krg"):
        backend_from_arrays("gp", {}, {}, {})


def test_default_settings_and_get_params():
    """The documented defaults (SMT's nugget 100 eps and seed 41, five starts; scikit-learn's
    Matérn 5/2, jitter 1e-10, two restarts, seed 0) and get_params listing exactly them."""
    assert make_backend("smt-kpls").get_params() == {
        "method": "kpls", "corr": "squar_exp", "n_comp": 2, "n_start": 5,
        "nugget": 100.0 * np.finfo(float).eps, "random_state": 41, "fit_subset": None}
    assert make_backend("sklearn-gpr").get_params() == {
        "nu": 2.5, "alpha": 1e-10, "n_restarts_optimizer": 2, "random_state": 0, "fit_subset": None}
    assert make_backend("smt-krg").backend == "smt-krg" and SklearnGPR.backend == "sklearn-gpr"


def test_describe_is_one_line_with_library_version_and_settings():
    """The report line: backend, library and version, every setting as 'name value'."""
    v = importlib.metadata.version("scikit-learn")
    described = make_backend("sklearn-gpr").describe()
    assert "\n" not in described and described.startswith(f"sklearn-gpr (scikit-learn {v}): ")
    for setting in ("nu 2.5", "alpha 1e-10", "n_restarts_optimizer 2", "random_state 0", "fit_subset None"):
        assert setting in described


# ---------------------------------------------------------------- checks
@pytest.mark.parametrize("name", ["smt-krg", "sklearn-gpr"])
def test_input_checks_name_the_shapes(data, name):
    """Wrong shapes, too few samples or NaN (a failed FE run) are refused before any library call."""
    X, Y, _ = data
    est = make_backend(name, **FAST[name])
    with pytest.raises(ValueError, match=r"X must have shape .*got shape \(16,\)"):
        est.fit(X[:, 0], Y)
    with pytest.raises(ValueError, match=r"Y must have shape \(16,\).*got \(15, 2\)"):
        est.fit(X, Y[:15])
    with pytest.raises(ValueError, match=r"Y must have shape \(16,\).*got \(16, 2, 1\)"):
        est.fit(X, Y[:, :, None])
    with pytest.raises(ValueError, match="at least 3 samples; got 2"):
        est.fit(X[:2], Y[:2])
    for bad in (np.nan, np.inf):
        Yb = Y.copy()
        Yb[3, 1] = bad
        with pytest.raises(ValueError, match=r"must be finite.*drop failed FE runs"):
            est.fit(X, Yb)
        Xb = X.copy()
        Xb[0, 0] = bad
        with pytest.raises(ValueError, match=r"must be finite.*drop failed FE runs"):
            est.fit(Xb, Y)


def test_three_samples_are_enough(data):
    """The documented minimum of 3 samples fits (an interpolator of them)."""
    X, Y, _ = data
    gpr = make_backend("sklearn-gpr", n_restarts_optimizer=0).fit(X[:3], Y[:3, 0])
    assert_allclose(gpr.predict(X[:3]), Y[:3, 0], atol=1e-6)


def test_fit_does_not_alias_the_callers_arrays(data):
    """fit keeps copies: changing the caller's arrays afterwards leaves the stored data alone."""
    X, Y, _ = data
    X2, Y2 = X.copy(), Y.copy()
    gpr = make_backend("sklearn-gpr", n_restarts_optimizer=0).fit(X2, Y2)
    X2[:] = 0.0
    Y2[:] = 0.0
    assert_array_equal(gpr.X_, X)
    assert_array_equal(gpr.Y_, Y)


@pytest.mark.parametrize("settings, message", [
    ({"method": "gp"}, "method .*'krg' or 'kpls'; got 'gp'"),
    ({"method": "kpls", "corr": "matern52"}, r"corr of smt-kpls .*\('squar_exp', 'abs_exp', 'pow_exp'\); got 'matern52'"),
    ({"corr": "gauss"}, r"corr of smt-krg .*'pow_exp', 'matern52', 'matern32'\); got 'gauss'"),
    ({"n_comp": 0}, "n_comp .*integer >= 1; got 0"),
    ({"n_comp": 1.0}, "n_comp .*integer >= 1; got 1.0"),
    ({"n_start": True}, "n_start .*integer >= 1; got True"),
    ({"n_start": 0}, "n_start .*integer >= 1; got 0"),
    ({"nugget": 0.0}, "nugget .*finite number > 0; got 0.0"),
    ({"nugget": np.inf}, "nugget .*finite number > 0; got inf"),
    ({"fit_subset": 2}, "fit_subset .*integer >= 3; got 2"),
    ({"fit_subset": True}, "fit_subset .*integer >= 3; got True"),
    ({"fit_subset": 8.0}, "fit_subset .*integer >= 3; got 8.0"),
])
def test_smt_setting_errors(data, settings, message):
    """Each bad SMT setting is named with its value and what is allowed."""
    X, Y, _ = data
    with pytest.raises(ValueError, match=message):
        SMTKriging(**settings).fit(X, Y)


def test_smt_boundary_settings_are_accepted(data):
    """The smallest allowed values (one start, one PLS component, fit_subset 3) and the Matérn
    correlations of KRG fit."""
    X, Y, _ = data
    SMTKriging(method="kpls", n_comp=1, n_start=1, fit_subset=3).fit(X, Y[:, 0])
    SMTKriging(method="krg", corr="matern32", n_start=1).fit(X, Y[:, 0])


def test_kpls_components_cannot_exceed_the_inputs(data):
    """KPLS with more PLS directions than inputs is refused with both numbers; as many is fine."""
    X, Y, _ = data
    with pytest.raises(ValueError, match="n_comp = 3 .*exceed the 2 inputs"):
        SMTKriging(method="kpls", n_comp=3, n_start=1).fit(X, Y)
    assert SMTKriging(method="kpls", n_comp=2, n_start=1).fit(X, Y).hyper_.shape == (2, 2)


@pytest.mark.parametrize("settings, message", [
    ({"nu": 2.0}, r"nu .*\(0.5, 1.5, 2.5, inf\); got 2.0"),
    ({"alpha": 0.0}, "alpha .*finite number > 0; got 0.0"),
    ({"alpha": np.nan}, "alpha .*finite number > 0; got nan"),
    ({"n_restarts_optimizer": -1}, "n_restarts_optimizer .*integer >= 0; got -1"),
    ({"n_restarts_optimizer": False}, "n_restarts_optimizer .*integer >= 0; got False"),
    ({"n_restarts_optimizer": 1.0}, "n_restarts_optimizer .*integer >= 0; got 1.0"),
])
def test_sklearn_setting_errors(data, settings, message):
    """Each bad scikit-learn setting is named with its value and what is allowed."""
    X, Y, _ = data
    with pytest.raises(ValueError, match=message):
        SklearnGPR(**settings).fit(X, Y)


def test_unfitted_and_wrong_width_predictions_are_refused(data, fitted):
    """predict/to_arrays before fit raise NotFittedError naming the class; a prediction input of
    the wrong width names the width fitted."""
    X, _, Xp = data
    for est in (SklearnGPR(), SMTKriging()):
        with pytest.raises(NotFittedError, match=f"{type(est).__name__} is not fitted.*call fit"):
            est.predict(Xp)
        with pytest.raises(NotFittedError):
            est.to_arrays()
    with pytest.raises(ValueError, match=r"X must have shape \(n_pred, 2\).*got \(20, 3\)"):
        fitted["sklearn-gpr"].predict(np.ones((20, 3)))
    with pytest.raises(ValueError, match=r"X must have shape \(n_pred, 2\).*got \(2,\)"):
        fitted["smt-krg"].predict(X[0])


# ---------------------------------------------------------------- fit and predict
@pytest.mark.parametrize("name", list(FAST))
def test_interpolates_the_training_outputs_with_zero_std_there(data, fitted, name):
    """Kriging interpolates: at the training points the means equal the outputs (to the jitter:
    1e-6 of the output scale) and the standard deviations vanish (< 1e-3 of it); between them
    the standard deviations are positive. Shapes (n_pred, n_outputs); attributes as fitted."""
    X, Y, Xp = data
    est = fitted[name]
    mean, std = est.predict(X, return_std=True)
    assert mean.shape == std.shape == (16, 2)
    assert_allclose(mean, Y, rtol=0, atol=1e-6)
    assert np.all(std >= 0) and np.all(std < 1e-3)
    mp, sp = est.predict(Xp, return_std=True)
    assert mp.shape == (20, 2) and np.all(sp > 1e-6)
    assert_array_equal(est.predict(Xp), mp)
    assert (est.n_features_in_, est.n_outputs_) == (2, 2) and est.fit_method_ == FitMethod("exact", 16, 16)
    n_hyper = {"smt-krg": 2, "smt-kpls": 1, "sklearn-gpr": 3}[name]
    assert est.hyper_.shape == (2, n_hyper)


@pytest.mark.parametrize("name", ["smt-krg", "sklearn-gpr"])
def test_one_dimensional_outputs_give_one_dimensional_predictions(data, fitted, name):
    """Y of shape (n,) gives (n_pred,) means and stds, equal to the 2-D fit's first column (same
    data, same seed: the same model)."""
    X, Y, Xp = data
    est = make_backend(name, **FAST[name]).fit(X, Y[:, 0])
    mean, std = est.predict(Xp, return_std=True)
    assert mean.shape == std.shape == (20,) and est.predict(Xp).shape == (20,)
    m2, s2 = fitted[name].predict(Xp, return_std=True)
    assert_allclose(mean, m2[:, 0], rtol=1e-9, atol=1e-12)
    assert_allclose(std, s2[:, 0], rtol=1e-6, atol=1e-12)


# ---------------------------------------------------------------- persistence
@pytest.mark.parametrize("name", list(FAST))
def test_arrays_round_trip_reproduces_the_predictions(data, fitted, name):
    """to_arrays/from_arrays (no pickle) refits at the stored hyperparameters: the same
    predictions and stds to 1e-12 relative (rounding; the docstring's bound), the same data,
    hyperparameters, record and settings; the attrs name the library and its version."""
    _, _, Xp = data
    est = fitted[name]
    arrays, attrs = est.to_arrays()
    assert set(arrays) == {"X", "Y", "hyper"} and arrays["hyper"] is est.hyper_
    lib = "smt" if name.startswith("smt") else "scikit-learn"
    assert attrs == {"y_1d": False, "library": lib, "library_version": importlib.metadata.version(lib),
                     "fit_method": json.dumps(FitMethod("exact", 16, 16).to_dict())}
    back = backend_from_arrays(name, arrays, attrs, est.get_params())
    assert type(back) is type(est) and back.get_params() == est.get_params()
    assert_array_equal(back.hyper_, est.hyper_)
    assert back.fit_method_ == est.fit_method_ and (back.n_features_in_, back.n_outputs_) == (2, 2)
    m0, s0 = est.predict(Xp, return_std=True)
    m1, s1 = back.predict(Xp, return_std=True)
    assert_allclose(m1, m0, rtol=1e-12, atol=1e-14)
    assert_allclose(s1, s0, rtol=1e-9, atol=1e-14)


def test_round_trip_keeps_one_dimensional_outputs(data):
    """A 1-D fit reloads as 1-D (the y_1d attribute)."""
    X, Y, Xp = data
    est = make_backend("sklearn-gpr", n_restarts_optimizer=0).fit(X, Y[:, 1])
    arrays, attrs = est.to_arrays()
    assert attrs["y_1d"] is True and arrays["Y"].shape == (16, 1)
    back = backend_from_arrays("sklearn-gpr", arrays, attrs, est.get_params())
    assert back.predict(Xp).shape == (20,)
    assert_allclose(back.predict(Xp), est.predict(Xp), rtol=1e-12)


def test_files_without_a_fit_record_were_fitted_exactly(data, fitted):
    """Files written before the subset fit carry no 'fit_method': all samples, exact."""
    arrays, attrs = fitted["smt-krg"].to_arrays()
    attrs = {k: v for k, v in attrs.items() if k != "fit_method"}
    back = backend_from_arrays("smt-krg", arrays, attrs, fitted["smt-krg"].get_params())
    assert back.fit_method_ == FitMethod("exact", 16, 16)


def test_another_library_version_is_warned_about(data, fitted):
    """A file of another library version loads with a UserWarning naming the backend, both
    versions and the consequence; the same version loads silently."""
    est = fitted["smt-kpls"]
    arrays, attrs = est.to_arrays()
    installed = importlib.metadata.version("smt")
    with pytest.warns(UserWarning, match=rf"'smt-kpls' .*smt 0\.1.*{installed} is installed"):
        backend_from_arrays("smt-kpls", arrays, dict(attrs, library_version="0.1"), est.get_params())
    with pytest.warns(UserWarning, match=r"fitted with smt \?;"):
        backend_from_arrays("smt-kpls", arrays, {k: v for k, v in attrs.items() if k != "library_version"},
                            est.get_params())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        backend_from_arrays("smt-kpls", arrays, attrs, est.get_params())


def test_loading_checks_the_settings(data, fitted):
    """Settings are checked at load as at fit (a file edited by hand)."""
    arrays, attrs = fitted["sklearn-gpr"].to_arrays()
    with pytest.raises(ValueError, match="nu must be one of"):
        backend_from_arrays("sklearn-gpr", arrays, attrs, dict(fitted["sklearn-gpr"].get_params(), nu=3.0))


# ---------------------------------------------------------------- subset fit
@pytest.mark.parametrize("name", ["smt-krg", "sklearn-gpr"])
def test_subset_fit_uses_the_hyperparameters_of_the_seeded_subset(data, name):
    """fit_subset = 8 of 16: the hyperparameters are those of the fit on the 8 samples drawn
    without replacement with seed random_state (sorted), the model interpolates all 16, and the
    record says so; fit_subset >= n fits all samples exactly."""
    X, Y, _ = data
    kw = dict(FAST[name], random_state=7)
    est = make_backend(name, fit_subset=8, **kw).fit(X, Y)
    idx = np.sort(np.random.default_rng(7).choice(16, 8, replace=False))
    ref = make_backend(name, **kw).fit(X[idx], Y[idx])
    assert_allclose(est.hyper_, ref.hyper_, rtol=1e-12)
    assert est.fit_method_ == FitMethod("subset", 16, 8, 7)
    assert_allclose(est.predict(X), Y, rtol=0, atol=1e-5)
    for fs in (16, 20):
        assert make_backend(name, fit_subset=fs, **kw).fit(X, Y).fit_method_ == FitMethod("exact", 16, 16)


# ---------------------------------------------------------------- the documented library models
def test_sklearn_model_is_the_documented_kernel(data):
    """The hyperparameters are those of scikit-learn's own GaussianProcessRegressor with the kernel
    of the docstring (constant in [1e-3, 1e3] times an anisotropic Matérn, lengths in [1e-2, 1e3]
    started at 0.5, normalised outputs, jitter alpha, the seed and restarts): identical to 1e-12
    (same optimiser path, same data); every setting reaches scikit-learn (nu 0.5 and alpha 1e-8 are
    not its defaults), also in the regressors rebuilt at load (same predictions and stds)."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern

    X, Y, Xp = data
    est = make_backend("sklearn-gpr", nu=0.5, alpha=1e-8, n_restarts_optimizer=1, random_state=3).fit(X, Y)
    back = backend_from_arrays("sklearn-gpr", *est.to_arrays(), est.get_params())
    for j in range(2):
        kernel = ConstantKernel(1.0, (1e-3, 1e3)) * Matern(np.full(2, 0.5), (1e-2, 1e3), nu=0.5)
        ref = GaussianProcessRegressor(kernel, alpha=1e-8, normalize_y=True, n_restarts_optimizer=1,
                                       random_state=3).fit(X, Y[:, j])
        assert_allclose(est.hyper_[j], ref.kernel_.theta, rtol=1e-12)
        assert_array_equal(est._models[j].kernel_.bounds, ref.kernel_.bounds)  # log of the documented bounds
        params = est._models[j].get_params()
        assert (params["alpha"], params["n_restarts_optimizer"], params["random_state"], params["normalize_y"]) == (
            1e-8, 1, 3, True)
        m0, s0 = ref.predict(Xp, return_std=True)
        m1, s1 = back.predict(Xp, return_std=True)
        assert_allclose(m1[:, j], m0, rtol=1e-10, atol=1e-14)
        assert_allclose(s1[:, j], s0, rtol=1e-8, atol=1e-14)


@pytest.mark.parametrize("method", ["krg", "kpls"])
def test_smt_model_is_the_documented_one(data, method, capsys):
    """The hyperparameters are those of SMT's own KRG/KPLS with the settings passed through
    (correlation, nugget, seed, starts, PLS components), and fitting prints nothing (SMT's
    print_global off)."""
    from smt.surrogate_models import KPLS, KRG

    X, Y, _ = data
    est = SMTKriging(method=method, corr="abs_exp", n_comp=1, n_start=2, nugget=1e-10, random_state=5).fit(X, Y)
    assert capsys.readouterr().out == ""
    for j in range(2):
        opts = {"corr": "abs_exp", "nugget": 1e-10, "print_global": False, "seed": 5, "n_start": 2}
        ref = KPLS(n_comp=1, **opts) if method == "kpls" else KRG(**opts)
        ref.set_training_values(X, Y[:, j])
        ref.train()
        assert_allclose(est.hyper_[j], ref.optimal_theta, rtol=1e-12)


def test_smt_theta_an_ulp_outside_its_bounds_is_kept_at_load(data, fitted):
    """SMT's optimum can sit an ulp above its upper theta bound (20.000000000000004); loading must
    use that theta, not SMT's random replacement of an out-of-bounds start: the rebuilt models
    carry exactly the stored thetas, below and above the default bounds."""
    est = fitted["smt-krg"]
    arrays, attrs = est.to_arrays()
    lo, hi = SMTKriging()._model().options["theta_bounds"]
    hyper = np.array([[np.nextafter(hi, np.inf), 0.5], [0.5 * lo, 1.0]])
    back = backend_from_arrays("smt-krg", dict(arrays, hyper=hyper), attrs, est.get_params())
    for j in range(2):
        assert_array_equal(back._models[j].optimal_theta, hyper[j])


def test_sklearn_load_uses_the_stored_theta_not_a_refit(data, fitted):
    """Loading builds each regressor at the stored kernel theta without optimising: a theta edited
    in the file (not the optimum of the data) is the one the rebuilt kernels carry."""
    est = fitted["sklearn-gpr"]
    arrays, attrs = est.to_arrays()
    hyper = np.log([[2.0, 0.3, 0.7], [0.5, 1.5, 0.2]])
    back = backend_from_arrays("sklearn-gpr", dict(arrays, hyper=hyper), attrs, est.get_params())
    for j in range(2):
        assert_allclose(back._models[j].kernel_.theta, hyper[j], rtol=1e-14)


def test_a_flat_input_is_not_warned_about(data):
    """An output that does not depend on one input drives that length to its upper bound (1e3 in
    the unit cube: "flat along that input", as intended); scikit-learn's "close to the specified
    upper bound" ConvergenceWarning is not passed on to the user."""
    X, _, _ = data
    y = np.sin(3 * X[:, 0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        est = make_backend("sklearn-gpr", n_restarts_optimizer=0).fit(X, y)
    assert est.hyper_[0, 2] == pytest.approx(np.log(1e3))


def test_library_future_warnings_are_silenced_other_warnings_are_not(data, monkeypatch):
    """A library's FutureWarning (a deprecation note about its own API, nothing the user can act
    on) raised while fitting or loading is not shown; any other warning of the library (here a
    RuntimeWarning) still reaches the user, at fit and at load."""
    from sklearn.gaussian_process import GaussianProcessRegressor

    original = GaussianProcessRegressor.fit

    def noisy_fit(self, X, y):
        warnings.warn("option x is deprecated", FutureWarning)
        warnings.warn("ill-conditioned", RuntimeWarning)
        return original(self, X, y)

    monkeypatch.setattr(GaussianProcessRegressor, "fit", noisy_fit)
    X, Y, _ = data
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        est = make_backend("sklearn-gpr", n_restarts_optimizer=0, fit_subset=8).fit(X, Y)
        backend_from_arrays("sklearn-gpr", *est.to_arrays(), est.get_params())
    kinds = [w.category for w in rec]
    assert FutureWarning not in kinds and kinds.count(RuntimeWarning) == 6  # 2 modes: fit on 8, rebuild on 16, load
