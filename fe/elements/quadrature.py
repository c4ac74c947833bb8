"""One-dimensional quadrature rules on [-1, 1] and their tensor products on the square.

Returns ``(points, weights)`` with ``points`` of shape ``(n,)`` (1D) or ``(n, 2)`` (2D).
"""

import numpy as np


def gauss_legendre(n):
    """Gauss–Legendre rule with ``n`` points on [-1, 1] (exact for degree 2n - 1)."""
    if n < 1:
        raise ValueError(f"number of Gauss points must be >= 1; got {n}")
    return np.polynomial.legendre.leggauss(n)


def gauss_lobatto(n):
    """Gauss–Lobatto rule with ``n`` points on [-1, 1], end points included.

    n = 2 is the trapezoidal rule and n = 3 Simpson's rule: the Newton–Cotes/Lobatto
    integration used for zero-thickness interfaces, which samples the relative
    displacement at the nodes and so avoids spurious traction oscillations.
    """
    if n == 2:
        return np.array([-1.0, 1.0]), np.array([1.0, 1.0])
    if n == 3:
        return np.array([-1.0, 0.0, 1.0]), np.array([1.0, 4.0, 1.0]) / 3.0
    if n < 2:
        raise ValueError(f"a Lobatto rule needs n >= 2 points; got {n}")
    # interior points: roots of P'_{n-1}; weights 2 / (n (n-1) P_{n-1}(x)^2)
    P = np.polynomial.legendre.Legendre.basis(n - 1)
    x = np.concatenate([[-1.0], np.sort(P.deriv().roots().real), [1.0]])
    w = 2.0 / (n * (n - 1) * P(x) ** 2)
    return x, w


def gauss_square(n):
    """Tensor-product Gauss rule on [-1, 1]^2: points ``(n*n, 2)``, weights ``(n*n,)``."""
    x, w = gauss_legendre(n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    return np.column_stack([X.ravel(), Y.ravel()]), np.outer(w, w).ravel()
