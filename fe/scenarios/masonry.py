"""Shared pieces of the mesoscale masonry scenarios: parameters and affine stiffness parts.

Units are expanded plane-stress continua; bed joints, head joints and unit mid-planes are
zero-thickness interfaces with uncoupled elastic stiffness diag(kV, kN) (thesis eq. 2.3 in 2D).
Head joints have ``r_hj`` times the bed-joint stiffness.
"""

import math
import re
from dataclasses import dataclass, fields

import numpy as np

from ..assembly import StiffnessPart, element_dofs
from ..elements.interface import IL4, IL6
from ..elements.quad import QUADS
from ..materials import D0, D1, plane_stress_coefficients
from ..mesh import BrickWallLayout, brick_wall
from ..sensors import sensor_table
from .base import ParameterInfo

_BIG = 1e9

MASONRY_PARAMETERS = (
    ParameterInfo("E_b", 12000.0, "MPa", 0.0, 1e6, "Young's modulus of the expanded units", lower_open=True),
    ParameterInfo("nu_b", 0.15, "-", 0.0, 0.5, "Poisson's ratio of the expanded units", upper_open=True),
    ParameterInfo("kN_bj", 100.0, "N/mm³", 0.0, _BIG, "normal stiffness of bed joints", lower_open=True),
    ParameterInfo("kV_bj", 40.0, "N/mm³", 0.0, _BIG, "shear stiffness of bed joints", lower_open=True),
    ParameterInfo("r_hj", 1.0, "-", 0.0, 10.0, "head-joint / bed-joint stiffness ratio"),
    ParameterInfo("kN_bb", 1e5, "N/mm³", 0.0, _BIG, "normal stiffness of unit mid-plane interfaces", lower_open=True),
    ParameterInfo("kV_bb", 1e5, "N/mm³", 0.0, _BIG, "shear stiffness of unit mid-plane interfaces", lower_open=True),
)


#: Input limits of the wall options: lengths in mm (below a micrometre or above 100 m is a unit
#: error), mesh divisions per unit and courses (the element count bounds memory: ~8 unknowns per
#: element, and a sparse factorisation of 10^5 elements already takes a few GiB), load levels.
MIN_LENGTH_MM, MAX_LENGTH_MM = 1e-3, 1e5
MAX_UNITS_PER_COURSE = 200
MAX_COURSES = 500
MAX_DIVISIONS = 64
MAX_ELEMENTS = 100_000
MAX_LOAD_LEVELS = 1000
MAX_LOAD = 1e9


@dataclass(frozen=True)
class WallOptions:
    """Options shared by the masonry wall scenarios (lengths in mm, loads in the scenario's unit).

    Geometry and discretisation as in :class:`~fe.mesh.BrickWallLayout`; ``thickness`` of the
    wall; ``continuum`` merges the units into one homogeneous body without joints (the
    stiff-joint limit, for verification); ``load_levels``; ``sensors`` (name → definition dict,
    see :func:`fe.sensors.sensor_from_dict`; None = the scenario's default set).
    """

    unit_length: float = 260.0
    unit_height: float = 65.0
    n_courses: int = 18
    units_per_course: float = 4.5
    thickness: float = 120.0
    bond: str = "running"
    nx: int = 6
    ny: int = 2
    element: str = "Q8"
    brick_interfaces: bool = True
    continuum: bool = False
    load_levels: tuple = (25.0, 50.0, 75.0, 100.0)
    sensors: dict | None = None

    def __post_init__(self):
        for name in ("unit_length", "unit_height", "thickness"):
            v = getattr(self, name)
            if not (math.isfinite(v) and MIN_LENGTH_MM <= v <= MAX_LENGTH_MM):
                raise ValueError(f"{name} must be > 0 mm (a length in [{MIN_LENGTH_MM:g}, {MAX_LENGTH_MM:g}] mm); got {v!r}")
        if not (math.isfinite(self.units_per_course) and 0.5 <= self.units_per_course <= MAX_UNITS_PER_COURSE):
            raise ValueError(f"units_per_course must be in [0.5, {MAX_UNITS_PER_COURSE}]; got {self.units_per_course!r}")
        for name, upper in (("n_courses", MAX_COURSES), ("nx", MAX_DIVISIONS), ("ny", MAX_DIVISIONS)):
            v = getattr(self, name)
            if isinstance(v, bool) or not 1 <= v <= upper:
                raise ValueError(f"{name} must be an integer in [1, {upper}]; got {v!r}")
        elements = self.n_courses * math.ceil(self.units_per_course + 1) * self.nx * self.ny
        if elements > MAX_ELEMENTS:
            raise ValueError(
                f"the mesh would have about {elements} elements (~{8 * elements} unknowns, several GiB for the "
                f"factorisation); at most {MAX_ELEMENTS}: reduce nx, ny or the wall size"
            )
        if not self.load_levels or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in self.load_levels):
            raise ValueError(f"load_levels must be a non-empty list of numbers; got {self.load_levels}")
        if len(self.load_levels) > MAX_LOAD_LEVELS or any(not (math.isfinite(v) and abs(v) <= MAX_LOAD)
                                                          for v in self.load_levels):
            raise ValueError(f"load_levels must be at most {MAX_LOAD_LEVELS} finite numbers of magnitude "
                             f"<= {MAX_LOAD:g}; got {str(self.load_levels)[:200]}")
        object.__setattr__(self, "sensors", sensor_table(self.sensors))  # [[sensors]] arrays become a table
        if self.sensors is not None and not self.sensors:
            raise ValueError("sensors must define at least one sensor (leave it out for the scenario's default set)")
        for name in self.sensors or ():
            if not isinstance(name, str) or re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,39}", name, re.ASCII) is None:
                raise ValueError(f"sensor name {name!r}: use 1-40 letters, digits, '_', '-' or '.' (it becomes a "
                                 "CSV column, an HDF5 key and a figure label)")
        if len(set(self.load_levels)) != len(self.load_levels):
            raise ValueError(f"load_levels must be distinct; got {self.load_levels}")
        object.__setattr__(self, "load_levels", tuple(float(v) for v in self.load_levels))


def wall_mesh(options):
    """The wall mesh of a scenario's options (fields of :class:`~fe.mesh.BrickWallLayout` plus
    ``continuum``: merge the units into one homogeneous body without joints, the stiff-joint
    limit used for verification)."""
    layout = BrickWallLayout(**{f.name: getattr(options, f.name) for f in fields(BrickWallLayout) if hasattr(options, f.name)})
    mesh = brick_wall(layout)
    return mesh.without_interfaces() if options.continuum else mesh


def masonry_parts(mesh, thickness):
    """The eight parameter-independent stiffness parts of a mesoscale masonry mesh.

    Returns
    -------
    list of StiffnessPart
        ``units_D0``, ``units_D1`` (see :mod:`fe.materials`), then ``{bed,head,brick}_{normal,shear}``
        (unit kN or kV). Families absent from the mesh give empty parts.
    """
    quad = QUADS[mesh.element]
    coords = mesh.nodes[mesh.quads]
    qdofs = element_dofs(mesh.quads)
    parts = [
        StiffnessPart("units_D0", qdofs, quad.stiffness(coords, D0, thickness)),
        StiffnessPart("units_D1", qdofs, quad.stiffness(coords, D1, thickness)),
    ]
    iface = IL6 if mesh.element == "Q8" else IL4
    for kind in ("bed", "head", "brick"):
        conn = mesh.interfaces[mesh.interfaces_of_kind(kind)]
        idofs = element_dofs(conn)
        xy = mesh.nodes[conn]
        parts.append(StiffnessPart(f"{kind}_normal", idofs, iface.stiffness(xy, 0.0, 1.0, thickness)))
        parts.append(StiffnessPart(f"{kind}_shear", idofs, iface.stiffness(xy, 1.0, 0.0, thickness)))
    return parts


def masonry_theta(values):
    """Coefficients of :func:`masonry_parts` for a full parameter dict, ``(8,)``."""
    c0, c1 = plane_stress_coefficients(values["E_b"], values["nu_b"])
    r = values["r_hj"]
    return np.array(
        [
            c0, c1,
            values["kN_bj"], values["kV_bj"],
            r * values["kN_bj"], r * values["kV_bj"],
            values["kN_bb"], values["kV_bb"],
        ]
    )
