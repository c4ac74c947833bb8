"""``podkrig surrogate build / validate / refine`` through typer's CliRunner on small stores."""

import json

import h5py
import numpy as np
import pytest
from numpy.testing import assert_array_equal
from typer.testing import CliRunner

from podkrig.cli import app
from podkrig.online.settings import SensitivitySettings
from podkrig.study.settings import SensitivityTable
from podkrig.io.surrogate_file import load_surrogate, save_surrogate
from podkrig.offline.runner import run_snapshots
from podkrig.offline.store import SnapshotStore
from podkrig.online.problem import SurrogateModel
from podkrig.parameters import ParameterSpace
from podkrig.surrogate.backends import make_backend
from podkrig.surrogate.podkriging import fit_from_store, training_data

runner = CliRunner()
SPEC = {"scenario": "diagonal_compression", "nx": 2, "ny": 1}
BOUNDS = {"kN_bj": (10, 1000, "log"), "kV_bj": (4, 400, "log"), "r_hj": (0.1, 1.0), "E_b": (5000, 20000)}


@pytest.fixture(scope="module")
def stores(tmp_path_factory, coarse_diagonal):
    d = tmp_path_factory.mktemp("stores")
    space = ParameterSpace.from_scenario(coarse_diagonal, BOUNDS)
    run_snapshots(d / "train.h5", coarse_diagonal, space, n=16, seed=0, workers=1)
    run_snapshots(d / "held.h5", coarse_diagonal, space, n=8, seed=3, sampling="random", workers=1)
    return d


def test_help():
    for cmd in ("build", "validate", "refine"):
        result = runner.invoke(app, ["surrogate", cmd, "--help"])
        assert result.exit_code == 0, result.output
    assert "--target-error" in runner.invoke(app, ["surrogate", "refine", "--help"]).output


def test_build_validate_refine(stores, tmp_path):
    out = tmp_path / "s.h5"
    result = runner.invoke(app, ["surrogate", "build", str(stores / "train.h5"), "--out", str(out), "--beta", "1.5"])
    assert result.exit_code == 0, result.output
    assert "16 snapshots, 6 POD modes" in result.output and "trained in" in result.output

    report = tmp_path / "report"
    result = runner.invoke(app, ["surrogate", "validate", str(out), "--held-out", str(stores / "held.h5"),
                                 "--report", str(report), "--format", "json"])
    assert result.exit_code == 0, result.output
    s = json.loads(result.stdout)
    assert {"n_train", "n_held_out", "n_modes", "rel_error", "pod_error", "coverage_2sigma"} <= set(s)
    assert (s["n_train"], s["n_held_out"], s["n_modes"]) == (16, 8, 6)
    assert set(s["rel_error"]) >= {"median", "p95", "max"} and s["rel_error"]["median"] < 0.2
    for name in ("index.html", "energy.png", "modes.png", "error_histograms.png", "predicted_vs_fe.png"):
        assert (report / name).is_file(), name
    assert "mm" in (report / "index.html").read_text()

    result = runner.invoke(app, ["surrogate", "validate", str(out), "--held-out", str(stores / "held.h5")])
    assert result.exit_code == 0 and "held-out runs" in result.output and "±2σ" in result.output

    train = tmp_path / "train.h5"
    train.write_bytes((stores / "train.h5").read_bytes())
    result = runner.invoke(app, ["surrogate", "refine", str(out), "--store", str(train), "--held-out",
                                 str(stores / "held.h5"), "--budget", "4", "--batch", "2",
                                 "--candidates", "256", "--target-error", "1e-9"])
    assert result.exit_code == 0, result.output
    assert "4 FE runs added" in result.output and "2 rounds" in result.output and "budget" in result.output
    with SnapshotStore.open(train) as st:
        assert st.counts()["done"] == 20  # the new runs are saved in the store


@pytest.mark.parametrize(
    "args, message",
    [
        (["surrogate", "build", "missing.h5", "--out", "x.h5"], "no snapshot store at missing.h5"),
        (["surrogate", "validate", "missing.h5", "--held-out", "h.h5"], "no surrogate file at missing.h5"),
    ],
)
def test_errors_are_one_line_with_exit_code_2(args, message):
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    assert message in result.output


def test_conflicting_truncation(stores, tmp_path):
    result = runner.invoke(app, ["surrogate", "build", str(stores / "train.h5"), "--out", str(tmp_path / "x.h5"),
                                 "--energy", "0.9", "--modes", "2"])
    assert result.exit_code == 2 and "--modes" in result.output and "either energy or modes" in result.output
    result = runner.invoke(app, ["surrogate", "build", str(stores / "train.h5"), "--out", str(tmp_path / "x.h5"),
                                 "--beta", "steep"])
    assert result.exit_code == 2 and "--beta 'steep'" in result.output and "fit-shared" in result.output


@pytest.mark.parametrize("backend", ["podkrig", "smt-krg", "smt-kpls", "sklearn-gpr"])
def test_backends_build_save_load_validate_invert(stores, tmp_path, backend):
    kriging = make_backend(backend, n_start=1) if backend.startswith("smt") else make_backend(backend)
    with SnapshotStore.open(stores / "train.h5") as s:
        sur = fit_from_store(s, kriging=kriging)
    with SnapshotStore.open(stores / "held.h5") as h:
        Xh, _ = training_data(h)
    mean, std = sur.predict(Xh, return_std=True)
    save_surrogate(sur, tmp_path / "s.h5")
    with h5py.File(tmp_path / "s.h5") as f:
        assert f.attrs["backend"] == backend and f.attrs["backend_version"]
    loaded = load_surrogate(tmp_path / "s.h5")
    assert loaded.backend_ == backend and type(loaded.kriging_) is type(sur.kriging_)
    # rebuilt from training data + fitted hyperparameters (no pickle, no optimiser): ours bitwise;
    # the libraries' refits agree to rounding (bitwise with numpy 2.4, 5e-13 relative for
    # scikit-learn with numpy 1.26)
    m2, s2 = loaded.predict(Xh, return_std=True)
    if backend == "podkrig":
        assert_array_equal(m2, mean)
        assert_array_equal(s2, std)
    np.testing.assert_allclose(m2, mean, rtol=0, atol=1e-11 * np.abs(mean).max())
    np.testing.assert_allclose(s2, std, rtol=1e-9)
    assert np.all(std > 0)
    m3, _ = SurrogateModel(loaded).predict_unit(loaded.space.to_unit(Xh), return_std=True)
    np.testing.assert_allclose(m3, mean, rtol=0, atol=1e-9 * np.abs(mean).max())

    result = runner.invoke(app, ["surrogate", "validate", str(tmp_path / "s.h5"), "--held-out",
                                 str(stores / "held.h5"), "--format", "json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["backend"] == backend and summary["n_held_out"] == 8
    # 16 coarse FE runs, 4 parameters: every backend lands at 0.055-0.067 median (measured), the
    # mean snapshot alone at 0.63; 0.1 fails a backend that learns little of the parameters
    assert summary["rel_error"]["median"] < 0.1
    assert ("loo_error" in summary) == (backend == "podkrig")


def test_build_with_backend_option(stores, tmp_path):
    out = tmp_path / "gpr.h5"
    result = runner.invoke(app, ["surrogate", "build", str(stores / "train.h5"), "--out", str(out),
                                 "--backend", "sklearn-gpr"])
    assert result.exit_code == 0, result.output
    assert "backend sklearn-gpr" in result.output and load_surrogate(out).backend_ == "sklearn-gpr"
    result = runner.invoke(app, ["surrogate", "build", str(stores / "train.h5"), "--out", str(out),
                                 "--backend", "smt-krg", "--beta", "1.5"])
    assert result.exit_code != 0 and "--beta set(s) the podkrig kriging" in result.output
    result = runner.invoke(app, ["surrogate", "build", str(stores / "train.h5"), "--out", str(out),
                                 "--backend", "gpy"])
    assert result.exit_code == 2 and "'gpy' is not one of" in result.output
    for name in ("podkrig", "smt-krg", "smt-kpls", "sklearn-gpr"):
        assert name in result.output


def test_sensitivity_command_writes_indices_figure_and_proposal(stores, tmp_path):
    """``podkrig sensitivity`` on a 16-snapshot surrogate: JSON with both index sets and their
    intervals, the figure, and (with --data) the misfit's indices; a noise model without data is
    refused."""
    sur = tmp_path / "s.h5"
    assert runner.invoke(app, ["surrogate", "build", str(stores / "train.h5"), "--out", str(sur)]).exit_code == 0
    model = SurrogateModel(load_surrogate(sur))
    x = [model.space.from_unit(np.full((1, 4), 0.5))[0]]
    Y = model.predict(np.array(x)).reshape(len(model.load_levels), -1)
    csv = tmp_path / "m.csv"
    csv.write_text("load," + ",".join(model.sensor_names) + "\n" + "\n".join(
        f"{lv:g}," + ",".join(f"{v:.6g}" for v in row) for lv, row in zip(model.load_levels, Y)) + "\n")
    out = tmp_path / "sens"
    result = runner.invoke(app, ["sensitivity", str(sur), "--n", "256", "--data", str(csv), "--noise-abs", "0.002",
                                 "--out", str(out), "--format", "json"])
    assert result.exit_code == 0, result.output
    d = json.loads(result.stdout)
    r = d["readings"]
    assert r["parameters"] == list(model.space.names) and len(r["outputs"]) == Y.size
    assert np.shape(r["total"]) == (Y.size, 4) and r["n_evaluations"] == 256 * 6
    assert d["misfit"]["outputs"] == ["misfit"] and isinstance(d["propose_fixing"], list)
    assert (out / "sensitivity.png").is_file() and (out / "sensitivity.json").is_file()
    refused = runner.invoke(app, ["sensitivity", str(sur), "--noise-rel", "0.01", "--out", str(out)])
    assert refused.exit_code != 0 and "needs --data" in refused.output
    # the defaults are the library's (SensitivitySettings), also the study's [sensitivity] table's
    default = json.loads(runner.invoke(app, ["sensitivity", str(sur), "--out", str(out), "--format", "json"]).stdout)
    assert default["readings"]["n_base"] == SensitivitySettings().n == SensitivityTable().n
    bad = runner.invoke(app, ["sensitivity", str(sur), "--n", "300", "--out", str(out)])
    assert bad.exit_code != 0 and "--n" in bad.output and "300" in bad.output and "power of two" in bad.output
