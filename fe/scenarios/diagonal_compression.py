"""Diagonal compression test of a square masonry panel (ASTM E519 / RILEM LUMB6 type).

Default geometry, fixed so that independent codes can be compared: expanded units 260 × 65 mm;
18 courses of 4.5 units (course 0 at the bottom starts with a full unit at x = 0, odd courses with
a half unit); panel 1170 × 1170 mm, thickness 120 mm.

Loading: force F along the bottom-left → top-right diagonal, applied as a uniform normal pressure
on the top face (−y) and on the right face (−x), each over the ``shoe_length`` = 130 mm nearest
the top-right corner and each with resultant F/√2, integrated over exactly that length (an edge
partly under a shoe is integrated over the part under it, so any length works at any mesh).
Load levels 25, 50, 75, 100 kN.

Supports: two shoes over ``support_length`` = 130 mm from the bottom-left corner, on
the bottom and on the left face (:mod:`fe.supports`):

- ``support = "rigid"`` (default): a rigid shoe bonded to the wall holds in x and y the nodes of
  the face edges lying inside the length — only nodes of the units touching the face, never the
  duplicated node of the next course across a bed joint. A length off the element edges is
  snapped to the nearest edge end, with a warning, ``scenario.support_length_used`` (face → mm)
  and ``derived`` of :func:`~fe.scenarios.catalogue.describe_scenario` for the spec.
- ``support = "springs"``: distributed springs of ``support_stiffness`` (N/mm³, default 1000, a
  stiff bedding; normal and tangential, like an interface to a rigid base) over exactly the
  length, partial edges included.

Formerly every node within the length was pinned by its coordinates, the node of the
second course at y = 130 mm included: a point constraint whose effect grows under refinement, so
absolute displacements did not converge (``scripts/bench_support_convergence.py``).

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

Mesh: 6 × 2 Q8 elements per full unit (9 364 dofs). D1 and D2 lie within 0.1 % and 0.25 % of
their 48 × 16 values (observed rate ≈ 2). Absolute displacements converge monotonically but
slower, rate 0.8–0.9 with rigid supports (the end of a bonded rigid shoe is a singular point) and
1.6 with springs: at 6 × 2 the DIC-grid rms is 3 % (rigid) / 1.4 % (springs) and the top-right
corner's small vertical displacement 19 % / 8 % from the Richardson limit
(``scripts/bench_support_convergence.py``, BENCHMARKS.md "Supports that converge").
``continuum = true`` merges the units into one homogeneous body without joints (the stiff-joint
limit, for verification).

References
----------
.. [1] ASTM E519/E519M, Standard test method for diagonal tension (shear) in masonry assemblages.
.. [2] C. Chisari, PhD thesis (Trieste), ch. 5: the diagonal compression test.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..boundary import Patch
from ..constraints import constraint_transform
from ..exceptions import SpecError
from ..loads import LoadPerturbation, edge_traction
from ..model import LinearModel
from ..sensors import Gauge, sensor_from_dict
from ..supports import SUPPORT_MODELS, shoe_supports
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
    supports along each face from their corner, the ``support`` model ("rigid" or "springs") and
    the springs' ``support_stiffness`` (N/mm³, used by "springs" only)."""

    shoe_length: float = 130.0
    support_length: float = 130.0
    support: str = "rigid"
    support_stiffness: float = 1000.0

    def __post_init__(self):
        super().__post_init__()
        check_support_options(self)


def check_support_options(o):
    """Raise ValueError naming the option for a bad ``support`` or ``support_stiffness``."""
    if o.support not in SUPPORT_MODELS:
        raise ValueError(f"option 'support' must be one of {SUPPORT_MODELS}; got {o.support!r}")
    if not (math.isfinite(o.support_stiffness) and 0.0 < o.support_stiffness <= 1e9):
        raise ValueError(f"option 'support_stiffness' must be a stiffness in (0, 1e9] N/mm³; got {o.support_stiffness!r}")


def corner_supports(scenario, kind):
    """The supports of the diagonal tests: shoes over ``support_length`` from the bottom-left corner
    on the bottom and left faces, ``kind`` "rigid" or "springs" (:func:`fe.supports.shoe_supports`); sets
    ``scenario.support_model`` and ``scenario.support_length_used`` (face → mm)."""
    o, mesh, name = scenario.options, scenario.mesh, scenario.name
    W, H = mesh.width, mesh.height
    for key in ("shoe_length", "support_length"):
        if not 0 < getattr(o, key) <= min(W, H):
            raise SpecError(f"{name}: option {key!r} must be in (0, {min(W, H):g}] mm; got {getattr(o, key)}")
    L = o.support_length
    patches = (Patch("bottom", 0, (0.0, L)), Patch("left", 1, (0.0, L)))
    support = shoe_supports(mesh, patches, o.thickness, kind, owner=name)
    scenario.support_model = support
    scenario.support_length_used = dict(support.lengths_used)
    return support


class DiagonalCompression(Scenario):
    """Diagonal compression of a square running-bond panel; see the module docstring."""

    name = "diagonal_compression"
    summary = ("Diagonal compression test of a square running-bond panel (ASTM E519 / RILEM "
               "LUMB6 type), linear elastic.")
    Options = DiagonalCompressionOptions
    PARAMETERS = MASONRY_PARAMETERS
    load_unit = "kN"

    def _build(self):
        o = self.options
        self.mesh = mesh = wall_mesh(o)
        support = corner_supports(self, o.support)
        self.supported_nodes, self.tie_groups = support.fixed_nodes, []
        parts = masonry_parts(mesh, o.thickness) + ([support.springs] if support.springs is not None else [])
        f = self._shoe_loads()
        if o.sensors is None:
            self.sensors = DEFAULT_SENSORS
        else:
            self.sensors = tuple(sensor_from_dict(k, v) for k, v in o.sensors.items())
        self.model = LinearModel(
            mesh, parts, constraint_transform(mesh.n_dofs, support.fixed_dofs),
            f[:, None], self.sensors, solver=self._solver_name,
        )
        self.load_coefficients = 1000.0 * self.load_levels[:, None]  # kN -> N times the unit load

    def derived(self):
        """``support_length_used`` (face → mm) when the rigid support's length was snapped to element
        edges (see :func:`corner_supports`)."""
        used = self.support_length_used
        if all(abs(v - self.options.support_length) <= 1e-9 * v for v in used.values()):
            return {}
        return {"support_length_used": dict(used)}

    def theta(self, values):
        theta = masonry_theta(values)
        return np.append(theta, self.options.support_stiffness) if self.options.support == "springs" else theta

    def _shoe_loads(self, gradient=False, rotated=False):
        """Nodal forces ``(n_dofs,)`` N of the two loading shoes for a unit load F = 1 N: pressure
        with resultant 1/√2 N on each. ``gradient``: the derivative of the pressure with respect
        to an offset e (mm) of both shoes' resultants towards the top-left corner. ``rotated``:
        the shoe tractions turned by +90° (counter-clockwise)."""
        o, mesh = self.options, self.mesh
        W, H, L = mesh.width, mesh.height, o.shoe_length
        p = (1.0 / np.sqrt(2.0)) / (L * o.thickness)
        # a linear pressure p (1 + 12 e (s − s_c) / L²) keeps the resultant and moves it by e
        g = 12.0 * p / L**2 if gradient else p
        sign_top, sign_right = (-1.0, 1.0) if gradient else (1.0, 1.0)  # top shoe moves to −x, right to +y
        t_top, t_right = np.array([0.0, -g * sign_top]), np.array([-g * sign_right, 0.0])
        if rotated:
            t_top, t_right = t_top[::-1] * (-1, 1), t_right[::-1] * (-1, 1)  # (x, y) -> (-y, x)
        f = edge_traction(mesh, mesh.edge_sets["top"], t_top, o.thickness, (W - L, W), axis=0, gradient=gradient)
        f += edge_traction(mesh, mesh.edge_sets["right"], t_right, o.thickness, (H - L, H), axis=1,
                           gradient=gradient)
        return f

    def load_perturbations(self):
        """The load line offset along the shoes (``"offset"``, mm) and rotated (``"rotation"``).

        ``offset``: an offset e (mm) moves the resultant of each loading shoe along its face towards
        the panel's top-left corner (the top shoe by −e in x, the right shoe by +e in y), i.e. the
        load line by √2·e off the diagonal, with the shoe pressure varying linearly; loads are
        exactly affine in e. Admissible while the pressure stays compressive:
        ``|e| ≤ shoe_length / 6``. Patterns ``(n_dofs, 1)`` N/mm per N of F.

        ``rotation``: every shoe traction turned by +90°, ``(n_dofs, 1)`` N per N of F; a load line
        rotated by φ (counter-clockwise, the tractions turning with it, e.g. a misaligned actuator
        with friction at the shoes) has patterns ``cos φ f + sin φ f⊥``.
        """
        return {
            "offset": LoadPerturbation(
                "offset", "shift", "mm", self.options.shoe_length / 6.0, "load line offset",
                lambda: self._shoe_loads(gradient=True)[:, None]),
            "rotation": LoadPerturbation(
                "rotation", "turn", "degree", None, "load line rotated",
                lambda: self._shoe_loads(rotated=True)[:, None]),
        }
