"""In-situ flat-jack tests: single, double, and the horizontal + vertical jack set-up (``flat_jack``).

A running-bond panel under an in-situ vertical pre-compression σ0 gets slots (horizontal ones in
a bed joint, vertical ones through units and head joints); each slot holds a flat jack with a
pressure history. Readings are taken at every step of the loading phases with the gauges zeroed
before the cut, as in the field (ASTM C1196/C1197, RILEM MDT.D.4/D.5). Geometry, jacks, phases,
layouts and defaults are a design for this project (INFERRED, see ``docs/references.md`` "INFERRED
choices"; **not** the layout of Chisari's thesis, which is not public).

Panel: expanded units 260 × 65 mm, 8 units × 24 courses = 2080 × 1560 mm, 120 mm thick;
course k (1-based) spans y ∈ [65(k−1), 65k]; odd courses have head joints at x = 260 i. Bottom
edge u_y = 0 and u_x = 0 at its middle node (both nodes of the head joint there); top edge loaded by σ0; sides free. Mesh: ``nx × ny``
Q8 per unit (default 2 × 1, i.e. 4 × 2 Q4-equivalent) and twice as fine in ``refine``
(default x ∈ [650, 1430], y ∈ [585, 1170]); node lines are added at every slot end
(8007 dofs; the 4 × 2 / 8 × 4 Q8 mesh, 24 315 dofs, changes the gauge readings by ≤ 0.5 %).

Presets (``preset``):

- ``"chisari"``: jack H in the bed joint y = 780 over x ∈ [845, 1235]; V1 and V2
  vertical at x = 845 and 1235 over y ∈ [780, 975]: a U-shaped cut round a 390 × 195 mm block
  held only by its top bed joint. Phases ``0b`` (cut, 1 step), ``1`` (p_H 0.1 → 1.0 MPa in 0.1
  steps, p_V1 = p_V2 = 0.05 seating, 10 steps), ``2`` (p_H = 1.0, p_V 0.10 → 0.50 in 0.05, 9
  steps), ``3`` (p_V2 = 0.5, p_V1 0.6 → 3.0 in 0.1, 25 steps; see *Phase 3* below). Layouts
  ``L6``, ``L18``, ``DIC`` (1200 points) or ``L18+DIC``; ``dic_subset`` (mm,
  0 = point values) makes each DIC reading the mean over a square subset, which straddles joints
  as real DIC does (:class:`fe.sensors.DICGrid`).
- ``"single"``: jack H alone (ASTM C1196 / RILEM MDT.D.4); phases ``0b`` and ``1``
  (p 0.05 → 0.60 MPa in 0.05 steps); layout ``standard``: three vertical gauges across the slot
  (x = 975, 1040, 1105; gauge lengths 195, 260, 195 mm: the anchors avoid head joints).
- ``"double"``: jacks H and H2 (bed joint y = 1170, 390 mm above; ASTM C1197 / RILEM MDT.D.5,
  "30 to 50 cm" apart) on a common supply; phases ``0b`` and ``1`` (p 0.1 → 1.0 MPa); layout
  ``standard``: three vertical gauges between the jacks (x = 975, 1040, 1105; gauge lengths 325,
  260, 325 mm) and one horizontal (195 mm) for the apparent Poisson's ratio.

``slots`` and ``schedule`` replace a preset's slots and phases (any number of jacks), e.g.::

    slots = [{name = "H", orientation = "horizontal", at = 780.0, start = 845.0, end = 1235.0, Ka = 1.0}]
    schedule = [{name = "1", steps = [{H = 0.1}, {H = 0.2}]}]

(``at`` is the y of a bed joint or the x of a vertical slot; ``start``/``end`` the extent along
the slot; a vertical slot spans whole courses.) Every jack not named in a step keeps its pressure.

Loading and superposition. The model is linear, so a test is the superposition of a few load
patterns on **one** model, the cut panel (slot interfaces removed): the release of the in-situ
stress on the slot faces, and a unit pressure in each jack. Cutting a slot under σ0 is the cut
panel loaded on the slot faces by the traction the removed joint carried; with the nominal
in-situ stress (σx, σy, τ) = (0, −σ0, 0) this is a jack "pressure" −σ0 on horizontal slots and
nothing on vertical ones (``release = "nominal"``, the default). This is exactly the principle of
the single flat-jack test (the reading returns to its pre-cut value at p = σ0) and exact whenever
the pre-compressed panel is uniformly stressed, as this support arrangement makes it (checked to
round-off in the tests). ``release = "exact"`` computes the traction from a pre-cut solve instead
(a second factorisation) for panels whose pre-compression is not uniform (FRP zones). Every
phase step then costs only a combination of pattern readings: **one factorisation per parameter
vector**, whatever the number of steps. A jack acts over its central length ``Ka × slot length``
with the pressure ``Km × p`` (``Km`` the jack efficiency, a parameter; ``Ka`` per slot).

Phase 3 (sliding of the block's top bed joint) runs elastic here, as a separate method
:meth:`FlatJack.phase3_check` comparing the top-joint stresses with the statics estimate
(Δp_V,crit = (L_H/h_V)(c + p_H tanφ)); the scenario ``flat_jack_shear_nl``
(:mod:`fe.scenarios.flat_jack_nl`) runs it nonlinearly, the joints sliding.

Load levels are step numbers 1, 2, … (``load_unit = "step"``); :attr:`FlatJack.steps` gives each
step's phase and jack pressures.

Simplifications: a 2D plane-stress slot is a through-thickness cut, whereas real
semicircular jacks load a circular segment, so 2D over-predicts the displacements (treat Km·Ka as
a nuisance, as the example study does); the jack's stiffness and welded edges are ignored (Ka < 1
removes the edges from the loaded length); collar joints and other wythes are ignored; the slot
faces never touch (the closure at the cut is ≈ 0.09 mm at σ0 = 0.3 MPa, far below a 3–10 mm
slot, so no contact is modelled).

Why one module of ~760 lines (a third documentation): one scenario with its presets, gauge
layouts, loading phases and slot geometry, which refer to each other by name; the closed forms it
is checked against are in :mod:`podkrig.analytical.flat_jack`.
"""

import dataclasses
import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from ..assembly import StiffnessPart, element_dofs
from ..constraints import constraint_transform
from ..display import Displayed
from ..elements.interface import IL4, IL6
from ..elements.quad import QUADS
from ..exceptions import MeshError, SpecError
from ..loads import edge_traction
from ..materials import D0, D1, plane_stress_coefficients
from ..mesh import BrickWallLayout
from ..mesh.ring import add_ring
from ..model import LinearModel
from ..response import Response
from ..sensors import DICGrid, Gauge, SlipGauge, sensor_from_dict, sensor_table
from .base import ParameterInfo, Scenario
from .masonry import MASONRY_PARAMETERS, wall_mesh

_DEFAULTS = {"E_b": 10000.0, "nu_b": 0.15, "kN_bj": 80.0, "kV_bj": 35.0, "r_hj": 0.6}  # §5.2

FLAT_JACK_PARAMETERS = tuple(
    dataclasses.replace(p, default=_DEFAULTS.get(p.name, p.default)) for p in MASONRY_PARAMETERS
) + (
    ParameterInfo("Km", 0.85, "-", 0.0, 1.5, "jack efficiency: effective / gauge pressure (calibration)", lower_open=True),
    ParameterInfo("sigma0", 0.30, "MPa", 0.0, 20.0, "in-situ vertical pre-compression (magnitude)"),
)

#: the orthotropic plane-stress matrix as Σ c_k D_k: coefficients (D11, D22, D12, D33)
RING_PARTS = {
    "ring_D11": np.diag([1.0, 0.0, 0.0]),
    "ring_D22": np.diag([0.0, 1.0, 0.0]),
    "ring_D12": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
    "ring_D33": np.diag([0.0, 0.0, 1.0]),
}


def ring_moduli(values, unit_height, unit_length):
    """Coefficients ``(D11, D22, D12, D33)`` (MPa) of the ring's homogenised orthotropic material
    (INFERRED, see ``docs/references.md`` "INFERRED choices"): ``1/E_y = 1/E_b + 1/(h kN)`` (series across bed joints),
    ``1/E_x = 1/E_b + 1/(l r kN)`` (a lower bound for running bond), ``1/G = 1/G_b + 1/(h kV)``,
    ``ν_xy = ν_b``, ``ν_yx = ν_xy E_y/E_x``; plane stress. The same moduli as
    :func:`podkrig.analytical.flat_jack.homogenised_moduli`."""
    Eb, nu = values["E_b"], values["nu_b"]
    Ey = 1.0 / (1.0 / Eb + 1.0 / (unit_height * values["kN_bj"]))
    Ex = 1.0 / (1.0 / Eb + 1.0 / (unit_length * values["r_hj"] * values["kN_bj"]))
    G = 1.0 / (2.0 * (1.0 + nu) / Eb + 1.0 / (unit_height * values["kV_bj"]))
    nu_yx = nu * Ey / Ex
    c = 1.0 / (1.0 - nu * nu_yx)
    return c * Ex, c * Ey, c * nu * Ey, G


# --- §5 geometry ---------------------------------------------------------------------------------

CHISARI_SLOTS = (
    {"name": "H", "orientation": "horizontal", "at": 780.0, "start": 845.0, "end": 1235.0, "Ka": 1.0},
    {"name": "V1", "orientation": "vertical", "at": 845.0, "start": 780.0, "end": 975.0, "Ka": 1.0},
    {"name": "V2", "orientation": "vertical", "at": 1235.0, "start": 780.0, "end": 975.0, "Ka": 1.0},
)


def _ramp(lo, hi, step):
    n = round((hi - lo) / step)
    return [round(lo + k * step, 10) for k in range(n + 1)]


CHISARI_SCHEDULE = (
    {"name": "0b", "steps": [{}]},
    {"name": "1", "steps": [{"H": p, "V1": 0.05, "V2": 0.05} for p in _ramp(0.1, 1.0, 0.1)]},
    {"name": "2", "steps": [{"V1": p, "V2": p} for p in _ramp(0.10, 0.50, 0.05)]},
    {"name": "3", "steps": [{"V1": p} for p in _ramp(0.6, 3.0, 0.1)]},
)

SINGLE_SLOTS = CHISARI_SLOTS[:1]
SINGLE_SCHEDULE = ({"name": "0b", "steps": [{}]}, {"name": "1", "steps": [{"H": p} for p in _ramp(0.05, 0.60, 0.05)]})
DOUBLE_SLOTS = (
    CHISARI_SLOTS[0],
    {"name": "H2", "orientation": "horizontal", "at": 1170.0, "start": 845.0, "end": 1235.0, "Ka": 1.0},
)
DOUBLE_SCHEDULE = ({"name": "0b", "steps": [{}]}, {"name": "1", "steps": [{"H": p, "H2": p} for p in _ramp(0.1, 1.0, 0.1)]})

# gauge layouts (mm), §5.5–5.7: anchors inside units, ≥ 10 mm from joints and slots
L6 = (
    Gauge("G1", (975, 682.5), (975, 877.5)),
    Gauge("G2", (1105, 682.5), (1105, 877.5)),
    Gauge("G3", (747.5, 877.5), (942.5, 877.5)),
    Gauge("G4", (1137.5, 877.5), (1332.5, 877.5)),
    SlipGauge("G5", (1000, 942.5), (1000, 1007.5)),  # slip: reads along +x
    Gauge("G6", (1365, 682.5), (1365, 877.5)),
)
L18_EXTRA = (
    Gauge("G7", (1040, 617.5), (1040, 877.5)),
    Gauge("G8", (715, 682.5), (715, 877.5)),
    Gauge("G9", (1105, 487.5), (1105, 682.5)),
    Gauge("G10", (1105, 942.5), (1105, 1137.5)),
    Gauge("G11", (747.5, 812.5), (942.5, 812.5)),
    Gauge("G12", (747.5, 942.5), (942.5, 942.5)),
    Gauge("G13", (1137.5, 812.5), (1332.5, 812.5)),
    Gauge("G14", (1137.5, 942.5), (1332.5, 942.5)),
    Gauge("G15", (877.5, 877.5), (1202.5, 877.5)),
    SlipGauge("G16", (880, 942.5), (880, 1007.5)),
    SlipGauge("G17", (1200, 942.5), (1200, 1007.5)),
    Gauge("G18", (877.5, 812.5), (1202.5, 1072.5)),
)
DIC = DICGrid("DIC", 642.5, 582.5, 642.5 + 20 * 39, 582.5 + 20 * 29, 40, 30)
STANDARD_SINGLE = (
    Gauge("S1", (975, 682.5), (975, 877.5)),
    Gauge("S2", (1040, 617.5), (1040, 877.5)),  # x = 1040 is a head joint in courses 11 and 13
    Gauge("S3", (1105, 682.5), (1105, 877.5)),
)
STANDARD_DOUBLE = (
    Gauge("D1", (975, 812.5), (975, 1137.5)),
    Gauge("D2", (1040, 877.5), (1040, 1137.5)),
    Gauge("D3", (1105, 812.5), (1105, 1137.5)),
    Gauge("DH", (942.5, 942.5), (1137.5, 942.5)),
)


def _layout(name):
    l6, l18 = L6, L6 + L18_EXTRA
    layouts = {"L6": l6, "L18": l18, "DIC": (DIC,), "L18+DIC": l18 + (DIC,), "L6+DIC": l6 + (DIC,),
               "standard-single": STANDARD_SINGLE, "standard-double": STANDARD_DOUBLE, "none": ()}
    return layouts[name]


LAYOUTS = ("L6", "L18", "DIC", "L6+DIC", "L18+DIC", "standard", "none")
PRESETS = {"chisari": (CHISARI_SLOTS, CHISARI_SCHEDULE), "single": (SINGLE_SLOTS, SINGLE_SCHEDULE),
           "double": (DOUBLE_SLOTS, DOUBLE_SCHEDULE)}


@dataclass(frozen=True)
class SlotGeometry:
    """A slot and its jack: ``orientation`` "horizontal" (in the bed joint ``y = at``) or
    "vertical" (``x = at``), extent ``[start, end]`` along it (mm), jack over the central
    ``Ka`` of its length."""

    name: str
    orientation: str
    at: float
    start: float
    end: float
    Ka: float = 1.0

    @property
    def length(self):
        return self.end - self.start

    @property
    def axis(self):
        """Coordinate index along the slot: 0 (x) for horizontal slots, 1 for vertical ones."""
        return 0 if self.orientation == "horizontal" else 1

    @property
    def jack_interval(self):
        """Loaded interval along the slot (mm): the central ``Ka`` of its length."""
        c, h = 0.5 * (self.start + self.end), 0.5 * self.Ka * self.length
        return c - h, c + h

    def endpoints(self):
        """The slot's end points ``((x, y), (x, y))`` in mm."""
        if self.axis == 0:
            return (self.start, self.at), (self.end, self.at)
        return (self.at, self.start), (self.at, self.end)


def _slot_from_dict(d, where):
    allowed = {"name", "orientation", "at", "start", "end", "Ka"}
    if not isinstance(d, dict) or set(d) - allowed or not {"name", "orientation", "at", "start", "end"} <= set(d):
        raise SpecError(f"{where}: a slot is a table with keys name, orientation, at, start, end[, Ka]; got {d!r}")
    s = SlotGeometry(str(d["name"]), d["orientation"], float(d["at"]), float(d["start"]), float(d["end"]), float(d.get("Ka", 1.0)))
    if s.orientation not in ("horizontal", "vertical"):
        raise SpecError(f"{where}: slot {s.name!r}: orientation must be 'horizontal' or 'vertical'; got {s.orientation!r}")
    if not s.end > s.start:
        raise SpecError(f"{where}: slot {s.name!r}: end ({s.end:g}) must exceed start ({s.start:g}) mm")
    if not 0 < s.Ka <= 1:
        raise SpecError(f"{where}: slot {s.name!r}: Ka must be in (0, 1]; got {s.Ka:g}")
    return s


@dataclass(frozen=True)
class Step:
    """One reading step: its phase and the gauge pressure of every jack (MPa)."""

    index: int
    phase: str
    pressures: dict

    def to_dict(self):
        return {"step": self.index, "phase": self.phase, "pressures_MPa": dict(self.pressures)}


@dataclass(frozen=True)
class FlatJackOptions:
    """Options of the flat-jack scenario (lengths mm, pressures MPa); see the module docstring.

    ``phases`` selects phases of the schedule by name (None = all); ``layout`` one of
    :data:`LAYOUTS` (``"standard"`` = the preset's standard gauges) and ``sensors`` adds gauges;
    ``frp`` stiffens the units at the ends of the vertical slots (x = at ± 130 mm, one course
    beyond each end) by a bonded fabric of in-plane stiffness ``frp_stiffness`` (N/mm, E_f × total
    fabric thickness over both faces; default one 0.17 mm CFRP ply of 230 GPa per face, INFERRED, ``docs/references.md``)
    smeared over the wall thickness. ``ring_width > 0`` surrounds the panel's sides and top with a
    homogenised elastic ring of that width (mm; 1000 is a good start), ``ring_layers``
    elements across, graded (see :mod:`fe.mesh.ring`), of the orthotropic material of the
    homogenised moduli: ``1/E_y = 1/E_b + 1/(h kN)``, ``1/E_x = 1/E_b + 1/(l r kN)``, ``1/G = 1/G_b + 1/(h kV)``,
    ``ν_xy = ν_b`` (INFERRED, ``docs/references.md``); σ0 then acts on the ring's top.
    """

    preset: str = "chisari"
    unit_length: float = 260.0
    unit_height: float = 65.0
    n_courses: int = 24
    units_per_course: float = 8.0
    thickness: float = 120.0
    bond: str = "running"
    nx: int = 2
    ny: int = 1
    element: str = "Q8"
    brick_interfaces: bool = False
    continuum: bool = False
    refine: tuple = (650.0, 1430.0, 585.0, 1170.0)
    slots: tuple | None = None
    schedule: tuple | None = None
    phases: tuple | None = None
    layout: str = "L18"
    dic_subset: float = 0.0
    sensors: dict | None = None
    release: str = "nominal"
    frp: bool = False
    frp_stiffness: float = 2 * 230000.0 * 0.17
    ring_width: float = 0.0
    ring_layers: int = 6

    def __post_init__(self):
        object.__setattr__(self, "sensors", sensor_table(self.sensors))  # [[sensors]] arrays become a table
        if self.preset not in PRESETS:
            raise ValueError(f"preset must be one of {sorted(PRESETS)}; got {self.preset!r}")
        if self.layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}; got {self.layout!r}")
        if self.release not in ("nominal", "exact"):
            raise ValueError(f"release must be 'nominal' or 'exact'; got {self.release!r}")
        if not (math.isfinite(self.dic_subset) and self.dic_subset >= 0.0):
            raise ValueError(f"dic_subset must be a subset size >= 0 mm; got {self.dic_subset}")
        if not self.thickness > 0:
            raise ValueError(f"thickness must be > 0 mm; got {self.thickness}")
        if not self.frp_stiffness >= 0:
            raise ValueError(f"frp_stiffness must be >= 0 N/mm; got {self.frp_stiffness}")
        if not self.ring_width >= 0 or self.ring_layers < 1:
            raise ValueError(f"ring_width must be >= 0 mm and ring_layers >= 1; got {self.ring_width}, {self.ring_layers}")
        if self.layout.startswith(("L6", "L18", "DIC")) and self.preset != "chisari" and self.slots is None:
            raise ValueError(f"layout {self.layout!r} belongs to the chisari preset; use layout = 'standard' for {self.preset!r}")


class FlatJack(Scenario):
    """Flat-jack tests on a pre-compressed running-bond panel; see the module docstring."""

    name = "flat_jack"
    summary = ("In-situ flat-jack tests in a running-bond panel: single, double, and horizontal "
               "+ vertical jacks.")
    Options = FlatJackOptions
    PARAMETERS = FLAT_JACK_PARAMETERS
    load_unit = "step"
    load_response = "discrete"  # steps of a test sequence, not a continuous load

    def _build(self):
        o = self.options
        preset_slots, preset_schedule = PRESETS[o.preset]
        raw = preset_slots if o.slots is None else o.slots
        self.slots = tuple(_slot_from_dict(dict(d), f"{self.name}: slots[{i}]") for i, d in enumerate(raw))
        names = [s.name for s in self.slots]
        if len(set(names)) != len(names):
            raise SpecError(f"{self.name}: slot names must be unique; got {names}")
        self.steps = self._steps(preset_schedule if o.schedule is None else o.schedule)
        self.mesh = mesh = self._mesh()
        self.slot_interfaces = self._find_slot_interfaces(mesh)
        cut = np.zeros(len(mesh.interfaces), bool)
        for idx in self.slot_interfaces.values():
            cut[idx] = True
        self._cut = cut
        ties = []
        self._ring_quads = np.zeros(len(mesh.quads), bool)
        if o.ring_width > 0:
            self.mesh, self._ring_quads, ties = add_ring(mesh, o.ring_width, o.ring_layers)
            mesh = self.mesh
        self._frp_quads = self._frp_quads_mask(mesh)
        bottom = mesh.node_sets["bottom"]
        # u_x = 0 at the bottom node(s) closest to the middle: both faces of a head joint there,
        # so that the support is symmetric about the panel's centre line
        x = mesh.nodes[bottom, 0]
        dist = np.abs(x - 0.5 * (mesh.nodes[:, 0].min() + mesh.nodes[:, 0].max()))
        pin = bottom[dist <= dist.min() + 1e-9]
        fixed = np.concatenate([2 * bottom + 1, 2 * pin])
        # ring–wall ties in x and y; a y tie on the supported bottom line is already fixed
        self.tie_groups = [2 * g for g in ties] + [2 * g + 1 for g in ties if mesh.nodes[g[0], 1] > 1e-9]
        self.supported_nodes = pin  # held in x (and y); the other bottom nodes are held in y only
        self.sensors = self._sensors()
        patterns = np.column_stack([self._release_pattern()] + [self._jack_pattern(s) for s in self.slots]
                                   + [self._top_pattern()])
        transform = constraint_transform(mesh.n_dofs, fixed, ties=self.tie_groups)
        self.model = LinearModel(mesh, self._parts(mesh), transform, patterns, self.sensors, solver=self._solver_name)
        self._n_jack_patterns = 1 + len(self.slots)  # release + jacks; the last column is σ0 on the top
        # the step multipliers of the patterns at the default σ0 and Km, for code that combines the
        # model's pattern readings itself (they depend on σ0 and Km: use step_coefficients(values))
        self.load_coefficients = np.hstack([self.step_coefficients(self.resolve()), np.zeros((len(self.steps), 1))])  # at the defaults

    # --- geometry -------------------------------------------------------------------------------

    def _steps(self, schedule):
        o = self.options
        if not isinstance(schedule, (list, tuple)) or not schedule:
            raise SpecError(f"{self.name}: schedule must be a non-empty list of phases {{name, steps}}")
        known = {s.name for s in self.slots}
        wanted = None if o.phases is None else [str(p) for p in o.phases]
        all_names = [str(ph.get("name")) for ph in schedule if isinstance(ph, dict)]
        if wanted is not None:
            missing = sorted(set(wanted) - set(all_names))
            if missing:
                raise SpecError(f"{self.name}: phases {missing} are not in the schedule; phases: {all_names}")
        pressure = {name: 0.0 for name in known}
        steps = []
        for i, ph in enumerate(schedule):
            if not isinstance(ph, dict) or set(ph) != {"name", "steps"} or not ph["steps"]:
                raise SpecError(f"{self.name}: schedule[{i}] must be a table {{name, steps}} with at least one step")
            for j, st in enumerate(ph["steps"]):
                bad = sorted(set(st) - known)
                if bad:
                    raise SpecError(f"{self.name}: schedule[{i}] ({ph['name']}), step {j + 1}: unknown jack(s) {bad}; jacks: {sorted(known)}")
                for k, v in st.items():
                    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                        raise SpecError(f"{self.name}: schedule[{i}] ({ph['name']}), step {j + 1}: pressure of {k!r} must be a number (MPa); got {v!r}")
                    pressure[k] = float(v)
                if wanted is None or str(ph["name"]) in wanted:
                    steps.append(Step(len(steps) + 1, str(ph["name"]), dict(pressure)))
        if not steps:
            raise SpecError(f"{self.name}: no step selected")
        return tuple(steps)

    def _mesh(self):
        o = self.options
        H, W = o.unit_height, o.units_per_course * o.unit_length
        x_lines, cuts = [], []
        for s in self.slots:
            if s.orientation == "horizontal":
                k = s.at / H
                if abs(k - round(k)) > 1e-9 or not 0 < round(k) < o.n_courses:
                    raise SpecError(f"{self.name}: horizontal slot {s.name!r} must lie in a bed joint: at = {s.at:g} mm is not an inner multiple of {H:g} mm")
                if not 0 < s.start < s.end < W:
                    raise SpecError(f"{self.name}: slot {s.name!r} must end inside the panel (0, {W:g}) mm")
                x_lines += [s.start, s.end, *s.jack_interval]
            else:
                if not 0 < s.at < W:
                    raise SpecError(f"{self.name}: vertical slot {s.name!r} at x = {s.at:g} mm is outside the panel")
                cuts.append((s.at, s.start, s.end))
        fields = {f.name: getattr(o, f.name) for f in dataclasses.fields(BrickWallLayout) if hasattr(o, f.name)}
        layout = SimpleNamespace(**fields, x_lines=tuple(sorted(set(x_lines))), cuts=tuple(cuts), continuum=o.continuum)
        try:
            mesh = wall_mesh(layout)
        except MeshError as e:
            raise SpecError(f"{self.name}: {e}") from e
        return mesh

    def _find_slot_interfaces(self, mesh):
        """Interface elements along each slot (removed by the cut) → ``{slot: indices}``."""
        half = mesh.interfaces.shape[1] // 2
        xy = mesh.nodes[mesh.interfaces[:, :half]]  # face A nodes
        out = {}
        for s in self.slots:
            ax, other = s.axis, 1 - s.axis
            on_line = np.all(np.abs(xy[:, :, other] - s.at) < 1e-6, axis=1)
            lo, hi = xy[:, :, ax].min(axis=1), xy[:, :, ax].max(axis=1)
            inside = on_line & (lo >= s.start - 1e-6) & (hi <= s.end + 1e-6)
            idx = np.flatnonzero(inside)
            covered = np.sum(hi[idx] - lo[idx])
            if abs(covered - s.length) > 1e-6 * s.length:
                raise SpecError(
                    f"{self.name}: slot {s.name!r} covers {covered:g} of its {s.length:g} mm of joint/cut "
                    "interfaces; a horizontal slot must lie in a bed joint, a vertical one span whole courses"
                )
            out[s.name] = idx
        return out

    def _frp_quads_mask(self, mesh):
        o = self.options
        mask = np.zeros(len(mesh.quads), bool)
        if not o.frp:
            return mask
        centre = mesh.nodes[mesh.quads[:, :4]].mean(axis=1)
        for s in self.slots:
            if s.orientation == "vertical":
                mask |= ((np.abs(centre[:, 0] - s.at) < o.unit_length / 2)
                         & (centre[:, 1] > s.start - o.unit_height) & (centre[:, 1] < s.end + o.unit_height))
        return mask

    def frp_zones(self):
        """FRP-stiffened rectangles ``(x0, x1, y0, y1)`` (mm), empty without ``frp``."""
        o = self.options
        if not o.frp:
            return []
        return [(s.at - o.unit_length / 2, s.at + o.unit_length / 2, s.start - o.unit_height, s.end + o.unit_height)
                for s in self.slots if s.orientation == "vertical"]

    def _sensors(self):
        o = self.options
        name = o.layout
        if name == "standard":
            name = {"single": "standard-single", "double": "standard-double"}.get(o.preset)
            if name is None:
                raise SpecError(f"{self.name}: preset {o.preset!r} has no standard layout; use L6, L18 or DIC")
        sensors = _layout(name)
        if o.dic_subset > 0.0:  # the DIC grid reads subset means (§5.7 "optional realism")
            sensors = tuple(dataclasses.replace(s, subset=o.dic_subset) if s is DIC else s for s in sensors)
        if o.sensors:
            sensors = sensors + tuple(sensor_from_dict(k, v) for k, v in o.sensors.items())
        if not sensors:
            raise SpecError(f"{self.name}: no sensors (layout 'none' and no 'sensors')")
        return sensors

    # --- stiffness and loads ----------------------------------------------------------------------

    def _parts(self, mesh):
        """Stiffness parts: units (D0, D1), FRP-zone units (D0, D1), then for each joint family
        kept and cut (slot) normal/shear parts."""
        o = self.options
        quad = QUADS[mesh.element]
        parts = []
        wall = ~self._ring_quads
        for prefix, mask in (("units", wall & ~self._frp_quads), ("frp_units", self._frp_quads)):
            conn = mesh.quads[mask]
            coords, qdofs = mesh.nodes[conn], element_dofs(conn)
            parts.append(StiffnessPart(f"{prefix}_D0", qdofs, quad.stiffness(coords, D0, o.thickness)))
            parts.append(StiffnessPart(f"{prefix}_D1", qdofs, quad.stiffness(coords, D1, o.thickness)))
        conn = mesh.quads[self._ring_quads]
        coords, qdofs = mesh.nodes[conn], element_dofs(conn)
        for name, D in RING_PARTS.items():
            parts.append(StiffnessPart(name, qdofs, quad.stiffness(coords, D, o.thickness)))
        iface = IL6 if mesh.element == "Q8" else IL4
        for state, mask in (("", ~self._cut), ("slot_", self._cut)):
            for kind in ("bed", "head", "brick"):
                conn = mesh.interfaces[mesh.interfaces_of_kind(kind) & mask]
                xy, idofs = mesh.nodes[conn], element_dofs(conn)
                parts.append(StiffnessPart(f"{state}{kind}_normal", idofs, iface.stiffness(xy, 0.0, 1.0, o.thickness)))
                parts.append(StiffnessPart(f"{state}{kind}_shear", idofs, iface.stiffness(xy, 1.0, 0.0, o.thickness)))
        return parts

    def theta(self, values, cut=True):
        """Coefficients of the stiffness parts, ``(20,)``: units, FRP units, ring (see
        :func:`ring_moduli`), kept joints, slot joints. After the cut (default) the slot
        interfaces carry nothing; ``cut=False`` gives the pre-cut panel."""
        c0, c1 = plane_stress_coefficients(values["E_b"], values["nu_b"])
        f0, f1 = plane_stress_coefficients(values["E_b"] + self.options.frp_stiffness / self.options.thickness, values["nu_b"])
        ring = ring_moduli(values, self.options.unit_height, self.options.unit_length)
        r = values["r_hj"]
        joints = [values["kN_bj"], values["kV_bj"], r * values["kN_bj"], r * values["kV_bj"], values["kN_bb"], values["kV_bb"]]
        return np.array([c0, c1, f0, f1, *ring] + joints + ([0.0] * 6 if cut else joints))

    def _face_loads(self, slot, traction_b, interval):
        """Nodal forces (N) of a uniform traction ``traction_b`` (MPa, vector) on face B of the
        slot and its opposite on face A, over ``interval`` along the slot (exact 3-point Gauss on
        the covered part of each element)."""
        mesh, t = self.mesh, self.options.thickness
        conn = mesh.interfaces[self.slot_interfaces[slot.name]]
        half = conn.shape[1] // 2
        iface = IL6 if half == 3 else IL4
        a, b = mesh.nodes[conn[:, 0], slot.axis], mesh.nodes[conn[:, 1], slot.axis]
        lo, hi = np.maximum(np.minimum(a, b), interval[0]), np.minimum(np.maximum(a, b), interval[1])
        g, w = np.polynomial.legendre.leggauss(3)
        f = np.zeros(self.mesh.n_dofs)
        for e in np.flatnonzero(hi > lo + 1e-12):
            s = 0.5 * (lo[e] + hi[e]) + 0.5 * (hi[e] - lo[e]) * g  # coordinate along the slot
            xi = (2 * s - (a[e] + b[e])) / (b[e] - a[e])
            nodal = iface.shape(xi).T @ w * 0.5 * (hi[e] - lo[e]) * t  # ∫ N ds · t, mm²
            for j in range(2):
                np.add.at(f, 2 * conn[e, half:] + j, nodal * traction_b[j])
                np.add.at(f, 2 * conn[e, :half] + j, -nodal * traction_b[j])
        return f

    def _normal(self, slot):
        """Unit normal of the slot's interfaces, from face A to face B."""
        conn = self.mesh.interfaces[self.slot_interfaces[slot.name][0]]
        d = self.mesh.nodes[conn[1]] - self.mesh.nodes[conn[0]]
        n = np.array([-d[1], d[0]])
        return n / np.linalg.norm(n)

    def _jack_pattern(self, slot):
        """Unit jack pressure (1 MPa) pushing the faces apart over the jack length, N."""
        return self._face_loads(slot, self._normal(slot), slot.jack_interval)

    def jack_pattern(self, slot, interval=None):
        """Nodal forces (N) of a unit jack pressure (1 MPa) in slot ``slot`` (name) pushing the faces
        apart over ``interval`` along the slot (mm; default the jack length ``Ka × slot length``):
        the scenario's own jack pattern, or a part of it (e.g. where the jack has lost contact)."""
        s = next((sl for sl in self.slots if sl.name == slot), None)
        if s is None:
            raise KeyError(f"{self.name}: no slot {slot!r}; slots are {[sl.name for sl in self.slots]}")
        lo, hi = s.jack_interval if interval is None else (float(interval[0]), float(interval[1]))
        if not s.start - 1e-9 <= lo <= hi <= s.end + 1e-9:
            raise ValueError(f"{self.name}: interval ({lo:g}, {hi:g}) mm must lie within slot {slot!r} "
                             f"[{s.start:g}, {s.end:g}] mm")
        return self._face_loads(s, self._normal(s), (lo, hi))

    def _release_pattern(self):
        """Release of the nominal in-situ stress (σx, σy, τ) = (0, −1, 0) MPa on every slot's
        faces: face B receives σ·n (and face A −σ·n), the traction the removed joint carried, N."""
        sigma = np.array([[0.0, 0.0], [0.0, -1.0]])
        f = np.zeros(self.mesh.n_dofs)
        for s in self.slots:
            f += self._face_loads(s, sigma @ self._normal(s), (s.start, s.end))
        return f

    def _top_pattern(self):
        """Unit pre-compression (1 MPa) on the top edge, N."""
        return edge_traction(self.mesh, self.mesh.edge_sets["top"], (0.0, -1.0), self.options.thickness)

    # --- running ------------------------------------------------------------------------------------

    @property
    def load_levels(self):
        """Step numbers 1 … n_steps (see :attr:`steps`)."""
        return np.arange(1, len(self.steps) + 1, dtype=float)

    def step_pressures(self):
        """Gauge pressures per step and jack, ``(n_steps, n_slots)`` MPa."""
        return np.array([[st.pressures[s.name] for s in self.slots] for st in self.steps])

    def step_coefficients(self, values):
        """Multipliers of the release and jack patterns at every step, ``(n_steps, 1 + n_slots)``:
        σ0 for the release (every step is after the cut), ``Km × p`` for each jack."""
        n = len(self.steps)
        return np.column_stack([np.full(n, values["sigma0"]), values["Km"] * self.step_pressures()])

    def joint_part_elements(self, kind):
        """The kept (not cut) interfaces of ``kind``: the slot's own are in the ``slot_`` parts."""
        return np.flatnonzero(self.mesh.interfaces_of_kind(kind) & ~self._cut)

    def load_coefficients_at(self, values):
        """The step multipliers of every load pattern for ``values`` (σ0 on the release, Km × p on
        each jack, 0 on the pre-compression of the top), ``(n_steps, n_patterns)``; see
        :meth:`fe.scenarios.base.Scenario.load_coefficients_at`.

        Raises
        ------
        NotImplementedError
            With ``release = "exact"``: the release pattern then comes from a pre-cut solve, not
            from a fixed column of ``model.rhs``.
        """
        if self.options.release == "exact":
            raise NotImplementedError(
                "flat_jack with release = 'exact': the release load comes from a pre-cut solve, not a fixed "
                "load pattern; use release = 'nominal' (the default) for analyses on the load patterns")
        return np.hstack([self.step_coefficients(values), np.zeros((len(self.steps), 1))])

    def pattern_solution(self, values):
        """Reduced displacements of the patterns on the cut panel ``(n_reduced, 1 + n_slots)``:
        the release for σ0 = 1 MPa (nominal, or exact from a pre-cut solve) and each jack at 1 MPa."""
        m, k = self.model, self._n_jack_patterns
        rhs = m.rhs[:, :k]
        if self.options.release == "exact":
            q0 = m.solve(self.theta(values, cut=False), rhs=m.rhs[:, k:])  # pre-cut, σ0 = 1 on top
            slot_only = self.theta(values, cut=False) - self.theta(values)
            K_slot = m.stiffness.matrix(slot_only)
            rhs = np.column_stack([K_slot @ q0[:, 0], rhs[:, 1:]])
        return m.solve(self.theta(values), rhs=rhs)

    def run(self, params=None, *, field=False):
        """Readings at every step, ``(n_steps, n_channels)`` mm, relative to the pre-cut state.

        One factorisation of the cut panel (two with ``release = "exact"``); the steps are
        combinations of the pattern responses. ``field``: nodal displacements per step since the
        pre-cut state.
        """
        values = self.resolve(params)
        q = self.pattern_solution(values)
        C = self.step_coefficients(values)
        readings = C @ self.model.readings(q)
        u = np.einsum("sp,pnc->snc", C, self.model.displacements(q)) if field else None
        return Response(readings, self.sensor_names, self.load_levels, self.load_unit, u)

    def precut_field(self, params=None):
        """Nodal displacements ``(n_nodes, 2)`` mm of phase 0a (σ0 on the uncut panel)."""
        values = self.resolve(params)
        m = self.model
        q0 = m.solve(self.theta(values, cut=False), rhs=m.rhs[:, -1:])
        return values["sigma0"] * m.displacements(q0)[0]

    # --- phase 3 (elastic; sliding needs the nonlinear interfaces) -----------------------------------

    def phase3_check(self, params=None, c=0.25, tan_phi=0.70, block_joint=None):
        """Elastic phase 3 against the statics estimate of the jack-loaded block (see :class:`Phase3Check`).

        Parameters
        ----------
        params : dict, optional
            Parameter values.
        c, tan_phi : float
            Cohesion (MPa) and friction coefficient of the block's top bed joint (the estimate only).
        block_joint : (y, x0, x1), optional
            The top bed joint of the block (mm); by default y = top of the vertical slots and the
            extent of the horizontal slot.
        """
        values = self.resolve(params)
        H = next((s for s in self.slots if s.orientation == "horizontal"), None)
        V = [s for s in self.slots if s.orientation == "vertical"]
        if H is None or len(V) != 2:
            raise SpecError(f"{self.name}: phase 3 needs one horizontal and two vertical slots (the chisari preset)")
        V1, V2 = sorted(V, key=lambda s: s.at)
        y, x0, x1 = block_joint or (V1.end, H.start, H.end)
        mesh = self.mesh
        half = mesh.interfaces.shape[1] // 2
        xy = mesh.nodes[mesh.interfaces[:, :half]]
        joint = np.flatnonzero(np.all(np.abs(xy[:, :, 1] - y) < 1e-6, axis=1)
                               & (xy[:, :, 0].min(axis=1) >= x0 - 1e-6) & (xy[:, :, 0].max(axis=1) <= x1 + 1e-6)
                               & mesh.interfaces_of_kind("bed"))
        q = self.pattern_solution(values)
        C = self.step_coefficients(values)
        u = np.einsum("sp,pnc->snc", C, self.model.displacements(q)).reshape(len(self.steps), -1)
        iface = IL6 if half == 3 else IL4
        Bd, ds = iface.relative_displacement_operator(mesh.nodes[mesh.interfaces[joint]])
        dofs = element_dofs(mesh.interfaces[joint])
        k = np.array([values["kV_bj"], values["kN_bj"]])
        t = np.einsum("epij,sej->sepi", Bd, u[:, dofs]) * k  # (steps, el, points, (t_s, t_n)) MPa
        mean = np.einsum("sepi,ep->si", t, ds) / ds.sum()
        # before the cut the joint carries the uniform compression σ0 and no shear (phase 0a)
        compression = values["sigma0"] - t[..., 1]
        p = self.step_pressures()
        iH, i1, i2 = (self.slots.index(s) for s in (H, V1, V2))
        dpv = p[:, i1] - p[:, i2]
        Km, L_H, h_V = values["Km"], x1 - x0, V1.length * V1.Ka
        sigma_top = Km * p[:, iH] * H.Ka * H.length / L_H
        return Phase3Check(
            steps=np.arange(1, len(self.steps) + 1), phase=np.array([s.phase for s in self.steps]),
            p_H=p[:, iH], delta_p_V=dpv, mean_shear=np.abs(mean[:, 0]), mean_normal=values["sigma0"] - mean[:, 1],
            statics_shear=np.abs(Km * dpv * h_V / L_H), statics_normal=sigma_top,
            peak_shear=np.abs(t[..., 0]).max(axis=(1, 2)),
            local_slip=(np.abs(t[..., 0]) > c + compression * tan_phi).any(axis=(1, 2)),
            delta_p_V_crit=L_H / h_V * (c + sigma_top * tan_phi) / Km,
        )



@dataclass(frozen=True, eq=False, repr=False)
class Phase3Check(Displayed):
    """Elastic phase-3 state of the block's top bed joint against the statics of the jack-loaded block.

    Per step (arrays ``(n_steps,)``): jack pressures ``p_H`` and ``delta_p_V = p_V1 − p_V2``
    (gauge, MPa); the FE mean shear stress and mean normal compression on the joint (MPa); the
    statics values ``Km Δp_V h_V / L_H`` and ``Km Ka p_H``
    (MPa; the statics are exact for the *mean* stresses by equilibrium of the block, so the FE
    must match them); the peak elastic shear (corner concentration); whether Mohr–Coulomb
    (``c``, ``tanφ``, with the joint compression σ0 + change) is exceeded somewhere elastically
    (local slip starts below the average estimate); and the statics estimate of the critical
    gauge ``Δp_V`` for sliding at each step's ``p_H``: ``(L_H/h_V)(c + Km p_H tanφ)/Km``.
    """

    steps: np.ndarray
    phase: np.ndarray
    p_H: np.ndarray
    delta_p_V: np.ndarray
    mean_shear: np.ndarray
    mean_normal: np.ndarray
    statics_shear: np.ndarray
    statics_normal: np.ndarray
    peak_shear: np.ndarray
    local_slip: np.ndarray
    delta_p_V_crit: np.ndarray

    def to_dict(self):
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in dataclasses.asdict(self).items()}


def homogeneous_slot_spec(size_factor, nx=4, ny=2, slot_length=260.0, spacing=None, gauge_offsets=(32.5, 97.5, 162.5, 292.5), x0=0.0):
    """Spec of a verification panel (the homogeneous verification cases of ``scripts/verify_flat_jack.py``): stiff joints (kN = kV = 10⁷
    N/mm³, the homogeneous limit), E_b = 4000 MPa, ν = 0.2, Km = 1, σ0 = 0, one horizontal slot of
    ``slot_length`` (mm) at the panel centre, or two (``spacing`` mm apart, a multiple of the
    course height, centred), in a square-ish panel ``size_factor`` × the slot length wide and high,
    refined around the slots; one step with 1 MPa in every jack.

    Gauges ``P{k}`` are vertical pin pairs at ``x = centre + x0 + 1`` mm (1 mm off the head-joint
    line through the centre) and heights ``±gauge_offsets[k]`` about the slot (single slot) or
    about the mid-line between the slots (two slots), mm.
    """
    H, L = 65.0, 260.0
    units = float(np.ceil(size_factor * slot_length / L))
    courses = int(np.ceil(size_factor * slot_length / H))
    courses += courses % 2
    xc, yc = round(units * L / 2 / 130.0) * 130.0, (courses // 2) * H
    a = slot_length / 2
    if spacing is None:
        slots = [{"name": "H", "orientation": "horizontal", "at": yc, "start": xc - a, "end": xc + a}]
        half = 2 * H
    else:
        s = spacing / 2
        slots = [{"name": n, "orientation": "horizontal", "at": yc + d, "start": xc - a, "end": xc + a}
                 for n, d in (("H", -s), ("H2", s))]
        half = s + 2 * H
    sensors = {f"P{k}": {"kind": "gauge", "p1": [xc + x0 + 1.0, yc - y], "p2": [xc + x0 + 1.0, yc + y]}
               for k, y in enumerate(gauge_offsets)}
    return {
        "scenario": "flat_jack", "units_per_course": units, "n_courses": courses, "nx": nx, "ny": ny,
        "refine": [xc - 2 * a, xc + 2 * a, yc - half - 2 * H, yc + half + 2 * H], "slots": slots,
        "schedule": [{"name": "1", "steps": [{sl["name"]: 1.0 for sl in slots}]}], "layout": "none",
        "sensors": sensors,
        "parameters": {"E_b": 4000.0, "nu_b": 0.2, "kN_bj": 1e7, "kV_bj": 1e7, "r_hj": 1.0, "Km": 1.0, "sigma0": 0.0},
    }
