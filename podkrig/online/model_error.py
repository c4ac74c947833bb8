"""The model-form part ``C_T`` of the data covariance (thesis eq. 2.10), estimated or assumed.

Two FE discretisations of the same test differ; data from another code (or from the specimen)
carry the difference as a systematic residual that more readings only make more significant.
:func:`discretisation_error` *estimates* the error of each reading of the scenario's own mesh:
the scenario is run at the same parameter values on a mesh refined ``refinement`` times in each
direction (options ``nx``, ``ny``), and Richardson's extrapolation gives the error of the coarse
reading from the difference,

    e_i = |g_i(h) − g_i(h/r)| · r^p / (r^p − 1),

with ``p`` the convergence rate of the readings (``DEFAULT_RATE``). Where the scenario removes
rigid-body motion from displacement fields, the difference is taken after that removal, as the
readings are. :func:`tolerance_error` is the user's fixed override, ``e_i = ε |d_i|``.

The diagnosis always adds ``C_T = diag(e²)`` to the noise; the inversion does when asked
(``podkrig invert --model-form-error estimated`` or ``ε``; :func:`parse_model_form_error`,
:func:`podkrig.online.calibrate.calibrate`).
"""

from dataclasses import dataclass

import numpy as np

from fe import build_scenario
from fe.exceptions import SpecError
from podkrig.display import Displayed

#: convergence rate p assumed in Richardson's factor r^p/(r^p − 1) (2.35 at r = 2): the slowest
#: rate observed for the default diagonal test (COMPUTED, BENCHMARKS "Supports that converge":
#: absolute displacements converge at p = 0.81–0.90 with rigid supports, whose ends are singular
#: points; gauges D1, D2 at p ≈ 2, for which the factor is cautious); configurable
DEFAULT_RATE = 0.8


@dataclass(frozen=True, eq=False, repr=False)
class ModelError(Displayed):
    """Standard deviation of the model-form error of each observed reading.

    Attributes
    ----------
    std : ndarray of shape (n_obs,)
        ``e_i``, mm, in the measurement's load-major order.
    method : str
        ``"two meshes"`` (estimated) or ``"tolerance"`` (fixed ``ε |d_i|``).
    tolerance : float or None
        ε of the fixed tolerance.
    refinement : int or None
        Mesh refinement factor r of the estimate.
    rate : float or None
        Convergence rate p of the estimate.
    mesh : str or None
        The two meshes, e.g. ``"Q8 6×2 and 12×4 per unit"``.
    note : str or None
        Why a fixed tolerance stands in for an estimate, if it does.
    """

    std: np.ndarray
    method: str
    tolerance: float | None = None
    refinement: int | None = None
    rate: float | None = None
    mesh: str | None = None
    note: str | None = None

    def relative(self, measurement):
        """``e_i / |d_i|`` (readings below 1e-12 mm give 0)."""
        d = np.abs(measurement.data)
        return np.divide(self.std, d, out=np.zeros_like(self.std), where=d > 1e-12)

    def describe(self):
        """In words, for the χ² basis of reports."""
        if self.method == "tolerance":
            text = f"(ε·d)², ε = {100 * self.tolerance:g} % of each reading"
            return text + (f" ({self.note})" if self.note else "")
        return (f"e², e estimated per reading from two meshes ({self.mesh}; Richardson, rate p = {self.rate:g})")

    def summary(self, measurement):
        """What an inversion result records: :meth:`to_dict` without the per-reading list, with the
        median and largest relative error and the :meth:`describe` sentence."""
        d = {k: v for k, v in self.to_dict(measurement).items() if k != "std_mm"}
        return {**d, "description": self.describe()}

    def to_dict(self, measurement=None):
        d = {"method": self.method, "tolerance": self.tolerance, "refinement": self.refinement, "rate": self.rate,
             "mesh": self.mesh, "note": self.note, "std_mm": self.std.tolist()}
        if measurement is not None:
            rel = self.relative(measurement)
            d["median_relative"] = float(np.median(rel))
            d["max_relative"] = float(np.max(rel))
        return d

    @classmethod
    def from_dict(cls, d):
        return cls(np.asarray(d["std_mm"], dtype=float), d["method"], d.get("tolerance"), d.get("refinement"),
                   d.get("rate"), d.get("mesh"), d.get("note"))


#: relative tolerance standing in when a scenario's mesh cannot be refined (a named choice: two
#: sound discretisations of the default diagonal test differ by about 0.5 % on the diagonals)
FALLBACK_TOLERANCE = 0.01


def tolerance_error(measurement, tolerance, note=None):
    """The fixed model-form tolerance ``e_i = ε |d_i|`` (the user's override, or the fallback
    ``FALLBACK_TOLERANCE`` with the ``note`` saying why)."""
    return ModelError(np.abs(tolerance * measurement.data), "tolerance", tolerance=float(tolerance), note=note)


#: what ``--model-form-error`` accepts besides a relative tolerance ε
MODEL_FORM_ERROR_CHOICES = ("none", "estimated")


def parse_model_form_error(value, source="--model-form-error"):
    """The inversion's model-form error option: None (none), ``"estimated"`` (two meshes, at the
    first optimum) or a relative tolerance ε in [0, 0.5) (``e_i = ε |d_i|``); ``value`` as the
    user wrote it (str or number). ``source`` names the option or key in the error message."""
    if value is None or (isinstance(value, str) and value.strip().lower() == "none"):
        return None
    if isinstance(value, str) and value.strip().lower() == "estimated":
        return "estimated"
    try:
        eps = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{source} must be none, estimated or a relative tolerance in [0, 0.5) "
                         f"(e.g. 0.01 for 1 % of each reading); got {value!r}") from None
    if not 0 <= eps < 0.5:
        raise ValueError(f"{source}: a relative tolerance must be in [0, 0.5); got {eps:g}")
    return eps


def discretisation_error(scenario, values, measurement, refinement=2, rate=DEFAULT_RATE, rigid_body=None,
                         observation=None):
    """Estimate the discretisation error of each observed reading of ``scenario`` at ``values``.

    Parameters
    ----------
    scenario : fe.Scenario
        With mesh options ``nx`` and ``ny`` (divisions per unit).
    values : dict of str to float
        Every parameter's value (the calibrated model's).
    measurement : Measurement
        The observed sensors and load levels.
    refinement : int
        r: the second mesh has ``r·nx × r·ny`` divisions per unit.
    rate : float
        p > 0, the convergence rate of the readings.
    rigid_body : RigidBodyModes, optional
        The rigid-body modes removed from data and model (:mod:`podkrig.online.rigid_body`): the
        difference of the two meshes is taken with its rigid motion removed as well, since the
        readings compared with the data are.
    observation : ObservationOperator, optional
        How the observed entries follow from the flattened readings (an inverse problem's
        ``misfit.observation``, e.g. readings interpolated to measured loads); default: the
        measurement's own load levels picked from the scenario's.

    Returns
    -------
    ModelError
        ``e_i = |g_i(h) − g_i(h/r)| r^p / (r^p − 1)``, mm.
    """
    if refinement < 2 or rate <= 0:
        raise ValueError(f"refinement must be an integer ≥ 2 and rate > 0; got {refinement}, {rate}")
    options = scenario.spec.options
    if "nx" not in options or "ny" not in options:
        raise ValueError(f"{scenario.name}: no mesh options nx, ny to refine; give a fixed model_tolerance instead")
    nx, ny = options["nx"], options["ny"]
    try:
        fine = build_scenario({**scenario.spec.to_dict(), "nx": refinement * nx, "ny": refinement * ny})
    except SpecError as e:
        raise ValueError(f"{scenario.name}: the mesh refined {refinement}× cannot be built ({e}); give a fixed "
                         "model_tolerance instead") from e
    if observation is None:
        idx = measurement.output_indices(scenario.sensor_names, scenario.load_levels)
        difference = scenario.run(values).readings.ravel()[idx] - fine.run(values).readings.ravel()[idx]
    else:
        difference = observation.apply(np.stack([scenario.run(values).readings.ravel(),
                                                 fine.run(values).readings.ravel()]))
        difference = difference[0] - difference[1]
    if rigid_body is not None:
        difference = rigid_body.remove(difference)
    factor = refinement**rate / (refinement**rate - 1.0)
    element = options.get("element", "Q8")
    return ModelError(np.abs(difference) * factor, "two meshes", refinement=int(refinement), rate=float(rate),
                      mesh=f"{element} {nx}×{ny} and {refinement * nx}×{refinement * ny} per unit")
