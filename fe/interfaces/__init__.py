"""Nonlinear constitutive laws of zero-thickness interfaces behind one API.

A law holds per-point properties and maps a relative-displacement increment ``du`` ``(n, 2)``
(opening, slip; mm) and the converged :class:`InterfaceState` to a :class:`LawUpdate`
(tractions, new state, consistent tangent), vectorised over all integration points in numba.

- :class:`CompositeInterface`: Lourenço–Rots tension cut-off + Coulomb friction + cap.
- :class:`HyperbolicInterface`: the thesis' hyperbolic Mode I/II surface (eq. 2.4) with work
  softening and an optional compressive cap (ellipse or hyperbola).
"""

from .composite import CompositeInterface, composite_properties
from .hyperbolic import HyperbolicInterface, hyperbolic_properties
from .mixed import MixedInterface
from .state import InterfaceState, LawUpdate

__all__ = [
    "CompositeInterface", "HyperbolicInterface", "InterfaceState", "LawUpdate", "MixedInterface",
    "composite_properties", "hyperbolic_properties",
]
