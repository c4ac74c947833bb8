"""Lourenço–Rots composite interface law: tension cut-off, Coulomb friction, compressive cap.

Thesis §2.2 (the mesoscale model) with the surfaces of Lourenço & Rots (1997, ``docs/references.md``;
the equations as OOFEM's Masonry02 and DIANA's "Combined Cracking-Shearing-Crushing" state them). Tension positive, traction ``t = (σ, τ)`` normal first,
``t = D (u − u^p)``, ``D = diag(k_n, k_s)``:

- f1 = σ − σ̄1(κ1),  σ̄1 = f_t exp(−f_t κ1 / G_f^I); associated flow m1 = (1, 0).
- f2 = |τ| + σ tanφ(κ2) − σ̄2(κ2),  σ̄2 = c exp(−c κ2 / G_f^II),
  tanφ = tanφ0 + (tanφr − tanφ0)(c − σ̄2)/c; non-associated flow m2 = (tanψ, sign τ).
- f3 = C_nn σ² + C_ss τ² + C_n σ − σ̄3(κ3)² for σ < 0; associated flow, κ̇3 = λ̇3 ‖m3‖.
- Coupled softening of f1/f2, α = G_f^I c / (G_f^II f_t): κ̇1 = λ̇1 + α λ̇2, κ̇2 = λ̇1/α + λ̇2,
  and in the corner κ̇1 = √(λ̇1² + (α λ̇2)²), κ̇2 = κ̇1/α.

Return mapping: Euler-backward closest point. Every active set {1}, {2}, {3}, {1,2}, {2,3} is a
Newton problem in its Δλ (1 or 2 unknowns) with the traction explicit in Δλ (the cap's flow is
linear in t); the set is searched in a fixed order (violated single surfaces by decreasing
relative violation, then the corners) and accepted when every Δλ ≥ 0, no inactive surface is
violated and the slip does not change sign. Without a consistent return the increment is split
into 2, 4, …, 64 sub-steps. The algorithmic tangent is the exact derivative of the return map
(implicit function theorem on the local residual), non-symmetric when ψ ≠ φ.

INFERRED choices (named, configurable through the parameters of :class:`CompositeInterface`):

- cap hardening/softening law (READ shape): ``σ̄3 = σ̄_i + (σ̄_p − σ̄_i)(2κ/κ_p − κ²/κ_p²)`` up to
  κ_p (OOFEM's parabola replacing the infinitely steep first branch), a parabola to (κ_m, σ̄_m),
  then an exponential to σ̄_r; ``cap_ratios = (σ̄_i, σ̄_m, σ̄_r)/f_c = (1/3, 1/2, 1/7)`` (OOFEM's
  commented defaults); C_nn = 1, C_n = 0, C_ss = C_s.
- κ_m from G_fc: G_fc is taken as the post-peak area above the residual,
  ``∫_{κ_p}^∞ (σ̄3 − σ̄_r) dκ3`` (the L&R closed form is NOT FOUND), which is linear in κ_m − κ_p.
- the cap only exists on the compressive side (σ < 0).
- a surface with an infinite strength (``f_t``, ``c`` or ``f_c`` = inf) is switched off.
"""

import logging
import math

import numba
import numpy as np

from ..admissibility import Inequality
from .state import InterfaceState, LawUpdate

logger = logging.getLogger(__name__)

# columns of the per-point property array
KN, KS, FT, GFI, C, TANPHI0, TANPHIR, GFII, TANPSI, FC, CSS, CNN, CN, KP, KM, SI, SM, SR = range(18)
N_PROPS = 18
PROPERTY_NAMES = ("kn", "ks", "ft", "GfI", "c", "tanphi0", "tanphir", "GfII", "tanpsi", "fc", "Css",
                  "Cnn", "Cn", "kappa_p", "kappa_m", "sig_i", "sig_m", "sig_r")

MAX_LOCAL_ITERATIONS = 30
MAX_SUBSTEP_LEVEL = 6  # up to 2**6 sub-steps
_RTOL = 1e-11


def cap_kappa_m(fc, Gfc, kappa_p, ratios=(1 / 3, 1 / 2, 1 / 7)):
    """κ_m (mm) of the cap law such that ``∫_{κ_p}^∞ (σ̄3 − σ̄_r) dκ3 = G_fc`` (COMPUTED closed form).

    With σ̄_p = f_c, σ̄_m = r_m f_c, σ̄_r = r_r f_c the area is
    ``(κ_m − κ_p) [(σ̄_p − σ̄_r) + (σ̄_m − σ̄_p)/3 + (σ̄_m − σ̄_r)² / (2 (σ̄_p − σ̄_m))]``.
    """
    _, rm, rr = ratios
    factor = (1.0 - rr) + (rm - 1.0) / 3.0 + (rm - rr) ** 2 / (2.0 * (1.0 - rm))
    return kappa_p + Gfc / (factor * fc)


@numba.njit(cache=True)
def _cap_strength(p, k3):
    """σ̄3(κ3) and its derivative (MPa, MPa/mm)."""
    return cap_strength(p[FC], p[SI], p[SM], p[SR], p[KP], p[KM], k3)


@numba.njit(cache=True)
def cap_strength(fc, ri, rm, rr, kp, km, k3):
    """The cap's C¹ hardening/softening law σ̄3(κ3) and its derivative (MPa, MPa/mm).

    ``fc`` peak (MPa), ``(ri, rm, rr)`` = (σ̄_i, σ̄_m, σ̄_r)/f_c, ``kp``, ``km`` (mm): a parabola
    from σ̄_i to the peak f_c at κ_p, a parabola to (κ_m, σ̄_m), an exponential to σ̄_r (module
    docstring; shared with :mod:`fe.interfaces.hyperbolic`)."""
    si, sp, sm, sr = ri * fc, fc, rm * fc, rr * fc
    if k3 < kp:
        x = k3 / kp
        return si + (sp - si) * (2.0 * x - x * x), (sp - si) * (2.0 - 2.0 * x) / kp
    if k3 < km:
        x = (k3 - kp) / (km - kp)
        return sp + (sm - sp) * x * x, 2.0 * (sm - sp) * x / (km - kp)
    m = 2.0 * (sm - sp) / (km - kp)
    e = math.exp(m * (k3 - km) / (sm - sr))
    return sr + (sm - sr) * e, m * e


@numba.njit(cache=True)
def _surfaces(p, sig, tau, s, kap, f, ft_, fk):
    """Yield values f (3,), gradients ∂f/∂t ft_ (3, 2), ∂f/∂κ fk (3, 3) at (σ, τ, κ).

    ``s`` is the slip direction used for |τ| in f2 (sign of the trial τ). Switched-off surfaces
    (infinite strength) and the cap in tension get f = -inf.
    """
    for i in range(3):
        f[i] = -np.inf
        for j in range(2):
            ft_[i, j] = 0.0
        for j in range(3):
            fk[i, j] = 0.0
    if math.isfinite(p[FT]):
        s1 = p[FT] * math.exp(-p[FT] * kap[0] / p[GFI])
        f[0] = sig - s1
        ft_[0, 0] = 1.0
        fk[0, 0] = p[FT] / p[GFI] * s1
    if math.isfinite(p[C]):
        c0 = p[C]
        s2 = c0 * math.exp(-c0 * kap[1] / p[GFII])
        ds2 = -c0 / p[GFII] * s2
        tphi = p[TANPHI0] + (p[TANPHIR] - p[TANPHI0]) * (c0 - s2) / c0
        dtphi = -(p[TANPHIR] - p[TANPHI0]) * ds2 / c0
        f[1] = s * tau + sig * tphi - s2
        ft_[1, 0] = tphi
        ft_[1, 1] = s
        fk[1, 1] = sig * dtphi - ds2
    if math.isfinite(p[FC]) and sig < 0.0:
        s3, ds3 = _cap_strength(p, kap[2])
        f[2] = p[CNN] * sig * sig + p[CSS] * tau * tau + p[CN] * sig - s3 * s3
        ft_[2, 0] = 2.0 * p[CNN] * sig + p[CN]
        ft_[2, 1] = 2.0 * p[CSS] * tau
        fk[2, 2] = -2.0 * s3 * ds3


@numba.njit(cache=True)
def _tolerances(p, sig_tr, tau_tr, tol):
    scale = abs(sig_tr) + abs(tau_tr) + 1e-12
    tol[0] = _RTOL * (scale + (p[FT] if math.isfinite(p[FT]) else 0.0))
    tol[1] = _RTOL * (scale + (p[C] if math.isfinite(p[C]) else 0.0))
    fc = p[FC] if math.isfinite(p[FC]) else 0.0
    tol[2] = _RTOL * (scale + fc) ** 2


@numba.njit(cache=True)
def _solve_small(A, b, k, out):
    """Solve the k×k (k ≤ 2) system A out = b; False when singular."""
    if k == 1:
        if A[0, 0] == 0.0:
            return False
        out[0] = b[0] / A[0, 0]
        return True
    det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    scale = abs(A[0, 0] * A[1, 1]) + abs(A[0, 1] * A[1, 0])
    if scale == 0.0 or abs(det) < 1e-13 * scale:
        return False
    out[0] = (A[1, 1] * b[0] - A[0, 1] * b[1]) / det
    out[1] = (A[0, 0] * b[1] - A[1, 0] * b[0]) / det
    return True


@numba.njit(cache=True)
def _state_of(p, act, k, x, sig_tr, tau_tr, s, kap_n, alpha, coupled,
              t, t_dl, t_tr, kap, kap_dl, kap_t):
    """Traction, κ and their derivatives for multipliers x on the active set ``act[:k]``."""
    kn, ks = p[KN], p[KS]
    l1 = l2 = l3 = 0.0
    for a in range(k):
        if act[a] == 0:
            l1 = x[a]
        elif act[a] == 1:
            l2 = x[a]
        else:
            l3 = x[a]
    a1 = 1.0 + 2.0 * kn * p[CNN] * l3
    a2 = 1.0 + 2.0 * ks * p[CSS] * l3
    sig = (sig_tr - kn * l1 - kn * p[TANPSI] * l2 - kn * p[CN] * l3) / a1
    tau = (tau_tr - ks * s * l2) / a2
    t[0], t[1] = sig, tau
    t_tr[0] = 1.0 / a1
    t_tr[1] = 1.0 / a2
    for a in range(k):
        i = act[a]
        if i == 0:
            t_dl[0, a], t_dl[1, a] = -kn / a1, 0.0
        elif i == 1:
            t_dl[0, a], t_dl[1, a] = -kn * p[TANPSI] / a1, -ks * s / a2
        else:
            t_dl[0, a] = (-kn * p[CN] - sig * 2.0 * kn * p[CNN]) / a1
            t_dl[1, a] = -tau * 2.0 * ks * p[CSS] / a2
    for i in range(3):
        kap[i] = kap_n[i]
        for j in range(2):
            kap_t[i, j] = 0.0
        for a in range(2):
            kap_dl[i, a] = 0.0
    has1 = has2 = False
    a_1 = a_2 = -1
    for a in range(k):
        if act[a] == 0:
            has1, a_1 = True, a
        elif act[a] == 1:
            has2, a_2 = True, a
    # coupled κ1/κ2
    if has1 and has2 and coupled:
        r = math.sqrt(l1 * l1 + alpha * alpha * l2 * l2)
        kap[0] += r
        kap[1] += r / alpha
        d1 = l1 / r if r > 0 else 1.0
        d2 = alpha * alpha * l2 / r if r > 0 else alpha
        kap_dl[0, a_1], kap_dl[0, a_2] = d1, d2
        kap_dl[1, a_1], kap_dl[1, a_2] = d1 / alpha, d2 / alpha
    else:
        if has1:
            kap[0] += l1
            kap_dl[0, a_1] = 1.0
            if coupled:
                kap[1] += l1 / alpha
                kap_dl[1, a_1] = 1.0 / alpha
        if has2:
            kap[1] += l2
            kap_dl[1, a_2] = 1.0
            if coupled:
                kap[0] += alpha * l2
                kap_dl[0, a_2] = alpha
    for a in range(k):
        if act[a] == 2:
            m0 = 2.0 * p[CNN] * sig + p[CN]
            m1 = 2.0 * p[CSS] * tau
            nm = math.sqrt(m0 * m0 + m1 * m1)
            kap[2] += l3 * nm
            kap_dl[2, a] = nm
            if nm > 0:
                kap_t[2, 0] = l3 * 2.0 * p[CNN] * m0 / nm
                kap_t[2, 1] = l3 * 2.0 * p[CSS] * m1 / nm


@numba.njit(cache=True)
def _try_set(p, act, k, sig_tr, tau_tr, s, kap_n, alpha, coupled, tol, x0,
             t, kap, x, D_alg):
    """Closest-point return on the active set ``act[:k]``; returns (accepted, iterations)."""
    t_dl = np.zeros((2, 2))
    t_tr = np.zeros(2)
    kap_dl = np.zeros((3, 2))
    kap_t = np.zeros((3, 2))
    f = np.zeros(3)
    fgrad = np.zeros((3, 2))
    fk = np.zeros((3, 3))
    R = np.zeros(2)
    J = np.zeros((2, 2))
    G = np.zeros((2, 2))
    dx = np.zeros(2)
    xt = np.zeros(2)
    for a in range(k):
        x[a] = x0[a]
    converged = False
    it = 0
    for it in range(MAX_LOCAL_ITERATIONS + 1):
        _state_of(p, act, k, x, sig_tr, tau_tr, s, kap_n, alpha, coupled, t, t_dl, t_tr, kap, kap_dl, kap_t)
        _surfaces(p, t[0], t[1], s, kap, f, fgrad, fk)
        ok = True
        for a in range(k):
            R[a] = f[act[a]]
            if not math.isfinite(R[a]):
                return False, it
            if abs(R[a]) > tol[act[a]]:
                ok = False
        if ok:
            converged = True
            break
        if it == MAX_LOCAL_ITERATIONS:
            break
        for a in range(k):
            i = act[a]
            for j in range(2):
                G[a, j] = fgrad[i, j] + fk[i, 0] * kap_t[0, j] + fk[i, 1] * kap_t[1, j] + fk[i, 2] * kap_t[2, j]
            for b in range(k):
                J[a, b] = G[a, 0] * t_dl[0, b] + G[a, 1] * t_dl[1, b]
                for m in range(3):
                    J[a, b] += fk[i, m] * kap_dl[m, b]
        if not _solve_small(J, R, k, dx):
            return False, it
        # backtracking on the scaled residual norm; multipliers kept non-negative
        r0 = 0.0
        for a in range(k):
            r0 += (R[a] / tol[act[a]]) ** 2
        eta = 1.0
        for _ in range(8):
            for a in range(k):
                xt[a] = max(x[a] - eta * dx[a], 0.0)
            _state_of(p, act, k, xt, sig_tr, tau_tr, s, kap_n, alpha, coupled, t, t_dl, t_tr, kap, kap_dl, kap_t)
            _surfaces(p, t[0], t[1], s, kap, f, fgrad, fk)
            r1 = 0.0
            for a in range(k):
                r1 += (f[act[a]] / tol[act[a]]) ** 2
            if r1 < r0 or not math.isfinite(r0):
                break
            eta *= 0.5
        for a in range(k):
            x[a] = xt[a]
    if not converged:
        return False, it
    # admissibility of the return
    for a in range(k):
        if x[a] < 0.0:
            return False, it
    for i in range(3):
        active = False
        for a in range(k):
            if act[a] == i:
                active = True
        if not active and f[i] > tol[i]:
            return False, it
    for a in range(k):
        if act[a] == 1 and s * t[1] < -tol[1]:
            return False, it  # the slip changed sign: not a shear return
    # consistent tangent: dt/du = (diag(t_tr) + t_dl dx/dt_tr) D, dx/dt_tr = -J⁻¹ G diag(t_tr)
    for a in range(k):
        i = act[a]
        for j in range(2):
            G[a, j] = fgrad[i, j] + fk[i, 0] * kap_t[0, j] + fk[i, 1] * kap_t[1, j] + fk[i, 2] * kap_t[2, j]
        for b in range(k):
            J[a, b] = G[a, 0] * t_dl[0, b] + G[a, 1] * t_dl[1, b]
            for m in range(3):
                J[a, b] += fk[i, m] * kap_dl[m, b]
    col = np.zeros(2)
    dxdt = np.zeros((2, 2))
    for j in range(2):
        for a in range(k):
            R[a] = -G[a, j] * t_tr[j]
        if not _solve_small(J, R, k, col):
            return False, it
        for a in range(k):
            dxdt[a, j] = col[a]
    kd = (p[KN], p[KS])
    for i in range(2):
        for j in range(2):
            v = t_tr[i] if i == j else 0.0
            for a in range(k):
                v += t_dl[i, a] * dxdt[a, j]
            D_alg[i, j] = v * kd[j]
    return True, it


@numba.njit(cache=True)
def _return_once(p, u_inc, t_n, up_n, kap_n, t, up, kap, D_alg):
    """One Euler-backward step from (t_n, u^p_n, κ_n) for the increment ``u_inc``.

    Returns (status 0 ok / 2 failed, Newton iterations of the accepted active set).
    """
    kn, ks = p[KN], p[KS]
    sig_tr = t_n[0] + kn * u_inc[0]
    tau_tr = t_n[1] + ks * u_inc[1]
    s = 1.0 if tau_tr >= 0.0 else -1.0
    tol = np.zeros(3)
    _tolerances(p, sig_tr, tau_tr, tol)
    f = np.zeros(3)
    fg = np.zeros((3, 2))
    fk = np.zeros((3, 3))
    _surfaces(p, sig_tr, tau_tr, s, kap_n, f, fg, fk)
    D_alg[0, 0], D_alg[0, 1], D_alg[1, 0], D_alg[1, 1] = kn, 0.0, 0.0, ks
    for i in range(3):
        kap[i] = kap_n[i]
    if f[0] <= tol[0] and f[1] <= tol[1] and f[2] <= tol[2]:
        t[0], t[1] = sig_tr, tau_tr
        up[0], up[1] = up_n[0], up_n[1]
        return 0, 0
    alpha = p[GFI] * p[C] / (p[GFII] * p[FT])
    coupled = math.isfinite(alpha) and alpha > 0.0
    # candidate active sets: violated singles by decreasing relative violation, then corners
    rel = np.empty(3)
    for i in range(3):
        rel[i] = f[i] / tol[i] if f[i] > tol[i] else -1.0
    order = np.argsort(-rel)
    cands = np.full((6, 2), -1, dtype=np.int64)
    ks_ = np.zeros(6, dtype=np.int64)
    n = 0
    for q in range(3):
        if rel[order[q]] > 0:
            cands[n, 0], ks_[n] = order[q], 1
            n += 1
    if rel[0] > 0 or rel[1] > 0:
        cands[n, 0], cands[n, 1], ks_[n] = 0, 1, 2
        n += 1
    if rel[1] > 0 or rel[2] > 0:
        cands[n, 0], cands[n, 1], ks_[n] = 1, 2, 2
        n += 1
    x = np.zeros(2)
    x0 = np.zeros(2)
    single = np.full(3, -1.0)  # multipliers of the single-surface attempts: corner starting values
    A = np.zeros((2, 2))
    for c in range(n):
        act = cands[c]
        k = ks_[c]
        x0[0] = x0[1] = 0.0
        tries = 1
        if k == 2:
            # start from the linearised (perfectly plastic) corner multipliers, then from the
            # multipliers of the single-surface attempts
            for a in range(2):
                for b in range(2):
                    ia, ib = act[a], act[b]
                    mb0 = 1.0 if ib == 0 else (p[TANPSI] if ib == 1 else fg[2, 0])
                    mb1 = 0.0 if ib == 0 else (s if ib == 1 else fg[2, 1])
                    A[a, b] = fg[ia, 0] * kn * mb0 + fg[ia, 1] * ks * mb1
            rhs = np.array([max(f[act[0]], 0.0), max(f[act[1]], 0.0)])
            if not _solve_small(A, rhs, 2, x0) or x0[0] <= 0 or x0[1] <= 0:
                big = max(abs(x0[0]), abs(x0[1]), 1e-30)
                x0[0] = max(x0[0], 1e-3 * big)
                x0[1] = max(x0[1], 1e-3 * big)
            tries = 2
        for attempt in range(tries):
            if attempt == 1:
                for a in range(2):
                    x0[a] = single[act[a]] if single[act[a]] > 0 else 1e-3 * max(x0[0], x0[1])
            ok, it = _try_set(p, act, k, sig_tr, tau_tr, s, kap_n, alpha, coupled, tol, x0, t, kap, x, D_alg)
            if k == 1 and it < MAX_LOCAL_ITERATIONS:
                single[act[0]] = x[0]
            if ok:
                l = np.zeros(3)
                for a in range(k):
                    l[act[a]] = x[a]
                m30 = 2.0 * p[CNN] * t[0] + p[CN]
                m31 = 2.0 * p[CSS] * t[1]
                up[0] = up_n[0] + l[0] + l[1] * p[TANPSI] + l[2] * m30
                up[1] = up_n[1] + l[1] * s + l[2] * m31
                return 0, it
    return 2, MAX_LOCAL_ITERATIONS


@numba.njit(cache=True)
def composite_update(du, jump_n, t_n, up_n, kap_n, work_n, props):
    """Vectorised return mapping over all points (see the module docstring).

    Parameters
    ----------
    du : (n, 2) increment of the relative displacement (u_n, u_s), mm.
    jump_n, t_n, up_n, kap_n, work_n : the converged state (see :class:`InterfaceState`).
    props : (n, N_PROPS) per-point properties (columns ``PROPERTY_NAMES``).

    Returns
    -------
    jump, t, up, kap, work, tangent (n, 2, 2), iterations (n,), status (n,)
    """
    n = du.shape[0]
    jump = jump_n + du
    t = np.empty((n, 2))
    up = np.empty((n, 2))
    kap = np.empty((n, 3))
    work = np.empty(n)
    tangent = np.empty((n, 2, 2))
    iterations = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int64)
    inc = np.empty(2)
    ts = np.empty(2)
    ups = np.empty(2)
    ks = np.empty(3)
    t1 = np.empty(2)
    up1 = np.empty(2)
    k1 = np.empty(3)
    for e in range(n):
        p = props[e]
        inc[0], inc[1] = du[e, 0], du[e, 1]
        st, it = _return_once(p, inc, t_n[e], up_n[e], kap_n[e], t[e], up[e], kap[e], tangent[e])
        iterations[e] = it
        if st != 0:
            # sub-stepping: 2, 4, ... equal parts of the increment
            for level in range(1, MAX_SUBSTEP_LEVEL + 1):
                parts = 2 ** level
                ts[:] = t_n[e]
                ups[:] = up_n[e]
                ks[:] = kap_n[e]
                inc[0], inc[1] = du[e, 0] / parts, du[e, 1] / parts
                st = 0
                for _ in range(parts):
                    st, it = _return_once(p, inc, ts, ups, ks, t1, up1, k1, tangent[e])
                    iterations[e] += it
                    if st != 0:
                        break
                    ts[:] = t1
                    ups[:] = up1
                    ks[:] = k1
                if st == 0:
                    t[e, :] = ts
                    up[e, :] = ups
                    kap[e, :] = ks
                    st = 1
                    break
            if st != 1:
                st = 2
                t[e, :] = t_n[e]
                up[e, :] = up_n[e]
                kap[e, :] = kap_n[e]
        status[e] = st
        work[e] = work_n[e] + 0.5 * ((t_n[e, 0] + t[e, 0]) * (up[e, 0] - up_n[e, 0])
                                     + (t_n[e, 1] + t[e, 1]) * (up[e, 1] - up_n[e, 1]))
    return jump, t, up, kap, work, tangent, iterations, status


class CompositeInterface:
    """The Lourenço–Rots composite law for ``n`` integration points with per-point properties.

    Parameters
    ----------
    props : ndarray of shape (n, N_PROPS)
        Per-point properties, columns :data:`PROPERTY_NAMES`; build rows with :func:`composite_properties`.

    Example
    -------
    >>> import numpy as np
    >>> law = CompositeInterface(composite_properties(kn=82, ks=36, ft=0.25, GfI=0.018, c=0.35)[None])
    >>> upd = law.update(np.array([[0.01, 0.0]]), law.initial_state())
    >>> round(float(upd.state.traction[0, 0]), 3) < 0.25     # tension cut-off reached and softening
    True
    """

    name = "composite"

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
        """Return-map the increment ``du`` ``(n, 2)`` (mm, normal first) from the converged ``state``.

        Returns
        -------
        LawUpdate
        """
        du = np.ascontiguousarray(du, dtype=float)
        jump, t, up, kap, work, tangent, iterations, status = composite_update(
            du, state.jump, state.traction, state.plastic, state.kappa, state.work, self.props)
        return LawUpdate(InterfaceState(jump, t, up, kap, work), tangent, iterations, status)

    def elastic_tangent(self):
        """``diag(k_n, k_s)`` per point, ``(n, 2, 2)`` N/mm³."""
        D = np.zeros((len(self.props), 2, 2))
        D[:, 0, 0] = self.props[:, KN]
        D[:, 1, 1] = self.props[:, KS]
        return D

    def near_surfaces(self, state, fraction):
        """Points whose traction is beyond ``fraction`` of their current tension cut-off
        (column 0) or Coulomb strength (column 1), ``(n, 2)`` bool."""
        p, t, k = self.props, state.traction, state.kappa
        out = np.zeros((len(p), 2), bool)
        with np.errstate(invalid="ignore", over="ignore"):
            s1 = p[:, FT] * np.exp(-p[:, FT] * k[:, 0] / p[:, GFI])
            s2 = p[:, C] * np.exp(-p[:, C] * k[:, 1] / p[:, GFII])
            tphi = p[:, TANPHI0] + (p[:, TANPHIR] - p[:, TANPHI0]) * (p[:, C] - s2) / p[:, C]
            out[:, 0] = np.isfinite(p[:, FT]) & (t[:, 0] >= fraction * s1)
            out[:, 1] = np.isfinite(p[:, C]) & (np.abs(t[:, 1]) + t[:, 0] * tphi >= fraction * s2)
        return out

    def damage(self, state):
        """Fraction of cohesion lost, ``1 − σ̄2/c`` ∈ [0, 1] per point (0 where shear is switched off)."""
        c = self.props[:, C]
        finite = np.isfinite(c)
        d = np.zeros(len(c))
        d[finite] = 1.0 - np.exp(-c[finite] * state.kappa[finite, 1] / self.props[finite, GFII])
        return d


def _finite(*names):
    return lambda p: all(np.isfinite(p[n]) for n in names)


#: The admissible combinations of the law's properties, checked by :func:`composite_properties`
#: and, read in a scenario's parameter names, over a whole sampling box before any FE run
#: (:mod:`fe.admissibility`). Each side is monotone in each property. A surface switched off (an
#: infinite ``ft`` or ``c``) or a zero stiffness (a rigid dummy) drops the inequalities it carries.
INEQUALITIES = (
    Inequality("dilatancy", "{tanpsi}", "{tanphi0}", "-",
               "more dilatancy than friction is not admissible",
               lambda p: p["tanpsi"], lambda p: p["tanphi0"], applies=_finite("c")),
    Inequality("tension_apex", "{ft}", "{c} / max({tanphi0}, {tanphir})", "MPa",
               "the Coulomb friction surface also limits tension: the tensile strength may not exceed "
               "the tension at its apex",
               lambda p: p["ft"], lambda p: p["c"] / max(p["tanphi0"], p["tanphir"]),
               applies=lambda p: _finite("ft", "c")(p) and max(p["tanphi0"], p["tanphir"]) > 0),
    Inequality("tension_snap_back", "{ft}² / {GfI}", "{kn}", "N/mm³",
               "else the tension softening branch is steeper than the elastic one: local snap-back, "
               "no unique return",
               lambda p: p["ft"] ** 2 / p["GfI"], lambda p: p["kn"], strict=True,
               applies=lambda p: _finite("ft")(p) and p["kn"] > 0),
    Inequality("shear_snap_back", "{c}² / {GfII}", "{ks}", "N/mm³",
               "else the shear softening branch is steeper than the elastic one: local snap-back in shear",
               lambda p: p["c"] ** 2 / p["GfII"], lambda p: p["ks"], strict=True,
               applies=lambda p: _finite("c")(p) and p["ks"] > 0),
)


def composite_properties(*, kn, ks, ft=np.inf, GfI=1.0, c=np.inf, tanphi0=0.0, tanphir=None, GfII=1.0,
                         tanpsi=0.0, fc=np.inf, Cs=9.0, Gfc=5.0, kappa_p=0.09,
                         cap_ratios=(1 / 3, 1 / 2, 1 / 7), where="interface"):
    """One row of properties, checked for admissibility.

    Parameters (units N, mm, MPa): ``kn``, ``ks`` (N/mm³); ``ft`` (MPa), ``GfI`` (N/mm);
    ``c`` (MPa), ``tanphi0``, ``tanphir`` (default ``tanphi0``), ``GfII`` (N/mm), ``tanpsi``;
    ``fc`` (MPa), ``Cs``, ``Gfc`` (N/mm), ``kappa_p`` (mm); ``cap_ratios`` = (σ̄_i, σ̄_m, σ̄_r)/f_c.
    An infinite ``ft``, ``c`` or ``fc`` switches that surface off. ``where`` names the interface
    family in error messages.

    Raises
    ------
    ValueError
        Naming the offending quantity and the reason: positive strengths and energies, the cap's
        ordering, and the inequalities of :data:`INEQUALITIES` (``ft ≤ c / max(tanphi0, tanphir)``:
        the friction surface also limits tension, DIANA resets f_t, this solver refuses;
        ``kn > ft²/GfI`` and ``ks > c²/GfII``: else the return has no unique solution, local
        snap-back; ``tanpsi ≤ tanphi0``).
    """
    tanphir = tanphi0 if tanphir is None else tanphir
    if not (kn >= 0 and ks >= 0):
        raise ValueError(f"{where}: stiffness must be >= 0 N/mm³; got kn={kn}, ks={ks}")
    for name, v in (("ft", ft), ("c", c), ("fc", fc), ("GfI", GfI), ("GfII", GfII), ("Gfc", Gfc),
                    ("kappa_p", kappa_p)):
        if not v > 0:
            raise ValueError(f"{where}: {name} must be > 0; got {v}")
    if not (tanphi0 >= 0 and tanphir >= 0 and tanpsi >= 0):
        raise ValueError(f"{where}: tanphi0, tanphir and tanpsi must be >= 0; got {tanphi0}, {tanphir}, {tanpsi}")
    props = dict(kn=kn, ks=ks, ft=ft, GfI=GfI, c=c, tanphi0=tanphi0, tanphir=tanphir, GfII=GfII, tanpsi=tanpsi)
    for inequality in INEQUALITIES:
        inequality.check(props, where)
    ri, rm, rr = cap_ratios
    if not (0 < ri <= 1 and 0 < rr < rm < 1):
        raise ValueError(f"{where}: cap_ratios must satisfy 0 < sig_i <= 1 and 0 < sig_r < sig_m < 1; got {cap_ratios}")
    km = cap_kappa_m(fc, Gfc, kappa_p, cap_ratios) if np.isfinite(fc) else np.inf
    row = np.zeros(N_PROPS)
    row[[KN, KS, FT, GFI, C, TANPHI0, TANPHIR, GFII, TANPSI]] = kn, ks, ft, GfI, c, tanphi0, tanphir, GfII, tanpsi
    row[[FC, CSS, CNN, CN, KP, KM, SI, SM, SR]] = fc, Cs, 1.0, 0.0, kappa_p, km, ri, rm, rr
    return row
