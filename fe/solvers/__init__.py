"""Sparse linear solvers with a fixed sparsity pattern and reusable factorisations."""

from .linear import available_backends, make_solver

__all__ = ["make_solver", "available_backends"]
