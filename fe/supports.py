"""Supports: rigid shoes bonded over whole element edges, or distributed springs over exactly a
length; and a scenario's supports made compliant.

:func:`shoe_supports` builds the supports of a test from :class:`fe.boundary.Patch` es (e.g. the
diagonal compression test's two shoes, each over ``support_length`` from the bottom-left corner):

- ``"rigid"``: a rigid shoe bonded to the wall over the patch holds the nodes of the face edges
  lying inside it (:func:`fe.boundary.contact_nodes`) — only nodes of the units touching the face,
  never the duplicated node of the next unit across a joint (which would be a point constraint
  whose effect grows without bound under mesh refinement). A patch end off the element edge ends
  is snapped to the nearest one, and the length used is reported (``SupportModel.lengths_used``,
  a logged warning).
- ``"springs"``: distributed springs of stiffness ``k`` (N/mm³, the same normal and tangential,
  like an interface to a rigid base), consistent matrices integrated over exactly the patch,
  partial edges included (:func:`fe.boundary.patch_spring_matrices`): the length is honoured
  exactly at any mesh.

Compliant supports of any scenario:

A real support (a steel shoe bedded in mortar or gypsum, a neoprene pad, a test-rig foundation)
is not rigid. :func:`spring_supported_model` rebuilds a scenario's linear model with the supported
nodes free and tied to the ground by distributed springs of stiffness ``k_s`` (N/mm³, the same
in x and y, like an interface to a rigid base), lumped to the nodes by their tributary area of the
supported boundary (a supported node on no supported edge, such as the node of the next unit
where a support ends, stays fixed). The springs are one more affine stiffness part, so a new ``k_s`` costs one
factorisation; ``k_s → ∞`` recovers the rigid supports.
"""

import logging
from dataclasses import dataclass

import numpy as np

from .assembly import StiffnessPart
from .boundary import contact_nodes, patch_spring_matrices, snap_patch
from .constraints import constraint_transform
from .model import LinearModel

logger = logging.getLogger(__name__)

#: the support models of :func:`shoe_supports`
SUPPORT_MODELS = ("rigid", "springs")


@dataclass(frozen=True)
class SupportModel:
    """Supports built by :func:`shoe_supports`.

    Attributes
    ----------
    kind : {"rigid", "springs"}
    patches : tuple of fe.boundary.Patch
        The contact patches used (after snapping, for ``"rigid"``).
    lengths_used : dict of str to float
        Face → contact length used, mm.
    fixed_nodes : ndarray of int
        Nodes held in x and y (``"rigid"``; empty for ``"springs"``).
    springs : fe.assembly.StiffnessPart or None
        ``"support_springs"`` for a unit stiffness 1 N/mm³ (``"springs"``).
    """

    kind: str
    patches: tuple
    lengths_used: dict
    fixed_nodes: np.ndarray
    springs: StiffnessPart | None

    @property
    def fixed_dofs(self):
        return np.concatenate([2 * self.fixed_nodes, 2 * self.fixed_nodes + 1])


def spring_part(mesh, patches, thickness, name="support_springs"):
    """Consistent distributed springs over exactly the patches, one :class:`StiffnessPart` for a
    unit stiffness 1 N/mm³ (normal and tangential)."""
    blocks = [patch_spring_matrices(mesh, p, thickness) for p in patches]
    return StiffnessPart(name, np.concatenate([d for d, _ in blocks]), np.concatenate([m for _, m in blocks]))


def shoe_supports(mesh, patches, thickness, kind="rigid", anchors=None, owner="supports"):
    """Supports over ``patches`` (:class:`fe.boundary.Patch`); see the module docstring.

    Parameters
    ----------
    anchors : sequence of {0, 1}, optional
        For ``"rigid"``: which end of each patch is its fixed end (the corner the shoe sits in;
        default 0, the lower end); the other end is snapped to the nearest element edge end.
    owner : str
        Named in the warning about a snapped length.
    """
    if kind not in SUPPORT_MODELS:
        raise ValueError(f"support must be one of {SUPPORT_MODELS}; got {kind!r}")
    patches = tuple(patches)
    if kind == "springs":
        return SupportModel(kind, patches, {p.face: p.length for p in patches}, np.zeros(0, np.intp),
                            spring_part(mesh, patches, thickness))
    anchors = anchors or (0,) * len(patches)
    used = tuple(snap_patch(mesh, p, a) for p, a in zip(patches, anchors))
    for p, u in zip(patches, used):
        if u != p:
            logger.warning("%s: the rigid support on face %r ends off the element edges: its length %.6g mm is "
                           "snapped to %.6g mm (choose nx, ny so that an element edge ends there, or springs, where the "
                           "scenario offers support = \"springs\", for the exact length)",
                           owner, p.face, p.length, u.length)
    return SupportModel(kind, used, {u.face: u.length for u in used}, contact_nodes(mesh, used), None)


def support_areas(mesh, supported_nodes, thickness):
    """Tributary area of each supported node on the supported boundary, ``(n_supported,)`` mm².

    Boundary edges whose nodes are all supported count, with the consistent weights of a
    uniform traction (1/6, 1/6, 2/3 of the edge area on quadratic edges, 1/2, 1/2 on linear ones).
    """
    supported_nodes = np.asarray(supported_nodes)
    area = np.zeros(mesh.n_nodes)
    is_supported = np.zeros(mesh.n_nodes, bool)
    is_supported[supported_nodes] = True
    seen = set()
    for edges in mesh.edge_sets.values():
        for e in edges:
            key = tuple(sorted(e.tolist()))
            if key in seen or not is_supported[e].all():
                continue
            seen.add(key)
            length = np.linalg.norm(mesh.nodes[e[1]] - mesh.nodes[e[0]])
            weights = (1 / 6, 1 / 6, 2 / 3) if len(e) == 3 else (0.5, 0.5)
            area[e] += length * thickness * np.asarray(weights)
    return area[supported_nodes]


def spring_supported_model(scenario):
    """The scenario's model with its supports on springs.

    A scenario with contact patches (``scenario.support_model``, a :class:`SupportModel`) gets
    consistent springs over exactly its patches; any other, springs lumped to its
    ``supported_nodes`` by :func:`support_areas`.

    Returns
    -------
    LinearModel
        Parts: the scenario's parts, then ``support_springs`` (coefficient ``k_s`` in N/mm³); use
        ``np.append(scenario.theta(values), k_s)``. Same sensors and load patterns.
    """
    model, mesh = scenario.model, scenario.mesh
    support = getattr(scenario, "support_model", None)
    if support is not None:
        if support.kind != "rigid":
            raise ValueError(f"{scenario.name}: the supports are springs already (option support_stiffness)")
        springs = spring_part(mesh, support.patches, scenario.options.thickness)
        transform = constraint_transform(mesh.n_dofs, (), ties=scenario.tie_groups)
        return LinearModel(mesh, model.parts + (springs,), transform, model.load_patterns, model.sensors,
                           solver=scenario._solver_name)
    nodes = np.asarray(scenario.supported_nodes)
    area = support_areas(mesh, nodes, scenario.options.thickness)
    if not np.any(area > 0):
        raise ValueError(f"{scenario.name}: no supported boundary edge to put springs on")
    on_springs, still_fixed = nodes[area > 0], nodes[area == 0]  # e.g. a node where the support ends
    area = area[area > 0]
    dofs = np.concatenate([2 * on_springs, 2 * on_springs + 1])[:, None]
    springs = StiffnessPart("support_springs", dofs, np.concatenate([area, area])[:, None, None])
    fixed = np.concatenate([2 * still_fixed, 2 * still_fixed + 1])
    transform = constraint_transform(mesh.n_dofs, fixed, ties=scenario.tie_groups)
    return LinearModel(mesh, model.parts + (springs,), transform, model.load_patterns, model.sensors,
                       solver=scenario._solver_name)
