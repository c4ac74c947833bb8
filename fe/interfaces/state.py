"""State of the integration points of nonlinear interfaces and the result of a law update.

Conventions (those of Lourenço & Rots 1997, ``docs/references.md``): the relative displacement
``u = (u_n, u_s)`` (opening, slip; mm) and the traction ``t = (σ, τ)`` (MPa) are **normal
first**, positive in tension/opening; ``t = D (u − u^p)`` with ``D = diag(k_n, k_s)`` (N/mm³).
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class InterfaceState:
    """History of ``n`` interface integration points at a converged step.

    Attributes
    ----------
    jump : ndarray of shape (n, 2)
        Relative displacement ``(u_n, u_s)``, mm.
    traction : ndarray of shape (n, 2)
        ``(σ, τ)``, MPa.
    plastic : ndarray of shape (n, 2)
        Plastic relative displacement ``u^p``, mm.
    kappa : ndarray of shape (n, 3)
        Internal variables κ1 (mode I, mm), κ2 (mode II, mm), κ3 (cap, mm).
    work : ndarray of shape (n,)
        Plastic work per unit interface area ``∫ t · du^p``, N/mm (mid-point rule per step).
    """

    jump: np.ndarray
    traction: np.ndarray
    plastic: np.ndarray
    kappa: np.ndarray
    work: np.ndarray

    @classmethod
    def zeros(cls, n):
        """The virgin state of ``n`` points (no pre-stress)."""
        return cls(np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 3)), np.zeros(n))

    def __len__(self):
        return len(self.work)

    def take(self, index):
        """The state of a subset of points."""
        return InterfaceState(self.jump[index], self.traction[index], self.plastic[index],
                              self.kappa[index], self.work[index])


@dataclass(frozen=True, eq=False)
class LawUpdate:
    """Result of one constitutive update of all integration points.

    Attributes
    ----------
    state : InterfaceState
        The end-of-step state (accepted by the caller only when the global step converges).
    tangent : ndarray of shape (n, 2, 2)
        Consistent (algorithmic) tangent ``∂t/∂u``, N/mm³; non-symmetric in general.
    iterations : ndarray of shape (n,) int
        Local Newton iterations of the accepted active set (0 when elastic; summed over
        sub-steps; rejected active sets are not counted).
    status : ndarray of shape (n,) int
        0: converged in one step; 1: converged with sub-stepping (tangent of the last sub-step);
        2: no consistent return found (the caller must cut the global step).
    """

    state: InterfaceState
    tangent: np.ndarray
    iterations: np.ndarray
    status: np.ndarray

    @property
    def failed(self):
        """Number of points without a consistent return."""
        return int(np.count_nonzero(self.status == 2))
