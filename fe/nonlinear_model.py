"""The nonlinear static FE model: elastic units, nonlinear zero-thickness interfaces.

``r(q) = f_int(q) − f_ext``, ``f_int = K_units q + Σ_ip w Bᵀ t(B q)``, ``u = T q``. The tangent
``K_units + Σ_ip w Bᵀ D_alg B`` lives on the reduced CSR pattern of the linear model (built once;
interface contributions are scattered through a precomputed position map by a numba kernel), so a
general sparse solver analyses the pattern once and only refactorises numerically per iteration.

Interfaces are integrated at the node pairs (Newton–Cotes/Lobatto, :mod:`fe.elements.interface`)
or, with ``integration="gauss"``, at Gauss points; the interface law sees ``(opening, slip)``,
normal first.
"""

import numba
import numpy as np
import scipy.sparse as sp

from .assembly import AffineStiffness, StiffnessPart, element_dofs
from .elements.interface import IL4, IL6
from .sensors import sensor_operator
from .solvers import make_general_solver


@numba.njit(cache=True)
def _assemble_interfaces(B, w, D, t, pos, col, data, f):
    """Add ``Σ w Bᵀ D B`` to ``data`` (at ``pos``) and ``Σ w Bᵀ t`` to ``f`` (at ``col``)."""
    n_el, n_p, _, nl = B.shape
    for e in range(n_el):
        for q in range(n_p):
            ip = e * n_p + q
            ww = w[e, q]
            for i in range(nl):
                b0 = B[e, q, 0, i]
                b1 = B[e, q, 1, i]
                if b0 == 0.0 and b1 == 0.0:
                    continue
                ci = col[e, i]
                if ci >= 0:
                    f[ci] += ww * (b0 * t[ip, 0] + b1 * t[ip, 1])
                a0 = ww * (b0 * D[ip, 0, 0] + b1 * D[ip, 1, 0])
                a1 = ww * (b0 * D[ip, 0, 1] + b1 * D[ip, 1, 1])
                for j in range(nl):
                    pj = pos[e, i, j]
                    if pj >= 0:
                        data[pj] += a0 * B[e, q, 0, j] + a1 * B[e, q, 1, j]


class NonlinearModel:
    """Elastic plane-stress units plus nonlinear interfaces, reduced by ``u = T q``.

    Parameters
    ----------
    mesh : Mesh
    unit_parts : sequence of StiffnessPart
        The units' affine parts (``units_D0``, ``units_D1``), see :func:`fe.scenarios.masonry.masonry_parts`.
    interface_elements : ndarray of int
        Indices of the mesh interfaces that are modelled as nonlinear (all by default in the scenarios).
    thickness : float
        Out-of-plane thickness, mm.
    transform : scipy.sparse matrix (n_dofs, n_reduced)
    sensors : sequence of sensors
    solver : {"auto", "pardiso", "superlu"}
    integration : {"lobatto", "gauss"}
        Integration rule of the interfaces (:data:`fe.elements.interface.RULES`; Lobatto by default,
        see :mod:`fe.elements.interface` for why).
    """

    def __init__(self, mesh, unit_parts, interface_elements, thickness, transform, sensors, solver="auto",
                 integration="lobatto"):
        self.mesh = mesh
        self.integration = integration
        self.transform = T = sp.csr_matrix(transform)
        self.interface_elements = np.asarray(interface_elements, dtype=np.intp)
        conn = mesh.interfaces[self.interface_elements]
        iface = IL6 if mesh.element == "Q8" else IL4
        Bd, ds = iface.relative_displacement_operator(mesh.nodes[conn], integration)
        self.B = np.ascontiguousarray(Bd[:, :, ::-1, :])  # rows (opening, slip): normal first
        self.weights = np.ascontiguousarray(thickness * ds)  # (e, p) mm²
        self.n_points_per_element = self.B.shape[1]
        idofs = element_dofs(conn)
        pattern = StiffnessPart("interfaces", idofs, np.ones((len(conn), idofs.shape[1], idofs.shape[1])))
        self.stiffness = AffineStiffness(tuple(unit_parts) + (pattern,), mesh.n_dofs, T)
        self.n_unit_parts = len(unit_parts)
        n = self.stiffness.n
        # reduced column of every full dof (-1: fixed); T has one unit entry per free row
        col = -np.ones(mesh.n_dofs, np.int64)
        rows = np.repeat(np.arange(mesh.n_dofs), np.diff(T.indptr))
        col[rows] = T.indices
        self.col = np.ascontiguousarray(col[idofs])
        ci = np.repeat(self.col[:, :, None], idofs.shape[1], axis=2)
        cj = np.repeat(self.col[:, None, :], idofs.shape[1], axis=1)
        keys = ci.astype(np.int64) * n + cj
        pos = np.searchsorted(self.stiffness._keys, keys)
        pos[(ci < 0) | (cj < 0)] = -1
        self.positions = np.ascontiguousarray(pos.astype(np.int64))
        # global relative-displacement operator: jumps (n_points, 2) = (Bglob @ q).reshape(-1, 2)
        E, P, _, nl = self.B.shape
        r = np.repeat(np.arange(E * P * 2), nl)
        c = np.repeat(self.col[:, None, None, :], P, axis=1).repeat(2, axis=2).ravel()
        v = self.B.ravel()
        keep = (c >= 0) & (v != 0)
        self.jump_operator = sp.csr_matrix((v[keep], (r[keep], c[keep])), shape=(E * P * 2, n))
        self.sensors = tuple(sensors)
        H, self.channel_names = sensor_operator(mesh, sensors)
        self.observation = (H @ T).tocsr()
        self.solver = make_general_solver(solver, self.stiffness.indptr, self.stiffness.indices, n)
        self._units_data = None
        self._units_matrix = None

    @property
    def n_dofs(self):
        """Unknowns after elimination of the constraints."""
        return self.stiffness.n

    @property
    def n_points(self):
        """Interface integration points."""
        return self.B.shape[0] * self.B.shape[1]

    def set_units(self, theta_units):
        """Fix the units' elastic coefficients (see :func:`fe.materials.plane_stress_coefficients`)."""
        theta = np.zeros(self.n_unit_parts + 1)
        theta[: self.n_unit_parts] = theta_units
        self._units_data = self.stiffness.values(theta)
        self._units_matrix = sp.csr_matrix((self._units_data, self.stiffness.indices, self.stiffness.indptr),
                                           shape=(self.n_dofs, self.n_dofs))

    def reduce_loads(self, f):
        """Full nodal forces ``(n_dofs_full,)`` N → reduced ``Tᵀ f``."""
        return np.asarray(self.transform.T @ f).ravel()

    def jumps(self, q):
        """Relative displacements ``(n_points, 2)`` (opening, slip) mm at the integration points."""
        return (self.jump_operator @ q).reshape(-1, 2)

    def tangent_and_force(self, q, traction, tangent):
        """Tangent data on the pattern ``(nnz,)`` N/mm and internal force ``(n_reduced,)`` N."""
        data = self._units_data.copy()
        f = self._units_matrix @ q
        _assemble_interfaces(self.B, self.weights, np.ascontiguousarray(tangent), np.ascontiguousarray(traction),
                             self.positions, self.col, data, f)
        return data, f

    def readings(self, q):
        """Sensor readings ``(n_channels,)`` mm."""
        return np.asarray(self.observation @ q).ravel()

    def displacements(self, q):
        """Nodal displacements ``(n_nodes, 2)`` mm."""
        return np.asarray(self.transform @ q).reshape(-1, 2)

    def point_coordinates(self):
        """Coordinates ``(n_points, 2)`` mm of the interface integration points (face A)."""
        iface = IL6 if self.mesh.element == "Q8" else IL4
        s, _ = iface.integration_points(self.integration)
        N = iface.shape(s)
        conn = self.mesh.interfaces[self.interface_elements][:, : iface.nodes_per_face]
        return np.einsum("pf,efj->epj", N, self.mesh.nodes[conn]).reshape(-1, 2)

    def point_nodes(self):
        """The face-A node of every integration point ``(n_points,)``: the node it sits on (Lobatto)
        or the nearest one (Gauss)."""
        iface = IL6 if self.mesh.element == "Q8" else IL4
        s, _ = iface.integration_points(self.integration)
        local = np.argmax(iface.shape(s), axis=1)  # (p,) face node of each point
        conn = self.mesh.interfaces[self.interface_elements][:, : iface.nodes_per_face]
        return conn[:, local].ravel()

    def column_positions(self, dof):
        """Rows and pattern positions of the entries of column ``dof`` (``K[:, dof] = data[pos]``)."""
        rows = np.repeat(np.arange(self.n_dofs), np.diff(self.stiffness.indptr))
        pos = np.flatnonzero(self.stiffness.indices == dof)
        return rows[pos], pos

    def row_positions(self, dofs):
        """Positions in the pattern data of the rows and columns of reduced ``dofs`` and of their
        diagonal entries (to hold those dofs: zero row and column, unit diagonal)."""
        dofs = np.asarray(dofs, dtype=np.int64)
        n = self.n_dofs
        rows = np.repeat(np.arange(n), np.diff(self.stiffness.indptr))
        cols = self.stiffness.indices
        mask = np.isin(rows, dofs) | np.isin(cols, dofs)
        diag = np.searchsorted(self.stiffness._keys, dofs * n + dofs)
        return np.flatnonzero(mask), diag

