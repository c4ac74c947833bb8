"""Kinematic constraints by elimination: ``u = T q`` with ``T`` sparse ``(n_dofs, n_reduced)``.

Supports (homogeneous Dirichlet conditions) drop dofs; ties make a group of dofs follow one
master dof (e.g. a rigid loading beam that keeps the top edge of a wall horizontal).
"""

import numpy as np
import scipy.sparse as sp

from .exceptions import FEError


def constraint_transform(n_dofs, fixed=(), ties=()):
    """Build the elimination transform.

    Parameters
    ----------
    n_dofs : int
    fixed : array_like of int
        Dofs held at zero displacement.
    ties : sequence of array_like of int
        Each group of dofs moves together: ``u[g] = u[g[0]]`` (the first is the master).

    Returns
    -------
    T : scipy.sparse.csr_matrix of shape (n_dofs, n_reduced)
        ``u = T @ q``; each column is a free dof or a tie group.
    """
    fixed = np.unique(np.asarray(fixed, dtype=np.intp))
    owner = np.arange(n_dofs)
    for group in ties:
        group = np.asarray(group, dtype=np.intp)
        if np.isin(group, fixed).any():
            raise FEError("a tied dof is also fixed: remove it from the tie or from the supports")
        owner[group] = group[0]
    is_free = np.ones(n_dofs, bool)
    is_free[fixed] = False
    masters = np.flatnonzero(is_free & (owner == np.arange(n_dofs)))
    column = -np.ones(n_dofs, np.intp)
    column[masters] = np.arange(len(masters))
    rows = np.flatnonzero(is_free)
    cols = column[owner[rows]]
    return sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_dofs, len(masters)))
