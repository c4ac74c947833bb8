"""The misfit ω(m) of thesis eq. (2.13), vectorised over a population of parameter vectors.

.. math::

    ω(\\mathbf m) = \\tfrac12\\left[(\\mathbf g(\\mathbf m) - \\mathbf d_{obs})^t \\mathbf C_D^{-1}
    (\\mathbf g(\\mathbf m) - \\mathbf d_{obs}) + (\\mathbf m - \\mathbf m_{prior})^t \\mathbf C_M^{-1}
    (\\mathbf m - \\mathbf m_{prior})\\right], \\qquad \\mathbf C_D = \\mathbf C_d + \\mathbf C_T

(thesis eqs. 2.10, 2.13): the data covariance ``C_d`` of the noise model plus the modelling
covariance ``C_T``, here the surrogate's predictive variance at ``m`` (diagonal), so that
surrogate error widens the fit instead of biasing it; optionally also the model-form error of the
FE model itself, ``diag(e²)`` with ``e`` per reading (``form_error``:
:mod:`podkrig.online.model_error`). The prior term is optional. As an
alternative, ``kind="relative"`` gives the relative least-squares discrepancy of the group's
papers, ½ Σ ((g_i − d_i) / d_i)².

With ``rigid_body`` (:class:`~podkrig.online.rigid_body.RigidBodyModes`) the rigid-body motion of
each group of absolute displacement readings (a DIC grid) is removed from the residual, data and
model alike: ``χ² = (P r)ᵀ (P C_D Pᵀ)⁺ (P r)`` with ``P = I − R (RᵀR)⁻¹ Rᵀ`` per group and load level,
computed as the whitened residual with the whitened rigid modes projected out; the χ² then has
``n_obs − n_removed`` degrees of freedom before the free parameters (:attr:`Misfit.n_removed`).

One :class:`Misfit` serves the GA (a population ``(n, d)`` at a time), a local least-squares
polish (:meth:`Misfit.whitened_residuals`) and MCMC (``-ω`` is the log-posterior up to a constant).
"""

import functools
from dataclasses import dataclass

import numpy as np

from podkrig.online.measurement import ObservationOperator
from podkrig.online.rigid_body import project_out


@dataclass(frozen=True, eq=False)
class Misfit:
    """Noise-weighted misfit of a model against a measurement.

    Parameters
    ----------
    model : callable
        ``model(X) -> (mean, std)`` with ``X`` ``(n, n_params)`` physical parameters and ``mean``,
        ``std`` ``(n, n_outputs)`` mm (``std`` may be None: no modelling error).
    measurement : Measurement
    noise : NoiseModel
    output_indices : ObservationOperator or ndarray of shape (n_obs,)
        How the observed entries follow from the model's flattened output
        (:meth:`Measurement.observation`), or the position of each (an exact-level measurement).
    prior_mean : ndarray of shape (n_params,), optional
    prior_cov : ndarray of shape (n_params, n_params), optional
        Gaussian prior (thesis eq. 2.11), physical units.
    kind : {"gaussian", "relative"}
    model_error : bool
        Add the model's predictive variance ``C_T`` to ``C_d``.
    rigid_body : RigidBodyModes, optional
        Rigid-body motions removed from the residual (module docstring); None: none.
    form_error : ndarray of shape (n_obs,), optional
        Standard deviation of the FE model's model-form (discretisation) error of each observed
        entry, mm: ``diag(form_error²)`` is added to ``C_d`` (thesis eq. 2.10); None: none.
    """

    model: object
    measurement: object
    noise: object
    output_indices: object
    prior_mean: np.ndarray | None = None
    prior_cov: np.ndarray | None = None
    kind: str = "gaussian"
    model_error: bool = True
    rigid_body: object = None
    form_error: np.ndarray | None = None

    def __post_init__(self):
        # checks of the arguments only; the data vector, the observation operator, the covariances
        # and the prior's factor (a dense n_obs x n_obs matrix, its eigenvalues for a full noise
        # covariance) are built on first use (cached properties)
        if self.kind not in ("gaussian", "relative"):
            raise ValueError(f"misfit kind must be 'gaussian' or 'relative'; got {self.kind!r}")
        if (self.prior_mean is None) != (self.prior_cov is None):
            raise ValueError("a Gaussian prior needs both prior_mean and prior_cov")
        n = len(self._d)
        if self.form_error is not None:
            e = np.asarray(self.form_error, dtype=float)
            if e.shape != (n,) or not np.all(np.isfinite(e)) or np.any(e < 0):
                raise ValueError(f"form_error must be {n} finite standard deviations ≥ 0 (mm), one per "
                                 f"observed entry; got shape {e.shape}")
        if self.observation.n_obs != n:
            raise ValueError(f"the observation gives {self.observation.n_obs} entries; the measurement has {n}")
        if self.rigid_body is not None and self.rigid_body.n_obs != n:
            raise ValueError(f"the rigid-body modes are for {self.rigid_body.n_obs} entries; the measurement has {n}")

    @functools.cached_property
    def _d(self):
        """The observed data vector ``d_obs``, ``(n_obs,)`` mm."""
        return self.measurement.data

    @functools.cached_property
    def observation(self):
        """The :class:`ObservationOperator` of ``output_indices``."""
        op = self.output_indices
        return op if isinstance(op, ObservationOperator) else ObservationOperator.from_indices(op)

    @functools.cached_property
    def _identity_indices(self):
        op = self.observation
        return op.exact and bool(np.array_equal(op.indices, np.arange(op.n_obs)))

    @functools.cached_property
    def _noise_cov(self):
        """``C_d`` of the noise model, ``(n_obs, n_obs)`` mm²."""
        return self.noise.covariance_matrix(self.measurement)

    @functools.cached_property
    def _Cd(self):
        """``C_d`` plus ``diag(form_error²)``, ``(n_obs, n_obs)`` mm²."""
        if self.form_error is None:
            return self._noise_cov
        return self._noise_cov + np.diag(np.asarray(self.form_error, dtype=float) ** 2)

    @functools.cached_property
    def _noise_sd(self):
        return np.sqrt(np.diag(self._noise_cov))

    @functools.cached_property
    def _sd(self):
        return np.sqrt(np.diag(self._Cd))

    @functools.cached_property
    def _prior_chol(self):
        return np.linalg.cholesky(np.asarray(self.prior_cov, float))

    @property
    def n_obs(self):
        return len(self._d)

    @property
    def n_removed(self):
        """Degrees of freedom taken by the removed rigid-body motions (3 per group and load level)."""
        return 0 if self.rigid_body is None else self.rigid_body.n_removed

    @property
    def noise_std(self):
        """Noise standard deviation of each observed entry, ``(n_obs,)`` mm (without ``form_error``)."""
        return self._noise_sd

    def prior_residuals(self, X):
        """``L_M⁻¹ (m − m_prior)`` for each row of ``X``, ``(n, n_params)``; zeros without a prior."""
        X = np.atleast_2d(X)
        if self.prior_mean is None:
            return np.zeros((len(X), 0))
        return np.linalg.solve(self._prior_chol, (X - self.prior_mean).T).T

    def predict(self, X):
        """Model predictions at the observed entries: ``(mean, std)`` each ``(n, n_obs)`` mm."""
        mean, std = self.model(np.atleast_2d(X))
        if not (mean.shape[1] == self.n_obs and self._identity_indices):  # skip a copy when all observed
            mean = self.observation.apply(mean)
            std = None if std is None else self.observation.apply_std(std)
        return mean, None if not self.model_error else std

    def whitened_residuals(self, X):
        """``L_D⁻¹ (g(m) − d)`` with ``C_D = L_D L_Dᵀ``, ``(n, n_obs)`` (dimensionless).

        For ``kind="relative"``: ``(g − d)/|d|``. With rigid-body removal, the whitened residual
        with the whitened rigid modes projected out (its squares sum to ``(P r)ᵀ (P C_D Pᵀ)⁺ (P r)``;
        a relative residual is ``P (g − d)/|d|``).
        """
        mean, std = self.predict(X)
        return self.whiten(mean - self._d, std)

    def whiten(self, r, std=None):
        """Whitened residuals of raw residuals ``r`` ``(n, n_obs)`` mm, with the model's predictive
        std ``std`` (``(n, n_obs)`` mm, None: noise only) in ``C_D``; see :meth:`whitened_residuals`."""
        r = np.array(np.atleast_2d(r), dtype=float)
        rigid = self.rigid_body
        if self.kind == "relative":
            r = r if rigid is None else rigid.remove(r)
            return r / np.maximum(np.abs(self._d), 1e-12)
        if self.noise.is_diagonal:
            if std is not None and std.ndim == 2 and std.strides[0] == 0:
                std = std[0]  # the same std for every row (frozen C_T): weights computed once
            sd = self._sd if std is None else np.sqrt(self._sd**2 + std**2)
            r *= 1.0 / sd
            return r if rigid is None else rigid.whiten_diagonal(r, sd)
        C = np.broadcast_to(self._Cd, (len(r),) + self._Cd.shape).copy()
        if std is not None:
            idx = np.arange(self.n_obs)
            C[:, idx, idx] += std**2
        L = np.linalg.cholesky(C)
        w = np.linalg.solve(L, r[..., None])[..., 0]
        return w if rigid is None else project_out(rigid.whitened_basis(L), w)

    def chi2(self, X):
        """Data term ``(g − d)ᵀ C_D⁻¹ (g − d)``, ``(n,)``."""
        w = self.whitened_residuals(X)
        return np.einsum("ij,ij->i", w, w)

    def __call__(self, X):
        """ω(m), ``(n,)``; thesis eq. (2.13)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        omega = 0.5 * self.chi2(X)
        z = self.prior_residuals(X)
        return omega + 0.5 * np.einsum("ij,ij->i", z, z)
