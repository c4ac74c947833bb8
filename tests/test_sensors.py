"""Optimal sensor placement (podkrig.sensors): sensitivities, criteria, search, Monte Carlo, output.

A small diagonal-compression panel (390 × 390 mm, 6 courses of 1.5 units, coarse Q8 mesh) keeps
every FE step in milliseconds; the numerics are the same as on the full panel.
"""

import itertools
import json
import re
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import spearmanr
from typer.testing import CliRunner

from fe.scenarios import ScenarioSpec, build_scenario
from fe.scenarios.flat_jack import homogeneous_slot_spec
from fe.sensors import locate_points
from podkrig.cli import app
from podkrig.online.problem import FEModel
from podkrig.parameters import ParameterSpace
from podkrig.sensors.candidates import CandidateSet, Zone, dic_points, gauge_grid, user_candidates
from podkrig.sensors.criteria import (
    LayoutCriterion,
    SensorNoise,
    fisher_per_candidate,
    pod_per_candidate,
)
from podkrig.sensors.montecarlo import candidate_surrogate, monte_carlo
from podkrig.sensors.placement import place_sensors, spec_toml
from podkrig.sensors.search import PlacementProblem, choose_layout
from podkrig.sensors.sensitivity import (
    CandidateFEModel,
    ExactSensitivitiesUnavailable,
    candidate_sensitivities,
    model_sensitivities,
    prior_points,
)
from podkrig.sensors.settings import ComparisonSettings, PlacementSettings, SearchSettings
from podkrig.study import load_study

SMALL = {
    "scenario": "diagonal_compression", "n_courses": 6, "units_per_course": 1.5, "nx": 2, "ny": 1,
    "sensors": {"C": {"kind": "gauge", "p1": [100.0, 100.0], "p2": [290.0, 290.0]}},
}
GRID = np.arange(20.0, 390.0, 40.0)
BOUNDS = {"E_b": (5000, 20000), "kN_bj": (10, 1000, "log"), "kV_bj": (4, 400, "log"), "r_hj": (0.1, 1.0)}


def _job(*, n_random=20, **search):
    """Placement settings: the search's, and ``n_random`` random layouts to compare against."""
    return PlacementSettings(search=SearchSettings(**search), comparison=ComparisonSettings(n_random=n_random))


@pytest.fixture(scope="module")
def scenario():
    return build_scenario(SMALL)


@pytest.fixture(scope="module")
def space(scenario):
    return ParameterSpace.from_scenario(scenario, BOUNDS)


@pytest.fixture(scope="module")
def twenty(scenario):
    """20 gauges drawn (seeded) from the grid candidates."""
    cand = gauge_grid(scenario.mesh, GRID, GRID, lengths=(50, 160))
    return cand.subset(np.sort(np.random.default_rng(1).choice(len(cand), 20, replace=False)))


@pytest.fixture(scope="module")
def sens20(scenario, space, twenty):
    return candidate_sensitivities(scenario, space, twenty, prior_points(space, 16))


def test_gauge_grid_lengths_orientations_joints_and_zones(scenario):
    zone = Zone(150.0, 150.0, 250.0, 250.0)
    cand = gauge_grid(scenario.mesh, GRID, GRID, lengths=(50, 160), orientations=(0, 90), forbidden=[zone])
    assert len(cand) > 20
    for s in cand.sensors:
        d = np.subtract(s.p2, s.p1)
        assert 50 - 1e-9 <= s.length <= 160 + 1e-9
        assert abs(d[0]) < 1e-9 or abs(d[1]) < 1e-9  # horizontal or vertical only
        assert not zone.contains(s.points).any() and not zone.crossed_by(s.p1, s.p2)[0]
        locate_points(scenario.mesh, s.points)  # raises on a joint or outside
    # a grid line on a bed joint (y = 65 mm) gives no end point there
    on_joint = gauge_grid(scenario.mesh, GRID, [65.0, 70.0, 100.0], lengths=(30, 35), orientations=(90,))
    assert len(on_joint) and all(65.0 not in (s.p1[1], s.p2[1]) for s in on_joint.sensors)
    with pytest.raises(ValueError, match="no gauge of length"):
        gauge_grid(scenario.mesh, GRID, [65.0, 100.0], lengths=(30, 40), orientations=(90,))


def test_user_candidates_refuse_points_on_joints(scenario):
    with pytest.raises(ValueError, match="on a joint"):
        user_candidates(scenario.mesh, {"bad": {"kind": "gauge", "p1": [100.0, 65.0], "p2": [100.0, 120.0]}})
    ok = user_candidates(scenario.mesh, {"g": {"kind": "gauge", "p1": [100.0, 70.0], "p2": [100.0, 120.0], "cost": 3.0}})
    assert ok.cost.tolist() == [3.0] and ok.kinds == ("lvdt",)


def test_candidate_readings_and_sensitivities_match_scenario_run(scenario, space):
    """Readings of any candidate are the FE readings; sensitivities match central differences of
    full FE runs (tolerance 1e-5 relative: the difference step 1e-5 of the unit box gives O(1e-10)
    truncation, round-off of the differenced readings ~1e-11/1e-5 relative)."""
    cand = gauge_grid(scenario.mesh, GRID, GRID, lengths=(50, 160))
    cand = cand.subset([0, 17, 101, len(cand) - 1]) + dic_points(scenario.mesh, [210.0], [230.0])
    x = np.array([9000.0, 80.0, 30.0, 0.6])
    sens = candidate_sensitivities(scenario, space, cand, x[None])
    spec = dict(SMALL, sensors={s.name: s.to_dict() for s in cand.sensors})
    sc = build_scenario(spec)
    assert sc.sensor_names == sens.channel_names
    ref = sc.run(space.as_params(x)).readings
    np.testing.assert_allclose(sens.readings[0], ref, rtol=1e-10, atol=1e-14)
    u = space.to_unit(x[None])[0]
    h = 1e-5
    for j in range(space.n_params):
        up, um = u.copy(), u.copy()
        up[j] += h
        um[j] -= h
        fd = (sc.run(space.as_params(space.from_unit(up[None])[0])).readings
              - sc.run(space.as_params(space.from_unit(um[None])[0])).readings) / (2 * h)
        scale = np.abs(fd).max()
        np.testing.assert_allclose(sens.jacobian[0, :, :, j], fd, rtol=0, atol=1e-5 * scale)


def test_fisher_information_is_the_stacked_jacobian_product(sens20):
    """F_S + F_0 from per-candidate sums equals J_Sᵀ C⁻¹ J_S + F_0 built from the stacked Jacobian;
    Ψ_D, Ψ_A, Ψ_E are log det, trace of the inverse and smallest eigenvalue of it (rounding only)."""
    noise = SensorNoise(lvdt=0.001)
    F = fisher_per_candidate(sens20, noise)
    layout = np.array([3, 7, 11])
    ch = sens20.channels_of(layout)
    n = sens20.n_points
    J = sens20.jacobian[:, :, ch, :].reshape(n, -1, sens20.n_params) / 0.001
    ref = np.einsum("nij,nik->njk", J, J) + 12.0 * np.eye(4)
    values = {}
    for kind in ("d", "a", "e"):
        crit = LayoutCriterion(F, kind)
        np.testing.assert_allclose(crit.layout_information(layout[None])[0], ref, rtol=1e-12)
        values[kind] = crit.value(layout[None])[0]
    assert values["d"] == pytest.approx(np.mean(np.linalg.slogdet(ref)[1]), rel=1e-12)
    assert values["a"] == pytest.approx(np.mean(np.trace(np.linalg.inv(ref), axis1=1, axis2=2)), rel=1e-10)
    assert values["e"] == pytest.approx(np.mean(np.linalg.eigvalsh(ref)[:, 0]), rel=1e-10)
    # an empty slot (-1) adds nothing
    crit = LayoutCriterion(F, "d")
    assert crit.value([[3, 7, 11, -1]])[0] == pytest.approx(values["d"], rel=1e-14)


def test_pod_criterion_is_information_on_normalised_modal_amplitudes(sens20):
    """With every candidate chosen and K = all modes, the POD information is the covariance of the
    whitened snapshots projected on the modes: G = diag(s_k²/N) (modes orthonormal)."""
    noise = SensorNoise(lvdt=0.001)
    G, energy = pod_per_candidate(sens20, noise, n_modes=4)
    total = G[0].sum(axis=0)
    Y = (sens20.readings / 0.001).reshape(sens20.n_points, -1)
    s = np.linalg.svd(Y - Y.mean(axis=0), compute_uv=False)
    np.testing.assert_allclose(total, np.diag(s[:4] ** 2 / sens20.n_points), rtol=1e-9, atol=1e-9 * s[0] ** 2)
    assert 0 < energy <= 1


@pytest.mark.parametrize("kind", ["d", "a", "e", "pod"])
def test_search_finds_the_exhaustive_optimum_within_one_percent(sens20, twenty, kind):
    """Choose 4 of 20: every C(20, 4) = 4845 layout evaluated; the search (each start alone, and the
    GA alone) is within 1 % of the best criterion value."""
    noise = SensorNoise(lvdt=0.0005)
    info = pod_per_candidate(sens20, noise)[0] if kind == "pod" else fisher_per_candidate(sens20, noise)
    crit = LayoutCriterion(info, kind, 1.0 if kind == "pod" else 12.0)
    every = np.array(list(itertools.combinations(range(20), 4)))
    loss = crit.loss(every)
    best = crit.value(every[np.argmin(loss)][None])[0]
    for methods in (("greedy", "qr", "ga"), ("ga",)):
        found = choose_layout(PlacementProblem(crit, twenty, k=4), methods=methods, rng=3)
        assert abs(found.value - best) <= 0.01 * abs(best), (kind, methods, found.value, best)
        assert len(set(found.indices)) == 4


def test_constraints_spacing_must_include_budget_exclude(sens20, twenty):
    crit = LayoutCriterion(fisher_per_candidate(sens20, SensorNoise(lvdt=0.0005)), "d")
    centres = twenty.centres
    problem = PlacementProblem(crit, twenty, k=4, must_include=(5,), min_spacing=120.0, exclude=(0, 1, 2))
    found = choose_layout(problem, rng=0)
    idx = found.indices
    assert 5 in idx and not set(idx) & {0, 1, 2}
    d = np.hypot(*(centres[idx][:, None] - centres[idx][None]).transpose(2, 0, 1))
    assert d[np.triu_indices(4, 1)].min() >= 120.0
    # exhaustive optimum under the same constraints
    every = [L for L in itertools.combinations([i for i in range(20) if i not in (0, 1, 2, 5)], 3)]
    layouts = problem.full(np.array(every))
    ok = problem.feasible(layouts)
    best = crit.value(layouts[ok]).max()
    assert found.value >= best - 0.01 * abs(best)
    # budget: costs 1 or 3, budget 5 -> at most 5 cheap ones or fewer with dear ones
    cost = np.where(np.arange(20) % 2 == 0, 1.0, 3.0)
    priced = CandidateSet(twenty.sensors, twenty.kinds, cost)
    found = choose_layout(PlacementProblem(crit, priced, budget=5.0), rng=0)
    assert cost[found.indices].sum() <= 5.0 and len(found.indices) >= 2


@pytest.mark.slow
def test_criterion_ranking_agrees_with_monte_carlo_scatter(scenario):
    """Layouts ranked by the linearised 95 % width at the truth (criterion) rank the same way by the
    scatter of parameters identified by the actual inversion under noise (Spearman ρ ≥ 0.8 over five
    layouts spread from the best to the worst by the criterion; 30 realisations each)."""
    space = ParameterSpace.from_scenario(scenario, {"E_b": (5000, 20000), "kN_bj": (10, 1000, "log")})
    cand = gauge_grid(scenario.mesh, GRID, GRID, lengths=(50, 160))
    cand = cand.subset(np.arange(0, len(cand), max(1, len(cand) // 40)))
    sens = candidate_sensitivities(scenario, space, cand, prior_points(space, 32))
    sur = candidate_surrogate(sens)
    truth = space.from_unit(np.array([[0.45, 0.55]]))
    noise = SensorNoise(lvdt=0.0005)
    at_truth = candidate_sensitivities(scenario, space, cand, truth)
    crit = LayoutCriterion(fisher_per_candidate(at_truth, noise), "d")
    pairs = np.array(list(itertools.combinations(range(len(cand)), 2)))
    lin = crit.linearised_widths(pairs).mean(axis=1)
    order = np.argsort(lin)
    picks = pairs[order[np.linspace(0, len(order) - 1, 5).astype(int)]]
    predicted = crit.linearised_widths(picks).mean(axis=1)
    observed = [monte_carlo(sur, sens, L, noise, truth, n_realisations=30, rng=i, population_size=20,
                            generations=10, n_starts=2).mean_width_unit for i, L in enumerate(picks)]
    rho = spearmanr(predicted, observed)[0]
    assert rho >= 0.8, (predicted, observed)


@pytest.mark.slow
def test_parameter_unidentifiable_with_one_layout_identifiable_with_the_chosen(scenario):
    """One gauge reads one combination of E_b and r_hj (its readings are proportional to the load):
    the inversion scatters over most of the box for at least one of them. The chosen 3-gauge layout
    pins both (Monte-Carlo 95 % width < 0.25 of the box)."""
    space = ParameterSpace.from_scenario(scenario, {"E_b": (5000, 20000), "r_hj": (0.1, 1.0)})
    cand = gauge_grid(scenario.mesh, GRID, GRID, lengths=(50, 160))
    result = place_sensors(scenario, space, cand, _job(k=3, n_points=16, include_current=False, n_random=0,
                                                       methods=("greedy",)), noise=SensorNoise(lvdt=0.0005))
    sens = candidate_sensitivities(scenario, space, result.candidates, prior_points(space, 32))
    sur = candidate_surrogate(sens)
    truth = space.from_unit(np.array([[0.5, 0.5]]))
    opts = dict(n_realisations=20, population_size=20, generations=10, n_starts=2)
    one = monte_carlo(sur, sens, result.layout.indices[:1], SensorNoise(lvdt=0.0005), truth, **opts)
    chosen = monte_carlo(sur, sens, result.layout.indices, SensorNoise(lvdt=0.0005), truth, **opts)
    assert one.width_unit.max() > 0.5, one.width_unit
    assert chosen.width_unit.max() < 0.25, chosen.width_unit


def test_place_sensors_spec_is_accepted_by_the_scenario_and_the_study(scenario, space, tmp_path):
    cand = gauge_grid(scenario.mesh, GRID, GRID, lengths=(80, 160))
    result = place_sensors(scenario, space, cand, _job(k=3, n_points=8, n_random=3, methods=("greedy",)))
    assert [s.label for s in result.scores][:2] == ["chosen", "current"] and len(result.scores) == 5
    text = spec_toml(result.spec())
    spec = ScenarioSpec.from_dict(tomllib.loads(text))
    sc = build_scenario(spec)
    assert sc.sensor_names == result.layout.names
    chosen = [result.candidates.sensors[i] for i in result.layout.indices]
    assert tuple(sc.sensors) == tuple(chosen)
    table = tomllib.loads(spec_toml(result.spec(), table="scenario"))["scenario"]
    assert ScenarioSpec.from_dict(table) == spec
    # the study accepts the [scenario] table as it is written
    example = (Path(__file__).parents[1] / "examples" / "diagonal_compression.toml").read_text()
    body = re.sub(r"\[scenario\].*?(?=\n\[parameters\])", "", example, flags=re.DOTALL)
    study = tmp_path / "study.toml"
    study.write_text(body + "\n" + spec_toml(result.spec(), table="scenario"))
    shutil.copy(Path(__file__).parents[1] / "examples" / "diagonal_compression_measured.csv", tmp_path)
    loaded = load_study(study).spec  # the study adds its [fixed] values to the spec parameters
    assert loaded.options["sensors"] == spec.options["sensors"] and loaded.options["n_courses"] == 6
    d = result.to_dict()
    assert d["layout"]["names"] == list(result.layout.names) and len(d["scores"]) == 5


def test_cli_sensors_writes_a_usable_layout(tmp_path):
    spec = tmp_path / "small.toml"
    spec.write_text(spec_toml(ScenarioSpec.from_dict(SMALL)))
    out = tmp_path / "out"
    runner = CliRunner()
    args = ["sensors", "--scenario", "diagonal_compression", "--spec", str(spec), "--param", "E_b=5000:20000",
            "--param", "kN_bj=10:1000:log", "--k", "3", "--grid-x", "20:380:40", "--grid-y", "20:380:40",
            "--length", "80:160", "--n-points", "8", "--random", "3", "--out", str(out)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    for name in ("layout.toml", "scenario_table.toml", "placement.json", "comparison.md", "layout.png"):
        assert (out / name).exists(), name
    sim = runner.invoke(app, ["simulate", "diagonal_compression", "--spec", str(out / "layout.toml"), "--format", "csv"])
    assert sim.exit_code == 0, sim.output
    assert len(sim.stdout.splitlines()[0].split(",")) == 4  # load + 3 chosen sensors
    bad = runner.invoke(app, args[:9] + ["--k", "3", "--out", str(out)])
    assert bad.exit_code == 2 and "no candidates" in bad.output


def test_noise_per_sensor_kind_scales_the_information(scenario, space):
    """A DIC point's information scales as 1/σ_dic², a gauge's as 1/σ_lvdt², independently; a DIC
    point reads both displacement components (two channels)."""
    cand = gauge_grid(scenario.mesh, GRID, GRID, lengths=(80, 90)).subset([0]) + dic_points(scenario.mesh, [210.0], [230.0])
    sens = candidate_sensitivities(scenario, space, cand, prior_points(space, 4))
    assert [len(sens.channels_of(i)) for i in range(2)] == [1, 2]
    F1 = fisher_per_candidate(sens, SensorNoise(lvdt=0.002, dic=0.005))
    F2 = fisher_per_candidate(sens, SensorNoise(lvdt=0.002, dic=0.010))
    np.testing.assert_allclose(F2[:, 0], F1[:, 0], rtol=1e-14)
    np.testing.assert_allclose(F2[:, 1], F1[:, 1] / 4, rtol=1e-12)
    # relative noise: σ = δ |reading| per reading
    rel = SensorNoise(relative=0.01, floor=1e-12)
    J = sens.jacobian[:, :, :1, :] / (0.01 * np.abs(sens.readings[:, :, :1, None]))
    np.testing.assert_allclose(fisher_per_candidate(sens, rel)[:, 0], np.einsum("nlcj,nlck->njk", J, J), rtol=1e-10)


@pytest.mark.slow
def test_surrogate_sensitivities_approach_the_exact_ones(scenario, space, twenty):
    """The model path (central differences of a POD-kriging surrogate of the candidates' readings,
    for scenarios without an affine model) agrees with the exact FE sensitivities: the D-criterion
    ranking of 200 random 4-sensor layouts has Spearman ρ > 0.95 and the chosen layouts' exact
    criteria differ by < 2 % (surrogate of 128 Sobol' points; kriging error ~1e-3 relative)."""
    train = candidate_sensitivities(scenario, space, twenty, prior_points(space, 128, rng=3))
    sur = candidate_surrogate(train)

    class Model:  # what SurrogateModel exposes, over the candidates' channels
        sensor_names, load_levels = train.channel_names, train.load_levels

        def __init__(self):
            self.space = space

        def predict(self, X):
            return sur.predict(X)

    X = prior_points(space, 16)
    exact = candidate_sensitivities(scenario, space, twenty, X)
    approx = model_sensitivities(Model(), twenty, X)
    noise = SensorNoise(lvdt=0.0005)
    c_exact = LayoutCriterion(fisher_per_candidate(exact, noise), "d")
    c_approx = LayoutCriterion(fisher_per_candidate(approx, noise), "d")
    layouts = np.array([np.random.default_rng(i).choice(20, 4, replace=False) for i in range(200)])
    assert spearmanr(c_exact.value(layouts), c_approx.value(layouts))[0] > 0.95
    best_exact = choose_layout(PlacementProblem(c_exact, twenty, k=4)).value
    via_approx = c_exact.value(choose_layout(PlacementProblem(c_approx, twenty, k=4)).indices[None])[0]
    assert abs(via_approx - best_exact) < 0.02 * abs(best_exact)


def test_place_sensors_through_a_batched_model_matches_the_exact_path(scenario, space, twenty):
    """``model=`` (here the FE model in the loop, central differences) chooses the same layout as
    the exact affine path, with criterion values within 1e-5 relative (difference truncation)."""
    spec = dict(SMALL, sensors={s.name: s.to_dict() for s in twenty.sensors})
    fe_model = FEModel(build_scenario(spec), space)
    job = _job(k=4, n_points=8, include_current=False, n_random=0, methods=("greedy",))
    exact = place_sensors(scenario, space, twenty, job)
    via_model = place_sensors(scenario, space, twenty, job, model=fe_model)
    assert set(via_model.layout.indices) == set(exact.layout.indices)
    assert via_model.layout.value == pytest.approx(exact.layout.value, rel=1e-5)


def test_current_sensor_in_a_forbidden_zone_is_scored_but_not_chosen(scenario, space):
    zone = Zone(150.0, 150.0, 250.0, 250.0)  # the current gauge C (100,100)→(290,290) crosses it
    cand = gauge_grid(scenario.mesh, GRID, GRID, lengths=(80, 160), forbidden=[zone])
    job = _job(k=3, n_points=8, n_random=0, methods=("greedy",))
    free = place_sensors(scenario, space, cand, job)
    assert "C" in free.layout.names  # the best sensor when allowed
    barred = place_sensors(scenario, space, cand, job, forbidden=[zone])
    assert "C" not in barred.layout.names and barred.score("current").names == ("C",)
    assert barred.zones == (zone,)


def test_two_load_patterns_shear_compression_readings_match():
    """Shear-compression has two load patterns (pre-compression and shear) combined per load level;
    candidate readings still equal the FE readings."""
    sc = build_scenario({"scenario": "shear_compression", "nx": 2, "ny": 1})
    assert sc.load_coefficients.shape[1] == 2
    space = ParameterSpace.from_scenario(sc, {"kN_bj": (10, 1000, "log"), "r_hj": (0.1, 1.0)})
    g = np.arange(20.0, 980.0, 70.0)
    cand = gauge_grid(sc.mesh, g, g, lengths=(60, 150))
    cand = cand.subset([0, 5, len(cand) // 2, len(cand) - 1])
    x = np.array([80.0, 0.6])
    sens = candidate_sensitivities(sc, space, cand, x[None])
    ref = build_scenario({"scenario": "shear_compression", "nx": 2, "ny": 1,
                          "sensors": {c.name: c.to_dict() for c in cand.sensors}}).run(space.as_params(x)).readings
    np.testing.assert_allclose(sens.readings[0], ref, rtol=1e-10, atol=1e-14)


def test_budget_through_place_sensors_prices_current_sensors_like_candidates(scenario, space):
    cand = gauge_grid(scenario.mesh, GRID, GRID, lengths=(80, 160), cost=2.5)
    result = place_sensors(scenario, space, cand, _job(budget=8.0, n_points=8, n_random=2, methods=("greedy",)))
    assert result.candidates.cost[result.candidates.is_current].tolist() == [2.5]
    assert len(result.layout.indices) == 3 and result.candidates.cost[result.layout.indices].sum() <= 8.0


def test_flat_jack_loads_scaled_by_km_get_exact_sensitivities():
    """The flat-jack loads scale with Km (jack force = Km × p): the exact path adds (∂C/∂Km) H q.
    With σ0 = 0 the readings are proportional to Km, so ∂g/∂u = g/Km × (Km_max − Km_min) in closed
    form, to 1e-8 relative (central differences of the linear multipliers: round-off only); and it
    agrees with central differences of FE runs (``model=``, step 1e-4 of the box): the panel's
    joints are 10⁷ N/mm³ stiff (the homogeneous limit), so each solve carries ~1e-10 relative
    round-off, which a difference over 1e-4 turns into ~1e-6 (5e-6 measured for E_b): 2e-5."""
    sc = build_scenario(homogeneous_slot_spec(2.0, nx=2, ny=1, gauge_offsets=(32.5, 97.5)))
    cands = user_candidates(sc.mesh, {s.name: s.to_dict() for s in sc.sensors})
    with_km = ParameterSpace.from_scenario(sc, {"E_b": (3000.0, 5000.0), "Km": (0.75, 0.95)})
    X = prior_points(with_km, 2)
    exact = candidate_sensitivities(sc, with_km, cands, X)
    km = X[:, 1][:, None, None]
    assert np.abs(exact.readings).max() > 0
    np.testing.assert_allclose(exact.jacobian[..., 1], exact.readings / km * 0.2, rtol=1e-8, atol=1e-14)
    # Km fixed off its spec value: the readings are those of scenario.run at that Km
    stiff_only = ParameterSpace.from_scenario(sc, {"E_b": (3000.0, 5000.0)})
    off = candidate_sensitivities(sc, stiff_only, cands, X[:1, :1], fixed={"Km": 0.8})
    np.testing.assert_allclose(off.readings[0], sc.run({"E_b": X[0, 0], "Km": 0.8}).readings, rtol=1e-10, atol=1e-14)
    sens = model_sensitivities(FEModel(sc, with_km), cands, X)
    np.testing.assert_allclose(sens.readings, exact.readings, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(sens.jacobian, exact.jacobian, rtol=2e-5, atol=1e-6 * np.abs(exact.jacobian).max())


def test_fe_differences_stand_in_where_exact_sensitivities_cannot(tmp_path, caplog):
    """``CandidateFEModel`` reads every candidate off FE displacement fields: for the scenario's own
    gauges it reproduces ``scenario.run`` (the operator H applied to the field against the scenario's
    readings: same FE solve, round-off only). The flat jack with ``release = "exact"`` (release
    load from a pre-cut solve, not a load pattern) has no exact sensitivities:
    ``place_sensors(model="auto")`` falls back to FE differences (logged), ``"exact"`` refuses, and
    the CLI does the same through ``--sensitivities``."""
    spec = {**homogeneous_slot_spec(2.0, nx=2, ny=1, gauge_offsets=(32.5, 97.5)), "release": "exact"}
    sc = build_scenario(spec)
    cands = user_candidates(sc.mesh, {f"c_{s.name}": s.to_dict() for s in sc.sensors})
    with_km = ParameterSpace.from_scenario(sc, {"E_b": (3000.0, 5000.0), "Km": (0.75, 0.95)})
    model = CandidateFEModel(sc, with_km, cands)
    x = np.array([[4000.0, 0.9]])
    np.testing.assert_allclose(model.predict(x)[0], sc.run({"E_b": 4000.0, "Km": 0.9}).readings.ravel(), rtol=1e-10, atol=1e-14)
    assert model.n_runs == 1
    job = _job(k=1, n_points=4, n_random=2, methods=("greedy",), include_current=False)
    with pytest.raises(ExactSensitivitiesUnavailable, match="release = 'exact'"):
        place_sensors(sc, with_km, cands, job, model="exact")
    with pytest.raises(ValueError, match="model must be .*one of"):
        place_sensors(sc, with_km, cands, job, model="surrogate")
    with caplog.at_level("WARNING", logger="podkrig.sensors.placement"):
        auto = place_sensors(sc, with_km, cands, job, model="auto")
    assert "differences of FE runs" in caplog.text
    fe = place_sensors(sc, with_km, cands, job, model="fe")
    assert auto.layout.names == fe.layout.names and len(fe.layout.names) == 1

    spec_file = tmp_path / "fj.json"
    spec_file.write_text(json.dumps(spec))
    cand_file = tmp_path / "cands.json"
    cand_file.write_text(json.dumps({"sensors": {n: s.to_dict() for n, s in zip(cands.names, cands.sensors)}}))
    args = ["sensors", "--scenario", "flat_jack", "--spec", str(spec_file), "--param", "E_b=3000:5000",
            "--param", "Km=0.75:0.95", "--candidates", str(cand_file), "--k", "1", "--n-points", "4",
            "--random", "2", "--no-current", "--out", str(tmp_path / "out")]
    runner = CliRunner()
    refused = runner.invoke(app, args + ["--sensitivities", "exact"])
    assert refused.exit_code == 2 and "release = 'exact'" in refused.output
    done = runner.invoke(app, args)
    assert done.exit_code == 0, done.output
    assert json.loads((tmp_path / "out" / "placement.json").read_text())["layout"]["names"] == list(fe.layout.names)
