"""Real laboratory logs (issue 14): units in headers, delimiters and decimal commas, extra and missing
columns, missing cells, repeats, zeroing, load ranges; the model evaluated at the measured loads;
the checks `podkrig run` makes before any FE work (and right after the training snapshots)."""

import json
from pathlib import Path

import numpy as np
import openpyxl
import pytest
from numpy.testing import assert_allclose
from typer.testing import CliRunner

from fe import FEError
from fe.scenarios import Scenario, build_scenario
from podkrig.cli import app
from podkrig.online.data_check import reading_problems
from podkrig.online.measurement import Measurement, NoiseModel, instrument_noise, level_weights
from podkrig.io.measurement_log import ImportSettings, read_measurement, split_header
from podkrig.online.problem import FEModel, InverseProblem
from podkrig.parameters import ParameterSpace
from podkrig.study import load_study, stages
from podkrig.study.pipeline import Progress
from podkrig.study.schema import StudyError
from podkrig.study.stages import probe_points
from lab_study import STUDY

SENSORS = ("D1", "D2", "U1")
LEVELS = (10.0, 20.0, 30.0, 40.0)
runner = CliRunner()
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _write(tmp_path, text, name="log.csv", encoding="utf-8"):
    p = tmp_path / name
    p.write_bytes(text.encode(encoding))
    return p


# ----------------------------------------------------------------------------------------- reading


def test_semicolon_decimal_comma_units_extra_columns_and_preamble(tmp_path):
    """The issue's semicolon file: a title line, time and channel columns, µm and mm headers, a
    decimal comma, an empty cell — read, converted and described."""
    p = _write(tmp_path, "Wall 3, 2026-11-02\ntime [s];load [kN];D1 [µm];D2 (mm);ch\n"
                         "0;10,03;-32,1;0,0151;7\n1;10,41;-33,5;;7\n2;20;-65,0;0,030;7\n")
    m = read_measurement(p, SENSORS, LEVELS, "kN", "affine")
    assert_allclose(m.load_levels, [10.03, 10.41, 20.0])
    assert_allclose(m.values, [[-0.0321, 0.0151], [-0.0335, np.nan], [-0.065, 0.030]])
    assert m.sensor_names == ("D1", "D2") and m.n_obs == 5 and m.ignored_columns == ("time [s]", "ch")
    notes = " | ".join(m.notes)
    for part in ("skipped 1 line(s) before the header", "ignored column(s) that name no sensor: time [s], ch",
                 "not in the file, not used: U1", "D1 converted from µm to mm (× 0.001)", "decimal comma"):
        assert part in notes


def test_units_are_converted_and_unknown_or_incompatible_ones_named(tmp_path):
    p = _write(tmp_path, "load [N],D1 [m],D2 [um]\n10000,-0.0001,15\n20000,-0.0002,30\n")
    m = read_measurement(p, SENSORS, LEVELS, "kN", "affine")
    assert_allclose(m.load_levels, [10.0, 20.0])
    assert_allclose(m.values, [[-0.1, 0.015], [-0.2, 0.030]])
    with pytest.raises(ValueError, match=r"row 1, column 2 \(D1 \[kN\]\): .*not a length"):
        read_measurement(_write(tmp_path, "load [kN],D1 [kN]\n10,1\n"), SENSORS, LEVELS, "kN", "affine")
    with pytest.raises(ValueError, match=r"row 1, column 1 \(load \[bananas\]\): .*'bananas'"):
        read_measurement(_write(tmp_path, "load [bananas],D1\n10,1\n"), SENSORS, LEVELS, "kN", "affine")


def test_units_row_tab_delimiter_and_windows_1252(tmp_path):
    """A units row below the header, tab-separated, saved by lab software as Windows-1252 (µ = 0xB5)."""
    p = _write(tmp_path, "load\tD1\n[kN]\t[µm]\n10\t-30\n40\t-120\n", encoding="cp1252")
    m = read_measurement(p, SENSORS, LEVELS, "kN", "affine")
    assert_allclose(m.values[:, 0], [-0.03, -0.12])
    assert any("Windows-1252" in n for n in m.notes) and any("units from row 2" in n for n in m.notes)


def test_excel_workbook(tmp_path):
    book = openpyxl.Workbook()
    ws = book.active
    ws.title = "log"
    ws.append(["time [s]", "load [kN]", "D1 [µm]", "U1 [mm]"])
    ws.append([0, 10.03, -31.5, None])
    ws.append([1, 25.5, -80.25, 0.0012])
    book.create_sheet("other")
    p = tmp_path / "log.xlsx"
    book.save(p)
    m = read_measurement(p, SENSORS, LEVELS, "kN", "affine")
    assert_allclose(m.load_levels, [10.03, 25.5])
    assert_allclose(m.values, [[-0.0315, np.nan], [-0.08025, 0.0012]])
    with pytest.raises(ValueError, match=r"'nope'.*\['log', 'other'\]"):
        read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(sheet="nope"))
    bad = tmp_path / "bad.xlsx"
    bad.write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(ValueError, match=r"bad\.xlsx: .*Excel"):
        read_measurement(bad, SENSORS, LEVELS, "kN", "affine")


def test_repeats_averaged_or_kept_and_load_range(tmp_path):
    p = _write(tmp_path, "load,D1,D2\n10.0,1,\n10.02,3,5\n20,4,6\n20.01,6,8\n35,9,9\n")
    avg = read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(load_tolerance=0.05))
    assert_allclose(avg.load_levels, [10.01, 20.005, 35.0])
    assert_allclose(avg.values, [[2.0, 5.0], [5.0, 7.0], [9.0, 9.0]])  # an empty cell does not count
    keep = read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(repeats="keep"))
    assert keep.values.shape == (5, 2) and keep.n_obs == 9
    rng = read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(load_range=(15, 30)))
    assert_allclose(rng.load_levels, [20.0, 20.01])
    with pytest.raises(ValueError, match=r"load_range \[50, 60\] kN.*\[10, 35\]"):
        read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(load_range=(50, 60)))


def test_zero_at_first_row_or_a_load(tmp_path):
    p = _write(tmp_path, "load,D1\n2,0.5\n10,1.3\n30,2.9\n")
    first = read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero="first"))
    assert first.reference_load == 2.0
    assert_allclose(first.load_levels, [10, 30])
    assert_allclose(first.values, [[0.8], [2.4]])
    at = read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero=6.0))  # between rows 2 and 3
    assert at.reference_load == 6.0
    assert_allclose(at.load_levels, [2, 10, 30])
    assert_allclose(at.values, [[-0.4], [0.4], [2.0]])
    with pytest.raises(ValueError, match=r"never reaches .*load 50 kN"):
        read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero=50.0))


PHASE_LOG = ("time [s],phase,load [kN],D1 [µm],D2 [µm]\n"
             "0,precompression,0,0,0\n1,precompression,2.5,5.5,-2\n2,Precompression,5,10.5,-4.5\n"
             "3,shear,7.5,16,-7\n4,shear,10,21,-9\n5,shear,20,42,-18.5\n6,unloading,10,22,-9.5\n")


def test_zero_at_the_end_of_a_phase_equals_zeroing_at_its_load_by_hand(tmp_path):
    """zero = "end of precompression": the last precompression row (row 4, 5 kN; the phase name's
    case does not matter) is the reference, and it and the rows before it are not used. The same
    readings as zeroing at the load of that row (the log reaches 5 kN exactly there) and dropping
    the rows up to it by hand; and as subtracting row 4 from the later rows of the file."""
    p = _write(tmp_path, PHASE_LOG)
    m = read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero="End of precompression"))
    by_load = read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero=5.0))
    assert m.reference_load == by_load.reference_load == 5.0
    assert_allclose(by_load.load_levels[:3], [0, 2.5, 5])  # the load form keeps the earlier rows
    assert_allclose(m.load_levels, by_load.load_levels[3:])
    assert_allclose(m.values, by_load.values[3:], rtol=1e-12)
    assert_allclose(m.values, 1e-3 * (np.array([[16, -7], [21, -9], [42, -18.5], [22, -9.5]]) - [10.5, -4.5]))
    notes = " | ".join(m.notes)
    assert "phase 'Precompression' (row 4, 5 kN)" in notes and "3 row(s) up to it" in notes
    assert "column 2 (phase): " in notes and "precompression, Precompression, shear, unloading" in notes
    assert "no sensor: time [s]" in notes and "phase" not in m.ignored_columns
    # load_range selects among the rows after the reference
    rng = read_measurement(p, SENSORS, LEVELS, "kN", "affine",
                           ImportSettings(zero="end of precompression", load_range=(8, 30)))
    assert_allclose(rng.load_levels, [10, 20, 10])


def test_zero_at_a_phase_is_checked_with_file_row_and_column(tmp_path):
    p = _write(tmp_path, PHASE_LOG)
    phases = "'precompression', 'Precompression', 'shear', 'unloading'"
    with pytest.raises(ValueError, match=rf"log\.csv, column 2 \(phase\): .*'pre-compression'.*{phases}") as e:
        read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero="end of pre-compression"))
    assert "typo of 'precompression'" in str(e.value)  # the hint
    with pytest.raises(ValueError, match=r"log\.csv, row 1: .*phase column 'step'.*\['time \[s\]', 'phase', .*phase_column"):
        read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero="end of shear", phase_column="step"))
    with pytest.raises(ValueError, match=r"row 1, column 4: phase_column 'd1' .*sensor"):
        read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero="end of shear", phase_column="d1"))
    with pytest.raises(ValueError, match=r"row 8, column 2 \(phase\): .*'unloading'.*last row"):
        read_measurement(p, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero="end of unloading"))
    gap = _write(tmp_path, PHASE_LOG.replace("2,Precompression,5,10.5,-4.5", "2,Precompression,5,,-4.5"))
    with pytest.raises(ValueError, match=r"row 4: .*'Precompression'.*of D1"):
        read_measurement(gap, SENSORS, LEVELS, "kN", "affine", ImportSettings(zero="end of precompression"))
    with pytest.raises(ValueError, match=r'zero must be .*"end of PHASE".*got \'end of \''):
        ImportSettings(zero="end of ")


def test_phase_column_without_zero_is_an_ignored_column(tmp_path):
    m = read_measurement(_write(tmp_path, PHASE_LOG), SENSORS, LEVELS, "kN", "affine")
    assert m.ignored_columns == ("time [s]", "phase") and m.reference_load is None
    assert any("no sensor: time [s], phase" in note for note in m.notes)
    assert_allclose(m.values[2], [0.0105, -0.0045])


def test_phase_labels_from_excel_and_the_study_file_form(tmp_path):
    """Phase numbers from an Excel sheet (2.0) match "end of 2"; the study file accepts
    zero = "end of PHASE" with phase_column and refuses other text naming the allowed forms."""
    book = openpyxl.Workbook()
    ws = book.active
    ws.append(["step", "load [kN]", "D1 [mm]"])
    for row in ([1, 0, 0.0], [2, 5, 0.01], [3, 10, 0.03], [3, 20, 0.05]):
        ws.append(row)
    book.save(tmp_path / "log.xlsx")
    m = read_measurement(tmp_path / "log.xlsx", SENSORS, LEVELS, "kN", "affine",
                         ImportSettings(zero="end of 2", phase_column="Step"))
    assert m.reference_load == 5.0
    assert_allclose(m.values[:, 0], [0.02, 0.04])
    (tmp_path / "log.csv").write_text(PHASE_LOG)
    study = STUDY.replace('instrument = "lvdt"', 'instrument = "lvdt"\nzero = "end of precompression"\n'
                                                 'phase_column = "Phase"')
    (tmp_path / "study.toml").write_text(study)
    settings = load_study(tmp_path / "study.toml").measurement.import_settings()
    assert settings.zero == "end of precompression" and settings.phase_column == "Phase"
    (tmp_path / "study.toml").write_text(study.replace('"end of precompression"', '"after precompression"'))
    with pytest.raises(StudyError, match=r'measurement\.zero: .*not a zero reference.*"end of PHASE"'):
        load_study(tmp_path / "study.toml")


def test_loads_outside_what_the_model_can_evaluate_are_refused_with_the_row(tmp_path):
    p = _write(tmp_path, "load [mm],D1\n0.5,1\n3.4,2\n")
    with pytest.raises(ValueError, match=r"row 3, column 1 \(load \[mm\]\): .*range \[0\.25, 3\] mm"):
        read_measurement(p, SENSORS, (0.25, 1.0, 3.0), "mm", "path")
    with pytest.raises(ValueError, match=r"row 2, column 1 \(load \[mm\]\): .*level 0\.5 mm"):
        read_measurement(p, SENSORS, (0.25, 1.0, 3.0), "mm", "discrete")
    with pytest.raises(ValueError, match=r"'kN' is not convertible to mm"):
        read_measurement(_write(tmp_path, "load [kN],D1\n10,1\n"), SENSORS, (0.25, 1.0), "mm", "path")


# --------------------------------------------------------------------------- evaluation at any load


@pytest.mark.parametrize("scenario", ["diagonal_compression", "shear_compression"])
def test_linear_scenarios_are_evaluated_exactly_at_any_load(scenario):
    """A linear scenario's readings at loads 3.7 … 47 kN from its four levels equal an FE run whose
    levels are those loads (the independent reference; shear compression adds a constant
    pre-compression, so the readings are affine, not proportional, in the load)."""
    spec = {"scenario": scenario, "nx": 2, "ny": 1}
    base = build_scenario(spec)
    loads = np.array([3.7, 10.03, 10.41, 25.0, 33.3, 47.0])
    ref = build_scenario({**spec, "load_levels": loads.tolist()}).run({"E_b": 9000.0}).readings
    m = Measurement(ref, base.sensor_names, loads)
    op = m.observation(base.sensor_names, base.load_levels, base.load_response)
    got = op.apply(base.run({"E_b": 9000.0}).readings.ravel()[None])[0]
    assert_allclose(got, ref.ravel(), rtol=1e-9, atol=1e-12 * np.abs(ref).max())


def test_path_interpolation_weights_and_no_extrapolation():
    index, w = level_weights([1.5, 2.0, 0.25], [0.25, 1.0, 2.0, 3.0], "path", "mm")
    assert index[0].tolist() == [1, 2]
    assert_allclose(w[0], [0.5, 0.5])
    assert index[1, 0] == 2 and w[1].tolist() == [1.0, 0.0] and index[2, 0] == 0
    with pytest.raises(ValueError, match=r"outside .*range \[0\.25, 3\] mm"):
        level_weights([3.5], [0.25, 1.0, 2.0, 3.0], "path", "mm")


# --------------------------------------------------------------------------- the inversion


def test_continuous_log_inverts_like_the_exact_load_file(tmp_path):
    """The issue's case: a continuous log (loads 10.03, 10.41 … kN, gauges in µm, a time column)
    identifies the same parameters as a file at the model's exact load levels, within the noise.

    Both are FE readings of one hidden truth with LVDT noise (σ_res = 1 µm, δ = 1 %); each is
    inverted by least squares on the FE model from the same start. The tolerance is 3 standard
    errors of the difference, from each fit's Gauss–Newton covariance (JᵀJ)⁻¹ in the unit cube."""
    spec = {"scenario": "diagonal_compression", "nx": 2, "ny": 1, "load_levels": [25.0, 50.0, 75.0, 100.0]}
    sc = build_scenario(spec)
    truth = {"E_b": 10500.0, "kN_bj": 70.0}  # kV_bj, r_hj at the scenario defaults
    rng = np.random.default_rng(14)
    noise = instrument_noise("lvdt", sc.sensor_names)

    def noisy(readings, loads):
        m = Measurement(readings, sc.sensor_names, loads)
        return readings + noise.std(m).reshape(readings.shape) * rng.standard_normal(readings.shape)

    exact = tmp_path / "exact.csv"
    d = noisy(sc.run(truth).readings, sc.load_levels)
    exact.write_text("load," + ",".join(sc.sensor_names) + "\n" + "".join(
        f"{lv:g}," + ",".join(f"{v:.8g}" for v in row) + "\n" for lv, row in zip(sc.load_levels, d)))
    loads = np.round(np.sort(np.concatenate([[10.03, 10.41], rng.uniform(11, 100, 22)])), 2)
    log_readings = noisy(build_scenario({**spec, "load_levels": loads.tolist()}).run(truth).readings, loads)
    log = tmp_path / "log.csv"
    log.write_text("time [s];load [kN];" + ";".join(f"{s} [µm]" for s in sc.sensor_names) + "\n" + "".join(
        f"{i};{str(lv).replace('.', ',')};" + ";".join(f"{1000 * v:.6g}".replace(".", ",") for v in row) + "\n"
        for i, (lv, row) in enumerate(zip(loads, log_readings))))
    space = ParameterSpace.from_scenario(sc, {"E_b": (5000.0, 20000.0), "kN_bj": (10.0, 1000.0, "log")})
    model = FEModel(sc, space)
    fits = []
    for path in (exact, log):
        data = read_measurement(path, sc.sensor_names, sc.load_levels, sc.load_unit, sc.load_response)
        problem = InverseProblem(model, data, instrument_noise("lvdt", data.sensor_names))
        x, _ = problem.polish(np.array([9000.0, 100.0]))
        u = problem.free_space.to_unit(x[None])[0]
        J = problem.jacobian_unit(u)
        fits.append((u, np.sqrt(np.diag(np.linalg.inv(J.T @ J)))))
    (u1, s1), (u2, s2) = fits
    assert np.all(np.abs(u1 - u2) <= 3 * np.hypot(s1, s2)), (u1, u2, s1, s2)
    assert np.all(np.hypot(s1, s2) < 0.05), (s1, s2)  # and the test is sharp: both well determined


def test_noise_floor_is_flagged():
    m = Measurement([[0.2, 0.0009]], ("D1", "U1"), [100.0])
    assert set(NoiseModel(delta=0.01).below_floor(m)) == {"U1"}  # σ = 9 nm
    assert NoiseModel(sigma=0.001, delta=0.01).below_floor(m) == {}
    assert_allclose(instrument_noise("lvdt", ("D1", "U1")).std(m), np.hypot(0.001, 0.01 * np.array([0.2, 0.0009])))


# --------------------------------------------------------------------------- podkrig run: checked early


def _study(tmp_path, csv_text):
    (tmp_path / "study.toml").write_text(STUDY)
    (tmp_path / "log.csv").write_text(csv_text)
    return runner.invoke(app, ["run", str(tmp_path / "study.toml"), "--out", str(tmp_path / "out")])


def test_run_refuses_dof_le_0_before_any_fe_work(tmp_path, fe_counter):
    fe = fe_counter()
    result = _study(tmp_path, "load [kN],D1 [mm]\n50,-0.16\n")
    assert result.exit_code == 2, result.output
    out = " ".join(result.output.split())
    assert "1 reading(s)" in out and "3 free parameter(s)" in out and "= -2 ≤ 0" in out
    assert fe.calls == 0 and not (tmp_path / "out" / "train.h5").exists()


def test_run_refuses_a_bad_file_before_any_fe_work(tmp_path, fe_counter):
    fe = fe_counter()
    result = _study(tmp_path, "load [kN];D1 [mm];D2 [mm]\n25;-0,08;0,04\n50;-0,16;abc\n")
    assert result.exit_code == 2, result.output
    assert "row 3, column 3 (D2 [mm])" in result.output.replace("\n", "") and "'abc'" in result.output
    assert fe.calls == 0 and not (tmp_path / "out" / "train.h5").exists()


def test_run_flags_um_read_as_mm_before_the_training_snapshots(tmp_path, fe_counter):
    """The issue's µm-as-mm file (no unit in the header): stopped by the probe — 7 FE runs (the box
    centre and each of the 3 parameters at its bounds) — before any training snapshot, naming the
    sensor and the factor; with the unit stated the study runs, reusing the cached probe."""
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    r = sc.run({"E_b": 11000.0, "kN_bj": 90.0, "kV_bj": 35.0}).readings * 1000.0  # µm, written as mm
    text = "load," + ",".join(sc.sensor_names) + "\n" + "".join(
        f"{lv:g}," + ",".join(f"{v:.6g}" for v in row) + "\n" for lv, row in zip(sc.load_levels, r))
    fe = fe_counter()
    result = _study(tmp_path, text)
    out = " ".join(result.output.split())
    assert result.exit_code == 2, result.output
    assert "7 probe FE run(s)" in out
    assert "D1 is about 1000× larger" in out and "µm read as mm?" in out
    assert fe.calls == len(probe_points(3, nonlinear=False)) == 7
    assert not (tmp_path / "out" / "train.h5").exists() and (tmp_path / "out" / "probe.npz").exists()
    # the same readings with their unit stated in the header pass both checks; the probe is not run again
    (tmp_path / "log.csv").write_text(text.replace(",".join(sc.sensor_names), ",".join(f"{s} [µm]" for s in sc.sensor_names)))
    fe = fe_counter()
    ok = runner.invoke(app, ["run", str(tmp_path / "study.toml"), "--out", str(tmp_path / "out")])
    assert ok.exit_code == 0, ok.output
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["stages"]["measurement"]["dof"] == 24 - 3
    assert summary["stages"]["probe"]["cached"] and summary["stages"]["probe"]["n_runs"] == 7
    assert fe.calls == 8 + 4 + 1  # training, held-out, the FE check of the inversion


def _demo_run(tmp_path, scale=1.0, header="", replace=None):
    """The bundled default study (4 free parameters, the default 9360-dof mesh) with its measured
    readings multiplied by ``scale`` and ``header`` ("" or e.g. " [mm]") as every gauge's unit: a
    :class:`StudyRun` whose measurement check has run (``replace``: an (old, new) edit of the study file)."""
    text = (EXAMPLES / "diagonal_compression.toml").read_text()
    if replace is not None:
        assert replace[0] in text
        text = text.replace(*replace)
    (tmp_path / "study.toml").write_text(text)
    rows = (EXAMPLES / "diagonal_compression_measured.csv").read_text().splitlines()
    names = [split_header(c)[0] for c in rows[0].split(",")]
    lines = [",".join(["load [kN]"] + [n + header for n in names[1:]])]
    lines += [",".join([r.split(",")[0]] + [f"{scale * float(v):.8g}" for v in r.split(",")[1:]]) for r in rows[1:]]
    (tmp_path / "diagonal_compression_measured.csv").write_text("\n".join(lines) + "\n")
    run = stages.StudyRun(load_study(tmp_path / "study.toml"), tmp_path / "out", Progress())
    stages.measurement_check(run, run.study.calibration_tests[0])
    return run


def test_bundled_study_with_um_as_mm_stops_before_any_snapshot(tmp_path, fe_counter):
    """The demo study with its readings in µm under 'D1 [mm]' headers: `podkrig run` stops after the
    9 probe runs (2·4 + 1), before the 256 training runs — no store is written."""
    _demo_run(tmp_path, scale=1000.0, header=" [mm]")
    fe = fe_counter()
    result = runner.invoke(app, ["run", str(tmp_path / "study.toml"), "--out", str(tmp_path / "out")])
    out = " ".join(result.output.split())
    assert result.exit_code == 2, result.output
    assert "D1 is about 1000× larger" in out and "µm read as mm?" in out
    assert "D2 is about 1000× larger" in out  # although the probe's D2 spans 100×
    assert fe.calls == len(probe_points(4, nonlinear=False)) == 9
    assert not any((tmp_path / "out" / f).exists() for f in ("train.h5", "held_out.h5", "surrogate.h5"))


def test_bundled_measurement_passes_the_probe_silently(tmp_path, fe_counter, caplog):
    """The demo's own file: the probe runs 9 times, finds nothing and warns of nothing; a second
    run reuses it (no FE)."""
    run = _demo_run(tmp_path)
    fe = fe_counter()
    with caplog.at_level("WARNING"):
        stages.probe(run, run.study.calibration_tests[0])
        stages.range_check(run, run.study.calibration_tests[0], "probe")
    assert fe.calls == 9 and not caplog.records
    assert run.manifest("probe")["result"]["n_failed"] == 0
    again = stages.StudyRun(run.study, run.out, Progress())
    stages.probe(again, again.study.calibration_tests[0])
    assert fe.calls == 9 and again.records[0].cached


def test_a_failed_probe_run_is_noted_and_left_out(tmp_path, monkeypatch):
    """An FE run of the probe that fails (here the 2nd, E_b at its lower bound) is named in the
    stage's notes and left out of the check, which still stops the µm-as-mm file on the others."""
    run = _demo_run(tmp_path, scale=1000.0, header=" [mm]")
    original, calls = Scenario.run, []

    def second_fails(scenario, params, *args, **kwargs):
        calls.append(params)
        if len(calls) == 2:
            raise FEError("singular stiffness matrix")
        return original(scenario, params, *args, **kwargs)

    monkeypatch.setattr(Scenario, "run", second_fails)
    stages.probe(run, run.study.calibration_tests[0])
    result = run.manifest("probe")["result"]
    assert result["n_runs"] == 9 and result["n_failed"] == 1 and calls[1]["E_b"] == 5000.0
    assert result["notes"][0].startswith("probe run 2 at {'E_b': 5000.0, ") and "failed (FEError: singular" in result["notes"][0]
    with pytest.raises(ValueError, match=r"8 probe FE run\(s\) .*D1 is about 1000×"):
        stages.range_check(run, run.study.calibration_tests[0], "probe")


def test_sign_flipped_file_gets_the_sign_wording(tmp_path):
    run = _demo_run(tmp_path, scale=-1.0)
    stages.probe(run, run.study.calibration_tests[0])
    with pytest.raises(ValueError, match=r"9 probe FE run\(s\) .*D1 has the opposite sign") as e:
        stages.range_check(run, run.study.calibration_tests[0], "probe")
    assert "beyond 3σ" in str(e.value) and "sign error" in str(e.value)
    assert "D2 has" not in str(e.value)  # the probe run with kN_bj at its lower bound, 10 N/mm³, reads D2 < 0


def test_range_check_false_runs_no_probe(tmp_path, fe_counter):
    """The opt-out: no probe runs (and none in the FE work asked about), no check."""
    run = _demo_run(tmp_path, scale=1000.0, header=" [mm]",
                    replace=('instrument = "lvdt"', 'instrument = "lvdt"\nrange_check = false'))
    assert stages.fe_work(run)[0].startswith("352 FE runs")  # 256 training + 32 held-out + 64 validation, no probe
    fe = fe_counter()
    stages.probe(run, run.study.calibration_tests[0])
    stages.range_check(run, run.study.calibration_tests[0], "probe")
    assert fe.calls == 0 and not (tmp_path / "out" / "probe.npz").exists()


def test_probe_points():
    """The box centre, then each parameter at its lower and upper bound (the others at the centre);
    the centre alone for a nonlinear scenario."""
    assert_allclose(probe_points(2, nonlinear=False), [[0.5, 0.5], [0, 0.5], [1, 0.5], [0.5, 0], [0.5, 1]])
    assert_allclose(probe_points(3, nonlinear=True), [[0.5, 0.5, 0.5]])


def test_range_check_names_units_and_signs_but_not_noise():
    """Unit and sign errors are named with the factor; a gauge that reads only noise is not."""
    levels, names = np.array([10.0, 20.0]), ("A", "B", "C", "N")
    per_kn = np.array([0.01, -0.002, 0.003, 1e-6])  # mm/kN; N barely moves in the model
    runs = np.array([s * np.outer(levels, per_kn) for s in (0.8, 1.0, 1.25)]).reshape(3, -1)
    d = np.outer(levels, per_kn * np.array([1000.0, 1.0, -1.0, 1.0])) + np.array([0, 0, 0, 0.0008])
    m = Measurement(d, names, levels)
    found = reading_problems(m, NoiseModel(sigma=0.001, delta=0.01), names, levels, "affine", runs)
    assert [(f.code, f.values["sensor"]) for f in found] == [("reading-scale", "A"), ("reading-sign", "C")]
    # B matches; N reads noise (0.8 µm with σ = 1 µm), not a unit error
    a = found[0].values
    assert a["direction"] == "larger" and a["unit_slip"] and a["runs"] == "training" and a["n_runs"] == 3
    # the ratio to the geometric middle of the runs' extremes (0.8 and 1.25 × the model): exactly 1000
    assert a["ratio"] == pytest.approx(1000.0, rel=1e-12)
