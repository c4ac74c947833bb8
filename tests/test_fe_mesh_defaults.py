"""Default meshes and control ranges of the nonlinear scenarios (scripts/mesh_convergence.py).

Which mesh the convergence data justify is recorded in BENCHMARKS.md; here: the confined wall's
default control range ends where its curve is mesh-objective and a response past it says so, and a
coarse default mesh gives the peak of a fine one.
"""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import load_file
from fe.exceptions import ConstraintError, SpecError
from fe.interfaces import CompositeInterface
from fe.scenarios import build_scenario
from fe.scenarios.walls_nonlinear import MESH_OBJECTIVE_LIMITS
from podkrig.cli import app

COARSE = {"scenario": "shear_compression_nl", "nx": 2, "ny": 1}


def test_confined_wall_defaults_to_its_mesh_objective_range_and_full_range_is_flagged():
    """Top fixed: the default levels end at the mesh-objective limit and the response says it is
    mesh-objective; ``control_range = "full"`` goes to 3 mm and the response (and its summary)
    says it is not. Under constant N the whole 3 mm is the default and objective. (A two-increment
    budget keeps the runs short: the flag depends on the levels asked for, not on how far a run got.)"""
    limit = MESH_OBJECTIVE_LIMITS["fixed_vertical"]
    default = build_scenario(dict(COARSE, max_steps=2))
    assert default.load_levels[-1] == limit and default.options.control_range == "mesh_objective"
    r = default.run()
    assert r.mesh_objective and r.summary()["mesh_objective"] is True
    full = build_scenario(dict(COARSE, max_steps=2, control_range="full"))
    assert full.load_levels[-1] == 3.0
    r = full.run()
    assert not r.mesh_objective
    assert r.summary()["mesh_objective"] is False and r.summary()["mesh_objective_limit"] == limit
    # explicit levels past the limit are flagged the same way
    assert not build_scenario(dict(COARSE, max_steps=2, load_levels=[0.5, 2.0])).run().mesh_objective
    constant = build_scenario(dict(COARSE, top="constant_force", max_steps=2))
    assert constant.load_levels[-1] == 3.0 and constant.run().mesh_objective


def test_control_range_is_validated():
    with pytest.raises(SpecError, match="control_range.*'mesh_objective'.*'most'"):
        build_scenario(dict(COARSE, control_range="most"))


def test_simulate_says_when_the_range_is_not_mesh_objective():
    """``podkrig simulate`` prints the limit past which the readings depend on the mesh, and its
    JSON output carries the flag; the default range prints no such line."""
    runner = CliRunner()
    args = ["simulate", "shear_compression_nl", "--option", "nx=2", "--option", "ny=1", "--option", "max_steps=2"]
    full = runner.invoke(app, args + ["--option", "control_range=full"])
    assert "not mesh-objective past 1.75 mm" in full.output
    default = runner.invoke(app, args)
    assert "mesh-objective" not in default.output
    out = json.loads(runner.invoke(app, args + ["--option", "control_range=full", "--format", "json"]).stdout)
    assert out["mesh_objective"] is False and out["mesh_objective_limit"] == 1.75


def test_triplet_default_mesh_gives_the_peak_and_curve_of_a_fine_mesh():
    """The triplet's default mesh (Q8 4 × 1 per unit, 101 dofs) against Q8 12 × 4 (955 dofs), same
    increments: peak within 1 % (the criterion of the default; measured 0.06 %), loads at every
    level within 1 % of the fine mesh's peak."""
    coarse = build_scenario("triplet_shear")
    fine = build_scenario({"scenario": "triplet_shear", "nx": 12, "ny": 4})
    assert coarse.n_dofs < fine.n_dofs / 9
    rc, rf = coarse.run(), fine.run()
    assert rc.peak_load == pytest.approx(rf.peak_load, rel=0.01)
    assert np.max(np.abs(rc.loads - rf.loads)) <= 0.01 * rf.peak_load


def test_a_runaway_newton_iterate_is_cut_back_before_the_law_is_evaluated_there(monkeypatch):
    """J4D (Q8 4 × 2 per unit, top fixed): near 1.2 mm one increment's Newton iterates run away (interface
    jumps of 10–600 mm, where the law sub-steps at many points and an update costs up to 70 ms
    against 2 ms). With ``divergence_factor`` (default 100) the increment is cut back before the
    law sees such an iterate: the largest jump increment the law is asked for stays below 20 mm, on
    the same path (same peak to 1e-9, same failed increments). Without it (0) the law is evaluated
    at a jump above 100 mm."""
    seen = []

    class Recording(CompositeInterface):
        def update(self, du, state):
            seen.append(float(np.abs(du).max()))
            return super().update(du, state)

    monkeypatch.setattr("fe.scenarios.nonlinear.CompositeInterface", Recording)
    sc = build_scenario({"scenario": "shear_compression_nl", "nx": 4, "ny": 2})
    runs = {}
    for factor in (100.0, 0.0):
        seen.clear()
        r = sc.run(settings=dataclasses.replace(sc.options.path_settings(), divergence_factor=factor))
        runs[factor] = (r, max(seen))
    (guarded, guarded_jump), (free, free_jump) = runs[100.0], runs[0.0]
    assert guarded.converged and free.converged
    assert guarded_jump < 20.0 < 100.0 < free_jump
    assert guarded.peak_load == pytest.approx(free.peak_load, rel=1e-9)
    assert guarded.path.failed_steps == free.path.failed_steps


def test_snapshot_benchmark_box_is_the_widest_equal_spread_the_wall_admits():
    """``scripts/bench_nonlinear_snapshots.py`` samples the eight parameters over Set A ± 20 %: a box
    the scenario admits (f_t ≤ c / tanφ at every corner); ± 30 % is refused naming the inequality."""
    bench = load_file(Path(__file__).resolve().parents[1] / "scripts" / "bench_nonlinear_snapshots.py")
    sc = build_scenario("shear_compression_nl")
    space = bench.space_around_defaults(sc, 0.2)
    assert space.names == bench.PARAMETERS
    with pytest.raises(ConstraintError, match="ft_bj.*c_bj.*tanphi_bj"):
        bench.space_around_defaults(sc, 0.3)
