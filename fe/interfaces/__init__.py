"""Nonlinear constitutive laws of zero-thickness interfaces behind one API.

A law holds per-point properties and maps a relative-displacement increment ``du`` ``(n, 2)``
(opening, slip; mm) and the converged :class:`InterfaceState` to a :class:`LawUpdate`
(tractions, new state, consistent tangent), vectorised over all integration points in numba.

- :class:`CompositeInterface`: Lourenço–Rots tension cut-off + Coulomb friction + cap.
"""

from .composite import CompositeInterface, composite_properties
from .state import InterfaceState, LawUpdate

__all__ = ["CompositeInterface", "composite_properties", "InterfaceState", "LawUpdate"]
