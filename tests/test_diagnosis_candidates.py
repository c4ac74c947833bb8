"""The candidate causes of issue 18, item 5: a gauge that slipped, the flat jack's efficiency and
slot contact, and the onset of nonlinearity (joints cracking or sliding).

Each candidate is off at its neutral value (bit-identical readings), does what it claims (checked
against an independent construction through the scenario's public API), and is named with its
location by ``diagnose`` on hidden-effect data (the diagnosis never sees the cause, location or
strength). The nonlinear test uses data from the nonlinear solver itself, cracked at the top load
only, read at the linear scenario's force levels by interpolation written here, independently of
the candidate's.
"""

import numpy as np
import pytest
from diagnosis_trials import make_trial
from numpy.testing import assert_allclose, assert_array_equal

from fe import build_scenario
from fe.scenarios.diagonal_compression import DEFAULT_SENSORS
from fe.scenarios.flat_jack import homogeneous_slot_spec
from podkrig.diagnosis import (
    CANDIDATES,
    DEFAULT_CANDIDATES,
    DiagnosisSettings,
    FEContext,
    build_base_surrogate,
    diagnose,
)
from podkrig.diagnosis.nonlinear_runs import ELASTIC_SCALE, NonlinearTwin, readings_at_forces
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.parameters import ParameterSpace

WALL_BOUNDS = {"kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log")}
JACK_BOUNDS = {"E_b": (2000.0, 30000.0, "log"), "kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log")}
DIC = {"kind": "dic", "x0": 65.0, "y0": 32.5, "x1": 1105.0, "y1": 1072.5, "nx": 9, "ny": 9}


def _wall_spec():
    sensors = {g.name: g.to_dict() for g in DEFAULT_SENSORS}
    sensors["DIC"] = dict(DIC)
    return {"scenario": "diagonal_compression", "nx": 2, "ny": 1, "sensors": sensors}


class Setup:
    def __init__(self, spec, bounds):
        self.scenario = build_scenario(spec)
        self.space = ParameterSpace.from_scenario(self.scenario, bounds)
        self.surrogate = build_base_surrogate(self.scenario, self.space, self.scenario.resolve(), 64, 0)

    def diagnose(self, measurement, noise, candidates=None, seed=0, model_tolerance=None, **options):
        return diagnose(self.scenario, measurement, noise, self.space,
                        DiagnosisSettings(seed=seed, model_tolerance=model_tolerance), surrogate=self.surrogate,
                        candidates=candidates, **options)


@pytest.fixture(scope="module")
def wall():
    return Setup(_wall_spec(), WALL_BOUNDS)


@pytest.fixture(scope="module")
def jack():
    """The chisari flat-jack set-up (H, V1, V2) with its 18 gauges, the release and phases 1–2
    (20 steps) on a smaller panel (6 units × 18 courses, 1560 × 1170 mm: every gauge and slot
    inside, fewer joint segments to screen); Km fixed, so that jack efficiency is a candidate."""
    return Setup({"scenario": "flat_jack", "phases": ["0b", "1", "2"], "layout": "L18", "n_courses": 18,
                  "units_per_course": 6.0}, JACK_BOUNDS)


def _context(setup, values=None):
    values = setup.scenario.resolve(values)
    ctx = FEContext(setup.scenario, setup.space.names, values)
    ctx.offset_scale = float(np.max(np.abs(ctx.readings(values))))
    return ctx, values


# ---------------------------------------------------------------------------- off and what they do


def test_new_candidates_are_off_at_their_neutral_value(wall, jack):
    """Bit-identical readings at the neutral value (not merely close)."""
    for setup, names in ((wall, ("gauge_slip",)), (jack, ("gauge_slip", "jack_efficiency", "slot_contact"))):
        ctx, values = _context(setup)
        base = ctx.readings(values)
        for name in names:
            cand = CANDIDATES[name]
            assert cand.not_applicable(ctx) is None, name
            for loc in cand.locations(ctx):
                par = cand.parameter(ctx, loc)
                assert par.lower <= par.off <= par.upper and par.off == par.neutral
                assert_array_equal(cand.readings(ctx, values, loc, par.off), base, err_msg=f"{name} at {loc.key}")


def test_flat_jack_candidates_apply_only_where_they_make_sense(wall, jack):
    ctx, _ = _context(wall)
    for name in ("jack_efficiency", "slot_contact"):
        assert "no flat jacks" in CANDIDATES[name].not_applicable(ctx)
    sc = jack.scenario
    ctx = FEContext(sc, ("E_b", "Km"), sc.resolve())
    assert "Km is a free parameter" in CANDIDATES["jack_efficiency"].not_applicable(ctx)
    assert CANDIDATES["slot_contact"].not_applicable(ctx) is None
    assert "no nonlinear counterpart" in CANDIDATES["nonlinearity_onset"].not_applicable(ctx)
    assert "nonlinearity_onset" not in DEFAULT_CANDIDATES and "gauge_slip" in DEFAULT_CANDIDATES


def test_gauge_slip_offsets_one_sensor_from_its_level_on(wall):
    ctx, values = _context(wall)
    base = ctx.readings(values)
    cand = CANDIDATES["gauge_slip"]
    locations = cand.locations(ctx)
    n_loads, n_sensors = base.shape
    assert len(locations) == n_sensors * (n_loads - 1)  # a step at the first level would be an offset
    loc = next(lc for lc in locations if lc.detail["sensor"] == "D2" and lc.detail["level"] == 2)
    c = 0.0123
    R = cand.readings(ctx, values, loc, c)
    j = ctx.sensor_names.index("D2")
    assert_array_equal(R[:2], base[:2])  # levels before the slip untouched
    assert_array_equal(np.delete(R, j, axis=1), np.delete(base, j, axis=1))  # other sensors untouched
    assert_allclose(R[2:, j] - base[2:, j], c, rtol=0, atol=1e-15)  # exactly c from level 3 on
    assert "between 50 and 75 kN" in loc.label


def test_jack_efficiency_scales_like_a_km_change(jack):
    sc = jack.scenario
    ctx, values = _context(jack)
    cand = CANDIDATES["jack_efficiency"]
    locations = {lc.key: lc for lc in cand.locations(ctx)}
    assert set(locations) == {"all jacks", "jack H", "jack V1", "jack V2"}
    km = 0.62
    # one efficiency for all jacks: the scenario run at that Km
    run = sc.run({**values, "Km": km}).readings
    assert_allclose(cand.readings(ctx, values, locations["all jacks"], km), run, rtol=1e-9,
                    atol=1e-12 * np.abs(run).max())
    # jack V1 alone: the scenario whose schedule gives V1 the pressure × Km/Km0 (every step)
    ratio = km / values["Km"]
    spec = sc.spec.to_dict()
    schedule = [{"name": st.phase, "steps": [{**st.pressures, "V1": ratio * st.pressures["V1"]}]} for st in sc.steps]
    scaled = build_scenario({**spec, "schedule": schedule, "phases": None}).run(values).readings
    assert_allclose(cand.readings(ctx, values, locations["jack V1"], km), scaled, rtol=1e-9,
                    atol=1e-12 * np.abs(scaled).max())


def test_slot_contact_removes_the_stated_resultant_and_equals_a_shorter_jack():
    """The lost load has resultant ℓ·t per MPa on each slot face; losing ℓ = 65 mm at both ends of
    a 260 mm jack is the scenario's own jack with Ka = 0.5 (the same mesh: the loss ends sit on
    existing node lines)."""
    spec = {**homogeneous_slot_spec(2.0, nx=2, ny=1, gauge_offsets=(32.5, 97.5)), "parameters": {
        "kN_bj": 80.0, "kV_bj": 30.0, "Km": 0.9}}
    sc = build_scenario(spec)
    values = sc.resolve()
    ctx = FEContext(sc, ("E_b",), values)
    cand = CANDIDATES["slot_contact"]
    locations = {lc.key: lc for lc in cand.locations(ctx)}
    assert set(locations) == {"H start", "H end", "H both"}
    slot = sc.slots[0]
    faces = sc.mesh.interfaces[sc.slot_interfaces["H"]]
    half = faces.shape[1] // 2
    face_b = np.unique(faces[:, half:])
    t = sc.options.thickness
    for key, loss in (("H start", 40.0), ("H end", 97.0), ("H both", 31.0)):
        f = cand.lost_pattern(sc, locations[key], loss)
        ends = 2 if key == "H both" else 1
        assert_allclose(f[2 * face_b + 1].sum(), ends * loss * t, rtol=1e-12)  # N per MPa, pushing face B up
        assert_allclose(f.reshape(-1, 2).sum(axis=0), 0.0, atol=1e-9)  # self-equilibrated
        full = sc.jack_pattern("H")
        assert_allclose((full - f)[2 * face_b + 1].sum(), (slot.length - ends * loss) * t, rtol=1e-12)
    shorter = build_scenario({**spec, "slots": [{**sc.spec.to_dict()["slots"][0], "Ka": 0.5}]})
    assert shorter.mesh.n_nodes == sc.mesh.n_nodes
    expected = shorter.run(values).readings
    got = cand.readings(ctx, values, locations["H both"], 65.0)
    assert_allclose(got, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
    assert np.all(np.abs(got) < np.abs(ctx.readings(values)))  # less load, smaller gauge openings


# ---------------------------------------------------------------------------- hidden effects


def _strong_trial(setup, cause, rng, truth):
    for _ in range(20):
        trial = make_trial(setup.scenario, setup.space, truth(rng), cause, rng=rng)
        if trial.identifiable_effect >= 3.0:
            return trial
    raise AssertionError(f"no identifiable {cause} drawn in 20 tries")


def _wall_truth(rng):
    return {"kN_bj": float(np.exp(rng.uniform(np.log(30), np.log(300)))),
            "kV_bj": float(np.exp(rng.uniform(np.log(12), np.log(120))))}


def _jack_truth(rng):
    return {"E_b": float(np.exp(rng.uniform(np.log(5000), np.log(15000)))),
            "kN_bj": float(np.exp(rng.uniform(np.log(40), np.log(200)))),
            "kV_bj": float(np.exp(rng.uniform(np.log(15), np.log(80))))}


def _named(d, trial):
    return [d.best.location.key] + [a.location.key for a in d.alternatives if a.name == trial.cause]


@pytest.mark.slow
@pytest.mark.parametrize("cause, setup, truth, seed", [("gauge_slip", "wall", _wall_truth, 1818),
                                                      ("slot_contact", "jack", _jack_truth, 1819)])
def test_hidden_effect_is_named_with_its_location(cause, setup, truth, seed, request):
    """A slipped gauge (its sensor and level) on the diagonal test, a jack without contact at one
    end (its jack and end) on the flat-jack panel."""
    setup = request.getfixturevalue(setup)
    trial = _strong_trial(setup, cause, np.random.default_rng(seed), truth)
    d = setup.diagnose(trial.measurement, trial.noise)
    assert d.verdict == "inadequate" and d.cause == cause, [c.to_dict() for c in d.candidates[:3]]
    assert trial.location.key in _named(d, trial)
    assert d.to_dict()["extended"]["chi2_dof"] < 1.5


def _nonlinear_readings_at(spec, values, forces, target):
    """Readings of the nonlinear twin of ``spec`` at ``forces`` (kN): linear interpolation on the
    converged force–readings path at the first crossing of each force (written here, not the
    candidate's code)."""
    nl = build_scenario({**spec, "scenario": "diagonal_compression_nl", "load_levels": [target]})
    path = nl.run(values).path
    F = np.concatenate([[0.0], path.load])
    R = np.vstack([np.zeros((1, path.readings.shape[1])), path.readings])
    out = []
    for f in forces:
        i = int(np.argmax(F >= f))
        assert F[i] >= f, f"the run did not reach {f} kN (peak {F.max():.1f} kN)"
        a = (f - F[i - 1]) / (F[i] - F[i - 1])
        out.append((1 - a) * R[i - 1] + a * R[i])
    return np.array(out), nl


@pytest.mark.slow
def test_data_cracked_at_the_top_load_are_diagnosed_as_nonlinearity_onset(wall):
    """Pseudo-data from the nonlinear solver with joint strengths at 1.4 × the defaults (ft 0.35,
    c 0.49, f_c 14.7 MPa; fracture energies × 1.96): within the noise up to 75 kN, cracked near
    the loaded corner at 100 kN. The diagnosis, told of every candidate, names nonlinearity_onset at the top
    level; its effect is off at the neutral strength."""
    sc = wall.scenario
    truth = sc.resolve({"kN_bj": 60.0, "kV_bj": 25.0})
    s = 1.4
    nl0 = build_scenario({**_wall_spec(), "scenario": "diagonal_compression_nl", "load_levels": [1.0]}).resolve()
    strengths = {k: s * nl0[k] for k in ("ft_bj", "c_bj", "fc")}
    strengths.update({k: s * s * nl0[k] for k in ("GfI_bj", "GfII_bj", "Gfc")})
    elastic = sc.run(truth).readings
    data_clean, _ = _nonlinear_readings_at(_wall_spec(), {**truth, **strengths}, sc.load_levels, 1.2)
    sigma = 0.01 * float(np.max(np.abs(elastic)))
    departure = np.max(np.abs(data_clean - elastic), axis=1) / sigma
    # the premise, cracked at the top only: within the noise up to 75 kN (0.84σ at 75 kN with the
    # rigid supports of issue 18, 3.4σ at 100 kN)
    assert np.all(departure[:3] < 1.0) and departure[3] > 3.0, departure
    rng = np.random.default_rng(18)
    data = data_clean + sigma * rng.standard_normal(data_clean.shape)
    measurement = Measurement(data, sc.sensor_names, sc.load_levels, "nonlinear pseudo-data")
    # the nonlinear twin shares the model's mesh: no model-form error (the user's override, 0), and
    # no rigid motion between data and model to remove (removed, it takes half of the departure
    # near the loaded corner with it: 1.5σ left after refitting, under the 2σ a cause needs)
    d = wall.diagnose(measurement, NoiseModel(sigma=sigma), candidates=list(CANDIDATES), model_tolerance=0.0,
                      rigid_body="keep")
    assert d.verdict == "inadequate" and d.cause == "nonlinearity_onset", [c.to_dict() for c in d.candidates[:4]]
    assert d.best.location.detail["level"] == 3 and d.best.location.detail["load"] == 100.0
    assert "from load level 100 kN on" in d.best.location.label and "joint at" in d.best.location.label
    # off at the neutral strength, bit for bit, in the diagnosis' own context
    ctx = FEContext(sc, wall.space.names, truth)
    cand = CANDIDATES["nonlinearity_onset"]
    for loc in cand.locations(ctx):
        par = cand.parameter(ctx, loc)
        assert_array_equal(cand.readings(ctx, truth, loc, par.off), ctx.readings(truth))
        assert np.any(cand.readings(ctx, truth, loc, par.lower) != ctx.readings(truth))


@pytest.mark.parametrize("name", ["diagonal_compression", "shear_compression"])
def test_nonlinear_twin_at_elastic_strength_reproduces_the_linear_scenario(name):
    """The twin (same mesh, sensors, elastic values; displacement controlled) read at the linear
    scenario's force levels by interpolation on its path equals the linear run to round-off when no
    joint yields (strengths × 10³): the spec mapping, the force measure (kN) and the interpolation
    are right. The shear wall's linear readings include the pre-compression, as the twin's do."""
    sc = build_scenario({"scenario": name, "nx": 2, "ny": 1})
    values = sc.resolve({"kN_bj": 70.0, "kV_bj": 30.0})
    twin = NonlinearTwin(sc)
    assert twin.dropped_options == []
    run = twin.run(values, ELASTIC_SCALE)
    expected = sc.run(values).readings
    assert run.reached.all() and run.peak >= sc.load_levels[-1]
    assert_allclose(run.readings, expected, rtol=1e-8, atol=1e-9 * np.abs(expected).max())


def test_readings_at_forces_interpolates_at_the_first_crossing():
    """A path that rises, falls back and rises again (a snap-through): each force is read where the
    path first reaches it, linearly between the bracketing steps; forces never reached take the last
    state and are flagged."""

    class Path:
        phase = ("pre", "load", "load", "load", "load")
        load = np.array([0.0, 10.0, 20.0, 15.0, 30.0])
        readings = np.array([[1.0], [2.0], [4.0], [3.0], [9.0]])

        def of_phase(self, name):
            return np.array([p == name for p in self.phase])

    R, reached, F = readings_at_forces(Path(), "load", [5.0, 18.0, 25.0, 40.0])
    # zero load is the state before the phase (reading 1), then 10 → 2, 20 → 4, 15 → 3, 30 → 9
    assert_allclose(R[:, 0], [1.5, 2.0 + 0.8 * 2.0, 3.0 + (10 / 15) * 6.0, 9.0])
    assert_array_equal(reached, [True, True, True, False])
    assert_array_equal(F, [0.0, 10.0, 20.0, 15.0, 30.0])
