"""The flat-jack shear test run nonlinearly (``flat_jack_shear_nl``): elastic phases, equilibrium of
the block, the critical jack pressure against the statics of the reference scenario, monotonicity,
the repeats 3' and the command line."""

import dataclasses
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from fe.exceptions import SpecError
from fe.scenarios import build_scenario
from fe.scenarios.catalogue import describe_scenario
from fe.solvers.nonlinear import PathSettings
from podkrig.cli import app

#: joints that never leave the elastic range at the jack pressures of phases 0a–2 (strengths ≫ 1 MPa)
ELASTIC_JOINTS = {"ft_bj": 20.0, "c_bj": 30.0, "GfI_bj": 100.0, "GfII_bj": 100.0}


def _scenario(**options):
    return build_scenario({"scenario": "flat_jack_shear_nl", **options})


@pytest.fixture(scope="module")
def runs():
    """Critical pressures of fresh runs keyed by (p_H, c_bj, σ0), cached for the module."""
    cache = {}

    def get(p_H, c=0.25, sigma0=0.30):
        if (p_H, c, sigma0) not in cache:
            sc = _scenario(p_H=p_H)
            params = {"c_bj": c, "sigma0": sigma0}
            r = sc.run(params)
            assert r.converged, r.message
            cache[p_H, c, sigma0] = sc.critical_pressures(r, params)[0]
        return cache[p_H, c, sigma0]

    return get


def test_elastic_phases_equal_the_linear_scenarios_readings():
    """With joints that stay elastic, the readings of steps 0b–2 (gauges zeroed before the cut) are
    those of the linear ``flat_jack`` at the same parameters: the nonlinear path starts from the uncut
    panel's uniform state and cuts the slots by releasing their traction, the linear scenario
    superposes the same loads (relative to the largest reading; the Newton steps of a linear problem
    are exact to round-off)."""
    sc = _scenario(load_levels=[0.002])
    r = sc.run(ELASTIC_JOINTS)
    linear = build_scenario({"scenario": "flat_jack", "phases": ["0b", "1", "2"]}).run()
    got = sc.step_readings(r)
    assert got.shape == linear.readings.shape == (20, 18)
    scale = np.abs(linear.readings).max()
    np.testing.assert_allclose(got, linear.readings, rtol=0, atol=1e-9 * scale)
    assert [s.pressures for s in sc.steps] == [s.pressures for s in sc.linear.steps]


def test_default_joints_crack_before_phase_3():
    """At the default strengths (f_t = 0.15 MPa) the phases before the shear phase are not quite
    elastic: head joints beside the cut crack when the slot is cut, and the bed joint beyond the H
    jack's ends opens from p_H ≈ 0.8 MPa. The readings stay within 3 µm of the linear ones up to
    p_H = 0.7 MPa and depart by more than 10 µm at p_H = 1.0 (docs/nonlinear.md)."""
    sc = _scenario(load_levels=[0.002])
    r = sc.run()
    linear = build_scenario({"scenario": "flat_jack", "phases": ["0b", "1", "2"]}).run()
    diff = np.abs(sc.step_readings(r) - linear.readings).max(axis=1)
    p_H = np.array([s.pressures["H"] for s in sc.steps])
    assert diff[p_H <= 0.7 + 1e-9].max() < 3e-3
    assert diff[10] > 10e-3 and p_H[10] == 1.0


def _checked_phases(sc, values, follower, slips, seen):
    """The scenario's phases with phase 3 split at ``slips`` (the same path), recording in ``seen``
    after each phase the top joint's forces and the jacks' forces on the block."""
    steps = {f"{s.phase}:{k}": s.pressures for k, s in enumerate(sc.steps, start=1)}
    for phase in sc.phases(values, follower):
        if phase.name != "3":
            yield phase
            if phase.name in steps:
                seen[phase.name] = (sc.top_joint_forces(follower), sc.jack_forces(values, steps[phase.name]))
            continue
        for s in slips:
            yield dataclasses.replace(phase, name=f"3@{s:g}", target=s, levels=(s,))
            pressures = dict(sc.steps[-1].pressures, V1=follower.lam)
            seen[f"3@{s:g}"] = (sc.top_joint_forces(follower), sc.jack_forces(values, pressures))
        return


def test_block_equilibrium_jack_forces_against_the_top_joint():
    """At the end of the cut, of phases 1 and 2, and before, at and after the peak of phase 3, the
    block's top joint carries what the jacks push: normal force Km p_H L_H t and shear
    Km (p_V1 − p_V2) h_V t (N), to the Newton tolerance (1e-3 of the force norm, a few N here)."""
    sc = _scenario()
    values = sc.resolve()
    follower = sc.path_follower(values)
    checked = {}
    path = follower.run(_checked_phases(sc, values, follower, (0.01, 0.12, 0.3), checked))
    assert path.status == "converged", path.message
    for name in ("0b:1", "1:11", "2:20", "3@0.01", "3@0.12", "3@0.3"):
        (N, T), (N_jack, T_jack) = checked[name]
        assert N == pytest.approx(N_jack, abs=5.0), name  # N_jack = 0.85 · 1 · 390 · 120 ≈ 39.8 kN
        assert T == pytest.approx(T_jack, abs=5.0), name  # T_jack ≤ 0.85 · 1.8 · 195 · 120 ≈ 35.8 kN
    assert checked["3@0.12"][1][1] > 20e3  # the shear is really carried (near the peak)


@pytest.mark.slow
def test_critical_pressure_against_the_statics_estimate_at_three_p_H(runs):
    """Δp_V,crit of the refined peak lies within 25 % of the statics estimate
    (L_H/h_V)(c + Km p_H tanφ)/Km of the reference scenario at p_H = 0.5 and 1.5 MPa (the estimate
    is an average; the shear concentrated at the block's corners makes sliding progressive, so the
    FE value lies below it). At σ0 = 0.3 MPa, p_H = 1.5 lifts the wall above the block off its
    neighbours and the wall beside V1 slides first (docs/nonlinear.md), so p_H = 1.5 is checked
    at σ0 = 0.6 MPa."""
    for p_H, sigma0 in ((0.5, 0.30), (1.0, 0.30), (1.5, 0.60)):
        crit = runs(p_H, sigma0=sigma0)
        assert crit.resolved
        assert crit.statics == pytest.approx(2 * (0.25 + 0.85 * p_H * 0.70) / 0.85)
        assert 0.75 <= crit.ratio <= 1.25, (p_H, crit)


@pytest.mark.slow
def test_critical_pressure_grows_with_p_H_and_with_cohesion(runs):
    low, high = runs(0.5), runs(1.0)
    assert low.delta_p_V < high.delta_p_V
    assert runs(0.5, c=0.35).delta_p_V > low.delta_p_V


@pytest.mark.slow
def test_repeat_at_a_further_p_H_slides_on_the_damaged_joint(runs):
    """3': after phase 3 (to 0.5 mm of slip) V1 is unloaded and H set to 0.5 MPa; the second slide
    of the same joint peaks below a fresh joint's at that p_H (cohesion partly spent) and above
    friction alone, 2 Km p_H tanφr / Km."""
    sc = _scenario(further_p_H=[0.5])
    r = sc.run()
    assert r.converged, r.message
    first, repeat = sc.critical_pressures(r)
    assert first.phase == "3" and repeat.phase == "3'(p_H=0.5)" and repeat.p_H == 0.5
    assert 2 * 0.5 * 0.70 < repeat.delta_p_V < runs(0.5).delta_p_V
    curve = r.extra["p_V1(p_H=0.5)"]
    assert curve.shape == r.loads.shape and np.isfinite(curve).all()
    assert np.nanmax(curve) <= repeat.p_V1 + 1e-9


def test_defaults_and_options_in_the_catalogue():
    d = describe_scenario("flat_jack_shear_nl")
    defaults = {p.name: p.default for p in d.parameters}
    assert {k: defaults[k] for k in ("E_b", "kN_bj", "kV_bj", "r_hj", "ft_bj", "c_bj", "tanphi_bj", "GfII_bj",
                                     "Km", "sigma0")} == {
        "E_b": 10000.0, "kN_bj": 80.0, "kV_bj": 35.0, "r_hj": 0.6, "ft_bj": 0.15, "c_bj": 0.25, "tanphi_bj": 0.70,
        "GfII_bj": 0.10, "Km": 0.85, "sigma0": 0.30}
    assert d.options["p_H"] == 1.0 and d.options["p_V2"] == 0.5 and d.options["further_p_H"] == ()
    assert d.load_unit == "mm" and d.options["max_cpu_seconds"] > 0


@pytest.mark.parametrize("option, value, fragments", [
    ("p_H", 7.0, ("p_H", "MPa", "5")),
    ("p_V2", 0.0, ("p_V2", "MPa")),
    ("further_p_H", [0.5, -1.0], ("further_p_H", "MPa")),
    ("layout", "standard", ("layout", "L18")),
])
def test_options_are_checked(option, value, fragments):
    with pytest.raises(SpecError, match="flat_jack_shear_nl") as e:
        _scenario(**{option: value})
    for fragment in fragments:
        assert fragment in str(e.value)


def test_budget_ends_the_run_and_names_its_limit():
    sc = _scenario()
    r = sc.run(settings=PathSettings(max_total_iterations=30))
    assert r.status == "budget_exhausted" and r.limit == "iterations"
    assert np.isnan(r.loads).all()


@pytest.mark.slow
def test_podkrig_simulate_runs_the_shear_phase_end_to_end():
    runner = CliRunner()
    result = runner.invoke(app, ["simulate", "flat_jack_shear_nl", "--option", "p_H=0.5", "--format", "json"])
    assert result.exit_code == 0, result.output[-2000:]
    out = json.loads(result.output)
    assert out["status"] == "converged" and out["force_unit"] == "MPa"
    assert out["options"]["p_H"] == 0.5
    peak = out["peak_load"]
    assert 0.5 + 0.75 * 2 * (0.25 + 0.85 * 0.5 * 0.7) / 0.85 < peak  # the statics check of the test above
    assert len(out["delta_p_V"]) == len(out["load_levels"])
    assert out["solver"]["peaks"]["3"]["resolved"]


def test_the_two_logs_of_the_test_read_the_elastic_steps_and_the_jack_pressures():
    """The elastic record ``flat_jack_elastic_nl`` is the shear scenario's phases 0b–2, gauge by
    gauge at steps 1–20 (the same path: equal to round-off); the shear record reads V1's gauge
    pressure ``p_V1`` at each slip level (its load) and the repeat's as ``p_V1_repeat1`` (the extra
    output of the repeat), in MPa; the elastic record refuses the repeats it does not run."""
    shear = _scenario(further_p_H=[0.5], load_levels=[0.05, 0.2])
    r = shear.run()
    elastic = build_scenario({"scenario": "flat_jack_elastic_nl"})
    e = elastic.run()
    assert e.converged and e.readings.shape == (20, 18) and elastic.load_unit == "step"
    np.testing.assert_array_equal(e.load_levels, np.arange(1, 21))
    np.testing.assert_allclose(e.readings, shear.step_readings(r), rtol=0, atol=1e-12)
    assert shear.sensor_names[-2:] == ("p_V1", "p_V1_repeat1")
    assert shear.sensor_units["p_V1"] == shear.sensor_units["p_V1_repeat1"] == "MPa"
    np.testing.assert_array_equal(r.readings[:, -2], r.loads)
    np.testing.assert_array_equal(r.readings[:, -1], r.extra["p_V1(p_H=0.5)"])
    assert sorted(r.extra) == ["delta_p_V", "p_V1(p_H=0.5)"]
    assert 0.5 < r.readings[-1, -1] < r.readings[-1, -2]  # the repeat at the lower p_H slides at a lower p_V1
    with pytest.raises(SpecError, match="further_p_H"):
        build_scenario({"scenario": "flat_jack_elastic_nl", "further_p_H": [0.5]})
