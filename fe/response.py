"""The :class:`Response` of a scenario: sensor readings per load level, optionally the full field."""

from dataclasses import dataclass

import numpy as np

from .display import Displayed


@dataclass(frozen=True, eq=False, repr=False)
class Response(Displayed):
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

    def to_dict(self):
        """JSON-able (strict JSON: a reading at a level the run did not reach, NaN here, is None):
        ``load_levels`` and ``load_unit``, and ``readings``, sensor name → one reading per load
        level (mm; a load reading in its own unit)."""
        return {"load_levels": _json_floats(self.load_levels), "load_unit": self.load_unit,
                "readings": {name: _json_floats(self.readings[:, j]) for j, name in enumerate(self.sensor_names)}}


@dataclass(frozen=True, eq=False, repr=False)
class NonlinearResponse(Response):
    """Readings of a nonlinear virtual test at prescribed levels of its control variable.

    Besides :class:`Response`'s fields (``load_levels`` are the control levels, in ``load_unit``,
    e.g. the top displacement in mm; readings are NaN at levels the run did not reach; after the
    gauges they hold the load readings of :class:`~fe.scenarios.nonlinear.NonlinearScenario` —
    ``F``, equal to ``loads``, in ``force_unit``, and with ``peak_readings`` ``F_peak`` and ``d_peak``):

    Attributes
    ----------
    loads : ndarray of shape (n_loads,)
        Load (the reaction of the control) at each level, in ``force_unit``; NaN where not reached.
    force_unit : str
    peak_load : float
        Largest load on the converged path, ``force_unit``.
    peak_displacement : float
        Control displacement at the peak load, mm.
    status : str
        ``converged``, ``not_converged`` or ``budget_exhausted``.
    limit : str or None
        With ``budget_exhausted``: the limit of the budget that ended the run (``"steps"``,
        ``"iterations"``, ``"cpu"`` or ``"wall"``, see :data:`fe.solvers.nonlinear.LIMITS`).
    message : str
        Why the run stopped early ("" when it reached the last level).
    reached : float
        Last converged value of the control variable, ``load_unit``.
    extra : dict of str to ndarray
        Further per-level quantities (e.g. ``vertical_reaction`` in kN).
    path : object
        The full :class:`~fe.solvers.nonlinear.PathResult` (every converged step).
    mesh_objective_limit : float or None
        Control value (``load_unit``) up to which the scenario's curve is known not to depend on
        the mesh (its mesh-convergence study); None when the study found no such limit.
    """

    loads: np.ndarray | None = None
    force_unit: str = "kN"
    peak_load: float = float("nan")
    peak_displacement: float = float("nan")
    status: str = "converged"
    limit: str | None = None
    message: str = ""
    reached: float = float("nan")
    extra: dict | None = None
    path: object = None
    mesh_objective_limit: float | None = None

    @property
    def converged(self):
        return self.status == "converged"

    @property
    def mesh_objective(self):
        """False when the levels go past :attr:`mesh_objective_limit`: the readings there, and a
        peak found there, depend on the mesh."""
        limit = self.mesh_objective_limit
        return limit is None or float(self.load_levels[-1]) <= limit * (1 + 1e-9)

    def summary(self):
        """Plain dict of the scalar results and the per-level loads (JSON-ready)."""
        return {
            "status": self.status, "limit": self.limit, "message": self.message, "reached": float(self.reached),
            "peak_load": float(self.peak_load), "peak_displacement": float(self.peak_displacement),
            "force_unit": self.force_unit,
            "mesh_objective": self.mesh_objective, "mesh_objective_limit": self.mesh_objective_limit,
            "loads": _json_floats(self.loads),
            **{k: _json_floats(v) for k, v in (self.extra or {}).items()},
        }

    def to_dict(self):
        """:meth:`Response.to_dict`, then :meth:`summary` and ``solver``, the path's
        :meth:`~fe.solvers.nonlinear.PathResult.to_dict` (None without a path)."""
        return {**super().to_dict(), **self.summary(), "solver": None if self.path is None else self.path.to_dict()}


def _json_floats(values):
    """A list of floats, a non-finite value as None (strict JSON)."""
    return [float(v) if np.isfinite(v) else None for v in np.asarray(values, dtype=float)]
