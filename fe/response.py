"""The :class:`Response` of a scenario: sensor readings per load level, optionally the full field."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Response:
    """Readings of a virtual test.

    Attributes
    ----------
    readings : ndarray of shape (n_loads, n_sensors)
        Sensor readings, mm. Flattened in C order this is the snapshot vector
        (load-major: all sensors at the first load level, then the next).
    sensor_names : tuple of str
    load_levels : ndarray of shape (n_loads,)
        In ``load_unit``.
    load_unit : str
    field : ndarray of shape (n_loads, n_nodes, 2) or None
        Nodal displacements (x, y), mm, when requested.
    """

    readings: np.ndarray
    sensor_names: tuple
    load_levels: np.ndarray
    load_unit: str = "kN"
    field: np.ndarray | None = None

    def __post_init__(self):
        shape = (len(self.load_levels), len(self.sensor_names))
        if self.readings.shape != shape:
            raise ValueError(f"readings must have shape {shape} (n_loads, n_sensors); got {self.readings.shape}")

    def reading(self, sensor):
        """Readings of one sensor at every load level, ``(n_loads,)`` mm."""
        try:
            return self.readings[:, self.sensor_names.index(sensor)]
        except ValueError:
            raise KeyError(f"no sensor {sensor!r}; sensors are {list(self.sensor_names)}") from None

    def as_dict(self):
        """Sensor name → list of readings (one per load level), mm."""
        return {name: self.readings[:, j].tolist() for j, name in enumerate(self.sensor_names)}
