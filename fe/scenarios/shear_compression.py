"""Shear–compression test of a masonry wall in the style of the TU Eindhoven shear walls.

Geometry (after Raijmakers & Vermeltfoort's TU Eindhoven walls as modelled by Lourenço & Rots
[1]_): bricks 210 × 52 × 100 mm with 10 mm joints, i.e. expanded units 220 × 62 mm; 16 courses of
4.5 units, a wall 990 mm wide, 992 mm high and 100 mm thick, running bond as in
:mod:`fe.scenarios.diagonal_compression`.

Loading, as in the tests: first a vertical pre-compression ``precompression`` (MPa) on the top,
then a horizontal force H at the top, with the top edge kept horizontal by a rigid steel beam
(all top nodes share one horizontal and one vertical displacement). The bottom edge is fixed.
Load levels are values of H (kN); every reading includes the pre-compression.

Sensors (mm, gauges positive when lengthening): ``top_ux`` (horizontal displacement of the top
beam), the diagonals ``D1`` (bottom-left → top-right) and ``D2``, and vertical toe gauges
``V_left`` and ``V_right`` (flexural rotation). This scenario serves as a *validation model*:
calibrated parameters are propagated through it (RVC).

Default parameters are those identified for these walls in [1]_: E_b = 16 700 MPa, ν = 0.15,
kN = 82 N/mm³, kV = 36 N/mm³.

``base_joints`` (off here, on in the nonlinear ``shear_compression_nl``): lay the wall on a rigid
beam and cap it with one, each joined to the wall by a bed joint (the walls as built; see
:func:`wall_supports`). Off, this scenario is exactly the model it always was; the option lets the
nonlinear twin of a linear wall (same options) and a study that wants the joints choose them.

References
----------
.. [1] P. B. Lourenço, J. G. Rots, Multisurface interface model for analysis of masonry
   structures, J. Eng. Mech. 123 (1997) 660–668.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..constraints import constraint_transform
from ..model import LinearModel
from ..sensors import Gauge, PointDisplacement, sensor_from_dict
from .base import Scenario
from .masonry import MASONRY_PARAMETERS, WallOptions, masonry_parts, masonry_theta, wall_mesh

_DEFAULTS = {"E_b": 16700.0, "nu_b": 0.15, "kN_bj": 82.0, "kV_bj": 36.0}

DEFAULT_SENSORS = (
    PointDisplacement("top_ux", (495.0, 992.0), "x"),
    Gauge("D1", (100.0, 100.0), (890.0, 890.0)),
    Gauge("D2", (100.0, 890.0), (890.0, 100.0)),
    Gauge("V_left", (50.0, 20.0), (50.0, 200.0)),
    Gauge("V_right", (940.0, 20.0), (940.0, 200.0)),
)


def wall_supports(mesh, base_joints):
    """Nodes held fixed (the bottom beam or the wall's bottom face) and nodes tied to the top beam's
    u_x, u_y (every top-beam node, or the wall's top face) of a wall mesh, ``(bottom, top)``.

    With ``base_joints`` the mesh has beam blocks joined to the wall by bed joints
    (:class:`~fe.mesh.BrickWallLayout` ``base_joints``); holding or tying *every* node of a beam
    makes it rigid. Without, the wall's faces are clamped and tied directly.
    """
    if base_joints:
        return mesh.node_sets["bottom_beam"], mesh.node_sets["top_beam"]
    return mesh.node_sets["bottom"], mesh.node_sets["top"]


def default_sensors(mesh, base_joints):
    """:data:`DEFAULT_SENSORS`; with base joints ``top_ux`` moves from the wall's top face (then a
    joint, where the displacement jumps) to mid-height of the top beam, which it then reads."""
    if not base_joints or "top_beam" not in mesh.node_sets:
        return DEFAULT_SENSORS
    y = float(mesh.nodes[mesh.node_sets["top_beam"], 1].mean())
    return tuple(PointDisplacement(s.name, (s.point[0], y), s.component) if s.name == "top_ux" else s
                 for s in DEFAULT_SENSORS)


@dataclass(frozen=True)
class ShearCompressionOptions(WallOptions):
    """Options of the shear–compression scenario: those of
    :class:`~fe.scenarios.masonry.WallOptions` with the TU Eindhoven wall's geometry, plus the
    vertical ``precompression`` (MPa) and ``base_joints`` (bed joints between the wall and rigid
    bottom and top beams; off); load levels are horizontal forces (kN)."""

    unit_length: float = 220.0
    unit_height: float = 62.0
    n_courses: int = 16
    thickness: float = 100.0
    load_levels: tuple = (10.0, 20.0, 30.0, 40.0)
    precompression: float = 0.30
    base_joints: bool = False

    def __post_init__(self):
        super().__post_init__()
        if not self.precompression >= 0:
            raise ValueError(f"precompression must be >= 0 MPa; got {self.precompression}")


class ShearCompression(Scenario):
    """Pre-compressed wall under a horizontal top load with the top kept horizontal."""

    name = "shear_compression"
    summary = "Shear–compression test of a wall in the style of the TU Eindhoven shear walls, linear elastic."
    Options = ShearCompressionOptions
    PARAMETERS = tuple(
        dataclasses.replace(p, default=_DEFAULTS.get(p.name, p.default)) for p in MASONRY_PARAMETERS
    )
    load_unit = "kN"

    def _build(self):
        o = self.options
        self.mesh = mesh = wall_mesh(o)
        bottom, top = wall_supports(mesh, o.base_joints)
        fixed = np.concatenate([2 * bottom, 2 * bottom + 1])
        self.supported_nodes, self.tie_groups = bottom, [2 * top, 2 * top + 1]
        transform = constraint_transform(mesh.n_dofs, fixed, ties=self.tie_groups)
        patterns = np.zeros((mesh.n_dofs, 2))
        patterns[2 * top[0] + 1, 0] = -o.precompression * mesh.width * o.thickness  # N on the beam
        patterns[2 * top[0], 1] = 1.0  # unit horizontal force on the beam, N
        if o.sensors is None:
            self.sensors = default_sensors(mesh, o.base_joints)
        else:
            self.sensors = tuple(sensor_from_dict(k, v) for k, v in o.sensors.items())
        self.model = LinearModel(
            mesh, masonry_parts(mesh, o.thickness), transform, patterns, self.sensors,
            solver=self._solver_name,
        )
        levels = self.load_levels
        self.load_coefficients = np.column_stack([np.ones_like(levels), 1000.0 * levels])

    def theta(self, values):
        return masonry_theta(values)
