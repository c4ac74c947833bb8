"""Compliant supports: the supported nodes of a scenario on elastic springs instead of held fixed.

A real support (a steel shoe bedded in mortar or gypsum, a neoprene pad, a test-rig foundation)
is not rigid. :func:`spring_supported_model` rebuilds a scenario's linear model with the supported
nodes free and tied to the ground by distributed springs of stiffness ``k_s`` (N/mm³, the same
in x and y, like an interface to a rigid base), lumped to the nodes by their tributary area of the
supported boundary (a supported node on no supported edge, such as the node of the next unit
where a support ends, stays fixed). The springs are one more affine stiffness part, so a new ``k_s`` costs one
factorisation; ``k_s → ∞`` recovers the rigid supports.
"""

import numpy as np

from .assembly import StiffnessPart
from .constraints import constraint_transform
from .model import LinearModel


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

    Returns
    -------
    LinearModel
        Parts: the scenario's parts, then ``support_springs`` (coefficient ``k_s`` in N/mm³); use
        ``np.append(scenario.theta(values), k_s)``. Same sensors and load patterns.
    """
    model, mesh = scenario.model, scenario.mesh
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
