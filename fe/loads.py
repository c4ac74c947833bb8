"""Consistent nodal forces of distributed boundary tractions."""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .boundary import edge_quadrature


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
        Only the part of the edges inside ``[a, b]`` along coordinate ``axis`` (0 = x, 1 = y) is
        loaded (a loading shoe of length ``b − a``): an edge partly inside is integrated over the
        part inside (:func:`fe.boundary.edge_quadrature`), so the patch need not start or end on
        element edges and its resultant and centre are exact at any mesh.
    axis : int, optional
    gradient : bool
        Instead of the uniform traction ``t``, the linearly varying one ``t · (s − s_c)`` where
        ``s`` is the coordinate along ``axis`` and ``s_c`` the centre of ``interval`` (``traction``
        is then in MPa per mm): a traction with zero resultant and moment ``t · L³/12`` per unit
        thickness over a patch of length ``L``. Needs ``interval`` and ``axis``.

    Returns
    -------
    f : ndarray of shape (n_dofs,)
        Nodal forces ∫ N_i t(s) thickness ds, N (3-point Gauss on each edge or part of an edge:
        exact for quadratic edges and a linear traction; on whole quadratic edges a uniform
        traction gets the weights 1/6, 1/6, 2/3 of the edge force).

    Raises
    ------
    MeshError
        The edges do not cover the whole interval (a patch beyond the face).
    """
    if gradient and interval is None:
        raise ValueError("a traction gradient needs the patch interval and axis")
    qd = edge_quadrature(mesh, edges, interval, axis)
    profile = qd.s - 0.5 * (interval[0] + interval[1]) if gradient else 1.0
    nodal = np.einsum("eg,egi->ei", qd.w * profile * thickness, qd.N)  # (n_edges, nodes_per_edge) mm²
    f = np.zeros(mesh.n_dofs)
    traction = np.asarray(traction, dtype=float)
    for j in range(2):
        np.add.at(f, 2 * qd.edges + j, nodal * traction[j])
    return f
