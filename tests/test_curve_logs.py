"""Force–displacement curves as data: the load reading ``F`` of a displacement-controlled scenario,
``podkrig simulate --format csv`` read back unchanged, lab curve logs (uneven control steps, a
post-peak branch, N under a header) evaluated at the measured control values, and the noise of a
load cell."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from typer.testing import CliRunner

from fe.exceptions import SpecError
from fe.scenarios import build_scenario
from podkrig.cli import app
from podkrig.diagnosis.engine import build_base_surrogate
from podkrig.io.measurement_log import ImportSettings, read_measurement
from podkrig.io.surrogate_file import save_surrogate
from podkrig.offline.runner import run_snapshots
from podkrig.offline.store import SnapshotStore
from podkrig.online.calibrate import calibrate
from podkrig.online.data_check import MeasurementCheckError, check_loads, check_readings
from podkrig.online.measurement import Measurement, instrument_noise
from podkrig.online.problem import InverseProblem, SurrogateModel
from podkrig.online.settings import CalibrationSettings, InversionSettings, RegionSettings
from podkrig.parameters import ParameterSpace
from podkrig.reports.findings import refusal
from podkrig.surrogate.podkriging import fit_from_store

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()
#: a coarse wall whose run takes well under a second: the file format is under test, not the wall
WALL_OPTIONS = {"nx": 2, "ny": 1, "load_levels": [0.1, 0.3, 0.6], "top": "constant_force"}


@pytest.fixture(scope="module")
def triplet():
    sc = build_scenario({"scenario": "triplet_shear"})
    return sc, sc.run()


def test_the_load_is_a_reading_in_kN_after_the_gauges(triplet):
    """``F`` is the last sensor, in kN, equal to the response's load at every level: positive
    (the push), rising to the peak and falling after it."""
    sc, r = triplet
    assert sc.sensor_names[-1] == "F" and sc.sensor_units["F"] == "kN"
    assert all(sc.sensor_units[n] == "mm" for n in sc.sensor_names[:-1])
    assert sc.sensor_definitions()["F"]["kind"] == "force"
    assert_allclose(r.reading("F"), r.loads, rtol=0, atol=0)  # the same numbers, not a recomputation
    F = r.reading("F")
    k = int(np.argmax(F))
    assert np.all(F > 0) and 0 < k < len(F) - 1 and F[-1] < 0.5 * F[k]
    assert F[k] <= r.peak_load * (1 + 1e-9)  # the levels sample the curve; the refined peak lies above


def test_a_gauge_named_like_the_load_reading_is_refused():
    with pytest.raises(SpecError, match=r"'F'.*load reading"):
        build_scenario({"scenario": "triplet_shear",
                        "sensors": {"F": {"kind": "gauge", "p1": [105.0, 102.0], "p2": [105.0, 146.0]}}})


@pytest.mark.parametrize("scenario, options", [("triplet_shear", {}), ("shear_compression_nl", WALL_OPTIONS)])
def test_simulate_csv_reads_back_unchanged(tmp_path, scenario, options):
    """``simulate --format csv`` → ``read_measurement`` → the response's readings to the printed
    precision (8 significant digits: rtol 1e-7) at exactly the control levels, units from the header."""
    args = ["simulate", scenario, "--format", "csv"]
    for k, v in options.items():
        args += ["--option", f"{k}={v}"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    header = result.stdout.splitlines()[0]
    assert header.startswith("load [mm],") and header.endswith(",F [kN]")
    path = tmp_path / "curve.csv"
    path.write_text(result.stdout)
    sc = build_scenario({"scenario": scenario, **options})
    data = read_measurement(path, sc.sensor_names, sc.load_levels, sc.load_unit, sc.load_response,
                            sensor_units=sc.sensor_units)
    assert data.sensor_names == sc.sensor_names and data.sensor_units[-1] == "kN"
    assert_allclose(data.load_levels, sc.load_levels, rtol=1e-6, atol=0)  # levels to 6 digits (%g)
    assert_allclose(data.values, sc.run().readings, rtol=1e-7, atol=0)
    op = data.observation(sc.sensor_names, sc.load_levels, sc.load_response)
    assert op.exact  # at the model's own levels: its own outputs, no interpolation


def test_the_model_curve_at_its_own_levels_is_exact_and_between_them_linear_in_the_control():
    """A model curve given at control levels ``L``: evaluated at ``L`` it is itself (weights 1), and at
    uneven control values between them it is ``np.interp`` along the control, sensor by sensor
    (rtol 1e-12: two floating-point weights)."""
    levels = np.array([0.01, 0.02, 0.05, 0.1, 0.2, 0.5])
    curve = np.column_stack([levels * 0.9, np.array([6.5, 13.0, 20.3, 18.3, 15.3, 10.1])])  # (slip, F) per level
    Y = curve.reshape(1, -1)
    names = ("middle_ux", "F")
    at_levels = Measurement(curve, names, levels, sensor_units=("mm", "kN"))
    op = at_levels.observation(names, levels, "path", "mm")
    assert op.exact
    assert_allclose(op.apply(Y).ravel(), curve.ravel(), rtol=0, atol=0)  # the outputs themselves
    control = np.array([0.013, 0.0371, 0.05, 0.0712, 0.33, 0.49])
    measured = Measurement(np.zeros((len(control), 2)), names, control, sensor_units=("mm", "kN"))
    got = measured.observation(names, levels, "path", "mm").apply(Y).reshape(len(control), 2)
    for j in range(2):
        assert_allclose(got[:, j], np.interp(control, levels, curve[:, j]), rtol=1e-12, atol=0)


def _lab_log(path, sc, response, control, title=True):
    """A lab curve log made from ``response``: the control at the uneven values ``control`` (mm), the
    force in N, V_top in µm (both linear in the control between levels), decimal commas, a title."""
    levels = sc.load_levels
    F = np.interp(control, levels, response.reading("F")) * 1000.0  # N
    V = np.interp(control, levels, response.reading("V_top")) * 1000.0  # µm
    lines = (["Triplet T2, 0.2 MPa, 12 Nov 2026"] if title else []) + ["time [s];slip [mm];F [N];V_top [µm]"]
    for i, (c, f, v) in enumerate(zip(control, F, V)):
        lines.append(f"{0.5 * i:g};{c:.9g};{f:.9g};{v:.9g}".replace(".", ","))
    path.write_text("\n".join(lines) + "\n")


def test_an_uneven_post_peak_lab_log_in_newtons_is_read_and_the_model_evaluated_there(tmp_path, triplet):
    """Uneven control steps, a force that rises then falls (the post-peak branch), N and µm under
    their headers: read without refusal, converted (N → kN, µm → mm), and the model's curve at the
    measured control values reproduces the log (which was made by linear interpolation of the same
    curve: exact to the 9 digits written)."""
    sc, r = triplet
    control = np.array([0.0, 0.004, 0.012, 0.019, 0.033, 0.047, 0.061, 0.09, 0.15, 0.31, 0.52, 0.97, 1.43, 1.99])
    path = tmp_path / "triplet_T2.csv"
    _lab_log(path, sc, r, control)
    with pytest.raises(ValueError, match=r"row 3, column 2 \(slip \[mm\]\).*control value.*0\.01, 2\] mm.*load_range"):
        read_measurement(path, sc.sensor_names, sc.load_levels, sc.load_unit, sc.load_response,
                         ImportSettings(load_column="slip"), sc.sensor_units)  # below the first level: not modelled
    data = read_measurement(path, sc.sensor_names, sc.load_levels, sc.load_unit, sc.load_response,
                            ImportSettings(load_column="slip", load_range=(0.01, 2.0)), sc.sensor_units)
    notes = " | ".join(data.notes)
    assert "2 row(s) outside load_range" in notes
    assert "F converted from N to kN" in notes and "V_top converted from µm to mm" in notes
    assert "middle_ux" in notes  # a sensor of the model the log has no column of: named
    assert data.sensor_names == ("F", "V_top") and data.sensor_units == ("kN", "mm")
    F = data.values[:, 0]
    assert np.argmax(F) not in (0, len(F) - 1)  # a post-peak branch, read as it is
    assert_allclose(data.load_levels, control[2:], rtol=1e-12, atol=0)
    op = data.observation(sc.sensor_names, sc.load_levels, sc.load_response)
    model = op.apply(r.readings.reshape(1, -1)).ravel()
    assert_allclose(model, data.data, rtol=1e-8, atol=1e-12)  # 9 digits written


def test_control_values_beyond_the_modelled_range_are_refused_naming_row_and_options(tmp_path, triplet):
    """The model is never extrapolated past its last control level: the first row beyond it is named
    with the two remedies (``load_range`` and the scenario's ``load_levels``); load_range lets the
    rest through."""
    sc, r = triplet
    control = np.array([0.01, 0.05, 0.4, 1.5, 2.6, 3.1])
    path = tmp_path / "long.csv"
    _lab_log(path, sc, r, np.minimum(control, 2.0))
    text = path.read_text().splitlines()
    text[6] = text[6].replace(";2;", ";2,6;")
    text[7] = text[7].replace(";2;", ";3,1;")
    path.write_text("\n".join(text) + "\n")
    settings = ImportSettings(load_column="slip")
    with pytest.raises(ValueError, match=r"row 7.*control value.*\[0\.01, 2\] mm.*2\.6 mm.*load_range.*load_levels"):
        read_measurement(path, sc.sensor_names, sc.load_levels, "mm", "path", settings, sc.sensor_units)
    data = read_measurement(path, sc.sensor_names, sc.load_levels, "mm", "path",
                            ImportSettings(load_column="slip", load_range=(0.0, 2.0)), sc.sensor_units)
    assert len(data.load_levels) == 4


def test_a_force_column_in_metres_or_a_gauge_in_newtons_is_refused(tmp_path, triplet):
    sc, _ = triplet
    path = tmp_path / "wrong.csv"
    path.write_text("slip [mm],F [mm],V_top [mm]\n0.01,6.5,-0.003\n")
    with pytest.raises(ValueError, match=r"column 2 \(F \[mm\]\).*'mm'.*force"):
        read_measurement(path, sc.sensor_names, sc.load_levels, "mm", "path", ImportSettings(load_column="slip"),
                         sc.sensor_units)
    path.write_text("slip [mm],F [kN],V_top [N]\n0.01,6.5,-0.003\n")
    with pytest.raises(ValueError, match=r"column 3 \(V_top \[N\]\).*'N'.*length"):
        read_measurement(path, sc.sensor_names, sc.load_levels, "mm", "path", ImportSettings(load_column="slip"),
                         sc.sensor_units)


def test_a_control_in_micrometres_under_a_millimetre_header_is_named_as_a_control_displacement():
    """The load check on a displacement-controlled scenario speaks of the control displacement and
    names µm; on a load-controlled scenario it still speaks of loads and N."""
    levels = [0.01, 0.1, 1.0, 2.0]
    with pytest.raises(MeasurementCheckError) as e:
        check_loads([10.0, 500.0, 1990.0], levels, "mm", source="t.csv", column="slip [mm]", rows=[2, 3, 4])
    (finding,) = e.value.findings
    assert finding.code == "load-scale" and finding.values["quantity"] == "control displacement"
    assert finding.values["likely_unit"] == "µm" and finding.values["row"] == 4
    text = refusal(e.value, "cli")
    for fragment in ("control displacement of 1990 mm", "last control level 2 mm", "µm", "'slip [µm]'"):
        assert fragment in text
    with pytest.raises(MeasurementCheckError) as e:
        check_loads([-0.01, -0.5, -1.2], levels, "mm", source="t.csv", column="slip [mm]")
    assert e.value.findings[0].code == "load-sign"
    assert "control displacement(s) are negative" in refusal(e.value, "cli")
    with pytest.raises(MeasurementCheckError) as e:
        check_loads([1000.0, 50000.0], [10.0, 50.0], "kN", source="w.csv", column="load [kN]")
    assert e.value.findings[0].values["quantity"] == "load" and "loads in N under a kN header" in refusal(e.value)


def test_a_falling_force_passes_the_load_check(tmp_path, triplet):
    """The force is a reading, not the control: a log whose force rises to 60 kN (30× the last
    control level: refused as a control, the premise) and falls after its peak is read as it is;
    only the control column is checked against the levels."""
    sc, _ = triplet
    control, F = [0.01, 0.05, 0.2, 1.0, 2.0], [10.0, 60.0, 45.0, 30.0, 20.0]
    with pytest.raises(MeasurementCheckError):
        check_loads(F, sc.load_levels, "mm")  # these numbers in the control column would be refused
    path = tmp_path / "falling.csv"
    path.write_text("slip [mm],F [kN]\n" + "\n".join(f"{c:g},{f:g}" for c, f in zip(control, F)) + "\n")
    data = read_measurement(path, sc.sensor_names, sc.load_levels, sc.load_unit, sc.load_response,
                            ImportSettings(load_column="slip"), sc.sensor_units)
    assert data.sensor_names == ("F",)
    assert_allclose(data.load_levels, control, rtol=0, atol=0)
    assert_allclose(data.values[:, 0], F, rtol=0, atol=0)  # the post-peak branch kept, in order


def test_a_load_cell_weighs_the_force_and_a_displacement_instrument_never_does():
    """``instrument = "lvdt"`` for all: the gauges take the LVDT (1 µm, 1 %), the force the load cell
    (0.05 kN, 1 %); an LVDT named for the force, or a load cell for a gauge, is refused naming the
    sensor and the instrument it needs."""
    names, units = ("middle_ux", "F"), ("mm", "kN")
    noise = instrument_noise("lvdt", names, units)
    assert noise.sigma == {"middle_ux": 0.001, "F": 0.05} and noise.delta == {"middle_ux": 0.01, "F": 0.01}
    assert "middle_ux 0.001 mm, F 0.05 kN" in noise.describe()
    m = Measurement([[0.2, 20.0]], names, [0.05], sensor_units=units)
    assert_allclose(noise.std(m), [np.hypot(0.001, 0.002), np.hypot(0.05, 0.2)], rtol=1e-12)
    with pytest.raises(ValueError, match=r"'lvdt'.*'F'.*kN.*load_cell"):
        instrument_noise({"middle_ux": "lvdt", "F": "lvdt"}, names, units)
    with pytest.raises(ValueError, match=r"'load_cell'.*'middle_ux'.*mm.*lvdt"):
        instrument_noise({"middle_ux": "load_cell", "F": "load_cell"}, names, units)


def test_the_curve_log_example_of_the_docs_runs(tmp_path, monkeypatch):
    """docs/measurements.md "Curve logs": the commands and the Python block run as written."""
    text = (ROOT / "docs" / "measurements.md").read_text()
    section = text.split("## Curve logs", 1)[1].split("\n## ", 1)[0]
    monkeypatch.chdir(tmp_path)
    for line in re.findall(r"```bash\n(.*?)```", section, re.S)[0].splitlines():
        args = line.split(" #")[0].split()
        if not args:
            continue
        assert args[0] == "podkrig" and ">" in args
        out = args[args.index(">") + 1]
        result = runner.invoke(app, args[1:args.index(">")])
        assert result.exit_code == 0, result.output
        Path(out).write_text(result.stdout)
    code = re.findall(r"```python\n(.*?)```", section, re.S)[0]
    exec(compile(code, "docs/measurements.md", "exec"), {})


def test_hidden_truth_cohesion_and_mode_II_energy_from_a_noisy_force_curve(triplet):
    """Hidden truth on the force alone: the triplet at c_bj = 0.3 MPa, GfII_bj = 0.1 N/mm, its F
    curve with load-cell noise (1 % + 0.05 kN, seeded), inverted on a 32-run surrogate over
    c_bj ∈ [0.2, 0.5], GfII_bj ∈ [0.05, 0.3]: the truth lies in the region's intervals and the
    optimum within 2 % (c_bj, from the peak) and 5 % (GfII_bj, from the softening branch), each
    interval narrower than a tenth of its bounds."""
    sc, _ = triplet
    truth = {"c_bj": 0.3, "GfII_bj": 0.1}
    bounds = {"c_bj": (0.2, 0.5), "GfII_bj": (0.05, 0.3)}
    space = ParameterSpace.from_scenario(sc, bounds)
    model = SurrogateModel(build_base_surrogate(sc, space, sc.resolve(), 32, 0))
    F = sc.run(truth).reading("F")
    rng = np.random.default_rng(7)
    noisy = F + rng.standard_normal(F.shape) * np.hypot(0.05, 0.01 * F)
    data = Measurement(noisy[:, None], ("F",), sc.load_levels, source="pseudo-triplet", sensor_units=("kN",))
    noise = instrument_noise("load_cell", ("F",), ("kN",))
    problem = InverseProblem(model, data, noise)
    settings = CalibrationSettings(inversion=InversionSettings(population_size=16, generations=15, n_starts=2),
                                   region=RegionSettings(samples=4096), fe_check=False)
    result = calibrate(problem, settings, calibration_rvc=False)
    found = result.inversion.parameters
    # measured: c_bj 0.2982, GfII_bj 0.0980, region ±3 % and ±4 % (one noise draw: a few σ of room)
    assert found["c_bj"] == pytest.approx(0.3, rel=0.02)
    assert found["GfII_bj"] == pytest.approx(0.1, rel=0.05)
    for name, value in truth.items():
        lo, hi = result.region.intervals[name]
        assert lo <= value <= hi, (name, lo, hi)
        assert hi - lo < 0.1 * (bounds[name][1] - bounds[name][0])  # the curve pins it down


def test_a_force_in_newtons_under_a_kilonewton_header_is_named_as_such():
    """The readings check on the load reading speaks of N and kN (not µm and mm)."""
    levels = np.array([0.01, 0.05, 0.2])
    runs = np.array([[[0.01, 6.0], [0.05, 20.0], [0.2, 15.0]], [[0.01, 7.0], [0.05, 24.0], [0.2, 17.0]]])
    data = Measurement([[0.01, 6500.0], [0.05, 22000.0], [0.2, 16000.0]], ("middle_ux", "F"), levels,
                       source="t.csv", sensor_units=("mm", "kN"))
    noise = instrument_noise("lvdt", data.sensor_names, data.sensor_units)
    with pytest.raises(MeasurementCheckError) as e:
        check_readings(data, noise, ("middle_ux", "F"), levels, "path", runs.reshape(2, -1))
    (finding,) = e.value.findings
    assert finding.values["sensor"] == "F" and finding.values["unit"] == "kN"
    assert "N read as kN?" in refusal(e.value, "cli")


def test_the_peak_load_and_its_displacement_as_two_readings(tmp_path, triplet):
    """``peak_readings = true``: ``F_peak`` (kN) and ``d_peak`` (mm) are readings, the response's
    refined peak at every level; the CSV states each once (the first row), read back as one
    observation each, which the model gives exactly at any control value (constant along it)."""
    _, plain = triplet
    result = runner.invoke(app, ["simulate", "triplet_shear", "--option", "peak_readings=true", "--format", "csv"])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert lines[0].endswith(",F [kN],F_peak [kN],d_peak [mm]")
    assert all(line.endswith(",,") for line in lines[2:]) and not lines[1].endswith(",")
    path = tmp_path / "peak.csv"
    path.write_text(result.stdout)
    sc = build_scenario({"scenario": "triplet_shear", "peak_readings": True})
    data = read_measurement(path, sc.sensor_names, sc.load_levels, sc.load_unit, sc.load_response,
                            sensor_units=sc.sensor_units)
    assert data.sensor_units[-2:] == ("kN", "mm") and np.isfinite(data.values[:, -2:]).sum() == 2
    assert_allclose(data.values[0, -2:], [plain.peak_load, plain.peak_displacement], rtol=1e-7)
    r = sc.run()
    assert_allclose(r.readings[:, :-2], plain.readings, rtol=0, atol=0)  # the other readings unchanged
    only_peak = Measurement([[r.peak_load, r.peak_displacement]], ("F_peak", "d_peak"), [0.137],
                            sensor_units=("kN", "mm"))
    got = only_peak.observation(sc.sensor_names, sc.load_levels, "path").apply(r.readings.reshape(1, -1))
    assert_allclose(got.ravel(), [r.peak_load, r.peak_displacement], rtol=1e-14)


def test_a_surrogate_from_a_store_knows_the_force_is_in_kN_and_reads_a_curve_log_in_N(tmp_path, triplet):
    """Snapshots of the triplet carry ``F`` like any sensor (its definition in the store); the
    surrogate built from them records each sensor's unit, so its inversion model reads ``F [N]``
    as kN: the log written from an FE run is read back within the 9 digits written."""
    sc, r = triplet
    space = ParameterSpace.from_scenario(sc, {"c_bj": (0.3, 0.4, "linear")})
    run_snapshots(tmp_path / "s.h5", sc, space, n=4, seed=0, workers=1)
    with SnapshotStore.open(tmp_path / "s.h5") as store:
        assert store.sensor_names[-1] == "F" and store.sensor_definitions["F"]["unit"] == "kN"
        surrogate = fit_from_store(store)
    model = SurrogateModel(surrogate)
    assert model.sensor_units == {"middle_ux": "mm", "V_top": "mm", "F": "kN"}
    path = tmp_path / "lab.csv"
    _lab_log(path, sc, r, np.array([0.01, 0.03, 0.2, 1.7]), title=False)
    data = read_measurement(path, model.sensor_names, model.load_levels, model.load_unit, model.load_response,
                            ImportSettings(load_column="slip"), model.sensor_units)
    assert_allclose(data.values[:, 0], np.interp([0.01, 0.03, 0.2, 1.7], sc.load_levels, r.reading("F")), rtol=1e-8)
    # podkrig invert on that log: one instrument named for all (the force takes the load cell)
    save_surrogate(surrogate, tmp_path / "sur.h5")
    result = runner.invoke(app, ["invert", str(tmp_path / "sur.h5"), "--data", str(path), "--load-column", "slip",
                                 "--instrument", "lvdt", "--format", "json", "--generations", "8",
                                 "--population-size", "12", "--region-samples", "1024", "--no-fe-check"])
    assert result.exit_code == 0, result.output
    found = json.loads(result.stdout)["inversion"]["parameters"]["c_bj"]
    assert found == pytest.approx(0.35, rel=0.02)  # the log is the default c_bj = 0.35 (4 training runs)


STUDY = '''name = "triplet_curve"
[scenario]
scenario = "triplet_shear"
[parameters]
c_bj = { lower = 0.2, upper = 0.5 }
GfII_bj = { lower = 0.05, upper = 0.3 }
[sampling]
train = { n = 32, seed = 0 }
held_out = { n = 8, seed = 1, method = "random" }
workers = 1
[measurement]
file = "triplet_T1.csv"
load_column = "slip"
load_range = [0.01, 2.0]
noise_abs = { F = 0.05, V_top = 0.001 }
noise_rel = 0.01
[inversion]
seed = 0
'''


def test_a_study_identifies_the_joints_from_a_lab_curve_log_in_newtons(tmp_path, triplet):
    """``podkrig run`` on a triplet study whose log is a lab curve (from zero slip, uneven steps, the
    force in N with 1 % + 0.05 kN noise, seeded; truth c_bj = 0.3 MPa, GfII_bj = 0.1 N/mm): every
    stage runs, and the region of equivalence holds the truth (measured: c_bj in [0.286, 0.301],
    GfII_bj in [0.098, 0.106])."""
    sc, _ = triplet
    r = sc.run({"c_bj": 0.3, "GfII_bj": 0.1})
    control = np.array([0.0, 0.006, 0.013, 0.021, 0.034, 0.046, 0.07, 0.13, 0.27, 0.55, 0.98, 1.52, 1.97])
    F = np.interp(control, sc.load_levels, r.reading("F"))
    F = F + np.random.default_rng(3).standard_normal(F.shape) * np.hypot(0.05, 0.01 * F)
    V = np.interp(control, sc.load_levels, r.reading("V_top"))
    rows = [f"{i},{c:g},{1000 * f:.1f},{v:.5f}" for i, (c, f, v) in enumerate(zip(control, F, V))]
    (tmp_path / "triplet_T1.csv").write_text("\n".join(["Triplet T1", "time [s],slip [mm],F [N],V_top [mm]", *rows]))
    (tmp_path / "triplet.toml").write_text(STUDY)
    result = runner.invoke(app, ["run", str(tmp_path / "triplet.toml"), "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output[-3000:]
    summary = json.loads(next((tmp_path / "out").rglob("summary.json")).read_text())
    intervals = summary["stages"]["calibration"]["region"]["intervals"]
    for name, value in {"c_bj": 0.3, "GfII_bj": 0.1}.items():
        lo, hi = intervals[name]
        assert lo <= value <= hi, (name, lo, hi)
