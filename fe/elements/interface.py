"""Zero-thickness line interface elements (4-node linear and 6-node quadratic).

An interface joins face A and face B of a joint, which coincide geometrically. Node order per
element: ``[A_0, A_1, (A_mid), B_0, B_1, (B_mid)]`` with A's nodes ordered along the tangent
``s``; the normal ``n = (-s_y, s_x)`` points from A to B. The relative displacement
``δ = u_B − u_A`` has components ``δ_s`` (slip) and ``δ_n`` (opening, positive when the faces
separate). The elastic traction is (thesis eq. 2.3 in 2D)

.. math:: \\mathbf t = \\begin{bmatrix} t_s \\\\ t_n \\end{bmatrix}
          = \\operatorname{diag}(k_V, k_N) \\begin{bmatrix} δ_s \\\\ δ_n \\end{bmatrix},

with ``k_V, k_N`` in N/mm³ (stiffness per unit area). Integration is Newton–Cotes/Lobatto at the
nodes (trapezoidal for 4 nodes, Simpson for 6) by default, which decouples the node pairs;
``rule="gauss"`` selects Gauss–Legendre points (as many as face nodes; exact for the elastic
stiffness, a consistent rather than lumped interface stiffness). Lobatto is the default for
nonlinear interfaces: with stiff (dummy) interfaces Gauss integration produces spurious traction
oscillations [Vignollet, May & de Borst 2015, ``docs/references.md``], while Day &
Potts (1994) attribute them to ill-conditioning, hence the switch.
"""

from dataclasses import dataclass

import numpy as np

from .quadrature import gauss_legendre, gauss_lobatto

#: Integration rules of the interface elements (Newton–Cotes/Lobatto at the nodes, or Gauss).
RULES = ("lobatto", "gauss")


@dataclass(frozen=True)
class LineInterface:
    """A zero-thickness line interface type: ``"IL4"`` (4 nodes) or ``"IL6"`` (6 nodes)."""

    name: str
    nodes_per_face: int

    @property
    def n_nodes(self):
        return 2 * self.nodes_per_face

    def shape(self, s):
        """1D face shape functions at ``s`` ``(n_points,)`` → ``(n_points, nodes_per_face)``.

        Face node order is (start, end[, mid]).
        """
        s = np.atleast_1d(np.asarray(s, dtype=float))[:, None]
        if self.nodes_per_face == 2:
            return np.hstack([0.5 * (1 - s), 0.5 * (1 + s)])
        return np.hstack([0.5 * s * (s - 1), 0.5 * s * (s + 1), 1 - s**2])

    def shape_grad(self, s):
        s = np.atleast_1d(np.asarray(s, dtype=float))[:, None]
        if self.nodes_per_face == 2:
            return np.hstack([-0.5 + 0 * s, 0.5 + 0 * s])
        return np.hstack([s - 0.5, s + 0.5, -2 * s])

    def integration_points(self, rule="lobatto"):
        """Points ``s`` and weights on [-1, 1] of ``rule`` (see :data:`RULES`), ``nodes_per_face`` each."""
        if rule == "lobatto":
            return gauss_lobatto(self.nodes_per_face)
        if rule == "gauss":
            return gauss_legendre(self.nodes_per_face)
        raise ValueError(f"interface integration rule must be one of {RULES}; got {rule!r}")

    def relative_displacement_operator(self, coords, rule="lobatto"):
        """Operator from element dofs to local relative displacement at the integration points.

        Parameters
        ----------
        coords : ndarray of shape (n_elements, n_nodes, 2)
            Nodal coordinates, mm (face A then face B).
        rule : {"lobatto", "gauss"}
            Integration rule (module docstring).

        Returns
        -------
        Bd : ndarray of shape (n_elements, n_points, 2, 2*n_nodes)
            ``[δ_s, δ_n] = Bd @ u_e`` in mm.
        ds : ndarray of shape (n_elements, n_points)
            Length element |dx/ds| times the integration weight, mm.
        """
        s, w = self.integration_points(rule)
        N = self.shape(s)  # (p, f)
        dN = self.shape_grad(s)
        xa = coords[:, : self.nodes_per_face]
        tangent = np.einsum("pf,efj->epj", dN, xa)  # dx/ds on face A
        jac = np.linalg.norm(tangent, axis=-1)
        if np.any(jac <= 0):
            raise ValueError("an interface element has zero length")
        t_hat = tangent / jac[..., None]
        n_hat = np.stack([-t_hat[..., 1], t_hat[..., 0]], axis=-1)
        R = np.stack([t_hat, n_hat], axis=-2)  # (e, p, 2 local, 2 global)
        n_el, n_p = jac.shape
        nf = self.nodes_per_face
        # global relative displacement: δ_j = Σ_f N_f (u_B,f,j − u_A,f,j)
        M = np.zeros((n_p, 2, 2 * self.n_nodes))
        for f in range(nf):
            for j in range(2):
                M[:, j, 2 * f + j] = -N[:, f]
                M[:, j, 2 * (nf + f) + j] = N[:, f]
        Bd = np.einsum("epij,pjk->epik", R, M)
        return Bd, jac * w

    def stiffness(self, coords, k_shear, k_normal, thickness):
        """Element stiffness ``K_e = t ∫ Bd^T diag(kV, kN) Bd ds``, ``(n_elements, 2n, 2n)`` N/mm.

        ``k_shear`` and ``k_normal`` (N/mm³) may be scalars or arrays of shape ``(n_elements,)``.
        """
        Bd, ds = self.relative_displacement_operator(coords)
        k = np.zeros((len(coords), 2))
        k[:, 0] = k_shear
        k[:, 1] = k_normal
        return thickness * np.einsum("epki,ek,epkj,ep->eij", Bd, k, Bd, ds, optimize=True)


IL4 = LineInterface("IL4", 2)
IL6 = LineInterface("IL6", 3)
