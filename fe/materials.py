"""Elastic constitutive matrices, split into parameter-independent affine parts.

Plane stress (thesis §2, units as expanded continuum elements):

.. math:: \\mathbf D(E, ν) = \\frac{E}{1-ν^2}\\left(\\mathbf D_0 + ν \\mathbf D_1\\right),\\quad
   \\mathbf D_0 = \\begin{bmatrix}1&0&0\\\\0&1&0\\\\0&0&\\tfrac12\\end{bmatrix},\\quad
   \\mathbf D_1 = \\begin{bmatrix}0&1&0\\\\1&0&0\\\\0&0&-\\tfrac12\\end{bmatrix}

so a stiffness matrix is the sum of two parameter-independent parts with coefficients
``E/(1-ν²)`` and ``E ν/(1-ν²)`` (MPa).
"""

import numpy as np

D0 = np.diag([1.0, 1.0, 0.5])
D1 = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -0.5]])


def plane_stress(E, nu):
    """Plane-stress constitutive matrix ``(3, 3)`` in MPa for Young's modulus E (MPa) and ν."""
    return E / (1.0 - nu**2) * (D0 + nu * D1)


def plane_stress_coefficients(E, nu):
    """Coefficients ``(E/(1-ν²), E ν/(1-ν²))`` of the parts ``D0``, ``D1``, MPa."""
    c = E / (1.0 - nu**2)
    return c, c * nu


def interface_stiffness_from_moduli(E_u, E_m, G_u, G_m, h_m):
    """Interface stiffness from unit and mortar moduli, thesis eq. (2.5).

    .. math:: k_N = \\frac{E_u E_m}{h_m (E_u - E_m)}, \\qquad k_V = \\frac{G_u G_m}{h_m (G_u - G_m)}

    Moduli in MPa, joint thickness ``h_m`` in mm; returns ``(kN, kV)`` in N/mm³.
    """
    if not (E_u > E_m > 0 and G_u > G_m > 0 and h_m > 0):
        raise ValueError(
            "eq. (2.5) needs E_u > E_m > 0, G_u > G_m > 0 and h_m > 0; "
            f"got E_u={E_u}, E_m={E_m}, G_u={G_u}, G_m={G_m} MPa, h_m={h_m} mm"
        )
    return E_u * E_m / (h_m * (E_u - E_m)), G_u * G_m / (h_m * (G_u - G_m))
