"""Pseudo-data shared by the front end's API and browser tests: the readings of a coarse diagonal
compression test at :data:`TRUTH` (:func:`measured`), and a tiny joint study — a diagonal and a
shear test sharing kN_bj and kV_bj, the shear test with its own r_hj; 16 training runs per test,
noise-free pseudo-data at :data:`TRUTH` (the shear test's r_hj at :data:`SHEAR_R_HJ`)."""

import numpy as np

from fe.scenarios import build_scenario
from podkrig.io.measurement_log import write_measurement_csv
from podkrig.online.measurement import Measurement

TRUTH = {"E_b": 11000.0, "r_hj": 0.6, "kN_bj": 90.0, "kV_bj": 35.0}
DIAGONAL_R_HJ, SHEAR_R_HJ = TRUTH["r_hj"], 0.45


def measured(path, seed=0, scale=1.0):
    """Pseudo-measured readings (mm) of the diagonal compression test on a 2 × 1 mesh at
    :data:`TRUTH`, with 1 % noise (``seed``) and multiplied by ``scale``, written to ``path``;
    returns them ``(n_loads, n_sensors)``."""
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    clean = sc.run(TRUTH).readings
    noisy = clean * (1 + 0.01 * np.random.default_rng(seed).standard_normal(clean.shape)) * scale
    write_measurement_csv(path, Measurement(noisy, sc.sensor_names, sc.load_levels))
    return noisy

STUDY = """\
name = "tiny_joint_serve"

[parameters]
kN_bj = { lower = 30.0, upper = 300.0, scale = "log" }
kV_bj = { lower = 10.0, upper = 120.0, scale = "log" }

[fixed]
E_b = 11000.0

[sampling]
train = { n = 16, seed = 0 }
held_out = { n = 4, seed = 1, method = "random" }
workers = 1

[inversion]
population_size = 20
generations = 10
n_starts = 2
region_samples = 4096

[[test]]
name = "diagonal"
scenario = { scenario = "diagonal_compression", nx = 2, ny = 1 }
measurement = { file = "diagonal.csv", noise_abs = 0.001, noise_rel = 0.01 }
fixed = { r_hj = 0.6 }

[[test]]
name = "shear"
scenario = { scenario = "shear_compression", nx = 2, ny = 1 }
measurement = { file = "shear.csv", noise_abs = 0.001, noise_rel = 0.01 }
parameters = { r_hj = { lower = 0.2, upper = 1.0 } }
"""


def write_joint_study(folder):
    """The study file and its two measurement files in ``folder``; returns the study file."""
    for name, scenario, r_hj in (("diagonal", "diagonal_compression", DIAGONAL_R_HJ),
                                 ("shear", "shear_compression", SHEAR_R_HJ)):
        sc = build_scenario({"scenario": scenario, "nx": 2, "ny": 1})
        clean = sc.run({**TRUTH, "r_hj": r_hj}).readings
        write_measurement_csv(folder / f"{name}.csv", Measurement(clean, sc.sensor_names, sc.load_levels))
    (folder / "study.toml").write_text(STUDY)
    return folder / "study.toml"
