"""Measurement CSV reading/validation and noise models."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.measurement_csv import read_measurement_csv, write_measurement_csv

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
        ("force,D1\n25,1\n", r"row 1: no load column 'load' in the header \['force', 'D1'\]"),
        ("load,D9\n25,1\n", r"row 1: no column names a sensor of the model"),
        ("load,D1,D1\n25,1,2\n", r"row 1, column 3: sensor 'D1' appears more than once"),
        ("load,D1,D2\n25,1,abc\n", r"row 2, column 3 \(D2\): 'abc' is not a number"),
        ("load,D1,D2\n25,1,2\n50,inf,2\n", r"row 3, column 2 \(D1\): 'inf' is not a finite number"),
        ("load,D1\n30,1\n", r"row 2, column 1 \(load\): unknown load level 30 kN"),
        ("load,D1\n25,1,3\n", r"row 2: 3 cells, expected 2"),
        ("load,D1\n", "no data rows"),
        ("load [kN],D1 [furlongs/fortnight]\n25,1\n", r"row 1, column 2 \(D1 \[furlongs/fortnight\]\): unit "
                                                        r"'furlongs/fortnight' is not a length"),
        ("load [kN],D1 [parsecs2]\n25,1\n", r"row 1, column 2 \(D1 \[parsecs2\]\): unknown unit 'parsecs2'"),
        ("load [MPa],D1\n25,1\n", r"row 1, column 1 \(load \[MPa\]\): unit 'MPa' is not convertible to kN"),
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
    with pytest.raises(ValueError, match="^give either a covariance or an absolute sigma"):
        NoiseModel(sigma=0.1, covariance=C)
    with pytest.raises(ValueError, match="^give a noise model"):
        NoiseModel()
    with pytest.raises(ValueError, match="sigma must be > 0 mm"):
        NoiseModel(sigma=0.0)
    with pytest.raises(ValueError, match=r"no noise sigma given for sensor\(s\) \['D2'\]"):
        NoiseModel(sigma={"D1": 0.001}).std(m)
    with pytest.raises(ValueError, match=r"must be \(4, 4\)"):
        NoiseModel(covariance=np.eye(3)).covariance_matrix(m)


def test_output_indices_match_levels_to_1e_9_and_name_what_is_unknown():
    """Levels match to a relative 1e-9 (two model levels 5e-6 apart stay distinct), and an unknown
    sensor or level is named with the source and what the model has."""
    m = Measurement(np.array([[1.0, 2.0]]), ("D2", "D1"), np.array([100.0005]), source="site.csv")
    # load-major: level index 1 of 2, 3 sensors per level → 3 + sensor position
    assert m.output_indices(["D1", "D2", "U1"], [100.0, 100.0005]).tolist() == [3 + 1, 3 + 0]
    with pytest.raises(ValueError, match=r"site\.csv: unknown sensor 'D2'; the model has \['D1', 'U1'\]"):
        m.output_indices(["D1", "U1"], [100.0005])
    with pytest.raises(ValueError, match=r"site\.csv: unknown load level 100\.001; the model has \[100\.0, 99\.0\]"):
        m.output_indices(["D1", "D2"], [100.0, 99.0])


def test_measurement_converts_its_inputs_and_names_bad_values():
    m = Measurement([[1, 2]], ["a", "b"], [50], source="site.csv")
    assert m.values.dtype == float and m.load_levels.dtype == float and m.sensor_names == ("a", "b")
    assert m.data.tolist() == [1.0, 2.0] and m.n_obs == 2
    with pytest.raises(ValueError, match=r"^site\.csv: values must have shape \(1, 2\) \(n_loads, n_sensors\); got \(2,\)"):
        Measurement([1.0, 2.0], ["a", "b"], [50], source="site.csv")
    with pytest.raises(ValueError, match=r"^site\.csv: measured values must be finite numbers"):
        Measurement([[1.0, np.inf]], ["a", "b"], [50], source="site.csv")
    # NaN is a missing reading (issue 14): left out of the data, the rest kept in load-major order
    gap = Measurement([[1.0, np.nan], [3.0, 4.0]], ["a", "b"], [50, 60], source="site.csv")
    assert gap.data.tolist() == [1.0, 3.0, 4.0] and gap.n_obs == 3 and not gap.complete
    with pytest.raises(ValueError, match=r"^site\.csv: no readings"):
        Measurement([[np.nan, np.nan]], ["a", "b"], [50], source="site.csv")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"sigma": {"D1": 0.001, "D2": 0.0}}, r"^absolute noise sigma must be > 0 mm; got \{'D2': 0\.0\}"),
        ({"delta": 0.0}, r"^relative noise delta must be in \(0, 1\); got 0\.0"),
        ({"delta": 1.0}, r"^relative noise delta must be in \(0, 1\)"),
        ({"delta": 1.5}, r"^relative noise delta must be in \(0, 1\)"),
    ],
)
def test_noise_model_bounds(kwargs, match):
    with pytest.raises(ValueError, match=match):
        NoiseModel(**kwargs)


def test_singular_noise_covariance_is_refused():
    m = Measurement(np.zeros((2, 2)), ("D1", "D2"), np.array([50.0, 100.0]))
    with pytest.raises(ValueError, match="^noise covariance must be symmetric positive definite"):
        NoiseModel(covariance=np.diag([1.0, 0.0, 1.0, 1.0])).covariance_matrix(m)
    with pytest.raises(ValueError, match="^noise covariance must be symmetric positive definite"):
        NoiseModel(covariance=np.eye(4) + np.triu(np.ones((4, 4)), 1) * 0.1).covariance_matrix(m)
