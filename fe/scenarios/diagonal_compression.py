"""Diagonal compression test of a square masonry panel (ASTM E519 / RILEM LUMB6 type).

Default geometry, fixed so that independent codes can be compared: expanded units 260 × 65 mm;
18 courses of 4.5 units (course 0 at the bottom starts with a full unit at x = 0, odd courses with
a half unit); panel 1170 × 1170 mm, thickness 120 mm.

Loading: force F along the bottom-left → top-right diagonal, applied as a uniform normal pressure
on the top face (−y) and on the right face (−x), each over the 130 mm nearest the top-right corner
and each with resultant F/√2. Support: every node on the bottom face and on the left face within
130 mm of the bottom-left corner is fixed in x and y. Load levels 25, 50, 75, 100 kN.

Sensors (gauges, mm, positive when lengthening):

- ``D1``: compressed diagonal, (302.157, 302.157) → (867.843, 867.843); ``D2``: tensile
  diagonal, (302.157, 867.843) → (867.843, 302.157). Both are 800 mm long and centred.
- Short gauges on the panel centre line, where the stress state is nearly uniform shear plus
  compression, chosen so that E_b, kN_bj, kV_bj and r_hj are jointly identifiable
  (``scripts/identifiability.py`` prints the singular values of the normalised sensitivity
  matrix; ``tests/test_diagonal_compression.py`` checks its conditioning):

  - ``U1``: 100 mm horizontal gauge inside one unit (course 8): unit strain only → E_b;
  - ``BJ_V``: 50 mm vertical gauge across the bed joint at y = 585 mm: unit strain plus bed-joint
    closure → kN_bj;
  - ``BJ_D``: 50 mm gauge inclined at 45° across the same bed joint: adds bed-joint slip → kV_bj;
  - ``HJ_H``: 50 mm horizontal gauge across the head joint at x = 520 mm in course 8: head-joint
    opening → r_hj.

Mesh: 6 × 2 Q8 elements per full unit (9 360 dofs). D1 and D2 change by less than 0.5 % under
a further refinement and lie within 0.25 % of the Richardson-extrapolated limit
(``scripts/bench_fe.py --convergence``). ``continuum = true`` merges the units into one
homogeneous body without joints (the stiff-joint limit, for verification).

References
----------
.. [1] ASTM E519/E519M, Standard test method for diagonal tension (shear) in masonry assemblages.
.. [2] C. Chisari, PhD thesis (Trieste), ch. 5: the diagonal compression test.
"""

from dataclasses import dataclass

import numpy as np

from ..constraints import constraint_transform
from ..exceptions import SpecError
from ..loads import edge_traction
from ..model import LinearModel
from ..sensors import Gauge, sensor_from_dict
from .base import Scenario
from .masonry import MASONRY_PARAMETERS, WallOptions, masonry_parts, masonry_theta, wall_mesh

_D_LO, _D_HI = 302.157, 867.843

DEFAULT_SENSORS = (
    Gauge("D1", (_D_LO, _D_LO), (_D_HI, _D_HI)),
    Gauge("D2", (_D_LO, _D_HI), (_D_HI, _D_LO)),
    Gauge("U1", (540.0, 552.5), (640.0, 552.5)),
    Gauge("BJ_V", (600.0, 560.0), (600.0, 610.0)),
    Gauge("BJ_D", (575.0, 560.0), (625.0, 610.0)),
    Gauge("HJ_H", (495.0, 552.5), (545.0, 552.5)),
)


@dataclass(frozen=True)
class DiagonalCompressionOptions(WallOptions):
    """Options of the diagonal compression scenario (lengths in mm, loads in kN): those of
    :class:`~fe.scenarios.masonry.WallOptions` plus the lengths of the loading shoes and of the
    supports along each face from their corner."""

    shoe_length: float = 130.0
    support_length: float = 130.0


class DiagonalCompression(Scenario):
    """Diagonal compression of a square running-bond panel; see the module docstring."""

    name = "diagonal_compression"
    Options = DiagonalCompressionOptions
    PARAMETERS = MASONRY_PARAMETERS
    load_unit = "kN"

    def _build(self):
        o = self.options
        self.mesh = mesh = wall_mesh(o)
        W, H = mesh.width, mesh.height
        for name in ("shoe_length", "support_length"):
            if not 0 < getattr(o, name) <= min(W, H):
                raise SpecError(f"{self.name}: {name} must be in (0, {min(W, H):g}] mm; got {getattr(o, name)}")
        x, y = mesh.nodes[:, 0], mesh.nodes[:, 1]
        tol = 1e-9 * W
        supported = np.flatnonzero(
            ((np.abs(y) < tol) & (x <= o.support_length + tol)) | ((np.abs(x) < tol) & (y <= o.support_length + tol))
        )
        fixed = np.concatenate([2 * supported, 2 * supported + 1])
        # unit load F = 1 N: pressure p with resultant 1/√2 N on each shoe
        p = (1.0 / np.sqrt(2.0)) / (o.shoe_length * o.thickness)
        f = edge_traction(mesh, mesh.edge_sets["top"], (0.0, -p), o.thickness, (W - o.shoe_length, W), axis=0)
        f += edge_traction(mesh, mesh.edge_sets["right"], (-p, 0.0), o.thickness, (H - o.shoe_length, H), axis=1)
        if o.sensors is None:
            self.sensors = DEFAULT_SENSORS
        else:
            self.sensors = tuple(sensor_from_dict(k, v) for k, v in o.sensors.items())
        self.model = LinearModel(
            mesh, masonry_parts(mesh, o.thickness), constraint_transform(mesh.n_dofs, fixed),
            f[:, None], self.sensors, solver=self._solver_name,
        )
        self.load_coefficients = 1000.0 * self.load_levels[:, None]  # kN -> N times the unit load

    def theta(self, values):
        return masonry_theta(values)
