"""Patches of a straight boundary face: exact quadrature over any part of the face, contact nodes.

A loading or support shoe acts on an interval ``[a, b]`` (mm) of one face of the specimen, along
the coordinate ``axis`` (0 = x, 1 = y). The interval need not start or end on element edges: a
partial edge is integrated over the part of it inside the interval, with 3-point Gauss–Legendre
on that part (exact for the quadratic edge shape functions times a linear traction, degree 3,
and for the products of two shape functions, degree 4, of a consistent spring matrix). So the
length of a shoe is honoured exactly at any mesh, and loads and springs converge under
refinement instead of jumping with the node positions.
"""

from dataclasses import dataclass

import numpy as np

from .exceptions import MeshError

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(3)


@dataclass(frozen=True)
class Patch:
    """The interval ``[a, b]`` mm along ``axis`` (0 = x, 1 = y) of the boundary face ``face`` (a key
    of ``mesh.edge_sets``, e.g. ``"bottom"``)."""

    face: str
    axis: int
    interval: tuple

    def __post_init__(self):
        a, b = (float(v) for v in self.interval)
        if not b > a:
            raise MeshError(f"patch on face {self.face!r}: interval [{a}, {b}] mm must have b > a")
        object.__setattr__(self, "interval", (a, b))

    @property
    def length(self):
        """Length of the patch, mm."""
        return self.interval[1] - self.interval[0]

    def to_dict(self):
        return {"face": self.face, "axis": "xy"[self.axis], "interval": list(self.interval)}


def edge_shape_functions(xi, nodes_per_edge):
    """Shape functions of an edge at ``xi`` (any shape), ``xi.shape + (nodes_per_edge,)``; node
    order (start, end[, mid]) as in ``mesh.edge_sets``."""
    xi = np.asarray(xi, dtype=float)
    if nodes_per_edge == 3:
        return np.stack([0.5 * xi * (xi - 1), 0.5 * xi * (xi + 1), 1 - xi**2], axis=-1)
    return np.stack([0.5 * (1 - xi), 0.5 * (1 + xi)], axis=-1)


@dataclass(frozen=True)
class PatchQuadrature:
    """Gauss points on the part of each face edge inside a patch.

    Attributes
    ----------
    edges : ndarray of shape (n_edges, nodes_per_edge)
        The face edges that overlap the patch (start, end[, mid]).
    N : ndarray of shape (n_edges, 3, nodes_per_edge)
        Edge shape functions at the Gauss points.
    s : ndarray of shape (n_edges, 3) or None
        Coordinate along the patch axis of the Gauss points, mm (None for whole edges).
    w : ndarray of shape (n_edges, 3)
        Length weights (∑ w = patch length), mm.
    """

    edges: np.ndarray
    N: np.ndarray
    s: np.ndarray
    w: np.ndarray


def patch_quadrature(mesh, patch):
    """Quadrature of ``patch`` on ``mesh``: see :class:`PatchQuadrature`.

    Raises
    ------
    MeshError
        The face is unknown or its edges do not cover the whole patch (a patch beyond the face).
    """
    if patch.face not in mesh.edge_sets:
        raise MeshError(f"no boundary face {patch.face!r}; faces are {sorted(mesh.edge_sets)}")
    try:
        return edge_quadrature(mesh, mesh.edge_sets[patch.face], patch.interval, patch.axis)
    except MeshError as e:
        raise MeshError(f"face {patch.face!r}: {e}") from None


def edge_quadrature(mesh, edges, interval=None, axis=None):
    """Gauss points on straight boundary ``edges`` ``(n_edges, 2 or 3)``: on the whole edges, or on
    the part of each inside ``interval`` ``(a, b)`` mm along ``axis``; see :class:`PatchQuadrature`.

    Raises
    ------
    MeshError
        The edges do not cover the whole interval.
    """
    p, q = mesh.nodes[edges[:, 0]], mesh.nodes[edges[:, 1]]
    if interval is None:
        xi = np.broadcast_to(_GAUSS_X, (len(edges), 3))
        w = _GAUSS_W[None] * (0.5 * np.linalg.norm(q - p, axis=1))[:, None]
        return PatchQuadrature(edges, edge_shape_functions(xi, edges.shape[1]), None, w)
    a, b = interval
    sa, sb = p[:, axis], q[:, axis]
    lo = np.maximum(np.minimum(sa, sb), a)
    hi = np.minimum(np.maximum(sa, sb), b)
    tol = 1e-9 * max(1.0, b - a)
    keep = hi - lo > tol
    covered = np.sum(hi[keep] - lo[keep])
    if abs(covered - (b - a)) > tol:
        raise MeshError(f"the interval [{a:g}, {b:g}] mm along {'xy'[axis]} is not on the loaded boundary: "
                        f"its edges cover {covered:.6g} mm of it")
    edges, sa, sb, lo, hi = edges[keep], sa[keep], sb[keep], lo[keep], hi[keep]
    centre, half = 0.5 * (sa + sb), 0.5 * (sb - sa)  # s(ξ) = centre + half ξ on a straight edge
    xi0, xi1 = (lo - centre) / half, (hi - centre) / half
    xi = 0.5 * (xi0 + xi1)[:, None] + 0.5 * (xi1 - xi0)[:, None] * _GAUSS_X[None]
    s = centre[:, None] + half[:, None] * xi
    w = _GAUSS_W[None] * (0.5 * (hi - lo))[:, None]
    return PatchQuadrature(edges, edge_shape_functions(xi, edges.shape[1]), s, w)


def snap_patch(mesh, patch, anchor):
    """The patch with its free end moved to the nearest edge end of the face (its ``anchor`` end,
    0 = ``a`` or 1 = ``b``, stays): a rigid shoe bonded to whole element edges.

    Returns
    -------
    Patch
        Unchanged if the free end already lies on an edge end (to 1e-9 of the length).
    """
    edges = mesh.edge_sets[patch.face]
    ends = np.unique(mesh.nodes[edges[:, :2].ravel(), patch.axis])
    fixed_end = patch.interval[anchor]
    free_end = patch.interval[1 - anchor]
    candidates = ends[(ends > fixed_end) if anchor == 0 else (ends < fixed_end)]
    if len(candidates) == 0:
        raise MeshError(f"face {patch.face!r} has no edge end beyond {fixed_end:g} mm")
    snapped = candidates[np.argmin(np.abs(candidates - free_end))]
    if abs(snapped - free_end) <= 1e-9 * max(1.0, patch.length):
        return patch
    interval = (fixed_end, snapped) if anchor == 0 else (snapped, fixed_end)
    return Patch(patch.face, patch.axis, interval)


def contact_nodes(mesh, patches):
    """Nodes of the face edges lying wholly inside the patches, sorted ``(n,)``: the nodes a rigid
    shoe bonded over the patch holds (never the duplicated node of the next unit, whose edge lies
    outside). The patches should end on edge ends (:func:`snap_patch`)."""
    nodes = []
    for patch in patches:
        edges = mesh.edge_sets[patch.face]
        a, b = patch.interval
        tol = 1e-9 * max(1.0, b - a)
        sa = mesh.nodes[edges[:, 0], patch.axis]
        sb = mesh.nodes[edges[:, 1], patch.axis]
        inside = (np.minimum(sa, sb) >= a - tol) & (np.maximum(sa, sb) <= b + tol)
        nodes.append(edges[inside].ravel())
    return np.unique(np.concatenate(nodes)) if nodes else np.zeros(0, np.intp)


def patch_spring_matrices(mesh, patch, thickness):
    """Consistent matrices of distributed springs (unit stiffness 1 N/mm³, the same in x and y)
    over the patch: ``(dofs (n_edges, 2 k), matrices (n_edges, 2 k, 2 k))`` N/mm, ``k`` nodes per
    edge, dofs ordered (x, y) node by node; ∫ Nᵀ N t ds on the part of each edge inside."""
    qd = patch_quadrature(mesh, patch)
    M = np.einsum("eg,egi,egj->eij", qd.w * thickness, qd.N, qd.N)
    matrices = np.einsum("eij,ab->eiajb", M, np.eye(2)).reshape(len(M), 2 * M.shape[1], 2 * M.shape[1])
    dofs = np.stack([2 * qd.edges, 2 * qd.edges + 1], axis=-1).reshape(len(qd.edges), -1)
    return dofs, matrices
