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
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.parameters import Parameter, ParameterSpace

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


@pytest.mark.slow
def test_the_triplet_series_covers_its_hidden_truths(tmp_path):
    """The study built once (3 × (128 + 16) training and held-out runs, the 64 runs of its capacity
    triplet at 1.4 MPa), 40 calibrations on its surrogates (~180 s CPU in all): measured 36 of 40
    inside the region and 38 of 40 capacities inside their band (BENCHMARKS.md; the misses are
    explained in docs/strength.md, "Coverage: hidden-truth tests")."""
    summary = _script().main(["--study", "triplet", "--n", "40", "--out", str(tmp_path)])
    assert summary["inside"] >= 36, summary
    assert summary["capacity_inside"] >= 36, summary
