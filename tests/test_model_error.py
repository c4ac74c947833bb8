"""The model-form error ``C_T`` (podkrig.online.model_error): Richardson's estimate from two meshes
against a response whose discretisation error is known in closed form, the fixed tolerance, the
``--model-form-error`` option and the record an inversion or a diagnosis keeps.

The two-mesh estimate is checked on a stand-in scenario (``_Scenario``) whose readings converge
exactly as ``g(h) = g₀ + c_x h_x^p + c_y h_y^p`` with ``h = 1/n`` per direction: Richardson's factor
at the right rate then returns the coarse mesh's true error ``|g(h) − g₀|`` to rounding, with no
FE solve (the FE path is covered by tests/test_diagnosis_selection.py).
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fe.exceptions import SpecError
from fe.sensors import DICGrid, Gauge, absolute_displacements
from podkrig.online import model_error as me
from podkrig.online.measurement import Measurement
from podkrig.online.model_error import (
    DEFAULT_RATE,
    FALLBACK_TOLERANCE,
    ModelError,
    discretisation_error,
    parse_model_form_error,
    tolerance_error,
)
from podkrig.online.rigid_body import rigid_body_modes

SENSORS = ("a", "b", "c")
LEVELS = np.array([10.0, 20.0])
G0 = np.array([[1.0, -2.0, 0.5], [2.0, -4.0, 1.0]])  # the converged readings, mm
CX = np.array([[0.3, 0.1, -0.2], [0.6, 0.2, -0.4]])  # error coefficients along x and y, mm
CY = np.array([[0.1, 0.05, -0.1], [0.2, 0.1, -0.2]])


class _Spec:
    def __init__(self, options):
        self.options = dict(options)

    def to_dict(self):
        return dict(self.options)


class _Run:
    def __init__(self, readings):
        self.readings = readings


class _Scenario:
    """Readings ``g₀ + c_x (1/nx)^p + c_y (1/ny)^p`` (same sign per reading), ``p`` = ``rate``;
    ``shift`` (a function of nx) is added to every reading, e.g. a mesh-dependent rigid motion."""

    name = "stand-in"

    def __init__(self, options, rate, sensors=SENSORS, g0=G0, cx=CX, cy=CY, shift=None):
        self.spec = _Spec(options)
        self.rate, self.sensor_names, self.load_levels = rate, tuple(sensors), LEVELS
        self.g0, self.cx, self.cy, self.shift = g0, cx, cy, shift
        self.runs = []

    def run(self, values):
        self.runs.append(dict(values))
        o, p = self.spec.options, self.rate
        g = self.g0 + self.cx * (1.0 / o["nx"]) ** p + self.cy * (1.0 / o["ny"]) ** p
        return _Run(g + (0.0 if self.shift is None else self.shift(o["nx"])))

    def exact_error(self):
        o, p = self.spec.options, self.rate
        return np.abs(self.cx * (1.0 / o["nx"]) ** p + self.cy * (1.0 / o["ny"]) ** p)


@pytest.fixture
def refine(monkeypatch):
    """``build_scenario`` replaced by one building a ``_Scenario`` like ``coarse`` from the refined
    spec; the fine scenarios built are appended to ``refine.built``."""

    class Refine:
        built = []
        coarse = None
        fail = None

        def build(self, spec):
            if self.fail is not None:
                raise SpecError(self.fail)
            c = self.coarse
            fine = _Scenario(spec, c.rate, c.sensor_names, c.g0, c.cx, c.cy, c.shift)
            self.built.append(fine)
            return fine

    r = Refine()
    monkeypatch.setattr(me, "build_scenario", r.build)
    return r


@pytest.mark.parametrize("rate, refinement", [(0.8, 2), (2.0, 2), (1.0, 3)])
def test_richardson_recovers_the_exact_error_of_a_reading_converging_at_rate_p(refine, rate, refinement):
    """``e = |g(h) − g(h/r)| r^p/(r^p − 1)`` equals ``|g(h) − g₀|`` exactly when the readings converge
    at rate p (here in both directions: a mesh refined in x alone, or by another factor, would
    not); 1e-12 relative is rounding. The fine mesh has ``r·nx × r·ny`` divisions and keeps every
    other option; both meshes are run at the given values; the record names the meshes, the
    element (Q8 unless the spec names another), r and p."""
    coarse = _Scenario({"nx": 3, "ny": 2, "element": "Q4", "thickness": 120.0}, rate)
    refine.coarse = coarse
    meas = Measurement(G0 + 0.01, SENSORS, LEVELS)
    e = discretisation_error(coarse, {"E": 3.0}, meas, refinement=refinement, rate=rate)
    assert_allclose(e.std, coarse.exact_error().ravel(), rtol=1e-12)
    (fine,) = refine.built
    assert fine.spec.options == {"nx": refinement * 3, "ny": refinement * 2, "element": "Q4", "thickness": 120.0}
    assert coarse.runs == [{"E": 3.0}] and fine.runs == [{"E": 3.0}]
    assert (e.method, e.refinement, e.rate, e.tolerance, e.note) == ("two meshes", refinement, rate, None, None)
    assert isinstance(e.refinement, int) and isinstance(e.rate, float)
    assert e.mesh.startswith("Q4 3×2 and ") and f"{3 * refinement}×{2 * refinement}" in e.mesh  # both meshes
    described = e.describe()
    assert "two meshes" in described and e.mesh in described and f"rate p = {rate:g}" in described


def test_default_rate_and_refinement_and_only_the_observed_readings(refine):
    """Defaults r = 2 and p = DEFAULT_RATE (0.8: factor 2^0.8/(2^0.8 − 1) ≈ 2.35); the element
    defaults to Q8; a measurement of two sensors with a missing reading gets one error per
    observed reading, load-major, in its own sensor order (1e-12: rounding)."""
    coarse = _Scenario({"nx": 4, "ny": 1}, DEFAULT_RATE)
    refine.coarse = coarse
    values = np.array([[1.0, 2.0], [np.nan, 3.0]])
    meas = Measurement(values, ("c", "a"), LEVELS)
    e = discretisation_error(coarse, {}, meas)
    exact = coarse.exact_error()
    assert_allclose(e.std, [exact[0, 2], exact[0, 0], exact[1, 0]], rtol=1e-12)
    assert (e.refinement, e.rate) == (2, 0.8) and e.mesh == "Q8 4×1 and 8×2 per unit"
    assert 2**0.8 / (2**0.8 - 1) == pytest.approx(2.35, abs=0.01)


def test_an_observation_operator_interpolates_both_meshes_alike(refine):
    """With an observation operator (measured loads between the model's levels), the difference is
    that of the interpolated readings: at 15 kN, halfway, the error is half the sum of the two
    levels' errors (same sign here), 1e-12 relative."""
    coarse = _Scenario({"nx": 2, "ny": 2}, 1.0)
    refine.coarse = coarse
    meas = Measurement([[1.0, 1.0, 1.0]], SENSORS, [15.0])
    obs = meas.observation(SENSORS, LEVELS, load_response="affine")
    assert not obs.exact
    e = discretisation_error(coarse, {}, meas, rate=1.0, observation=obs)
    exact = coarse.exact_error()
    assert_allclose(e.std, 0.5 * (exact[0] + exact[1]), rtol=1e-12)


def test_a_mesh_dependent_rigid_motion_is_not_counted_as_model_error(refine):
    """DIC readings whose two meshes differ by a rigid rotation and translation of the grid (plus a
    known error at one reading) and a gauge: with the rigid modes the rotation is removed from the
    difference (as it is from data and model), leaving the known error minus its own rigid fit;
    the gauge's error is untouched. Without the modes the rotation counts in full. 1e-9 mm:
    rounding of a 12-reading least-squares fit."""
    sensors = (Gauge("D1", (0.0, 0.0), (100.0, 100.0)), DICGrid("G", 0.0, 0.0, 300.0, 200.0, 2, 2))
    names = tuple(n for s in sensors for n in s.channel_names)
    disp = absolute_displacements(sensors)
    n = len(names)

    def rigid(nx):  # a rotation 1e-4/nx rad and translation 0.01/nx mm: differs between meshes
        out = np.zeros((2, n))
        for j, name in enumerate(names):
            if name in disp:
                x, y, c, _ = disp[name]
                out[:, j] = 0.01 / nx + (1e-4 / nx) * (-y if c == 0 else x)
        return out

    g0, cx = np.ones((2, n)), np.zeros((2, n))
    cx[:, 0] = 0.2  # the gauge's error along x
    cx[1, 3] = 0.5  # one DIC reading's error at the second level
    coarse = _Scenario({"nx": 2, "ny": 2}, 1.0, names, g0, cx, np.zeros((2, n)), shift=rigid)
    refine.coarse = coarse
    meas = Measurement(g0, names, LEVELS)
    modes = rigid_body_modes(meas, disp)
    with_modes = discretisation_error(coarse, {}, meas, rate=1.0, rigid_body=modes)
    known = (cx * 0.5).ravel()
    assert_allclose(with_modes.std, np.abs(modes.remove(known)), atol=1e-9)
    assert with_modes.std[0] == pytest.approx(0.1) and with_modes.std[n] == pytest.approx(0.1)
    assert_allclose(with_modes.std[1:n], 0.0, atol=1e-9)  # first level: a rigid difference only
    without = discretisation_error(coarse, {}, meas, rate=1.0)
    assert without.std[1] > 1e-3  # the rotation counted as model error


@pytest.mark.parametrize("kw", [{"rate": 0.0}, {"rate": -1.0}, {"refinement": 1}])
def test_bad_refinement_or_rate_is_refused_with_both_values(refine, kw):
    coarse = _Scenario({"nx": 2, "ny": 2}, 1.0)
    refine.coarse = coarse
    meas = Measurement(G0, SENSORS, LEVELS)
    r, p = kw.get("refinement", 2), kw.get("rate", DEFAULT_RATE)
    with pytest.raises(ValueError, match=rf"refinement .*≥ 2.*rate > 0.*got {r}, {p}"):
        discretisation_error(coarse, {}, meas, **kw)
    assert refine.built == [] and coarse.runs == []


@pytest.mark.parametrize("options", [{"nx": 2}, {"ny": 2}, {}])
def test_a_scenario_without_mesh_options_asks_for_a_fixed_tolerance(refine, options):
    coarse = _Scenario(options, 1.0)
    refine.coarse = coarse
    with pytest.raises(ValueError, match=r"stand-in: no mesh options nx, ny.*model_tolerance"):
        discretisation_error(coarse, {}, Measurement(G0, SENSORS, LEVELS))


def test_a_refined_mesh_that_cannot_be_built_names_the_factor_and_the_reason(refine):
    """The spec error of the refined mesh (e.g. too many elements) is reported with the scenario,
    the refinement and what to do instead, chained to the original error."""
    refine.coarse = _Scenario({"nx": 2, "ny": 2}, 1.0)
    refine.fail = "nx = 6 exceeds 5"
    with pytest.raises(ValueError, match=r"stand-in: .*refined 3×.*\(nx = 6 exceeds 5\).*model_tolerance") as info:
        discretisation_error(refine.coarse, {}, Measurement(G0, SENSORS, LEVELS), refinement=3)
    assert isinstance(info.value.__cause__, SpecError)


def test_tolerance_error_is_eps_times_each_reading():
    """``e_i = ε |d_i|`` for the observed readings (a missing one left out), recorded as the
    tolerance with its note; relative error ε where d ≠ 0 and 0 at a zero reading."""
    meas = Measurement([[1.0, -2.0, 0.0], [np.nan, 4.0, -0.5]], SENSORS, LEVELS)
    e = tolerance_error(meas, 0.02, note="mesh cannot be refined")
    assert_allclose(e.std, [0.02, 0.04, 0.0, 0.08, 0.01], rtol=1e-15)
    assert (e.method, e.tolerance, e.note, e.refinement, e.rate, e.mesh) == (
        "tolerance", 0.02, "mesh cannot be refined", None, None, None)
    assert_allclose(e.relative(meas), [0.02, 0.02, 0.0, 0.02, 0.02], rtol=1e-15)
    assert "ε = 2 %" in e.describe() and "cannot be refined" in e.describe()  # the value and why it was used
    assert "ε = 1 %" in tolerance_error(meas, FALLBACK_TOLERANCE).describe()
    assert isinstance(tolerance_error(meas, 1).tolerance, float)


def test_relative_error_ignores_readings_of_zero_size():
    """Readings of 1e-12 mm or less (numerical zeros) give relative error 0, not a huge ratio;
    2e-12 mm is a reading."""
    meas = Measurement([[0.0, 1e-13, 2e-12]], SENSORS, [1.0])
    e = ModelError(np.array([1e-3, 1e-3, 1e-14]), "two meshes")
    assert_allclose(e.relative(meas), [0.0, 0.0, 0.005], rtol=1e-12)


def test_relative_error_of_zero_readings_is_zero_whatever_the_memory_held():
    """The zero entries are written, not left to whatever memory the result reuses: after arrays
    of 7.0 of the same size were freed (numpy's allocator hands such blocks out again), 500 zero
    readings still give exactly 0 in each of 20 calls."""
    values = np.zeros((1, 1000))
    values[0, ::2] = 1.0
    meas = Measurement(values, [f"s{i}" for i in range(1000)], [1.0])
    e = ModelError(np.full(1000, 0.01), "tolerance", tolerance=0.01)
    for _ in range(20):
        junk = np.full(1000, 7.0)
        del junk
        rel = e.relative(meas)
        assert np.all(rel[1::2] == 0.0) and np.all(rel[::2] == 0.01)


def test_record_round_trips_and_summarises_the_relative_error():
    """``to_dict`` keeps every field and the per-reading list; with a measurement it adds the
    median and largest relative error; ``summary`` drops the list and adds the description;
    ``from_dict`` restores the fields, and a record written without the optional keys reads back
    with None."""
    meas = Measurement([[1.0, -2.0, 4.0]], SENSORS, [1.0])
    e = ModelError(np.array([0.01, 0.1, 0.08]), "two meshes", refinement=2, rate=0.8, mesh="Q8 2×1 and 4×2 per unit")
    d = e.to_dict()
    assert d == {"method": "two meshes", "tolerance": None, "refinement": 2, "rate": 0.8,
                 "mesh": "Q8 2×1 and 4×2 per unit", "note": None, "std_mm": [0.01, 0.1, 0.08]}
    full = e.to_dict(meas)
    assert full["median_relative"] == pytest.approx(0.02) and full["max_relative"] == pytest.approx(0.05)
    assert type(full["median_relative"]) is float and type(full["max_relative"]) is float
    s = e.summary(meas)
    assert "std_mm" not in s and s["description"] == e.describe() and s["max_relative"] == pytest.approx(0.05)
    assert set(s) == set(full) - {"std_mm"} | {"description"}
    back = ModelError.from_dict(full)
    assert_allclose(back.std, e.std, rtol=0)
    assert back.std.dtype == float
    assert (back.method, back.tolerance, back.refinement, back.rate, back.mesh, back.note) == (
        "two meshes", None, 2, 0.8, "Q8 2×1 and 4×2 per unit", None)
    t = ModelError.from_dict(tolerance_error(meas, 0.01, "why").to_dict())
    assert (t.method, t.tolerance, t.note) == ("tolerance", 0.01, "why")
    bare = ModelError.from_dict({"std_mm": [1, 2], "method": "tolerance"})
    assert bare.std.dtype == float and (bare.tolerance, bare.refinement, bare.rate, bare.mesh, bare.note) == (
        None, None, None, None, None)


@pytest.mark.parametrize("value, expected", [(None, None), ("none", None), (" None ", None), ("estimated", "estimated"),
                                             ("  ESTIMATED", "estimated"), ("0.01", 0.01), (0.02, 0.02), (0, 0.0),
                                             ("0", 0.0), (0.499, 0.499)])
def test_model_form_error_option_accepts_none_estimated_or_a_tolerance(value, expected):
    assert parse_model_form_error(value) == expected


@pytest.mark.parametrize("value, match", [
    ("big", r"--model-form-error .*none, estimated.*\[0, 0\.5\).*got 'big'"),
    ([0.1], r"--model-form-error .*none, .*; got \[0\.1\]"),
    (0.5, r"--model-form-error: .*\[0, 0\.5\); got 0\.5"),
    ("-0.01", r"--model-form-error: .*\[0, 0\.5\); got -0\.01")])
def test_model_form_error_option_refuses_other_values_naming_the_option(value, match):
    """The message names the option, what it accepts and the value given; the user sees no
    internal ``float()`` error chained to it."""
    with pytest.raises(ValueError, match=match) as info:
        parse_model_form_error(value)
    assert info.value.__cause__ is None and (info.value.__context__ is None or info.value.__suppress_context__)


def test_model_form_error_message_names_the_study_key():
    with pytest.raises(ValueError, match=r"\[inversion\] model_form_error: .*tolerance"):
        parse_model_form_error(0.7, source="[inversion] model_form_error")
    with pytest.raises(ValueError, match=r"\[inversion\] model_form_error .*none"):
        parse_model_form_error("x", source="[inversion] model_form_error")
