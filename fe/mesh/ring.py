"""A homogenised elastic ring round a brick wall: the surrounding masonry of an in-situ test.

An in-situ test loads a small region of a large wall; modelling the whole wall at the mesoscale is
wasteful, cutting it free at a few unit lengths over-estimates the displacements (free edges,
the finite-panel effect). :func:`add_ring` surrounds the wall's left, right and top sides with a band of ordinary continuum quads (a homogenised orthotropic material, one body) on a
structured grid whose inner lines are the wall's boundary node lines, graded geometrically
outwards. The ring's nodes on the wall boundary coincide with the wall's nodes there (one ring node
for the one or two wall nodes at a joint end); :func:`add_ring` returns them as tie groups
(``u[group] = u[group[0]]``, see :func:`fe.constraints.constraint_transform`).
"""

from dataclasses import replace

import numpy as np

from ..exceptions import MeshError
from .brick_wall import _block_grid


def _graded(length, first, n):
    """``n`` element lengths growing geometrically from ``first`` to fill ``length`` (mm)."""
    if n * first >= length:
        return np.full(n, length / n)
    lo, hi = 1.0, 2.0
    while first * (hi**n - 1) / (hi - 1) < length:
        hi *= 2
    for _ in range(100):  # bisection on the growth ratio
        r = 0.5 * (lo + hi)
        if first * (r**n - 1) / (r - 1) < length:
            lo = r
        else:
            hi = r
    steps = first * r ** np.arange(n)
    return steps * length / steps.sum()


def add_ring(mesh, width, n_layers=6):
    """The wall mesh with a homogenised ring of ``width`` (mm) on its left, right and top sides.

    Parameters
    ----------
    mesh : Mesh
        A brick-wall mesh (origin at its bottom-left corner).
    width : float
        Ring width, mm (e.g. 1000).
    n_layers : int
        Elements across the ring, graded from the wall's boundary element size outwards.

    Returns
    -------
    mesh : Mesh
        Wall and ring; ring quads form one new block (and unit). Node sets ``bottom`` (the wall's
        and the ring's bottom nodes) and ``top``, and edge set ``top``, are those of the outer
        boundary; ``left``/``right`` those of the ring's outer sides; ``wall_*`` keep the wall's.
    ring_quads : ndarray of bool, shape (n_quads,)
    ties : list of ndarray
        Groups of coincident nodes on the wall boundary, the ring's node first.
    """
    if not width > 0:
        raise MeshError(f"ring width must be > 0 mm; got {width}")
    quadratic = mesh.element == "Q8"
    W, H = mesh.width, mesh.height
    tol = 1e-6
    # the wall's boundary element corners: every boundary node for Q4, every other one for Q8
    edge_ends = np.concatenate([mesh.edge_sets[s][:, :2].ravel() for s in ("left", "right", "top")])
    corners = mesh.nodes[np.unique(edge_ends)]
    xs_wall = np.unique(np.round(corners[np.abs(corners[:, 1] - H) < tol, 0], 6))
    ys_wall = np.unique(np.round(corners[np.abs(corners[:, 0]) < tol, 1], 6))
    if not np.array_equal(ys_wall, np.unique(np.round(corners[np.abs(corners[:, 0] - W) < tol, 1], 6))):
        raise MeshError("the wall's left and right sides have different node lines; a ring needs matching ones")
    side = np.cumsum(_graded(width, np.diff(ys_wall).max(), n_layers))
    xs = np.concatenate([-side[::-1], xs_wall, W + side])
    ys = np.concatenate([ys_wall, H + side])
    nodes, quads, _index = _block_grid(xs, ys, quadratic)
    # keep the quads outside the wall
    centre = nodes[quads[:, :4]].mean(axis=1)
    outside = ~((centre[:, 0] > 0) & (centre[:, 0] < W) & (centre[:, 1] < H))
    quads = quads[outside]
    used = np.unique(quads)
    renumber = -np.ones(len(nodes), np.intp)
    renumber[used] = np.arange(len(used)) + mesh.n_nodes
    ring_nodes, quads = nodes[used], renumber[quads]
    all_nodes = np.vstack([mesh.nodes, ring_nodes])
    # ties: ring nodes on the wall boundary ↔ wall nodes at the same place
    on_boundary = ((np.abs(ring_nodes[:, 0]) < tol) | (np.abs(ring_nodes[:, 0] - W) < tol)) & (ring_nodes[:, 1] <= H + tol)
    on_boundary |= (np.abs(ring_nodes[:, 1] - H) < tol) & (ring_nodes[:, 0] >= -tol) & (ring_nodes[:, 0] <= W + tol)
    wall_boundary = np.unique(np.concatenate([mesh.node_sets[s] for s in ("left", "right", "top")]))
    key = {}
    for n in wall_boundary:
        key.setdefault(tuple(np.round(mesh.nodes[n], 6)), []).append(n)
    ties = []
    for k in np.flatnonzero(on_boundary):
        partners = key.get(tuple(np.round(ring_nodes[k], 6)), [])
        if not partners:
            raise MeshError(f"ring node at {tuple(ring_nodes[k])} mm has no wall node to join")
        ties.append(np.array([mesh.n_nodes + k, *partners]))
    block = len(mesh.block_bounds)
    xr, yr = all_nodes[:, 0], all_nodes[:, 1]
    top_edges = _top_edges(quads, all_nodes, H + width, quadratic)
    ring = replace(
        mesh,
        nodes=all_nodes,
        quads=np.vstack([mesh.quads, quads]),
        quad_block=np.concatenate([mesh.quad_block, np.full(len(quads), block)]),
        block_unit=np.append(mesh.block_unit, mesh.block_unit.max() + 1),
        block_bounds=np.vstack([mesh.block_bounds, [-width, 0.0, W + width, H + width]]),
        node_sets={
            **{f"wall_{k}": v for k, v in mesh.node_sets.items()},
            "bottom": np.flatnonzero(np.abs(yr) < tol),
            "top": np.flatnonzero(np.abs(yr - H - width) < tol),
            "left": np.flatnonzero(np.abs(xr + width) < tol),
            "right": np.flatnonzero(np.abs(xr - W - width) < tol),
        },
        edge_sets={**{f"wall_{k}": v for k, v in mesh.edge_sets.items()}, "top": top_edges},
    )
    ring_quads = np.zeros(len(ring.quads), bool)
    ring_quads[len(mesh.quads):] = True
    return ring, ring_quads, ties


def _top_edges(quads, nodes, y_top, quadratic):
    """The top edges (start, end[, mid]) of the quads touching ``y = y_top``."""
    # local corners 3 → 2 is the top edge (counter-clockwise numbering), mid-side node 6
    top = quads[np.all(np.abs(nodes[quads[:, [2, 3]], 1] - y_top) < 1e-6, axis=1)]
    return top[:, [3, 2, 6]] if quadratic else top[:, [3, 2]]
