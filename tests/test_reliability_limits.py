"""Issue 13, deliverable 2 (one validation layer): the same bounds with memory or time estimates in
the study file, the CLI and the Python API; ``--yes`` for large FE jobs; finite noise levels."""

import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from podkrig import limits
from podkrig.cli import app
from podkrig.ga.options import GAOptions
from podkrig.online.measurement import NoiseModel
from podkrig.online.region import likelihood_ratio_region, noise_monte_carlo_region
from podkrig.sensors.candidates import parse_range
from podkrig.study import load_study
from podkrig.study.schema import StudyError

runner = CliRunner()
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _study(tmp_path, replace=(), append=""):
    """The bundled demo study with its measurement, edited: ``replace`` is (old, new) pairs."""
    text = (EXAMPLES / "diagonal_compression.toml").read_text()
    for old, new in replace:
        assert old in text
        text = text.replace(old, new)
    (tmp_path / "diagonal_compression_measured.csv").write_bytes(
        (EXAMPLES / "diagonal_compression_measured.csv").read_bytes())
    path = tmp_path / "study.toml"
    path.write_text(text + append)
    return path


# ----------------------------------------------------------------------------- study file bounds
@pytest.mark.parametrize("replace, key, message", [
    (("seed = 0\nconfidence", "seed = 0\npopulation_size = 1000000000000\nconfidence"),
     "inversion.population_size", r"above the limit of 262144: one generation would need about 7\.3 PiB"),
    (("seed = 0\nconfidence", "seed = 0\ngenerations = 1000000000000\nconfidence"),
     "inversion.generations", r"GA evaluations, above the limit .* history alone would need about 9\.\d PiB"),
    (("seed = 0\nconfidence", "seed = 0\nregion_samples = 1000000000000\nconfidence"),
     "inversion.region_samples", r"at most 16777216; got 1000000000000 \(one round would need about 727\.6 TiB"),
    (("seed = 0\nconfidence", "seed = 0\nn_starts = 100000\nconfidence"), "inversion.n_starts", "above the limit of 1024"),
    (("workers  = 1 ", "workers  = 100000 "), "sampling.workers", "above the limit of 1024"),
    (("train    = { n = 256", "train    = { n = 1000000000"), "sampling.train.n",
     r"above the limit of 16777216 rows: the store would need about 953\.7 GiB"),
    (("n = 64\n", "n = 100000000000\n"), r"validation\[1\]\.n", "above the limit of 16777216 rows"),
])
def test_study_sizes_have_upper_bounds_with_an_estimate(tmp_path, replace, key, message):
    """Before: each of these was accepted by the study file (and ended in MemoryError or days of work)."""
    with pytest.raises(StudyError, match=key + ": .*" + message):
        load_study(_study(tmp_path, [replace]))


def test_the_demo_study_is_within_every_bound(tmp_path):
    study = load_study(_study(tmp_path))
    assert study.inversion.population_size == 100 and study.train.n == 256


# ----------------------------------------------------------------------------- Python API bounds
def test_ga_population_and_budget_are_bounded_in_the_api():
    with pytest.raises(ValueError, match=r"population_size = 1000000000000 .* 7\.3 PiB"):
        GAOptions(population_size=10**12)
    with pytest.raises(ValueError, match="GA evaluations, above the limit"):
        GAOptions(population_size=1000, max_generations=10**6)
    with pytest.raises(ValueError, match="GA evaluations, above the limit"):
        GAOptions(max_evaluations=10**12)
    assert GAOptions(population_size=np.int64(60)).population_size == 60  # numpy integers are integers


@pytest.mark.parametrize("kwargs, message", [
    ({"n_samples": 16}, "n_samples must be at least 1024"),
    ({"n_samples": 0}, "n_samples must be at least 1024"),
    ({"n_samples": -5}, "n_samples must be at least 1024"),
    ({"n_samples": 2**40}, "n_samples must be at most"),
    ({"confidence": 1.5}, r"confidence must be in \(0, 1\)"),
    ({"confidence": float("nan")}, "confidence must be a finite number"),
])
def test_region_arguments_are_checked_in_the_python_api(kwargs, message):
    """Before: only the CLI checked --region-samples; likelihood_ratio_region(n_samples=16) reported a
    far too narrow region (issue 13, finding 5)."""
    with pytest.raises(ValueError, match=message):
        likelihood_ratio_region(None, np.zeros(1), **kwargs)


@pytest.mark.parametrize("kwargs, message", [
    ({"n_realisations": 3}, r"n_realisations .*\[20, 100000\]"),
    ({"confidence": 0.0}, r"confidence must be in \(0, 1\)"),
])
def test_noise_monte_carlo_region_arguments_are_checked(kwargs, message):
    with pytest.raises(ValueError, match=message):
        noise_monte_carlo_region(None, np.zeros(1), **kwargs)


@pytest.mark.parametrize("kwargs, message", [
    ({"sigma": float("inf")}, r"sigma \(mm\) .*finite.*got inf"),
    ({"sigma": float("nan")}, "finite number; got nan"),
    ({"sigma": 1e300}, r"must be in \[1e-07, 1e\+06\] mm"),
    ({"sigma": {"D1": 0.01, "D2": float("inf")}}, "sigma of sensor 'D2' .* finite"),
    ({"delta": float("nan")}, "delta .*finite"),
    ({"covariance": np.array([[1.0, 0.0], [0.0, np.inf]])}, "covariance .*finite"),
])
def test_noise_levels_must_be_finite(kwargs, message):
    """Before: NoiseModel(sigma=inf) was accepted and made every reading weightless (χ² = 0)."""
    with pytest.raises(ValueError, match=message):
        NoiseModel(**kwargs)


@pytest.fixture(scope="module")
def small_surrogate(tmp_path_factory):
    """A 16-run surrogate of the coarse diagonal test (E_b free) and noise-free data of it."""
    from fe.scenarios import build_scenario
    from podkrig.online.measurement import Measurement
    from podkrig.io.measurement_log import write_measurement_csv

    d = tmp_path_factory.mktemp("limits_cli")
    spec = d / "spec.toml"
    spec.write_text('scenario = "diagonal_compression"\nnx = 2\nny = 1\n')
    for args in (["snapshots", "run", "--spec", spec, "--param", "E_b=6000:18000", "--n", 16, "--seed", 0,
                  "--store", d / "s.h5", "--workers", 1], ["surrogate", "build", d / "s.h5", "--out", d / "sur.h5"]):
        result = runner.invoke(app, [str(a) for a in args])
        assert result.exit_code == 0, result.output
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    write_measurement_csv(d / "data.csv", Measurement(sc.run({"E_b": 11000.0}).readings, sc.sensor_names,
                                                      sc.load_levels))
    return d / "sur.h5", d / "data.csv"


@pytest.mark.parametrize("noise", [["--noise-abs", "inf"], ["--noise-abs", "D1=nan"], ["--noise-abs", "1e300"]])
def test_invert_refuses_a_non_finite_noise_level_on_the_cli(small_surrogate, noise):
    """Before: ``podkrig invert --noise-abs inf`` ran and reported every parameter "not pinned down"."""
    sur, data = small_surrogate
    result = runner.invoke(app, ["invert", str(sur), "--data", str(data), *noise, "--no-fe-check"])
    assert result.exit_code != 0, result.output
    assert result.output.startswith("error:") and "Traceback" not in result.output


@pytest.mark.parametrize("text, message", [
    ("0:1e9:1e-3", r"1e\+12 points along one axis.*131072"),
    ("0:inf:1", "must be finite numbers"),
    ("nan:1:1", "must be finite numbers"),
])
def test_grid_ranges_are_bounded(text, message):
    """Before: MemoryError (7.3 TiB), OverflowError and a NaN conversion error."""
    with pytest.raises(ValueError, match=message):
        parse_range(text, "--dic-x")


def test_grids_of_too_many_points_are_refused_with_an_estimate():
    with pytest.raises(ValueError, match=r"the DIC grid has 160000 points.*131072.*156\.2 MiB"):
        limits.check_grid(400 * 400, "dic", "the DIC grid")
    with pytest.raises(ValueError, match=r"5000 points.*4096.*gauge candidates.*1\.2 GiB"):
        limits.check_grid(5000, "gauge")


# ----------------------------------------------------------------------------- --yes for large jobs
def test_job_estimate_states_runs_time_and_disk():
    text, large = limits.fe_job_estimate([(256, 9360, False)], 10**6)
    assert all(f in text for f in ("256 FE runs", "9360 dofs", "3.8 s", "976.6 KiB")) and not large
    # 512 nonlinear runs of 9360 dofs at 4e-4 s per dof: 1917 s, half an hour, asked without
    text, large = limits.fe_job_estimate([(512, 9360, True), (64, 8000, False)], 10**6)
    assert all(f in text for f in ("576 (512 nonlinear) FE runs", "8000–9360 dofs", "32 min")) and not large
    assert limits.fe_job_estimate([(5000, 9360, True)], 0)[1]  # 5.2 h of nonlinear runs
    assert limits.fe_job_estimate([(2**16 + 1, 10, False)], 0)[1]  # runs alone
    assert limits.fe_job_estimate([(10, 10, False)], 5 * 2**30)[1]  # disk alone


def test_job_estimate_uses_the_measured_seconds_per_run():
    """Before: every nonlinear run of 8006 dofs was counted at ~40 s, so 208 flat-jack runs (3.3 s
    each) asked for --yes; a measured time per run replaces the model for its job."""
    text, large = limits.fe_job_estimate([(208, 8006, True, 3.3)], 0)
    assert "about 11.4 min on one core, from the runs stored" in text and not large
    text, large = limits.fe_job_estimate([(208, 8006, True, 60.0)], 0)  # runs that keep failing: 3.5 h
    assert "3.47 h" in text and large
    text, _ = limits.fe_job_estimate([(10, 100, True, None)], 0)  # none stored yet: the per-dof model
    assert "from the runs stored" not in text and "0.4 s" in text


def test_snapshots_run_refuses_a_huge_job_without_yes(tmp_path):
    """Before: --n 2**20 on a new store asked on a terminal only; a script got 'Aborted!'. Now the
    estimate is printed and nothing is created."""
    store = tmp_path / "big.h5"
    result = runner.invoke(app, ["snapshots", "run", "--scenario", "diagonal_compression", "--param", "E_b=6000:18000",
                                 "--n", str(2**20), "--seed", "0", "--store", str(store), "--workers", "1"])
    assert result.exit_code != 0
    assert re.search(r"this job is 1048576 FE runs of \d+ dofs \(about .* on one core\) and .* on disk: .*--yes",
                     " ".join(result.output.split()))
    assert not store.exists()


def test_snapshots_run_refuses_many_nonlinear_runs_without_yes(tmp_path):
    """4096 nonlinear runs (≈ 3.7 s each on one core) are hours of FE work though the store is small
    and the row count is far below the row limit: the question comes from the FE hours."""
    assert 4096 < limits.CONFIRM_ROWS
    result = runner.invoke(app, ["snapshots", "run", "--scenario", "diagonal_compression_nl", "--param",
                                 "E_b=6000:18000", "--n", "4096", "--seed", "0", "--store", str(tmp_path / "nl.h5")])
    assert result.exit_code != 0 and "4096 nonlinear FE runs" in result.output and "--yes" in result.output
    assert not (tmp_path / "nl.h5").exists()


def test_podkrig_run_refuses_a_huge_study_without_yes(tmp_path):
    """Before: `podkrig run` had no --yes and started 10⁵ FE runs without a question."""
    study = _study(tmp_path, [("train    = { n = 256", "train    = { n = 100000")])
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", str(study), "--out", str(out)])
    text = " ".join(result.output.split())
    assert result.exit_code != 0 and "this job is 100105 FE runs" in text and "--yes" in text
    assert not out.exists()  # nothing written


def test_study_fe_work_counts_only_missing_runs(tmp_path, coarse_diagonal):
    """A rerun asks about the runs still to do, not the finished ones."""
    from podkrig.offline.runner import run_snapshots
    from podkrig.parameters import ParameterSpace
    from podkrig.study import stages
    from podkrig.study.pipeline import Progress

    study = load_study(_study(tmp_path, [("nx = 6", "nx = 2"), ("ny = 2", "ny = 1"),
                                         ("train    = { n = 256", "train    = { n = 8")]))
    run = stages.StudyRun(study, tmp_path / "out", Progress())
    assert stages.fe_work(run)[0].startswith("113 FE runs")  # 9 probe + 8 + 32 held out + 64 validation
    space = ParameterSpace.from_dict(study.space.to_dict())
    run_snapshots(tmp_path / "out" / "train.h5", study.spec, space, n=8, seed=0, workers=1)
    assert stages.fe_work(run)[0].startswith("105 FE runs")
