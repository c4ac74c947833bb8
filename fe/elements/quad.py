"""Plane-stress isoparametric quadrilaterals: 4-node bilinear (Q4) and 8-node serendipity (Q8).

Conventions
-----------
Reference square [-1, 1]^2. Corner nodes 0..3 counter-clockwise from (-1, -1); Q8 adds the
mid-side nodes 4..7 on the edges (0-1), (1-2), (2-3), (3-0). Element dofs are ordered
``[u_0x, u_0y, u_1x, u_1y, ...]`` (dof = 2*local_node + component). Batched arrays have the
elements on axis 0: ``coords`` is ``(n_elements, n_nodes, 2)`` in mm.
"""

from dataclasses import dataclass

import numpy as np

from .quadrature import gauss_square

_Q4_NODES = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
_Q8_NODES = np.vstack([_Q4_NODES, [[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]])


@dataclass(frozen=True)
class QuadElement:
    """A quadrilateral element type.

    Attributes
    ----------
    name : str
        ``"Q4"`` or ``"Q8"``.
    n_nodes : int
        Nodes per element.
    gauss_order : int
        Points per direction of the full Gauss rule used for the stiffness (2 for Q4, 3 for Q8).
    """

    name: str
    n_nodes: int
    gauss_order: int

    @property
    def reference_nodes(self):
        """Nodal coordinates in the reference square, ``(n_nodes, 2)``."""
        return _Q4_NODES if self.n_nodes == 4 else _Q8_NODES

    def shape(self, xi):
        """Shape functions at reference points ``xi`` ``(n_points, 2)`` → ``(n_points, n_nodes)``."""
        xi = np.atleast_2d(np.asarray(xi, dtype=float))
        s, t = xi[:, :1], xi[:, 1:]
        si, ti = self.reference_nodes[:, 0], self.reference_nodes[:, 1]
        if self.n_nodes == 4:
            return 0.25 * (1 + s * si) * (1 + t * ti)
        N = np.empty((xi.shape[0], 8))
        c = slice(0, 4)
        N[:, c] = 0.25 * (1 + s * si[c]) * (1 + t * ti[c]) * (s * si[c] + t * ti[c] - 1)
        N[:, [4, 6]] = 0.5 * (1 - s**2) * (1 + t * ti[[4, 6]])
        N[:, [5, 7]] = 0.5 * (1 + s * si[[5, 7]]) * (1 - t**2)
        return N

    def shape_grad(self, xi):
        """Reference gradients ``dN/d(xi, eta)`` → ``(n_points, n_nodes, 2)``."""
        xi = np.atleast_2d(np.asarray(xi, dtype=float))
        s, t = xi[:, :1], xi[:, 1:]
        si, ti = self.reference_nodes[:, 0], self.reference_nodes[:, 1]
        dN = np.empty((xi.shape[0], self.n_nodes, 2))
        if self.n_nodes == 4:
            dN[..., 0] = 0.25 * si * (1 + t * ti)
            dN[..., 1] = 0.25 * ti * (1 + s * si)
            return dN
        c = slice(0, 4)
        dN[:, c, 0] = 0.25 * si[c] * (1 + t * ti[c]) * (2 * s * si[c] + t * ti[c])
        dN[:, c, 1] = 0.25 * ti[c] * (1 + s * si[c]) * (s * si[c] + 2 * t * ti[c])
        m = [4, 6]
        dN[:, m, 0] = -s * (1 + t * ti[m])
        dN[:, m, 1] = 0.5 * (1 - s**2) * ti[m]
        m = [5, 7]
        dN[:, m, 0] = 0.5 * si[m] * (1 - t**2)
        dN[:, m, 1] = -t * (1 + s * si[m])
        return dN

    def strain_operator(self, coords, xi):
        """Strain–displacement matrices and Jacobian determinants at reference points.

        Parameters
        ----------
        coords : ndarray of shape (n_elements, n_nodes, 2)
            Nodal coordinates, mm.
        xi : ndarray of shape (n_points, 2)
            Reference coordinates.

        Returns
        -------
        B : ndarray of shape (n_elements, n_points, 3, 2*n_nodes)
            Engineering strains ``[eps_xx, eps_yy, gamma_xy] = B @ u_e``, 1/mm.
        det_J : ndarray of shape (n_elements, n_points)
            Jacobian determinants, mm².
        """
        dN = self.shape_grad(xi)  # (p, n, 2)
        J = np.einsum("pni,enj->epij", dN, coords)  # J[i, j] = d x_j / d xi_i
        det_J = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
        if np.any(det_J <= 0):
            bad = int(np.argwhere(det_J <= 0)[0, 0])
            raise ValueError(f"element {bad} has a non-positive Jacobian: nodes not counter-clockwise")
        inv_J = np.empty_like(J)
        inv_J[..., 0, 0] = J[..., 1, 1] / det_J
        inv_J[..., 1, 1] = J[..., 0, 0] / det_J
        inv_J[..., 0, 1] = -J[..., 0, 1] / det_J
        inv_J[..., 1, 0] = -J[..., 1, 0] / det_J
        dNdx = np.einsum("epij,pnj->epni", inv_J, dN)  # physical gradients
        n_el, n_p = det_J.shape
        B = np.zeros((n_el, n_p, 3, 2 * self.n_nodes))
        B[:, :, 0, 0::2] = dNdx[..., 0]
        B[:, :, 1, 1::2] = dNdx[..., 1]
        B[:, :, 2, 0::2] = dNdx[..., 1]
        B[:, :, 2, 1::2] = dNdx[..., 0]
        return B, det_J

    def stiffness(self, coords, D, thickness):
        """Element stiffness matrices ``K_e = t Σ_gp B^T D B det_J w``.

        Parameters
        ----------
        coords : ndarray of shape (n_elements, n_nodes, 2)
            Nodal coordinates, mm.
        D : ndarray of shape (3, 3)
            Constitutive matrix, MPa (any symmetric matrix: the affine parts of plane
            stress are passed one at a time, see :func:`fe.materials.plane_stress_coefficients`).
        thickness : float
            Out-of-plane thickness, mm.

        Returns
        -------
        K : ndarray of shape (n_elements, 2*n_nodes, 2*n_nodes)
            N/mm when D is in MPa.
        """
        xi, w = gauss_square(self.gauss_order)
        B, det_J = self.strain_operator(coords, xi)
        return thickness * np.einsum("epki,kl,eplj,ep,p->eij", B, D, B, det_J, w, optimize=True)

    def inverse_map(self, coords, x, tol=1e-12, max_iter=30):
        """Reference coordinates of physical points by Newton's method on x(xi) = x.

        Parameters
        ----------
        coords : ndarray of shape (n, n_nodes, 2)
            Coordinates of the candidate element of each point, mm.
        x : ndarray of shape (n, 2)
            Physical points, mm.

        Returns
        -------
        xi : ndarray of shape (n, 2)
            Reference coordinates (may lie outside [-1, 1]^2 when the point is outside).
        """
        xi = np.zeros((len(x), 2))
        for _ in range(max_iter):
            N = self.shape(xi)  # (n, nodes)
            dN = self.shape_grad(xi)  # (n, nodes, 2)
            r = x - np.einsum("en,enj->ej", N, coords)
            J = np.einsum("eni,enj->eji", dN, coords)  # dx_j/dxi_i transposed: J[j, i]
            dxi = np.linalg.solve(J, r[..., None])[..., 0]
            xi += dxi
            if np.max(np.abs(dxi), initial=0.0) < tol:
                break
        return xi


Q4 = QuadElement("Q4", 4, 2)
Q8 = QuadElement("Q8", 8, 3)
QUADS = {"Q4": Q4, "Q8": Q8}
