"""Measurement CSV reading/validation and noise models."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig.online.measurement import (
    SIGMA_FLOOR_MM,
    Measurement,
    NoiseModel,
    ObservationOperator,
    instrument_noise,
    level_weights,
)
from podkrig.io.measurement_log import read_measurement_csv, write_measurement_csv

SENSORS = ("D1", "D2", "U1")
LEVELS = (25.0, 50.0, 75.0, 100.0)


def _write(tmp_path, text):
    p = tmp_path / "data.csv"
    p.write_text(text)
    return p


def test_round_trip_and_subset(tmp_path):
    m = Measurement(np.array([[-0.06, 0.027], [-0.24, 0.11]]), ("D1", "D2"), np.array([25.0, 100.0]), source="x")
    p = tmp_path / "m.csv"
    write_measurement_csv(p, m)
    back = read_measurement_csv(p, SENSORS, LEVELS)
    assert back.sensor_names == ("D1", "D2")
    assert_allclose(back.values, m.values, rtol=1e-12)
    # flattened positions in a (4 loads × 3 sensors) output, load-major
    assert back.output_indices(SENSORS, LEVELS).tolist() == [0, 1, 9, 10]


@pytest.mark.parametrize(
    "text, match",
    [
        ("force,D1\n25,1\n", r"row 1: .*'load'.*\['force', 'D1'\]"),
        ("load,D9\n25,1\n", r"row 1: .*sensor of the model"),
        ("load,D1,D1\n25,1,2\n", r"row 1, column 3: .*'D1' .*more than once"),
        ("load,D1,D2\n25,1,abc\n", r"row 2, column 3 \(D2\): 'abc'"),
        ("load,D1,D2\n25,1,2\n50,inf,2\n", r"row 3, column 2 \(D1\): 'inf'"),
        ("load,D1\n30,1\n", r"row 2, column 1 \(load\): .*30 kN"),
        ("load,D1\n25,1,3\n", r"row 2: 3 cells, expected 2"),
        ("load,D1\n", "no data rows"),
        ("load [kN],D1 [furlongs/fortnight]\n25,1\n", r"row 1, column 2 \(D1 \[furlongs/fortnight\]\): .*not a length"),
        ("load [kN],D1 [parsecs2]\n25,1\n", r"row 1, column 2 \(D1 \[parsecs2\]\): .*'parsecs2'"),
        ("load [MPa],D1\n25,1\n", r"row 1, column 1 \(load \[MPa\]\): .*'MPa'.*kN"),
    ],
)
def test_bad_files_name_file_row_and_column(tmp_path, text, match):
    p = _write(tmp_path, text)
    with pytest.raises(ValueError, match=match) as info:
        read_measurement_csv(p, SENSORS, LEVELS)
    assert str(p) in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(ValueError, match="cannot read measurement file"):
        read_measurement_csv(tmp_path / "nope.csv", SENSORS, LEVELS)


def test_noise_models():
    m = Measurement(np.array([[-0.2, 0.1], [-0.4, 0.0]]), ("D1", "D2"), np.array([50.0, 100.0]))
    assert_allclose(NoiseModel(sigma=0.002).std(m), 0.002)
    assert_allclose(NoiseModel(sigma={"D1": 0.001, "D2": 0.003}).std(m), [0.001, 0.003, 0.001, 0.003])
    assert_allclose(NoiseModel(delta=0.01, floor=1e-4).std(m), [0.002, 0.001, 0.004, 1e-4])
    C = np.diag([1.0, 2.0, 3.0, 4.0]) * 1e-6
    assert_allclose(NoiseModel(covariance=C).std(m), np.sqrt(np.diag(C)))
    # the instrument model: σ_i² = σ_res² + (δ d_i)², by hand for d = (-0.2, 0.1, -0.4, 0.0) mm
    assert_allclose(NoiseModel(sigma=0.001, delta=0.01).std(m),
                    np.sqrt(0.001**2 + (0.01 * np.array([0.2, 0.1, 0.4, 0.0])) ** 2))
    with pytest.raises(ValueError, match="either a covariance or .*sigma"):
        NoiseModel(sigma=0.1, covariance=C)
    with pytest.raises(ValueError, match="give a noise model"):
        NoiseModel()
    with pytest.raises(ValueError, match=r"sigma must be in \[1e-07, 1e\+06\] mm; got 0\.0"):
        NoiseModel(sigma=0.0)
    with pytest.raises(ValueError, match=r"no noise sigma .*\['D2'\]"):
        NoiseModel(sigma={"D1": 0.001}).std(m)
    with pytest.raises(ValueError, match=r"must be \(4, 4\)"):
        NoiseModel(covariance=np.eye(3)).covariance_matrix(m)


def test_output_indices_match_levels_to_1e_9_and_name_what_is_unknown():
    """Levels match to a relative 1e-9 (two model levels 5e-6 apart stay distinct), and an unknown
    sensor or level is named with the source and what the model has."""
    m = Measurement(np.array([[1.0, 2.0]]), ("D2", "D1"), np.array([100.0005]), source="site.csv")
    # load-major: level index 1 of 2, 3 sensors per level → 3 + sensor position
    assert m.output_indices(["D1", "D2", "U1"], [100.0, 100.0005]).tolist() == [3 + 1, 3 + 0]
    with pytest.raises(ValueError, match=r"site\.csv: .*'D2'.*\['D1', 'U1'\]"):
        m.output_indices(["D1", "U1"], [100.0005])
    with pytest.raises(ValueError, match=r"site\.csv: .*level 100\.001.*\[100\.0, 99\.0\]"):
        m.output_indices(["D1", "D2"], [100.0, 99.0])


def test_measurement_converts_its_inputs_and_names_bad_values():
    m = Measurement([[1, 2]], ["a", "b"], [50], source="site.csv")
    assert m.values.dtype == float and m.load_levels.dtype == float and m.sensor_names == ("a", "b")
    assert m.data.tolist() == [1.0, 2.0] and m.n_obs == 2
    with pytest.raises(ValueError, match=r"site\.csv: values .*\(1, 2\).*got \(2,\)"):
        Measurement([1.0, 2.0], ["a", "b"], [50], source="site.csv")
    with pytest.raises(ValueError, match=r"site\.csv: .*finite"):
        Measurement([[1.0, np.inf]], ["a", "b"], [50], source="site.csv")
    # NaN is a missing reading (issue 14): left out of the data, the rest kept in load-major order
    gap = Measurement([[1.0, np.nan], [3.0, 4.0]], ["a", "b"], [50, 60], source="site.csv")
    assert gap.data.tolist() == [1.0, 3.0, 4.0] and gap.n_obs == 3 and not gap.complete
    with pytest.raises(ValueError, match=r"site\.csv: no readings"):
        Measurement([[np.nan, np.nan]], ["a", "b"], [50], source="site.csv")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"sigma": {"D1": 0.001, "D2": 0.0}}, r"sigma .*\[1e-07, 1e\+06\] mm; got \{'D2': 0\.0\}"),
        ({"delta": 0.0}, r"delta .*\[1e-06, 1\); got 0\.0"),
        ({"delta": 1.0}, r"delta .*\[1e-06, 1\); got 1\.0"),
        ({"delta": 1.5}, r"delta .*\[1e-06, 1\); got 1\.5"),
        # absurd: σ below the size of an atom (σ² underflowed: "inf× the noise"), δ below 1 ppm
        ({"sigma": 1e-300}, r"sigma .*\[1e-07, 1e\+06\] mm; got 1e-300"),
        ({"sigma": {"D1": 0.001, "D2": 1e-9}}, r"sigma .*\[1e-07, 1e\+06\] mm; got \{'D2': 1e-09\}"),
        ({"delta": 1e-300}, r"delta .*\[1e-06, 1\); got 1e-300"),
    ],
)
def test_noise_model_bounds(kwargs, match):
    with pytest.raises(ValueError, match=match):
        NoiseModel(**kwargs)


def test_singular_noise_covariance_is_refused():
    m = Measurement(np.zeros((2, 2)), ("D1", "D2"), np.array([50.0, 100.0]))
    with pytest.raises(ValueError, match="covariance .*positive definite"):
        NoiseModel(covariance=np.diag([1.0, 0.0, 1.0, 1.0])).covariance_matrix(m)
    with pytest.raises(ValueError, match="covariance .*symmetric"):
        NoiseModel(covariance=np.eye(4) + np.triu(np.ones((4, 4)), 1) * 0.1).covariance_matrix(m)


def test_observation_operator_sums_weighted_columns_and_bounds_the_std():
    """Entry i = Σ_k w_ik Y[:, c_ik] (hand-computed for two rows); the std bound Σ_k |w_ik| s_ik uses
    |w| (a zeroed gauge has weight −1); columns of zero weight everywhere are dropped, so an operator
    whose only nonzero weights are 1 in its first column is exact; mismatched shapes are named."""
    op = ObservationOperator([[0, 1], [2, 2], [1, 0]], [[0.25, 0.75], [1.0, -1.0], [2.0, -0.5]])
    Y = np.array([[1.0, 2.0, 3.0], [10.0, 20.0, 40.0]])
    expected = np.array([[0.25 * 1 + 0.75 * 2, 3.0 - 3.0, 2 * 2.0 - 0.5 * 1.0],
                         [0.25 * 10 + 0.75 * 20, 40.0 - 40.0, 2 * 20.0 - 0.5 * 10.0]])
    assert_allclose(op.apply(Y), expected, rtol=1e-15)
    assert_allclose(op.apply(Y[0]), expected[:1], rtol=1e-15)  # one row: (n_outputs,) → (1, n_obs)
    S = np.array([[0.1, 0.2, 0.4]])
    assert_allclose(op.apply_std(S), [[0.25 * 0.1 + 0.75 * 0.2, 0.4 + 0.4, 2 * 0.2 + 0.5 * 0.1]], rtol=1e-15)
    assert op.n_obs == 3 and not op.exact
    with pytest.raises(ValueError, match=r"not at the model's load levels.*interpolated"):
        op.indices
    single = ObservationOperator([[2, 0], [0, 1]], [[1.0, 0.0], [1.0, 0.0]])  # column 2 never weighs
    assert single.columns.shape == (2, 1) and single.exact and single.indices.tolist() == [2, 0]
    assert_allclose(single.apply(Y), Y[:, [2, 0]], rtol=0)
    assert_allclose(single.apply_std(S[0]), S[:, [2, 0]], rtol=0)
    # every weight 0: the first column is still kept (the entries are 0, not an empty sum)
    zero = ObservationOperator([[1, 2]], [[0.0, 0.0]])
    assert zero.columns.tolist() == [[1]] and zero.apply(Y).tolist() == [[0.0], [0.0]]
    assert ObservationOperator.from_indices([2, 0]).weights.tolist() == [[1.0], [1.0]]
    with pytest.raises(ValueError, match=r"columns \(1, 2\) .*weights \(1, 3\).*same shape"):
        ObservationOperator([[0, 1]], [[1.0, 0.0, 0.0]])


def test_affine_levels_reproduce_a_linear_response_at_any_load_and_name_the_units():
    """A linear scenario's readings r(P) = 2 + 3 P are reproduced exactly between, below and above
    its (unsorted) levels 20, 10 and 40 kN; at a level the weight is 1 on that level alone (hand values:
    15 kN = ½ (10 + 20), 5 kN = 1.5·r(10) − 0.5·r(20), 60 kN = −r(20) + 2 r(40))."""
    levels = [20.0, 10.0, 40.0]
    loads = [15.0, 5.0, 60.0, 10.0, 40.0]
    index, w = level_weights(loads, levels, "affine", "kN")
    r = 2.0 + 3.0 * np.asarray(levels)
    assert_allclose(np.sum(r[index] * w, axis=1), 2.0 + 3.0 * np.asarray(loads), rtol=1e-14)
    assert index[:3].tolist() == [[1, 0], [1, 0], [0, 2]]
    assert_allclose(w[:3], [[0.5, 0.5], [1.5, -0.5], [-1.0, 2.0]], rtol=1e-14)
    assert index[3:, 0].tolist() == [1, 2] and w[3:].tolist() == [[1.0, 0.0], [1.0, 0.0]]
    # integer inputs are loads like any other (no integer division of t)
    index_i, w_i = level_weights([15], [10, 20], "affine")
    assert index_i.tolist() == [[0, 1]] and w_i.tolist() == [[0.5, 0.5]]
    with pytest.raises(ValueError, match=r"site\.csv: load 15 kN .*only level 10 kN.*at least two"):
        level_weights([10.0, 15.0], [10.0], "affine", "kN", "site.csv")
    with pytest.raises(ValueError, match=r"measurement: load 15 .*level 10;"):
        level_weights([15.0], [10.0], "path")
    with pytest.raises(ValueError, match=r"load_response .*\('affine', 'path', 'discrete'\).*got 'linear'"):
        level_weights([10.0], [10.0], "linear")


def test_levels_match_within_a_relative_1e_9_or_1e_12_absolute_at_zero():
    """A reading at 0 kN matches a level 1e-13 off zero (absolute tolerance 1e-12) but not one 1e-11
    off; a load a little above or below a level (within a relative 1e-9) takes that level, not its
    neighbour 1e-6 away; the default is a discrete (stepped) model that refuses anything off its levels,
    naming the first such load and the levels (as floats, also when given as integers)."""
    assert level_weights([0.0], [1e-13, 5.0])[0].tolist() == [[0, 0]]
    with pytest.raises(ValueError, match=r"measurement: .*level 0;.*\[1e-11, 5\.0\].*steps"):
        level_weights([0.0], [1e-11, 5.0])
    index, w = level_weights([0.0, 5.000000001, 100.00000005, 100.0001, 99.99999996], [100.0001, 0.0, 5.0, 100.0])
    assert index[:, 0].tolist() == [1, 2, 3, 0, 3] and w.tolist() == [[1.0, 0.0]] * 5
    with pytest.raises(ValueError, match=r"lab: .*level 7\.5 kN.*\[5\.0, 10\.0\]"):
        level_weights([5.0, 7.5, 8.0], [5, 10], load_unit="kN", source="lab")
    with pytest.raises(ValueError, match=r"site\.csv: .*level 12 kN.*\[10\.0, 20\.0\]"):
        Measurement([[1.0]], ("a",), [12.0], source="site.csv").observation(("a",), [10.0, 20.0], load_unit="kN")


def test_path_scenarios_interpolate_inside_and_name_every_load_outside():
    """A nonlinear scenario is interpolated linearly between its levels (load 1.5 mm between 1 and 2:
    weights ½, ½) and never extrapolated: the message counts the loads outside, names the modelled
    range with its unit, the first such load and the extremes, and says what to change."""
    index, w = level_weights([1.5, 0.25, 3.0, 0.5, 2.5], [0.25, 1.0, 2.0, 3.0], "path", "mm")
    assert index.tolist() == [[1, 2], [0, 0], [3, 0], [0, 1], [2, 3]]
    assert_allclose(w, [[0.5, 0.5], [1.0, 0.0], [1.0, 0.0], [2 / 3, 1 / 3], [0.5, 0.5]], rtol=1e-14)
    with pytest.raises(ValueError, match=r"log\.csv: 3 measured control value\(s\).*\[0\.25, 3\] mm.*3\.5 mm.*0\.1 and 4 mm.*load_range.*load_levels"):
        level_weights([1.5, 3.5, 0.1, 4.0], [0.25, 1.0, 2.0, 3.0], "path", "mm", "log.csv")
    with pytest.raises(ValueError, match=r"measurement: 1 measured control value\(s\).*\[0\.25, 3\] of"):
        level_weights([0.2], [0.25, 1.0, 2.0, 3.0], "path")


def test_gauges_zeroed_at_a_reference_load_read_the_change_since_then():
    """Readings zeroed at P_ref are compared with g(P) − g(P_ref), per sensor, by hand on a
    flattened output (3 levels × 2 sensors, load-major); a missing reading is left out; such
    readings are not single outputs. The reference load is checked like a reading (named as such)."""
    y = np.array([[1.0, 10.0], [2.0, 20.0], [4.0, 40.0]])  # levels 10, 20, 30 kN; sensors a, b
    m = Measurement([[5.0, np.nan], [7.0, 8.0]], ("b", "a"), [20.0, 25.0], source="zeroed.csv", reference_load=15.0)
    op = m.observation(("a", "b"), [10.0, 20.0, 30.0], "affine", "kN")
    g15 = 0.5 * (y[0] + y[1])
    expected = [y[1, 1] - g15[1], 0.5 * (y[1, 1] + y[2, 1]) - g15[1], 0.5 * (y[1, 0] + y[2, 0]) - g15[0]]
    assert_allclose(op.apply(y.ravel()), [expected], rtol=1e-14)
    with pytest.raises(ValueError, match=r"zeroed\.csv: .*not single model outputs"):
        Measurement([[5.0]], ("b",), [20.0], source="zeroed.csv", reference_load=10.0).output_indices(
            ("a", "b"), [10.0, 20.0])
    with pytest.raises(ValueError, match=r"zeroed\.csv \(reference load.*level 15 kN"):
        m.observation(("a", "b"), [10.0, 20.0, 25.0], "discrete", "kN")
    with pytest.raises(ValueError, match=r"zeroed\.csv: .*\['c', 'd'\].*\['a', 'b'\]"):
        Measurement([[1.0, 2.0]], ("c", "d"), [10.0], source="zeroed.csv").observation(("a", "b"), [10.0])
    with pytest.raises(ValueError, match=r"zeroed\.csv: .*reference load.*finite"):
        Measurement([[1.0]], ("a",), [10.0], source="zeroed.csv", reference_load=float("nan"))
    with pytest.raises(ValueError, match=r"zeroed\.csv: loads must be finite numbers"):
        Measurement([[1.0]], ("a",), [np.inf], source="zeroed.csv")


def test_missing_readings_round_trip_through_the_grid_and_the_summary_lists_what_matters():
    """``grid`` puts observed entries back on the (load, sensor) grid with NaN at a missing reading;
    ``with_data`` keeps everything but the data; the check summary gives counts, the load range,
    the sensors of the model not used, ignored columns, notes and the σ below the floor."""
    m = Measurement([[1.0, np.nan], [3.0, 4.0]], ("a", "b"), [50, 10], source="site.csv", reference_load=5.0,
                    notes=["µm converted"], ignored_columns=("time",))
    assert_allclose(m.grid([7.0, 8.0, 9.0]), [[7.0, np.nan], [8.0, 9.0]], rtol=0)
    new = m.with_data(np.array([-1.0, -3.0, -4.0]))
    assert_allclose(new.values, [[-1.0, np.nan], [-3.0, -4.0]], rtol=0)
    assert (new.source, new.sensor_names, new.reference_load, new.notes, new.ignored_columns) == (
        "site.csv", ("a", "b"), 5.0, ("µm converted",), ("time",))
    assert new.load_levels.tolist() == [50.0, 10.0] and m.with_data(m.data, "copy").source == "copy"
    noise = NoiseModel(sigma={"a": 0.0001, "b": 0.002})
    assert m.check_summary(("c", "a", "b", "d"), noise) == {
        "file": "site.csv", "n_obs": 3, "n_loads": 2, "sensors": ["a", "b"], "load_min": 10.0, "load_max": 50.0,
        "reference_load": 5.0, "not_used": ["c", "d"], "ignored": ["time"], "notes": ["µm converted"],
        "sigma_below_floor": {"a": 0.0001}, "sigma_floor_mm": SIGMA_FLOOR_MM}
    assert m.check_summary(("a", "b"), noise, floor=0.003)["sigma_below_floor"] == {"a": 0.0001, "b": 0.002}


def test_below_floor_names_each_sensor_with_its_smallest_sigma():
    """A relative model gives σ = δ |d| per reading: a sensor is named once, with its smallest σ over
    the loads, when any of its readings is below the floor (strictly); the default floor is 0.5 µm."""
    m = Measurement([[0.02, 0.2, 1.0], [0.04, 0.3, 2.0]], ("U1", "D1", "D2"), [10.0, 20.0])
    rel = NoiseModel(delta=0.01)  # σ: U1 0.2, 0.4 µm; D1 2, 3 µm; D2 10, 20 µm
    assert rel.below_floor(m) == pytest.approx({"U1": 0.0002}, rel=1e-12)
    low = rel.below_floor(m, floor=0.0025)
    assert list(low) == ["U1", "D1"] and low == pytest.approx({"U1": 0.0002, "D1": 0.002}, rel=1e-12)
    assert rel.below_floor(m, floor=0.0002) == {}  # σ equal to the floor is not below it


@pytest.mark.parametrize(
    "kwargs, text",
    [
        ({"sigma": 0.002}, ("absolute", "σ_res = 0.002 mm")),
        ({"delta": 0.015}, ("relative", "δ = 1.5 %")),
        ({"sigma": 0.001, "delta": 0.01}, ("σ_res = 0.001 mm", "δ = 1 %")),
        ({"sigma": {"D1": 0.001, "U1": 0.0025}, "delta": {"D1": 0.01, "U1": 0.0}},
         ("D1 0.001 mm", "U1 0.0025 mm", "D1 1 %", "U1 0 %")),
        ({"covariance": np.eye(2)}, ("covariance",)),
    ],
)
def test_noise_model_describes_itself_with_units(kwargs, text):
    """The description names the model and every level with its unit (mm, %)."""
    described = NoiseModel(**kwargs).describe()
    assert all(fragment in described for fragment in text), described


def test_instrument_noise_takes_each_sensors_instrument():
    """σ_res and δ per sensor from the instrument table (LVDT 1 µm and 1 %, DIC 2.5 µm and 0);
    an unknown instrument or a sensor without one is named with what is known."""
    noise = instrument_noise({"D1": "lvdt", "U1": "dic"}, ("D1", "U1"))
    assert noise.sigma == {"D1": 0.001, "U1": 0.0025} and noise.delta == {"D1": 0.01, "U1": 0.0}
    m = Measurement([[0.2, 0.2]], ("D1", "U1"), [10.0])
    assert_allclose(noise.std(m), [np.hypot(0.001, 0.002), 0.0025], rtol=1e-12)
    assert instrument_noise("dial_gauge", ["a", "b"]).sigma == {"a": 0.001, "b": 0.001}
    with pytest.raises(ValueError, match=r"\{'U1': 'laser'\}.*\['dial_gauge', 'dic', 'load_cell', 'lvdt'\]"):
        instrument_noise({"D1": "lvdt", "U1": "laser"}, ("D1", "U1"))
    with pytest.raises(ValueError, match=r"no instrument given for sensor\(s\) \['U1'\]"):
        instrument_noise({"D1": "lvdt"}, ("D1", "U1"))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"sigma": float("inf")}, r"sigma \(mm\) .*finite.*got inf"),
        ({"sigma": {"D1": 0.001, "U1": float("nan")}},
         r"sigma of sensor 'U1' .*finite.*got nan"),
        ({"sigma": 2e6}, r"sigma .*\[1e-07, 1e\+06\] mm; got 2000000\.0"),
        ({"delta": float("nan")}, r"delta .*finite.*got nan"),
        ({"sigma": 0.001, "delta": {"U1": float("inf")}},
         r"delta of sensor 'U1' .*finite.*got inf"),
        ({"covariance": np.array([[1.0, np.nan], [np.nan, 1.0]])},
         r"covariance .*finite.*NaN"),
        ({"delta": {"D1": 0.01, "U1": 1.0}}, r"delta .*0 or in \[1e-06, 1\).*got \{'U1': 1\.0\}"),
        ({"delta": {"D1": 0.01, "U1": -0.01}}, r"delta .*0 or in \[1e-06, 1\).*got \{'U1': -0\.01\}"),
        ({"delta": {"D1": 0.01, "U1": 0.0}}, r"delta of 0 needs .*sigma"),
        ({"sigma": -0.001}, r"sigma .*\[1e-07, 1e\+06\] mm; got -0\.001"),
        ({"delta": 0.01, "covariance": np.eye(2)}, r"either a covariance or .*sigma"),
    ],
)
def test_noise_levels_must_be_finite_and_in_range(kwargs, match):
    """NaN or infinite σ/δ/covariance (σ = inf made every reading weightless: χ² = 0) and values out
    of range are refused, naming the sensor of a per-sensor value."""
    with pytest.raises(ValueError, match=match):
        NoiseModel(**kwargs)


def test_per_sensor_noise_follows_missing_readings_and_a_zero_delta_with_sigma():
    """Per-sensor σ and δ are laid out load-major over the readings that exist (NaN left out); a
    relative-only model floors σ at ``floor``; δ = 0 for one sensor is allowed with a σ."""
    m = Measurement([[0.1, np.nan], [-0.2, 0.4]], ("a", "b"), [10.0, 20.0])
    noise = NoiseModel(sigma={"a": 0.001, "b": 0.002}, delta={"a": 0.0, "b": 0.01})
    assert_allclose(noise.std(m), [0.001, 0.001, np.hypot(0.002, 0.004)], rtol=1e-12)
    assert_allclose(NoiseModel(delta={"a": 0.01, "b": 0.02}).std(m), [0.001, 0.002, 0.008], rtol=1e-12)
    assert_allclose(NoiseModel(delta=0.01, floor=0.0015).std(m), [0.0015, 0.002, 0.004], rtol=1e-12)
    assert_allclose(NoiseModel(delta=0.01).std(Measurement([[0.0]], ("a",), [1.0])), [1e-6], rtol=1e-12)
    for noise in (NoiseModel(delta={"a": 0.01}), NoiseModel(sigma=0.001, delta={"a": 0.01})):
        with pytest.raises(ValueError, match=r"no noise delta .*\['b'\]"):
            noise.std(m)
    C = NoiseModel(sigma=0.001, delta=0.01).covariance_matrix(m)
    assert_allclose(C, np.diag(np.hypot(0.001, 0.01 * np.array([0.1, 0.2, 0.4])) ** 2), rtol=1e-12)
    assert NoiseModel(sigma=0.001).is_diagonal and not NoiseModel(covariance=np.eye(3)).is_diagonal


def test_a_level_repeated_by_a_load_cycle_is_read_at_its_first_occurrence():
    """A stepped loading–unloading cycle 0.5 → 5 → 0.5 MPa (19 levels, each but the peak twice): a
    reading at 1, 3 or 4.5 MPa is matched to the loading branch (the level's first occurrence:
    indices 1, 5, 8), not to the unloading one, however many levels the cycle has."""
    up = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0]
    index, w = level_weights([1.0, 3.0, 4.5], up + up[-2::-1], "discrete", "MPa")
    assert index[:, 0].tolist() == [1, 5, 8] and w.tolist() == [[1.0, 0.0]] * 3
