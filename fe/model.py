"""The linear static FE model: affine stiffness, constraints by elimination, load patterns, sensors.

A model is built once per mesh (element matrices, sparsity pattern, symbolic factorisation);
each new parameter vector costs one sum of stiffness parts, one numerical factorisation and a
solve for every load pattern (the factorisation is reused across load levels).
"""

import logging

import numpy as np
import scipy.sparse as sp

from .assembly import AffineStiffness, StiffnessPart
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
        self.parts = tuple(parts)
        self.transform = sp.csr_matrix(transform)
        self.stiffness = AffineStiffness(parts, mesh.n_dofs, self.transform)
        self.load_patterns = np.asarray(load_patterns, dtype=float)
        self.rhs = self.reduce_loads(self.load_patterns)
        self.sensors = tuple(sensors)
        H, self.channel_names = sensor_operator(mesh, sensors)
        self.observation = (H @ self.transform).tocsr()  # readings = observation @ q
        self.solver = make_solver(solver, self.stiffness.indptr, self.stiffness.indices, self.stiffness.n)

    @property
    def n_dofs(self):
        """Number of unknowns after elimination of the constraints."""
        return self.stiffness.n

    def reduce_loads(self, load_patterns):
        """Nodal force patterns ``(n_dofs_full, n_patterns)`` N → reduced right-hand sides ``Tᵀ f``."""
        return np.asarray(self.transform.T @ load_patterns)

    def part_increment(self, name, elements):
        """The stiffness of some elements of part ``name`` as a :class:`~fe.assembly.StiffnessIncrement`
        (e.g. one joint segment of the ``bed_normal`` part), for :meth:`solve`'s ``increments``."""
        part = next((p for p in self.parts if p.name == name), None)
        if part is None:
            raise KeyError(f"no stiffness part {name!r}; parts are {[p.name for p in self.parts]}")
        elements = np.asarray(elements)
        return self.stiffness.increment(StiffnessPart(name, part.dofs[elements], part.matrices[elements]))

    def solve(self, theta, increments=(), rhs=None):
        """Reduced displacements ``q`` for every load pattern, ``(n_reduced, n_patterns)`` mm.

        Parameters
        ----------
        theta : ndarray of shape (n_parts,)
            Coefficients of the stiffness parts.
        increments : sequence of (float, StiffnessIncrement)
            Extra stiffness ``Σ c_i ΔK_i`` on top of ``K(θ)`` (local modifications such as a weak joint).
        rhs : ndarray of shape (n_reduced, n_patterns), optional
            Reduced loads (:meth:`reduce_loads`); the model's own load patterns by default.
        """
        self.solver.factorize(self.stiffness.values(theta, increments))
        rhs = self.rhs if rhs is None else rhs
        q = self.solver.solve(rhs)
        return q.reshape(self.n_dofs, -1)

    def readings(self, q):
        """Sensor readings ``(n_patterns, n_channels)`` mm from reduced displacements."""
        return np.asarray(self.observation @ q).T

    def displacements(self, q):
        """Nodal displacements ``(n_patterns, n_nodes, 2)`` mm from reduced displacements."""
        u = np.asarray(self.transform @ q).T
        return u.reshape(u.shape[0], -1, 2)
