"""The diagnosis on curve data: a strength test's force–displacement curve (one EN 1052-3
triplet, F + two gauges), its strength candidates and hidden truths (tests/strength_trials.py).

- the triplet option ``joint_strength_factors`` leaves the specimen unchanged at its default and
  makes one joint weaker as the closed forms say (peak governed by the weaker joint, the same
  residual friction);
- on a nonlinear scenario the candidates that act on the linear model say why they do not apply,
  and the two strength candidates are off at their neutral value;
- one joint 20–30 % weaker is named as ``weak_joint_strength``, dilatancy as ``dilatancy``, and
  clean curves raise at most one alarm in 20 noise seeds;
- what the data can show: with the cohesion free as well, a 25 % weaker joint is absorbed by a
  lower c_bj (under 1σ left), which is why the base model of these trials fixes the series' c_bj.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.optimize import least_squares

from fe import build_scenario
from podkrig.diagnosis import CANDIDATES, FEContext
from strength_trials import (
    BOUNDS,
    NOISE_ABS,
    NOISE_REL,
    SPEC,
    TRUTH,
    base_model,
    diagnose_trial,
    make_strength_trial,
)

AREA = 210.0 * 100.0  # mm², one bed joint of the default triplet
SIGMA_N = 0.6  # MPa, the trials' pre-compression


def test_joint_strength_factors_default_leaves_the_triplet_unchanged():
    default = build_scenario(SPEC).run(TRUTH).readings
    explicit = build_scenario({**SPEC, "joint_strength_factors": [1, 1]}).run(TRUTH).readings
    assert_array_equal(explicit, default)  # the same code path in one process: identical


def test_a_weaker_joint_governs_the_peak_and_keeps_the_residual_friction():
    """Closed forms for uniform joints (units much stiffer than the joints): a sound triplet peaks
    at ``2 A (c + σ tanφ)`` and ends at ``2 A σ tanφr``. With the upper joint's bond × 0.75 the two
    joints share one slip, so the peak lies between twice the weaker joint's strength (both at
    their peaks together) and the sum of both strengths (32.1 kN between 30.9 and 32.4 kN); the
    residual friction is the same."""
    s = 0.75
    sound = build_scenario(SPEC).run(TRUTH)
    weak = build_scenario({**SPEC, "joint_strength_factors": [1.0, s]}).run(TRUTH)
    tau, tau_weak = TRUTH["c_bj"] + SIGMA_N * TRUTH["tanphi_bj"], s * TRUTH["c_bj"] + SIGMA_N * TRUTH["tanphi_bj"]
    # 3 %: the Q8 4 × 1 mesh's units are not rigid and the peak sits between path steps
    assert_allclose(sound.peak_load, 2 * AREA * tau / 1000, rtol=0.03)
    assert 2 * AREA * tau_weak / 1000 * 0.99 < weak.peak_load < AREA * (tau + tau_weak) / 1000
    residual = 2 * AREA * SIGMA_N * 0.75 / 1000  # tanφr = 0.75 (the scenario's default)
    f = sound.sensor_names.index("F")
    assert_allclose([sound.readings[-1, f], weak.readings[-1, f]], residual, rtol=0.01)  # 2 mm slip: on the plateau


@pytest.mark.parametrize("factors, fragment", [([1.2, 1.0], "(0, 1]"), ([0.5], "two factors"), ([0.0, 1.0], "(0, 1]")])
def test_joint_strength_factors_outside_their_range_are_refused(factors, fragment):
    with pytest.raises(ValueError, match="joint_strength_factors") as err:
        build_scenario({**SPEC, "joint_strength_factors": factors})
    assert fragment in str(err.value)


def test_joint_strength_factors_need_the_composite_law():
    with pytest.raises(ValueError, match="law='composite'"):
        build_scenario({**SPEC, "joint_strength_factors": [1.0, 0.8], "law": "hyperbolic"})


def test_on_a_curve_scenario_only_the_candidates_that_can_act_apply():
    sc, space, fixed = base_model()
    ctx = FEContext(sc, space.names, sc.resolve(fixed), bounds={"tanphi_bj": (0.6, 1.1)})
    for name in ("weak_joint", "support_compliance", "load_eccentricity"):
        assert "nonlinear" in CANDIDATES[name].not_applicable(ctx), name
    assert "no head joints" in CANDIDATES["head_joint_stiffness"].not_applicable(ctx)
    for name in ("weak_joint_strength", "dilatancy", "gauge_fault", "gauge_slip", "unit_stiffness"):
        assert CANDIDATES[name].not_applicable(ctx) is None, name
    # the dilatancy range ends at min(tanφ0, tanφr), tanφ0 at its lowest in the box
    (loc,) = CANDIDATES["dilatancy"].locations(ctx)
    par = CANDIDATES["dilatancy"].parameter(ctx, loc)
    assert (par.neutral, par.upper) == (0.0, min(0.6, sc.resolve()["tanphir_bj"]))
    joints = CANDIDATES["weak_joint_strength"].locations(ctx)
    assert [loc.key for loc in joints] == ["lower bed joint", "upper bed joint"]
    assert [loc.detail["y"][0] for loc in joints] == [62.0, 124.0]  # mm, between the courses
    # a base model that frees tanpsi_bj or sets the factors has nothing left for the candidate
    assert "free parameter" in CANDIDATES["dilatancy"].not_applicable(FEContext(sc, ("tanpsi_bj",), ctx.values))
    weak = build_scenario({**SPEC, "joint_strength_factors": [0.8, 1.0]})
    assert "already" in CANDIDATES["weak_joint_strength"].not_applicable(FEContext(weak, space.names, ctx.values))


def test_the_strength_candidates_are_off_at_their_neutral_value_and_act_away_from_it():
    sc, space, fixed = base_model()
    values = sc.resolve(fixed)
    ctx = FEContext(sc, space.names, values)
    base = ctx.readings(values)
    f, v_top = sc.sensor_names.index("F"), sc.sensor_names.index("V_top")
    for name in ("weak_joint_strength", "dilatancy"):
        cand = CANDIDATES[name]
        for loc in cand.locations(ctx):
            par = cand.parameter(ctx, loc)
            assert_array_equal(cand.readings(ctx, values, loc, par.off), base, err_msg=f"{name} at {loc.key}")
            on = cand.readings(ctx, values, loc, par.reference)
            if name == "weak_joint_strength":  # a lower peak
                assert on[:, f].max() < 0.97 * base[:, f].max()
            else:  # the upper joint opens as it slides: V_top grows by about tanψ × slip
                assert on[-1, v_top] - base[-1, v_top] > 0.5 * par.reference * sc.load_levels[-1]


def test_with_the_cohesion_free_a_25_percent_weaker_joint_is_absorbed():
    """What the data can show: the largest whitened residual left when the base model is fitted to
    the noise-free curve of a triplet whose upper joint is 25 % weaker. With c_bj free a lower
    cohesion of both joints takes the effect (< 1σ left: no test can name it); with c_bj at the
    series' value it stands at several σ."""
    data = build_scenario({**SPEC, "joint_strength_factors": [1.0, 0.75]}).run(TRUTH).readings
    sc = build_scenario(SPEC)
    sigma = np.hypot([NOISE_ABS[n] for n in sc.sensor_names], NOISE_REL * data)

    def left(free):
        lo, hi = np.array([BOUNDS[n] for n in free]).T

        def residual(u):
            values = {**TRUTH, **dict(zip(free, lo + u * (hi - lo)))}
            return ((sc.run(values).readings - data) / sigma).ravel()

        u0 = (np.array([TRUTH[n] for n in free]) - lo) / (hi - lo)
        return float(np.max(np.abs(least_squares(residual, u0, bounds=(0, 1), diff_step=1e-4).fun)))

    assert left(("c_bj", "GfII_bj")) < 1.0
    assert left(("GfII_bj",)) > 3.0


@pytest.mark.slow
@pytest.mark.usefixtures("memo_nonlinear_runs")  # the diagnosis's repeated FE runs: conftest.py
def test_one_joint_20_to_30_percent_weaker_is_named():
    named = []
    for seed in range(5):
        trial = make_strength_trial("weak_joint_strength", np.random.default_rng(3200 + seed))
        d = diagnose_trial(trial, seed)
        assert d.verdict == "inadequate", d.to_dict()["candidates"][:3]
        named.append(d.cause)
        if d.cause == "weak_joint_strength":
            # whichever joint carries it (the curve hardly tells which); 0.1: the scatter of the
            # fitted s over noise seeds (up to 0.072 in 10 seeds of scripts/bench_diagnosis_strength.py)
            assert_allclose(d.causes[0].value, trial.value, atol=0.1)
            other = {"lower bed joint": "upper bed joint", "upper bed joint": "lower bed joint"}[d.causes[0].location.key]
            assert ("weak_joint_strength", other) in [(a.name, a.location.key) for a in d.alternatives]
    assert named.count("weak_joint_strength") >= 4, named


@pytest.mark.slow
@pytest.mark.usefixtures("memo_nonlinear_runs")  # the diagnosis's repeated FE runs: conftest.py
def test_dilatancy_is_named():
    for seed in range(3):
        trial = make_strength_trial("dilatancy", np.random.default_rng(3200 + seed))
        d = diagnose_trial(trial, seed)
        assert d.verdict == "inadequate" and d.cause == "dilatancy", [c.to_dict() for c in d.causes]
        assert_allclose(d.causes[0].value, trial.value, rtol=0.1)  # V_top at 2 µm reads tanψ × 2 mm closely


@pytest.mark.slow
@pytest.mark.usefixtures("memo_nonlinear_runs")  # the diagnosis's repeated FE runs: conftest.py
def test_clean_curves_raise_at_most_one_alarm_in_20():
    verdicts = [diagnose_trial(make_strength_trial(None, np.random.default_rng(3200 + seed)), seed).verdict
                for seed in range(20)]
    assert verdicts.count("inadequate") <= 1, verdicts
