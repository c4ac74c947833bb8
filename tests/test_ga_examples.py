"""The GA example and benchmark scripts: importable without side effects, --help, small runs."""

import pathlib

import numpy as np
import pytest

from conftest import load_file

SCRIPTS = pathlib.Path(__file__).resolve().parents[1] / "scripts"
NAMES = ["example_ga_rastrigin", "example_ga_tmd", "example_ga_constrained", "bench_ga"]

pytest.importorskip("matplotlib")


def load_script(name):
    """Import ``scripts/<name>.py`` as a module (scripts/ is not a package)."""
    return load_file(SCRIPTS / f"{name}.py")


@pytest.mark.parametrize("name", NAMES)
def test_import_has_no_side_effects_and_help_works(name, capsys):
    module = load_script(name)
    assert capsys.readouterr().out == ""
    with pytest.raises(SystemExit) as exit_info:
        module.main(["--help"])
    assert exit_info.value.code == 0
    assert "usage:" in capsys.readouterr().out


def test_rastrigin_example(tmp_path, capsys):
    module = load_script("example_ga_rastrigin")
    # 10-D is solved in test_ga.py; here 5-D keeps the figure drawing short
    results = module.main(["--dims", "2", "5", "--seed", "1", "--out", str(tmp_path)])
    for d, res in results.items():
        assert res.success and res.fun <= 1e-2 and res.x.shape == (d,)
        assert (tmp_path / f"rastrigin_{d}d_history.png").stat().st_size > 0
        assert (tmp_path / f"rastrigin_{d}d_parameters.png").stat().st_size > 0
    assert "Rastrigin 5-D" in capsys.readouterr().out


def test_tmd_example(tmp_path):
    module = load_script("example_ga_tmd")
    res = module.main(["--mu", "0.02", "--max-evaluations", "2000", "--out", str(tmp_path)])
    f_dh, z_dh = module.den_hartog(0.02)
    peak_dh = module.peak_amplification(np.array([[f_dh, z_dh]]), 0.02)[0]
    assert res.fun <= 1.005 * peak_dh  # see test_ga.py: Den Hartog is approximate
    for name in ("tmd_history.png", "tmd_parameters.png", "tmd_response.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_constrained_example(tmp_path):
    module = load_script("example_ga_constrained")
    res = module.main(["--constraint-handling", "penalty", "--out", str(tmp_path)])
    x_opt, _ = module.analytical_optimum()
    # active-set accuracy of the SLSQP polish within feasibility_tol (see test_ga.py)
    np.testing.assert_allclose(res.x, x_opt, rtol=0.0, atol=1e-5)
    assert (tmp_path / "constrained_history.png").stat().st_size > 0


def test_benchmark_runs_on_a_tiny_budget(capsys):
    module = load_script("bench_ga")
    rows = module.main(["--quick", "--seeds", "1", "--solvers", "podkrig GA"])
    out = capsys.readouterr().out
    assert len(rows) == 3 and "| podkrig GA | 1/1 |" in rows[0]
    assert "GA overhead per generation" in out and "threadpoolctl" in out


def test_inversion_problem_optimum_is_a_least_squares_minimum():
    module = load_script("bench_ga")
    space, misfit, x_ls = module.make_inversion_problem()
    U = space.to_unit(x_ls)[None] + 1e-4 * np.eye(4)
    # a small step in any direction from the optimum increases the misfit
    assert np.all(misfit(space.from_unit(U)) > misfit(x_ls[None]))
