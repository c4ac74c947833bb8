"""The J4D wall's strength study (``examples/j4d_wall.toml``): the file loads with its six free
parameters and stated fixed values, the sampling box satisfies the scenario's constraints at every
point (checked here from the formulas, independently of the checker), the curve is read as the
model's with the stated noise, and the make script reproduces the shipped pseudo-data; (slow) a
reduced variant killed mid-way resumes without recomputing a finished FE run."""

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from typer.testing import CliRunner

from conftest import done_rows, load_file

from fe import SCENARIOS
from fe.scenarios import build_scenario
from podkrig.cli import app
from podkrig.offline.sampling import sobol
from podkrig.offline.store import SnapshotStore
from podkrig.study.schema import load_study
from podkrig.study.stages import read_study_measurement

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
STUDY = EXAMPLES / "j4d_wall.toml"
FREE = ["ft_bj", "c_bj", "tanphi_bj", "GfI_bj", "GfII_bj", "kV_bj"]


def _make_script():
    return load_file(EXAMPLES / "make_j4d_wall.py")


def test_the_study_loads_with_six_free_parameters_around_the_hidden_truth():
    """J4D at 0.30 MPa with the top fixed, the make script's 13 control levels; the five strength
    parameters and kV_bj free, each hidden value strictly inside its bounds (not on a face, where a
    region would be cut); E_b, kN_bj, tanphir_bj fixed at the scenario's Set A defaults."""
    make = _make_script()
    study = load_study(STUDY)
    assert study.spec.scenario == "shear_compression_nl"
    assert study.spec.options["precompression"] == make.SPEC["precompression"] == 0.30
    assert study.spec.options["top"] == make.SPEC["top"] == "fixed_vertical"
    assert_allclose(study.spec.options["load_levels"], make.LEVELS, rtol=1e-12)
    assert [p.name for p in study.free_parameters] == FREE == list(make.TRUTH)
    for p in study.free_parameters:
        assert p.lower < make.TRUTH[p.name] < p.upper, p.name
    defaults = {p.name: p.default for p in SCENARIOS["shear_compression_nl"].PARAMETERS}
    assert study.fixed == {n: defaults[n] for n in ("E_b", "kN_bj", "tanphir_bj")}
    assert study.sensitivity.enabled
    assert study.workers == 1  # a shared machine: one FE process
    assert [(v.name, v.spec.scenario, v.spec.options["precompression"], v.spec.options["top"], v.outputs)
            for v in study.validation] == [
        ("J6D", "shear_compression_nl", 1.21, "fixed_vertical", ("F_peak", "d_peak")),
        ("wall_opening", "wall_opening_nl", 0.30, "constant_force", ("F_peak", "d_peak"))]


def test_every_point_of_the_box_satisfies_the_scenarios_constraints():
    """The constraints of ``podkrig scenarios shear_compression_nl`` written out here and evaluated
    on 4 096 Sobol' points and the 64 corners of the box, with the fixed and default values
    (kN_bj 82, r_hj 1, tanphir_bj 0.75, tanpsi_bj 0): every one holds with a margin (the smallest
    is the Coulomb apex, ft ≤ c / max(tanφ, tanφ_r), 0.30 against 0.311 at the worst corner); the
    checker agrees (no violation)."""
    study = load_study(STUDY)
    sp = study.space
    corners = np.array(np.meshgrid(*[[0.0, 1.0]] * sp.n_params, indexing="ij")).reshape(sp.n_params, -1).T
    X = sp.from_unit(np.vstack([sobol(4096, sp.n_params, 0), corners]))
    v = dict(zip(sp.names, X.T))
    kN, r_hj, tanphir, tanpsi = 82.0, 1.0, 0.75, 0.0
    margins = {
        "tanpsi ≤ tanphi": v["tanphi_bj"] - tanpsi,
        "ft ≤ c / max(tanphi, tanphir)": v["c_bj"] / np.maximum(v["tanphi_bj"], tanphir) - v["ft_bj"],
        "ft² / GfI < kN (bed and head)": min(1.0, r_hj) * kN - v["ft_bj"] ** 2 / v["GfI_bj"],
        "c² / GfII < kV (bed and head)": min(1.0, r_hj) * v["kV_bj"] - v["c_bj"] ** 2 / v["GfII_bj"],
    }
    for name, m in margins.items():
        assert m.min() > 0, name
    assert_allclose(margins["ft ≤ c / max(tanphi, tanphir)"].min(), 0.28 / 0.90 - 0.30, rtol=1e-9)
    bounds = {p.name: (p.lower, p.upper, p.scale) for p in sp.parameters}
    SCENARIOS["shear_compression_nl"].check_spec_box(study.spec, bounds)  # raises on a violation


def test_the_curve_is_read_at_the_control_levels_with_the_stated_noise():
    """F in kN and five displacements in mm at the 13 levels; σ per reading is the make script's
    (1 % + 0.05 kN on F, 1 % + 2 µm on the gauges); the curve rises to 1.75 mm (top fixed: no
    softening inside the mesh-objective range)."""
    make = _make_script()
    study = load_study(STUDY)
    (test,) = study.calibration_tests
    assert test.measurement.file == make.DATA.resolve()
    sc = build_scenario(test.spec)
    data, noise = read_study_measurement(test, sc.sensor_names, sc.load_levels, sc.load_unit, sc.load_response,
                                         sc.sensor_units)
    assert data.sensor_names == ("top_ux", "D1", "D2", "V_left", "V_right", "F")
    assert data.sensor_units == ("mm",) * 5 + ("kN",)
    assert_allclose(data.load_levels, make.LEVELS, rtol=1e-12)
    sigma_abs = np.array([make.NOISE_ABS[n] for n in data.sensor_names])
    expected = np.hypot(sigma_abs, make.NOISE_REL * np.abs(data.values)).ravel()
    assert_allclose(noise.std(data), expected, rtol=1e-12)
    F = data.values[:, -1]
    assert 40 < F.max() < 60 and np.argmax(F) >= len(F) - 3


def test_the_make_script_reproduces_the_shipped_curve(tmp_path):
    """One FE run at the hidden truth (a few s of CPU) plus the seeded noise: the shipped file to the
    8 digits written (rtol 1e-6 leaves room for solver round-off across machines, far below the
    ≥ 1 % noise of every reading)."""
    make = _make_script()
    made = make.make(tmp_path / "j4d.csv")
    assert made.read_text().splitlines()[0] == make.DATA.read_text().splitlines()[0]
    a, b = (np.loadtxt(f, delimiter=",", skiprows=1) for f in (made, make.DATA))
    assert_allclose(a, b, rtol=1e-6, atol=1e-9)


def _reduced_study(folder, n_train=8, n_held=4):
    """The example with small designs, no sensitivity or validation models, next to a copy of its
    curve."""
    text = STUDY.read_text().split("\n# Capacity with its spread")[0]
    for old, new in (("n = 256, seed = 0", f"n = {n_train}, seed = 0"), ("n = 32, seed = 1", f"n = {n_held}, seed = 1"),
                     ("[sensitivity]                    # Sobol' indices on the surrogate: proposes parameters to fix\n"
                      "enabled = true", "[sensitivity]\nenabled = false")):
        assert old in text, old
        text = text.replace(old, new)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "j4d_wall.toml").write_text(text)
    (folder / "j4d_wall_measured.csv").write_text(_make_script().DATA.read_text())
    return folder / "j4d_wall.toml"


@pytest.mark.slow
def test_a_killed_study_resumes_without_recomputing_a_finished_run(tmp_path):
    """The study with 8 training and 4 held-out runs (about 1 min CPU): ``podkrig run`` SIGKILLed
    once 3 training rows are written, then run again — the second run does exactly the missing
    FE runs (5 training + 4 held-out + the FE check; the probe is cached), the finished rows are
    kept bitwise, and the study ends with an inversion of all six parameters."""
    study = _reduced_study(tmp_path / "study")
    out = tmp_path / "out"
    args = ["run", str(study), "--out", str(out), "--yes"]
    job = subprocess.Popen([sys.executable, "-c", "from podkrig.cli import app; app(prog_name='podkrig')", *args],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 600
        while done_rows(out / "train.h5") < 3:
            assert job.poll() is None, "the study ended before it could be killed"
            assert time.monotonic() < deadline, "no 3 training rows within 600 s"
            time.sleep(0.05)
        job.kill()  # SIGKILL: no cleanup
    finally:
        job.kill()
        job.wait()
    with SnapshotStore.open(out / "train.h5") as store:
        done = store.done_mask()
        before = store.readings(only_done=False)[done]
    assert 3 <= done.sum() < 8

    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output[-3000:]
    stages = json.loads((out / "summary.json").read_text())["stages"]
    assert stages["probe"]["cached"]
    assert stages["offline"]["fe_runs"] == 8 - done.sum()  # nothing finished is run again
    assert stages["held_out"]["fe_runs"] == 4
    with SnapshotStore.open(out / "train.h5") as store:
        assert store.counts()["done"] + store.counts()["failed"] == 8
        assert_array_equal(store.readings(only_done=False)[done], before)
    assert set(stages["calibration"]["region"]["intervals"]) == set(FREE)
