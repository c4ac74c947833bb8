"""Small-specimen tests to failure (couplet tension, triplet shear, prism), Eindhoven Set A defaults.

Couplet tension, triplet shear (EN 1052-3) and stack-bonded prism compression, nonlinear. Default
parameters are the TU Eindhoven walls' Set A, the same as ``shear_compression_nl``
(:data:`~fe.scenarios.nonlinear.SET_A_STIFFNESS`: E_b = 16 700 MPa, ν = 0.15, kN = 82 and
kV = 36 N/mm³; strengths f_t = 0.25, c = 0.35 MPa, tanφ = 0.75, G_f^I = 0.018, G_f^II = 0.125 N/mm,
cap f_c = 10.5 MPa: :data:`~fe.scenarios.nonlinear.STRENGTH_PARAMETERS`).

Specimens are stacks of units (stack bond, one unit per course) with bed joints only; the joints
of length ``unit_length`` and area ``A = unit_length · thickness``. Steel plates are rigid: the
nodes of a loaded face share their displacement (ties). Closed forms for uniform joints (units
much stiffer than the joints): couplet peak ``A f_t``; triplet peak ``2 A (c + σ tanφ0)`` and
residual ``2 A σ tanφr``; prism peak ``A f_c``. Default meshes (elements per unit): couplet and prism
Q4 2 × 1, triplet Q8 4 × 1, the cheapest whose peak and load–displacement curve stay within 1 % of
a Q8 12 × 4 mesh (``scripts/mesh_convergence.py``). Control displacements (``load_levels``, mm) are
positive in the loading direction; loads are in kN, positive in the loading direction.
"""

from dataclasses import dataclass

import numpy as np

from ..constraints import constraint_transform
from ..sensors import Gauge, PointDisplacement, sensor_from_dict
from .masonry import wall_mesh
from .nonlinear import (
    SET_A_STIFFNESS,
    NonlinearOptions,
    NonlinearScenario,
    Phase,
    nonlinear_parameters,
    reduced_dof,
)


@dataclass(frozen=True)
class SpecimenOptions(NonlinearOptions):
    """Geometry of a small specimen: bricks of 210 × 100 mm with 10 mm joints by default
    (``unit_height`` = brick height + joint, 62 mm), one unit per course, stack bond, no unit
    mid-plane cracks."""

    unit_length: float = 210.0
    unit_height: float = 62.0
    n_courses: int = 2
    units_per_course: float = 1.0
    thickness: float = 100.0
    bond: str = "stack"
    nx: int = 6
    ny: int = 2
    brick_interfaces: bool = False
    load_levels: tuple = (0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.4)
    increment: float = 0.0005
    max_increment: float = 0.01


def _sensors(options, default):
    if options.sensors is None:
        return default
    return tuple(sensor_from_dict(k, v) for k, v in options.sensors.items())


@dataclass(frozen=True)
class CoupletOptions(SpecimenOptions):
    """Couplet geometry plus the ``control`` variable: ``"displacement"`` (the top plate's vertical
    displacement, mm) or ``"opening"`` (the mean opening of the bed joint over its integration
    points, mm: indirect displacement control, which follows a snap-back of the load against the
    plate displacement)."""

    control: str = "displacement"
    element: str = "Q4"
    nx: int = 2
    ny: int = 1

    def __post_init__(self):
        super().__post_init__()
        if self.control not in ("displacement", "opening"):
            raise ValueError(f"control must be 'displacement' or 'opening'; got {self.control!r}")


class CoupletTension(NonlinearScenario):
    """Direct tension of one bed joint between two units; the top plate is pulled up (control:
    its vertical displacement or the joint's mean opening, mm; see :class:`CoupletOptions`).
    Sensors: ``joint_opening`` (44 mm vertical gauge across the joint) and ``top_uy``."""

    name = "couplet_tension"
    summary = ("Couplet in direct tension: one bed joint between two units pulled apart up to "
               "failure; Eindhoven Set A defaults.")
    Options = CoupletOptions
    PARAMETERS = nonlinear_parameters(SET_A_STIFFNESS)

    def _build(self):
        o = self.options
        if o.n_courses != 2:
            raise ValueError("couplet_tension has two courses (n_courses = 2)")
        self.mesh = mesh = wall_mesh(o)
        bottom, top = mesh.node_sets["bottom"], mesh.node_sets["top"]
        fixed = np.concatenate([2 * bottom, 2 * bottom + 1])
        self.supported_nodes, self.tie_groups = bottom, [2 * top, 2 * top + 1]
        T = constraint_transform(mesh.n_dofs, fixed, ties=self.tie_groups)
        L, H = mesh.width, mesh.height
        self.sensors = _sensors(o, (Gauge("joint_opening", (L / 2, H / 2 - 22), (L / 2, H / 2 + 22)),
                                    PointDisplacement("top_uy", (L / 2, H), "y")))
        self.model = self._nonlinear_model(T)
        self._control = reduced_dof(T, 2 * top[0] + 1)

    def phases(self, values):
        o = self.options
        n = self.model.n_dofs
        if o.control == "displacement":
            return [self._control_phase("tension", self._control, np.zeros(n))]
        J = self.model.jump_operator
        c = np.asarray(J[0::2].sum(axis=0)).ravel() / (J.shape[0] // 2)  # mean opening = c · q
        f_ref = np.zeros(n)
        f_ref[self._control] = 1000.0  # per kN
        return [Phase("tension", "indirect", target=o.load_levels[-1], increment=o.increment, f_const=np.zeros(n),
                      f_ref=f_ref, c=c, levels=o.load_levels, load_scale=1.0)]


@dataclass(frozen=True)
class TripletOptions(SpecimenOptions):
    """Triplet geometry (three units) plus the pre-compression ``precompression`` (MPa) normal to
    the bed joints, applied first by the top plate and held constant, and
    ``joint_strength_factors`` = (s_lower, s_upper), each in (0, 1]: the bond strengths (f_t, c)
    of the lower and upper bed joint × s (default (1, 1): both joints as the parameters say)."""

    n_courses: int = 3
    nx: int = 4
    ny: int = 1
    precompression: float = 0.2
    load_levels: tuple = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0)
    increment: float = 0.002
    max_increment: float = 0.05
    joint_strength_factors: tuple = (1.0, 1.0)

    def __post_init__(self):
        super().__post_init__()
        if not self.precompression >= 0:
            raise ValueError(f"precompression must be >= 0 MPa; got {self.precompression}")
        factors = tuple(self.joint_strength_factors)
        if len(factors) != 2 or not all(0.0 < f <= 1.0 for f in factors):
            raise ValueError("joint_strength_factors (lower, upper bed joint) must be two factors in (0, 1]; "
                             f"got {self.joint_strength_factors!r} (1: the joint as the parameters say)")
        if factors != (1.0, 1.0) and self.law != "composite":
            raise ValueError(f"joint_strength_factors {factors} need law='composite'; got law={self.law!r}")
        object.__setattr__(self, "joint_strength_factors", tuple(float(f) for f in factors))


class TripletShear(NonlinearScenario):
    """EN 1052-3 triplet in 2D: three stacked units, bottom face fixed, top plate held horizontally
    and pressed with ``precompression`` (vertical force constant), the middle unit pushed through a
    rigid plate on its left face (control: its horizontal displacement, mm). Both bed joints shear.
    Sensors: ``middle_ux`` (centre of the middle unit), ``V_top`` (44 mm vertical gauge across the
    upper joint: dilatancy/compaction).

    The option ``joint_strength_factors`` = (s_lower, s_upper) makes one joint weaker than the
    other: the bond strengths :data:`WEAK_STRENGTHS` (``ft_bj``, ``c_bj``) of that joint are
    multiplied by its factor s ∈ (0, 1] (friction, fracture energies and stiffness unchanged; the
    default (1, 1) leaves the specimen as the parameters say). Scaling f_t and c together keeps
    every inequality of the composite law that holds for the sound joint (``ft ≤ c / max(tanφ0,
    tanφr)`` scales on both sides, the snap-back limits ``ft²/GfI < kn`` and ``c²/GfII < ks`` only
    ease), so the option adds no admissibility constraint.
    """

    name = "triplet_shear"
    summary = ("Triplet shear test (EN 1052-3): two bed joints sheared under constant "
               "pre-compression up to failure; Eindhoven Set A defaults.")
    Options = TripletOptions
    PARAMETERS = nonlinear_parameters(SET_A_STIFFNESS)

    def _build(self):
        o = self.options
        if o.n_courses != 3:
            raise ValueError("triplet_shear has three courses (n_courses = 3)")
        self.mesh = mesh = wall_mesh(o)
        bottom, top = mesh.node_sets["bottom"], mesh.node_sets["top"]
        x = mesh.nodes[:, 0]
        middle_nodes = np.unique(mesh.quads[mesh.block_unit[mesh.quad_block] == 1])
        plate = middle_nodes[np.abs(x[middle_nodes]) < 1e-9]
        fixed = np.concatenate([2 * bottom, 2 * bottom + 1, 2 * top])
        self.supported_nodes, self.tie_groups = bottom, [2 * top + 1, 2 * plate]
        T = constraint_transform(mesh.n_dofs, fixed, ties=self.tie_groups)
        L, h = mesh.width, o.unit_height
        self.sensors = _sensors(o, (PointDisplacement("middle_ux", (L / 2, 1.5 * h), "x"),
                                    Gauge("V_top", (L / 2, 2 * h - 22), (L / 2, 2 * h + 22))))
        self.model = self._nonlinear_model(T)
        self._control = reduced_dof(T, 2 * plate[0])
        self._vertical = reduced_dof(T, 2 * top[0] + 1)

    #: the parameters a joint strength factor multiplies (the bond: tensile strength and cohesion)
    WEAK_STRENGTHS = ("ft_bj", "c_bj")

    def _property_rows(self, values):
        rows = super()._property_rows(values)
        model = self.model
        # the bed joint of each interface element: lower (y = h) or upper (y = 2h)
        y = self.mesh.nodes[self.mesh.interfaces[model.interface_elements], 1].mean(axis=1)
        upper = np.repeat(y > 1.5 * self.options.unit_height, model.n_points_per_element)
        for is_upper, factor in zip((False, True), self.options.joint_strength_factors):
            if factor != 1.0:
                weak = super()._property_rows({**values, **{n: factor * values[n] for n in self.WEAK_STRENGTHS}})
                rows[upper == is_upper] = weak[upper == is_upper]
        return rows

    def phases(self, values):
        o = self.options
        n = self.model.n_dofs
        f = np.zeros(n)
        f[self._vertical] = -o.precompression * self.mesh.width * o.thickness
        pre = Phase("precompression", "load", target=1.0, increment=1.0, f_const=np.zeros(n), f_ref=f)
        return [pre, self._control_phase("shear", self._control, f)]


@dataclass(frozen=True)
class PrismOptions(SpecimenOptions):
    """A stack-bonded prism of five units compressed between rigid plates."""

    n_courses: int = 5
    element: str = "Q4"
    nx: int = 2
    ny: int = 1
    load_levels: tuple = (0.05, 0.1, 0.2, 0.3, 0.5, 0.8, 1.2, 2.0)
    increment: float = 0.01
    max_increment: float = 0.05


class PrismCompression(NonlinearScenario):
    """Compression of a stack-bonded prism: bottom face fixed, top plate pushed down (control: its
    downward displacement, mm). Crushing is lumped into the joints' cap (Lourenço & Rots 1997). Sensors:
    ``shortening`` (vertical gauge over the middle three courses, positive when shortening is
    negative: a gauge lengthens positive) and ``top_uy``."""

    name = "prism_compression"
    summary = ("Stack-bonded prism of five units compressed between rigid plates up to "
               "crushing; Eindhoven Set A defaults.")
    Options = PrismOptions
    PARAMETERS = nonlinear_parameters(SET_A_STIFFNESS)
    control_sign = -1.0

    def _build(self):
        o = self.options
        self.mesh = mesh = wall_mesh(o)
        bottom, top = mesh.node_sets["bottom"], mesh.node_sets["top"]
        fixed = np.concatenate([2 * bottom, 2 * bottom + 1])
        self.supported_nodes, self.tie_groups = bottom, [2 * top, 2 * top + 1]
        T = constraint_transform(mesh.n_dofs, fixed, ties=self.tie_groups)
        L, H, h = mesh.width, mesh.height, o.unit_height
        self.sensors = _sensors(o, (Gauge("shortening", (L / 2, h / 2), (L / 2, H - h / 2)),
                                    PointDisplacement("top_uy", (L / 2, H), "y")))
        self.model = self._nonlinear_model(T)
        self._control = reduced_dof(T, 2 * top[0] + 1)

    def phases(self, values):
        return [self._control_phase("compression", self._control, np.zeros(self.model.n_dofs))]
