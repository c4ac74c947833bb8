"""Measured responses and their noise model (no file reading here; see :mod:`podkrig.measurement_csv`).

A :class:`Measurement` holds measured readings ``(n_loads, n_sensors)`` in mm for a subset of a
scenario's sensors and load levels; :meth:`Measurement.output_indices` maps them into the
flattened (load-major, C order) output vector of a response or a surrogate. A
:class:`NoiseModel` gives the data covariance ``C_d`` of the observed vector (thesis eq. 2.9).
"""

from dataclasses import dataclass, field

import numpy as np

from podkrig.limits import MAX_ABS_READING_MM, check_finite


@dataclass(frozen=True, eq=False)
class Measurement:
    """Measured readings.

    Attributes
    ----------
    values : ndarray of shape (n_loads, n_sensors)
        Readings, mm.
    sensor_names : tuple of str
    load_levels : ndarray of shape (n_loads,)
        In the scenario's load unit.
    source : str
        Where the data came from (file name), for messages and reports.
    """

    values: np.ndarray
    sensor_names: tuple
    load_levels: np.ndarray
    source: str = "measurement"

    def __post_init__(self):
        object.__setattr__(self, "values", np.asarray(self.values, dtype=float))
        object.__setattr__(self, "load_levels", np.asarray(self.load_levels, dtype=float))
        object.__setattr__(self, "sensor_names", tuple(self.sensor_names))
        shape = (len(self.load_levels), len(self.sensor_names))
        if self.values.shape != shape:
            raise ValueError(f"{self.source}: values must have shape {shape} (n_loads, n_sensors); got {self.values.shape}")
        if not np.all(np.isfinite(self.values)):
            raise ValueError(f"{self.source}: measured values must be finite numbers")

    @property
    def data(self):
        """The observed vector ``d_obs``, ``(n_obs,)`` mm, load-major."""
        return self.values.ravel()

    @property
    def n_obs(self):
        return self.values.size

    def output_indices(self, sensor_names, load_levels):
        """Positions of the observed entries in a flattened ``(n_loads_all, n_sensors_all)`` output.

        Parameters
        ----------
        sensor_names : sequence of str
            All sensors of the model, in its order.
        load_levels : array_like of shape (n_loads_all,)
            All load levels of the model.

        Returns
        -------
        ndarray of shape (n_obs,)
        """
        sensor_names = list(sensor_names)
        load_levels = np.asarray(load_levels, dtype=float)
        cols = []
        for s in self.sensor_names:
            if s not in sensor_names:
                raise ValueError(f"{self.source}: unknown sensor {s!r}; the model has {sensor_names}")
            cols.append(sensor_names.index(s))
        rows = []
        for level in self.load_levels:
            hit = np.flatnonzero(np.isclose(load_levels, level, rtol=1e-9, atol=1e-12))
            if len(hit) == 0:
                raise ValueError(f"{self.source}: unknown load level {level:g}; the model has {load_levels.tolist()}")
            rows.append(hit[0])
        return (np.array(rows)[:, None] * len(sensor_names) + np.array(cols)[None, :]).ravel()


@dataclass(frozen=True)
class NoiseModel:
    """Measurement noise: absolute σ (mm, one for all or one per sensor), relative δ, or a covariance.

    Exactly one of ``sigma``, ``delta`` or ``covariance`` is given.

    Parameters
    ----------
    sigma : float or dict of str to float, optional
        Absolute standard deviation, mm (a dict gives one per sensor name).
    delta : float, optional
        Relative noise level: σ_i = δ |d_i|, floored at ``floor``.
    covariance : ndarray of shape (n_obs, n_obs), optional
        Full data covariance ``C_d``, mm², in the measurement's (load-major) order.
    floor : float
        Smallest σ for the relative model, mm (a reading of zero is not known exactly either).
    """

    sigma: float | dict | None = None
    delta: float | None = None
    covariance: np.ndarray | None = field(default=None, repr=False)
    floor: float = 1e-6

    def __post_init__(self):
        _require_finite_noise(self)
        given = [x is not None for x in (self.sigma, self.delta, self.covariance)]
        if sum(given) != 1:
            raise ValueError("give exactly one noise model: an absolute sigma (mm), a relative delta, or a covariance")
        if isinstance(self.sigma, dict):
            bad = {k: v for k, v in self.sigma.items() if not v > 0}
            if bad:
                raise ValueError(f"absolute noise sigma must be > 0 mm; got {bad}")
        elif self.sigma is not None and not self.sigma > 0:
            raise ValueError(f"absolute noise sigma must be > 0 mm; got {self.sigma}")
        if self.delta is not None and not 0 < self.delta < 1:
            raise ValueError(f"relative noise delta must be in (0, 1); got {self.delta}")

    @property
    def is_diagonal(self):
        return self.covariance is None

    def std(self, measurement):
        """Standard deviation of each observed entry, ``(n_obs,)`` mm (diagonal models only)."""
        n_loads = len(measurement.load_levels)
        if self.covariance is not None:
            return np.sqrt(np.diag(self.covariance_matrix(measurement)))
        if self.delta is not None:
            return np.maximum(self.delta * np.abs(measurement.data), self.floor)
        if isinstance(self.sigma, dict):
            missing = [s for s in measurement.sensor_names if s not in self.sigma]
            if missing:
                raise ValueError(f"no noise sigma given for sensor(s) {missing}")
            per_sensor = np.array([self.sigma[s] for s in measurement.sensor_names], dtype=float)
            return np.tile(per_sensor, n_loads)
        return np.full(measurement.n_obs, float(self.sigma))

    def covariance_matrix(self, measurement):
        """``C_d``, ``(n_obs, n_obs)`` mm²."""
        if self.covariance is None:
            return np.diag(self.std(measurement) ** 2)
        C = np.asarray(self.covariance, dtype=float)
        if C.shape != (measurement.n_obs,) * 2:
            raise ValueError(
                f"noise covariance must be ({measurement.n_obs}, {measurement.n_obs}) for "
                f"{measurement.source}; got {C.shape}"
            )
        if not np.allclose(C, C.T) or np.linalg.eigvalsh(C).min() <= 0:
            raise ValueError("noise covariance must be symmetric positive definite")
        return C


def _require_finite_noise(noise):
    """Refuse NaN, infinite or absurd noise levels (σ = inf made every reading weightless: χ² = 0)."""
    sigmas = noise.sigma if isinstance(noise.sigma, dict) else {None: noise.sigma}
    for sensor, sigma in sigmas.items():
        if sigma is not None:
            what = "absolute noise sigma (mm)" if sensor is None else f"absolute noise sigma of sensor {sensor!r} (mm)"
            check_finite(sigma, what, lower=0.0, upper=MAX_ABS_READING_MM)
    deltas = noise.delta if isinstance(noise.delta, dict) else {None: noise.delta}
    for sensor, delta in deltas.items():
        if delta is not None:
            what = "relative noise delta" if sensor is None else f"relative noise delta of sensor {sensor!r}"
            check_finite(delta, what)
    if noise.covariance is not None and not np.isfinite(np.asarray(noise.covariance, dtype=float)).all():
        raise ValueError("noise covariance must hold finite numbers (mm²); it has NaN or infinite entries")
