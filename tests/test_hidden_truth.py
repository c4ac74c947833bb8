"""Hidden-truth coverage of the triplet series (``scripts/hidden_truth.py``): 40 pseudo-experiments
on one set of surrogates, the truth inside the 95 % region of equivalence and the FE capacity of a
fourth triplet (1.4 MPa) inside the 5–95 % band of its RVC in ≥ 36 of 40 each (fewer than 36 of
40 has probability 4.8 % when the coverage is 95 %). The truths are drawn by the script, used to
make the data and to judge the result; the calibration sees only the readings and the noise model.
"""

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from conftest import load_file
from podkrig.online.invert import invert
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.problem import InverseProblem
from podkrig.parameters import Parameter, ParameterSpace
from tests.test_online_results import SIGMA, TRUTH, LinearModel

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "hidden_truth.py"


def _script():
    return load_file(SCRIPT)


def test_truths_stay_away_from_the_faces_and_the_noise_is_the_study_s():
    """The truths fill the middle 80 % of each range (log scale included), distinct and
    reproducible; the pseudo-data's whitened noise, (d − g) / σ with σ = √(σ_abs² + (0.01 g)²)
    at the noise-free reading g, has unit variance (2 000 readings: the sample variance lies within
    ±0.1 of 1 with probability > 0.998); 36 of 40 is the 5 % binomial floor of a 95 % coverage."""
    ht = _script()
    space = ParameterSpace((Parameter("c", 0.15, 0.6), Parameter("G", 0.03, 0.3, scale="log")))
    X = ht.truths(space, 40, 32)
    U = space.to_unit(X)
    assert U.min() >= ht.MARGIN and U.max() <= 1 - ht.MARGIN
    assert len(np.unique(X[:, 0])) == 40
    assert_allclose(ht.truths(space, 40, 32), X, rtol=0, atol=0)  # same seed, same truths
    clean = np.linspace(-40.0, 60.0, 2000)  # kN: readings from the absolute to the relative regime
    data = Measurement(clean.reshape(1000, 2), ("F", "G"), np.arange(1000.0), sensor_units=("kN", "kN"))
    noise = NoiseModel(sigma=0.05, delta=0.01)
    noisy = ht.pseudo_data(data, noise, clean, np.random.default_rng(0))
    z = (noisy.data - clean) / np.hypot(0.05, 0.01 * clean)
    assert abs(z.var() - 1) < 0.1 and abs(z.mean()) < 0.1
    assert ht.binomial_floor(40) == 36


class CornerVarianceModel(LinearModel):
    """The linear model with a predictive std growing to 5 mm (500 σ) at the corner (2, 2) of the
    box: a kriging surrogate's variance far from its training runs, as on the J4D wall's corners."""

    def predict(self, X, return_std=False):
        Y = super().predict(X)
        std = 5.0 * (np.prod(np.atleast_2d(X), axis=1) / 4.0) ** 4
        return (Y, np.repeat(std[:, None], Y.shape[1], axis=1)) if return_std else Y


def test_a_corner_optimum_lies_below_the_truth_only_with_c_t_frozen_there():
    """The J4D finding in closed form. With C_T growing to the corner, ω = ½ Σ r²/(σ² + s(m)²)
    is lowest at the corner: the inversion stops there (every parameter on a bound), below ω(truth).
    With C_T frozen at that corner, ω(truth) ≈ 0 lies below ω(m*) — a negative
    ``omega_excess`` that is no optimiser stop — while ``omega_gap`` (C_T at each point) is
    positive. Defects: either gap computed with the other C_T, or against another point."""
    ht = _script()
    model = CornerVarianceModel()
    clean = LinearModel().predict(TRUTH[None])[0].reshape(2, 3)
    noisy = clean + SIGMA * np.random.default_rng(5).standard_normal(clean.shape)
    problem = InverseProblem(model, Measurement(noisy, model.sensor_names, model.load_levels),
                             NoiseModel(sigma=SIGMA))
    best = invert(problem, rng=0, population_size=20, generations=10, n_starts=2)
    assert set(best.at_bound) == {"m1", "m2"}
    excess, gap = ht.omega_gaps(problem, TRUTH, best.x)
    r_true, r_best = (model.predict(x[None])[0] - noisy.ravel() for x in (TRUTH, best.x))
    s_true, s_best = (model.predict(x[None], return_std=True)[1][0] for x in (TRUTH, best.x))
    omega = lambda r, s: 0.5 * np.sum(r**2 / (SIGMA**2 + s**2))  # noqa: E731
    # closed forms to rounding (sums of 6 squares)
    assert_allclose(excess, omega(r_true, s_best) - omega(r_best, s_best), rtol=1e-9)
    assert_allclose(gap, omega(r_true, s_true) - omega(r_best, s_best), rtol=1e-9)
    assert excess < 0 < gap


@pytest.mark.slow
def test_the_triplet_series_covers_its_hidden_truths(tmp_path, triplet_series_run):
    """The study built once (3 × (128 + 16) training and held-out runs, the 64 runs of its capacity
    triplet at 1.4 MPa), 40 calibrations on its surrogates (~180 s CPU in all): measured 36 of 40
    inside the region and 38 of 40 capacities inside their band (BENCHMARKS.md; the misses are
    explained in docs/strength.md, "Coverage: hidden-truth tests").

    The study's snapshots and surrogates come from the session's ``podkrig run`` of the same study
    file (``--reuse``): its stages are cached by their inputs' contents (study settings, data files),
    so the script's own ``run_study`` skips exactly the stages it would have computed to the same
    files, and the 40 pseudo-experiments run on the same surrogates as without it."""
    folder, exit_code, output = triplet_series_run
    assert exit_code == 0, output[-3000:]
    summary = _script().main(["--study", "triplet", "--n", "40", "--out", str(tmp_path),
                              "--reuse", str(folder / "out" / "triplet_series")])
    assert summary["inside"] >= 36, summary
    assert summary["capacity_inside"] >= 36, summary
