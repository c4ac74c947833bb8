"""Symmetric positive-definite sparse solvers on a fixed CSR pattern.

The pattern (symbolic structure) is analysed once per mesh; each new parameter vector only
refactorises numerically. Backends:

- ``"pardiso"``: MKL PARDISO (via ``pypardiso``'s library loader) as a real SPD matrix
  (mtype 2, upper triangle): symbolic analysis once (phase 11), numerical factorisation per
  matrix (phase 22), solves (phase 33).
- ``"superlu"``: SciPy SuperLU with the symmetric MMD_AT_PLUS_A ordering, always available.

``make_solver("auto", ...)`` takes PARDISO when it is installed.

:func:`make_general_solver` gives the same two backends for general (non-symmetric) matrices on
a structurally symmetric pattern, e.g. the consistent tangent of non-associated interfaces:
PARDISO as real non-symmetric (mtype 11, full matrix, analysis once) or SuperLU with partial
pivoting.
"""

import logging
import os

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..exceptions import SolverError

logger = logging.getLogger(__name__)

_SINGULAR_HINT = (
    "the stiffness matrix is singular or not positive definite: check that the supports "
    "prevent rigid-body motion and that no stiffness parameter is zero"
)


def _pardiso_solver(mtype):
    """A new ``pypardiso.PyPardisoSolver(mtype=mtype)``.

    pypardiso looks for MKL's runtime library at every construction (``find_library``, then a
    recursive glob of the Python environment: 0.12 s of CPU and 0.25 s wall per FE model, more than
    a coarse FE run). The first construction finds it; its path is handed to the later ones through
    ``PYPARDISO_MKL_RT``, pypardiso's own setting for it (unless the user has set it).
    """
    import pypardiso

    solver = pypardiso.PyPardisoSolver(mtype=mtype)
    os.environ.setdefault("PYPARDISO_MKL_RT", solver.libmkl._name)
    return solver


def available_backends():
    """Names of the solver backends usable on this machine."""
    names = ["superlu"]
    try:
        import pypardiso  # noqa: F401

        names.insert(0, "pardiso")
    except Exception:  # pragma: no cover - depends on the platform (MKL is x86-only)
        pass
    return names


def make_solver(backend, indptr, indices, n):
    """A solver for SPD matrices with the given CSR pattern (full, both triangles).

    Parameters
    ----------
    backend : {"auto", "pardiso", "superlu"}
    indptr, indices : ndarray
        CSR pattern of the full symmetric matrix, sorted indices.
    n : int
        Matrix size.
    """
    if backend == "auto":
        backend = available_backends()[0]
    if backend == "pardiso":
        return PardisoSolver(indptr, indices, n)
    if backend == "superlu":
        return SuperLUSolver(indptr, indices, n)
    raise ValueError(f"unknown solver backend {backend!r}; available: {available_backends()}")


class SuperLUSolver:
    """SuperLU on the full matrix with a symmetric fill-reducing ordering."""

    name = "superlu"

    def __init__(self, indptr, indices, n):
        self.indptr, self.indices, self.n = indptr, indices, n
        self._lu = None

    def factorize(self, data):
        """Factorise the matrix with values ``data`` (aligned with the CSR pattern)."""
        K = sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))
        try:
            self._lu = spla.splu(
                K.tocsc(),
                permc_spec="MMD_AT_PLUS_A",
                options=dict(SymmetricMode=True),
                diag_pivot_thresh=0.0,
            )
        except RuntimeError as e:
            raise SolverError(_SINGULAR_HINT) from e

    def solve(self, rhs):
        """Solve for ``rhs`` of shape ``(n,)`` or ``(n, k)``."""
        x = self._lu.solve(np.asarray(rhs, dtype=float))
        if not np.all(np.isfinite(x)):
            raise SolverError(_SINGULAR_HINT)
        return x


class PardisoSolver:
    """MKL PARDISO for real SPD matrices; the symbolic analysis is done once per pattern.

    PARDISO runs on ``threads`` MKL threads of its own (thread-local, whatever the process-wide
    MKL setting): one by default below 200 000 unknowns, where threads only add overhead (default
    diagonal test, 9 360 dofs: 12.6 ms per parameter vector on one thread against 17.1 ms on two;
    73 000 dofs: 162 against 168 ms). A fixed count also keeps the analysis and the factorisations
    consistent: PARDISO crashes when they run with different thread counts.
    """

    name = "pardiso"

    def __init__(self, indptr, indices, n, threads=None):
        import ctypes

        rows = np.repeat(np.arange(n), np.diff(indptr))
        upper = indices >= rows
        self._upper = np.flatnonzero(upper)  # positions of the upper triangle in the full data
        counts = np.bincount(rows[upper], minlength=n)
        self._indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self._indices = indices[upper].astype(np.int64)
        self.n = n
        self._solver = _pardiso_solver(mtype=2)
        iparm = self._solver.iparm  # 0-based here; MKL documents them 1-based
        iparm[0] = 1  # use the values below instead of all defaults
        iparm[1] = 2  # METIS nested-dissection ordering
        iparm[7] = 0  # no iterative refinement: SPD, direct solve to round-off
        iparm[9] = 8  # pivot perturbation 1e-8 (MKL default for symmetric matrices)
        iparm[17] = -1  # report the number of non-zeros in the factor (iparm[17] after phase 11)
        self.threads = int(threads if threads is not None else (1 if n < 200_000 else 0))  # 0: MKL's
        self._set_threads = self._solver.libmkl.MKL_Set_Num_Threads_Local  # C API (the lowercase name is Fortran)
        self._set_threads.argtypes = [ctypes.c_int]
        self._set_threads.restype = ctypes.c_int
        self._analysed = False
        self._matrix = None

    def _call(self, phase, rhs):
        self._solver.set_phase(phase)
        previous = self._set_threads(self.threads)
        try:
            return self._solver._call_pardiso(self._matrix, rhs)
        except Exception as e:  # pypardiso raises PyPardisoError with MKL's error code
            raise SolverError(f"{_SINGULAR_HINT} (PARDISO: {e})") from e
        finally:
            self._set_threads(previous)

    def factorize(self, data):
        """Factorise the matrix with values ``data`` (aligned with the full CSR pattern)."""
        self._matrix = sp.csr_matrix(
            (np.ascontiguousarray(data[self._upper]), self._indices, self._indptr),
            shape=(self.n, self.n),
        )
        dummy = np.zeros((self.n, 1), order="F")
        if not self._analysed:
            self._call(11, dummy)
            self._analysed = True
        self._call(22, dummy)

    def solve(self, rhs):
        """Solve for ``rhs`` of shape ``(n,)`` or ``(n, k)``."""
        rhs = np.asarray(rhs, dtype=float)
        x = self._call(33, np.asfortranarray(rhs))
        if not np.all(np.isfinite(x)):
            raise SolverError(_SINGULAR_HINT)
        return x


def make_general_solver(backend, indptr, indices, n):
    """A solver for general (non-symmetric, possibly indefinite) matrices with the given CSR pattern.

    Parameters as :func:`make_solver`; the pattern must hold both triangles (it is analysed once).
    """
    if backend == "auto":
        backend = available_backends()[0]
    if backend == "pardiso":
        return GeneralPardisoSolver(indptr, indices, n)
    if backend == "superlu":
        return GeneralSuperLUSolver(indptr, indices, n)
    raise ValueError(f"unknown solver backend {backend!r}; available: {available_backends()}")


_GENERAL_HINT = (
    "the tangent stiffness is singular: the structure lost its last load path (a fully cracked "
    "section) or a support is missing"
)


class GeneralSuperLUSolver:
    """SuperLU with threshold partial pivoting for general matrices."""

    name = "superlu"

    def __init__(self, indptr, indices, n):
        self.indptr, self.indices, self.n = indptr, indices, n
        self._lu = None

    def factorize(self, data):
        K = sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))
        try:
            self._lu = spla.splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.1)
        except RuntimeError as e:
            raise SolverError(_GENERAL_HINT) from e

    def solve(self, rhs):
        x = self._lu.solve(np.asarray(rhs, dtype=float))
        if not np.all(np.isfinite(x)):
            raise SolverError(_GENERAL_HINT)
        return x


class GeneralPardisoSolver:
    """MKL PARDISO for real non-symmetric matrices (mtype 11) on a fixed full CSR pattern.

    Symbolic analysis (phase 11) once; numerical factorisation (22) per matrix; solves (33), with
    two steps of iterative refinement only when pivots were perturbed (MKL's automatic mode). Weighted matching and scaling are off: they are computed
    from the values at analysis time, which change during a Newton iteration; pivots are perturbed
    by 1e-13 instead (MKL's default for non-symmetric matrices). One MKL thread, as
    :class:`PardisoSolver`.
    """

    name = "pardiso"

    def __init__(self, indptr, indices, n, threads=1):
        import ctypes

        self._indptr = np.asarray(indptr, dtype=np.int64)
        self._indices = np.asarray(indices, dtype=np.int64)
        self.n = n
        self._solver = _pardiso_solver(mtype=11)
        iparm = self._solver.iparm  # 0-based here; MKL documents them 1-based
        iparm[0] = 1  # use the values below
        iparm[1] = 2  # METIS ordering
        iparm[7] = 0  # iterative refinement only when pivots were perturbed (two steps then)
        iparm[9] = 13  # pivot perturbation 1e-13
        iparm[10] = 0  # no scaling
        iparm[11] = 0  # solve A x = b with A in CSR
        iparm[12] = 0  # no weighted matching
        self.threads = int(threads)
        self._set_threads = self._solver.libmkl.MKL_Set_Num_Threads_Local
        self._set_threads.argtypes = [ctypes.c_int]
        self._set_threads.restype = ctypes.c_int
        self._analysed = False
        self._matrix = None

    def _call(self, phase, rhs):
        self._solver.set_phase(phase)
        previous = self._set_threads(self.threads)
        try:
            return self._solver._call_pardiso(self._matrix, rhs)
        except Exception as e:
            raise SolverError(f"{_GENERAL_HINT} (PARDISO: {e})") from e
        finally:
            self._set_threads(previous)

    def factorize(self, data):
        self._matrix = sp.csr_matrix((np.ascontiguousarray(data, dtype=float), self._indices, self._indptr),
                                     shape=(self.n, self.n))
        dummy = np.zeros((self.n, 1), order="F")
        if not self._analysed:
            self._call(11, dummy)
            self._analysed = True
        self._call(22, dummy)

    def solve(self, rhs):
        x = self._call(33, np.asfortranarray(np.asarray(rhs, dtype=float)))
        if not np.all(np.isfinite(x)):
            raise SolverError(_GENERAL_HINT)
        return x
