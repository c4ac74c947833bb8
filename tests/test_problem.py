"""The inverse problem (podkrig/online/problem.py) on small analytic models: misfit closed forms
for each misfit kind and model-error choice, the frozen model error, the one-sided Jacobian and the
bounded polish (start, box, budget, evaluation count), the checks of free and fixed parameters, and
the values filled from the scenario. Each test fails for the defects named in its docstring (found
by mutation testing, issue 12); all run in well under a second."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fe.sensors import PointDisplacement
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.problem import (
    FEModel,
    InverseProblem,
    SurrogateModel,
    check_dof,
    fix_from_scenario,
    unit_template,
)
from podkrig.parameters import Parameter, ParameterSpace

SIGMA = 0.01  # mm, noise of every reading
A = np.array([[1.0, 0.5], [0.2, 1.5]])  # (sensors, parameters), mm per parameter unit at 10 kN


class LineModel:
    """Two gauges reading ``(L / 10 kN) · A m`` mm at loads L = 10, 20 kN (linear in the load), with
    predictive std ``0.02 (1 + m1)`` mm on every reading; records every row it evaluates."""

    space = ParameterSpace((Parameter("m1", 0.0, 1.0, unit="MPa"), Parameter("m2", 0.0, 2.0)))
    sensor_names = ("g1", "g2")
    load_levels = np.array([10.0, 20.0])

    def __init__(self):
        self.rows = []

    def clean(self, X):
        X = np.atleast_2d(X)
        return (self.load_levels[None, :, None] / 10.0 * (X @ A.T)[:, None, :]).reshape(len(X), -1)

    def std(self, X):
        return np.repeat(0.02 * (1.0 + np.atleast_2d(X)[:, :1]), 4, axis=1)

    def predict(self, X, return_std=False):
        X = np.atleast_2d(X)
        self.rows.extend(X.tolist())
        Y = self.clean(X)
        return (Y, self.std(X)) if return_std else Y


class UnitLineModel(LineModel):
    """The same model with a unit-cube entry point, as the surrogate has."""

    def predict_unit(self, U, return_std=False):
        return self.predict(self.space.from_unit(np.atleast_2d(U)), return_std=return_std)


def _data(model, x, loads=(10.0, 20.0)):
    """Exact readings ``(L / 10 kN) · A x`` of the two gauges at ``loads`` (kN)."""
    values = np.array([L / 10.0 * (A @ np.asarray(x, dtype=float)) for L in loads])
    return Measurement(values, model.sensor_names, np.array(loads), source="line.csv")


TRUTH = np.array([0.3, 1.1])


def test_omega_is_the_closed_form_of_each_misfit_kind():
    """Defects: the misfit kind or the model-error choice not passed on to the misfit."""
    model = LineModel()
    meas = _data(model, TRUTH)
    d = model.clean(TRUTH)[0]
    x = np.array([0.5, 0.9])
    r = model.clean(x)[0] - d
    s_t = model.std(x)[0]
    cases = {
        ("gaussian", True): 0.5 * np.sum(r**2 / (SIGMA**2 + s_t**2)),  # C_D = C_d + C_T, eq. 2.10
        ("gaussian", False): 0.5 * np.sum(r**2 / SIGMA**2),
        ("relative", False): 0.5 * np.sum((r / d) ** 2),
    }
    for (kind, model_error), omega in cases.items():
        problem = InverseProblem(model, meas, NoiseModel(sigma=SIGMA), kind=kind, model_error=model_error)
        assert problem.omega(x)[0] == pytest.approx(omega, rel=1e-12), (kind, model_error)


def test_the_model_std_is_asked_for_only_when_it_enters_c_d():
    """With ``model_error`` the model's std is asked for at every evaluated row, on both entry
    points; without it only the means (for kriging the std costs O(n²) per point against O(n d)),
    and ω is the same as when the std was computed and dropped. Defects: the std computed without
    model_error, or dropped with it."""

    class AskingModel(UnitLineModel):
        def predict(self, X, return_std=False):
            self.asked.append(return_std)
            return super().predict(X, return_std)

    x = np.array([[0.5, 0.9], [0.2, 1.4]])
    for model_error in (True, False):
        model = AskingModel()
        model.asked = []
        problem = InverseProblem(model, _data(model, TRUTH), NoiseModel(sigma=SIGMA), model_error=model_error)
        omega = problem.omega(x)
        omega_unit = problem.omega_unit(problem.free_space.to_unit(x))
        assert model.asked == [model_error, model_error]
        r = model.clean(x) - model.clean(TRUTH)
        var = SIGMA**2 + (model.std(x) ** 2 if model_error else 0.0)
        assert_allclose(omega, 0.5 * np.sum(r**2 / var, axis=1), rtol=1e-12)
        assert_allclose(omega_unit, omega, rtol=1e-12)


def test_frozen_model_error_uses_the_std_at_the_freezing_point():
    """Defects: the std not frozen (or frozen at another point), a model without predictive variance
    not returned as it is, the unit-cube path of a frozen problem ignoring the frozen std."""
    for model in (LineModel(), UnitLineModel()):
        problem = InverseProblem(model, _data(model, TRUTH), NoiseModel(sigma=SIGMA))
        x0, x1 = np.array([0.9, 1.0]), np.array([0.1, 1.2])
        frozen = problem.freeze_model_error(x0)
        r = model.clean(x1)[0] - model.clean(TRUTH)[0]
        expected = 0.5 * np.sum(r**2 / (SIGMA**2 + model.std(x0)[0] ** 2))
        assert frozen.omega(x1)[0] == pytest.approx(expected, rel=1e-12)
        assert frozen.omega_unit(problem.free_space.to_unit(x1[None]))[0] == pytest.approx(expected, rel=1e-12)
        # unfrozen: the std at x1 itself (0.022 mm, not 0.038 mm)
        unfrozen = 0.5 * np.sum(r**2 / (SIGMA**2 + model.std(x1)[0] ** 2))
        assert problem.omega_unit(problem.free_space.to_unit(x1[None]))[0] == pytest.approx(unfrozen, rel=1e-12)

    class NoVarianceModel(LineModel):  # as FEModel: predict(..., return_std=True) gives std None
        def predict(self, X, return_std=False):
            Y = self.clean(X)
            return (Y, None) if return_std else Y

    problem = InverseProblem(NoVarianceModel(), _data(LineModel(), TRUTH), NoiseModel(sigma=SIGMA))
    assert problem.freeze_model_error(TRUTH) is problem


def test_jacobian_is_exact_for_a_linear_model_and_one_sided_at_the_faces():
    """Defects: the Jacobian step taken outside the box at an upper face (extrapolation), integer
    corner coordinates truncating the steps to zero."""
    model = LineModel()
    problem = InverseProblem(model, _data(model, TRUTH), NoiseModel(sigma=SIGMA), model_error=False)
    widths = np.array([1.0, 2.0])  # upper − lower of m1, m2
    # whitened residuals (L/10)(A m − A m*)/σ per load: d/du = (L/10) A diag(widths) / σ
    expected = np.vstack([L / 10.0 * A * widths / SIGMA for L in (10.0, 20.0)])
    for u in (np.array([1, 0]), np.array([1.0, 1.0]), np.array([0.5, 0.0])):
        model.rows.clear()
        assert_allclose(problem.jacobian_unit(u), expected, rtol=1e-6)
        rows = np.array(model.rows)
        assert np.all(rows >= 0.0) and np.all(rows[:, 0] <= 1.0) and np.all(rows[:, 1] <= 2.0)
    # the polish (Gauss-Newton on a linear model) lands on the truth; its count is the rows evaluated
    model.rows.clear()
    x, n_evaluations = problem.polish([0.9, 0.1])
    assert_allclose(x, TRUTH, rtol=1e-8)
    assert n_evaluations == len(model.rows)


class TwoBasinModel:
    """One parameter m in [0, 1]; two gauges read ``c (m − 0.2)(m − 0.8)`` mm at 10 kN: with zero
    data, exact minima at m = 0.2 and m = 0.8."""

    space = ParameterSpace((Parameter("m", 0.0, 1.0),))
    sensor_names = ("g1", "g2")
    load_levels = np.array([10.0])

    def __init__(self):
        self.n_rows = 0

    def predict(self, X, return_std=False):
        m = np.atleast_2d(X)[:, :1]
        self.n_rows += len(m)
        Y = np.hstack([1.0, 2.0]) * (m - 0.2) * (m - 0.8)
        return (Y, np.zeros_like(Y)) if return_std else Y


def _zero_data(model, value=0.0):
    return Measurement(np.full((1, 2), value), model.sensor_names, model.load_levels, source="zero.csv")


def test_polish_is_local_bounded_budgeted_and_counts_its_evaluations():
    """Defects: the start not clipped into the box (or moved to a face), the bounds dropped or
    widened, the budget ignored, the Jacobian not the batched one, the evaluation count wrong."""
    model = TwoBasinModel()
    problem = InverseProblem(model, _zero_data(model), NoiseModel(sigma=SIGMA))
    for x0, basin in ((0.25, 0.2), (0.75, 0.8), (1.7, 0.8)):  # a start outside: from the face
        model.n_rows = 0
        x, n_evaluations = problem.polish([x0])
        assert x[0] == pytest.approx(basin, abs=1e-6), x0
        assert n_evaluations == model.n_rows  # the reported count is the model rows evaluated
    assert 0.0 <= problem.polish([-0.5])[0][0] <= 1.0  # below the box: clipped, never an error
    # budget: one residual evaluation (and at most one Jacobian of 2 rows) instead of convergence
    model.n_rows = 0
    x, n_evaluations = problem.polish([0.45], max_nfev=1)
    assert n_evaluations == model.n_rows <= 3 and abs(x[0] - 0.2) > 1e-3
    # data that only m = 1.3 would fit (readings 0.55 c): the polish stops at the face m = 1
    problem = InverseProblem(model, Measurement(np.array([[0.55, 1.1]]), model.sensor_names, model.load_levels,
                                                source="high.csv"), NoiseModel(sigma=SIGMA))
    x, _ = problem.polish([0.9])
    assert x[0] == pytest.approx(1.0, abs=1e-9)


def test_polish_from_the_lower_face_reaches_the_nearest_basin():
    """With zero data the start m = 0 (the GA's best clipped to the face) lies in the basin of
    m = 0.2 (cost 640 at the face, gradient pointing inward). Defect (found by mutation testing):
    started exactly on the face, scipy's 'trf' stopped at m = 2e-10."""
    model = TwoBasinModel()
    problem = InverseProblem(model, _zero_data(model), NoiseModel(sigma=SIGMA))
    assert problem.polish([0.0])[0][0] == pytest.approx(0.2, abs=1e-6)


def test_free_and_fixed_parameters_are_checked_with_messages_that_say_what_to_do():
    """Defects: a parameter both free and fixed accepted, the "no free parameter" message not
    listing the parameters, a fixed value at a bound of the trained box refused, the unit-cube
    template accepting a parameter that is neither free nor fixed."""
    model, noise = LineModel(), NoiseModel(sigma=SIGMA)
    meas = _data(model, TRUTH)
    with pytest.raises(ValueError, match=r"\['m1'\] .*both free and fixed"):
        InverseProblem(model, meas, noise, free=("m1",), fixed={"m1": 0.5, "m2": 1.0})
    with pytest.raises(ValueError, match="no free parameters.*m1, m2"):
        InverseProblem(model, meas, noise, free=(), fixed={"m1": 0.5, "m2": 1.0})
    for bound in (0.0, 2.0):  # the box is closed
        assert InverseProblem(model, meas, noise, free=("m1",), fixed={"m2": bound}).parameters_at([0.5])["m2"] == bound
    with pytest.raises(ValueError, match="outside the model's trained range"):
        InverseProblem(model, meas, noise, free=("m1",), fixed={"m2": 2.0 + 1e-9})
    with pytest.raises(ValueError, match=r"\['m2'\] are neither free nor fixed"):
        unit_template(model.space, [0], {})
    assert_allclose(unit_template(model.space, [0], {"m2": 1.5}), [0.0, 0.75])


def test_load_response_and_load_unit_of_the_model_reach_the_measurement():
    """Defects: the model's load response (readings between levels) or load unit (in messages and
    in the measurement summary) not passed on."""
    noise = NoiseModel(sigma=SIGMA)

    class AffineModel(LineModel):
        load_response = "affine"
        load_unit = "kN"

    meas = _data(AffineModel(), TRUTH, loads=(15.0,))  # between the levels 10 and 20 kN
    problem = InverseProblem(AffineModel(), meas, noise, model_error=False)
    assert problem.omega(TRUTH)[0] == pytest.approx(0.0, abs=1e-20)  # linear in the load: exact
    assert problem.omega(TRUTH + [0.1, 0.0])[0] == pytest.approx(0.5 * np.sum((0.15 * A[:, 0] / SIGMA) ** 2))
    assert problem.measurement_summary()["load_unit"] == "kN"

    class DiscreteKN(LineModel):
        load_unit = "kN"

    with pytest.raises(ValueError, match=r"unknown load level 15 kN; "):
        InverseProblem(DiscreteKN(), meas, noise)
    with pytest.raises(ValueError, match=r"unknown load level 15; "):  # a model without a load unit
        InverseProblem(LineModel(), meas, noise)

    class NewtonModel(LineModel):
        load_unit = "N"

    assert InverseProblem(NewtonModel(), _data(model := LineModel(), TRUTH), noise).measurement_summary()["load_unit"] == "N"
    assert InverseProblem(model, _data(model, TRUTH), noise).measurement_summary()["load_unit"] == "kN"  # default


class _PositionedLineModel(LineModel):
    """The line model with point displacement sensors (as a DIC grid has), whose positions a
    surrogate would rebuild its scenario to give: every look at them is counted."""

    sensor_names = ("P1x", "P1y")
    looked_at_sensors = 0

    @property
    def sensors(self):
        type(self).looked_at_sensors += 1
        return (PointDisplacement("P1x", (0.0, 0.0), "x"), PointDisplacement("P1y", (0.0, 0.0), "y"))


def test_constructing_a_problem_only_checks_it_and_the_misfit_is_built_on_first_use():
    """Constructing an inverse problem (and each copy made by ``dataclasses.replace``) checks the
    parameter choice and the data against the model, and does nothing heavy: no model evaluation,
    no sensor positions asked for (a surrogate rebuilds its scenario for them), no noise covariance.
    Defect: work moved back into the constructor. The misfit is built once, on first use, and is
    the same object afterwards; it builds its noise covariance when first evaluated; bad data are
    still refused by the constructor."""
    model = _PositionedLineModel()
    _PositionedLineModel.looked_at_sensors = 0
    data = Measurement(np.array([[0.1, 0.2], [0.2, 0.4]]), model.sensor_names, np.array([10.0, 20.0]))
    problem = InverseProblem(model, data, NoiseModel(sigma=SIGMA), rigid_body="remove")
    copy = problem.with_noisy_data(TRUTH, np.random.default_rng(0))  # evaluates the model once, at TRUTH
    assert model.rows == [TRUTH.tolist()] and _PositionedLineModel.looked_at_sensors == 1  # the original's misfit
    assert "misfit" not in vars(copy)
    misfit = copy.misfit
    assert _PositionedLineModel.looked_at_sensors == 2 and copy.misfit is misfit
    assert copy.n_removed == 2 * 2  # x and y translations at each of 2 loads (no rotation from one point)
    fresh = InverseProblem(model, data, NoiseModel(sigma=SIGMA), rigid_body="keep")
    assert "_Cd" not in vars(fresh.misfit)  # the misfit builds its noise covariance on first evaluation
    fresh.omega(TRUTH[None])
    assert "_Cd" in vars(fresh.misfit)
    with pytest.raises(ValueError, match=r"unknown sensor|P9x"):  # the data are still checked at once
        InverseProblem(model, Measurement(np.zeros((2, 1)), ("P9x",), np.array([10.0, 20.0])), NoiseModel(sigma=SIGMA))


def test_noisy_copy_keeps_its_provenance():
    """Defect: the noisy copy of a measurement loses its source (reports name the data file)."""
    model = LineModel()
    problem = InverseProblem(model, _data(model, TRUTH), NoiseModel(sigma=SIGMA))
    copy = problem.with_noisy_data(TRUTH, np.random.default_rng(0))
    assert copy.measurement.source.startswith("line.csv") and "noisy copy" in copy.measurement.source


def test_fix_from_scenario_fills_defaults_at_the_box_faces_and_skips_unknown_names():
    """Defects: a scenario default exactly at a bound of the box not taken, a parameter missing from
    the spec not given the scenario's default, a model parameter the scenario does not know (or a
    model without a scenario spec) raising instead of being left to the caller."""

    class Model:
        # E_b default 12000 = lower bound, nu_b default 0.15 = upper bound, kN_bj default 100 (in the
        # box, not in the spec), "extra" unknown to the scenario
        space = ParameterSpace((Parameter("E_b", 12000.0, 20000.0), Parameter("nu_b", 0.1, 0.15),
                                Parameter("kN_bj", 10.0, 150.0), Parameter("kV_bj", 1.0, 50.0),
                                Parameter("extra", 0.0, 1.0)))
        scenario_spec = {"scenario": "diagonal_compression", "parameters": {"kV_bj": 30.0}}

    free, fixed = fix_from_scenario(Model(), ("extra",), {})
    assert free == ("extra",) and fixed == {"E_b": 12000.0, "nu_b": 0.15, "kN_bj": 100.0, "kV_bj": 30.0}
    free, fixed = fix_from_scenario(Model(), ("E_b", "nu_b", "kN_bj", "kV_bj"), {})
    assert fixed == {}  # "extra" has no scenario value: InverseProblem will report it

    class NoSpec:
        space = Model.space

    assert fix_from_scenario(NoSpec(), ("E_b",), {"nu_b": 0.12}) == (("E_b",), {"nu_b": 0.12})


def test_check_dof_counts_and_refuses_no_degrees_of_freedom():
    """Defects: dof ≠ n_obs − n_free, dof = 0 accepted, a message without both counts."""
    assert check_dof(12, ("a", "b")) == 10
    assert check_dof(3, ["a", "b"]) == 1  # any sequence of names
    with pytest.raises(ValueError, match=r"data.csv: 2 reading\(s\).*2 free parameter\(s\) \(a, b\)") as raised:
        check_dof(2, ("a", "b"), "data.csv")
    assert "2 − 2 = 0" in str(raised.value) and "fix parameters" in str(raised.value)  # the count, a remedy
    with pytest.raises(ValueError, match=r"measurement: 1 reading\(s\) .*1 − 3 = -2"):
        check_dof(1, ("a", "b", "c"))


class _Readings:
    def __init__(self, readings):
        self.readings = readings


class _Scenario:
    """An FE stand-in: readings ``(L / 10 kN) · A m`` of 2 gauges at 10, 20 kN, from a parameter dict."""

    sensor_names = ("g1", "g2")
    sensors = ()  # no absolute displacements (nothing rigid to remove)
    load_levels = (10, 20)
    load_unit = "kN"
    load_response = "affine"

    def run(self, params):
        m = np.array([params["m1"], params["m2"]])
        return _Readings(np.array([L / 10.0 * (A @ m) for L in self.load_levels]))


def test_fe_model_runs_one_scenario_per_row_and_passes_the_scenario_on():
    """Defects: rows not all run or run with other values, the run count wrong, the scenario's
    sensors, levels, unit or load response not exposed, a std returned for the FE model."""
    model = FEModel(_Scenario(), LineModel.space)
    assert model.sensor_names == ("g1", "g2") and model.load_unit == "kN" and model.load_response == "affine"
    assert model.load_levels.dtype == float and model.load_levels.tolist() == [10.0, 20.0]
    X = np.array([[0.3, 1.1], [1.0, 0.0], [0.0, 2.0]])
    assert_allclose(model.predict(X), LineModel().clean(X), rtol=1e-15)
    Y, std = model.predict(X[0], return_std=True)
    assert std is None and Y.shape == (1, 4) and model.n_runs == 4
    assert_allclose(Y[0], LineModel().clean(X[0])[0], rtol=1e-15)

    class Bare:  # a scenario without a load response: discrete levels
        sensor_names, sensors, load_levels, load_unit, run = ("g1",), (), (1.0,), "mm", None

    assert FEModel(Bare(), LineModel.space).load_response == "discrete"


class _Surrogate:
    """What SurrogateModel reads of a fitted PODKriging: space, provenance_, predict, predict_unit."""

    def __init__(self, provenance, space=LineModel.space):
        self.provenance_ = provenance
        self.space = space
        self.line = UnitLineModel()

    def predict(self, X, return_std=False):
        return self.line.predict(X, return_std=return_std)

    def predict_unit(self, U, return_std=False):
        return self.line.predict_unit(U, return_std=return_std)


def test_surrogate_model_exposes_the_provenance_and_refuses_what_cannot_invert():
    """Defects: a surrogate without sensors, levels, spec or space accepted (or the message not
    naming what is missing and how to build one), a field surrogate accepted, provenance values
    (sensors, levels, unit, spec, the scenario's load response) not exposed, predictions altered."""
    spec = {"scenario": "diagonal_compression", "parameters": {}}
    prov = {"sensor_names": ["g1", "g2"], "load_levels": [10, 20], "scenario_spec": spec, "load_unit": "N"}
    model = SurrogateModel(_Surrogate(prov))
    assert model.sensor_names == ("g1", "g2") and model.load_levels.tolist() == [10.0, 20.0]
    assert model.load_levels.dtype == float and model.load_unit == "N" and model.scenario_spec == spec
    assert model.space is LineModel.space and model.load_response == "affine"  # diagonal_compression
    X = np.array([[0.3, 1.1], [0.9, 0.2]])
    Y, std = model.predict(X, return_std=True)
    assert_allclose(Y, LineModel().clean(X), rtol=1e-15)
    assert_allclose(std, LineModel().std(X), rtol=1e-15)
    Yu, stdu = model.predict_unit(LineModel.space.to_unit(X), return_std=True)
    assert_allclose(Yu, Y, rtol=1e-12)
    assert_allclose(stdu, std, rtol=1e-12)
    assert_allclose(model.predict(X), Y, rtol=1e-15)
    assert_allclose(model.predict_unit(LineModel.space.to_unit(X)), Y, rtol=1e-12)

    defaults = SurrogateModel(_Surrogate({k: v for k, v in prov.items() if k != "load_unit"}
                                         | {"scenario_spec": {"scenario": "flat_jack"}}))
    assert defaults.load_unit == "kN" and defaults.load_response == "discrete"  # flat_jack
    assert SurrogateModel(_Surrogate(prov | {"scenario_spec": "not a dict"})).load_response == "discrete"
    assert SurrogateModel(_Surrogate(prov | {"output": "readings"})).sensor_names == ("g1", "g2")

    build = "'podkrig surrogate build'"
    with pytest.raises(ValueError, match=r"lacks \['sensor_names', 'scenario_spec'\]: .*" + build):
        SurrogateModel(_Surrogate({"load_levels": [10]}))
    with pytest.raises(ValueError, match=r"lacks \['a parameter space'\]: .*" + build):
        SurrogateModel(_Surrogate(prov, space=None))
    with pytest.raises(ValueError, match="predicts displacement fields.*sensor readings"):
        SurrogateModel(_Surrogate(prov | {"output": "field"}))


def test_surrogate_model_rebuilds_its_training_scenario():
    """Defects: the scenario not rebuilt from the surrogate's spec (its parameter values lost), the
    solver choice not passed on. Two scenario builds, ~0.7 s each."""
    spec = {"scenario": "diagonal_compression", "parameters": {"E_b": 15000.0}}
    prov = {"sensor_names": ["D1"], "load_levels": [10], "scenario_spec": spec}
    model = SurrogateModel(_Surrogate(prov))
    scenario = model.scenario(solver="superlu")
    assert scenario.name == "diagonal_compression" and scenario.parameters["E_b"].default == 15000.0
    assert model.scenario().spec == scenario.spec  # the default solver ("auto") builds it too
    with pytest.raises(ValueError, match="unknown solver backend 'no-such-solver'"):
        model.scenario(solver="no-such-solver")
