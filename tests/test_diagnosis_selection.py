"""Several causes in turn and the estimated model-form error (issue 18, items 3 and 4).

Candidates declare what they change (:class:`~podkrig.diagnosis.candidates.Effect`), and
:meth:`FEContext.readings_with` combines several into one FE model: checked against direct FE
runs of the combined model (round-off only). The forward selection is checked on pseudo-data with
two hidden effects (the code under test is told neither), and the discretisation error estimate
against its closed form (two runs and Richardson's factor).
"""

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fe import build_scenario
from fe.scenarios.diagonal_compression import DEFAULT_SENSORS
from podkrig.diagnosis import CANDIDATES, DiagnosisResult, DiagnosisSettings, FEContext, diagnose
from podkrig.online.model_error import discretisation_error, tolerance_error
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.parameters import ParameterSpace

BOUNDS = {"kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log")}
DIC = {"kind": "dic", "x0": 65.0, "y0": 32.5, "x1": 1105.0, "y1": 1072.5, "nx": 9, "ny": 9}
#: the demo's hidden values (examples/make_measured_data.py); the scenario's defaults are
#: E_b = 12000 MPa and r_hj = 1, so a base model with kN_bj, kV_bj free misses two effects
DEMO_TRUTH = {"E_b": 10500.0, "kN_bj": 70.0, "kV_bj": 28.0, "r_hj": 0.55}


def _spec(nx=2, ny=1, dic=True):
    sensors = {g.name: g.to_dict() for g in DEFAULT_SENSORS}
    if dic:
        sensors["DIC"] = dict(DIC)
    return {"scenario": "diagonal_compression", "nx": nx, "ny": ny, "sensors": sensors}


@pytest.fixture(scope="module")
def wall(dic_diagonal):
    """``_spec()``: the session's coarse diagonal test with six gauges and a 9 × 9 grid (conftest)."""
    return dic_diagonal


def _location(ctx, name, key=None):
    locations = CANDIDATES[name].locations(ctx)
    return locations[0] if key is None else next(loc for loc in locations if loc.key == key)


def test_parameter_effects_combine_like_a_direct_run(wall):
    values = wall.resolve()
    ctx = FEContext(wall, BOUNDS, values)
    terms = [(CANDIDATES["head_joint_stiffness"], _location(ctx, "head_joint_stiffness"), 0.4),
             (CANDIDATES["unit_stiffness"], _location(ctx, "unit_stiffness"), 9000.0)]
    direct = wall.run({**values, "r_hj": 0.4, "E_b": 9000.0}).readings
    assert_allclose(ctx.readings_with(values, terms), direct, rtol=1e-12)
    assert_allclose(ctx.readings_with(values, terms[::-1]), direct, rtol=1e-12)


def test_weak_joints_see_a_head_joint_ratio_found_before_or_after(wall):
    """Parameter values apply first, so a weak head-joint segment scales with the r_hj of the
    combination whatever the order; weakening every segment by f is kN, kV scaled by f."""
    values = wall.resolve()
    ctx = FEContext(wall, BOUNDS, values)
    weak = CANDIDATES["weak_joint"]
    f = 0.3
    segments = [(weak, loc, f) for loc in weak.locations(ctx) if "segment" in loc.detail]
    head = (CANDIDATES["head_joint_stiffness"], _location(ctx, "head_joint_stiffness"), 0.5)
    direct = wall.run({**values, "r_hj": 0.5, "kN_bj": f * values["kN_bj"], "kV_bj": f * values["kV_bj"]}).readings
    assert_allclose(ctx.readings_with(values, [head, *segments]), direct, rtol=1e-9, atol=1e-12)
    assert_allclose(ctx.readings_with(values, [*segments, head]), direct, rtol=1e-9, atol=1e-12)


def test_a_whole_bed_joint_is_its_segments_together(wall):
    """A whole-bed-joint location weakens every segment at its height (exactly the segments
    combined); its segments overlap it (not tried beside it), other joints do not."""
    values = wall.resolve()
    ctx = FEContext(wall, BOUNDS, values)
    weak = CANDIDATES["weak_joint"]
    locations = weak.locations(ctx)
    whole = next(loc for loc in locations if loc.key == "bed joint y 585")
    inside = [loc for loc in locations if "segment" in loc.detail and loc.detail["kind"] == "bed"
              and loc.detail["y"][0] == 585.0]
    assert len(inside) == len(whole.detail["segments"]) > 1
    # the same FE model both ways: agreement to round-off of one factorisation
    assert_allclose(weak.readings(ctx, values, whole, 0.2), ctx.readings_with(values, [(weak, loc, 0.2) for loc in inside]),
                    rtol=1e-9, atol=1e-12)
    assert weak.overlaps(inside[0], whole) and weak.overlaps(whole, inside[-1])
    other = next(loc for loc in locations if "segment" in loc.detail and loc.detail["y"][0] == 520.0)
    assert not weak.overlaps(other, whole)


def test_load_and_sensor_effects_superpose_exactly(wall):
    """A load-line offset is affine in e; a gauge offset adds o to its column only, after the solve."""
    values = wall.resolve()
    ctx = FEContext(wall, BOUNDS, values)
    ecc, fault = CANDIDATES["load_eccentricity"], CANDIDATES["gauge_fault"]
    shift = _location(ctx, "load_eccentricity", "offset")
    offset = _location(ctx, "gauge_fault", "D1 offset")
    R0 = ctx.readings_with(values, [])
    R1 = ctx.readings_with(values, [(ecc, shift, 5.0)])
    R2 = ctx.readings_with(values, [(ecc, shift, 10.0)])
    assert_allclose(R2 - R0, 2.0 * (R1 - R0), rtol=1e-9, atol=1e-14)
    both = ctx.readings_with(values, [(ecc, shift, 5.0), (fault, offset, 0.02)])
    expected = R1.copy()
    expected[:, wall.sensor_names.index("D1")] += 0.02
    assert_allclose(both, expected, rtol=1e-12, atol=1e-15)
    # a rotated load line: cos φ f + sin φ f⊥, so ±φ average to cos φ times the plain readings
    rot = _location(ctx, "load_eccentricity", "rotation")
    mean = 0.5 * (ctx.readings_with(values, [(ecc, rot, 7.0)]) + ctx.readings_with(values, [(ecc, rot, -7.0)]))
    assert_allclose(mean, np.cos(np.radians(7.0)) * R0, rtol=1e-9, atol=1e-14)


def test_compliant_supports_combine_with_a_weak_joint():
    """Springs 10⁵ × stiffer than a joint are the rigid supports to first order in 1/k, with a weak
    joint on top as well; two support compliances cannot be combined."""
    sc = build_scenario({"scenario": "shear_compression", "nx": 2, "ny": 1})
    values = sc.resolve()
    ctx = FEContext(sc, BOUNDS, values)
    weak = (CANDIDATES["weak_joint"], CANDIDATES["weak_joint"].locations(ctx)[3], 0.1)
    support = CANDIDATES["support_compliance"]
    loc = support.locations(ctx)[0]
    alone = ctx.readings_with(values, [weak])
    assert np.max(np.abs(alone - ctx.readings(values))) > 1e-3 * np.abs(alone).max()
    assert_allclose(ctx.readings_with(values, [(support, loc, 1e-7), weak]), alone, rtol=1e-4, atol=1e-8)
    soft = ctx.readings_with(values, [(support, loc, 0.5), weak])
    top_ux = sc.sensor_names.index("top_ux")
    assert soft[-1, top_ux] > 1.2 * alone[-1, top_ux]
    with pytest.raises(ValueError, match="two support-compliance"):
        ctx.readings_with(values, [(support, loc, 0.5), (support, loc, 0.1)])


def test_discretisation_error_is_richardson_on_two_meshes():
    sc = build_scenario(_spec(dic=False))
    fine = build_scenario(_spec(4, 2, dic=False))
    values = sc.resolve({"kN_bj": 70.0})
    R, Rf = sc.run(values).readings, fine.run(values).readings
    m = Measurement(R, sc.sensor_names, sc.load_levels, "model")
    e1 = discretisation_error(sc, values, m, rate=1.0)
    assert_allclose(e1.std, 2.0 * np.abs(R - Rf).ravel(), rtol=1e-10)
    e2 = discretisation_error(sc, values, m, rate=2.0)
    assert_allclose(e2.std, 4.0 / 3.0 * np.abs(R - Rf).ravel(), rtol=1e-10)
    assert e1.mesh == "Q8 2×1 and 4×2 per unit" and "two meshes" in e1.describe()
    assert_allclose(tolerance_error(m, 0.01).std, 0.01 * np.abs(R).ravel())
    with pytest.raises(ValueError, match="rate > 0"):
        discretisation_error(sc, values, m, rate=0.0)
    with pytest.raises(ValueError, match="refinement"):
        discretisation_error(sc, values, m, refinement=1)


@pytest.mark.slow
def test_the_demos_two_hidden_effects_are_named_in_turn(wall):
    """Pseudo-data at the demo's hidden values (E_b and r_hj off the base model's fixed values),
    six gauges and a 9 × 9 grid, σ = 2 µm; each effect survives refitting with the other by more
    than 3σ. The model and the data share the mesh, hence no model-form error (tolerance 0) and no
    rigid-body discrepancy to remove (rigid_body = "keep": with the default "auto" the grid's rigid
    motion, which carries most of E_b's signature here, is removed — on exact data the χ² that
    E_b = 12 000 leaves after refitting drops from 668 to 103 — and only r_hj is named)."""
    space = ParameterSpace.from_scenario(wall, BOUNDS)
    R = wall.run(DEMO_TRUTH).readings
    rng = np.random.default_rng(18)
    sigma = 0.002
    m = Measurement(R + sigma * rng.standard_normal(R.shape), wall.sensor_names, wall.load_levels, "two effects")
    d = diagnose(wall, m, NoiseModel(sigma=sigma), space, DiagnosisSettings(seed=1, model_tolerance=0.0),
                 rigid_body="keep")
    assert d.verdict == "inadequate"
    named = {c.name: c.value for c in d.causes}
    assert set(named) == {"unit_stiffness", "head_joint_stiffness"}, [s.to_dict() for s in d.steps]
    assert_allclose(named["unit_stiffness"], 10500.0, rtol=0.03)
    assert_allclose(named["head_joint_stiffness"], 0.55, rtol=0.05)
    assert len(d.steps) == 2 and all(s.dropped is None for s in d.steps)
    for s in d.steps:  # each step a real gain, its effect surviving the refit of everything before it
        assert s.chi2_after < s.chi2_before and 2.0 <= s.score.effect_left <= s.score.effect_size + 1e-9
    assert d.extended.chi2_dof < 1.3 and d.fully_explained
    out = d.to_dict()
    assert [c["cause"] for c in out["causes"]] == [s.score.name for s in d.steps]
    assert [s["cause"] for s in out["gain"]["steps"]] == [c.name for c in d.causes]
    full = json.loads(json.dumps(d.to_dict(state=True)))
    back = DiagnosisResult.from_dict(full, scenario=wall)
    assert back.to_dict(state=True) == full


@pytest.mark.slow
def test_clean_data_from_an_independent_discretisation_raise_at_most_one_alarm_in_20(
        wall, dic_diagonal_space, dic_diagonal_surrogate):
    """The independent-code situation inside the project: data from Q4 elements on a mesh eight times
    finer than the model's (Q8 2 × 1 per unit), six gauges and a 9 × 9 grid, clean (no effect), 20
    noise realisations. With the model-form error estimated (the default) and the rigid-body
    motion of the grid removed (the default for DIC), at most one false alarm (the issue's target:
    ≤ 1 in 20)."""
    data_model = build_scenario({**_spec(16, 8), "element": "Q4"})
    space, surrogate = dic_diagonal_space, dic_diagonal_surrogate  # BOUNDS free, 64 Sobol' FE runs (seed 0)
    rng = np.random.default_rng(1818)
    alarms = []
    for k in range(20):
        truth = {"kN_bj": float(np.exp(rng.uniform(np.log(30), np.log(300)))),
                 "kV_bj": float(np.exp(rng.uniform(np.log(12), np.log(120))))}
        R = data_model.run(truth).readings
        sigma = max(0.01 * float(np.max(np.abs(R))), 1e-3)
        m = Measurement(R + sigma * rng.standard_normal(R.shape), wall.sensor_names, wall.load_levels, "Q4 data")
        d = diagnose(wall, m, NoiseModel(sigma=sigma), space, DiagnosisSettings(seed=k), surrogate=surrogate)
        if d.verdict != "adequate":
            alarms.append((k, [c.name for c in d.causes], round(d.base.chi2_dof, 2)))
    assert len(alarms) <= 1, alarms
