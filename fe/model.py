"""The linear static FE model: affine stiffness, constraints by elimination, load patterns, sensors.

A model is built once per mesh (element matrices, sparsity pattern, symbolic factorisation);
each new parameter vector costs one sum of stiffness parts, one numerical factorisation and a
solve for every load pattern (the factorisation is reused across load levels).
"""

import logging

import numpy as np
import scipy.sparse as sp

from .assembly import AffineStiffness
from .sensors import sensor_operator
from .solvers import make_solver

logger = logging.getLogger(__name__)


class LinearModel:
    """A linear static model ``Tᵀ K(θ) T q = Tᵀ f``, ``u = T q``, readings ``H u``.

    Parameters
    ----------
    mesh : Mesh
    parts : sequence of fe.assembly.StiffnessPart
        Parameter-independent stiffness parts; ``θ`` gives one coefficient per part.
    transform : scipy.sparse matrix of shape (n_dofs, n_reduced)
        Constraint transformation (see :func:`fe.constraints.constraint_transform`).
    load_patterns : ndarray of shape (n_dofs, n_patterns)
        Nodal force vectors, N.
    sensors : sequence of sensors (see :mod:`fe.sensors`)
    solver : {"auto", "pardiso", "superlu"}
    """

    def __init__(self, mesh, parts, transform, load_patterns, sensors, solver="auto"):
        self.mesh = mesh
        self.transform = sp.csr_matrix(transform)
        self.stiffness = AffineStiffness(parts, mesh.n_dofs, self.transform)
        self.rhs = np.asarray(self.transform.T @ load_patterns)
        H, self.channel_names = sensor_operator(mesh, sensors)
        self.observation = (H @ self.transform).tocsr()  # readings = observation @ q
        self.solver = make_solver(solver, self.stiffness.indptr, self.stiffness.indices, self.stiffness.n)

    @property
    def n_dofs(self):
        """Number of unknowns after elimination of the constraints."""
        return self.stiffness.n

    def solve(self, theta):
        """Reduced displacements ``q`` for every load pattern, ``(n_reduced, n_patterns)`` mm."""
        self.solver.factorize(self.stiffness.values(theta))
        q = self.solver.solve(self.rhs)
        return q.reshape(self.n_dofs, -1)

    def readings(self, q):
        """Sensor readings ``(n_patterns, n_channels)`` mm from reduced displacements."""
        return np.asarray(self.observation @ q).T

    def displacements(self, q):
        """Nodal displacements ``(n_patterns, n_nodes, 2)`` mm from reduced displacements."""
        u = np.asarray(self.transform @ q).T
        return u.reshape(u.shape[0], -1, 2)
