"""Sparse linear solvers with a fixed sparsity pattern and reusable factorisations, and the
path-following solver of nonlinear models."""

from .linear import available_backends, make_general_solver, make_solver

__all__ = ["make_solver", "make_general_solver", "available_backends"]
