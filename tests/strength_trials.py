"""Hidden-effect trials on a strength test's curve: one EN 1052-3 triplet (``triplet_shear`` at
0.6 MPa, the triplet series' 14 control levels) read as a force–displacement curve with two gauges,
``F`` (kN), ``middle_ux`` and ``V_top`` (mm), noise 1 % + 0.05 kN on the force and 1 % + 2 µm on the
gauges (the triplet series' noise model), for testing and benchmarking the diagnosis's strength
candidates. The effect — a weaker bond of one bed joint (``joint_strength_factors``) or dilatancy
(``tanpsi_bj``) — is drawn here, from the trial's own generator, and only the noisy curve, the noise
model and the base model reach the diagnosis.

The base model is the specimen's against its series: the joints' cohesion and friction fixed at
the series' *identified* values (``SERIES_FIT``, docs/strength.md, not this trial's truth),
the mode-II fracture energy free. (With the cohesion free as well, a 20–30 % weaker joint is
absorbed by a lower c_bj: :func:`identifiable_weak_joint` measures it.)
"""

from dataclasses import dataclass

import numpy as np

from fe import build_scenario
from podkrig.diagnosis import DiagnosisSettings, diagnose
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.parameters import Parameter, ParameterSpace

LEVELS = [0.01, 0.02, 0.03, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0]
SPEC = {"scenario": "triplet_shear", "precompression": 0.6, "load_levels": LEVELS}
#: the hidden joint law (the triplet series' truth, examples/make_triplet_series.py)
TRUTH = {"c_bj": 0.30, "tanphi_bj": 0.85, "GfII_bj": 0.10, "ft_bj": 0.10}
#: the base model's fixed values: the series' identified cohesion and friction (docs/strength.md)
SERIES_FIT = {"c_bj": 0.303, "tanphi_bj": 0.845}
NOISE_ABS = {"middle_ux": 0.002, "V_top": 0.002, "F": 0.05}  # mm, mm, kN
NOISE_REL = 0.01
BOUNDS = {"c_bj": (0.15, 0.6), "tanphi_bj": (0.6, 1.1), "GfII_bj": (0.03, 0.3)}


@dataclass(frozen=True, eq=False)
class StrengthTrial:
    """One pseudo-experiment: ``effect`` (None, "weak_joint_strength" or "dilatancy"), where and
    how strong (``joint``: 0 lower, 1 upper; ``value``: the factor s or tanψ), the curve."""

    effect: str | None
    joint: int | None
    value: float | None
    measurement: Measurement
    noise: NoiseModel


def noise_model():
    return NoiseModel(sigma=dict(NOISE_ABS), delta=NOISE_REL, units={"F": "kN"})


def make_strength_trial(effect, rng):
    """A noisy curve with ``effect`` drawn from ``rng``: a weak joint (lower or upper, s uniform in
    [0.7, 0.8]: 20–30 % weaker), dilatancy (tanψ uniform in [0.03, 0.1]) or none."""
    options, values, joint, value = {}, {}, None, None
    if effect == "weak_joint_strength":
        joint, value = int(rng.integers(2)), float(rng.uniform(0.7, 0.8))
        factors = [1.0, 1.0]
        factors[joint] = value
        options = {"joint_strength_factors": factors}
    elif effect == "dilatancy":
        value = float(rng.uniform(0.03, 0.1))
        values = {"tanpsi_bj": value}
    elif effect is not None:
        raise ValueError(f"unknown effect {effect!r}")
    sc = build_scenario({**SPEC, **options})
    clean = sc.run({**TRUTH, **values}).readings
    sigma = np.hypot([NOISE_ABS[n] for n in sc.sensor_names], NOISE_REL * clean)
    data = clean + sigma * rng.standard_normal(clean.shape)
    m = Measurement(data, sc.sensor_names, sc.load_levels, f"pseudo-data ({effect or 'no effect'})")
    return StrengthTrial(effect, joint, value, m, noise_model())


def base_model(free=("GfII_bj",)):
    """The triplet scenario (no effect), the base model's space over ``free`` and its fixed values."""
    return build_scenario(SPEC), ParameterSpace([Parameter(n, *BOUNDS[n]) for n in free]), dict(SERIES_FIT)


def diagnose_trial(trial, seed, free=("GfII_bj",)):
    """The diagnosis of ``trial`` with the base model of :func:`base_model`: data and model on one
    mesh (``model_tolerance = 0``), a 32-run base surrogate."""
    sc, space, fixed = base_model(free)
    settings = DiagnosisSettings(seed=seed, model_tolerance=0.0, n_train=32)
    return diagnose(sc, trial.measurement, trial.noise, space, settings, fixed=fixed)
