"""Sensors: linear operators from nodal displacements to readings (mm).

- :class:`Gauge` (LVDT / extensometer): relative displacement of two points along the line
  joining them, positive when they move apart (DESIGN sign convention).
- :class:`SlipGauge`: relative displacement of two points along a fixed direction (joint slip).
- :class:`PointDisplacement`: one displacement component of a point.
- :class:`DICGrid`: both displacement components on a regular grid of points, as digital image
  correlation would give them.

Each point is located in its element by inverse isoparametric mapping. A point on an interface
(a joint or a unit mid-plane, where the displacement is discontinuous) is refused with an error
naming the sensor: move it off the joint.
"""

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .elements.quad import QUADS
from .exceptions import SensorError

_INSIDE_TOL = 1e-9  # reference-coordinate tolerance for "inside an element"


@dataclass(frozen=True)
class Gauge:
    """A gauge between points ``p1`` and ``p2`` (mm); reading in mm, positive when lengthening."""

    name: str
    p1: tuple
    p2: tuple

    kind = "gauge"

    def __post_init__(self):
        object.__setattr__(self, "p1", tuple(float(v) for v in self.p1))
        object.__setattr__(self, "p2", tuple(float(v) for v in self.p2))
        if np.allclose(self.p1, self.p2):
            raise SensorError(f"gauge {self.name!r} has coincident end points {self.p1} mm")

    @property
    def channel_names(self):
        return (self.name,)

    @property
    def points(self):
        return np.array([self.p1, self.p2])

    @property
    def length(self):
        """Gauge length, mm."""
        return float(np.hypot(self.p2[0] - self.p1[0], self.p2[1] - self.p1[1]))

    def weights(self):
        """Reading_c = Σ w u_comp(point): arrays ``(channel, point, component, w)``."""
        e = (np.array(self.p2) - np.array(self.p1)) / self.length
        return np.zeros(4, np.intp), np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1]), np.r_[-e, e]

    def to_dict(self):
        return {"kind": "gauge", "p1": list(self.p1), "p2": list(self.p2)}


@dataclass(frozen=True)
class SlipGauge(Gauge):
    """A gauge with anchors ``p1``, ``p2`` reading ``(u(p2) − u(p1))·e`` along a fixed unit
    ``direction`` e (default +x) instead of along the line joining them: e.g. the slip of a bed
    joint read by two anchors one above the other (mm)."""

    direction: tuple = (1.0, 0.0)

    kind = "slip"

    def __post_init__(self):
        super().__post_init__()
        d = np.asarray(self.direction, float)
        if d.shape != (2,) or not np.linalg.norm(d) > 0:
            raise SensorError(f"slip gauge {self.name!r}: direction must be a non-zero (x, y); got {self.direction}")
        object.__setattr__(self, "direction", tuple(float(v) for v in d / np.linalg.norm(d)))

    def weights(self):
        e = np.asarray(self.direction)
        return np.zeros(4, np.intp), np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1]), np.r_[-e, e]

    def to_dict(self):
        return {"kind": "slip", "p1": list(self.p1), "p2": list(self.p2), "direction": list(self.direction)}


@dataclass(frozen=True)
class PointDisplacement:
    """Displacement component ``"x"`` or ``"y"`` of a point (mm)."""

    name: str
    point: tuple
    component: str

    kind = "point"

    def __post_init__(self):
        object.__setattr__(self, "point", tuple(float(v) for v in self.point))
        if self.component not in ("x", "y"):
            raise SensorError(f"sensor {self.name!r}: component must be 'x' or 'y'; got {self.component!r}")

    @property
    def channel_names(self):
        return (self.name,)

    @property
    def points(self):
        return np.array([self.point])

    def weights(self):
        return np.zeros(1, np.intp), np.zeros(1, np.intp), np.array(["xy".index(self.component)]), np.ones(1)

    def to_dict(self):
        return {"kind": "point", "point": list(self.point), "component": self.component}


@dataclass(frozen=True)
class DICGrid:
    """Displacements (x and y) on an ``nx × ny`` grid of points spanning ``[x0, x1] × [y0, y1]`` mm.

    Channels are named ``f"{name}[i,j].ux"`` and ``f"{name}[i,j].uy"``, i along x.

    With ``subset > 0`` each channel is the mean displacement over a ``subset × subset`` mm square
    centred on its grid point, as a correlation subset measures it (e.g. 15 × 15 mm, which
    straddles joints as real DIC does): the midpoint rule on ``subset_samples × subset_samples`` cell centres of the square
    (4 × 4 by default: exact for a field linear in each element, and a subset straddling a joint
    averages both sides with the weight of their areas to 1/``subset_samples``). The sample count
    is a named choice (INFERRED, not from a DIC code; ``docs/references.md``). ``subset = 0``: point values.
    """

    name: str
    x0: float
    y0: float
    x1: float
    y1: float
    nx: int
    ny: int
    subset: float = 0.0
    subset_samples: int = 4

    kind = "dic"

    def __post_init__(self):
        if self.nx < 1 or self.ny < 1:
            raise SensorError(f"DIC grid {self.name!r} needs nx, ny >= 1; got {self.nx}, {self.ny}")
        if not (math.isfinite(self.subset) and self.subset >= 0.0):
            raise SensorError(f"DIC grid {self.name!r}: subset must be a size >= 0 mm; got {self.subset}")
        if not 1 <= self.subset_samples <= 16:
            raise SensorError(f"DIC grid {self.name!r}: subset_samples must be 1-16 per side; got {self.subset_samples}")

    @property
    def points(self):
        """The grid points (subset centres), ``(nx·ny, 2)`` mm."""
        X, Y = np.meshgrid(
            np.linspace(self.x0, self.x1, self.nx), np.linspace(self.y0, self.y1, self.ny), indexing="ij"
        )
        return np.column_stack([X.ravel(), Y.ravel()])

    def _offsets(self):
        m = self.subset_samples if self.subset > 0.0 else 1
        t = ((np.arange(m) + 0.5) / m - 0.5) * self.subset
        dx, dy = np.meshgrid(t, t, indexing="ij")
        return np.column_stack([dx.ravel(), dy.ravel()])

    @property
    def sample_points(self):
        """Where the field is sampled (the points :meth:`weights` refers to): the grid points, or
        every subset's sample points, subset by subset, ``(nx·ny·m², 2)`` mm."""
        return (self.points[:, None, :] + self._offsets()[None, :, :]).reshape(-1, 2)

    @property
    def channel_names(self):
        return tuple(
            f"{self.name}[{i},{j}].u{c}" for i in range(self.nx) for j in range(self.ny) for c in "xy"
        )

    def weights(self):
        n, m2 = self.nx * self.ny, len(self._offsets())
        point = np.repeat(np.arange(n * m2), 2)  # every sample, x then y
        component = np.tile([0, 1], n * m2)
        channel = 2 * (point // m2) + component
        return channel, point, component, np.full(2 * n * m2, 1.0 / m2)

    def to_dict(self):
        d = {"kind": "dic", "x0": self.x0, "y0": self.y0, "x1": self.x1, "y1": self.y1, "nx": self.nx, "ny": self.ny}
        if self.subset > 0.0:
            d.update(subset=self.subset, subset_samples=self.subset_samples)
        return d


#: the forms a spec's ``sensors`` take (TOML), for error messages and docs
SENSOR_TABLE_FORMS = (
    "a table of named sensors:\n"
    "    [sensors]                      # [scenario.sensors] in a study file\n"
    '    D1 = { kind = "gauge", p1 = [302.2, 302.2], p2 = [867.8, 867.8] }\n'
    "or an array of tables, each with its name:\n"
    "    [[sensors]]                    # [[scenario.sensors]] in a study file\n"
    '    name = "D1"\n'
    '    kind = "gauge"\n'
    "    p1 = [302.2, 302.2]\n"
    "    p2 = [867.8, 867.8]\n"
    "(kinds: gauge, point, dic, slip; `podkrig scenarios NAME` shows their fields)"
)


def sensor_table(value):
    """A spec's ``sensors`` as a dict name → definition: a table of named sensors as is, an
    array of tables (TOML ``[[sensors]]``) keyed by each entry's ``name``; None stays None.

    Raises
    ------
    SensorError
        Any other form, an entry without a string ``name`` or a repeated name; the message shows
        the accepted forms (:data:`SENSOR_TABLE_FORMS`).
    """
    if value is None or isinstance(value, dict):
        return value
    if not isinstance(value, (list, tuple)):
        raise SensorError(f"sensors: got {type(value).__name__} {str(value)[:60]!r}; give {SENSOR_TABLE_FORMS}")
    table = {}
    for k, entry in enumerate(value):
        if not isinstance(entry, dict) or not isinstance(entry.get("name"), str):
            raise SensorError(f"sensors: entry {k + 1} of the array ({str(entry)[:60]}) has no name = \"...\"; "
                              f"give {SENSOR_TABLE_FORMS}")
        definition = {key: v for key, v in entry.items() if key != "name"}
        if entry["name"] in table:
            raise SensorError(f"sensors: the name {entry['name']!r} is used twice (entries of the array); "
                              "give each sensor its own name")
        table[entry["name"]] = definition
    return table


def sensor_from_dict(name, d):
    """Rebuild a sensor from its ``to_dict()`` form."""
    kinds = {"gauge": Gauge, "slip": SlipGauge, "point": PointDisplacement, "dic": DICGrid}
    if not isinstance(d, dict):
        raise SensorError(f"sensor {name!r}: its definition must be a table such as "
                          f'{{ kind = "gauge", p1 = [x1, y1], p2 = [x2, y2] }}; got {str(d)[:60]!r}')
    d = dict(d)
    kind = d.pop("kind", None)
    if kind not in kinds:
        raise SensorError(f"sensor {name!r}: kind must be one of {sorted(kinds)}; got {kind!r}")
    return kinds[kind](name, **d)


def absolute_displacements(sensors):
    """The readings that are absolute displacements of a point, and where that point is.

    Gauges and slip gauges read relative displacements (immune to a rigid-body motion of the
    specimen) and are left out; a :class:`PointDisplacement` reads one component of its point; a
    :class:`DICGrid` reads both at each grid point (a subset mean equals the value at the subset
    centre for a field linear in x and y, as a rigid motion is).

    Parameters
    ----------
    sensors : sequence of sensors

    Returns
    -------
    dict of str to tuple
        Channel name → ``(x, y, component, grid)``: the point (mm), the component (0 = x, 1 = y)
        and the DIC grid's name (None for a point displacement sensor).
    """
    out = {}
    for s in sensors:
        if isinstance(s, DICGrid):
            names = s.channel_names
            for k, (x, y) in enumerate(s.points):
                for c in (0, 1):
                    out[names[2 * k + c]] = (float(x), float(y), c, s.name)
        elif isinstance(s, PointDisplacement):
            out[s.name] = (s.point[0], s.point[1], "xy".index(s.component), None)
    return out


def locate_points(mesh, points, owner="point"):
    """Element and reference coordinates of each point.

    Parameters
    ----------
    mesh : Mesh
    points : ndarray of shape (n_points, 2)
        Physical coordinates, mm.
    owner : str or sequence of str
        Name(s) used in error messages (one per point, or one for all).

    Returns
    -------
    element : ndarray of shape (n_points,)
    xi : ndarray of shape (n_points, 2)

    Raises
    ------
    SensorError
        A point outside the mesh, or on an interface (in elements of two different blocks).
    """
    points = np.atleast_2d(np.asarray(points, dtype=float))
    owners = [owner] * len(points) if isinstance(owner, str) else list(owner)
    etype = QUADS[mesh.element]
    corner_xy = mesh.nodes[mesh.quads[:, :4]]
    lo, hi = corner_xy.min(axis=1), corner_xy.max(axis=1)
    span = max(mesh.width, mesh.height)
    tol = 1e-9 * span
    element = np.empty(len(points), np.intp)
    xi = np.empty((len(points), 2))
    for k, p in enumerate(points):
        cand = np.flatnonzero(np.all((p >= lo - tol) & (p <= hi + tol), axis=1))
        if len(cand) == 0:
            raise SensorError(f"sensor {owners[k]!r}: point ({p[0]:g}, {p[1]:g}) mm lies outside the specimen")
        ref = etype.inverse_map(mesh.nodes[mesh.quads[cand]], np.repeat(p[None], len(cand), axis=0))
        inside = np.all(np.abs(ref) <= 1 + _INSIDE_TOL, axis=1)
        if not inside.any():
            raise SensorError(f"sensor {owners[k]!r}: point ({p[0]:g}, {p[1]:g}) mm lies outside the specimen")
        blocks = np.unique(mesh.quad_block[cand[inside]])
        if len(blocks) > 1:
            raise SensorError(
                f"sensor {owners[k]!r}: point ({p[0]:g}, {p[1]:g}) mm lies on an interface (joint or unit "
                "mid-plane) where the displacement jumps; move it off the joint"
            )
        first = np.flatnonzero(inside)[0]
        element[k], xi[k] = cand[first], ref[first]
    return element, xi


def sensor_operator(mesh, sensors):
    """The sparse operator ``H`` with readings = ``H @ u``.

    Parameters
    ----------
    mesh : Mesh
    sensors : sequence of Gauge, PointDisplacement or DICGrid

    Returns
    -------
    H : scipy.sparse.csr_matrix of shape (n_channels, n_dofs)
    names : tuple of str
        Channel names, in row order.
    """
    etype = QUADS[mesh.element]
    rows, cols, vals, names = [], [], [], []
    for s in sensors:
        pts = getattr(s, "sample_points", s.points)  # a DIC subset is sampled at several points
        element, xi = locate_points(mesh, pts, owner=s.name)
        N = etype.shape(xi)  # (n_points, n_nodes)
        nodes = mesh.quads[element]  # (n_points, n_nodes)
        channel, point, component, w = s.weights()
        rows.append(np.repeat(len(names) + channel, nodes.shape[1]))
        cols.append((2 * nodes[point] + component[:, None]).ravel())
        vals.append((w[:, None] * N[point]).ravel())
        names.extend(s.channel_names)
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise SensorError(f"sensor names must be unique; repeated: {dup}")
    if not names:
        return sp.csr_matrix((0, mesh.n_dofs)), ()
    H = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(len(names), mesh.n_dofs),
    )
    return H, tuple(names)
