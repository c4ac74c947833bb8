"""The one measurement check of every door (:mod:`podkrig.online.data_check`): loads and readings
against what the model produces, as codes and values; their words at the edge
(:func:`podkrig.reports.findings.refusal`); and the doors that call it — the reader every command
uses, ``podkrig run``, ``invert``, ``rvc``, ``sensitivity`` and ``diagnose``.

The adversarial logs: loads in N under a ``kN`` header, readings in mm under ``µm`` headers,
loads of 10⁶ kN and more, negative loads, readings in µm under ``[mm]`` headers. Each is refused
with the file, the column, the likely unit and the option or study key to fix it; a clean log
passes unchanged.
"""

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose
from typer.testing import CliRunner

from fe.scenarios import build_scenario
from podkrig.cli import app
from podkrig.io.measurement_log import read_measurement
from podkrig.io.surrogate_file import load_surrogate
from podkrig.offline.store import SnapshotStore
from podkrig.online.data_check import (
    LOAD_OFFSET_SHARE,
    RANGE_FACTOR,
    MeasurementCheckError,
    check_loads,
    check_readings,
    likely_unit,
    reading_problems,
    surrogate_training_outputs,
)
from podkrig.online.calibrate import calibrate
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.problem import InverseProblem, SurrogateModel
from podkrig.online.settings import CalibrationSettings, InversionSettings, RegionSettings
from podkrig.reports.findings import refusal
from lab_study import STUDY

runner = CliRunner()
LEVELS = np.array([25.0, 50.0, 75.0, 100.0])  # kN: the diagonal compression test's levels
TRUTH = {"E_b": 11000.0, "kN_bj": 90.0, "kV_bj": 35.0, "r_hj": 0.6}
PARAMS = ["--param", "E_b=6000:18000", "--param", "kN_bj=30:300:log", "--param", "kV_bj=10:120:log",
          "--param", "r_hj=0.2:1.0"]


def _refused(call):
    with pytest.raises(MeasurementCheckError) as e:
        call()
    return e.value


# ----------------------------------------------------------------------------- loads (codes, values)


def test_loads_in_newtons_under_a_kilonewton_header():
    """1000× the top level: ``load-scale`` with the ratio, the unit the log was probably in (N),
    the column and the row of the largest load."""
    e = _refused(lambda: check_loads(LEVELS * 1000, LEVELS, "kN", source="log.csv", column="load [kN]",
                                     rows=[2, 3, 4, 5]))
    (f,) = e.findings
    assert f.code == "load-scale" and f.level == "error"
    v = f.values
    assert v["ratio"] == pytest.approx(1000.0, rel=1e-12) and v["likely_unit"] == "N"
    assert (v["source"], v["column"], v["row"], v["load_max"], v["level_max"]) == ("log.csv", "load [kN]", 5,
                                                                                 100000.0, 100.0)


def test_loads_of_a_million_kilonewtons_are_a_unit_error_without_a_guess():
    """10⁴× the top level is no neighbouring unit: refused, no unit guessed."""
    (f,) = _refused(lambda: check_loads([1e6], LEVELS, "kN")).findings
    assert f.code == "load-scale" and f.values["ratio"] == pytest.approx(1e4, rel=1e-12)
    assert f.values["likely_unit"] is None


def test_negative_loads_are_a_sign_convention_but_a_load_cell_offset_is_not():
    """Loads below −2 % of the top level where every level is positive: ``load-sign`` with their
    count and the extreme; an offset at rest within 2 % passes; a model with negative levels takes
    negative loads."""
    (f,) = _refused(lambda: check_loads(-LEVELS, LEVELS, "kN", rows=[2, 3, 4, 5])).findings
    assert f.code == "load-sign"
    assert (f.values["n_loads"], f.values["load_min"], f.values["row"]) == (4, -100.0, 5)
    offset = -0.99 * LOAD_OFFSET_SHARE * LEVELS.max()
    check_loads([offset, *LEVELS], LEVELS, "kN")
    check_loads(-LEVELS, -LEVELS, "kN")
    (f,) = _refused(lambda: check_loads([-1.01 * LOAD_OFFSET_SHARE * 100, 50.0], LEVELS, "kN")).findings
    assert f.code == "load-sign" and f.values["n_loads"] == 1


def test_loads_within_the_range_factor_and_step_numbers_pass():
    """A linear model is evaluated exactly beyond its levels: a test loaded 19× further passes, as
    do loads far below the top level; the step numbers of a stepped test are not loads."""
    check_loads([0.5, 0.99 * RANGE_FACTOR * 100], LEVELS, "kN")
    check_loads([5000.0], [1.0, 2.0, 3.0], "step")
    (f,) = _refused(lambda: check_loads([RANGE_FACTOR * 100], LEVELS, "kN")).findings
    assert f.code == "load-scale"


def test_likely_unit_names_the_neighbouring_unit_of_a_clean_power_of_ten():
    assert likely_unit("kN", 1000.0) == "N" and likely_unit("kN", 100.0) == "daN"
    assert likely_unit("mm", 1000.0) == "µm" and likely_unit("kN", 4000.0) is None
    assert likely_unit("kN", 1e4) is None and likely_unit("step", 1000.0) is None


# ----------------------------------------------------------------------------- readings (codes, values)


@pytest.fixture(scope="module")
def runs():
    """Readings of three models 0.8, 1 and 1.25 × a linear one (mm, load-major), and the model's."""
    per_kn = np.array([-0.003, 0.0015])  # mm/kN
    model = np.outer(LEVELS, per_kn)
    return np.array([s * model for s in (0.8, 1.0, 1.25)]).reshape(3, -1), model


@pytest.mark.parametrize("scale, direction", [(1000.0, "larger"), (1e-3, "smaller")])
def test_readings_a_thousand_times_off_name_the_slip(runs, scale, direction):
    """µm written under [mm] (1000× larger) and mm under [µm] (1000× smaller): ``reading-scale``
    per sensor, the ratio to the geometric middle of the runs' extremes — here exactly 1000 — and
    the µm ↔ mm slip flagged."""
    Y, model = runs
    m = Measurement(model * scale, ("D1", "D2"), LEVELS, source="log.csv")
    e = _refused(lambda: check_readings(m, NoiseModel(sigma=1e-4), ("D1", "D2"), LEVELS, "affine", Y))
    assert [(f.code, f.values["sensor"], f.values["direction"]) for f in e.findings] == [
        ("reading-scale", "D1", direction), ("reading-scale", "D2", direction)]
    for f in e.findings:
        assert f.values["ratio"] == pytest.approx(1000.0, rel=1e-9) and f.values["unit_slip"]
        assert (f.values["runs"], f.values["n_runs"]) == ("training", 3)


def test_clean_readings_pass_and_a_flipped_gauge_is_a_sign_error(runs):
    Y, model = runs
    m = Measurement(model, ("D1", "D2"), LEVELS)
    assert reading_problems(m, NoiseModel(sigma=1e-4), ("D1", "D2"), LEVELS, "affine", Y) == []
    flipped = Measurement(model * [1.0, -1.0], ("D1", "D2"), LEVELS)
    (f,) = reading_problems(flipped, NoiseModel(sigma=1e-4), ("D1", "D2"), LEVELS, "affine", Y, runs="probe")
    assert (f.code, f.values["sensor"], f.values["runs"]) == ("reading-sign", "D2", "probe")


def test_the_surrogates_training_outputs_are_its_training_runs(lab):
    """The comparison runs of a surrogate: its predictions at its training points, which the
    interpolating kriging reproduces — the store's FE readings, to the POD truncation (1 − 10⁻⁸ of
    the energy) and the solver's rounding: 1e-6 of the largest reading."""
    d, _ = lab
    sur = load_surrogate(d / "sur.h5")
    with SnapshotStore.open(d / "s.h5") as store:
        Y_fe = store.readings(only_done=True).reshape(len(sur.X_), -1)
    Y = surrogate_training_outputs(sur)
    assert Y.shape == Y_fe.shape
    assert_allclose(Y, Y_fe, rtol=0, atol=1e-6 * np.abs(Y_fe).max())


# ----------------------------------------------------------------------------- the reader and the words


def _write(path, loads, readings, names, load_header="load [kN]", unit=" [mm]"):
    lines = [",".join([load_header] + [n + unit for n in names])]
    lines += [",".join([f"{p:.10g}"] + [f"{v:.10g}" for v in row]) for p, row in zip(loads, readings)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_the_reader_every_door_uses_refuses_wrong_loads_with_file_row_and_column(tmp_path):
    """:func:`read_measurement` (``run``, ``invert``, ``rvc``, ``sensitivity``, ``diagnose``) runs
    the load check: the refusal names the file, the row of the largest load and the column; its
    words give the remedy of each door — an option, or a study-file key."""
    path = _write(tmp_path / "log.csv", LEVELS * 1000, np.ones((4, 1)) * 0.1, ["D1"])
    e = _refused(lambda: read_measurement(path, ("D1", "D2"), LEVELS, "kN", "affine"))
    assert e.findings[0].values["row"] == 5 and e.findings[0].values["column"] == "load [kN]"
    cli, study = refusal(e, "cli"), refusal(e, "study")
    for text in (cli, study):
        assert "log.csv, row 5, column 'load [kN]'" in text and "1000×" in text and "N under a kN header" in text
        assert "'load [N]'" in text
    assert "--load-column" in cli and "[measurement] load_column" in study
    path = _write(tmp_path / "neg.csv", -LEVELS, np.ones((4, 1)) * 0.1, ["D1"])
    e = _refused(lambda: read_measurement(path, ("D1",), LEVELS, "kN", "affine"))
    assert "4 load(s) are negative" in refusal(e) and "--load-range" in refusal(e)
    assert "[measurement] load_range" in refusal(e, "study")


def test_readings_refused_together_in_one_sentence(runs):
    Y, model = runs
    m = Measurement(model * 1000, ("D1", "D2"), LEVELS, source="log.csv")
    e = _refused(lambda: check_readings(m, NoiseModel(sigma=1e-4), ("D1", "D2"), LEVELS, "affine", Y, runs="surrogate"))
    text = refusal(e, "cli")
    assert text.startswith("log.csv: the readings do not look like any of the surrogate's 3 training FE runs")
    assert "D1 is about 1000× larger than every FE run: µm read as mm?; D2 is about 1000× larger" in text
    assert "'D1 [µm]'" in text and "--no-range-check" in text
    assert "[measurement] range_check = false" in refusal(e, "study")


# ----------------------------------------------------------------------------- the doors


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """A coarse diagonal compression surrogate (64 FE runs), its scenario's readings at TRUTH (mm)
    and the adversarial logs."""
    d = tmp_path_factory.mktemp("check_doors")
    spec = d / "spec.toml"
    spec.write_text('scenario = "diagonal_compression"\nnx = 2\nny = 1\n')
    for args in (["snapshots", "run", "--spec", spec, *PARAMS, "--n", 64, "--seed", 0, "--store", d / "s.h5",
                  "--workers", 1], ["surrogate", "build", d / "s.h5", "--out", d / "sur.h5"]):
        result = runner.invoke(app, [str(a) for a in args])
        assert result.exit_code == 0, result.output
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    r = sc.run(TRUTH).readings * (1 + 0.01 * np.random.default_rng(0).standard_normal((4, 6)))
    names, L = sc.sensor_names, sc.load_levels
    logs = {
        "clean": _write(d / "clean.csv", L, r, names),
        "N_as_kN": _write(d / "N_as_kN.csv", L * 1000, r, names),
        "mm_as_um": _write(d / "mm_as_um.csv", L, r, names, unit=" [µm]"),
        "million_kN": _write(d / "million_kN.csv", L * 1e4, r, names),
        "negative": _write(d / "negative.csv", -L, r, names),
        "um_as_mm": _write(d / "um_as_mm.csv", L, r * 1000, names),
    }
    return d, logs


#: each adversarial log: the fragments its refusal gives (what, where, the likely unit, the fix)
REFUSED = {
    "N_as_kN": ["N_as_kN.csv, row 5, column 'load [kN]'", "1000×", "N under a kN header", "'load [N]'",
                "--load-column"],
    "mm_as_um": ["mm_as_um.csv", "D1 is about 1000× smaller", "mm read as µm", "'D1 [µm]'", "--no-range-check"],
    "million_kN": ["million_kN.csv, row 5, column 'load [kN]'", "1e+06 kN", "10000×", "a unit error?",
                   "--load-column"],
    "negative": ["negative.csv, row 5, column 'load [kN]'", "4 load(s) are negative", "--load-range"],
    "um_as_mm": ["um_as_mm.csv", "surrogate's 64 training FE runs", "D1 is about 1000× larger", "µm read as mm?",
                 "--no-range-check"],
}


def _out(result):
    return " ".join(result.output.split())


def test_calibrate_runs_the_check_itself_for_any_front_end(lab):
    """The library's calibration (what ``podkrig invert`` and ``rvc`` call, and any other front
    end) compares the readings with the surrogate's training runs before the inversion; the
    caller that compared them already opts out."""
    d, logs = lab
    model = SurrogateModel(load_surrogate(d / "sur.h5"))
    data = read_measurement(logs["um_as_mm"], model.sensor_names, model.load_levels, model.load_unit,
                            model.load_response)
    problem = InverseProblem(model, data, NoiseModel(sigma=0.001, delta=0.01))
    e = _refused(lambda: calibrate(problem))
    assert {f.values["sensor"] for f in e.findings} >= {"D1", "D2"}
    assert all(f.code == "reading-scale" and f.values["runs"] == "surrogate" for f in e.findings)
    settings = CalibrationSettings(inversion=InversionSettings(population_size=8, generations=2, n_starts=1),
                                   region=RegionSettings(samples=1024), fe_check=False)
    assert calibrate(problem, settings, range_check=False, calibration_rvc=False).inversion.chi2_dof > 1e3


@pytest.mark.parametrize("log", list(REFUSED))
def test_invert_refuses_each_adversarial_log_before_the_inversion(lab, log):
    d, logs = lab
    result = runner.invoke(app, ["invert", str(d / "sur.h5"), "--data", str(logs[log]), "--instrument", "lvdt"])
    assert result.exit_code == 2, result.output
    out = _out(result)
    for fragment in REFUSED[log]:
        assert fragment in out, (fragment, out)
    assert "Traceback" not in out and "χ²/dof" not in out


def test_a_clean_log_inverts_unchanged_by_the_check(lab):
    """The check refuses nothing and changes nothing: the inversion with it and with
    --no-range-check gives the same numbers (same process, same seed)."""
    d, logs = lab
    args = ["invert", str(d / "sur.h5"), "--data", str(logs["clean"]), "--instrument", "lvdt", "--format", "json",
            "--region-samples", "4096", "--generations", "10", "--population-size", "16", "--no-fe-check"]
    outs = []
    for extra in ([], ["--no-range-check"]):
        result = runner.invoke(app, args + extra)
        assert result.exit_code == 0, result.output
        outs.append(json.loads(result.stdout)["inversion"])
    a, b = outs
    assert a["parameters"].keys() == b["parameters"].keys()
    # the same computation in one process: equal to rounding (no BLAS path differs)
    assert_allclose([a["parameters"][k] for k in a["parameters"]], [b["parameters"][k] for k in a["parameters"]],
                    rtol=1e-12, atol=0)
    assert a["chi2_dof"] == pytest.approx(b["chi2_dof"], rel=1e-12)


def test_no_range_check_lets_the_readings_through_but_never_the_loads(lab):
    """The opt-out is of the readings' comparison (the study's range_check = false); wrong loads
    are refused whatever it says."""
    d, logs = lab
    base = ["invert", str(d / "sur.h5"), "--instrument", "lvdt", "--no-range-check", "--region-samples", "4096",
            "--generations", "3", "--population-size", "8", "--no-fe-check", "--format", "json"]
    assert runner.invoke(app, base + ["--data", str(logs["um_as_mm"])]).exit_code == 0
    result = runner.invoke(app, base + ["--data", str(logs["N_as_kN"])])
    assert result.exit_code == 2 and "N under a kN header" in _out(result)


@pytest.mark.parametrize("command", ["rvc", "sensitivity", "overparam"])
def test_rvc_sensitivity_and_overparam_refuse_the_same_logs(lab, command):
    d, logs = lab
    extra = ["--noise-rel", "0.01"] + {"sensitivity": ["--n", "256", "--out", str(d / "sens")],
                                       "overparam": ["--set", "kN_bj,kV_bj", "--set", "kN_bj"]}.get(command, [])
    for log in ("um_as_mm", "N_as_kN"):
        result = runner.invoke(app, [command, str(d / "sur.h5"), "--data", str(logs[log]), *extra])
        assert result.exit_code == 2, result.output
        assert all(fragment in _out(result) for fragment in REFUSED[log][:3]), _out(result)


def test_diagnose_refuses_wrong_loads_before_any_fe_run(lab, fe_counter):
    d, logs = lab
    fe = fe_counter()
    result = runner.invoke(app, ["diagnose", "--scenario", "diagonal_compression", "--spec", str(d / "spec.toml"),
                                 "--data", str(logs["N_as_kN"]), *PARAMS[:4], "--noise-rel", "0.01"])
    assert result.exit_code == 2, result.output
    assert all(fragment in _out(result) for fragment in REFUSED["N_as_kN"]), _out(result)
    assert fe.calls == 0


def test_diagnose_refuses_readings_unlike_its_base_surrogates_training_runs(lab, fe_counter):
    """µm under [mm] headers: refused after the base surrogate's 16 FE runs, before any
    calibration or candidate cause; --no-range-check is the opt-out it names."""
    d, logs = lab
    fe = fe_counter()
    result = runner.invoke(app, ["diagnose", "--scenario", "diagonal_compression", "--spec", str(d / "spec.toml"),
                                 "--data", str(logs["um_as_mm"]), *PARAMS[:4], "--noise-rel", "0.01",
                                 "--n-train", "16"])
    assert result.exit_code == 2, result.output
    out = _out(result)
    for fragment in ("surrogate's 16 training FE runs", "D1 is about 1000× larger", "µm read as mm?",
                     "--no-range-check"):
        assert fragment in out, (fragment, out)
    assert fe.calls == 16


# ----------------------------------------------------------------------------- podkrig run


def _run(tmp_path, log, replace=None):
    text = STUDY if replace is None else STUDY.replace(*replace)
    (tmp_path / "study.toml").write_text(text)
    (tmp_path / "log.csv").write_bytes(log.read_bytes())
    return runner.invoke(app, ["run", str(tmp_path / "study.toml"), "--out", str(tmp_path / "out")])


@pytest.mark.parametrize("log, fragments", [
    ("N_as_kN", ["log.csv, row 5, column 'load [kN]'", "N under a kN header", "[measurement] load_column"]),
    ("million_kN", ["log.csv, row 5, column 'load [kN]'", "10000×", "a unit error?", "[measurement] load_column"]),
    ("negative", ["log.csv, row 5, column 'load [kN]'", "4 load(s) are negative", "[measurement] load_range"]),
])
def test_run_refuses_wrong_loads_before_any_fe_work(lab, tmp_path, fe_counter, log, fragments):
    fe = fe_counter()
    result = _run(tmp_path, lab[1][log])
    assert result.exit_code == 2, result.output
    assert all(fragment in _out(result) for fragment in fragments), _out(result)
    assert fe.calls == 0 and not (tmp_path / "out" / "train.h5").exists()


def test_run_refuses_mm_under_micrometre_headers_after_the_probe(lab, tmp_path, fe_counter):
    """The readings 1000× smaller than every probe run: stopped by the probe (7 linear runs), before
    any training snapshot; the remedy names the study-file key."""
    fe = fe_counter()
    result = _run(tmp_path, lab[1]["mm_as_um"])
    assert result.exit_code == 2, result.output
    out = _out(result)
    for fragment in ("7 probe FE run(s)", "D1 is about 1000× smaller", "mm read as µm",
                     "[measurement] range_check = false"):
        assert fragment in out, (fragment, out)
    assert fe.calls == 7 and not (tmp_path / "out" / "train.h5").exists()


# ----------------------------------------------------------------------------- noise: the same ranges everywhere


@pytest.mark.parametrize("where", ["study", "cli"])
def test_absurd_noise_is_refused_at_every_door_naming_the_range(lab, tmp_path, where):
    """σ = 10⁻³⁰⁰ mm (its square underflowed: "inf× the noise", exit 0) is below the 10⁻⁷ mm floor
    (0.1 nm): refused naming the key or option, the value and the allowed range."""
    d, logs = lab
    if where == "study":
        result = _run(tmp_path, logs["clean"], replace=('instrument = "lvdt"', "noise_abs = 1e-300"))
        fragments = ["study.toml, line 18", "measurement.noise_abs", "1e-300", "[1e-07, 1e+06] mm"]
    else:
        result = runner.invoke(app, ["invert", str(d / "sur.h5"), "--data", str(logs["clean"]), "--noise-abs",
                                     "1e-300"])
        fragments = ["--noise-abs 1e-300", "out of range", "[1e-07, 1e+06] mm"]
    assert result.exit_code == 2, result.output
    assert all(fragment in _out(result) for fragment in fragments), _out(result)


@pytest.mark.parametrize("where", ["study", "cli"])
def test_a_noise_table_naming_an_unknown_sensor_names_file_key_sensor_and_the_known_ones(lab, tmp_path, where):
    d, logs = lab
    table = "{ D1 = 0.001, D2 = 0.001, U1 = 0.001, BJ_V = 0.001, BJ_D = 0.001, HJ_H = 0.001, D9 = 0.001 }"
    if where == "study":
        result = _run(tmp_path, logs["clean"], replace=('instrument = "lvdt"', f"noise_abs = {table}"))
        fragments = ["study.toml", "[measurement] noise_abs", "'D9'", "diagonal_compression"]
    else:
        result = runner.invoke(app, ["invert", str(d / "sur.h5"), "--data", str(logs["clean"]),
                                     "--noise-abs", "D1=0.001", "--noise-abs", "D9=0.001"])
        fragments = ["--noise-abs: 'D9'", "is not a sensor of the model"]
    assert result.exit_code == 2, result.output
    out = _out(result)
    assert all(fragment in out for fragment in fragments), out
    assert "D1, D2, U1, BJ_V, BJ_D, HJ_H" in out  # the sensors to choose from
