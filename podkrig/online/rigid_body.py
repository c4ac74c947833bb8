"""Rigid-body motion of displacement fields: fitted by least squares and removed from data and model alike.

Absolute displacement readings (DIC grid points, point displacement sensors) include the
in-plane rigid motion of the specimen, which depends on details of the supports that a model
rarely gets right: two FE codes of the same diagonal test differ by 3–8 % at the displacement
points, nearly all of it a rigid rotation of 1.8e-5 rad. DIC users remove it before
comparing fields; gauges (relative displacements of two points) are immune and never touched.

For a *group* of readings (one DIC grid, or point sensors the user names together) at one load
level, the small rigid motion is

.. math::

    u_i = t_x - ω (y_i - y_c), \\qquad v_i = t_y + ω (x_i - x_c),

i.e. ``r = R β`` with ``β = (t_x, t_y, ω)`` and one row of ``R`` per reading: ``(1, 0, −(y − y_c))``
for an x component, ``(0, 1, x − x_c)`` for a y component (``(x_c, y_c)`` the group's centroid,
mm). Its least-squares fit is ``β̂ = R⁺ r`` and the readings minus it are ``P r`` with the
orthogonal projector

.. math::

    P = I - R (R^t R)^{-1} R^t ,

one block per group and load level (identity on every other reading). ``P`` is symmetric,
idempotent, of rank ``n − 3`` per block (fewer removed when the block cannot tell all three
motions apart: a single point, or x components only). It is linear, so it applies identically to
measured data, model predictions, surrogate outputs and Jacobians.

Noise. The removed readings have covariance ``P C Pᵀ``, singular (rank ``n − 3`` per block). The
misfit uses its pseudo-inverse:

.. math::

    χ^2 = (P r)^t (P C P^t)^+ (P r) = r^t N (N^t C N)^{-1} N^t r ,

``N`` an orthonormal basis of the range of ``P`` — the "projected whitening", which is the same as
dropping 3 dof per block. It equals ``‖(I − Q Qᵀ) L⁻¹ r‖²`` with ``C = L Lᵀ`` and ``Q`` an
orthonormal basis of ``L⁻¹ R`` (the residual whitened, then the whitened rigid modes projected out
— the generalised least-squares fit of the rigid motion, REML identity), which is how it is
computed: an ``n``-vector whose squares sum to χ² and whose entries stay one per reading, and for a
diagonal ``C`` one 3 × 3 solve per block. Under the noise alone χ² then follows χ² with
``n − k`` degrees of freedom, ``k`` = :attr:`RigidBodyModes.n_removed` (3 per block), which the
χ²/dof of an inversion and a diagnosis count.

Options (:data:`RIGID_BODY_CHOICES`): ``"auto"`` (default) removes the motion of each DIC grid and
of the point sensors the user groups; ``"remove"`` also puts the other point displacement
sensors into one group; ``"keep"`` removes nothing.
"""

import functools
import re
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

#: the rigid-body options of an inversion or a diagnosis
RIGID_BODY_CHOICES = ("auto", "remove", "keep")
#: what each option removes, for error messages, the CLI and the docs
RIGID_BODY_TEXT = ("auto: the rigid motion of each DIC grid (and of point sensors grouped with rigid_groups) is "
                   "removed from data and model; remove: also of all other point displacement sensors, together; "
                   "keep: nothing removed")
#: the group of the point displacement sensors not named in a group (option "remove")
POINT_GROUP = "point sensors"
#: channel names of a DIC grid (:class:`fe.sensors.DICGrid`): ``name[i,j].ux`` / ``.uy``
_DIC_CHANNEL = re.compile(r"^.+\[\d+,\d+\]\.u[xy]$")
#: a block's singular value below this fraction of its largest is a motion the block cannot see
_RANK_RTOL = 1e-9


def may_remove(sensor_names, option="auto", groups=None):
    """Whether the option can remove anything from readings of ``sensor_names`` — without the
    sensor definitions (building them may mean rebuilding a scenario): "auto" without groups acts
    only on DIC grid channels, recognised by their names ``grid[i,j].ux``."""
    check_option(option)
    if option == "keep":
        return False
    return option == "remove" or bool(groups) or any(_DIC_CHANNEL.match(s) for s in sensor_names)


def check_option(option):
    """Refuse an unknown rigid-body option, naming the allowed ones."""
    if option not in RIGID_BODY_CHOICES:
        raise ValueError(f"rigid_body must be one of {list(RIGID_BODY_CHOICES)}; got {option!r} ({RIGID_BODY_TEXT})")


@dataclass(frozen=True, eq=False)
class RigidBodyModes:
    """The rigid-body modes of the observed entries of a measurement, block by block.

    Attributes
    ----------
    block : ndarray of int, shape (n_obs,)
        The block (group × load level) of each observed entry; −1: not touched (gauges, point
        sensors outside any group).
    modes : ndarray of shape (n_obs, 3)
        Rows of ``R``: ``(1, 0, −(y − y_c)/ℓ)`` for an x component, ``(0, 1, (x − x_c)/ℓ)`` for a
        y component (ℓ the block's RMS distance from its centroid, mm, so that the columns are
        of one size); zero rows outside any block.
    labels : tuple of (str, int)
        Each block's group name and load-level row.
    lengths : ndarray of shape (n_blocks,)
        ℓ of each block, mm (the rotation coefficient of a fit is ``ω ℓ``).

    Derived: ``basis`` ``(n_obs, 3)``, each block's rows an orthonormal basis of its columns of
    ``R`` (zero columns where a block has rank < 3), and ``rank`` ``(n_blocks,)``.
    """

    block: np.ndarray
    modes: np.ndarray
    labels: tuple
    lengths: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "block", np.asarray(self.block, dtype=np.intp))
        object.__setattr__(self, "modes", np.asarray(self.modes, dtype=float))
        object.__setattr__(self, "labels", tuple(self.labels))
        object.__setattr__(self, "lengths", np.asarray(self.lengths, dtype=float))

    # the derived state (one SVD per block, sparse maps) is built on first use

    @functools.cached_property
    def _orthonormal(self):
        """``(basis, rank)``: each block's orthonormal basis of its columns of ``R`` and its rank."""
        basis = np.zeros_like(self.modes)
        rank = np.zeros(len(self.labels), dtype=np.intp)
        for b in range(len(self.labels)):
            rows = np.flatnonzero(self.block == b)
            A, s, _ = np.linalg.svd(self.modes[rows], full_matrices=False)
            r = int(np.sum(s > _RANK_RTOL * s[0])) if len(s) and s[0] > 0 else 0
            basis[rows, :r] = A[:, :r]
            rank[b] = r
        return basis, rank

    @property
    def basis(self):
        """Each block's rows an orthonormal basis of its columns of ``R``, ``(n_obs, 3)``."""
        return self._orthonormal[0]

    @property
    def rank(self):
        """Rank of each block's modes, ``(n_blocks,)``."""
        return self._orthonormal[1]

    @functools.cached_property
    def _indicator(self):
        """``(n_blocks, n_obs)`` sparse: 1 where an entry belongs to a block."""
        touched = self.block >= 0
        return sp.csr_matrix((np.ones(int(touched.sum())), (self.block[touched], np.flatnonzero(touched))),
                             shape=(len(self.labels), len(self.block)))

    @functools.cached_property
    def _pad(self):
        """``(n_blocks, 3)``: the columns a block of rank < 3 does not have."""
        return np.arange(3)[None, :] >= self.rank[:, None]

    def _block_map(self, width, values):
        """Sparse ``(n_obs, n_blocks * width)``: reading i → ``values[i]`` in its block's ``width`` columns."""
        idx = np.flatnonzero(self.block >= 0)
        cols = self.block[idx, None] * width + np.arange(width)[None, :]
        return sp.csr_matrix((values.ravel(), (np.repeat(idx, width), cols.ravel())),
                             shape=(len(self.block), len(self.labels) * width))

    @functools.cached_property
    def _outer(self):
        """Reading i → its block's 9 entries of ``U_i U_iᵀ`` (:meth:`whiten_diagonal`)."""
        basis = self.basis[self.block >= 0]
        return self._block_map(9, (basis[:, :, None] * basis[:, None, :]).reshape(-1, 9))

    @functools.cached_property
    def _rows(self):
        """Reading i → its 3 entries of ``U_i`` (:meth:`whiten_diagonal`)."""
        return self._block_map(3, self.basis[self.block >= 0])

    @property
    def n_obs(self):
        return len(self.block)

    @property
    def n_blocks(self):
        return len(self.labels)

    @property
    def n_removed(self):
        """Degrees of freedom removed: Σ rank over blocks (3 per group and load level)."""
        return int(self.rank.sum())

    @property
    def groups(self):
        """The group names, in order of appearance."""
        return tuple(dict.fromkeys(g for g, _ in self.labels))

    def _sum_blocks(self, X):
        """Sum ``X`` ``(n_obs, ...)`` over the entries of each block → ``(n_blocks, ...)``."""
        X = np.asarray(X)
        return (self._indicator @ X.reshape(len(X), -1)).reshape((self.n_blocks,) + X.shape[1:])

    def dense_basis(self):
        """The orthonormal basis of the removed motions as one matrix, ``(n_obs, n_removed)``."""
        cols = [np.where((self.block == b)[:, None], self.basis[:, :r], 0.0) for b, r in enumerate(self.rank)]
        return np.hstack(cols) if cols else np.zeros((self.n_obs, 0))

    def projector(self):
        """``P = I − R (Rᵀ R)⁻¹ Rᵀ``, ``(n_obs, n_obs)`` dense (for checks and small problems)."""
        U = self.dense_basis()
        return np.eye(self.n_obs) - U @ U.T

    def remove(self, V):
        """``P v`` for each row of ``V`` ``(..., n_obs)``: the readings minus their fitted rigid
        motion (data, model predictions, surrogate outputs alike), mm. A Jacobian ``(n_obs, p)``
        goes in transposed: ``remove(J.T).T``."""
        V = np.asarray(V, dtype=float)
        if not self.n_blocks:  # no displacement reading in these rows (a subset): nothing to remove
            return V.copy()
        X = np.moveaxis(V, -1, 0)  # (n_obs, ...)
        coef = self._sum_blocks(self.basis.reshape((self.n_obs, 3) + (1,) * (X.ndim - 1)) * X[:, None])
        back = np.einsum("ij,ij...->i...", self.basis, coef[np.maximum(self.block, 0)])
        return np.moveaxis(X - back, 0, -1)

    def fit(self, v):
        """The fitted rigid motion of ``v`` ``(n_obs,)``: ``(n_blocks, 3)`` rows ``(t_x, t_y, ω)``
        in mm, mm, rad (translation of the block's centroid; NaN for a motion the block cannot see)."""
        v = np.asarray(v, dtype=float)
        out = np.full((self.n_blocks, 3), np.nan)
        for b in range(self.n_blocks):
            rows = self.block == b
            beta, *_ = np.linalg.lstsq(self.modes[rows], v[rows], rcond=_RANK_RTOL)
            if self.rank[b] == 3:
                out[b] = beta[0], beta[1], beta[2] / self.lengths[b]
            else:  # only what the block's readings determine
                seen = np.abs(self.modes[rows]).sum(axis=0) > 0
                out[b, seen] = beta[seen] / np.where(np.arange(3)[seen] == 2, self.lengths[b], 1.0)
        return out

    def covariance(self, C):
        """``P C Pᵀ`` of a covariance ``C`` ``(n_obs, n_obs)`` mm²: singular, rank n − n_removed."""
        P = self.projector()
        return P @ C @ P.T

    def whiten_diagonal(self, u, sd):
        """Whitened residuals with the rigid motion removed, for a diagonal covariance.

        Parameters
        ----------
        u : ndarray of shape (n, n_obs)
            Residuals divided by their standard deviation, ``(g − d)/σ``.
        sd : ndarray of shape (n_obs,) or (n, n_obs)
            σ of each entry (noise and model error), mm.

        Returns
        -------
        ndarray of shape (n, n_obs)
            ``(I − Q Qᵀ) u``, ``Q`` an orthonormal basis of ``R/σ`` per block: squares sum to
            ``(P r)ᵀ (P C Pᵀ)⁺ (P r)`` (module docstring).
        """
        u = np.atleast_2d(u)
        nb = self.n_blocks
        if not nb:
            return np.array(u, dtype=float)
        inv_sd = 1.0 / np.atleast_2d(sd)  # (n|1, n_obs)
        # per block Σ_i U_i U_iᵀ / σ_i² and Σ_i U_i u_i / σ_i, as sparse products (9 and 3 entries per reading)
        A = (self._outer.T @ (inv_sd**2).T).T.reshape(-1, nb, 3, 3) + np.eye(3) * self._pad[None, :, None, :]
        c = (self._rows.T @ (u * inv_sd).T).T.reshape(-1, nb, 3)
        beta = np.linalg.solve(A, c[..., None])[..., 0]  # (n, n_blocks, 3)
        return u - inv_sd * np.einsum("ij,sij->si", self.basis, beta[:, np.maximum(self.block, 0)])

    def whitened_basis(self, L):
        """Orthonormal basis ``Q`` of ``L⁻¹ R`` for a full covariance ``C = L Lᵀ`` (``L`` lower
        triangular ``(n_obs, n_obs)``, or a stack ``(n, n_obs, n_obs)``): ``(…, n_obs, n_removed)``;
        :func:`project_out` then removes the rigid motion from whitened residuals."""
        W = np.linalg.solve(L, np.broadcast_to(self.dense_basis(), np.shape(L)[:-1] + (self.n_removed,)))
        return np.linalg.qr(W)[0]

    def subset(self, rows):
        """The modes of the observed entries ``rows`` (e.g. the load levels a fit keeps)."""
        rows = np.asarray(rows)
        block = self.block[rows]
        kept = np.unique(block[block >= 0])
        renumber = np.full(self.n_blocks + 1, -1, dtype=np.intp)
        renumber[kept] = np.arange(len(kept))
        return RigidBodyModes(renumber[block], self.modes[rows], tuple(self.labels[b] for b in kept), self.lengths[kept])

    def to_dict(self):
        """``groups``, ``n_blocks`` and ``n_removed`` (the dof removed), JSON-able."""
        return {"groups": list(self.groups), "n_blocks": self.n_blocks, "n_removed": self.n_removed}


def project_out(Q, w):
    """``(I − Q Qᵀ) w`` for whitened residuals ``w`` ``(…, n_obs)`` and a basis from
    :meth:`RigidBodyModes.whitened_basis` (``Q`` None: ``w`` as is)."""
    if Q is None:
        return w
    return w - np.einsum("...ik,...k->...i", Q, np.einsum("...ik,...i->...k", Q, w))


def rigid_body_modes(measurement, displacements, option="auto", groups=None):
    """The rigid-body modes to remove from a measurement's observed entries, or None.

    Parameters
    ----------
    measurement : Measurement
        The observed entries (load-major, missing readings left out).
    displacements : dict of str to tuple
        Channel name → ``(x, y, component, grid)`` of every absolute displacement reading of the
        model (:func:`fe.sensors.absolute_displacements`).
    option : {"auto", "remove", "keep"}
        See the module docstring.
    groups : dict of str to sequence of str, optional
        Group name → point displacement sensors whose rigid motion is fitted together.

    Returns
    -------
    RigidBodyModes or None
        None when nothing is removed.

    Raises
    ------
    ValueError
        An unknown option, or a group naming a sensor that is not a point displacement sensor of
        the model (a gauge, a DIC channel, an unknown name) or naming one twice.
    """
    check_option(option)
    groups = dict(groups or {})
    member = {}
    for g, names in groups.items():
        for s in names:
            if s in member:
                raise ValueError(f"rigid_groups: sensor {s!r} is in groups {member[s]!r} and {g!r}; give each one group")
            where = displacements.get(s)
            if where is None or where[3] is not None:
                what = "a DIC grid channel (each grid is one group already)" if where else "not a point displacement sensor"
                raise ValueError(f"rigid_groups: {s!r} in group {g!r} is {what}; a group holds point displacement "
                                 f"sensors (kind = \"point\"): {sorted(k for k, v in displacements.items() if v[3] is None)}")
            member[s] = g
    if option == "keep":
        return None

    def group_of(name):
        where = displacements.get(name)
        if where is None:
            return None  # a gauge: relative, immune
        if where[3] is not None:
            return where[3]
        return member.get(name, POINT_GROUP if option == "remove" else None)

    sensor_group = [group_of(s) for s in measurement.sensor_names]
    if all(g is None for g in sensor_group):
        return None
    n_loads, n_sensors = measurement.values.shape
    load_row, sensor = np.indices((n_loads, n_sensors))
    mask = measurement.mask
    load_row, sensor = load_row[mask], sensor[mask]
    keys = {}
    block = np.full(len(sensor), -1, dtype=np.intp)
    for i, (k, j) in enumerate(zip(load_row, sensor)):
        g = sensor_group[j]
        if g is not None:
            block[i] = keys.setdefault((g, int(k)), len(keys))
    xyc = np.array([displacements[s][:3] if g is not None else (0.0, 0.0, 0) for s, g
                    in zip(measurement.sensor_names, sensor_group)], dtype=float)[sensor]
    modes = np.zeros((len(sensor), 3))
    lengths = np.ones(len(keys))
    for b in range(len(keys)):
        rows = block == b
        xy = xyc[rows, :2]
        centred = xy - xy.mean(axis=0)
        ell = float(np.sqrt(np.mean(np.sum(centred**2, axis=1)))) or 1.0
        lengths[b] = ell
        is_y = xyc[rows, 2] == 1
        modes[rows, 0] = ~is_y
        modes[rows, 1] = is_y
        modes[rows, 2] = np.where(is_y, centred[:, 0], -centred[:, 1]) / ell
    return RigidBodyModes(block, modes, tuple(keys), lengths)


__all__ = ["POINT_GROUP", "RIGID_BODY_CHOICES", "RigidBodyModes", "check_option", "may_remove", "project_out",
           "rigid_body_modes"]
