"""The triplet-series example (EN 1052-3, three pre-compressions as one joint calibration): the
study file loads, its three curves are read as the model's, the make script reproduces them, and
(slow) ``podkrig run`` finds the hidden truth inside the 95 % region and proposes to fix the
tensile strength no shear test informs."""

import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from conftest import load_file
from fe.scenarios import build_scenario
from podkrig.study.schema import load_study
from podkrig.study.stages import read_study_measurement

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
STUDY = EXAMPLES / "triplet_series.toml"


def _make_script():
    return load_file(EXAMPLES / "make_triplet_series.py")


def test_the_study_loads_and_each_curve_is_read_for_its_triplet():
    """Three tests at 0.2, 0.6 and 1.0 MPa sharing c_bj, tanphi_bj, GfII_bj (and ft_bj, free for the
    sensitivity to reject); each log read at the scenario's 14 control levels with F in kN and the
    stated noise (1 % + 0.05 kN on F, 1 % + 2 µm on the gauges)."""
    make = _make_script()
    study = load_study(STUDY)
    tests = study.calibration_tests
    assert [t.spec.options["precompression"] for t in tests] == list(make.PRECOMPRESSIONS)
    assert [p.name for p in study.free_parameters] == ["c_bj", "tanphi_bj", "GfII_bj", "ft_bj"]
    assert study.sensitivity.enabled
    for t, p in zip(tests, make.PRECOMPRESSIONS):
        assert t.measurement.file == make.data_file(p).resolve()
        sc = build_scenario(t.spec)
        data, noise = read_study_measurement(t, sc.sensor_names, sc.load_levels, sc.load_unit, sc.load_response,
                                             sc.sensor_units)
        assert data.sensor_names == ("middle_ux", "V_top", "F") and data.sensor_units == ("mm", "mm", "kN")
        assert_allclose(data.load_levels, make.LEVELS, rtol=1e-12)
        sigma_abs = np.array([make.NOISE_ABS[n] for n in data.sensor_names])
        expected = np.hypot(sigma_abs, make.NOISE_REL * np.abs(data.values)).ravel()
        assert_allclose(noise.std(data), expected, rtol=1e-12)  # the make script's σ, reading by reading
        F = data.values[:, 2]
        assert 0 < np.argmax(F) < len(F) - 1  # a peak and a softening branch


def test_the_make_script_reproduces_the_shipped_curves(tmp_path):
    """Same truth, seeds and solver: the shipped files to the 8 digits written (rtol 1e-6 leaves room
    for solver round-off across machines; the noise is ≥ 1 % of every reading)."""
    make = _make_script()
    for made, p in zip(make.make(tmp_path), make.PRECOMPRESSIONS):
        a, b = (np.loadtxt(f, delimiter=",", skiprows=1) for f in (made, make.data_file(p)))
        assert made.read_text().splitlines()[0] == make.data_file(p).read_text().splitlines()[0]
        assert_allclose(a, b, rtol=1e-6, atol=1e-9, err_msg=str(p))


@pytest.mark.slow
def test_the_series_finds_the_hidden_truth_and_proposes_to_fix_the_tensile_strength(triplet_series_run):
    """``podkrig run examples/triplet_series.toml`` (518 FE runs, ~32 s CPU): the truth of the make
    script lies in the 95 % region of c_bj, tanphi_bj and GfII_bj, each identified within a tenth of
    its range (measured: [0.294, 0.313] MPa, [0.825, 0.865], [0.096, 0.104] N/mm); ft_bj is not
    identified, and the sensitivity proposes to fix it, naming a tension test.

    The capacity of the validation triplet at 1.4 MPa: the 5–95 % band of its peak load and of the
    slip there contains the FE peak of a run at the hidden truth (measured: F_peak 61.9 kN in
    [61.1, 62.3] kN, d_peak 0.118 mm in [0.116, 0.119] mm), the peak load is Coulomb's 2 A (c + σ
    tanφ) = 62.6 kN within 3 %, none of its 16 FE runs at region members failed and each lies within
    1 % of the surrogate, and the one snapshot over the box without a load maximum (tanφ < tanφ_r:
    friction hardens) is left out of its surrogate; the report shows its distribution figure."""
    truth = _make_script().TRUTH
    folder, exit_code, output = triplet_series_run  # one fresh run per session (conftest.py)
    assert exit_code == 0, output[-3000:]
    out = folder / "out" / "triplet_series"
    summary = json.loads((out / "summary.json").read_text())
    capacity = summary["stages"]["calibration"]["rvc"]["p1_4MPa"]
    (model,) = load_study(STUDY).validation
    fe = build_scenario(model.spec).run({**truth, **model.spec.parameters})
    for k, (name, unit, at_truth) in enumerate((("F_peak", "kN", fe.peak_load), ("d_peak", "mm", fe.peak_displacement))):
        assert capacity["outputs"][k] == name and capacity["units"][k] == unit
        lo, hi = capacity["quantiles"][0][k], capacity["quantiles"][-1][k]
        assert lo <= at_truth <= hi, (name, lo, at_truth, hi)
    coulomb = 2 * 210 * 100 * (truth["c_bj"] + 1.4 * truth["tanphi_bj"]) / 1000  # kN
    assert capacity["mean"][0] == pytest.approx(coulomb, rel=0.03)
    runs = capacity["runs"]
    assert runs["n_runs"] == 16 and capacity["failed_share"] == 0.0
    assert_allclose(runs["fe"], runs["surrogate"], rtol=0.01)  # the surrogate at region members
    fit = summary["stages"]["validation_model.p1_4MPa"]["surrogate"]
    assert len(fit["excluded_rows"]) == 1 and fit["n_train"] == 63
    assert (out / "report" / "rvc_p1_4MPa.png").is_file()
    assert "rvc_p1_4MPa.png" in (out / "report" / "index.html").read_text()
    region = summary["stages"]["calibration"]["region"]
    bounds = {p.name: (p.lower, p.upper) for p in load_study(STUDY).free_parameters}
    for name in ("c_bj", "tanphi_bj", "GfII_bj"):
        lo, hi = region["intervals"][name]
        assert lo <= truth[name] <= hi, (name, lo, hi)
        assert hi - lo < 0.1 * (bounds[name][1] - bounds[name][0]), name
    assert not region["identifiability"]["ft_bj"]["identifiable"]
    assert summary["stages"]["sensitivity"]["propose_fixing"] == ["ft_bj"]
    assert "couplet_tension" in output
