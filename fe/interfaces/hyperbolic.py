"""The thesis' hyperbolic Mode I/II interface surface (eq. 2.4 in 2D) with work softening.

Yield function (thesis eq. (2.4), Macorini & Izzuddin 2011, one shear component, tension
positive), in the better-scaled √-form:

.. math:: F = \\sqrt{τ^2 + a^2} - (c - σ \\tanφ), \\qquad a = c - σ_t \\tanφ \\ge 0,

which meets the σ-axis at σ = σ_t with a vertical tangent (no tension/shear corner) and tends to
the Coulomb line |τ| = c − σ tanφ in compression.

INFERRED choices (``docs/references.md`` "INFERRED choices": the Macorini–Izzuddin potential, cap
and softening laws are not at hand; named here; the flow and the softening are switchable only by replacing this law, the cap through
:func:`hyperbolic_properties`):

- flow (non-potential): ``m = (tanψ + (tanφ − tanψ) a/ρ, τ/ρ)``, ``ρ = √(τ² + a²)``: associated
  (normal to F) at the tension apex, tending to Coulomb flow with dilatancy tanψ far in shear and
  once the surface has softened (a → 0);
- work softening with one variable κ ∈ [0, 1]: ``dκ = dW_I/G_f^I + dW_II/G_f^II``,
  ``dW_I = ⟨σ⟩ du_n^p``, ``dW_II = ⟨|τ| + min(σ, 0) tanφ⟩ |du_s^p|`` (the shear work above
  friction); ``σ_t = σ_t0 (1 − κ)``, ``c = c0 (1 − κ)``, ``tanφ = tanφ0 + (tanφr − tanφ0) κ``.
  In pure mode I (II) the dissipated energy is G_f^I (G_f^II above friction) and the softening is
  exponential in the plastic relative displacement, as in the composite law;
- the compressive cap F2 (the thesis names "a second hyperbolic function" without its equation;
  the Lourenço–Rots ellipse is the likely one), a configurable ``cap_shape``:

  * ``"ellipse"``: ``F2 = √(σ² + C_s τ²) − σ̄3(κ3)`` (the Lourenço–Rots cap with C_nn = 1,
    C_n = 0, in √-form);
  * ``"hyperbola"``: ``F2 = √(C_s τ² + σ̄3²) − (2 σ̄3 + σ)``, the mirror image of F1: vertex at
    σ = −σ̄3 with the ellipse's curvature there (both are −σ ≈ σ̄3 − C_s τ²/(2 σ̄3) near the
    vertex), asymptotes √C_s |τ| = 2 σ̄3 + σ, so it closes the elastic domain towards tension
    instead of rounding it.

  Both have associated flow (READ for the L&R cap), ``κ̇3 = λ̇3 ‖m3‖`` (the equivalent plastic
  relative displacement; for the hyperbola ‖m3‖ depends on σ̄3(κ3), handled by the same two
  fixed-point passes as κ), the L&R C¹ hardening/softening law σ̄3(κ3) of
  :func:`fe.interfaces.composite.cap_strength` (READ shape, OOFEM's parabola, ``cap_ratios``
  (σ̄_i, σ̄_m, σ̄_r)/f_c = (1/3, 1/2, 1/7) by default, κ_m from G_fc by
  :func:`~fe.interfaces.composite.cap_kappa_m`), no coupling with the work softening of F1
  (READ for L&R), and it exists only for σ < 0. ``fc = inf`` (the default) switches it off and
  leaves the law exactly as it was without a cap.

Return mapping: Euler backward with an active-set search over {F1}, {F2}, {F1, F2} (violated
surfaces by decreasing relative violation, then the corner, started from the end state of the
rejected cap return, from the linearised (cutting-plane) multipliers, then from the end state of
the rejected hyperbola return), accepted when every
Δλ ≥ 0, the inactive surface holds and the slip keeps its sign. Each set is a safeguarded Newton
method on the unknowns (σ, τ, Δλ…) (3 or 4) whose Jacobian is formed by central differences
(h = 1e-7 relative); the algorithmic tangent follows from the implicit function theorem,
``∂x/∂t_tr = J⁻¹ [I; 0]``, so it is exact up to the differencing error (~1e-9 relative).
Sub-stepping (2…64 parts) when no set gives a consistent return.
"""

import math

import numba
import numpy as np

from ..admissibility import Inequality
from .composite import INEQUALITIES as COMPOSITE_INEQUALITIES
from .composite import cap_kappa_m, cap_strength
from .state import InterfaceState, LawUpdate

KN, KS, FT, GFI, C, TANPHI0, TANPHIR, GFII, TANPSI, FC, CSS, KP, KM, SI, SM, SR, SHAPE = range(17)
N_PROPS = 17
PROPERTY_NAMES = ("kn", "ks", "ft", "GfI", "c", "tanphi0", "tanphir", "GfII", "tanpsi", "fc", "Cs",
                  "kappa_p", "kappa_m", "sig_i", "sig_m", "sig_r", "cap_shape")
#: codes of the ``cap_shape`` column
CAP_SHAPES = ("ellipse", "hyperbola")
MAX_ITERATIONS = 40
MAX_SUBSTEP_LEVEL = 6  # up to 2**6 sub-steps


@numba.njit(cache=True)
def _cap(p, sig, tau, k3, compressive_only):
    """F2 (MPa) and its gradient m3 = ∂F2/∂t at (σ, τ, κ3); -inf where the cap is switched off
    and, with ``compressive_only``, for σ ≥ 0 (the local Newton uses the formula everywhere)."""
    if not math.isfinite(p[FC]) or (compressive_only and sig >= 0.0):
        return -np.inf, 0.0, 0.0
    s3, _ = cap_strength(p[FC], p[SI], p[SM], p[SR], p[KP], p[KM], k3)
    if p[SHAPE] == 0.0:
        r = math.sqrt(sig * sig + p[CSS] * tau * tau)
        if r == 0.0:  # the centre of the ellipse: any direction; the compressive one
            return -s3, -1.0, 0.0
        return r - s3, sig / r, p[CSS] * tau / r
    r = math.sqrt(p[CSS] * tau * tau + s3 * s3)
    return r - 2.0 * s3 - sig, -1.0, p[CSS] * tau / r


@numba.njit(cache=True)
def _residual(p, has1, has3, x, sig_tr, tau_tr, kap_n, k3_n, out, kap3):
    """Residual (2 + has1 + has3,) at x = (σ, τ[, Δλ1][, Δλ3]); κ and κ3 of the end state in kap3.

    κ enters its own update through tanφ(κ) and a(κ): two fixed-point passes from κ_n (the work
    increment of a step is small against G_f, so the second pass changes κ by O(Δκ²)); κ3 the
    same way through ‖m3‖ (exact for the ellipse, whose ‖m3‖ does not depend on κ3)."""
    sig, tau = x[0], x[1]
    kap = kap_n
    k3 = k3_n
    if has1:
        dl = x[2]
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
    else:
        out[0] = sig - sig_tr
        out[1] = tau - tau_tr
    if has3:
        j = 2 + has1
        l3 = x[j]
        f3 = m0 = m1 = 0.0
        for _ in range(2):  # κ3 depends on the end state through ‖m3‖ (the hyperbola's)
            f3, m0, m1 = _cap(p, sig, tau, k3, False)
            k3 = k3_n + l3 * math.sqrt(m0 * m0 + m1 * m1)
        f3, m0, m1 = _cap(p, sig, tau, k3, False)
        out[0] += p[KN] * l3 * m0
        out[1] += p[KS] * l3 * m1
        out[j] = f3
    kap3[0] = kap
    kap3[1] = k3


@numba.njit(cache=True)
def _jacobian(p, has1, has3, n, x, sig_tr, tau_tr, kap_n, k3_n, scale, J):
    r1 = np.empty(4)
    r2 = np.empty(4)
    kk = np.empty(2)
    xp = x.copy()
    for j in range(n):
        h = 1e-7 * scale[j]
        xp[j] = x[j] + h
        _residual(p, has1, has3, xp, sig_tr, tau_tr, kap_n, k3_n, r1, kk)
        xp[j] = x[j] - h
        _residual(p, has1, has3, xp, sig_tr, tau_tr, kap_n, k3_n, r2, kk)
        xp[j] = x[j]
        for i in range(n):
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
def _inverse(J, n, out):
    """Inverse of the leading n×n block (n = 3 by cofactors, n = 4 by Gauss–Jordan elimination
    with partial pivoting); False when singular."""
    if n == 3:
        return _inverse3(J, out)
    A = np.zeros((n, 2 * n))
    for i in range(n):
        for j in range(n):
            A[i, j] = J[i, j]
        A[i, n + i] = 1.0
    big = 0.0
    for i in range(n):
        for j in range(n):
            big = max(big, abs(J[i, j]))
    for col in range(n):
        piv = col
        for r in range(col + 1, n):
            if abs(A[r, col]) > abs(A[piv, col]):
                piv = r
        if not abs(A[piv, col]) > 1e-14 * big:
            return False
        for j in range(2 * n):
            A[col, j], A[piv, j] = A[piv, j], A[col, j]
        d = A[col, col]
        for j in range(2 * n):
            A[col, j] /= d
        for r in range(n):
            if r != col and A[r, col] != 0.0:
                f = A[r, col]
                for j in range(2 * n):
                    A[r, j] -= f * A[col, j]
    for i in range(n):
        for j in range(n):
            out[i, j] = A[i, n + j]
    return True


@numba.njit(cache=True)
def _yield(p, sig, tau, kap):
    tphi = p[TANPHI0] + (p[TANPHIR] - p[TANPHI0]) * kap
    a = max(p[C] * (1.0 - kap) - p[FT] * (1.0 - kap) * tphi, 0.0)
    return math.sqrt(tau * tau + a * a) - (p[C] * (1.0 - kap) - sig * tphi)


@numba.njit(cache=True)
def _linear_multiplier(p, which, sig, tau, kap, k3):
    """Δλ of one step of the cutting-plane method on F1 (``which`` 0) or the cap (1) from (σ, τ):
    ⟨F⟩ / (n · D m), at least a tiny positive value."""
    if which == 0:
        tphi = p[TANPHI0] + (p[TANPHIR] - p[TANPHI0]) * kap
        a = max(p[C] * (1.0 - kap) - p[FT] * (1.0 - kap) * tphi, 0.0)
        rho = math.sqrt(tau * tau + a * a) + 1e-300
        f = _yield(p, sig, tau, kap)
        mn = p[TANPSI] + (tphi - p[TANPSI]) * a / rho
        h = tphi * p[KN] * mn + (tau / rho) * p[KS] * (tau / rho)
    else:
        f, n0, n1 = _cap(p, sig, tau, k3, False)
        h = n0 * p[KN] * n0 + n1 * p[KS] * n1
    return max(f, 1e-12 * p[C]) / h if h > 0.0 else 1e-12


@numba.njit(cache=True)
def _try_set(p, has1, has3, x, sig_tr, tau_tr, kap_n, k3_n, tol, stress, t, up_n, up, D):
    """Newton on the active set from the start x (n,); returns (accepted, iterations); on
    acceptance t, up = (u_n^p, u_s^p, κ, κ3), D (tangent) and x (the multipliers) are set."""
    kn, ks = p[KN], p[KS]
    n = 2 + has1 + has3
    scale = np.array([stress, stress, stress / kn, stress / kn])
    R = np.empty(4)
    Rt = np.empty(4)
    J = np.empty((4, 4))
    xt = np.empty(4)
    Jinv = np.empty((4, 4))
    dx = np.empty(4)
    kk = np.empty(2)
    for it in range(1, MAX_ITERATIONS + 1):
        _residual(p, has1, has3, x, sig_tr, tau_tr, kap_n, k3_n, R, kk)
        _jacobian(p, has1, has3, n, x, sig_tr, tau_tr, kap_n, k3_n, scale, J)
        if not _inverse(J, n, Jinv):
            return False, it
        for i in range(n):
            v = 0.0
            for j in range(n):
                v += Jinv[i, j] * R[j]
            dx[i] = -v
        r0 = 0.0
        for i in range(n):
            r0 += abs(R[i])
        eta = 1.0
        rt = 0.0
        for _ in range(10):
            for i in range(n):
                xt[i] = x[i] + eta * dx[i]
            for i in range(2, n):
                xt[i] = max(xt[i], 0.0)
            _residual(p, has1, has3, xt, sig_tr, tau_tr, kap_n, k3_n, Rt, kk)
            rt = 0.0
            for i in range(n):
                rt += abs(Rt[i])
            if rt < r0:
                break
            eta *= 0.5
        for i in range(n):
            x[i] = xt[i]
        if rt <= tol:
            _residual(p, has1, has3, x, sig_tr, tau_tr, kap_n, k3_n, R, kk)
            for i in range(2, n):
                if x[i] < 0.0:
                    return False, it
            if tau_tr * x[1] < -tol * abs(tau_tr):
                return False, it  # the slip changed sign: not a return
            if not has1 and _yield(p, x[0], x[1], kap_n) > tol:
                return False, it
            if not has3 and _cap(p, x[0], x[1], k3_n, True)[0] > tol:
                return False, it
            _jacobian(p, has1, has3, n, x, sig_tr, tau_tr, kap_n, k3_n, scale, J)
            if not _inverse(J, n, Jinv):
                return False, it
            # dx/dt_tr = J⁻¹ [I; 0] (R1, R2 contain −t_tr); dt/du = dt/dt_tr · D
            for i in range(2):
                for j in range(2):
                    D[i, j] = Jinv[i, j] * (kn if j == 0 else ks)
            t[0], t[1] = x[0], x[1]
            up[0] = up_n[0] + (sig_tr - x[0]) / kn
            up[1] = up_n[1] + (tau_tr - x[1]) / ks
            up[2] = kk[0]
            up[3] = kk[1]
            return True, it
    return False, MAX_ITERATIONS


@numba.njit(cache=True)
def _return_once(p, du, t_n, up_n, kap_n, k3_n, t, up, D):
    """One step; returns (status 0/2, iterations); up = (u_n^p, u_s^p, κ, κ3) of the end state."""
    kn, ks = p[KN], p[KS]
    sig_tr = t_n[0] + kn * du[0]
    tau_tr = t_n[1] + ks * du[1]
    D[0, 0], D[0, 1], D[1, 0], D[1, 1] = kn, 0.0, 0.0, ks
    stress = abs(sig_tr) + abs(tau_tr) + p[C] + 1e-12
    tol = 1e-11 * stress
    f1 = _yield(p, sig_tr, tau_tr, kap_n)
    f3, n30, n31 = _cap(p, sig_tr, tau_tr, k3_n, False)  # the gradient: the corner's start
    if sig_tr >= 0.0:
        f3 = -np.inf
    if f1 <= tol and f3 <= tol:
        t[0], t[1] = sig_tr, tau_tr
        up[0], up[1], up[2], up[3] = up_n[0], up_n[1], kap_n, k3_n
        return 0, 0
    x = np.zeros(4)
    # candidate sets (has1, has3): violated singles by decreasing violation, then the corner
    cand = np.zeros((3, 2), dtype=np.int64)
    nc = 0
    if f1 > tol and (f3 <= tol or f1 >= f3):
        cand[nc, 0], cand[nc, 1] = 1, 0
        nc += 1
    if f3 > tol:
        cand[nc, 0], cand[nc, 1] = 0, 1
        nc += 1
    if f1 > tol and nc == 1 and cand[0, 0] == 0:
        cand[nc, 0], cand[nc, 1] = 1, 0
        nc += 1
    if math.isfinite(p[FC]) and (sig_tr < 0.0 or f3 > tol):
        cand[nc, 0], cand[nc, 1] = 1, 1
        nc += 1
    # end states (σ, τ, Δλ) of the single-surface attempts that converged but were rejected
    # (the other surface violated): the corner's best starting points
    single = np.zeros((2, 3))
    tried = np.zeros(2, dtype=np.bool_)
    l1 = l3 = m10 = n11 = 0.0
    last = 0
    for c in range(nc):
        has1, has3 = cand[c, 0], cand[c, 1]
        starts = 1
        if has1 and has3:
            starts = 3
            # cutting-plane start: linearised multipliers at the trial state, n_i · D m_j λ_j = f_i
            tphi = p[TANPHI0] + (p[TANPHIR] - p[TANPHI0]) * kap_n
            a = max(p[C] * (1.0 - kap_n) - p[FT] * (1.0 - kap_n) * tphi, 0.0)
            rho = math.sqrt(tau_tr * tau_tr + a * a) + 1e-300
            n10, n11 = tphi, tau_tr / rho
            m10 = p[TANPSI] + (tphi - p[TANPSI]) * a / rho
            A00 = n10 * kn * m10 + n11 * ks * n11
            A01 = n10 * kn * n30 + n11 * ks * n31
            A10 = n30 * kn * m10 + n31 * ks * n11
            A11 = n30 * kn * n30 + n31 * ks * n31
            b0, b1 = max(f1, 0.0), max(f3, 0.0)
            det = A00 * A11 - A01 * A10
            l1 = (A11 * b0 - A01 * b1) / det if det != 0.0 else 0.0
            l3 = (A00 * b1 - A10 * b0) / det if det != 0.0 else 0.0
            big = max(abs(l1), abs(l3), 1e-30)
            l1, l3 = max(l1, 1e-3 * big), max(l3, 1e-3 * big)
        for attempt in range(starts):
            if has1 and has3:
                # starts: the cap's end state, the cutting plane, the hyperbola's end state
                if attempt == 0 or attempt == 2:
                    j = 1 if attempt == 0 else 0
                    if not tried[j]:
                        continue
                    x[0], x[1] = single[j, 0], single[j, 1]
                    # the other multiplier from that surface's linearised violation there
                    other = _linear_multiplier(p, 1 - j, x[0], x[1], kap_n, k3_n)
                    x[2] = single[0, 2] if j == 0 else other
                    x[3] = single[1, 2] if j == 1 else other
                else:
                    x[0] = sig_tr - kn * (l1 * m10 + l3 * n30)
                    x[1] = tau_tr - ks * (l1 * n11 + l3 * n31)
                    x[2], x[3] = l1, l3
            else:
                x[0], x[1], x[2], x[3] = sig_tr, tau_tr, 0.0, 0.0
            ok, it = _try_set(p, has1, has3, x, sig_tr, tau_tr, kap_n, k3_n, tol, stress, t, up_n, up, D)
            if ok:
                return 0, it
            if not (has1 and has3) and it < MAX_ITERATIONS and x[2] > 0:
                j = 0 if has1 else 1
                single[j, 0], single[j, 1], single[j, 2] = x[0], x[1], x[2]
                tried[j] = True
            last = it
    return 2, last


@numba.njit(cache=True)
def hyperbolic_update(du, jump_n, t_n, up_n, kap_n, work_n, props):
    """Vectorised update; arrays as :func:`fe.interfaces.composite.composite_update` (κ in
    kappa[:, 0], κ3 of the cap in kappa[:, 2], mm)."""
    n = du.shape[0]
    jump = jump_n + du
    t = np.empty((n, 2))
    up = np.empty((n, 2))
    kap = kap_n.copy()
    work = np.empty(n)
    tangent = np.empty((n, 2, 2))
    iterations = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int64)
    out = np.empty(4)
    for e in range(n):
        p = props[e]
        st, it = _return_once(p, du[e], t_n[e], up_n[e], kap_n[e, 0], kap_n[e, 2], t[e], out, tangent[e])
        iterations[e] = it
        if st != 0:
            for level in range(1, MAX_SUBSTEP_LEVEL + 1):
                parts = 2 ** level
                ts = t_n[e].copy()
                ups = np.array([up_n[e, 0], up_n[e, 1], kap_n[e, 0], kap_n[e, 2]])
                inc = du[e] / parts
                ok = True
                for _ in range(parts):
                    st, it = _return_once(p, inc, ts, ups, ups[2], ups[3], t[e], out, tangent[e])
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
                out[0], out[1], out[2], out[3] = up_n[e, 0], up_n[e, 1], kap_n[e, 0], kap_n[e, 2]
        status[e] = st
        up[e, 0], up[e, 1] = out[0], out[1]
        kap[e, 0] = out[2]
        kap[e, 2] = out[3]
        work[e] = work_n[e] + 0.5 * ((t_n[e, 0] + t[e, 0]) * (up[e, 0] - up_n[e, 0])
                                     + (t_n[e, 1] + t[e, 1]) * (up[e, 1] - up_n[e, 1]))
    return jump, t, up, kap, work, tangent, iterations, status


def _cap_slope(p):
    """The steepest softening slope of the cap, 2 f_c (1 − σ̄_m/f_c)/(κ_m − κ_p) = 2 (1 − r_m) A f_c²/G_fc
    (N/mm³; κ_m − κ_p = G_fc/(A f_c) by :func:`~fe.interfaces.composite.cap_kappa_m`)."""
    ratios = p.get("cap_ratios", (1 / 3, 1 / 2, 1 / 7))
    return 2.0 * p["fc"] * (1.0 - ratios[1]) / cap_kappa_m(p["fc"], p["Gfc"], 0.0, ratios)  # κ_p cancels


#: k_n above the steepest softening slope of the cap (only with a cap: a finite ``fc``).
CAP_SNAP_BACK = Inequality(
    "cap_snap_back", "0.818 {fc}² / {Gfc}", "{kn}", "N/mm³",
    "the steepest softening slope of the cap 2 fc (1 − sig_m/fc)/(kappa_m − kappa_p) (default cap ratios) "
    "must stay below kn: else local snap-back in compression",
    _cap_slope, lambda p: p["kn"], strict=True, applies=lambda p: np.isfinite(p["fc"]))

#: The admissible combinations of the law's properties, checked by :func:`hyperbolic_properties`
#: and, read in a scenario's parameter names, over a whole sampling box before any FE run
#: (:mod:`fe.admissibility`). Each side is monotone in each property (the cap's slope is
#: 2 (1 − r_m) A f_c²/G_fc, free of κ_p).
INEQUALITIES = (
    Inequality("friction", "0", "min({tanphi0}, {tanphir})", "-",
               "the normal flow at the apex of the hyperbola is tanφ",
               lambda p: 0.0, lambda p: min(p["tanphi0"], p["tanphir"]), strict=True),
    Inequality("dilatancy", "{tanpsi}", "min({tanphi0}, {tanphir})", "-",
               "more dilatancy than friction is not admissible",
               lambda p: p["tanpsi"], lambda p: min(p["tanphi0"], p["tanphir"])),
    Inequality("tension_apex", "{ft}", "{c} / max({tanphi0}, {tanphir})", "MPa",
               "the hyperbola needs a real apex: the tensile strength may not exceed the tension at the "
               "apex of its Coulomb asymptote",
               lambda p: p["ft"], lambda p: p["c"] / max(p["tanphi0"], p["tanphir"])),
    next(i for i in COMPOSITE_INEQUALITIES if i.key == "tension_snap_back"),
    CAP_SNAP_BACK,
)


def hyperbolic_properties(*, kn, ks, ft, GfI, c, tanphi0, tanphir=None, GfII, tanpsi=0.0, fc=np.inf, Cs=9.0,
                          Gfc=5.0, kappa_p=0.09, cap_ratios=(1 / 3, 1 / 2, 1 / 7), cap_shape="ellipse",
                          where="interface"):
    """One property row (columns :data:`PROPERTY_NAMES`), checked for admissibility.

    Parameters (units N, mm, MPa): ``kn``, ``ks`` (N/mm³); ``ft`` = σ_t (MPa), ``GfI`` (N/mm);
    ``c`` (MPa), ``tanphi0``, ``tanphir`` (default ``tanphi0``), ``GfII`` (N/mm), ``tanpsi``; the
    cap (module docstring; INFERRED shape and law, ``docs/references.md``): ``fc`` (MPa; ``inf``, the default, switches it
    off), ``Cs`` (shear contribution), ``Gfc`` (N/mm, post-peak area above the residual),
    ``kappa_p`` (mm, plastic relative displacement at the peak), ``cap_ratios`` =
    (σ̄_i, σ̄_m, σ̄_r)/f_c, ``cap_shape`` (one of :data:`CAP_SHAPES`). ``where`` names the interface
    family in error messages.

    Raises
    ------
    ValueError
        Naming the quantity and the reason: positive strengths and energies, and the inequalities
        of :data:`INEQUALITIES`: σ_t ≤ c/tanφ (a ≥ 0 while softening), tanφ > 0 (the normal flow
        at the apex is tanφ), tanψ ≤ tanφ, k_n > σ_t²/G_f^I (local snap-back in tension); for the
        cap: a known shape, positive C_s, G_fc, κ_p, ordered ratios and k_n above the steepest
        softening slope of the cap 2 f_c (1 − σ̄_m/f_c)/(κ_m − κ_p) (else the crushing return has no
        unique solution: local snap-back in compression).
    """
    tanphir = tanphi0 if tanphir is None else tanphir
    for name, v in (("kn", kn), ("ks", ks), ("ft", ft), ("GfI", GfI), ("c", c), ("GfII", GfII)):
        if not (v > 0 and np.isfinite(v)):
            raise ValueError(f"{where}: {name} must be finite and > 0; got {v}")
    for name, v in (("tanphi0", tanphi0), ("tanphir", tanphir), ("tanpsi", tanpsi)):
        if not (v >= 0 and np.isfinite(v)):
            raise ValueError(f"{where}: {name} must be finite and >= 0; got {v}")
    if not fc > 0:
        raise ValueError(f"{where}: cap strength fc must be > 0 MPa (inf: no cap); got {fc}")
    props = dict(kn=kn, ks=ks, ft=ft, GfI=GfI, c=c, tanphi0=tanphi0, tanphir=tanphir, GfII=GfII, tanpsi=tanpsi,
                 fc=fc, Gfc=Gfc, kappa_p=kappa_p, cap_ratios=cap_ratios)
    for inequality in INEQUALITIES:
        if inequality.key != "cap_snap_back":  # after the cap's own parameters are checked
            inequality.check(props, where)
    if cap_shape not in CAP_SHAPES:
        raise ValueError(f"{where}: cap_shape must be one of {CAP_SHAPES}; got {cap_shape!r}")
    km = np.inf
    if np.isfinite(fc):
        for name, v in (("Cs", Cs), ("Gfc", Gfc), ("kappa_p", kappa_p)):
            if not (v > 0 and np.isfinite(v)):
                raise ValueError(f"{where}: cap parameter {name} must be finite and > 0; got {v}")
        ri, rm, rr = cap_ratios
        if not (0 < ri <= 1 and 0 < rr < rm < 1):
            raise ValueError(f"{where}: cap_ratios (sig_i, sig_m, sig_r)/fc must satisfy 0 < sig_i <= 1 and "
                             f"0 < sig_r < sig_m < 1; got {cap_ratios}")
        km = cap_kappa_m(fc, Gfc, kappa_p, cap_ratios)
        CAP_SNAP_BACK.check(props, where)
    ri, rm, rr = cap_ratios
    return np.array([kn, ks, ft, GfI, c, tanphi0, tanphir, GfII, tanpsi, fc, Cs, kappa_p, km, ri, rm, rr,
                     float(CAP_SHAPES.index(cap_shape))], dtype=float)


class HyperbolicInterface:
    """The hyperbolic law (with its optional cap) for ``n`` points, same API as
    :class:`~fe.interfaces.CompositeInterface`; rows from :func:`hyperbolic_properties`.

    Example
    -------
    >>> import numpy as np
    >>> row = hyperbolic_properties(kn=82, ks=36, ft=0.25, GfI=0.018, c=0.35, tanphi0=0.75, GfII=0.125, fc=10.5)
    >>> law = HyperbolicInterface(row[None])
    >>> upd = law.update(np.array([[-0.1, 0.0]]), law.initial_state())
    >>> bool(-upd.state.traction[0, 0] < 8.2)      # crushing: the cap (f_c/3 at first yield) limits σ
    True
    """

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
