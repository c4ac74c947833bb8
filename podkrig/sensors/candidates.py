"""Candidate sensors for optimal placement: gauges on a grid, DIC points, or a user list.

A :class:`CandidateSet` is an ordered tuple of :mod:`fe.sensors` objects (each one candidate: a
gauge/LVDT with one channel, or a DIC point with two channels ``ux``, ``uy``), with a sensor *kind*
(``"lvdt"`` or ``"dic"``, which selects the noise level) and a cost per candidate. Candidates whose
points lie on a joint or unit mid-plane (where the displacement jumps), outside the specimen, or in a
forbidden zone are dropped when the set is built: :func:`valid_point_mask` says which.
"""

import math
from dataclasses import dataclass, replace

import numpy as np

from fe.exceptions import SensorError
from fe.sensors import DICGrid, Gauge, locate_points, sensor_from_dict
from podkrig.limits import MAX_DIC_POINTS, check_grid

KINDS = ("lvdt", "dic")

_ANGLE_TOL = 0.5  # degrees: a grid pair counts as oriented at θ when within this of θ (mod 180°)


@dataclass(frozen=True)
class Zone:
    """A forbidden rectangle ``[x0, x1] × [y0, y1]`` mm (e.g. around a flat-jack slot); sensors
    with a point inside (boundary included) are not candidates."""

    x0: float
    y0: float
    x1: float
    y1: float

    def __post_init__(self):
        if not (self.x0 < self.x1 and self.y0 < self.y1):
            raise ValueError(f"forbidden zone needs x0 < x1 and y0 < y1 (mm); got {self}")

    def contains(self, points):
        """Mask of points ``(..., 2)`` mm inside the zone, ``(...)``."""
        p = np.asarray(points, dtype=float)
        return (p[..., 0] >= self.x0) & (p[..., 0] <= self.x1) & (p[..., 1] >= self.y0) & (p[..., 1] <= self.y1)

    def crossed_by(self, p1, p2):
        """Mask of segments ``p1 → p2`` (each ``(n, 2)`` mm) with a point in the zone, ``(n,)``
        (the segment is sampled every 1/256 of its length: a gauge bridging the zone is refused)."""
        t = np.linspace(0.0, 1.0, 257)[None, :, None]
        p1, p2 = np.atleast_2d(p1)[:, None, :], np.atleast_2d(p2)[:, None, :]
        return self.contains(p1 + t * (p2 - p1)).any(axis=1)

    @classmethod
    def parse(cls, text):
        """``"X0:Y0:X1:Y1"`` (mm) → Zone."""
        parts = str(text).split(":")
        try:
            values = [float(v) for v in parts]
        except ValueError:
            values = []
        if len(values) != 4:
            raise ValueError(f"forbidden zone {text!r}: expected X0:Y0:X1:Y1 in mm, e.g. 500:500:700:650")
        return cls(*values)


@dataclass(frozen=True, eq=False)
class CandidateSet:
    """Candidate sensors.

    Attributes
    ----------
    sensors : tuple of fe.sensors sensor objects
        One per candidate; names are unique.
    kinds : tuple of str
        ``"lvdt"`` (gauges and point displacements) or ``"dic"`` (DIC points), per candidate.
    cost : ndarray of shape (n_candidates,)
        Cost per candidate, in the user's unit (e.g. € or instrument count); > 0.
    is_current : ndarray of shape (n_candidates,) of bool
        True for sensors of the scenario's current layout (added for comparison).
    """

    sensors: tuple
    kinds: tuple
    cost: np.ndarray = None
    is_current: np.ndarray = None

    def __post_init__(self):
        sensors = tuple(self.sensors)
        n = len(sensors)
        object.__setattr__(self, "sensors", sensors)
        object.__setattr__(self, "kinds", tuple(self.kinds))
        cost = np.ones(n) if self.cost is None else np.asarray(self.cost, dtype=float)
        current = np.zeros(n, bool) if self.is_current is None else np.asarray(self.is_current, dtype=bool)
        object.__setattr__(self, "cost", cost)
        object.__setattr__(self, "is_current", current)
        if len(self.kinds) != n or cost.shape != (n,) or current.shape != (n,):
            raise ValueError(f"kinds, cost and is_current need one entry per candidate ({n})")
        bad = sorted(set(self.kinds) - set(KINDS))
        if bad:
            raise ValueError(f"unknown sensor kind(s) {bad}; allowed: {KINDS}")
        if np.any(~(cost > 0)):
            raise ValueError("every candidate's cost must be > 0")
        names = [s.name for s in sensors]
        if len(set(names)) != n:
            dup = sorted({m for m in names if names.count(m) > 1})
            raise ValueError(f"candidate names must be unique; repeated: {dup}")

    def __len__(self):
        return len(self.sensors)

    @property
    def names(self):
        return tuple(s.name for s in self.sensors)

    @property
    def centres(self):
        """Centre of each candidate (gauge mid-point, the point itself), ``(n, 2)`` mm."""
        return np.array([s.points.mean(axis=0) for s in self.sensors]).reshape(-1, 2)

    def index(self, names):
        """Indices of candidates by name; a clear error for an unknown one."""
        lookup = {n: i for i, n in enumerate(self.names)}
        missing = [n for n in names if n not in lookup]
        if missing:
            raise ValueError(f"unknown candidate sensor(s) {missing}; candidates include {list(self.names[:8])}…")
        return np.array([lookup[n] for n in names], dtype=np.intp)

    def subset(self, indices):
        idx = np.asarray(indices, dtype=np.intp)
        return CandidateSet(tuple(self.sensors[i] for i in idx), tuple(self.kinds[i] for i in idx),
                            self.cost[idx], self.is_current[idx])

    def __add__(self, other):
        return CandidateSet(self.sensors + other.sensors, self.kinds + other.kinds,
                            np.concatenate([self.cost, other.cost]),
                            np.concatenate([self.is_current, other.is_current]))

    def with_cost(self, kind, cost):
        """A copy with every candidate of ``kind`` costing ``cost``."""
        c = self.cost.copy()
        c[np.array([k == kind for k in self.kinds], bool)] = float(cost)
        return replace(self, cost=c)

    def to_dict(self):
        return {
            "sensors": {s.name: s.to_dict() for s in self.sensors},
            "kinds": list(self.kinds),
            "cost": self.cost.tolist(),
            "is_current": self.is_current.tolist(),
        }


def valid_point_mask(mesh, points, forbidden=()):
    """Which points can carry a sensor end: inside the specimen, off every interface, outside
    every forbidden :class:`Zone`. ``points`` ``(n, 2)`` mm → mask ``(n,)``."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    ok = np.ones(len(points), bool)
    for zone in forbidden:
        ok &= ~zone.contains(points)
    for k in np.flatnonzero(ok):
        try:
            locate_points(mesh, points[k:k + 1])
        except SensorError:
            ok[k] = False
    return ok


def _sensor_ok(mesh, sensor, forbidden):
    if isinstance(sensor, Gauge) and any(z.crossed_by(sensor.p1, sensor.p2)[0] for z in forbidden):
        return False
    return bool(valid_point_mask(mesh, sensor.points, forbidden).all())


def gauge_grid(mesh, x, y, *, lengths, orientations=(0.0, 45.0, 90.0, 135.0), forbidden=(), cost=1.0, prefix="G"):
    """Gauges between pairs of points of the grid ``x × y`` whose length lies in ``lengths`` and whose
    direction is one of ``orientations``.

    Parameters
    ----------
    mesh : fe.mesh.Mesh
    x, y : array_like
        Grid coordinates, mm. Grid points on a joint, outside the specimen or in a forbidden zone
        are dropped.
    lengths : (float, float)
        Smallest and largest gauge length, mm.
    orientations : sequence of float
        Directions in degrees from the x axis (mod 180°), matched within 0.5°.
    forbidden : sequence of Zone
        No end point inside, and no gauge crossing one.
    cost : float
        Cost of each gauge.
    prefix : str
        Names are ``f"{prefix}{i}"`` in candidate order.

    Returns
    -------
    CandidateSet
        Each unordered pair of admissible grid points at most once, ordered by the first point's
        grid index (x-major), then the second's.
    """
    check_grid(len(x) * len(y), "gauge", "the gauge grid")
    lo, hi = (float(v) for v in lengths)
    if not 0 < lo <= hi:
        raise ValueError(f"gauge lengths must satisfy 0 < min <= max (mm); got {lengths}")
    X, Y = np.meshgrid(np.asarray(x, float), np.asarray(y, float), indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    pts = pts[valid_point_mask(mesh, pts, forbidden)]
    if len(pts) < 2:
        raise ValueError("fewer than two admissible grid points (off joints, inside the specimen, outside "
                         "forbidden zones): refine or move the grid")
    i, j = np.triu_indices(len(pts), k=1)
    d = pts[j] - pts[i]
    length = np.hypot(d[:, 0], d[:, 1])
    angle = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 180.0
    orient = np.asarray(orientations, float) % 180.0
    diff = np.abs(angle[:, None] - orient[None, :])
    diff = np.minimum(diff, 180.0 - diff)
    keep = (length >= lo - 1e-9) & (length <= hi + 1e-9) & np.any(diff <= _ANGLE_TOL, axis=1)
    i, j = i[keep], j[keep]
    for zone in forbidden:  # a gauge may not bridge a forbidden zone either
        clear = ~zone.crossed_by(pts[i], pts[j])
        i, j = i[clear], j[clear]
    sensors = tuple(Gauge(f"{prefix}{n}", tuple(pts[a]), tuple(pts[b])) for n, (a, b) in enumerate(zip(i, j)))
    if not sensors:
        raise ValueError(f"no gauge of length {lo:g}–{hi:g} mm along {list(orientations)}° fits the grid")
    return CandidateSet(sensors, ("lvdt",) * len(sensors), np.full(len(sensors), float(cost)))


def dic_points(mesh, x, y, *, forbidden=(), cost=1.0, prefix="P"):
    """DIC measurement points (both displacement components) on the grid ``x × y`` mm; points on
    joints, outside the specimen or in forbidden zones are dropped. Each is a 1 × 1
    :class:`fe.sensors.DICGrid` (channels ``NAME[0,0].ux`` and ``.uy``)."""
    check_grid(len(x) * len(y), "dic", "the DIC grid")
    X, Y = np.meshgrid(np.asarray(x, float), np.asarray(y, float), indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    pts = pts[valid_point_mask(mesh, pts, forbidden)]
    if not len(pts):
        raise ValueError("no admissible DIC point on the grid (all on joints, outside or forbidden)")
    sensors = tuple(DICGrid(f"{prefix}{n}", p[0], p[1], p[0], p[1], 1, 1) for n, p in enumerate(pts))
    return CandidateSet(sensors, ("dic",) * len(sensors), np.full(len(sensors), float(cost)))


def user_candidates(mesh, definitions, *, forbidden=(), cost=1.0, strict=True):
    """Candidates from a ``{name: definition dict}`` mapping (the scenario's ``sensors`` option
    format, see :func:`fe.sensors.sensor_from_dict`). A definition may carry ``cost``.

    With ``strict`` an inadmissible candidate (on a joint, outside, in a forbidden zone) is an
    error naming it; otherwise it is dropped.
    """
    sensors, kinds, costs = [], [], []
    for name, d in definitions.items():
        d = dict(d)
        c = float(d.pop("cost", cost))
        s = sensor_from_dict(name, d)
        if not _sensor_ok(mesh, s, forbidden):
            if strict:
                raise ValueError(f"candidate {name!r} has a point on a joint, outside the specimen or in a "
                                 "forbidden zone; move it")
            continue
        sensors.append(s)
        kinds.append("dic" if isinstance(s, DICGrid) else "lvdt")
        costs.append(c)
    return CandidateSet(tuple(sensors), tuple(kinds), np.array(costs))


def current_candidates(scenario, *, cost=1.0):
    """The scenario's current sensors as candidates flagged ``is_current`` (for comparison)."""
    kinds = tuple("dic" if isinstance(s, DICGrid) else "lvdt" for s in scenario.sensors)
    n = len(kinds)
    return CandidateSet(tuple(scenario.sensors), kinds, np.full(n, float(cost)), np.ones(n, bool))


def parse_range(text, what="--grid-x"):
    """``"START:STOP:STEP"`` mm (STOP included when on the step) → ndarray."""
    parts = str(text).split(":")
    try:
        a, b, s = (float(v) for v in parts)
    except ValueError:
        raise ValueError(f"{what} {text!r}: expected START:STOP:STEP in mm, e.g. 45:1125:90") from None
    if not all(math.isfinite(v) for v in (a, b, s)):
        raise ValueError(f"{what} {text!r}: START, STOP and STEP must be finite numbers (mm)")
    if not s > 0 or b < a:
        raise ValueError(f"{what} {text!r}: need STEP > 0 and STOP >= START")
    count = (b - a) / s + 1e-9
    if count >= MAX_DIC_POINTS:  # no grid axis is longer than the largest grid
        raise ValueError(f"{what} {text!r}: {count:.3g} points along one axis, above the limit of {MAX_DIC_POINTS} "
                         "(podkrig.limits); use a coarser step")
    return a + s * np.arange(int(np.floor(count)) + 1)


__all__ = [
    "KINDS",
    "CandidateSet",
    "Zone",
    "current_candidates",
    "dic_points",
    "gauge_grid",
    "parse_range",
    "user_candidates",
    "valid_point_mask",
]
