"""Estimators that own their state: the hyperparameter value object, persistence inside each
estimator, side-effect-free ``predict``, unit-cube prediction, and files of schema 1."""

import copy
import dataclasses
import datetime
import json
import logging
from pathlib import Path

import h5py
import numpy as np
import pytest
from numpy.testing import assert_array_equal, assert_equal

from podkrig.exceptions import NotFittedError, SchemaError, StoreError
from podkrig.io.surrogate_file import SCHEMA_VERSION, load_surrogate, save_surrogate
from podkrig.offline.sampling import sobol, uniform
from podkrig.offline.store import DONE, FAILED, SnapshotStore
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.surrogate.kriging import DEFAULT_BETA, KrigingHyperparameters, OrdinaryKriging
from podkrig.surrogate.backends import make_backend
from podkrig.surrogate.pod import POD
from podkrig.surrogate.podkriging import PODKriging, fit_from_store, training_data

DATA = Path(__file__).parent / "data"
SPACE = ParameterSpace((Parameter("E_b", 5000.0, 20000.0, unit="MPa"),
                        Parameter("kN_bj", 10.0, 1000.0, "log", "N/mm³"), Parameter("r_hj", 0.1, 1.0)))


def snapshots(X):
    """(n, 3, 4) readings, mm (the generator of tests/data/make_surrogate_v1.py)."""
    E, k, r = X.T
    base = np.stack([1e3 / E, 1 / k, r / k ** 0.5, np.sin(2 * r) / E ** 0.5], axis=1)
    return np.stack([lvl * base for lvl in (1.0, 2.0, 3.0)], axis=1)


@pytest.fixture(scope="module")
def surrogate():
    X = SPACE.from_unit(sobol(24, 3, seed=0, skip=8))
    return PODKriging(pod=POD(energy=1 - 1e-10), kriging=OrdinaryKriging(beta="fit"), space=SPACE).fit(X, snapshots(X))


def test_schema_1_file_loads_and_predicts_as_before(tmp_path):
    """The reference file was written by the code before this layout (see tests/data/README.md), on
    another machine: its predictions are reproduced to rounding, and a rewrite in today's schema
    predicts bit for bit what the loaded file predicts (one process)."""
    with h5py.File(DATA / "surrogate_v1.h5") as f:
        assert (f.attrs["format"], int(f.attrs["schema_version"])) == ("podkrig.surrogate", 1)
    sur = load_surrogate(DATA / "surrogate_v1.h5")
    expected = np.load(DATA / "surrogate_v1_expected.npz")
    mean, std = sur.predict(expected["X"], return_std=True, reshape=True)
    # the expected means were computed on another CPU: BLAS and numba kernels round differently
    # across CPUs (AMD EPYC: all 192 means differ, by at most 3e-11 relative); 1e-9 relative
    # (plus 1e-12 of the largest mean for values near zero) is rounding, far below any accuracy
    # that matters, and far above what a wrong weight or mode would leave
    np.testing.assert_allclose(mean, expected["mean"], rtol=1e-9, atol=1e-12 * np.abs(expected["mean"]).max())
    # the variance is now formed with the stored explicit L^-1 (a triangular product) instead of
    # triangular solves: the same formula in another rounding order. The kriging sums near the
    # conditioning limit amplify rounding ~1e6-fold: 7e-10 relative here; 1e-8 leaves a margin
    # far below any accuracy that matters (the std itself is an estimate)
    np.testing.assert_allclose(std, expected["std"], rtol=1e-8, atol=0)
    assert sur.backend_ == "podkrig" and sur.kriging_.hyperparameters_.variogram == "exponential"
    save_surrogate(sur, tmp_path / "v2.h5")  # rewritten in today's schema, same predictions
    with h5py.File(tmp_path / "v2.h5") as f:
        assert int(f.attrs["schema_version"]) == SCHEMA_VERSION == 3 and f.attrs["backend"] == "podkrig"
    again = load_surrogate(tmp_path / "v2.h5")
    assert_array_equal(again.predict(expected["X"], reshape=True), mean)  # same process: the same bits


def test_hyperparameters_are_one_frozen_value_object(surrogate):
    kr = surrogate.kriging_
    hp = kr.hyperparameters_
    assert isinstance(hp, KrigingHyperparameters)
    assert hp.ranges.shape == (kr.n_outputs_, 3) and hp.beta.shape == hp.mu.shape == hp.sigma2.shape == (kr.n_outputs_,)
    assert kr.beta_ is hp.beta and kr.ranges_ is hp.ranges and kr.sigma2_ is hp.sigma2
    with pytest.raises(dataclasses.FrozenInstanceError):
        hp.nugget = 1.0
    with pytest.raises(ValueError, match="read-only"):
        hp.beta[0] = 1.0
    assert KrigingHyperparameters.from_dict(hp.to_dict()) == hp
    assert KrigingHyperparameters.from_dict({**hp.to_dict(), "nugget": 1e-9}) != hp
    with pytest.raises(ValueError, match="sigma2 must have 1 dimension"):
        KrigingHyperparameters("exponential", 0.0, hp.ranges, hp.beta, hp.mu, hp.sigma2[:1])


def test_kriging_persists_itself_bitwise(surrogate):
    kr = surrogate.kriging_
    arrays, attrs = kr.to_arrays()
    back = OrdinaryKriging.from_arrays(arrays, attrs, kr.get_params())
    U = uniform(50, 3, seed=2)
    for a, b in zip(kr.predict(U, return_std=True), back.predict(U, return_std=True)):
        assert_array_equal(a, b)
    with pytest.raises(ValueError, match="does not match the variogram 'power'"):
        OrdinaryKriging.from_arrays(arrays, {**attrs, "variogram": "power"}, kr.get_params())


def test_surrogate_state_round_trips_as_arrays_without_a_file(surrogate):
    """The surrogate exchanges its state as plain arrays and metadata (what the file format writes):
    ``from_arrays(*to_arrays())`` predicts bitwise as the original in the same process, and the
    metadata is JSON-able (the file stores it as JSON text)."""
    arrays, attrs = surrogate.to_arrays()
    assert set(arrays) == {"X", "U", "lower", "upper", "train_norm", "train_residual_norm", "pod", "kriging"}
    json.dumps({k: attrs[k] for k in ("settings", "provenance", "parameter_space", "output_shape")})
    back = PODKriging.from_arrays(arrays, attrs)
    X = SPACE.from_unit(uniform(7, 3, seed=2))
    for a, b in zip(back.predict(X, return_std=True), surrogate.predict(X, return_std=True)):
        assert_equal(a, b)  # same process, same arrays: the same floating-point operations
    assert back.backend_ == "podkrig" and back.space.to_dict() == SPACE.to_dict()


def _state(obj):
    """Deep copy of ``vars(obj)``, podkrig objects inside as their own ``vars`` (compared by value)."""
    return {k: _state(v) if type(v).__module__.startswith("podkrig") else copy.deepcopy(v)
            for k, v in vars(obj).items()}


@pytest.mark.parametrize("use_numba", [None, False])
def test_predict_leaves_the_estimator_unchanged(use_numba):
    """Everything predict reuses (numba plan, L^-1 1) is built at fit; also after load."""
    rng = np.random.default_rng(0)
    X = rng.random((25, 2))
    Y = np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1], X[:, 0] * X[:, 1]])
    for ok in (OrdinaryKriging(beta="fit", use_numba=use_numba).fit(X, Y),
               OrdinaryKriging(variogram="power", beta=1.5, use_numba=use_numba).fit(X, Y)):
        before = _state(ok)
        ok.predict(rng.random((7, 2)), return_std=True)
        ok.predict(rng.random((3, 2)) * 1.5)  # reaching outside the unit cube: a plan of its own
        assert vars(ok).keys() == before.keys()
        assert_equal(_state(ok), before)


def test_surrogate_predict_and_predict_unit_leave_state_unchanged(surrogate, tmp_path):
    save_surrogate(surrogate, tmp_path / "s.h5")
    for sur in (surrogate, load_surrogate(tmp_path / "s.h5")):
        before, before_kr = _state(sur), _state(sur.kriging_)
        sur.predict(SPACE.from_unit(uniform(5, 3, seed=1)), return_std=True)
        sur.predict_unit(uniform(5, 3, seed=1), return_std=True)
        assert_equal(_state(sur), before)
        assert_equal(_state(sur.kriging_), before_kr)


def test_predict_unit_is_predict_without_the_round_trip(surrogate):
    U = uniform(40, 3, seed=3)
    U[:4] = [[0, 0, 0], [1, 1, 1], [0, 1, 0.5], [1 - 1e-16, 1 - 1e-16, 1e-300]]  # faces, an ulp inside
    m_unit, s_unit = surrogate.predict_unit(U, return_std=True)
    m_phys, s_phys = surrogate.predict(SPACE.from_unit(U), return_std=True)
    # the same points up to an ulp of the log scale's round trip, which the kriging weights
    # (sum |alpha_i k_i| ~ 1e7 |y|, BENCHMARKS.md) amplify to ~1e-11 of the outputs' scale
    np.testing.assert_allclose(m_unit, m_phys, rtol=0, atol=1e-9 * np.abs(m_phys).max())
    np.testing.assert_allclose(s_unit, s_phys, rtol=0, atol=1e-6 * s_phys.max())
    with pytest.raises(ValueError, match=r"unit coordinates .*\[0, 1\].*sample 0: kN_bj has 1.01"):
        surrogate.predict_unit([[0.5, 1.01, 0.5]])
    with pytest.raises(ValueError, match=r"U must have shape \(n, 3\)"):
        surrogate.predict_unit(np.zeros((2, 2)))
    # the mean alone by default; one sample as a vector; integer corners; the snapshot shape (another
    # batch size may change the BLAS path: equal to rounding, 1e-14)
    np.testing.assert_allclose(surrogate.predict_unit(U[:5]), m_unit[:5], rtol=1e-14)
    np.testing.assert_allclose(surrogate.predict_unit(U[4]), m_unit[4:5], rtol=1e-14)
    assert_array_equal(surrogate.predict_unit([[0, 1, 0]]), surrogate.predict_unit([[0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(surrogate.predict_unit(U[:5], reshape=True), m_unit[:5].reshape(5, 3, 4), rtol=1e-14)
    for bad in (np.nan, np.inf):
        with pytest.raises(ValueError, match=r"U must be finite"):
            surrogate.predict_unit([[0.5, bad, 0.5]])


def test_physical_box_is_exact():
    """from_unit of [0, 1] lands inside the bounds exactly (no tolerance in the box check);
    anything beyond them, by however little, is outside."""
    space = ParameterSpace((Parameter("a", 0.1, 0.7), Parameter("b", 3.0, 7.0, "log")))
    U = np.vstack([np.linspace(0, 1, 4001)] * 2).T
    X = space.from_unit(U)
    assert np.all((X >= space.lower) & (X <= space.upper))
    X = space.from_unit(sobol(32, 2, seed=0))
    sur = PODKriging(kriging=OrdinaryKriging(beta=1.8), space=space).fit(X, np.stack([X, X**2], axis=1))
    sur.predict(space.from_unit(U))  # every face point accepted
    with pytest.raises(ValueError, match="outside the trained box"):
        sur.predict([[np.nextafter(0.7, 1.0), 5.0]])


def test_one_default_exponent():
    from podkrig.cli.surrogate import surrogate_settings
    from podkrig.surrogate.settings import SurrogateSettings

    assert DEFAULT_BETA == "fit-shared" == OrdinaryKriging().beta
    assert surrogate_settings(None, None, "podkrig", None, None, None, None).templates()[1].beta == DEFAULT_BETA
    assert SurrogateSettings().beta == DEFAULT_BETA


# --- fitting on a snapshot store -----------------------------------------------------------------


@pytest.fixture(scope="module")
def store_path(tmp_path_factory, coarse_diagonal):
    """A store of 8 rows over (kN_bj, E_b): rows 0–4 done (readings and fields a smooth function of
    the parameters, no FE run), row 5 failed, rows 6 and 7 pending."""
    sc = coarse_diagonal
    space = ParameterSpace.from_scenario(sc, {"kN_bj": (10, 1000, "log"), "E_b": (5000, 20000)})
    path = tmp_path_factory.mktemp("store") / "store.h5"
    with SnapshotStore.create(path, sc, space, sobol(8, 2, seed=1), sampling="sobol", seed=1, fields=True) as s:
        X = s.parameters(only_done=False)[:6]
        shape = (s.n_loads, s.n_sensors)
        readings = np.stack([np.full(shape, 1 / k) + np.linspace(0, 1e3 / E, shape[1]) for k, E in X])
        fields = np.stack([np.full((s.n_loads, s.n_nodes, 2), 1e3 / E) for _, E in X])
        status = np.array([DONE] * 5 + [FAILED])
        s.write_results(np.arange(6), status, readings, [""] * 5 + ["SolverError: singular"],
                        np.full(6, 0.01), fields)
    return path


def test_training_data_are_the_finished_rows_of_the_store(store_path, tmp_path, coarse_diagonal):
    """Defects: failed or pending rows used, unit-cube instead of physical parameters, the readings
    given for ``output="field"``, another output kind accepted, fewer than 3 finished snapshots
    accepted (or refused without the path, the count and the remedy)."""
    with SnapshotStore.open(store_path) as s:
        done = s.status() == DONE
        X, Y = training_data(s)
        assert_array_equal(X, s.parameters(only_done=False)[done])
        assert X.shape == (5, 2) and X[:, 0].max() > 1.0  # physical kN_bj, not unit-cube coordinates
        assert_array_equal(Y, s.readings(only_done=False)[done])
        Xf, F = training_data(s, "field")
        assert_array_equal(Xf, X)
        assert F.shape == (5, s.n_loads, s.n_nodes, 2)
        assert_array_equal(F, np.broadcast_to((1e3 / X[:, 1])[:, None, None, None], F.shape))  # as written
        with pytest.raises(ValueError, match=r"output .*'readings' or 'field'; got 'fields'"):
            training_data(s, "fields")
    small = tmp_path / "small.h5"
    with SnapshotStore.open(store_path) as s, SnapshotStore.create(
            small, coarse_diagonal, s.space, s.parameters(physical=False, only_done=False)[:3], sampling="sobol",
            seed=1) as t:
        t.write_results(np.arange(3), np.array([DONE, DONE, FAILED]), s.readings(only_done=False)[:3],
                        ["", "", "SolverError"], np.full(3, 0.01))
        with pytest.raises(ValueError, match=r"has 2 finished snapshots.*at least 3") as raised:
            training_data(t)
        assert str(small) in str(raised.value) and "'podkrig snapshots run'" in str(raised.value)  # file, remedy
    three = tmp_path / "three.h5"
    with SnapshotStore.open(store_path) as s, SnapshotStore.create(
            three, coarse_diagonal, s.space, s.parameters(physical=False, only_done=False)[:3], sampling="sobol",
            seed=1) as t:
        t.write_results(np.arange(3), np.array([DONE] * 3), s.readings(only_done=False)[:3], [""] * 3,
                        np.full(3, 0.01))
        assert len(training_data(t)[0]) == 3  # the smallest design kriging accepts


def test_fit_from_store_fits_the_store_on_its_space_and_records_where_it_came_from(store_path):
    """Defects: the store's space not used for scaling, the templates not passed on, a provenance
    entry missing or wrong (store path, content hash, scenario, sensors, load levels and unit,
    reading unit, each sensor's unit, output kind, node count, training size)."""
    with SnapshotStore.open(store_path) as s:
        sur = fit_from_store(s, pod=POD(n_modes=1), kriging=OrdinaryKriging(beta=1.5))
        X, Y = training_data(s)
        direct = PODKriging(pod=POD(n_modes=1), kriging=OrdinaryKriging(beta=1.5), space=s.space).fit(X, Y)
        assert sur.space.to_dict() == s.space.to_dict() and sur.n_modes_ == 1
        assert sur.kriging_.hyperparameters_.beta == pytest.approx(1.5)
        assert_array_equal(sur.predict(X[:3]), direct.predict(X[:3]))
        prov = dict(sur.provenance_)
        assert datetime.datetime.fromisoformat(prov.pop("created")).tzinfo is not None  # ISO 8601, UTC
        assert prov.pop("package_version") == direct.provenance_["package_version"]
        assert prov == {
            "source_store": str(store_path.resolve()), "source_content_hash": s.content_hash(),
            "scenario_spec": s.spec.to_dict(), "sensor_names": list(s.sensor_names),
            "load_levels": list(s.load_levels), "load_unit": s.load_unit, "reading_unit": "mm",
            "output": "readings", "n_nodes": s.n_nodes, "n_train": 5,
            "sensor_units": ["mm"] * len(s.sensor_names),  # a linear test: every reading is a length
        }
        field = fit_from_store(s, output="field")
        assert field.provenance_["output"] == "field"
        assert field.output_shape_ == (s.n_loads, s.n_nodes, 2)  # the field was fitted, not the readings


def test_surrogate_file_describes_itself_to_a_reader_without_podkrig(tmp_path, surrogate):
    """What h5py alone shows of a surrogate file (``h5dump``, another language): when and by which
    version it was written, the backend's version, the unit of ``X``, and settings and provenance as
    JSON with sorted keys, so that two saves of one surrogate differ only in the time stamp. A
    provenance holding numpy values and other objects (a path) is written as plain JSON. Defects:
    an attribute missing or renamed, keys unsorted, numpy values or objects refused by ``json``."""
    import json

    from podkrig import __version__
    from podkrig.surrogate.backends import backend_version

    sur = copy.deepcopy(surrogate)
    sur.provenance_.update(zeta=np.float64(0.5), alpha=np.arange(3), count=np.int64(7), source=Path("a") / "b.h5")
    t0 = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    save_surrogate(sur, tmp_path / "a.h5")
    save_surrogate(sur, tmp_path / "b.h5")
    with h5py.File(tmp_path / "a.h5") as a, h5py.File(tmp_path / "b.h5") as b:
        saved = datetime.datetime.fromisoformat(a.attrs["saved"])
        assert t0 <= saved <= datetime.datetime.now(datetime.timezone.utc)
        assert a.attrs["package_version"] == __version__
        assert a.attrs["backend_version"] == backend_version(sur.kriging_) != ""
        assert a["X"].attrs["unit"] == "physical parameter units"
        for key in ("settings", "provenance"):
            text = a.attrs[key]
            assert text == json.dumps(json.loads(text), sort_keys=True) == b.attrs[key]
        prov = json.loads(a.attrs["provenance"])
        assert (prov["zeta"], prov["alpha"], prov["count"], prov["source"]) == (0.5, [0, 1, 2], 7, str(Path("a") / "b.h5"))


def test_get_params_gives_the_templates_back():
    """Defects: a template missing or swapped in ``get_params`` (scikit-learn's clone rebuilds the
    estimator from it)."""
    pod, kriging = POD(n_modes=2), OrdinaryKriging(beta=1.5)
    params = PODKriging(pod=pod, kriging=kriging, space=SPACE).get_params()
    assert params == {"pod": pod, "kriging": kriging, "space": SPACE}


def test_kriging_settings_round_trip_through_the_file(tmp_path):
    """Defects: a tuple or array setting of the kriging template (``range_bounds``, per-parameter
    ``ranges``) lost or not writable: a refit of the loaded surrogate would then use other settings."""
    X = SPACE.from_unit(sobol(16, 3, seed=0))
    kriging = OrdinaryKriging(beta=1.5, ranges=np.array([0.3, 0.5, 0.7]), range_bounds=(1e-3, 10.0))
    save_surrogate(PODKriging(kriging=kriging, space=SPACE).fit(X, snapshots(X)), tmp_path / "s.h5")
    back = load_surrogate(tmp_path / "s.h5").kriging.get_params()
    assert_array_equal(back.pop("ranges"), [0.3, 0.5, 0.7])
    assert back == {k: v for k, v in kriging.get_params().items() if k != "ranges"}


def _hdf5_with_attrs(path, **attrs):
    with h5py.File(path, "w") as f:
        f.attrs.update(attrs)
    return path


def test_every_refused_file_is_named_with_what_to_do(tmp_path, caplog):
    """load_surrogate refuses, with the file and the remedy in the whole message: a missing
    file; a file that is not HDF5 (the integrity check reads it first and names a damaged
    surrogate file); an HDF5 file of another format; a surrogate of an unknown or missing schema
    version. A file without a checksum is read with a warning naming it."""
    missing = tmp_path / "missing.h5"
    with pytest.raises(StoreError, match="no surrogate file at") as raised:
        load_surrogate(missing)
    assert str(missing) in str(raised.value) and "'podkrig surrogate build'" in str(raised.value)

    text = tmp_path / "notes.h5"
    text.write_text("not HDF5")
    with pytest.raises(StoreError, match=rf"{text} cannot be read: .*damaged"):
        load_surrogate(text)

    other = _hdf5_with_attrs(tmp_path / "other.h5", format="podkrig.snapshots")
    with caplog.at_level("WARNING", logger="podkrig.io.surrogate_file"), pytest.raises(StoreError) as raised:
        load_surrogate(other)
    assert str(raised.value).startswith(f"{other} is not a podkrig surrogate")
    assert "'podkrig.snapshots'" in str(raised.value) and "'podkrig surrogate build'" in str(raised.value)
    (record,) = caplog.records  # the file without a checksum is named, at WARNING
    assert record.levelno == logging.WARNING and str(other) in record.getMessage() and "checksum" in record.getMessage()

    for version, shown in ((99, "99"), (None, "None")):
        attrs = {"format": "podkrig.surrogate"} | ({} if version is None else {"schema_version": version})
        future = _hdf5_with_attrs(tmp_path / f"schema_{version}.h5", **attrs)
        with pytest.raises(SchemaError, match=f"schema version {shown}") as raised:
            load_surrogate(future)
        assert str(future) in str(raised.value) and "reads 1, 2, 3" in str(raised.value)

    empty = _hdf5_with_attrs(tmp_path / "empty.h5", format="podkrig.surrogate", schema_version=SCHEMA_VERSION)
    with pytest.raises(StoreError, match=rf"{empty} is a damaged .*\(KeyError: .+\).*rebuild"):
        load_surrogate(empty)


def test_another_backend_round_trips_through_the_file(tmp_path):
    """A surrogate of another backend (scikit-learn's GPR) is read back as that backend, with the
    predictions it had: the loader reads the backend the file records, not the default."""
    X = SPACE.from_unit(sobol(16, 3, seed=0))
    sur = PODKriging(pod=POD(n_modes=2), kriging=make_backend("sklearn-gpr"), space=SPACE).fit(X, snapshots(X))
    save_surrogate(sur, tmp_path / "gpr.h5")
    back = load_surrogate(tmp_path / "gpr.h5")
    assert back.backend_ == sur.backend_ == "sklearn-gpr"
    assert back.pod_.method_ == sur.pod_.method_ in ("svd", "snapshots")  # the POD method it used
    Xp = SPACE.from_unit(uniform(5, 3, seed=2))
    assert_array_equal(back.predict(Xp), sur.predict(Xp))


def test_points_are_checked_against_the_trained_box(surrogate):
    """check_box: one vector is a batch of one; a wrong width or dimension and a non-finite value
    are refused with whole messages; a point outside the trained box is refused by default and
    only warned about with extrapolate=True."""
    lo, hi = surrogate.lower_, surrogate.upper_
    centre = 0.5 * (lo + hi)
    assert_array_equal(surrogate.check_box(centre), SPACE.to_unit(centre[None, :]))
    for bad in (np.ones((2, 2)), np.ones((2, 3, 1))):
        with pytest.raises(ValueError, match=r"X must have shape \(n, 3\)") as raised:
            surrogate.check_box(bad)
        assert "['E_b', 'kN_bj', 'r_hj']" in str(raised.value) and f"got {bad.shape}" in str(raised.value)
    with pytest.raises(ValueError, match="X must be finite"):
        surrogate.check_box(np.array([centre[0], np.nan, centre[2]]))
    # two of three samples outside; the first outside entry is named, with its unit ("-": dimensionless)
    outside = np.array([[centre[0], centre[1], 1.5], centre, [0.5 * lo[0], centre[1], 1.5]])
    with pytest.raises(ValueError, match="2 of 3 samples lie outside"
) as raised:
        surrogate.check_box(outside)
    for fragment in ("sample 0: r_hj = 1.5 - not in [0.1, 1]", "extrapolate=True"):  # the first outside, the remedy
        assert fragment in str(raised.value)
    with pytest.warns(UserWarning, match=r"2 of 3 samples .*extrapolating") as caught:
        surrogate.predict(outside, extrapolate=True)
    assert [w.filename for w in caught] == [__file__]  # attributed to the caller of predict
    # without a parameter space: the box of the training data, parameters x0, x1, ..., no unit
    X = SPACE.from_unit(sobol(16, 3, seed=0))
    bare = PODKriging(pod=POD(n_modes=2), kriging=OrdinaryKriging()).fit(X, snapshots(X))
    low = np.array([[bare.lower_[0], 0.5 * bare.lower_[1], bare.lower_[2]]])
    with pytest.raises(ValueError) as raised:
        bare.check_box(low)
    assert str(raised.value).startswith(f"1 of 1 samples lie outside the trained box, e.g. sample 0: x1 = "
                                        f"{low[0, 1]:g} not in [{bare.lower_[1]:g}, {bare.upper_[1]:g}]; ")


def test_fit_keeps_its_own_copy_of_the_inputs():
    """Changing the caller's parameter array after the fit changes neither the stored training
    inputs nor the predictions."""
    X = SPACE.from_unit(sobol(16, 3, seed=0))
    sur = PODKriging(pod=POD(n_modes=2), kriging=OrdinaryKriging(), space=SPACE).fit(X, snapshots(X))
    kept, Xp = sur.X_.copy(), SPACE.from_unit(uniform(4, 3, seed=3))
    before = sur.predict(Xp)
    X[:] = X[::-1]
    assert_array_equal(sur.X_, kept)
    assert_array_equal(sur.predict(Xp), before)
    # parameters given as integers (moduli in MPa, say) are kept as floats, as the file expects
    whole = np.column_stack([np.round(kept[:, :2]), np.ones(16)]).astype(int)  # r_hj = 1: its upper bound
    assert PODKriging(pod=POD(n_modes=2), kriging=OrdinaryKriging(), space=SPACE).fit(whole, snapshots(whole)).X_.dtype == np.float64


def test_fit_refuses_bad_training_data_naming_what_is_wrong():
    """Each refusal of ``PODKriging.fit`` whole: parameters not a table, snapshots without one row per
    parameter vector (too few dimensions, or too few rows), a table narrower than the space, samples
    outside the space (the first parameter with an offending sample named, below or above, with
    its bounds and unit), and without a space a constant column. Defects: a check skipped or
    weakened (one of two conditions), a message emptied or naming the wrong parameter."""
    X = SPACE.from_unit(sobol(16, 3, seed=0))
    Y = snapshots(X)
    sur = PODKriging(pod=POD(n_modes=2), kriging=OrdinaryKriging(beta=1.5), space=SPACE)
    above, below_and_above = X.copy(), X.copy()
    above[5, 2] = 1.2
    below_and_above[5, 2], below_and_above[9, 1] = 1.2, 5.0
    constant = X.copy()
    constant[:, 1] = 50.0
    cases = [
        (sur, X[0], Y, "X must have shape (n_samples, n_params); got (3,)"),
        (sur, X, Y[:, 0, 0], "Y must have shape (16, ...) (one snapshot per row of X); got (16,)"),
        (sur, X, Y[:15], "Y must have shape (16, ...) (one snapshot per row of X); got (15, 3, 4)"),
        (sur, X[:, :2], Y, "X has 2 columns but the space has parameters ['E_b', 'kN_bj', 'r_hj']"),
        (sur, above, Y, "training samples of 'r_hj' lie outside its bounds [0.1, 1] -; widen the space"),
        (sur, below_and_above, Y, "training samples of 'kN_bj' lie outside its bounds [10, 1000] N/mm³; widen the space"),
        (PODKriging(pod=POD(n_modes=2), kriging=OrdinaryKriging(beta=1.5)), constant, Y,
         "parameter column 1 is constant (50) in the training samples; remove it or give a ParameterSpace"),
    ]
    for estimator, Xbad, Ybad, message in cases:
        with pytest.raises(ValueError) as raised:
            estimator.fit(Xbad, Ybad)
        assert str(raised.value) == message
    assert not hasattr(sur, "kriging_")  # nothing half-fitted left behind
    # accepted: samples on the space's bounds, and flat snapshots (n, n_outputs)
    X[0], X[1] = SPACE.lower, SPACE.upper
    sur.fit(X, snapshots(X).reshape(16, -1))
    assert sur.output_shape_ == (12,)
    assert_array_equal(sur.U_[:2], [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])


def test_defaults_the_log_line_and_use_before_fit(caplog):
    """Without a space the training box is mapped linearly onto the unit cube (the kriging sees
    (x - min) / (max - min)); the default POD keeps 1 - 1e-8 of the energy; the fit logs its sizes;
    a surrogate used before ``fit`` says so. Defects: another scaling, POD default or log
    argument; a bare error."""
    X = SPACE.from_unit(sobol(16, 3, seed=0))
    with caplog.at_level(logging.INFO, logger="podkrig.surrogate.podkriging"):
        bare = PODKriging(kriging=OrdinaryKriging(beta=1.5)).fit(X, snapshots(X))
    assert_array_equal(bare.U_, (X - X.min(axis=0)) / (X.max(axis=0) - X.min(axis=0)))
    assert bare.pod_.energy == 1 - 1e-8
    (record,) = [r for r in caplog.records if r.name == "podkrig.surrogate.podkriging"]
    assert record.levelno == logging.INFO and record.args == (16, 12, bare.pod_.n_modes_)  # samples, outputs, modes
    for use in (lambda s: s.predict(X), lambda s: s.n_modes_, lambda s: save_surrogate(s, "never.h5")):
        with pytest.raises(NotFittedError) as raised:
            use(PODKriging())
        assert "PODKriging instance is not fitted" in str(raised.value) and "fit(X, Y)" in str(raised.value)

