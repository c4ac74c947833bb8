"""Response variability over a region of equivalence (podkrig.online.propagation.rvc) on a
validation model whose outputs are known in closed form; each test names the defect it guards."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from podkrig.online.propagation import rvc
from podkrig.online.region import Region
from podkrig.parameters import Parameter, ParameterSpace


class ValidationModel:
    """Readings (mm) of sensors ``u``, ``v`` at loads 5 and 15: ``u = load · (a + 2c)``,
    ``v = load · (b − c)``; its parameters are in another order than the region's."""

    space = ParameterSpace((Parameter("c", 0.0, 1.0), Parameter("b", 0.0, 2.0), Parameter("a", 0.0, 2.0)))
    sensor_names = ("u", "v")
    load_levels = np.array([5.0, 15.0])

    def predict(self, X, return_std=False):
        c, b, a = np.atleast_2d(X).T
        Y = np.column_stack([level * col for level in self.load_levels for col in (a + 2 * c, b - c)])
        return (Y, np.zeros_like(Y)) if return_std else Y


def _region(samples):
    samples = np.asarray(samples, dtype=float)
    return Region("likelihood-ratio", 0.95, samples, np.zeros(len(samples)), 1.0,
                  {"a": (samples[:, 0].min(), samples[:, 0].max()), "b": (samples[:, 1].min(), samples[:, 1].max())},
                  ("a", "b"), ("-", "-"), len(samples), 0.0, {})


def test_rvc_maps_the_region_onto_the_model_parameters_by_name():
    """Fails if the region's members are fed to the model by position instead of by name, or a
    parameter the calibration did not free does not take its ``fixed`` value: members (a, b) =
    (1, 1), (1.2, 0.8), (0.8, 1.2) with c = 0.25 give u@15 = 15 (a + 0.5), v@15 = 15 (b − 0.25)."""
    region = _region([[1.0, 1.0], [1.2, 0.8], [0.8, 1.2]])
    out = rvc(region, ValidationModel(), fixed={"c": 0.25})
    assert out.outputs == ("u@15", "v@15")
    assert_allclose(out.values, [[22.5, 11.25], [25.5, 8.25], [19.5, 14.25]], rtol=1e-12)
    assert_allclose(out.mean, [22.5, 11.25], rtol=1e-12)
    assert_allclose(out.std, [3.0, 3.0], rtol=1e-12)  # sample std (ddof = 1) of ±3 about the mean
    assert_allclose(out.cv, [3 / 22.5, 3 / 11.25], rtol=1e-12)
    assert_allclose(out.range_ratio, [6 / 22.5, 6 / 11.25], rtol=1e-12)


def test_rvc_output_errors_name_what_is_missing_and_what_exists():
    """Fails if the message for an unknown output stops listing it with the first three valid
    names, or the one for a missing parameter stops naming it and the remedy."""
    region = _region([[1.0, 1.0], [1.2, 0.8]])
    with pytest.raises(ValueError, match=r"\['w@15'\].*SENSOR@LOAD.*\['u@5', 'v@5', 'u@15'\]"):
        rvc(region, ValidationModel(), fixed={"c": 0.25}, outputs=["u@5", "w@15"])
    with pytest.raises(ValueError, match=r"needs values for \['c'\].*fixed"):
        rvc(region, ValidationModel())
    picked = rvc(region, ValidationModel(), fixed={"c": 0.25}, outputs=["v@5", "u@5"])
    assert picked.outputs == ("v@5", "u@5")
    assert_allclose(picked.values, [[3.75, 7.5], [2.75, 8.5]], rtol=1e-12)
