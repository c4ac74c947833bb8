"""The thesis' hyperbolic Mode I/II interface surface (eq. 2.4 in 2D) with work softening.

Yield function (``reference/thesis-opening.txt`` eq. (2.4), one shear component, tension
positive), in the better-scaled √-form of ``reference/nonlinear-interfaces.md`` §1b:

.. math:: F = \\sqrt{τ^2 + a^2} - (c - σ \\tanφ), \\qquad a = c - σ_t \\tanφ \\ge 0,

which meets the σ-axis at σ = σ_t with a vertical tangent (no tension/shear corner) and tends to
the Coulomb line |τ| = c − σ tanφ in compression.

INFERRED choices (the Macorini–Izzuddin potential and softening laws are NOT FOUND; named here and
switchable only by replacing this law):

- flow (non-potential): ``m = (tanψ + (tanφ − tanψ) a/ρ, τ/ρ)``, ``ρ = √(τ² + a²)``: associated
  (normal to F) at the tension apex, tending to Coulomb flow with dilatancy tanψ far in shear and
  once the surface has softened (a → 0);
- work softening with one variable κ ∈ [0, 1]: ``dκ = dW_I/G_f^I + dW_II/G_f^II``,
  ``dW_I = ⟨σ⟩ du_n^p``, ``dW_II = ⟨|τ| + min(σ, 0) tanφ⟩ |du_s^p|`` (the shear work above
  friction); ``σ_t = σ_t0 (1 − κ)``, ``c = c0 (1 − κ)``, ``tanφ = tanφ0 + (tanφr − tanφ0) κ``.
  In pure mode I (II) the dissipated energy is G_f^I (G_f^II above friction) and the softening is
  exponential in the plastic relative displacement, as in the composite law;
- no compressive cap yet (the thesis' second hyperbola / the elliptical cap).

Return mapping: Euler backward on the unknowns (σ, τ, Δλ) with a safeguarded Newton method whose
3×3 Jacobian is formed by central differences (h = 1e-7 relative); the algorithmic tangent
follows from the implicit function theorem, ``∂x/∂t_tr = J⁻¹ [I; 0]``, so it is exact up to the
differencing error (~1e-9 relative). Sub-stepping (2…64 parts) when the return fails.
"""

import math

import numba
import numpy as np

from .state import InterfaceState, LawUpdate

KN, KS, FT, GFI, C, TANPHI0, TANPHIR, GFII, TANPSI = range(9)
N_PROPS = 9
MAX_ITERATIONS = 40


@numba.njit(cache=True)
def _residual(p, x, sig_tr, tau_tr, kap_n, out):
    """Residual (3,) at x = (σ, τ, Δλ); returns κ at the end of the step.

    κ enters its own update through tanφ(κ) and a(κ): two fixed-point passes from κ_n (the work
    increment of a step is small against G_f, so the second pass changes κ by O(Δκ²))."""
    sig, tau, dl = x[0], x[1], x[2]
    kap = kap_n
    for _ in range(2):  # κ depends on the end state through tanφ and the work split
        tphi = p[TANPHI0] + (p[TANPHIR] - p[TANPHI0]) * kap
        a = max(p[C] * (1.0 - kap) - p[FT] * (1.0 - kap) * tphi, 0.0)
        rho = math.sqrt(tau * tau + a * a) + 1e-300
        mn = p[TANPSI] + (tphi - p[TANPSI]) * a / rho
        ms = tau / rho
        w1 = max(sig, 0.0) * dl * mn
        w2 = max(abs(tau) + min(sig, 0.0) * tphi, 0.0) * dl * abs(ms)
        kap = min(1.0, kap_n + w1 / p[GFI] + w2 / p[GFII])
    tphi = p[TANPHI0] + (p[TANPHIR] - p[TANPHI0]) * kap
    a = max(p[C] * (1.0 - kap) - p[FT] * (1.0 - kap) * tphi, 0.0)
    rho = math.sqrt(tau * tau + a * a) + 1e-300
    mn = p[TANPSI] + (tphi - p[TANPSI]) * a / rho
    ms = tau / rho
    out[0] = sig - sig_tr + p[KN] * dl * mn
    out[1] = tau - tau_tr + p[KS] * dl * ms
    out[2] = rho - (p[C] * (1.0 - kap) - sig * tphi)
    return kap


@numba.njit(cache=True)
def _jacobian(p, x, sig_tr, tau_tr, kap_n, scale, J):
    r1 = np.empty(3)
    r2 = np.empty(3)
    xp = x.copy()
    for j in range(3):
        h = 1e-7 * scale[j]
        xp[j] = x[j] + h
        _residual(p, xp, sig_tr, tau_tr, kap_n, r1)
        xp[j] = x[j] - h
        _residual(p, xp, sig_tr, tau_tr, kap_n, r2)
        xp[j] = x[j]
        for i in range(3):
            J[i, j] = (r1[i] - r2[i]) / (2.0 * h)


@numba.njit(cache=True)
def _inverse3(J, out):
    """Inverse of a 3×3 matrix by cofactors (numba's LAPACK bindings compile slowly); False when singular."""
    c00 = J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1]
    c01 = J[1, 2] * J[2, 0] - J[1, 0] * J[2, 2]
    c02 = J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0]
    det = J[0, 0] * c00 + J[0, 1] * c01 + J[0, 2] * c02
    if det == 0.0 or not math.isfinite(det):
        return False
    out[0, 0], out[1, 0], out[2, 0] = c00 / det, c01 / det, c02 / det
    out[0, 1] = (J[0, 2] * J[2, 1] - J[0, 1] * J[2, 2]) / det
    out[1, 1] = (J[0, 0] * J[2, 2] - J[0, 2] * J[2, 0]) / det
    out[2, 1] = (J[0, 1] * J[2, 0] - J[0, 0] * J[2, 1]) / det
    out[0, 2] = (J[0, 1] * J[1, 2] - J[0, 2] * J[1, 1]) / det
    out[1, 2] = (J[0, 2] * J[1, 0] - J[0, 0] * J[1, 2]) / det
    out[2, 2] = (J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]) / det
    return True


@numba.njit(cache=True)
def _yield(p, sig, tau, kap):
    tphi = p[TANPHI0] + (p[TANPHIR] - p[TANPHI0]) * kap
    a = max(p[C] * (1.0 - kap) - p[FT] * (1.0 - kap) * tphi, 0.0)
    return math.sqrt(tau * tau + a * a) - (p[C] * (1.0 - kap) - sig * tphi)


@numba.njit(cache=True)
def _return_once(p, du, t_n, up_n, kap_n, t, up, D):
    """One step; returns (status 0/2, iterations); κ of the end state in up[2]."""
    kn, ks = p[KN], p[KS]
    sig_tr = t_n[0] + kn * du[0]
    tau_tr = t_n[1] + ks * du[1]
    D[0, 0], D[0, 1], D[1, 0], D[1, 1] = kn, 0.0, 0.0, ks
    stress = abs(sig_tr) + abs(tau_tr) + p[C] + 1e-12
    tol = 1e-11 * stress
    if _yield(p, sig_tr, tau_tr, kap_n) <= tol:
        t[0], t[1] = sig_tr, tau_tr
        up[0], up[1], up[2] = up_n[0], up_n[1], kap_n
        return 0, 0
    scale = np.array([stress, stress, stress / kn])
    x = np.array([sig_tr, tau_tr, 0.0])
    R = np.empty(3)
    Rt = np.empty(3)
    J = np.empty((3, 3))
    xt = np.empty(3)
    Jinv = np.empty((3, 3))
    dx = np.empty(3)
    for it in range(1, MAX_ITERATIONS + 1):
        _residual(p, x, sig_tr, tau_tr, kap_n, R)
        _jacobian(p, x, sig_tr, tau_tr, kap_n, scale, J)
        if not _inverse3(J, Jinv):
            return 2, it
        for i in range(3):
            dx[i] = -(Jinv[i, 0] * R[0] + Jinv[i, 1] * R[1] + Jinv[i, 2] * R[2])
        r0 = abs(R[0]) + abs(R[1]) + abs(R[2])
        eta = 1.0
        for _ in range(10):
            for i in range(3):
                xt[i] = x[i] + eta * dx[i]
            xt[2] = max(xt[2], 0.0)
            _residual(p, xt, sig_tr, tau_tr, kap_n, Rt)
            if abs(Rt[0]) + abs(Rt[1]) + abs(Rt[2]) < r0:
                break
            eta *= 0.5
        x[:] = xt
        if abs(Rt[0]) + abs(Rt[1]) + abs(Rt[2]) <= tol:
            kap = _residual(p, x, sig_tr, tau_tr, kap_n, R)
            if x[2] < 0.0 or tau_tr * x[1] < -tol * abs(tau_tr):
                return 2, it
            _jacobian(p, x, sig_tr, tau_tr, kap_n, scale, J)
            if not _inverse3(J, Jinv):
                return 2, it
            # dx/dt_tr = J⁻¹ [I; 0] (R1, R2 contain −t_tr); dt/du = dt/dt_tr · D
            for i in range(2):
                for j in range(2):
                    D[i, j] = Jinv[i, j] * (kn if j == 0 else ks)
            t[0], t[1] = x[0], x[1]
            up[0] = up_n[0] + (sig_tr - x[0]) / kn
            up[1] = up_n[1] + (tau_tr - x[1]) / ks
            up[2] = kap
            return 0, it
    return 2, MAX_ITERATIONS


@numba.njit(cache=True)
def hyperbolic_update(du, jump_n, t_n, up_n, kap_n, work_n, props):
    """Vectorised update; arrays as :func:`fe.interfaces.composite.composite_update` (κ in kappa[:, 0])."""
    n = du.shape[0]
    jump = jump_n + du
    t = np.empty((n, 2))
    up = np.empty((n, 2))
    kap = kap_n.copy()
    work = np.empty(n)
    tangent = np.empty((n, 2, 2))
    iterations = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int64)
    out = np.empty(3)
    for e in range(n):
        p = props[e]
        st, it = _return_once(p, du[e], t_n[e], up_n[e], kap_n[e, 0], t[e], out, tangent[e])
        iterations[e] = it
        if st != 0:
            for level in range(1, 7):
                parts = 2 ** level
                ts = t_n[e].copy()
                ups = np.array([up_n[e, 0], up_n[e, 1], kap_n[e, 0]])
                inc = du[e] / parts
                ok = True
                for _ in range(parts):
                    st, it = _return_once(p, inc, ts, ups, ups[2], t[e], out, tangent[e])
                    iterations[e] += it
                    if st != 0:
                        ok = False
                        break
                    ts[:] = t[e]
                    ups[:] = out
                if ok:
                    st = 1
                    out[:] = ups
                    break
            if st != 1:
                st = 2
                t[e, :] = t_n[e]
                out[0], out[1], out[2] = up_n[e, 0], up_n[e, 1], kap_n[e, 0]
        status[e] = st
        up[e, 0], up[e, 1] = out[0], out[1]
        kap[e, 0] = out[2]
        work[e] = work_n[e] + 0.5 * ((t_n[e, 0] + t[e, 0]) * (up[e, 0] - up_n[e, 0])
                                     + (t_n[e, 1] + t[e, 1]) * (up[e, 1] - up_n[e, 1]))
    return jump, t, up, kap, work, tangent, iterations, status


def hyperbolic_properties(*, kn, ks, ft, GfI, c, tanphi0, tanphir=None, GfII, tanpsi=0.0, where="interface"):
    """One property row, checked: σ_t ≤ c/tanφ (a ≥ 0 while softening), tanφ > 0 (the normal
    flow at the apex is tanφ), 0 ≤ tanψ ≤ tanφ, positive energies, k_n > σ_t²/G_f^I."""
    tanphir = tanphi0 if tanphir is None else tanphir
    for name, v in (("kn", kn), ("ks", ks), ("ft", ft), ("GfI", GfI), ("c", c), ("GfII", GfII),
                    ("tanphi0", tanphi0), ("tanphir", tanphir)):
        if not (v > 0 and np.isfinite(v)):
            raise ValueError(f"{where}: {name} must be finite and > 0; got {v}")
    if not 0 <= tanpsi <= min(tanphi0, tanphir):
        raise ValueError(f"{where}: need 0 <= tanpsi <= tanphi; got tanpsi={tanpsi}")
    if ft > c / max(tanphi0, tanphir) * (1 + 1e-12):
        raise ValueError(f"{where}: tensile strength ft={ft:g} MPa exceeds c/tanphi = {c / max(tanphi0, tanphir):.4g} "
                         "MPa: the hyperbola would have no real apex")
    if not kn > ft**2 / GfI:
        raise ValueError(f"{where}: kn={kn:g} N/mm³ must exceed ft²/GfI = {ft**2 / GfI:.4g} N/mm³ (local snap-back)")
    return np.array([kn, ks, ft, GfI, c, tanphi0, tanphir, GfII, tanpsi], dtype=float)


class HyperbolicInterface:
    """The hyperbolic law for ``n`` points, same API as :class:`~fe.interfaces.CompositeInterface`."""

    name = "hyperbolic"

    def __init__(self, props):
        props = np.ascontiguousarray(props, dtype=float)
        if props.ndim != 2 or props.shape[1] != N_PROPS:
            raise ValueError(f"props must have shape (n, {N_PROPS}); got {props.shape}")
        self.props = props

    def __len__(self):
        return len(self.props)

    def initial_state(self):
        return InterfaceState.zeros(len(self.props))

    def update(self, du, state):
        du = np.ascontiguousarray(du, dtype=float)
        jump, t, up, kap, work, tangent, iterations, status = hyperbolic_update(
            du, state.jump, state.traction, state.plastic, state.kappa, state.work, self.props)
        return LawUpdate(InterfaceState(jump, t, up, kap, work), tangent, iterations, status)

    def near_surfaces(self, state, fraction):
        """Points within (1 − fraction) of the surface, ``(n, 2)`` bool: column 0 on the tensile
        side (σ > 0), column 1 on the compressive side."""
        p, t, k = self.props, state.traction, state.kappa[:, 0]
        tphi = p[:, TANPHI0] + (p[:, TANPHIR] - p[:, TANPHI0]) * k
        size = p[:, C] * (1.0 - k) - t[:, 0] * tphi
        a = np.maximum(p[:, C] * (1.0 - k) - p[:, FT] * (1.0 - k) * tphi, 0.0)
        near = np.sqrt(t[:, 1] ** 2 + a**2) >= fraction * np.maximum(size, 0.0)
        return np.column_stack([near & (t[:, 0] > 0), near & (t[:, 0] <= 0)])

    def elastic_tangent(self):
        D = np.zeros((len(self.props), 2, 2))
        D[:, 0, 0] = self.props[:, KN]
        D[:, 1, 1] = self.props[:, KS]
        return D
