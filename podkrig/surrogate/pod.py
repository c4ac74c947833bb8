"""Proper orthogonal decomposition (POD) of a snapshot matrix.

Conventions: the snapshot matrix ``Y`` has shape ``(n_samples, n_outputs)``, one snapshot per row
(e.g. readings flattened load-major to ``n_loads * n_sensors`` values, mm). The fitted basis has
``mean_`` ``(n_outputs,)`` and orthonormal rows ``modes_`` ``(n_modes, n_outputs)``; the POD
coefficients of snapshots are ``(Y - mean_) @ modes_.T`` and the reconstruction is
``A @ modes_ + mean_``.

Example
-------
>>> import numpy as np
>>> from podkrig.surrogate.pod import POD
>>> rng = np.random.default_rng(0)
>>> Y = rng.random((20, 3)) @ rng.random((3, 50))        # rank-3 data, 20 snapshots of 50 outputs
>>> pod = POD(energy=1 - 1e-12).fit(Y)
>>> pod.n_modes_
3
>>> bool(np.allclose(pod.inverse_transform(pod.transform(Y)), Y, rtol=0, atol=1e-10))
True

References
----------
.. [1] L. Sirovich, "Turbulence and the dynamics of coherent structures, part I: coherent
   structures", Quarterly of Applied Mathematics 45(3), 561–571, 1987 (method of snapshots).
.. [2] The thesis, ch. 4 (POD of FE responses).
"""

import logging

import numpy as np
from scipy import linalg

from podkrig.exceptions import NotFittedError

logger = logging.getLogger(__name__)

METHODS = ("auto", "svd", "snapshots")


class POD:
    """POD basis of a snapshot matrix, truncated by retained energy or by a number of modes.

    Parameters
    ----------
    n_modes : int, optional
        Keep exactly this many modes (at most the numerical rank). Exclusive with ``energy``.
    energy : float, optional
        Keep the fewest modes whose retained energy
        :math:`\\sum_{k \\le K} \\lambda_k / \\sum_k \\lambda_k` reaches ``energy`` (i.e.
        :math:`1 - \\varepsilon`), ``0 < energy <= 1``. Exclusive with ``n_modes``. With neither,
        every mode above the numerical rank tolerance is kept.
    center : bool, default True
        Subtract the mean snapshot before the decomposition.
    blocks : int, optional
        Decompose ``blocks`` equal contiguous column blocks separately (e.g. the outputs of each
        control level of a nonlinear response, thesis §4.3.3): each block gets its own mean, modes
        and truncation (``energy`` or ``n_modes`` per block, ``n_modes`` clipped to the block's
        rank; a block without variance keeps none), and the modes are zero outside their block, so
        the retained modes stay orthonormal. ``None`` or 1: one POD of all columns.
    method : {"auto", "svd", "snapshots"}, default "auto"
        Thin SVD of the centred matrix, or the method of snapshots [1]_ (eigen-decomposition of the
        ``n_samples × n_samples`` Gram matrix; cheaper when ``n_outputs`` is much larger than
        ``n_samples``, but it squares the condition number, so modes with
        :math:`\\sigma_k / \\sigma_1 < 10^{-7}` lose accuracy). ``"auto"`` picks snapshots when
        ``n_outputs > 4 n_samples``.

    Attributes
    ----------
    mean_ : ndarray of shape (n_outputs,)
        Mean snapshot (zeros when ``center=False``), output units.
    modes_ : ndarray of shape (n_modes, n_outputs)
        Orthonormal POD modes (rows), ordered by decreasing singular value; the sign of each is
        fixed so that its largest-magnitude entry is positive.
    singular_values_ : ndarray of shape (n_rank,)
        All non-negligible singular values of the centred snapshot matrix, output units (per
        block: those of every block, in decreasing order).
    energy_ : ndarray of shape (n_rank,)
        Cumulative retained energy :math:`\\sum_{k \\le K} \\sigma_k^2 / \\sum_k \\sigma_k^2`.
    n_modes_ : int
        Number of retained modes.
    residual_variance_ : ndarray of shape (n_outputs,)
        Mean squared residual of the training snapshots off the retained basis, per output
        (output units²): the truncation part of the surrogate's predictive variance.
    method_ : str
        ``"svd"`` or ``"snapshots"``.
    block_modes_ : ndarray of shape (blocks,)
        Per block only: the number of modes kept in each block (their sum is ``n_modes_``).

    Notes
    -----
    With the centred snapshot matrix :math:`Y_c = U \\Sigma V^T`, the modes are the rows of
    :math:`V^T` and the energy of mode :math:`k` is :math:`\\lambda_k = \\sigma_k^2`. The projection
    error of a snapshot :math:`y` is :math:`\\| (y - \\bar y) - \\Phi^T \\Phi (y - \\bar y) \\|`.
    """

    def __init__(self, n_modes=None, energy=None, center=True, method="auto", blocks=None):
        self.n_modes = n_modes
        self.energy = energy
        self.center = center
        self.method = method
        self.blocks = blocks

    def get_params(self, deep=True):
        """Hyperparameters as a dict (scikit-learn convention)."""
        return {"n_modes": self.n_modes, "energy": self.energy, "center": self.center, "method": self.method,
                "blocks": self.blocks}

    def _check_settings(self):
        if self.n_modes is not None and self.energy is not None:
            raise ValueError(
                f"give either n_modes or energy, not both; got n_modes={self.n_modes!r}, energy={self.energy!r}"
            )
        if self.n_modes is not None and (
            isinstance(self.n_modes, bool) or not isinstance(self.n_modes, (int, np.integer)) or self.n_modes < 1
        ):
            raise ValueError(f"n_modes must be an integer >= 1; got {self.n_modes!r}")
        if self.energy is not None and not (np.isscalar(self.energy) and 0.0 < self.energy <= 1.0):
            raise ValueError(
                f"energy is the retained share 1 - eps and must satisfy 0 < energy <= 1; got {self.energy!r} "
                "(e.g. energy=0.9999 keeps 99.99 %)"
            )
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}; got {self.method!r}")
        if self.blocks is not None and (isinstance(self.blocks, bool) or not isinstance(self.blocks, (int, np.integer))
                                        or self.blocks < 1):
            raise ValueError(f"blocks must be an integer >= 1; got {self.blocks!r}")

    def fit(self, Y):
        """Compute the POD basis of the snapshot matrix ``Y`` (not modified).

        Parameters
        ----------
        Y : array_like of shape (n_samples, n_outputs)
            Snapshots, one per row, output units (e.g. mm).

        Returns
        -------
        self : POD

        Raises
        ------
        ValueError
            Wrong shape, non-finite values, fewer than 2 snapshots, conflicting truncation options,
            or ``n_modes`` above the numerical rank.
        """
        self._check_settings()
        Y = np.asarray(Y, dtype=float)
        if Y.ndim != 2:
            raise ValueError(f"Y must have shape (n_samples, n_outputs); got shape {Y.shape}")
        n, m = Y.shape
        if n < 2:
            raise ValueError(f"POD needs at least 2 snapshots; got {n}")
        if not np.all(np.isfinite(Y)):
            raise ValueError("Y must be finite; found NaN or inf (drop failed FE runs first)")
        if self.blocks not in (None, 1):
            return self._fit_blocks(Y)
        mean = Y.mean(axis=0) if self.center else np.zeros(m)
        Yc = Y - mean  # a new array: the input is never modified
        method = self.method
        if method == "auto":
            method = "snapshots" if m > 4 * n else "svd"
        if method == "svd":
            _, s, Vt = linalg.svd(Yc, full_matrices=False, lapack_driver="gesdd", check_finite=False)
        else:
            # Sirovich (1987): Yc Yc^T = W diag(s^2) W^T, modes V^T = diag(1/s) W^T Yc
            lam, W = linalg.eigh(Yc @ Yc.T, check_finite=False)
            lam, W = lam[::-1], W[:, ::-1]
            s = np.sqrt(np.clip(lam, 0.0, None))
            keep = s > s[0] * 1e-7 if s[0] > 0 else np.zeros(len(s), bool)
            s, W = s[keep], W[:, keep]
            Vt = (W.T @ Yc) / s[:, None]
        tol = (s[0] if len(s) else 0.0) * max(n, m) * np.finfo(float).eps
        rank = int(np.sum(s > tol))
        if rank == 0:
            raise ValueError("all snapshots are identical (zero variance after centring); nothing to decompose")
        s, Vt = s[:rank], Vt[:rank]
        # deterministic signs: largest-magnitude entry of each mode positive
        flip = np.sign(Vt[np.arange(rank), np.argmax(np.abs(Vt), axis=1)])
        Vt = Vt * flip[:, None]
        e2 = s**2
        energy_curve = np.cumsum(e2) / e2.sum()
        if self.n_modes is not None:
            if self.n_modes > rank:
                raise ValueError(
                    f"n_modes={self.n_modes} exceeds the numerical rank {rank} of the snapshot matrix "
                    f"({n} snapshots); choose n_modes <= {rank} or give energy= instead"
                )
            k = self.n_modes
        elif self.energy is not None:
            # fewest modes whose retained energy reaches 1 - eps (tolerance for rounding of the sum)
            k = int(np.searchsorted(energy_curve, self.energy - 1e-12) + 1)
            k = min(k, rank)
        else:
            k = rank
        self.mean_ = mean
        self.modes_ = np.ascontiguousarray(Vt[:k])
        self.singular_values_ = s
        self.energy_ = energy_curve
        self.n_modes_ = k
        self.method_ = method
        R = Yc - (Yc @ self.modes_.T) @ self.modes_
        self.residual_variance_ = np.mean(R * R, axis=0)
        self.n_samples_, self.n_outputs_ = n, m
        logger.info("POD (%s): %d snapshots x %d outputs, rank %d, %d modes keep %.10f of the energy",
                    method, n, m, rank, k, energy_curve[k - 1])
        return self

    def _fit_blocks(self, Y):
        """One POD per block of ``m / blocks`` contiguous columns, assembled block-diagonally."""
        n, m = Y.shape
        if m % self.blocks:
            raise ValueError(f"blocks={self.blocks} does not divide the {m} outputs of a snapshot")
        w = m // self.blocks
        mean, residual = np.zeros(m), np.zeros(m)
        rows, kept, s_all, methods = [], [], [], []
        for b in range(self.blocks):
            cols = slice(b * w, (b + 1) * w)
            Yb = Y[:, cols]
            centre = Yb.mean(axis=0) if self.center else np.zeros(w)
            mean[cols] = centre
            if not np.any(Yb - centre):  # no variance in this block: its mean alone reproduces it
                kept.append(0)
                continue
            sub = POD(center=self.center, method=self.method).fit(Yb)  # every mode above the rank tolerance
            rank = len(sub.singular_values_)
            if self.n_modes is not None:
                k = min(self.n_modes, rank)
            elif self.energy is not None:
                k = min(int(np.searchsorted(sub.energy_, self.energy - 1e-12) + 1), rank)
            else:
                k = rank
            block = np.zeros((k, m))
            block[:, cols] = sub.modes_[:k]
            rows.append(block)
            Rb = (Yb - centre) - ((Yb - centre) @ sub.modes_[:k].T) @ sub.modes_[:k]
            residual[cols] = np.mean(Rb * Rb, axis=0)
            kept.append(k)
            s_all.append(sub.singular_values_)
            methods.append(sub.method_)
        if not rows:
            raise ValueError("all snapshots are identical (zero variance after centring); nothing to decompose")
        s = np.concatenate(s_all)
        e2 = s**2
        in_kept = np.concatenate([np.arange(len(v)) < k for v, k in zip(s_all, [k for k in kept if k])])
        order = np.argsort(-s, kind="stable")
        self.mean_ = mean
        self.modes_ = np.ascontiguousarray(np.concatenate(rows))
        self.singular_values_ = s[order]
        self.energy_ = np.cumsum(e2[order]) / e2.sum()
        self.block_modes_ = np.asarray(kept, dtype=int)
        self._retained = float(e2[in_kept].sum() / e2.sum())
        self.n_modes_ = int(sum(kept))
        self.method_ = methods[0]
        self.residual_variance_ = residual
        self.n_samples_, self.n_outputs_ = n, m
        logger.info("POD per block: %d snapshots x %d outputs in %d blocks, %d modes (per block %s) keep %.10f of "
                    "the energy", n, m, self.blocks, self.n_modes_, kept, self._retained)
        return self

    # ------------------------------------------------------------------ state exchange
    _ARRAYS = ("mean_", "modes_", "singular_values_", "energy_", "residual_variance_")

    def to_arrays(self):
        """The fitted basis as named arrays and scalar attributes (for a file format; no pickle).

        Returns
        -------
        arrays : dict of str to ndarray
            ``mean`` ``(n_outputs,)``, ``modes`` ``(n_modes, n_outputs)``, ``singular_values``,
            ``energy``, ``residual_variance`` ``(n_outputs,)``; for a POD per block also
            ``block_modes`` ``(blocks,)``, the modes kept per block.
        attrs : dict
            ``method`` (str), ``n_samples`` (int); per block also ``retained_energy`` (float).
        """
        self._check_fitted()
        arrays = {name.rstrip("_"): getattr(self, name) for name in self._ARRAYS}
        attrs = {"method": self.method_, "n_samples": self.n_samples_}
        if hasattr(self, "block_modes_"):
            arrays["block_modes"] = self.block_modes_
            attrs["retained_energy"] = self._retained
        return arrays, attrs

    @classmethod
    def from_arrays(cls, arrays, attrs, params):
        """A fitted POD from :meth:`to_arrays` output and its settings ``params`` (:meth:`get_params`).

        Raises
        ------
        KeyError
            A missing array or attribute.
        """
        pod = cls(**params)
        for name in cls._ARRAYS:
            setattr(pod, name, np.asarray(arrays[name.rstrip("_")]))
        pod.method_ = str(attrs["method"])
        pod.n_samples_ = int(attrs["n_samples"])
        if "block_modes" in arrays:  # a POD per block
            pod.block_modes_ = np.asarray(arrays["block_modes"], dtype=int)
            pod._retained = float(attrs["retained_energy"])
        pod.n_modes_, pod.n_outputs_ = pod.modes_.shape
        return pod

    def _check_fitted(self):
        if not hasattr(self, "modes_"):
            raise NotFittedError("this POD instance is not fitted yet; call fit(Y) first")

    def _check_Y(self, Y):
        Y = np.asarray(Y, dtype=float)
        if Y.ndim != 2 or Y.shape[1] != self.n_outputs_:
            raise ValueError(f"Y must have shape (n_samples, {self.n_outputs_}); got {Y.shape}")
        return Y

    @property
    def retained_energy_(self):
        """Share of the energy kept by the retained modes, :math:`\\sum_{k \\le K}\\lambda_k/\\sum\\lambda_k`."""
        self._check_fitted()
        if hasattr(self, "block_modes_"):  # the kept modes of every block, not the top n_modes_ of all
            return self._retained
        return float(self.energy_[self.n_modes_ - 1])

    def transform(self, Y):
        """POD coefficients ``(Y - mean_) @ modes_.T``, ndarray of shape (n_samples, n_modes)."""
        self._check_fitted()
        return (self._check_Y(Y) - self.mean_) @ self.modes_.T

    def inverse_transform(self, A):
        """Snapshots from coefficients, ``A @ modes_ + mean_``, shape (n_samples, n_outputs).

        Parameters
        ----------
        A : array_like of shape (n_samples, n_modes)
        """
        self._check_fitted()
        A = np.asarray(A, dtype=float)
        if A.ndim != 2 or A.shape[1] != self.n_modes_:
            raise ValueError(f"A must have shape (n_samples, {self.n_modes_}); got {A.shape}")
        return A @ self.modes_ + self.mean_

    def project(self, Y):
        """Best approximation of ``Y`` in the affine POD space, shape (n_samples, n_outputs)."""
        return self.inverse_transform(self.transform(Y))

    def projection_error(self, Y, relative=True):
        """Per-snapshot projection (truncation) error.

        Parameters
        ----------
        Y : array_like of shape (n_samples, n_outputs)
        relative : bool, default True
            Divide by :math:`\\|y\\|` (a zero snapshot gives ``inf`` unless its error is 0).

        Returns
        -------
        err : ndarray of shape (n_samples,)
            :math:`\\|y - P y\\|` (output units) or :math:`\\|y - P y\\| / \\|y\\|`.
        """
        Y = self._check_Y(Y)
        err = np.linalg.norm(Y - self.project(Y), axis=1)
        if not relative:
            return err
        norm = np.linalg.norm(Y, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(err == 0, 0.0, err / norm)
