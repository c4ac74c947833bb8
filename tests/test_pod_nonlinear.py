"""POD of responses at several control levels, both ways (one POD stacked over all levels, or a
POD + kriging per level), scaling of mixed outputs (kN beside mm), and held-out errors per unit."""

from types import SimpleNamespace

import h5py
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from podkrig.io.surrogate_file import load_surrogate, save_surrogate
from podkrig.offline.sampling import sobol
from podkrig.online.findings import Finding, held_out_findings
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.surrogate.kriging import OrdinaryKriging
from podkrig.surrogate.pod import POD
from podkrig.surrogate.podkriging import PODKriging
from podkrig.surrogate.results import HeldOutResult, SurrogateFitResult
from podkrig.surrogate.settings import SurrogateSettings
from podkrig.surrogate.validation import compare_layouts, held_out_errors

SPACE = ParameterSpace((Parameter("c", 0.2, 0.5, unit="MPa"), Parameter("tanphi", 0.6, 0.9)))
LEVELS = np.array([0.05, 0.2, 0.5, 1.0, 2.0])  # control levels, mm


def curves(X, force_scale=1.0):
    """(n, 5 levels, 3 sensors): a slip and a dilatancy gauge (mm) and a softening force curve
    (kN × ``force_scale``), smooth in (c, tanφ): a stand-in for a triplet's FE runs."""
    c, t = X[:, :1], X[:, 1:]
    slip = LEVELS * (1 + 0.3 * c * t)
    dil = 0.01 * np.tanh(LEVELS / (0.2 + c)) * t
    force = force_scale * 100 * (c + 0.5 * t) * np.tanh(3 * LEVELS) * (1 - 0.1 * LEVELS * t)
    return np.stack([slip, dil, force], axis=2)


X_TRAIN = SPACE.from_unit(sobol(32, 2, seed=0))
X_HELD = SPACE.from_unit(sobol(16, 2, seed=1))
UNITS = ("mm", "mm", "kN")


def _fit(layout="stacked", scaling="none", Y=None, units=UNITS, pod=None):
    return PODKriging(pod=pod or POD(energy=1 - 1e-12), kriging=OrdinaryKriging(beta=1.8), space=SPACE,
                      layout=layout, scaling=scaling).fit(X_TRAIN, curves(X_TRAIN) if Y is None else Y, units)


def test_per_level_with_one_level_predicts_as_stacked():
    """One control level: the POD per level is the stacked POD; predictions and σ agree to rounding
    (1e-12 relative: the same arithmetic, only the code path differs)."""
    Y = curves(X_TRAIN)[:, 3:4, :]
    a, b = _fit("stacked", Y=Y), _fit("per_level", Y=Y)
    assert a.n_modes_ == b.n_modes_
    (pa, sa), (pb, sb) = a.predict(X_HELD, return_std=True), b.predict(X_HELD, return_std=True)
    assert_allclose(pb, pa, rtol=1e-12, atol=1e-12 * np.abs(pa).max())
    assert_allclose(sb, sa, rtol=1e-10, atol=1e-12 * np.abs(sa).max())


def test_per_level_is_a_separate_pod_and_kriging_at_each_level():
    """Hidden truth of the per-level layout: it predicts at each level what a surrogate fitted on
    that level's readings alone predicts (mean and σ, to rounding: the kriging of each coefficient
    is the same fit), reassembled in the (levels, sensors) layout; its modes are zero off their
    level and orthonormal."""
    Y = curves(X_TRAIN)
    sur = _fit("per_level", scaling="unit", Y=Y)
    P, S = sur.predict(X_HELD, return_std=True, reshape=True)
    assert P.shape == S.shape == (len(X_HELD), len(LEVELS), 3)
    for lvl in range(len(LEVELS)):
        alone = _fit("stacked", scaling="none", Y=Y[:, lvl, :] / sur.scale_[:3])
        p, s = alone.predict(X_HELD, return_std=True)
        assert_allclose(P[:, lvl, :], p * sur.scale_[:3], rtol=1e-8, atol=1e-10 * np.abs(P[:, lvl]).max())
        assert_allclose(S[:, lvl, :], s * sur.scale_[:3], rtol=1e-6, atol=1e-10 * np.abs(S[:, lvl]).max())
    modes = sur.pod_.modes_
    assert_allclose(modes @ modes.T, np.eye(len(modes)), atol=1e-12)
    assert sur.pod_.block_modes_.sum() == sur.n_modes_ and np.all(sur.pod_.block_modes_ <= 3)


def test_a_level_without_variance_keeps_no_mode_and_is_reproduced_by_its_mean():
    """A level where every run reads the same (e.g. before the load) keeps no mode and is predicted
    exactly, with σ 0; ``n_modes`` is clipped to each level's rank (3 sensors)."""
    Y = curves(X_TRAIN)
    Y[:, 0, :] = [0.0, 0.0, 1.5]
    sur = _fit("per_level", pod=POD(n_modes=5), Y=Y)
    assert sur.pod_.block_modes_[0] == 0 and np.all(sur.pod_.block_modes_[1:] == 3)
    P, S = sur.predict(X_HELD, return_std=True, reshape=True)
    assert_array_equal(P[:, 0, :], np.broadcast_to([0.0, 0.0, 1.5], P[:, 0, :].shape))
    assert_array_equal(S[:, 0, :], 0.0)


def test_scaling_keeps_a_sensor_in_large_numbers_from_dominating_the_pod():
    """Hidden truth: a slip gauge (mm) and the force read in N (× 1000 the kN numbers). The error
    of each sensor is measured relative to its variation over the held-out runs
    (‖ŷ − y‖ / ‖y − ȳ‖). Unscaled, the POD at 1 − 10⁻⁶ of the energy spends its modes on the force:
    the gauge is off by 10 % of its variation, the force by 0.2 %. Scaled per unit, both are
    reproduced to the same relative accuracy (below 1 %, within a factor of 3), and reading the
    force in kN changes nothing but its unit (predictions ÷ 1000 to 1e-6 relative: the scales absorb
    the factor, the rest is the same fit up to rounding)."""
    Y, truth = curves(X_TRAIN, 1000.0)[..., [0, 2]], curves(X_HELD, 1000.0)[..., [0, 2]]
    err = {}
    for scaling in ("none", "unit"):
        P = _fit(scaling=scaling, Y=Y, units=("mm", "N"), pod=POD(energy=1 - 1e-6)).predict(X_HELD, reshape=True)
        err[scaling] = [np.linalg.norm(P[..., j] - truth[..., j]) / np.linalg.norm(truth[..., j] - truth[..., j].mean(0))
                        for j in range(2)]
        if scaling == "unit":
            in_kn = _fit(scaling="unit", Y=Y * [1.0, 1e-3], units=("mm", "kN"),
                         pod=POD(energy=1 - 1e-6)).predict(X_HELD, reshape=True)
            assert_allclose(P, in_kn * [1.0, 1e3], rtol=1e-6)
    assert err["none"][0] > 0.05 and err["none"][1] < 0.005
    assert max(err["unit"]) < 0.01 and max(err["unit"]) / min(err["unit"]) < 3


def test_scales_are_the_pooled_standard_deviations_of_each_unit_or_sensor():
    """The scale of a unit is the RMS over its outputs of their standard deviations over the
    snapshots, relative to the first unit's (closed form on the training data); per sensor, each
    sensor's own relative to the first sensor's; none, or one unit only: ones (the outputs keep
    their numbers, and the fit is bitwise the unscaled one)."""
    Y = curves(X_TRAIN)
    sd = Y.std(axis=0)  # (levels, sensors)
    rms = np.sqrt(np.mean(sd**2, axis=0))
    unit = _fit(scaling="unit").scale_.reshape(len(LEVELS), 3)
    assert_allclose(unit[0], [1.0, 1.0, rms[2] / np.sqrt(np.mean(sd[:, :2] ** 2))], rtol=1e-12)
    sensor = _fit(scaling="sensor").scale_.reshape(len(LEVELS), 3)
    assert_allclose(sensor[3], rms / rms[0], rtol=1e-12)
    assert_array_equal(_fit().scale_, 1.0)
    one_unit = _fit(scaling="unit", units=("mm",) * 3)
    assert_array_equal(one_unit.scale_, 1.0)
    assert_array_equal(one_unit.predict(X_HELD), _fit(units=("mm",) * 3).predict(X_HELD))
    with pytest.raises(ValueError, match="units must name.*3 outputs"):
        _fit(units=("mm", "kN"))
    with pytest.raises(ValueError, match="layout must be one of"):
        PODKriging(layout="per-level").fit(X_TRAIN, Y)


@pytest.mark.parametrize("layout, scaling", [("stacked", "sensor"), ("per_level", "unit")])
def test_save_and_load_round_trip_of_both_layouts(tmp_path, layout, scaling):
    """A surrogate of either layout, scaled, predicts after a save and load exactly what it
    predicted before (mean and σ, bitwise in one process), with its layout, scaling, units and
    scales back (and in its fit result); the file records them."""
    sur = _fit(layout, scaling)
    save_surrogate(sur, tmp_path / "s.h5")
    back = load_surrogate(tmp_path / "s.h5")
    for a, b in zip(sur.predict(X_HELD, return_std=True), back.predict(X_HELD, return_std=True)):
        assert_array_equal(a, b)
    assert (back.layout, back.scaling, back.units_) == (layout, scaling, UNITS)
    assert_array_equal(back.scale_, sur.scale_)
    assert back.pod_.retained_energy_ == sur.pod_.retained_energy_
    fit = SurrogateFitResult.from_surrogate(back)
    assert (fit.pod, fit.scaling) == (layout, scaling) and SurrogateFitResult.from_dict(fit.to_dict()) == fit
    with h5py.File(tmp_path / "s.h5") as f:
        assert int(f.attrs["schema_version"]) == 4 and f["scale"].shape == (3 * len(LEVELS),)
        assert ("block_modes" in f["pod"]) == (layout == "per_level")


def test_surrogate_settings_choose_layout_and_scaling_with_their_defaults():
    """One definition: the defaults (stacked, scaled per unit: the better on the triplet series and
    J4D, BENCHMARKS.md) and a wrong choice refused naming the field and its options."""
    s = SurrogateSettings()
    assert (s.pod, s.scaling) == ("stacked", "unit")
    with pytest.raises(ValueError, match="pod(.|\n)*not one of the allowed"):
        SurrogateSettings(pod="levels")


def _stub(pred, units, names=("D1", "F")):
    pred = np.asarray(pred, float)
    return SimpleNamespace(
        output_shape_=(pred.shape[1] // len(units), len(units)), X_=np.zeros((5, 1)), units_=units,
        provenance_={"sensor_names": list(names), "output": "readings"},
        predict=lambda X, return_std: (pred, np.full_like(pred, 0.1)),
        project=lambda Y: np.asarray(Y, float), pod_=SimpleNamespace(n_modes_=2), kriging_=SimpleNamespace())


def test_held_out_errors_per_unit_never_add_kilonewtons_and_millimetres():
    """Hand values, one run of two levels × (gauge D1 in mm, force F in kN): D1 true (0.1, 0.2) mm
    predicted (0.1, 0.21), F true (10, 20) kN predicted (10, 21). Per unit: relative error
    0.01/‖(0.1, 0.2)‖ and 1/‖(10, 20)‖ (both 1/√500 ≈ 0.0447), error relative to the peak
    0.05 for both, peak value error 0.05; RMS and max absolute errors in each unit; the total
    relative error is the worse unit's, not ‖(0, 0.01, 0, 1)‖ / ‖(0.1, 10, 0.2, 20)‖ (which the
    force alone would set). The absolute error in mm and the noise check use only the gauges."""
    Y = np.array([[0.1, 10.0, 0.2, 20.0]])
    rep = held_out_errors(_stub([[0.1, 10.0, 0.21, 21.0]], ("mm", "kN")), np.zeros((1, 1)), Y.reshape(1, 2, 2),
                          with_loo=False)
    by = rep.summary()["by_unit"]
    rel = 0.01 / np.hypot(0.1, 0.2)  # = 1 / hypot(10, 20)
    assert_allclose([by["mm"]["rel_error"]["median"], by["kN"]["rel_error"]["median"]], [rel, rel], rtol=1e-12)
    assert_allclose([by[u][k]["max"] for u in ("mm", "kN") for k in ("peak_error", "peak_value_error")],
                    [0.05] * 4, rtol=1e-12)
    assert_allclose([by["mm"]["rms_abs_error"], by["kN"]["max_abs_error"]], [0.01 / np.sqrt(2), 1.0], rtol=1e-12)
    assert (by["mm"]["sensors"], by["kN"]["sensors"]) == (["D1"], ["F"])
    assert_allclose(rep.rel_error, [rel], rtol=1e-12)
    held = HeldOutResult.from_report(rep).to_dict()
    assert_allclose([held["rms_abs_error_mm"], held["max_abs_error_mm"]], [0.01 / np.sqrt(2), 0.01], rtol=1e-12)
    # a load cell's σ (kN) is not the gauges' σ: only D1's 0.02 mm is compared with the mm error
    assert held_out_findings({**held, "coverage_2sigma": 1.0}, noise_abs={"D1": 0.02, "F": 0.005}) == []
    (f,) = held_out_findings({**held, "coverage_2sigma": 1.0}, noise_abs={"D1": 0.005, "F": 0.5})
    assert f == Finding("surrogate-error", "held-out", {"rms_abs_error_mm": held["rms_abs_error_mm"],
                                                        "sigma_mm": 0.005})


def test_the_layout_comparison_refits_both_ways_with_the_surrogates_settings():
    """``compare_layouts`` gives each layout's per-unit held-out errors, equal to those of a
    surrogate fitted in that layout directly (same templates, scaling and units), and leaves the
    given surrogate as it was."""
    sur = _fit("stacked", "unit")
    before = sur.predict(X_HELD)
    got = compare_layouts(sur, X_TRAIN, curves(X_TRAIN), X_HELD, curves(X_HELD))
    assert set(got) == {"stacked", "per_level"}
    direct = held_out_errors(_fit("per_level", "unit"), X_HELD, curves(X_HELD), with_loo=False).by_unit()
    assert got["per_level"]["by_unit"] == direct and set(direct) == {"mm", "kN"}
    assert got["stacked"]["n_modes"] == sur.n_modes_
    assert got["stacked"]["by_unit"] == held_out_errors(sur, X_HELD, curves(X_HELD), with_loo=False).by_unit()
    assert_array_equal(sur.predict(X_HELD), before)
