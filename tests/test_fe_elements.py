"""Element contracts: quadrature, Q4/Q8 shape functions and stiffness, line interfaces, patch test."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fe.assembly import assemble_matrix, element_dofs
from fe.elements.interface import IL4, IL6
from fe.elements.quad import Q4, Q8
from fe.elements.quadrature import gauss_legendre, gauss_lobatto, gauss_square
from fe.materials import interface_stiffness_from_moduli, plane_stress


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5])
def test_gauss_legendre_exact_for_degree_2n_minus_1(n):
    x, w = gauss_legendre(n)
    for k in range(2 * n):
        exact = (1 - (-1) ** (k + 1)) / (k + 1)
        assert_allclose(np.sum(w * x**k), exact, rtol=0, atol=1e-14)


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_gauss_lobatto_includes_ends_and_is_exact_for_degree_2n_minus_3(n):
    x, w = gauss_lobatto(n)
    assert x[0] == -1.0 and x[-1] == 1.0
    for k in range(2 * n - 2):
        exact = (1 - (-1) ** (k + 1)) / (k + 1)
        assert_allclose(np.sum(w * x**k), exact, rtol=0, atol=1e-14)


def test_gauss_square_integrates_bilinear_monomials():
    p, w = gauss_square(2)
    assert_allclose(np.sum(w * p[:, 0] ** 2 * p[:, 1] ** 2), 4 / 9, rtol=1e-14)


class ElementContract:
    """Contract every quadrilateral element type must satisfy (after scipy's QMCEngineTests)."""

    element = None
    rng = np.random.default_rng(0)

    def random_points(self, n=7):
        return self.rng.uniform(-1, 1, (n, 2))

    def test_nodality(self):
        # N_i(x_j) = δ_ij: each shape function is 1 at its own node and 0 at the others
        assert_allclose(self.element.shape(self.element.reference_nodes), np.eye(self.element.n_nodes), atol=1e-15)

    def test_partition_of_unity_and_zero_gradient_sum(self):
        xi = self.random_points()
        assert_allclose(self.element.shape(xi).sum(axis=1), 1.0, rtol=0, atol=1e-14)
        assert_allclose(self.element.shape_grad(xi).sum(axis=1), 0.0, rtol=0, atol=1e-13)

    def test_gradients_match_central_differences(self):
        xi, eps = self.random_points(), 1e-6
        dN = self.element.shape_grad(xi)
        for d in range(2):
            step = np.zeros(2)
            step[d] = eps
            fd = (self.element.shape(xi + step) - self.element.shape(xi - step)) / (2 * eps)
            # central differences: truncation O(eps²) ~ 1e-12, round-off ~ 1e-16/eps ~ 1e-10
            assert_allclose(dN[..., d], fd, rtol=0, atol=1e-9)

    def distorted_coords(self):
        corners = np.array([[0.0, 0.0], [2.0, 0.3], [2.4, 2.1], [-0.2, 1.7]])
        if self.element.n_nodes == 4:
            return corners[None]
        mids = 0.5 * (corners + np.roll(corners, -1, axis=0))
        return np.vstack([corners, mids])[None]

    def test_stiffness_symmetric_psd_with_three_rigid_body_modes(self):
        K = self.element.stiffness(self.distorted_coords(), plane_stress(1000.0, 0.25), 10.0)[0]
        assert_allclose(K, K.T, rtol=0, atol=1e-10 * np.abs(K).max())
        eig = np.linalg.eigvalsh(K)
        tol = 1e-10 * eig.max()
        assert np.all(eig > -tol)
        assert np.count_nonzero(np.abs(eig) < tol) == 3  # two translations, one rotation

    def test_rigid_rotation_produces_no_force(self):
        coords = self.distorted_coords()
        K = self.element.stiffness(coords, plane_stress(1000.0, 0.25), 1.0)[0]
        x = coords[0]
        u = np.column_stack([-x[:, 1], x[:, 0]]).ravel()  # infinitesimal rotation
        assert_allclose(K @ u, 0.0, rtol=0, atol=1e-9 * np.abs(K).max())

    def test_patch_test_reproduces_linear_field(self):
        """A distorted 2 × 2 patch with the exact linear field on its boundary reproduces it inside."""
        nodes, quads = patch_mesh(self.element.n_nodes)
        D = plane_stress(2000.0, 0.3)
        K = assemble_matrix(element_dofs(quads), self.element.stiffness(nodes[quads], D, 5.0), 2 * len(nodes))
        exact = np.column_stack([1e-3 * nodes[:, 0] + 2e-3 * nodes[:, 1] + 0.1, -3e-3 * nodes[:, 0] + 5e-4 * nodes[:, 1]]).ravel()
        boundary = np.flatnonzero(
            np.isclose(nodes[:, 0], 0) | np.isclose(nodes[:, 0], 2) | np.isclose(nodes[:, 1], 0) | np.isclose(nodes[:, 1], 2)
        )
        fixed = np.concatenate([2 * boundary, 2 * boundary + 1])
        free = np.setdiff1d(np.arange(2 * len(nodes)), fixed)
        K = K.toarray()
        u = exact.copy()
        u[free] = np.linalg.solve(K[np.ix_(free, free)], -K[np.ix_(free, fixed)] @ exact[fixed])
        assert_allclose(u, exact, rtol=0, atol=1e-13)  # round-off
        B, _ = self.element.strain_operator(nodes[quads], self.random_points())
        strain = np.einsum("epij,ej->epi", B, u[element_dofs(quads)])
        assert_allclose(strain, np.broadcast_to([1e-3, 5e-4, -1e-3], strain.shape), rtol=0, atol=1e-14)

    def test_inverse_map_round_trip(self):
        coords = np.repeat(self.distorted_coords(), 5, axis=0)
        xi = self.random_points(5) * 0.9
        x = np.einsum("pn,pnj->pj", self.element.shape(xi), coords)
        assert_allclose(self.element.inverse_map(coords, x), xi, rtol=0, atol=1e-11)


def patch_mesh(n_nodes):
    """A 2 × 2 patch on [0, 2]² with a displaced interior vertex (straight-sided elements)."""
    v = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1.2, 0.85], [2, 1], [0, 2], [1, 2], [2, 2]], float)
    corners = np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]])
    if n_nodes == 4:
        return v, corners
    edges = {}
    nodes = list(v)
    quads = []
    for q in corners:
        mids = []
        for a, b in zip(q, np.roll(q, -1)):
            key = (min(a, b), max(a, b))
            if key not in edges:
                edges[key] = len(nodes)
                nodes.append(0.5 * (v[a] + v[b]))
            mids.append(edges[key])
        quads.append(list(q) + mids)
    return np.array(nodes), np.array(quads)


class TestQ4(ElementContract):
    element = Q4


class TestQ8(ElementContract):
    element = Q8


@pytest.mark.parametrize("iface", [IL4, IL6])
def test_interface_rigid_motion_of_both_faces_gives_no_force(iface):
    x = np.array([[0.0, 0.0], [50.0, 0.0], [25.0, 0.0]])[: iface.nodes_per_face]
    coords = np.vstack([x, x])[None]
    K = iface.stiffness(coords, 40.0, 100.0, 120.0)[0]
    for u in (np.tile([1.0, 0.0], iface.n_nodes), np.tile([0.0, 1.0], iface.n_nodes), np.column_stack([-coords[0, :, 1], coords[0, :, 0]]).ravel()):
        assert_allclose(K @ u, 0.0, rtol=0, atol=1e-10)
    assert_allclose(K, K.T, rtol=0, atol=1e-12)
    assert np.linalg.eigvalsh(K).min() > -1e-9


@pytest.mark.parametrize("iface", [IL4, IL6])
@pytest.mark.parametrize("angle", [0.0, 0.7, np.pi / 2])
def test_interface_uniform_opening_and_slip_give_exact_resultants(iface, angle):
    """Face B moved by δ_n along the normal and δ_s along the tangent: resultant = k δ L t."""
    L, t, kN, kV = 60.0, 100.0, 80.0, 30.0
    s_hat = np.array([np.cos(angle), np.sin(angle)])
    n_hat = np.array([-s_hat[1], s_hat[0]])
    face = np.array([[0.0], [L], [L / 2]])[: iface.nodes_per_face] * s_hat
    coords = np.vstack([face, face])[None]
    K = iface.stiffness(coords, kV, kN, t)[0]
    dn, ds = 0.01, -0.004
    u = np.zeros((iface.n_nodes, 2))
    u[iface.nodes_per_face :] = dn * n_hat + ds * s_hat
    f = (K @ u.ravel()).reshape(-1, 2)
    face_b_force = f[iface.nodes_per_face :].sum(axis=0)
    assert_allclose(face_b_force @ n_hat, kN * dn * L * t, rtol=1e-13)
    assert_allclose(face_b_force @ s_hat, kV * ds * L * t, rtol=1e-13)
    assert_allclose(f.sum(axis=0), 0.0, rtol=0, atol=1e-9)  # equilibrium of the element


def test_interface_stiffness_from_moduli_eq_2_5():
    kN, kV = interface_stiffness_from_moduli(E_u=16700, E_m=780, G_u=7261, G_m=325, h_m=10)
    assert_allclose(kN, 16700 * 780 / (10 * (16700 - 780)), rtol=1e-15)
    assert_allclose(kV, 7261 * 325 / (10 * (7261 - 325)), rtol=1e-15)
    with pytest.raises(ValueError, match="E_u > E_m"):
        interface_stiffness_from_moduli(E_u=500, E_m=780, G_u=7261, G_m=325, h_m=10)
