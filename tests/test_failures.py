"""Where FE runs fail (:mod:`podkrig.offline.failures`): the classifier of the failing region
against a hidden boundary, its words, and the inversion's warning when the best fit lies in it."""

from types import SimpleNamespace

import numpy as np
import pytest

from podkrig.offline.failures import FailureRegion, FailureReport
from podkrig.online.calibrate import calibrate
from podkrig.online.findings import FAILURE_PROBABILITY_LIMIT, Finding, failure_findings
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.problem import InverseProblem
from podkrig.online.settings import CalibrationSettings, InversionSettings, RegionSettings
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.reports.findings import word
from podkrig.reports.offline import failure_lines

NAMES = ("ft", "GfI", "c")


def _hidden_truth(U):
    """Runs fail where GfI (coordinate 1) exceeds a boundary that tilts slightly with ft; c plays no part."""
    return U[:, 1] > 0.6 + 0.1 * (U[:, 0] - 0.5)


@pytest.fixture(scope="module")
def region():
    U = np.random.default_rng(0).random((200, 3))
    return FailureRegion.fit(U, _hidden_truth(U), NAMES)


def test_the_classifier_separates_a_failing_half_space_and_names_its_driver(region):
    """Hidden truth: a known boundary. On 2 000 held-out points the classifier puts ≥ 90 % on the
    right side, names GfI (towards high values) as what drives failure, and not c."""
    U = np.random.default_rng(1).random((2000, 3))
    accuracy = np.mean((region.probability(U) > 0.5) == _hidden_truth(U))
    assert accuracy >= 0.9
    assert region.driving()[0] == "GfI" and region.direction("GfI") == "high"
    assert "c" not in region.driving()


def test_the_classifier_round_trips_and_needs_both_outcomes(region):
    again = FailureRegion.from_dict(region.to_dict())
    assert again == region
    report = FailureReport(200, (1, 2), {"iterations": 2}, region)
    assert FailureReport.from_dict(report.to_dict()) == report
    with pytest.raises(ValueError, match="at least 2 failed"):
        FailureRegion.fit(np.random.default_rng(0).random((10, 3)), np.eye(10, dtype=bool)[0], NAMES)


def test_the_failure_report_in_words_gives_share_reasons_and_region(region):
    lines = failure_lines(FailureReport(40, tuple(range(10)), {"iterations": 8, "not converged": 2}, region))
    assert "10 of 40 FE runs (25 %)" in lines[0]
    assert "8 ran out of their iteration budget" in lines[0] and "2 did not converge" in lines[0]
    assert "towards high GfI" in lines[1]


def test_the_near_failure_finding_fires_inside_the_region_and_not_far_from_it(region):
    (f,) = failure_findings(region, 0.4, [0.5, 0.95, 0.5])
    assert f.code == "near-failure" and f.values["probability"] > 0.9
    assert f.values["driving"][0] == {"parameter": "GfI", "towards": "high"}
    text = word(f)
    assert "40 % of the training FE runs failed" in text.message and "high GfI" in text.message
    assert "max_total_iterations" in text.remedy
    assert failure_findings(region, 0.4, [0.5, 0.1, 0.5]) == []
    assert region.probability([[0.5, 0.1, 0.5]])[0] < FAILURE_PROBABILITY_LIMIT


class _Linear:
    """Readings ``A m`` of 3 sensors at 2 loads (a stand-in surrogate), with the provenance of a
    store whose runs failed in ``region``."""

    sensor_names = ("g1", "g2", "g3")
    load_levels = np.array([10.0, 20.0])
    load_unit = "kN"

    def __init__(self, region):
        self.space = ParameterSpace(tuple(Parameter(n, 0.0, 2.0, unit="MPa") for n in NAMES))
        self.A = np.random.default_rng(3).uniform(0.2, 2.0, (6, 3))
        self.surrogate = SimpleNamespace(provenance_={"failure_region": region.to_dict(), "failed_share": 0.3})

    def predict(self, X, return_std=False):
        Y = np.atleast_2d(X) @ self.A.T
        return (Y, np.zeros_like(Y)) if return_std else Y


@pytest.mark.parametrize("gfi, fires", [(1.9, True), (0.3, False)])
def test_the_inversion_warns_when_its_best_fit_lies_in_the_failing_region(region, gfi, fires):
    """Data from parameters inside the failing region (GfI at 95 % of its range) raise
    ``near-failure`` with the predicted probability; data from far outside it (15 %) do not."""
    model = _Linear(region)
    truth = np.array([[1.0, gfi, 1.0]])
    data = model.predict(truth)[0].reshape(2, 3)
    problem = InverseProblem(model, Measurement(data, model.sensor_names, model.load_levels, source="lin.csv"),
                             NoiseModel(sigma=0.01), model_error=False)
    settings = CalibrationSettings(inversion=InversionSettings(population_size=20, generations=10, n_starts=2),
                                   region=RegionSettings(samples=2**10), fe_check=False)
    result = calibrate(problem, settings, check_measurement=False)
    near = [f for f in result.findings if f.code == "near-failure"]
    assert bool(near) == fires
    if fires:
        assert isinstance(near[0], Finding) and near[0].values["probability"] >= FAILURE_PROBABILITY_LIMIT
