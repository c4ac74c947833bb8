"""Optimal-design criteria for sensor layouts: D, A, E on the Fisher information, and the POD one.

Notation. A layout ``S`` is a set of candidate sensors; each candidate ``c`` has channels (one for a
gauge, two for a DIC point) read at every load level ``l``. With independent Gaussian noise of
standard deviation ``σ_{c}`` (per sensor kind, mm) and the sensitivities ``J`` of the readings with
respect to the unit coordinates ``u`` of the free parameters (:mod:`podkrig.sensors.sensitivity`;
log-scaled parameters in log10), the Fisher information of the layout at a parameter point ``m`` is
additive over sensors:

.. math::

    \\mathbf F_S(\\mathbf m) = \\mathbf J_S^T \\mathbf C_d^{-1} \\mathbf J_S
      = \\sum_{c \\in S} \\mathbf F_c(\\mathbf m), \\qquad
    \\mathbf F_c = \\sum_{l} \\sum_{i \\in c} \\frac{\\mathbf j_{l i} \\mathbf j_{l i}^T}{σ_{c}^2} ,

where ``j_{li}`` is the row of ``J`` for channel ``i`` at load ``l``. The prior box enters as a
Gaussian prior information ``F_0 = (1/s_0^2) I`` in unit coordinates (the project's choice; the
default ``s_0^2 = 1/12`` is the variance of a uniform prior over the box, so a parameter the layout
cannot see has the box's spread rather than an infinite one — Bayesian optimal design, Chaloner &
Verdinelli 1995 [1]_). Every criterion is averaged over a Sobol' set of points ``m_1..m_N`` of the
box (the information depends on where the truth lies):

- D-optimal: :math:`Ψ_D(S) = \\frac1N \\sum_n \\log\\det(\\mathbf F_S(\\mathbf m_n) + \\mathbf F_0)` (maximise;
  the log volume of the confidence ellipsoid, up to sign and a constant);
- A-optimal: :math:`Ψ_A(S) = \\frac1N \\sum_n \\operatorname{tr}(\\mathbf F_S + \\mathbf F_0)^{-1}`
  (minimise; the sum of the parameters' linearised variances, unit coordinates²);
- E-optimal: :math:`Ψ_E(S) = \\frac1N \\sum_n λ_{\\min}(\\mathbf F_S + \\mathbf F_0)` (maximise; the
  worst-determined direction);
- POD (the thesis' criterion, ch. 5; its exact formula is not at hand, so this is the project's
  named choice): the whitened candidate readings over the Sobol' set,
  :math:`\\tilde y = \\mathbf C_d^{-1/2} y`, are reduced by POD, :math:`\\tilde y ≈ \\bar y +
  \\sum_{k\\le K} a_k \\boldsymbol φ_k` with modal amplitudes normalised to unit variance over the box
  (:math:`\\boldsymbol φ_k` scaled by :math:`s_k/\\sqrt{N}`, ``s_k`` the singular values). Reading the
  layout's channels with unit whitened noise gives the information :math:`\\mathbf G_S = \\sum_{c\\in S}
  \\boldsymbol Φ_c \\boldsymbol Φ_c^T` on the amplitudes (``Φ_c`` the rows of the modes at the channels of
  ``c``), and :math:`Ψ_{POD}(S) = \\log\\det(\\mathbf G_S + \\mathbf I)` (maximise) — twice the expected
  information gain on the first ``K`` modes (``K = n_params`` by default). It needs no parameter
  derivatives, only snapshots, so it works on any surrogate or FE output.

Every criterion is evaluated for a whole batch of layouts at once (``(n_layouts, k)`` candidate
indices; ``-1`` marks an empty slot, used by budget-constrained searches).

References
----------
.. [1] K. Chaloner, I. Verdinelli, "Bayesian experimental design: a review", Statistical Science
   10(3) (1995) 273–304.
.. [2] C. Chisari et al., "Optimal sensor placement for structural parameter identification",
   Struct. Multidisc. Optim. 55 (2017) 647–662, doi:10.1007/s00158-016-1531-1; the thesis, ch. 5.
"""

from dataclasses import dataclass
from typing import Annotated

import numpy as np
import scipy.sparse as sp
from pydantic import AfterValidator

from podkrig.config import allowed, finite, settings
from podkrig.online.measurement import DELTA_RANGE, SIGMA_RANGE_MM

CRITERIA = ("d", "a", "e", "pod")
UNIFORM_PRIOR_INFORMATION = 12.0  # 1 / variance of U(0, 1): the box as a Gaussian prior, unit coords


_SIGMA = Annotated[float, AfterValidator(finite),
                   allowed(f"σ in [{SIGMA_RANGE_MM[0]:g}, {SIGMA_RANGE_MM[1]:g}] mm", unit="mm", ge=SIGMA_RANGE_MM[0],
                           le=SIGMA_RANGE_MM[1])]


@settings
class SensorNoise:
    """Noise per sensor kind: absolute σ (mm) for LVDTs/gauges and for DIC points, or a relative level.

    σ and δ take the ranges of a measurement's noise model
    (:data:`~podkrig.online.measurement.SIGMA_RANGE_MM`, :data:`~podkrig.online.measurement.DELTA_RANGE`).

    Parameters
    ----------
    lvdt : float
        σ of a gauge reading, mm (e.g. 0.002 for 2 µm).
    dic : float
        σ of each DIC displacement component, mm.
    relative : float or None
        If given, σ = max(relative × |reading|, floor) per reading (overrides the absolute values).
    floor : float
        Smallest σ of the relative model, mm (a numerical floor: any number > 0).
    """

    lvdt: _SIGMA = 0.002
    dic: _SIGMA = 0.005
    relative: Annotated[float, AfterValidator(finite),
                        allowed(f"δ in [{DELTA_RANGE[0]:g}, {DELTA_RANGE[1]:g})", unit="-", ge=DELTA_RANGE[0],
                                lt=DELTA_RANGE[1])] | None = None
    floor: Annotated[float, AfterValidator(finite), allowed("a number > 0 mm", unit="mm", gt=0)] = 1e-4

    def sigma(self, kind):
        """Absolute σ of a sensor kind, mm."""
        return {"lvdt": self.lvdt, "dic": self.dic}[kind]

    def std(self, sens):
        """σ of every reading of :class:`Sensitivities` ``sens``, ``(n_points, n_loads, n_channels)`` mm."""
        per_channel = np.array([self.sigma(sens.candidates.kinds[c]) for c in sens.channel_sensor])
        if self.relative is None:
            return np.broadcast_to(per_channel, sens.readings.shape)
        return np.maximum(self.relative * np.abs(sens.readings), self.floor)

    def to_dict(self):
        return {"lvdt_mm": self.lvdt, "dic_mm": self.dic, "relative": self.relative, "floor_mm": self.floor}


def _incidence(channel_sensor, n_candidates):
    """Sparse ``(n_candidates, n_channels)`` matrix summing channels into their candidate."""
    n = len(channel_sensor)
    return sp.csr_matrix((np.ones(n), (channel_sensor, np.arange(n))), shape=(n_candidates, n))


def fisher_per_candidate(sens, noise):
    """Fisher information of each candidate alone, ``F_c``, ``(n_points, n_candidates, p, p)``
    (unit coordinates⁻², see the module docstring)."""
    Jw = sens.jacobian / noise.std(sens)[..., None]  # (n, l, ch, p)
    outer = np.einsum("nlcj,nlck->ncjk", Jw, Jw)  # sum over load levels
    n, n_ch, p, _ = outer.shape
    A = _incidence(sens.channel_sensor, len(sens.candidates))
    per_cand = (A @ outer.transpose(1, 0, 2, 3).reshape(n_ch, -1)).reshape(-1, n, p, p)
    return np.ascontiguousarray(per_cand.transpose(1, 0, 2, 3))


def pod_per_candidate(sens, noise, n_modes=None):
    """Information on the normalised POD amplitudes from each candidate alone, ``G_c``,
    ``(1, n_candidates, K, K)``, and the retained energy fraction of the ``K`` modes."""
    n, n_l, n_ch = sens.readings.shape
    K = sens.n_params if n_modes is None else int(n_modes)
    if not 1 <= K <= min(n - 1, n_l * n_ch):
        raise ValueError(f"n_modes must be in [1, {min(n - 1, n_l * n_ch)}]; got {K}")
    Y = (sens.readings / noise.std(sens)).reshape(n, -1)
    Y = Y - Y.mean(axis=0)
    _, s, Vt = np.linalg.svd(Y, full_matrices=False)
    modes = Vt[:K] * (s[:K, None] / np.sqrt(n))  # (K, n_l * n_ch): amplitude std 1 ↔ these rows
    per_obs = np.einsum("ki,mi->ikm", modes, modes).reshape(n_l, n_ch, K, K).sum(axis=0)  # (ch, K, K)
    A = _incidence(sens.channel_sensor, len(sens.candidates))
    G = (A @ per_obs.reshape(n_ch, -1)).reshape(1, -1, K, K)
    energy = float(np.sum(s[:K] ** 2) / np.sum(s**2))
    return G, energy


class LayoutCriterion:
    """A criterion over layouts from additive per-candidate information matrices.

    Parameters
    ----------
    info : ndarray of shape (n_points, n_candidates, m, m)
        Per-candidate information (:func:`fisher_per_candidate` or :func:`pod_per_candidate`).
    kind : {"d", "a", "e", "pod"}
        ``"pod"`` is the D-criterion on POD information with a unit prior.
    prior_information : float
        ``1/s_0²`` of the prior information ``F_0 = I / s_0²`` (unit coordinates⁻²).

    Notes
    -----
    :meth:`loss` is what searches minimise (``-Ψ_D``, ``Ψ_A``, ``-Ψ_E``, ``-Ψ_POD``);
    :meth:`value` is the criterion itself.
    """

    def __init__(self, info, kind="d", prior_information=UNIFORM_PRIOR_INFORMATION):
        if kind not in CRITERIA:
            raise ValueError(f"criterion must be one of {CRITERIA}; got {kind!r}")
        if not prior_information > 0:
            raise ValueError(f"prior_information must be > 0; got {prior_information}")
        n, n_c, m, _ = info.shape
        # a zero matrix at index n_candidates: the empty slot (-1) of budget searches
        self.info = np.concatenate([info, np.zeros((n, 1, m, m))], axis=1)
        self.kind = kind
        self.prior = prior_information * np.eye(m)
        self.n_candidates = n_c
        self.sign = -1.0 if kind in ("d", "e", "pod") else 1.0

    @property
    def name(self):
        return {"d": "D-optimal", "a": "A-optimal", "e": "E-optimal", "pod": "POD (D on modal amplitudes)"}[self.kind]

    @property
    def unit(self):
        return {"d": "log det (unit coords⁻²)", "a": "Σ variance (unit coords²)", "e": "λ_min (unit coords⁻²)",
                "pod": "log det (-)"}[self.kind]

    def layout_information(self, layouts):
        """``F_S + F_0`` for a batch of layouts ``(n_layouts, k)``: ``(n_layouts, n_points, m, m)``."""
        L = np.atleast_2d(np.asarray(layouts, dtype=np.intp))
        L = np.where(L < 0, self.n_candidates, L)
        return self.info[:, L].sum(axis=2).transpose(1, 0, 2, 3) + self.prior

    def _values_of(self, F):
        if self.kind in ("d", "pod"):
            return np.linalg.slogdet(F)[1].mean(axis=-1)
        if self.kind == "a":
            return np.trace(np.linalg.inv(F), axis1=-2, axis2=-1).mean(axis=-1)
        return np.linalg.eigvalsh(F)[..., 0].mean(axis=-1)

    def value(self, layouts, chunk=2048):
        """Ψ(S) for each layout, ``(n_layouts,)``."""
        L = np.atleast_2d(np.asarray(layouts, dtype=np.intp))
        return np.concatenate([self._values_of(self.layout_information(L[i:i + chunk]))
                               for i in range(0, len(L), chunk)]) if len(L) else np.empty(0)

    def loss(self, layouts):
        """``sign × Ψ``: lower is better, ``(n_layouts,)``."""
        return self.sign * self.value(layouts)

    def linearised_widths(self, layouts):
        """Linearised 95 % interval width of each parameter, unit coordinates, mean over the points:
        ``2 × 1.96 × sqrt(diag (F_S + F_0)⁻¹)``, ``(n_layouts, m)`` (Fisher criteria only)."""
        F = self.layout_information(layouts)
        var = np.diagonal(np.linalg.inv(F), axis1=-2, axis2=-1)
        return (3.92 * np.sqrt(var)).mean(axis=1)

    def contributions(self, layout):
        """Each sensor's contribution: the loss increase when it alone is removed, ``(k,)``
        (criterion units; larger = more important)."""
        layout = np.asarray(layout, dtype=np.intp)
        k = len(layout)
        drops = np.array([np.delete(layout, i) for i in range(k)]) if k > 1 else np.full((1, 1), -1)
        return self.loss(drops) - self.loss(layout[None])[0]
