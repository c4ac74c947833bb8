"""The :class:`Mesh` value object: nodes, continuum quads, interfaces and named sets.

Array conventions (one row per entity, as in the rest of podkrig): ``nodes`` ``(n_nodes, 2)``
in mm; ``quads`` ``(n_quads, 4 or 8)``; ``interfaces`` ``(n_interfaces, 4 or 6)`` with face A
then face B (see :mod:`fe.elements.interface`). Dof numbering is ``2*node + component``.
"""

from dataclasses import dataclass, field, replace

import numpy as np

from ..exceptions import MeshError

#: interface kinds, indexed by ``Mesh.interface_kind``
INTERFACE_KINDS = ("bed", "head", "brick")


@dataclass(frozen=True, eq=False)
class Mesh:
    """A 2D mesoscale mesh.

    Attributes
    ----------
    nodes : ndarray of shape (n_nodes, 2)
        Coordinates, mm.
    element : str
        Continuum element type, ``"Q4"`` or ``"Q8"``.
    quads : ndarray of shape (n_quads, n_nodes_per_quad)
        Connectivity, counter-clockwise corners first.
    quad_block : ndarray of shape (n_quads,)
        Index of the block (a separately noded body: a unit or half a unit) of each quad.
    block_unit : ndarray of shape (n_blocks,)
        Index of the masonry unit each block belongs to.
    block_bounds : ndarray of shape (n_blocks, 4)
        ``[x0, y0, x1, y1]`` of each block, mm.
    interfaces : ndarray of shape (n_interfaces, 4 or 6)
        Interface connectivity, face A then face B.
    interface_kind : ndarray of shape (n_interfaces,)
        Index into :data:`INTERFACE_KINDS`.
    interface_blocks : ndarray of shape (n_interfaces, 2)
        Blocks on face A and face B of each interface element; the pair identifies the
        joint segment.
    node_sets : dict of str to ndarray
        Named node sets (``"bottom"``, ``"top"``, ``"left"``, ``"right"``, corners).
    edge_sets : dict of str to ndarray of shape (n_edges, 2 or 3)
        Named boundary edges, nodes ordered (start, end[, mid]).
    """

    nodes: np.ndarray
    element: str
    quads: np.ndarray
    quad_block: np.ndarray
    block_unit: np.ndarray
    block_bounds: np.ndarray
    interfaces: np.ndarray
    interface_kind: np.ndarray
    interface_blocks: np.ndarray
    node_sets: dict = field(default_factory=dict)
    edge_sets: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.nodes.ndim != 2 or self.nodes.shape[1] != 2:
            raise MeshError(f"nodes must have shape (n_nodes, 2); got {self.nodes.shape}")
        expected = {"Q4": 4, "Q8": 8}.get(self.element)
        if expected is None:
            raise MeshError(f"element must be 'Q4' or 'Q8'; got {self.element!r}")
        if self.quads.shape[1] != expected:
            raise MeshError(f"{self.element} quads need {expected} nodes; got {self.quads.shape[1]}")
        n_if = {4: 4, 8: 6}[expected]
        if len(self.interfaces) and self.interfaces.shape[1] != n_if:
            raise MeshError(
                f"{self.element} quads need {n_if}-node interfaces; got {self.interfaces.shape[1]}"
            )

    @property
    def n_nodes(self):
        return len(self.nodes)

    @property
    def n_dofs(self):
        return 2 * len(self.nodes)

    @property
    def width(self):
        """Overall width, mm."""
        return float(np.ptp(self.nodes[:, 0]))

    @property
    def height(self):
        """Overall height, mm."""
        return float(np.ptp(self.nodes[:, 1]))

    def interfaces_of_kind(self, kind):
        """Boolean mask of the interfaces of one kind (``"bed"``, ``"head"``, ``"brick"``)."""
        if kind not in INTERFACE_KINDS:
            raise ValueError(f"unknown interface kind {kind!r}; expected one of {INTERFACE_KINDS}")
        return self.interface_kind == INTERFACE_KINDS.index(kind)

    def check(self, atol=1e-9):
        """Invariant checks too costly for ``__post_init__``; returns a list of problems (empty if valid)."""
        problems = []
        half = self.interfaces.shape[1] // 2
        gap = np.abs(self.nodes[self.interfaces[:, :half]] - self.nodes[self.interfaces[:, half:]])
        if gap.size and gap.max() > atol:
            problems.append(f"interface faces do not coincide (max gap {gap.max():.3g} mm)")
        used = np.zeros(self.n_nodes, bool)
        used[self.quads.ravel()] = True
        if not used.all():
            problems.append(f"{np.count_nonzero(~used)} nodes belong to no quad")
        return problems

    def without_interfaces(self, atol=1e-9):
        """The continuum mesh: coincident nodes merged and interfaces removed.

        Used for the stiff-joint limit (a mesoscale model with very stiff joints must approach it).
        The result is one body: every quad belongs to block 0 of unit 0.
        """
        key = np.round(self.nodes / atol).astype(np.int64)
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        inverse = inverse.ravel()
        order = np.argsort(first)
        renumber = np.empty_like(order)
        renumber[order] = np.arange(len(order))
        new_of_old = renumber[inverse]
        nodes = self.nodes[first[order]]
        return replace(
            self,
            nodes=nodes,
            quads=new_of_old[self.quads],
            quad_block=np.zeros(len(self.quads), np.intp),
            block_unit=np.zeros(1, np.intp),
            block_bounds=np.r_[nodes.min(axis=0), nodes.max(axis=0)][None],
            interfaces=np.zeros((0, self.interfaces.shape[1]), np.intp),
            interface_kind=np.zeros(0, np.intp),
            interface_blocks=np.zeros((0, 2), np.intp),
            node_sets={k: np.unique(new_of_old[v]) for k, v in self.node_sets.items()},
            edge_sets={k: new_of_old[v] for k, v in self.edge_sets.items()},
        )
