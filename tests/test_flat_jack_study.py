"""The flat-jack example study: the file is valid and its pseudo-measured data are reproducible."""

from pathlib import Path

import numpy as np

from conftest import load_file
from podkrig.study.schema import load_study

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_flat_jack_study_is_valid():
    study = load_study(EXAMPLES / "flat_jack.toml")
    assert study.spec.scenario == "flat_jack" and study.spec.options["phases"] == ["0b", "1", "2"]
    assert study.space.names == ("E_b", "kN_bj", "kV_bj", "r_hj", "Km")
    assert study.fixed == {"nu_b": 0.15, "sigma0": 0.30}
    assert study.measurement.noise_abs == 0.002
    assert study.validation[0].spec.options["preset"] == "double"


def test_flat_jack_data_is_reproducible(tmp_path):
    """examples/make_flat_jack_data.py regenerates the shipped pseudo-measured data (the flat-jack
    study's, and the joint calibration's at the demo's hidden values)."""
    module = load_file(EXAMPLES / "make_flat_jack_data.py")
    for shipped_path, seed, truth in ((module.OUT, module.SEED, module.TRUTH),
                                      (module.JOINT_OUT, module.JOINT_SEED, module.JOINT_TRUTH)):
        made = module.make(tmp_path / "made.csv", seed, truth=truth).read_text().splitlines()
        shipped = shipped_path.read_text().splitlines()
        assert made[0] == shipped[0] and len(made) == 21  # header + 20 steps
        a = np.array([[float(c) for c in row.split(",")] for row in made[1:]])
        b = np.array([[float(c) for c in row.split(",")] for row in shipped[1:]])
        # written to 0.01 µm; solver differences are far below
        np.testing.assert_allclose(a, b, rtol=0, atol=1.5e-8, err_msg=shipped_path.name)
