"""Measured responses, how a model is evaluated at them, and their noise model (no file reading
here; see :mod:`podkrig.io.measurement_log`).

A :class:`Measurement` holds measured readings ``(n_loads, n_sensors)`` in mm (in kN for the load
reading ``F`` of a displacement-controlled scenario: a force–displacement curve is data) for a
subset of a scenario's sensors, at any measured loads (a lab log: 10.03, 10.41 … kN; or control
displacements, mm); a missing reading is NaN. :meth:`Measurement.observation` gives the :class:`ObservationOperator` that evaluates a
model's flattened (load-major, C order) output vector at the observed entries:

* at a modelled load level, the model's own output;
* between or beyond the levels of a **linear** scenario (``load_response = "affine"``), the
  exact affine combination of two levels (readings of a linear model are affine in the load:
  ``r(P) = r(L_a) + (P − L_a)/(L_b − L_a) (r(L_b) − r(L_a))``, exact also with a constant
  pre-compression);
* between the levels of a **nonlinear** scenario (``"path"``), linear interpolation along the
  control variable — never extrapolation beyond the modelled range (an error);
* a scenario whose levels are steps (``"discrete"``, the flat-jack test) takes only its levels.

Readings of gauges zeroed at a reference load ``P_ref`` are compared with ``g(P) − g(P_ref)``.

A :class:`NoiseModel` gives the data covariance ``C_d`` of the observed vector (thesis eq. 2.9);
the instrument model σ_i² = σ_res,i² + (δ d_i)² combines a resolution floor and a relative part.
:data:`INSTRUMENTS` gives typical values of common laboratory instruments.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from podkrig.limits import MAX_ABS_READING_MM, check_finite

#: How a scenario's readings depend on its load level (``fe`` scenario attribute ``load_response``).
LOAD_RESPONSES = ("affine", "path", "discrete")

#: Typical noise of laboratory instruments: σ_res (mm, resolution / repeatability floor) and the
#: relative part δ of σ_i² = σ_res² + (δ d_i)². LVDT σ = 1–5 µm and DIC 2.5–5 µm per component at
#: 0.25 mm/px are typical values from flat-jack and laboratory practice (INFERRED defaults, see
#: ``docs/references.md`` "INFERRED choices": ``noise_abs`` / ``noise_rel`` override them); a
#: mechanical deformometer or dial gauge reads to 1 µm ("millesimal"); δ = 1 % is the "1.0 % error
#: range" of the thesis (§3.2 caption, the only noise level it states; its use as a
#: calibration/linearity term is a choice). A load cell (the force of a displacement-controlled
#: test, kN): σ_res = 0.05 kN and δ = 1 % (INFERRED typical values of a 0.5–1 % class cell on a
#: 50–100 kN range).
INSTRUMENTS = {
    "lvdt": {"sigma_res_mm": 0.001, "delta": 0.01,
             "text": "LVDT / extensometer: σ_res = 1 µm (typical 1–5 µm, INFERRED: docs/references.md), δ = 1 % (thesis §3.2)"},
    "dial_gauge": {"sigma_res_mm": 0.001, "delta": 0.01,
                   "text": "dial gauge / mechanical deformometer: resolution 1 µm, δ = 1 %"},
    "dic": {"sigma_res_mm": 0.0025, "delta": 0.0,
            "text": "DIC point, per component: σ_res = 2.5 µm (typical 2.5–5 µm, INFERRED: docs/references.md), no relative part"},
    "load_cell": {"sigma_res_mm": 0.05, "delta": 0.01, "unit": "kN",
                  "text": "load cell (a force, kN): σ_res = 0.05 kN, δ = 1 % (typical values, INFERRED: docs/references.md)"},
}


def instrument_unit(name):
    """The unit instrument ``name`` of :data:`INSTRUMENTS` reads, ``"mm"`` unless its entry says
    ``unit`` (the load cell: ``"kN"``; its ``sigma_res_mm`` is then in that unit)."""
    return INSTRUMENTS[name].get("unit", "mm")


#: Smallest credible σ of one reading, mm: half the finest resolution of the instruments above
#: (1 µm). A smaller σ makes the region of equivalence optimistic (a 1 %-relative model
#: gave the 2 µm U1 gauge σ ≈ 0.02 µm); :meth:`NoiseModel.below_floor` names such sensors.
SIGMA_FLOOR_MM = 0.0005
#: The range of σ a noise model may state, mm. Below 10⁻⁷ mm (0.1 nm, the size of an atom and
#: 5000× finer than :data:`SIGMA_FLOOR_MM`) no displacement of a masonry specimen is defined, let
#: alone measured — and σ² underflows towards 0 (σ = 10⁻³⁰⁰ gave "inf× the noise"); above 10⁶ mm
#: (1 km, the largest reading accepted, :data:`~podkrig.limits.MAX_ABS_READING_MM`) σ weighs no
#: reading. Refused outside, at every door (the study file, the command line, the library).
SIGMA_RANGE_MM = (1e-7, MAX_ABS_READING_MM)
#: The range of a relative noise δ: below 10⁻⁶ (one part in a million) is far beyond the
#: calibration of any displacement transducer used on masonry (LVDTs, dial gauges and DIC are
#: 0.1–1 %); 1 (100 % of each reading) or more is no measurement.
DELTA_RANGE = (1e-6, 1.0)


@dataclass(frozen=True, eq=False)
class ObservationOperator:
    """The observed entries as weighted sums of a model's flattened outputs.

    Observed entry ``i`` is ``Σ_k weights[i, k] · Y[:, columns[i, k]]``: one column with weight 1
    at a modelled load level, two for interpolation between levels (or the exact affine
    combination of a linear scenario), twice as many for gauges zeroed at a reference load.

    Attributes
    ----------
    columns : ndarray of int, shape (n_obs, K)
    weights : ndarray of shape (n_obs, K)
    """

    columns: np.ndarray
    weights: np.ndarray

    def __post_init__(self):
        cols = np.atleast_2d(np.asarray(self.columns, dtype=np.intp))
        w = np.atleast_2d(np.asarray(self.weights, dtype=float))
        if cols.shape != w.shape:
            raise ValueError(f"columns {cols.shape} and weights {w.shape} must have the same shape")
        keep = np.any(w != 0, axis=0)  # drop columns of zero weight everywhere (all loads at levels)
        keep[0] = True
        cols, w = cols[:, keep], w[:, keep]
        object.__setattr__(self, "columns", cols)
        object.__setattr__(self, "weights", w)

    @classmethod
    def from_indices(cls, indices):
        """Each observed entry is one model output: ``Y[:, indices]``."""
        idx = np.asarray(indices, dtype=np.intp).reshape(-1, 1)
        return cls(idx, np.ones(idx.shape))

    @property
    def n_obs(self):
        return len(self.columns)

    @property
    def exact(self):
        """Every observed entry is one model output (no interpolation, no reference)."""
        return self.columns.shape[1] == 1 and bool(np.all(self.weights == 1.0))

    @property
    def indices(self):
        """The output of each observed entry, ``(n_obs,)`` (only when :attr:`exact`)."""
        if not self.exact:
            raise ValueError("the measurement is not at the model's load levels: its entries are interpolated "
                             "between levels (or zeroed at a reference load), not single outputs")
        return self.columns[:, 0]

    def apply(self, Y):
        """Model outputs ``(n, n_outputs)`` → observed entries ``(n, n_obs)``."""
        Y = np.atleast_2d(Y)
        if self.exact:
            return Y[:, self.columns[:, 0]]
        out = Y[:, self.columns[:, 0]] * self.weights[:, 0]
        for k in range(1, self.columns.shape[1]):
            out += Y[:, self.columns[:, k]] * self.weights[:, k]
        return out

    def apply_std(self, S):
        """Predictive std of the outputs ``(n, n_outputs)`` → of the observed entries, ``Σ_k |w_k| s_k``
        (the bound for fully correlated errors, which the smooth POD-kriging error along the load is)."""
        if self.exact:
            return np.atleast_2d(S)[:, self.columns[:, 0]]
        S = np.atleast_2d(S)
        out = S[:, self.columns[:, 0]] * np.abs(self.weights[:, 0])
        for k in range(1, self.columns.shape[1]):
            out += S[:, self.columns[:, k]] * np.abs(self.weights[:, k])
        return out


def level_weights(loads, levels, load_response="discrete", load_unit="", source="measurement"):
    """How to evaluate a model at measured loads from its outputs at its load levels.

    Parameters
    ----------
    loads : array_like of shape (n,)
        Measured loads (the scenario's control variable), ``load_unit``.
    levels : array_like of shape (n_levels,)
        The model's load levels.
    load_response : {"affine", "path", "discrete"}
        See the module docstring.

    Returns
    -------
    index : ndarray of int, shape (n, 2)
        Level indices (into ``levels``).
    weights : ndarray of shape (n, 2)

    Raises
    ------
    ValueError
        A load that is not a level of a ``discrete`` model, outside the modelled range of a
        ``path`` model, or a linear model with a single level — naming the load and the range.
    """
    if load_response not in LOAD_RESPONSES:
        raise ValueError(f"load_response must be one of {LOAD_RESPONSES}; got {load_response!r}")
    loads = np.asarray(loads, dtype=float).ravel()
    levels = np.asarray(levels, dtype=float).ravel()
    order = np.argsort(levels, kind="stable")
    L = levels[order]
    n_l = len(L)
    pos = np.searchsorted(L, loads)
    below, above = np.clip(pos - 1, 0, n_l - 1), np.clip(pos, 0, n_l - 1)
    hit_below = np.isclose(L[below], loads, rtol=1e-9, atol=1e-12)
    hit_above = np.isclose(L[above], loads, rtol=1e-9, atol=1e-12)
    exact = hit_below | hit_above
    index = np.zeros((len(loads), 2), dtype=np.intp)
    weights = np.zeros((len(loads), 2))
    index[:, 0] = np.where(hit_above, above, below)
    weights[exact, 0] = 1.0
    off = ~exact
    unit = f" {load_unit}" if load_unit else ""
    if np.any(off):
        first = float(loads[np.argmax(off)])
        if load_response == "discrete":
            raise ValueError(f"{source}: unknown load level {first:g}{unit}; the model has {levels.tolist()} "
                             "(its levels are steps: readings are taken only there)")
        if n_l < 2:
            raise ValueError(f"{source}: load {first:g}{unit} is not the model's only level {L[0]:g}{unit}; "
                             "evaluating between levels needs at least two")
        if load_response == "path":
            outside = off & ((loads < L[0]) | (loads > L[-1]))
            if np.any(outside):
                bad = loads[outside]
                raise ValueError(
                    f"{source}: {int(outside.sum())} measured control value(s) lie outside the modelled range "
                    f"[{L[0]:g}, {L[-1]:g}]{unit} of this nonlinear scenario (e.g. {bad[0]:g}{unit}; extremes "
                    f"{bad.min():g} and {bad.max():g}{unit}); the model is not extrapolated past its levels: "
                    "restrict the measurement's load range (load_range) or extend the scenario's load_levels")
        a = np.clip(pos[off] - 1, 0, n_l - 2)  # the bracketing pair; the end pair beyond the range (affine)
        b = a + 1
        t = (loads[off] - L[a]) / (L[b] - L[a])
        index[off] = np.column_stack([a, b])
        weights[off] = np.column_stack([1.0 - t, t])
    return order[index], weights


@dataclass(frozen=True, eq=False)
class Measurement:
    """Measured readings.

    Attributes
    ----------
    values : ndarray of shape (n_loads, n_sensors)
        Readings, mm; NaN where a reading is missing.
    sensor_names : tuple of str
    load_levels : ndarray of shape (n_loads,)
        Measured loads (the scenario's control variable), in the scenario's load unit; any
        values (a model is evaluated there, see :meth:`observation`).
    source : str
        Where the data came from (file name), for messages and reports.
    reference_load : float or None
        Gauges were zeroed at this load (readings are changes since then); None: readings are
        absolute, as the model's.
    notes : tuple of str
        What the import did (columns ignored, units converted, sensors not used ...), for the user.
    ignored_columns : tuple of str
        Columns of the file that name no sensor of the model (time, channel numbers ...).
    sensor_units : tuple of str
        The unit of each sensor's readings (mm; kN for a load reading); empty: every sensor in mm.
    """

    values: np.ndarray
    sensor_names: tuple
    load_levels: np.ndarray
    source: str = "measurement"
    reference_load: float | None = None
    notes: tuple = ()
    ignored_columns: tuple = ()
    sensor_units: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "values", np.asarray(self.values, dtype=float))
        object.__setattr__(self, "load_levels", np.asarray(self.load_levels, dtype=float))
        object.__setattr__(self, "sensor_names", tuple(self.sensor_names))
        object.__setattr__(self, "notes", tuple(self.notes))
        units = tuple(self.sensor_units) or ("mm",) * len(self.sensor_names)
        if len(units) != len(self.sensor_names):
            raise ValueError(f"{self.source}: sensor_units must give one unit per sensor ({len(self.sensor_names)}); "
                             f"got {len(units)}")
        object.__setattr__(self, "sensor_units", units)
        shape = (len(self.load_levels), len(self.sensor_names))
        if self.values.shape != shape:
            raise ValueError(f"{self.source}: values must have shape {shape} (n_loads, n_sensors); got {self.values.shape}")
        if np.any(np.isinf(self.values)):
            raise ValueError(f"{self.source}: measured values must be finite numbers (NaN marks a missing reading)")
        if not np.all(np.isfinite(self.load_levels)):
            raise ValueError(f"{self.source}: loads must be finite numbers")
        if not np.any(np.isfinite(self.values)):
            raise ValueError(f"{self.source}: no readings (every value is missing)")
        if self.reference_load is not None and not math.isfinite(self.reference_load):
            raise ValueError(f"{self.source}: the reference load must be a finite number")

    @property
    def mask(self):
        """Which readings exist, ``(n_loads, n_sensors)`` bool."""
        return np.isfinite(self.values)

    @property
    def complete(self):
        """Every sensor read at every load."""
        return bool(np.all(self.mask))

    @property
    def data(self):
        """The observed vector ``d_obs``, ``(n_obs,)`` mm, load-major, missing readings left out."""
        return self.values[self.mask] if not self.complete else self.values.ravel()

    @property
    def n_obs(self):
        return int(np.count_nonzero(self.mask))

    def grid(self, v):
        """Observed-entry values ``(n_obs,)`` on the ``(n_loads, n_sensors)`` grid, NaN where a
        reading is missing."""
        out = np.full(self.values.shape, np.nan)
        out[self.mask] = v
        return out

    def with_data(self, d, source=None):
        """The same measurement with the observed vector replaced by ``d`` ``(n_obs,)``."""
        values = np.full(self.values.shape, np.nan)
        values[self.mask] = d
        return Measurement(values, self.sensor_names, self.load_levels, source or self.source,
                           self.reference_load, self.notes, self.ignored_columns, self.sensor_units)

    def check_summary(self, sensor_names, noise, floor=SIGMA_FLOOR_MM):
        """What a user should know before any FE work: counts, columns not used, σ below ``floor``
        (the input of :func:`podkrig.online.findings.measurement_findings`)."""
        return {"file": self.source, "n_obs": self.n_obs, "n_loads": len(self.load_levels),
                "sensors": list(self.sensor_names),
                "load_min": float(self.load_levels.min()), "load_max": float(self.load_levels.max()),
                "reference_load": self.reference_load,
                "not_used": [s for s in sensor_names if s not in self.sensor_names],
                "ignored": list(self.ignored_columns), "notes": list(self.notes),
                "sigma_below_floor": noise.below_floor(self, floor), "sigma_floor_mm": floor}

    def observation(self, sensor_names, load_levels, load_response="discrete", load_unit=""):
        """How a model's flattened output ``(n_loads_all * n_sensors_all,)`` gives the observed entries.

        Parameters
        ----------
        sensor_names : sequence of str
            All sensors of the model, in its order.
        load_levels : array_like of shape (n_loads_all,)
            All load levels of the model.
        load_response : {"affine", "path", "discrete"}
            How the model's readings depend on the load (see the module docstring).
        load_unit : str
            For messages.

        Returns
        -------
        ObservationOperator
        """
        sensor_names = list(sensor_names)
        unknown = [s for s in self.sensor_names if s not in sensor_names]
        if unknown:
            named = f"sensor {unknown[0]!r}" if len(unknown) == 1 else f"sensor(s) {unknown}"
            raise ValueError(f"{self.source}: unknown {named}; the model has {sensor_names}")
        cols = np.array([sensor_names.index(s) for s in self.sensor_names], dtype=np.intp)
        n_s = len(sensor_names)
        index, weights = level_weights(self.load_levels, load_levels, load_response, load_unit, self.source)
        if self.reference_load is not None:
            ref_index, ref_weights = level_weights([self.reference_load], load_levels, load_response, load_unit,
                                                   f"{self.source} (reference load of the zeroed gauges)")
            index = np.hstack([index, np.broadcast_to(ref_index, index.shape)])
            weights = np.hstack([weights, -np.broadcast_to(ref_weights, weights.shape)])
        columns = index[:, None, :] * n_s + cols[None, :, None]  # (n_loads, n_sensors, K)
        w = np.broadcast_to(weights[:, None, :], columns.shape)
        mask = self.mask
        return ObservationOperator(columns[mask], w[mask])

    def output_indices(self, sensor_names, load_levels):
        """Positions of the observed entries in a flattened ``(n_loads_all, n_sensors_all)`` output,
        ``(n_obs,)``: the measured loads must be the model's levels (see :meth:`observation`)."""
        op = self.observation(sensor_names, load_levels)
        if not op.exact:
            raise ValueError(f"{self.source}: readings zeroed at a reference load are not single model outputs")
        return op.indices


def _per_sensor(value, measurement, what):
    """A number or a dict sensor → number as one value per observed entry, ``(n_obs,)``."""
    if not isinstance(value, dict):
        return np.full(measurement.n_obs, float(value))
    missing = [s for s in measurement.sensor_names if s not in value]
    if missing:
        raise ValueError(f"no noise {what} given for sensor(s) {missing}")
    per_sensor = np.array([value[s] for s in measurement.sensor_names], dtype=float)
    return np.broadcast_to(per_sensor, measurement.values.shape)[measurement.mask]


@dataclass(frozen=True)
class NoiseModel:
    """Measurement noise: σ_i² = σ_res,i² + (δ_i d_i)² (an instrument), or a full covariance.

    Give ``sigma`` (absolute), ``delta`` (relative) or both (the instrument model, combined in
    quadrature), or ``covariance`` alone.

    Parameters
    ----------
    sigma : float or dict of str to float, optional
        Absolute standard deviation σ_res, mm, in :data:`SIGMA_RANGE_MM` (a dict gives one per
        sensor name).
    delta : float or dict of str to float, optional
        Relative noise level δ, in :data:`DELTA_RANGE` (a dict gives one per sensor name, 0
        allowed there).
    covariance : ndarray of shape (n_obs, n_obs), optional
        Full data covariance ``C_d``, mm², in the measurement's (load-major) order.
    floor : float
        Smallest σ of a purely relative model, mm (a reading of zero is not known exactly either).
    units : dict of str to str, optional
        Sensor name → the unit of its readings and σ_res where it is not mm (a load reading ``F``:
        kN), for :meth:`describe`.
    """

    sigma: float | dict | None = None
    delta: float | dict | None = None
    covariance: np.ndarray | None = field(default=None, repr=False)
    floor: float = 1e-6
    units: dict | None = None

    def __post_init__(self):
        _require_finite_noise(self)
        if self.covariance is not None and (self.sigma is not None or self.delta is not None):
            raise ValueError("give either a covariance or an absolute sigma (mm) and/or a relative delta, not both")
        if self.covariance is None and self.sigma is None and self.delta is None:
            raise ValueError("give a noise model: an absolute sigma (mm), a relative delta, both, or a covariance")
        lo, hi = SIGMA_RANGE_MM
        if isinstance(self.sigma, dict):
            bad = {k: v for k, v in self.sigma.items() if not lo <= v <= hi}
            if bad:
                raise ValueError(f"absolute noise sigma must be in [{lo:g}, {hi:g}] mm; got {bad}")
        elif self.sigma is not None and not lo <= self.sigma <= hi:
            raise ValueError(f"absolute noise sigma must be in [{lo:g}, {hi:g}] mm; got {self.sigma}")
        d_lo, d_hi = DELTA_RANGE
        if isinstance(self.delta, dict):
            bad = {k: v for k, v in self.delta.items() if not (v == 0 or d_lo <= v < d_hi)}
            if bad:
                raise ValueError(f"relative noise delta must be 0 or in [{d_lo:g}, {d_hi:g}) per sensor; got {bad}")
            if self.sigma is None and any(v == 0 for v in self.delta.values()):
                raise ValueError("a relative delta of 0 needs an absolute sigma as well")
        elif self.delta is not None and not d_lo <= self.delta < d_hi:
            raise ValueError(f"relative noise delta must be in [{d_lo:g}, {d_hi:g}); got {self.delta}")

    @property
    def is_diagonal(self):
        return self.covariance is None

    def std(self, measurement):
        """Standard deviation of each observed entry, ``(n_obs,)`` mm."""
        if self.covariance is not None:
            return np.sqrt(np.diag(self.covariance_matrix(measurement)))
        if self.sigma is None:  # relative only
            return np.maximum(_per_sensor(self.delta, measurement, "delta") * np.abs(measurement.data), self.floor)
        sigma = _per_sensor(self.sigma, measurement, "sigma")
        if self.delta is None:
            return np.array(sigma, dtype=float)
        rel = _per_sensor(self.delta, measurement, "delta") * measurement.data
        return np.sqrt(sigma**2 + rel**2)

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

    def below_floor(self, measurement, floor=SIGMA_FLOOR_MM):
        """Sensors with a reading whose σ is below ``floor`` (mm): ``{sensor: smallest σ}``, mm."""
        sd = self.std(measurement)
        sensors = np.broadcast_to(np.arange(len(measurement.sensor_names)), measurement.values.shape)[measurement.mask]
        low = {}
        for j in np.unique(sensors[sd < floor]):
            low[measurement.sensor_names[j]] = float(sd[sensors == j].min())
        return low

    def describe(self):
        """The noise model in words, with units."""
        if self.covariance is not None:
            return "full covariance C_d"

        units = self.units or {}

        def fmt(v, unit, scale=1.0):
            if isinstance(v, dict):
                return ", ".join(f"{k} {scale * x:g}{unit if unit != ' mm' else ' ' + units.get(k, 'mm')}"
                                 for k, x in v.items())
            return f"{scale * v:g}{unit}"
        parts = []
        if self.sigma is not None:
            parts.append(f"σ_res = {fmt(self.sigma, ' mm')}")
        if self.delta is not None:
            parts.append(f"δ = {fmt(self.delta, ' %', 100.0)} of each reading")
        if len(parts) == 2:
            return "σ² = σ_res² + (δ d)², " + ", ".join(parts)
        return ("absolute, " if self.sigma is not None else "relative, ") + parts[0]


def instrument_noise(instruments, sensor_names, sensor_units=None):
    """Per-sensor σ_res and δ of named instruments (:data:`INSTRUMENTS`).

    Parameters
    ----------
    instruments : str or dict of str to str
        One instrument for every sensor of its unit, or sensor name → instrument. One name given
        for all: the sensors of another unit take ``load_cell`` (a force, kN) — a displacement
        instrument never weighs a force.
    sensor_names : sequence of str
    sensor_units : sequence of str, optional
        The unit of each sensor (mm; kN for a load reading); default all mm. An instrument of
        another unit than its sensor's is refused.

    Returns
    -------
    NoiseModel
    """
    units = dict(zip(sensor_names, sensor_units or ("mm",) * len(sensor_names)))
    if isinstance(instruments, str):
        if instruments in INSTRUMENTS:
            forces = [n for n in sensor_names if units[n] != instrument_unit(instruments) and units[n] == "kN"]
            instruments = {n: "load_cell" if n in forces else instruments for n in sensor_names}
        else:
            instruments = dict.fromkeys(sensor_names, instruments)
    unknown = {k: v for k, v in instruments.items() if v not in INSTRUMENTS}
    if unknown:
        raise ValueError(f"unknown instrument(s) {unknown}; known: {sorted(INSTRUMENTS)}")
    missing = [s for s in sensor_names if s not in instruments]
    if missing:
        raise ValueError(f"no instrument given for sensor(s) {missing}")
    wrong = [s for s in sensor_names if instrument_unit(instruments[s]) != units[s]]
    if wrong:
        s = wrong[0]
        raise ValueError(f"instrument {instruments[s]!r} of sensor {s!r} reads {instrument_unit(instruments[s])}, but "
                         f"{s} reads {units[s]}: give {s} an instrument in {units[s]} (e.g. "
                         f"{'load_cell' if units[s] == 'kN' else 'lvdt'})")
    sigma = {s: INSTRUMENTS[instruments[s]]["sigma_res_mm"] for s in sensor_names}  # in each sensor's unit
    delta = {s: INSTRUMENTS[instruments[s]]["delta"] for s in sensor_names}
    other = {s: u for s, u in units.items() if u != "mm"}
    return NoiseModel(sigma=sigma, delta=delta, units=other or None)


def _require_finite_noise(noise):
    """Refuse NaN, infinite or absurd noise levels (σ = inf made every reading weightless: χ² = 0)."""
    sigmas = noise.sigma if isinstance(noise.sigma, dict) else {None: noise.sigma}
    for sensor, sigma in sigmas.items():
        if sigma is not None:
            what = "absolute noise sigma (mm)" if sensor is None else f"absolute noise sigma of sensor {sensor!r} (mm)"
            check_finite(sigma, what)
    deltas = noise.delta if isinstance(noise.delta, dict) else {None: noise.delta}
    for sensor, delta in deltas.items():
        if delta is not None:
            what = "relative noise delta" if sensor is None else f"relative noise delta of sensor {sensor!r}"
            check_finite(delta, what)
    if noise.covariance is not None and not np.isfinite(np.asarray(noise.covariance, dtype=float)).all():
        raise ValueError("noise covariance must hold finite numbers (mm²); it has NaN or infinite entries")
