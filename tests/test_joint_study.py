"""A joint calibration study (``[[test]]`` tables, issue 19 item 3) end to end on coarse meshes:
per-test stages and files, one calibration over the shared parameters, a per-test
nuisance parameter, per-test χ²/dof, FE checks and diagnoses, the cache, the report, and the
study-file errors of the joint form."""

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fe.scenarios import build_scenario
from podkrig.cli import app
from podkrig.online.measurement import Measurement
from podkrig.io.measurement_log import write_measurement_csv
from podkrig.study import load_study
from podkrig.study.schema import StudyError

runner = CliRunner()

JOINT = """\
name = "tiny_joint"

[parameters]                     # shared
kN_bj = { lower = 30.0, upper = 300.0, scale = "log" }
kV_bj = { lower = 10.0, upper = 120.0, scale = "log" }

[fixed]
E_b = 11000.0

[sampling]
train = { n = 16, seed = 0 }
held_out = { n = 4, seed = 1, method = "random" }
workers = 1

[inversion]
population_size = 20
generations = 10
n_starts = 2
region_samples = 4096

[diagnosis]
enabled = true

[[test]]
name = "diagonal"
scenario = { scenario = "diagonal_compression", nx = 2, ny = 1 }
measurement = { file = "diagonal.csv", noise_abs = 0.001, noise_rel = 0.01 }
fixed = { r_hj = 0.6 }

[[test]]
name = "shear"
scenario = { scenario = "shear_compression", nx = 2, ny = 1 }
measurement = { file = "shear.csv", noise_abs = 0.001, noise_rel = 0.01 }
parameters = { r_hj = { lower = 0.2, upper = 1.0 } }   # this test's own
sampling = { train = { n = 24, seed = 3 } }
"""

TRUTH = {"E_b": 11000.0, "kN_bj": 90.0, "kV_bj": 35.0}


def _measured(path, scenario, r_hj, seed):
    sc = build_scenario({"scenario": scenario, "nx": 2, "ny": 1})
    clean = sc.run({**TRUTH, "r_hj": r_hj}).readings
    sigma = np.sqrt(0.001**2 + (0.01 * clean) ** 2)
    noisy = clean + sigma * np.random.default_rng(seed).standard_normal(clean.shape)
    write_measurement_csv(path, Measurement(noisy, sc.sensor_names, sc.load_levels))


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """The two tests' pseudo-measured files, made once (two FE runs) for every study of this module."""
    d = tmp_path_factory.mktemp("measured")
    _measured(d / "diagonal.csv", "diagonal_compression", 0.6, 0)
    _measured(d / "shear.csv", "shear_compression", 0.45, 1)
    return d


def _write(folder, measured, text=JOINT):
    (folder / "study.toml").write_text(text)
    for name in ("diagonal.csv", "shear.csv"):
        shutil.copyfile(measured / name, folder / name)
    return folder / "study.toml"


def _run(study, out):
    result = runner.invoke(app, ["run", str(study), "--out", str(out)])
    assert result.exit_code == 0, result.output
    return result.output


@pytest.fixture(scope="module")
def joint(tmp_path_factory, measured):
    d = tmp_path_factory.mktemp("joint")
    study = _write(d, measured)
    out = d / "out"
    return study, out, _run(study, out)


def test_joint_study_runs_each_test_and_fits_them_together(joint):
    _, out, text = joint
    stages = {p.stem: json.loads(p.read_text()) for p in (out / "stages").glob("*.json")}
    per_test = {f"{s}.{t}" for t in ("diagonal", "shear")
                for s in ("measurement", "probe", "offline", "held_out", "surrogate", "held_out_validation", "diagnosis")}
    assert set(stages) == per_test | {"sensitivity", "calibration"}
    sens = stages["sensitivity"]["result"]
    assert set(sens["readings"]) == {"diagonal", "shear"} and sens["misfit"]["parameters"] == ["kN_bj", "kV_bj", "r_hj"]
    assert sens["readings"]["diagonal"]["parameters"] == ["kN_bj", "kV_bj"]
    assert stages["offline.diagonal"]["fe_runs"] == 16 and stages["offline.shear"]["fe_runs"] == 24  # its own design
    assert stages["calibration"]["fe_runs"] == 2  # one FE check per test
    for t in ("diagonal", "shear"):
        assert (out / t / "train.h5").is_file() and (out / t / "surrogate.h5").is_file()
    summary = json.loads((out / "summary.json").read_text())
    calibration = summary["stages"]["calibration"]
    inv = calibration["inversion"]
    assert set(inv["parameters"]) == {"kN_bj", "kV_bj", "r_hj"}  # shared, then the shear test's own
    assert set(inv["tests"]["diagonal"]["parameters"]) == {"kN_bj", "kV_bj"}
    assert set(inv["tests"]["shear"]["parameters"]) == {"kN_bj", "kV_bj", "r_hj"}
    n_diag, n_shear = (inv["tests"][t]["measurement"]["n_obs"] for t in ("diagonal", "shear"))
    assert inv["measurement"]["n_obs"] == n_diag + n_shear and inv["dof"] == n_diag + n_shear - 3
    assert inv["tests"]["shear"]["dof"] == n_shear - 3 and inv["tests"]["diagonal"]["dof"] == n_diag - 2
    assert inv["chi2"] == pytest.approx(sum(inv["tests"][t]["chi2"] for t in ("diagonal", "shear")), rel=1e-9)
    for t in ("diagonal", "shear"):
        assert inv["tests"][t]["fe_check"] is not None
    region = calibration["region"]
    assert region["names"] == ["kN_bj", "kV_bj", "r_hj"]
    for name, (lo, hi) in region["intervals"].items():
        assert lo <= inv["parameters"][name] <= hi
    assert set(calibration["rvc"]) == {"calibration.diagonal", "calibration.shear"}
    assert "test diagonal:" in text and "test shear:" in text  # the CLI's χ²/dof and checks, per test


def test_joint_rerun_with_nothing_changed_does_no_fe_work(joint, fe_counter):
    study, out, _ = joint
    counter = fe_counter()
    _run(study, out)
    assert counter.calls == 0


def test_joint_report_has_each_tests_sections_and_figures(joint):
    _, out, _ = joint
    page = out / "report" / "index.html"
    source = page.read_text(encoding="utf-8")
    for t, scenario in (("diagonal", "diagonal_compression"), ("shear", "shear_compression")):
        assert f"Test {t} ({scenario})" in source
        for fig in ("energy.png", "modes.png", "predicted_vs_fe.png", "sensitivity.png", "fit.png", "residuals.png",
                    "deformed.png"):
            assert f'src="{t}/{fig}"' in source and (page.parent / t / fig).is_file(), (t, fig)
        assert f'href="{t}/diagnosis/index.html"' in source
        assert (page.parent / t / "diagnosis" / "index.html").is_file()
    assert "share of the joint fit" in source  # the section of each test's share
    assert not re.search(r"\bnan\b", source, re.IGNORECASE)


@pytest.mark.parametrize("edit, message", [
    (lambda s: 'scenario = "diagonal_compression"\n' + s,
     r"scenario: .*each \[\[test\]\] its own scenario"),
    (lambda s: s[: s.index('[[test]]\nname = "shear"')],
     r"one \[\[test\]\] table: .*two or more tests"),
    (lambda s: s.replace('name = "shear"', 'name = "diagonal"'), r"test\[2\]\.name: 'diagonal' names two tests"),
    (lambda s: s.replace('parameters = { r_hj', 'parameters = { kN_bj = { lower = 30.0, upper = 300.0 }, r_hj'),
     r"test\[2\]\.parameters\.kN_bj: .*shared parameter"),
    (lambda s: s.replace('kV_bj = { lower', 'Km = { lower = 0.7, upper = 0.9 }\nkV_bj = { lower'),
     r"parameters\.Km: unknown parameter"),
    (lambda s: s.replace('fixed = { r_hj = 0.6 }', 'fixed = { r_hj = 0.6, kN_bj = 50.0 }'),
     r"test\[1\]\.fixed\.kN_bj: .*also a free parameter"),
    (lambda s: s.replace("[fixed]\nE_b = 11000.0", "[fixed]\nE_b = 11000.0\nsigma0 = 0.3"),
     r"fixed\.sigma0: .*none of the tests"),
])
def test_joint_study_file_mistakes_are_named(tmp_path, measured, edit, message):
    """Each names the file, the key (tests numbered from 1, as written) and what is wrong."""
    study = _write(tmp_path, measured, edit(JOINT))
    with pytest.raises(StudyError, match=message):
        load_study(study)


def test_a_study_without_scenario_or_tests_names_both_forms(tmp_path, measured):
    text = JOINT[: JOINT.index("[[test]]")]
    study = _write(tmp_path, measured, text)
    with pytest.raises(StudyError, match=r"missing key 'scenario'.*\[\[test\]\] tables"):
        load_study(study)


def test_sensitivity_settings_are_checked(tmp_path, measured):
    study = _write(tmp_path, measured, JOINT + "\n[sensitivity]\nn = 1000\n")
    with pytest.raises(StudyError, match=r"sensitivity\.n: 1000 .*power of two"):
        load_study(study)
    study = _write(tmp_path, measured, JOINT + "\n[sensitivity]\nenabled = false\n")
    assert load_study(study).sensitivity.enabled is False


def test_the_joint_example_is_valid():
    examples = Path(__file__).resolve().parents[1] / "examples"
    study = load_study(examples / "joint_diagonal_shear.toml")
    assert [t.name for t in study.tests] == ["diagonal", "shear_wall"]
    assert all(t.space.names == ("E_b", "kN_bj", "kV_bj", "r_hj") for t in study.tests)
    assert study.tests[1].measurement.file == (examples / "shear_wall_measured.csv").resolve()
