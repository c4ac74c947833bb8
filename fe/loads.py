"""Consistent nodal forces of distributed boundary tractions."""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .exceptions import MeshError


@dataclass(frozen=True)
class LoadPerturbation:
    """A way a scenario's applied load can depart from its intended position, exactly linear.

    Two kinds, both built from one extra set of load patterns ``g = patterns()``
    ``(n_dofs, n_patterns)`` with the scenario's own load coefficients:

    - ``"shift"``: the loads become ``f + a g`` for an amplitude ``a`` in ``unit`` (e.g. a load
      line offset by ``a`` mm with the contact pressure varying linearly), admissible for
      ``|a| ≤ limit``;
    - ``"turn"``: the loads become ``cos φ f + sin φ g`` for an angle φ, ``g`` being ``f`` turned
      by +90° (``limit`` is then None: any angle is statically admissible).

    Consumers (the model diagnosis, sensitivity studies) choose what amplitudes to try; ``fe``
    only states the geometry of the perturbation.
    """

    name: str
    kind: str
    unit: str
    limit: float | None
    description: str
    patterns: Callable[[], np.ndarray]


def edge_traction(mesh, edges, traction, thickness, interval=None, axis=None, gradient=False):
    """Nodal forces of a uniform (or linearly varying) traction on boundary edges.

    Parameters
    ----------
    mesh : Mesh
    edges : ndarray of shape (n_edges, 2 or 3)
        Boundary edges, nodes (start, end[, mid]) as in ``mesh.edge_sets``.
    traction : array_like of shape (2,)
        Traction vector (x, y), MPa (N/mm²).
    thickness : float
        Out-of-plane thickness, mm.
    interval : (float, float), optional
        Only the edges lying inside ``[a, b]`` along coordinate ``axis`` (0 = x, 1 = y) are
        loaded; the interval must start and end on element edges.
    axis : int, optional
    gradient : bool
        Instead of the uniform traction ``t``, the linearly varying one ``t · (s − s_c)`` where
        ``s`` is the coordinate along ``axis`` and ``s_c`` the centre of ``interval`` (``traction``
        is then in MPa per mm): a traction with zero resultant and moment ``t · L³/12`` per unit
        thickness over a patch of length ``L``. Needs ``interval`` and ``axis``.

    Returns
    -------
    f : ndarray of shape (n_dofs,)
        Nodal forces, N. Quadratic edges get the consistent weights (1/6, 1/6, 2/3) of the
        edge length, linear ones (1/2, 1/2).
    """
    p = mesh.nodes[edges[:, 0]]
    q = mesh.nodes[edges[:, 1]]
    if interval is not None:
        a, b = interval
        lo = np.minimum(p[:, axis], q[:, axis])
        hi = np.maximum(p[:, axis], q[:, axis])
        tol = 1e-9 * max(1.0, abs(b - a))
        inside = (lo >= a - tol) & (hi <= b + tol)
        covered = np.sum(hi[inside] - lo[inside])
        if abs(covered - (b - a)) > 1e-6 * (b - a):
            raise MeshError(
                f"load patch [{a}, {b}] mm does not coincide with element edges "
                f"(edges cover {covered:.6g} mm); choose nx, ny so that element edges fall on it"
            )
        edges, p, q = edges[inside], p[inside], q[inside]
    length = np.linalg.norm(q - p, axis=1)
    if gradient:
        if interval is None:
            raise ValueError("a traction gradient needs the patch interval and axis")
        nodal = _linear_weights(mesh, edges, axis, 0.5 * (interval[0] + interval[1]), thickness)
    else:
        weights = np.array([1 / 6, 1 / 6, 2 / 3]) if edges.shape[1] == 3 else np.array([0.5, 0.5])
        nodal = (length * thickness)[:, None] * weights  # (n_edges, nodes_per_edge) mm²
    f = np.zeros(mesh.n_dofs)
    traction = np.asarray(traction, dtype=float)
    for j in range(2):
        np.add.at(f, 2 * edges + j, nodal * traction[j])
    return f


def _linear_weights(mesh, edges, axis, centre, thickness):
    """Consistent nodal weights ∫ N_i (s − centre) t dl of straight edges, ``(n_edges, nodes)`` mm³
    (3-point Gauss–Legendre: exact for the quadratic shape functions times a linear function)."""
    xi, w = np.polynomial.legendre.leggauss(3)
    if edges.shape[1] == 3:  # start, end, mid
        N = np.stack([0.5 * xi * (xi - 1), 0.5 * xi * (xi + 1), 1 - xi**2], axis=1)
    else:
        N = np.stack([0.5 * (1 - xi), 0.5 * (1 + xi)], axis=1)
    a = mesh.nodes[edges[:, 0], axis]
    b = mesh.nodes[edges[:, 1], axis]
    length = np.linalg.norm(mesh.nodes[edges[:, 1]] - mesh.nodes[edges[:, 0]], axis=1)
    s = 0.5 * (a + b)[:, None] + 0.5 * (b - a)[:, None] * xi[None]  # (n_edges, n_gauss)
    return np.einsum("g,gi,eg,e->ei", w, N, s - centre, 0.5 * length * thickness)
