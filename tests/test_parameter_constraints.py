"""Constraints between parameters: stated by each scenario, checked over a whole sampling box before
any FE run (library, ``snapshots run``, ``podkrig run``, ``simulate --set``), with a remedy that
makes the box admissible; ``podkrig scenarios`` lists them, in plain text."""

import itertools
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from fe.admissibility import Inequality, ParameterConstraint, check_box
from fe.exceptions import ConstraintError, SpecError
from fe.scenarios import SCENARIOS, ParameterInfo, build_scenario
from fe.scenarios.catalogue import describe_scenario
from fe.scenarios.nonlinear import interface_properties
from podkrig.cli import app
from podkrig.offline.runner import run_snapshots
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.study import StudyError, load_study

#: the coarse triplet (2 × 1 elements per unit, two levels): a nonlinear run of ~0.01 s CPU
TRIPLET = {"scenario": "triplet_shear", "nx": 2, "ny": 1, "load_levels": [0.01, 0.05],
           "parameters": {"ft_bj": 0.25}}
RST = re.compile(r"``|:[a-z]+:`|\*\*|(?<![\w`])`[^`\s][^`]*`")


def _triplet():
    return build_scenario(TRIPLET)


def _apply(remedy, bounds, scenario_spec):
    """Bounds and spec with one remedy applied (the way a user edits the study)."""
    bounds, fixed = dict(bounds), dict(scenario_spec["parameters"])
    if remedy.kind in ("at_most", "at_least"):
        fixed[remedy.parameter] = remedy.value
    else:
        lo, hi, scale = bounds[remedy.parameter]
        bounds[remedy.parameter] = (remedy.value, hi, scale) if remedy.kind == "lower" else (lo, remedy.value, scale)
    return bounds, {**scenario_spec, "parameters": fixed}


def test_the_triplet_box_is_refused_before_any_fe_run(tmp_path, count_fe_runs):
    space = ParameterSpace((Parameter("c_bj", 0.1, 0.6, unit="MPa"),))  # built past from_scenario's check
    with count_fe_runs() as counter:
        with pytest.raises(ConstraintError, match=r"ft_bj ≤ c_bj / max\(tanphi_bj, tanphir_bj\)") as info:
            run_snapshots(tmp_path / "s.h5", _triplet(), space, n=8, seed=0, workers=1)
    assert counter.calls == 0
    assert not (tmp_path / "s.h5").exists()
    text = str(info.value)
    # the worst corner (c_bj at its lower bound, ft_bj at its fixed value) and the remedies, in the unit
    for fragment in ("c_bj = 0.1 MPa", "ft_bj = 0.25 MPa", "raise c_bj's lower bound to 0.19 MPa",
                     "set ft_bj to at most 0.13 MPa"):
        assert fragment in text


def test_every_remedy_makes_the_box_admissible_and_is_tight():
    sc = _triplet()
    bounds = {"c_bj": (0.1, 0.6, "linear"), "ft_bj": (0.1, 0.3, "linear")}
    with pytest.raises(ConstraintError) as info:
        sc.check_box(bounds)
    (violation,) = info.value.violations
    remedies = {r.parameter: r for r in violation.remedies}
    assert {(r.parameter, r.kind) for r in remedies.values()} >= {("c_bj", "lower"), ("ft_bj", "upper")}
    # closed form at the worst corner (ft_bj = 0.3, c_bj = 0.1): c ≥ ft tanφ = 0.225, ft ≤ c/tanφ = 0.1333;
    # rounded to two significant digits on the safe side
    assert 0.225 <= remedies["c_bj"].value <= 0.23
    assert 0.13 <= remedies["ft_bj"].value <= 0.1 / 0.75
    for r in violation.remedies:
        new_bounds, spec = _apply(r, bounds, TRIPLET)
        build_scenario(spec).check_box(new_bounds)  # passes
        space = ParameterSpace.from_scenario(build_scenario(spec), new_bounds)  # the offline door, too
        assert space.names == ("c_bj", "ft_bj")


def test_a_log_scaled_stiffness_box_gets_its_remedy():
    """kN_bj sampled log-uniformly from 0.5 N/mm³: the bed joints' tension snap-back
    ft_bj²/GfI_bj < kN_bj (3.47 N/mm³ at Set A) fails at the lower corner; the head joints'
    r_hj·kN_bj too."""
    sc = _triplet()
    bounds = {"kN_bj": (0.5, 100.0, "log")}
    with pytest.raises(ConstraintError, match=r"ft_bj² / GfI_bj < kN_bj.*kN_bj = 0.5 N/mm³") as info:
        ParameterSpace.from_scenario(sc, bounds)
    threshold = 0.25**2 / 0.018
    for violation in info.value.violations:
        (kn,) = [r for r in violation.remedies if r.parameter == "kN_bj"]
        assert kn.kind == "lower" and threshold < kn.value <= 3.5
        new_bounds, spec = _apply(kn, bounds, TRIPLET)
        space = ParameterSpace.from_scenario(build_scenario(spec), new_bounds)
        assert space.scales == ("log",)


def test_an_admissible_box_passes_and_runs(tmp_path, count_fe_runs):
    space = ParameterSpace.from_scenario(_triplet(), {"c_bj": (0.2, 0.6), "ft_bj": (0.05, 0.15)})
    with count_fe_runs() as counter:
        summary = run_snapshots(tmp_path / "s.h5", _triplet(), space, n=2, seed=0, workers=1)
    assert summary.done == 2 and counter.calls == 2  # the counter sees nonlinear runs


@pytest.mark.parametrize("law", [{}, {"law": "hyperbolic"}, {"law": "hyperbolic", "hyperbolic_cap": "ellipse"}])
def test_the_constraints_are_the_fe_runs_check(law):
    """One definition: at random parameter sets around the boundaries, the scenario's constraints
    hold exactly where building the run's interface properties succeeds."""
    sc = build_scenario({**TRIPLET, **law})
    rng = np.random.default_rng(0)
    names = {"ft_bj": (0.05, 0.6), "c_bj": (0.05, 0.6), "tanphi_bj": (0.0, 1.2), "tanphir_bj": (0.0, 1.2),
             "tanpsi_bj": (0.0, 1.0), "GfI_bj": (0.001, 0.03), "GfII_bj": (0.001, 0.2), "kN_bj": (0.5, 50.0),
             "kV_bj": (0.5, 50.0), "r_hj": (0.2, 2.0), "ft_bb": (1.0, 30.0), "Gfc": (0.5, 20.0)}
    seen = set()
    for _ in range(400):
        values = {**{k: p.default for k, p in sc.parameters.items()},
                  **{k: float(rng.uniform(*b)) for k, b in names.items()}}
        admissible = all(c.evaluate(values)[0] for c in sc.constraints)
        try:
            props = interface_properties(sc.mesh, sc.model.interface_elements, values, sc.model.n_points_per_element)
            if law.get("law") == "hyperbolic":
                sc._hyperbolic_law(values, props)
            built = True
        except SpecError:
            built = False
        assert admissible == built, values
        seen.add(admissible)
    assert seen == {True, False}


def test_the_vertex_check_is_exact_for_monotone_constraints():
    """Random boxes over four parameters: the box passes iff every point of a 6^4 grid passes."""
    sc = _triplet()
    rng = np.random.default_rng(1)
    ranges = {"ft_bj": (0.05, 0.5), "c_bj": (0.05, 0.5), "tanphi_bj": (0.3, 1.2), "GfI_bj": (0.002, 0.03)}
    outcomes = set()
    for _ in range(40):
        bounds = {k: tuple(sorted(rng.uniform(*r, 2))) for k, r in ranges.items()}
        grid = [np.linspace(*bounds[k], 6) for k in bounds]
        values = {k: p.default for k, p in sc.parameters.items()}
        dense = all(c.evaluate({**values, **dict(zip(bounds, x))})[0]
                    for x in itertools.product(*grid) for c in sc.constraints)
        try:
            sc.check_box(bounds)
            vertex = True
        except ConstraintError:
            vertex = False
        assert vertex == dense, bounds
        outcomes.add(vertex)
    assert outcomes == {True, False}


def test_a_constraint_that_is_not_monotone_is_checked_on_a_grid():
    """(x − 1)² ≥ 0.01 holds at both ends of [0.5, 1.5] and fails inside: the dense check finds it."""
    dip = Inequality("dip", "0.01", "({x} − 1)²", "-", "a made-up dip", lambda p: 0.01,
                     lambda p: (p["x"] - 1.0) ** 2, monotone=False)
    constraint = ParameterConstraint(dip, "a test", {"x": ("x",)})
    info = {"x": ParameterInfo("x", 0.5, "-", 0.0, 10.0, "a parameter")}
    with pytest.raises(ConstraintError, match=r"grid points of the sampling box \(not monotone\): x = 0.99") as err:
        check_box([constraint], info, {"x": (0.5, 1.5)})
    assert err.value.violations[0].grid_points >= 1000
    check_box([constraint], info, {"x": (1.2, 1.5)})  # away from the dip: passes


def test_a_study_with_the_triplet_box_is_refused_at_its_line(tmp_path, count_fe_runs):
    (tmp_path / "m.csv").write_text("load,middle_ux,V_top\n0.01,0.01,0.0\n", encoding="utf-8")
    study = tmp_path / "study.toml"
    study.write_text(
        '[scenario]\nscenario = "triplet_shear"\nnx = 2\nny = 1\n\n'
        '[parameters]\nkN_bj = { lower = 10.0, upper = 1000.0, scale = "log" }\n'
        'c_bj = { lower = 0.1, upper = 0.6 }\n\n'
        '[fixed]\nft_bj = 0.25\n\n'
        '[sampling]\ntrain = { n = 8, seed = 0 }\nheld_out = { n = 4, seed = 1 }\n\n'
        '[measurement]\nfile = "m.csv"\nnoise_abs = 0.001\n', encoding="utf-8")
    with pytest.raises(StudyError, match=r"line 8: parameters.c_bj: .*raise c_bj's lower bound to 0.19 MPa"):
        load_study(study)
    with count_fe_runs() as counter:
        result = CliRunner().invoke(app, ["run", str(study), "--out", str(tmp_path / "out"), "--yes"])
    assert result.exit_code == 2 and counter.calls == 0
    assert "ft_bj ≤ c_bj / max(tanphi_bj, tanphir_bj)" in result.output


def test_snapshots_run_and_simulate_refuse_before_any_fe_run(tmp_path, count_fe_runs):
    runner = CliRunner()
    with count_fe_runs() as counter:
        snap = runner.invoke(app, ["snapshots", "run", "--scenario", "triplet_shear", "--param", "c_bj=0.1:0.6",
                                   "--param", "ft_bj=0.1:0.3", "--n", "4", "--seed", "0",
                                   "--store", str(tmp_path / "s.h5"), "--workers", "1"])
        sim = runner.invoke(app, ["simulate", "triplet_shear", "--set", "ft_bj=0.6"])
    assert counter.calls == 0
    assert snap.exit_code == 2 and "lower ft_bj's upper bound to 0.13 MPa" in snap.output
    assert not (tmp_path / "s.h5").exists()
    assert sim.exit_code == 2
    assert "ft_bj = 0.6 MPa" in sim.output and "set ft_bj to at most 0.46 MPa" in sim.output


def test_podkrig_scenarios_lists_the_constraints():
    result = CliRunner().invoke(app, ["scenarios", "triplet_shear"], env={"COLUMNS": "250"})
    assert result.exit_code == 0
    assert "ft_bj ≤ c_bj / max(tanphi_bj, tanphir_bj)" in result.output
    assert "Coulomb friction surface also limits tension" in result.output
    d = describe_scenario("triplet_shear").to_dict()
    (apex,) = [c for c in d["constraints"] if c["formula"].startswith("ft_bj ≤")]
    assert apex["unit"] == "MPa" and apex["where"] == "bed and head joints"
    linear = CliRunner().invoke(app, ["scenarios", "diagonal_compression"], env={"COLUMNS": "250"})
    assert "constraints between parameters: none" in linear.output


def test_scenario_listing_is_plain_text_and_says_what_each_test_is():
    runner = CliRunner()
    outputs = [runner.invoke(app, ["scenarios"], env={"COLUMNS": "300"})]
    outputs += [runner.invoke(app, ["scenarios", name], env={"COLUMNS": "300"}) for name in SCENARIOS]
    for out in outputs:
        assert out.exit_code == 0
        assert not RST.search(out.output), RST.search(out.output).group(0)
    summaries = {name: describe_scenario(name).summary for name in SCENARIOS}
    assert len(set(summaries.values())) == len(summaries)
    for name, words in {"prism_compression": "prism", "couplet_tension": "tension", "triplet_shear": "shear",
                        "flat_jack": "flat-jack", "diagonal_compression_nl": "failure"}.items():
        assert words in summaries[name].lower()
    assert "couplet" not in summaries["prism_compression"].lower()


JOINT = """
[parameters]
c_bj = { lower = 0.3, upper = 0.6 }

[fixed]
ft_bj = 0.25

[sampling]
train = { n = 8, seed = 0 }
held_out = { n = 4, seed = 1 }

[[test]]
name = "triplet"
scenario = { scenario = "triplet_shear", nx = 2, ny = 1 }
measurement = { file = "t.csv", noise_abs = 0.001 }

[[test]]
name = "couplet"
scenario = { scenario = "couplet_tension", nx = 2, ny = 1 }
measurement = { file = "c.csv", noise_abs = 0.001 }
fixed = { ft_bj = 0.3 }
parameters = { tanphi_bj = { lower = 0.5, upper = 1.2 } }
"""

VALIDATION = """
[scenario]
scenario = "couplet_tension"
nx = 2
ny = 1

[parameters]
c_bj = { lower = 0.3, upper = 0.6 }

[sampling]
train = { n = 8, seed = 0 }
held_out = { n = 4, seed = 1 }

[measurement]
file = "c.csv"
noise_abs = 0.001

[[validation]]
name = "tri"
scenario = { scenario = "triplet_shear", nx = 2, ny = 1, parameters = { ft_bj = 0.5 } }
n = 4
seed = 2
"""


@pytest.mark.parametrize("text, fragments", [
    # the couplet test's own ft_bj = 0.3 MPa and tanphi_bj up to 1.2: c ≥ 0.36 MPa (the triplet's box passes)
    (JOINT, ("line 3: parameters.c_bj", "test 'couplet'", "tanphi_bj = 1.2", "raise c_bj's lower bound to 0.36 MPa")),
    # the validation model's ft_bj = 0.5 MPa over the calibrated c_bj box: c ≥ 0.375 MPa
    (VALIDATION, ("validation[1].scenario", "validation model 'tri'", "raise c_bj's lower bound to 0.38 MPa")),
])
def test_joint_tests_and_validation_models_are_checked_over_their_boxes(tmp_path, text, fragments):
    (tmp_path / "t.csv").write_text("load,middle_ux,V_top\n0.01,0.01,0.0\n", encoding="utf-8")
    (tmp_path / "c.csv").write_text("load,joint_opening,top_uy\n0.01,0.01,0.0\n", encoding="utf-8")
    (tmp_path / "study.toml").write_text(text, encoding="utf-8")
    with pytest.raises(StudyError, match=re.escape(fragments[0])) as info:
        load_study(tmp_path / "study.toml")
    for fragment in fragments[1:]:
        assert fragment in str(info.value)
