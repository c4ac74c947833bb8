"""Assembly of batched element matrices into sparse matrices on a pattern built once per mesh.

The linear mesoscale model's stiffness is affine in the parameters,

.. math:: \\mathbf K(\\mathbf m) = \\sum_q θ_q(\\mathbf m)\\, \\mathbf K_q ,

with parameter-independent parts ``K_q`` (units' two plane-stress parts, the normal and shear
parts of each interface family). :class:`AffineStiffness` stores every part, already reduced to
the constrained subspace, as one row of a dense ``(n_parts, nnz)`` array aligned with a shared
CSR pattern, so a new parameter vector costs one small matrix–vector product (``θ @ data``)
before the factorisation.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


def element_dofs(connectivity):
    """Global dofs of each element, ``(n_elements, 2*n_nodes)``, ordered node-major (x, y)."""
    conn = np.asarray(connectivity)
    dofs = np.empty((conn.shape[0], 2 * conn.shape[1]), np.intp)
    dofs[:, 0::2] = 2 * conn
    dofs[:, 1::2] = 2 * conn + 1
    return dofs


def assemble_matrix(dofs, matrices, n_dofs):
    """Sum batched element matrices into a CSR matrix.

    Parameters
    ----------
    dofs : ndarray of shape (n_elements, n_local)
    matrices : ndarray of shape (n_elements, n_local, n_local)
    n_dofs : int

    Returns
    -------
    scipy.sparse.csr_matrix of shape (n_dofs, n_dofs)
    """
    n_local = dofs.shape[1]
    rows = np.repeat(dofs, n_local, axis=1).ravel()
    cols = np.tile(dofs, (1, n_local)).ravel()
    K = sp.coo_matrix((matrices.ravel(), (rows, cols)), shape=(n_dofs, n_dofs)).tocsr()
    K.sum_duplicates()
    return K


@dataclass(frozen=True)
class StiffnessPart:
    """One parameter-independent stiffness part ``K_q``.

    Attributes
    ----------
    name : str
        E.g. ``"units_D0"``, ``"bed_normal"``.
    dofs : ndarray of shape (n_elements, n_local)
    matrices : ndarray of shape (n_elements, n_local, n_local)
        Element matrices for a unit coefficient θ_q = 1, N/mm.
    """

    name: str
    dofs: np.ndarray
    matrices: np.ndarray


@dataclass(frozen=True)
class StiffnessIncrement:
    """A sparse addition to an :class:`AffineStiffness` matrix on its pattern.

    Attributes
    ----------
    name : str
    positions : ndarray of shape (m,)
        Indices into the pattern's data (unique).
    values : ndarray of shape (m,)
        Reduced matrix entries for a unit coefficient, N/mm.
    """

    name: str
    positions: np.ndarray
    values: np.ndarray


def _csr_keys(K):
    """Row-major linear keys ``row * n + col`` of a sorted CSR matrix's entries."""
    n = K.shape[1]
    return np.repeat(np.arange(K.shape[0], dtype=np.int64), np.diff(K.indptr)) * n + K.indices


class AffineStiffness:
    """``K(θ) = Σ θ_q K_q``, reduced by ``u = T q`` (``K_red = Tᵀ K T``), on one CSR pattern.

    Parameters
    ----------
    parts : sequence of StiffnessPart
    n_dofs : int
        Number of unconstrained dofs.
    transform : scipy.sparse matrix of shape (n_dofs, n_reduced)
        Constraint transformation (columns of the identity for Dirichlet-only elimination).

    Attributes
    ----------
    names : tuple of str
    indptr, indices : ndarray
        CSR pattern of the reduced matrix (sorted, both triangles).
    data : ndarray of shape (n_parts, nnz)
        Values of each reduced part on the pattern.
    """

    def __init__(self, parts, n_dofs, transform):
        self.names = tuple(p.name for p in parts)
        T = sp.csr_matrix(transform)
        self._transform, self._n_full = T, n_dofs
        reduced = [(T.T @ assemble_matrix(p.dofs, p.matrices, n_dofs) @ T).tocsr() for p in parts]
        union = sum(abs(K) for K in reduced).tocsr()
        union.sum_duplicates()
        union.sort_indices()
        n = union.shape[0]
        self.n = n
        self.indptr, self.indices = union.indptr, union.indices
        self._keys = union_keys = _csr_keys(union)
        self.data = np.zeros((len(parts), union.nnz))
        for q, K in enumerate(reduced):
            K.sort_indices()
            self.data[q, np.searchsorted(union_keys, _csr_keys(K))] = K.data

    def increment(self, part):
        """A sparse increment of the matrix by ``part`` (whose entries must lie on the pattern,
        e.g. a subset of the elements of one of the parts).

        Returns
        -------
        StiffnessIncrement
            Positions in the pattern's data and the reduced values there (N/mm per unit coefficient).
        """
        T = self._transform
        K = (T.T @ assemble_matrix(part.dofs, part.matrices, self._n_full) @ T).tocsr()
        K.sum_duplicates()
        K.sort_indices()
        keys = _csr_keys(K)
        pos = np.searchsorted(self._keys, keys)
        if np.any(pos >= len(self._keys)) or np.any(self._keys[np.minimum(pos, len(self._keys) - 1)] != keys):
            raise ValueError(f"part {part.name!r} has entries outside the stiffness pattern")
        return StiffnessIncrement(part.name, pos, K.data.copy())

    def values(self, theta, increments=()):
        """Values of ``K_red(θ)`` on the pattern, ``(nnz,)``; ``theta`` is ``(n_parts,)``.

        ``increments`` is a sequence of ``(coefficient, StiffnessIncrement)`` added on top.
        """
        values = np.asarray(theta, dtype=float) @ self.data
        for coefficient, inc in increments:
            values[inc.positions] += coefficient * inc.values
        return values

    def matrix(self, theta):
        """``K_red(θ)`` as a CSR matrix."""
        return sp.csr_matrix((self.values(theta), self.indices, self.indptr), shape=(self.n, self.n))
