"""The measurement check every door runs before any fitting: loads and readings against what the
model can produce — units, signs and range — as codes and numbers.

A unit slip is the commonest mistake in a laboratory log and the costliest to miss: readings in µm
under a ``[mm]`` header are 1000× every FE run, and an inversion on them puts every parameter on
a bound with χ²/dof ~10⁸ and no word on why. Two checks catch it, both here and both called by
every entry point that reads data (``podkrig run``, ``invert``, ``rvc``, ``overparam``,
``sensitivity``, ``diagnose``; :func:`podkrig.io.measurement_log.read_measurement` runs the
first on every log it reads):

1. :func:`check_loads` — the measured loads against the model's load levels, before anything is
   evaluated: a load ``RANGE_FACTOR`` × or more beyond the top level (N under a ``kN`` header is
   1000×), or loads of the opposite sign of every level beyond a load-cell offset
   (:data:`LOAD_OFFSET_SHARE` of the top level).
2. :func:`check_readings` — each sensor's readings against FE runs of the model (a study's probe
   runs and its training design; for a surrogate, its training outputs,
   :func:`surrogate_training_outputs`): a sensor ``RANGE_FACTOR`` × larger than every run, or
   smaller than every run, or of the opposite sign in every run at every reading beyond 3σ.

Both raise :class:`MeasurementCheckError`, which carries the problems as
:class:`~podkrig.online.findings.Finding` objects (level ``"error"``): a stable ``code`` and its
``values``. The sentences and the remedy — a command-line option or a study-file key — are
written by :mod:`podkrig.reports.findings` at the edge (the command line, the study).

Codes and their ``values``
--------------------------
- ``load-scale``: ``source``, ``column``, ``row`` (1-based, or None), ``load_max`` and
  ``level_max`` (load unit), ``unit``, ``ratio`` (-), ``likely_unit`` (str or None), ``quantity``;
- ``load-sign``: ``source``, ``column``, ``row``, ``n_loads``, ``load_min``, ``level_min``,
  ``level_max``, ``unit``, ``quantity``;

``quantity`` is ``"load"``, or ``"control displacement"`` for a displacement-controlled
(nonlinear) scenario, whose "loads" are the levels of its control displacement (a length unit):
the checks are the same — a µm log under a ``mm`` header is 1000× the last level, a control of the
other sign a sign convention — while the force is a reading (checked by :func:`check_readings`,
which lets it fall past the peak).
- ``reading-scale``: ``source``, ``sensor``, ``direction`` ("larger" or "smaller"), ``ratio``
  (-; the factor to the middle of the runs' range), ``unit_slip`` (bool: the ratio lies in
  :data:`UNIT_SLIP_RATIO`, a µm ↔ mm slip — N ↔ kN for a force), ``runs`` ("probe", "training" or
  "surrogate"), ``n_runs``, ``unit`` (the sensor's: mm, or kN for a load reading);
- ``reading-sign``: ``source``, ``sensor``, ``runs``, ``n_runs``.

Thresholds
----------
- :data:`RANGE_FACTOR` = 20: every power-of-ten unit slip from 100× up is caught, while parameter
  bounds somewhat off, and the spread of the box beyond the probe's points, pass.
- :data:`UNIT_SLIP_RATIO` = 300–3000: a ratio in this range names the neighbouring unit (µm for
  mm, N for kN); another one is "a unit error?".
- :data:`LOAD_OFFSET_SHARE` = 2 %: a load cell read at rest shows a small offset of either sign;
  loads beyond 2 % of the top level on the other side are a sign convention, not an offset.
"""

import math

import numpy as np

from podkrig.online.findings import Finding

__all__ = ["LOAD_OFFSET_SHARE", "RANGE_FACTOR", "UNIT_SLIP_RATIO", "MeasurementCheckError", "check_loads",
           "check_readings", "likely_unit", "reading_problems", "surrogate_training_outputs"]

#: A sensor (or the load) this many times larger (or smaller) than every FE run (or the top load
#: level) is a probable unit error (µm read as mm is 1000×).
RANGE_FACTOR = 20.0
#: A ratio in this range (1000× give or take the parameter box) names the neighbouring unit
#: ("µm read as mm?"); any other ratio beyond :data:`RANGE_FACTOR` is "a unit error?".
UNIT_SLIP_RATIO = (300.0, 3000.0)
#: Loads of the opposite sign of every model level are refused beyond this share of the top
#: level's magnitude (a load cell's offset at rest is smaller).
LOAD_OFFSET_SHARE = 0.02

#: Load units that are lengths: the scenario is displacement-controlled, its "load" the control displacement.
CONTROL_UNITS = ("mm",)

#: unit → {power of ten of (value as read) / (value in the unit): the unit the file was probably in}
_NEIGHBOURS = {
    "kN": {3: "N", 2: "daN"},
    "N": {3: "mN"},
    "mm": {3: "µm", 6: "nm"},
    "MPa": {3: "kPa", 6: "Pa"},
}


class MeasurementCheckError(ValueError):
    """A measurement refused by :func:`check_loads` or :func:`check_readings`.

    Attributes
    ----------
    findings : tuple of Finding
        Each problem as a code and its values (level ``"error"``); the edge words them
        (:func:`podkrig.reports.findings.refusal`).
    """

    def __init__(self, findings):
        self.findings = tuple(findings)
        super().__init__(self._plain())

    def _plain(self):
        """A plain fallback (codes and values) for a caller that does not word the findings."""
        parts = []
        for f in self.findings:
            values = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                               for k, v in f.values.items() if k != "source")
            parts.append(f"{f.code} ({values})")
        source = self.findings[0].values.get("source", "measurement") if self.findings else "measurement"
        return f"{source}: the measurement check refused the data: " + "; ".join(parts)


def likely_unit(unit, ratio):
    """The unit a value was probably written in when it reads ``ratio`` × its expected size in
    ``unit`` (``likely_unit("kN", 1000.0)`` → ``"N"``); None when the ratio is no clear power of
    ten of a neighbouring unit."""
    if not (ratio > 0 and math.isfinite(ratio)):
        return None
    p = round(math.log10(ratio))
    lo, hi = UNIT_SLIP_RATIO
    if p == 3 and not lo <= ratio <= hi:
        return None
    return _NEIGHBOURS.get(unit, {}).get(p)


def check_loads(loads, levels, load_unit="", *, source="measurement", column="load", rows=None):
    """Refuse measured loads of another unit or sign than the model's load levels.

    Parameters
    ----------
    loads : array_like of shape (n,)
        Measured loads, ``load_unit``.
    levels : array_like of shape (n_levels,)
        The model's load levels, ``load_unit``.
    load_unit : str
        The scenario's load unit (``"step"``: the levels are step numbers, not checked here;
        :func:`~podkrig.online.measurement.level_weights` takes only the levels themselves).
    source, column : str
        The file and the load column's header, for the message.
    rows : array_like of int, optional
        The row of each load in the file (1-based), for the message.

    Raises
    ------
    MeasurementCheckError
        ``load-scale``: the largest load is :data:`RANGE_FACTOR` × the top level or more;
        ``load-sign``: loads beyond :data:`LOAD_OFFSET_SHARE` of the top level on the other side
        of zero than every level.
    """
    loads = np.asarray(loads, dtype=float).ravel()
    levels = np.asarray(levels, dtype=float).ravel()
    if load_unit == "step" or not len(loads) or not len(levels):
        return
    top = float(np.max(np.abs(levels)))
    if not top > 0:
        return
    rows = None if rows is None else np.asarray(rows)

    def row(i):
        return None if rows is None else int(rows[i])

    found = []
    quantity = "control displacement" if load_unit in CONTROL_UNITS else "load"
    sign = 1.0 if np.all(levels >= 0) else -1.0 if np.all(levels <= 0) else 0.0
    if sign:
        wrong = sign * loads < -LOAD_OFFSET_SHARE * top
        if np.any(wrong):
            i = int(np.argmin(sign * loads))
            found.append(Finding("load-sign", "measurement", {
                "source": str(source), "column": column, "row": row(i), "n_loads": int(wrong.sum()),
                "load_min": float(loads[i]), "level_min": float(levels.min()), "level_max": float(levels.max()),
                "unit": load_unit, "quantity": quantity}, level="error"))
    i = int(np.argmax(np.abs(loads)))
    ratio = float(abs(loads[i])) / top
    if ratio >= RANGE_FACTOR:
        found.append(Finding("load-scale", "measurement", {
            "source": str(source), "column": column, "row": row(i), "load_max": float(loads[i]),
            "level_max": float(levels[np.argmax(np.abs(levels))]), "unit": load_unit, "ratio": ratio,
            "likely_unit": likely_unit(load_unit, ratio), "quantity": quantity}, level="error"))
    if found:
        raise MeasurementCheckError(found)


def reading_problems(data, noise, sensor_names, levels, response, Y, *, runs="training", factor=RANGE_FACTOR,
                     signs=True):
    """Sensors whose readings are ``factor``× larger or smaller than in every FE run, or of the
    opposite sign: a ``reading-scale`` or ``reading-sign`` finding each (level ``"error"``).

    A sensor is flagged when its largest reading beyond 3σ exceeds ``factor`` × the largest of any
    run (or its largest reading plus 3σ is below every run's largest ÷ ``factor``). The ratio
    given is of the sensor's largest reading to the geometric mean of the runs' smallest and largest extremes — the middle of the
    range the parameter box spans, so a box whose runs differ 10× among themselves still names a
    µm ↔ mm slip as "about 1000×" (:data:`UNIT_SLIP_RATIO`). A sensor is of the wrong sign when
    every run has the opposite sign at every reading beyond 3σ.

    Parameters
    ----------
    data : Measurement
    noise : NoiseModel
    sensor_names, levels, response
        The model's sensors, load levels and ``load_response`` (the runs' layout).
    Y : ndarray of shape (n_runs, n_loads * n_sensors)
        FE readings (mm) at the model's levels, load-major; NaN past the level a nonlinear run
        reached.
    runs : {"probe", "training", "surrogate"}
        What ``Y`` is, for the message.
    signs : bool
        Also flag sensors of the opposite sign. The diagnosis passes ``False``: a reversed or
        faulty gauge is one of the causes it exists to find (its ``gauge_fault`` candidate), while
        a unit slip of 1000× is not.

    Returns
    -------
    list of Finding
    """
    op = data.observation(sensor_names, levels, response)
    G = np.nan_to_num(op.apply(Y), nan=0.0)  # (n_runs, n_obs): every FE run at the measured loads
    d = data.data
    sd = noise.std(data)
    col = np.broadcast_to(np.arange(len(data.sensor_names)), data.values.shape)[data.mask]
    common = {"source": data.source, "runs": runs, "n_runs": int(len(Y))}
    lo, hi = UNIT_SLIP_RATIO
    found = []
    for j, name in enumerate(data.sensor_names):
        common["unit"] = data.sensor_units[j]
        sel = col == j
        dj, sj, gj = d[sel], sd[sel], G[:, sel]
        if not len(dj):
            continue
        run_max = np.abs(gj).max(axis=1)  # each run's largest reading of this sensor, mm
        excess = float(np.max(np.abs(dj) - 3 * sj))  # beyond the noise: a noise-level gauge is no unit error
        upper = float(np.max(np.abs(dj) + 3 * sj))
        moved = run_max[run_max > 0]
        middle = float(np.sqrt(moved.min() * moved.max())) if len(moved) else 0.0  # mm
        if excess > factor * run_max.max():
            r = float(np.max(np.abs(dj))) / middle if middle > 0 else math.inf
            found.append(Finding("reading-scale", "measurement", {
                **common, "sensor": name, "direction": "larger", "ratio": r, "unit_slip": bool(lo <= r <= hi)},
                level="error"))
        elif run_max.min() > factor * upper:
            largest = float(np.max(np.abs(dj)))
            r = middle / largest if largest > 0 else math.inf
            found.append(Finding("reading-scale", "measurement", {
                **common, "sensor": name, "direction": "smaller", "ratio": r, "unit_slip": bool(lo <= r <= hi)},
                level="error"))
        elif signs:
            signal = np.abs(dj) > 3 * sj
            fe_sign = np.sign(gj[:, signal])
            if fe_sign.size and np.all(fe_sign == -np.sign(dj[signal])[None, :]):
                found.append(Finding("reading-sign", "measurement", {**common, "sensor": name}, level="error"))
    return found


def check_readings(data, noise, sensor_names, levels, response, Y, *, runs="training", factor=RANGE_FACTOR,
                   signs=True):
    """:func:`reading_problems`, raised: the same parameters (``Y`` of shape ``(n_runs, n_loads *
    n_sensors)`` or ``(n_runs, n_loads, n_sensors)``, the model's readings: mm, kN for a load
    reading); nothing is checked when ``Y`` holds no run.

    Raises
    ------
    MeasurementCheckError
        One ``reading-scale`` or ``reading-sign`` finding per sensor flagged.
    """
    Y = np.asarray(Y, dtype=float)
    if not len(Y):
        return
    found = reading_problems(data, noise, sensor_names, levels, response, Y.reshape(len(Y), -1), runs=runs,
                             factor=factor, signs=signs)
    if found:
        raise MeasurementCheckError(found)


def surrogate_training_outputs(surrogate):
    """The readings the surrogate reproduces at its training points, ``(n_train, n_outputs)`` mm:
    its training FE runs (exactly for an interpolating kriging; within the POD truncation and any
    nugget otherwise — far below the :data:`RANGE_FACTOR` this is compared at)."""
    return np.asarray(surrogate.predict_unit(surrogate.U_), dtype=float)
