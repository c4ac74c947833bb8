"""Closed forms for flat-jack tests: pressurised elliptical hole and slot, several slots (DDM),
classical evaluations of single and double flat-jack tests.

Conventions: units mm, N, MPa; plane problem in x, y;
**tension positive**; a jack pressure ``p > 0`` pushes the slot faces apart; an in-situ
compression σ0 is a positive magnitude (σy∞ = −σ0). ``plane="stress"`` (default) or
``"strain"``; stresses do not depend on ν, displacements do. Every function takes and returns
NumPy arrays and broadcasts over its point arguments.

Contents
--------
- :func:`elliptical_hole_field`: Kolosov–Inglis elliptical hole (semi-axes a along x, b along y)
  with remote stresses (σx∞, σy∞, τ∞) and internal pressure p, stresses and displacements
  everywhere outside the hole (Muskhelishvili's conformal-map potentials [1]_).
- :func:`slot_opening_axis`, :func:`slot_stress_axis`, :func:`slot_stress_ahead`,
  :func:`slot_cod`, :func:`slot_stress_intensity`: the pressurised slot = pressurised crack
  (b → 0; Westergaard, Sneddon; the pin-displacement formula of Jaeger & Cook behind the rock
  flat-jack modulus of ASTM D4729) [3]_ [4]_.
- :func:`solve_slots` → :class:`DDMSolution`: constant-element displacement-discontinuity method
  (Crouch & Starfield 1983 [5]_) for several pressurised slots of any orientation.
- :func:`insitu_stress`, :func:`cancellation_pressure`, :func:`jack_efficiency`,
  :func:`chord_modulus`, :func:`apparent_poisson`: the classical evaluations (σ = Km·Ka·p from
  the pressure that restores the pre-cut gauge readings; modulus from a double-jack test).
- :func:`homogenised_moduli`, :func:`shear_lag_opening`, :func:`sliding_pressure_difference`:
  simplified masonry models (a reconstruction, INFERRED, see ``docs/references.md`` "INFERRED choices") and the statics estimate of the
  flat-jack scenario's phase 3 (jacks V1, V2 push a block along its top bed joint).

References
----------
.. [1] N. I. Muskhelishvili, Some basic problems of the mathematical theory of elasticity (1953).
.. [2] C. E. Inglis, Stresses in a plate due to the presence of cracks and sharp corners,
   Trans. Inst. Naval Architects 55 (1913) 219–241.
.. [3] I. N. Sneddon, The distribution of stress in the neighbourhood of a crack in an elastic
   solid, Proc. R. Soc. A 187 (1946) 229–260.
.. [4] J. C. Jaeger, N. G. W. Cook, Fundamentals of rock mechanics, ch. on flat-jack methods.
.. [5] S. L. Crouch, A. M. Starfield, Boundary element methods in solid mechanics (1983), ch. 5.
.. [6] ASTM C1196 / C1197; RILEM TC 177-MDT, MDT.D.4 and D.5 (2004).
"""

import os
from dataclasses import dataclass

import numpy as np

from podkrig.display import Displayed

PLANES = ("stress", "strain")


def _check_plane(plane):
    if plane not in PLANES:
        raise ValueError(f"plane must be one of {PLANES}; got {plane!r}")


def _elastic(E, nu, plane):
    """Shear modulus μ (MPa) and Kolosov constant κ (-)."""
    _check_plane(plane)
    if not E > 0:
        raise ValueError(f"Young's modulus E must be > 0 MPa; got {E}")
    if not -1.0 < nu < 0.5:
        raise ValueError(f"Poisson's ratio must be in (-1, 0.5); got {nu}")
    kappa = (3.0 - nu) / (1.0 + nu) if plane == "stress" else 3.0 - 4.0 * nu
    return E / (2.0 * (1.0 + nu)), kappa


@dataclass(frozen=True, eq=False)
class PlaneField:
    """Stresses (MPa) and, when the elastic constants were given, displacements (mm) at points.

    All arrays have the broadcast shape of the query points; NaN inside a hole.
    """

    sxx: np.ndarray
    syy: np.ndarray
    sxy: np.ndarray
    ux: np.ndarray | None = None
    uy: np.ndarray | None = None

    def to_dict(self):
        d = {"sxx_MPa": self.sxx.tolist(), "syy_MPa": self.syy.tolist(), "sxy_MPa": self.sxy.tolist()}
        if self.ux is not None:
            d.update(ux_mm=self.ux.tolist(), uy_mm=self.uy.tolist())
        return d


# --------------------------------------------------------------------------------------------
# §2.1 Elliptical hole with remote stress and internal pressure
# --------------------------------------------------------------------------------------------


def elliptical_hole_field(x, y, a, b, *, sx=0.0, sy=0.0, txy=0.0, p=0.0, E=None, nu=None, plane="stress",
                          use_numba=None):
    """Stresses and displacements around an elliptical hole in an infinite plate.

    The hole ``x²/a² + y²/b² ≤ 1`` (semi-axes ``a`` along x, ``b`` along y, mm; ``a = b`` is
    Kirsch's circle, ``b → 0`` a crack) carries an internal pressure ``p`` (MPa, > 0 pushes its
    faces apart); the plate is loaded at infinity by ``sx = σx∞``, ``sy = σy∞``, ``txy = τ∞``
    (MPa, tension positive).

    Muskhelishvili's solution [1]_ with the map ``z = ω(ζ) = R(ζ + m/ζ)``, ``R = (a+b)/2``,
    ``m = (a−b)/(a+b)``; loads enter through ``Γ = (σx∞+σy∞)/4`` and
    ``Γ' = (σy∞−σx∞)/2 + iτ∞``; with ``A = −conj(Γ') − mΓ − pm``:

    .. math:: φ(ζ) = R(Γζ + A/ζ),\\quad
       ψ(ζ) = −pR g − R(Γ/ζ + \\bar A ζ) − R\\,g\\,\\frac{Γζ^2 − A}{ζ^2 − m},\\quad g = 1/ζ + mζ,

    σxx + σyy = 4 Re Φ, σyy − σxx + 2iτxy = 2(z̄ Φ'(z) + Ψ(z)) with Φ = φ'/ω', Ψ = ψ'/ω', and
    ``2μ(u + iv) = κφ − ω conj(φ')/conj(ω') − conj(ψ)`` ([1]_; ψ' in closed form
    here, not by finite differences). Displacements of the remote field grow linearly; they are
    defined up to a rigid motion fixed by ``u(0) = 0`` of the uniform part.

    Parameters
    ----------
    x, y : array_like
        Points, mm (broadcast together). Points inside the hole give NaN.
    a, b : float
        Semi-axes, mm, ``a > 0``, ``b ≥ 0``.
    sx, sy, txy, p : float
        Remote stresses and internal pressure, MPa.
    E, nu : float, optional
        Young's modulus (MPa) and Poisson's ratio; give both to get displacements.
    plane : {"stress", "strain"}
    use_numba : bool, optional
        Evaluate point by point in a compiled kernel (default, unless ``PODKRIG_DISABLE_NUMBA=1``)
        or with whole-array NumPy operations (the reference the tests compare it with).

    Returns
    -------
    PlaneField
    """
    if not (a > 0 and b >= 0):
        raise ValueError(f"semi-axes must satisfy a > 0 and b >= 0 mm; got a={a}, b={b}")
    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    z = x + 1j * y
    R, m = 0.5 * (a + b), (a - b) / (a + b)
    gamma = 0.25 * (sx + sy)
    gamma2 = 0.5 * (sy - sx) + 1j * txy
    A = -np.conj(gamma2) - m * gamma - p * m
    if E is not None or nu is not None:
        if E is None or nu is None:
            raise ValueError("give both E and nu for displacements")
        mu, kappa = _elastic(E, nu, plane)
    else:
        mu = kappa = None
    if _numba_enabled(use_numba):
        out = np.empty((5, x.size))
        _ellipse_kernel(x.ravel(), y.ravel(), float(a), float(b), R, m, gamma, complex(A), float(p),
                        mu is not None, mu or 1.0, kappa or 0.0, out)
        out = out.reshape((5, *x.shape))
        return PlaneField(out[0], out[1], out[2], *((out[3], out[4]) if mu is not None else (None, None)))
    w = z / R
    root = np.sqrt(w * w - 4.0 * m)
    # the root of ζ² − wζ + m = 0 outside the unit circle: |ζ1|² − |ζ2|² = Re(w conj(root))
    root = np.where((w.real * root.real + w.imag * root.imag) >= 0, root, -root)
    inside = (x / a) ** 2 + (y / b if b > 0 else np.where(y == 0, 0.0, np.inf)) ** 2 < 1.0 - 1e-12
    zeta = np.where(inside, np.nan, 0.5 * (w + root))
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = 1.0 / zeta
        inv2 = inv * inv
        dphi = R * (gamma - A * inv2)  # φ'(ζ)
        ddphi = 2.0 * R * A * inv2 * inv
        q = 1.0 - m * inv2
        dom = R * q  # ω'(ζ)
        ddom = 2.0 * R * m * inv2 * inv
        g, dg = inv + m * zeta, m - inv2
        h = dphi / dom  # (Γζ² − A)/(ζ² − m) = Φ
        dh = 2.0 * (A - gamma * m) * inv2 * inv / (q * q)
        dpsi = -p * R * dg - R * (np.conj(A) - gamma * inv2) - R * (dg * h + g * dh)
        dPhi = (ddphi * dom - dphi * ddom) / dom**3
        X = 2.0 * (np.conj(z) * dPhi + dpsi / dom)
        trace = 4.0 * h.real
        sxx, syy, sxy = 0.5 * (trace - X.real), 0.5 * (trace + X.real), 0.5 * X.imag
        ux = uy = None
        if mu is not None:
            phi = R * (gamma * zeta + A * inv)
            psi = -p * R * g - R * (gamma * inv + np.conj(A) * zeta) - R * g * h
            omega = R * (zeta + m * inv)
            U = (kappa * phi - omega / np.conj(dom) * np.conj(dphi) - np.conj(psi)) / (2.0 * mu)
            ux, uy = U.real, U.imag
    return PlaneField(sxx, syy, sxy, ux, uy)


def _numba_enabled(use_numba):
    if use_numba is not None:
        return bool(use_numba) and _ellipse_kernel is not None
    return _ellipse_kernel is not None and os.environ.get("PODKRIG_DISABLE_NUMBA", "").strip().lower() not in ("1", "true", "yes")


def _ellipse_point(x, y, a, b, R, m, gamma, A, p, want_u, mu, kappa, out, k):
    """The formulas of :func:`elliptical_hole_field` at one point (compiled by numba)."""
    inside = (x / a) ** 2 + ((y / b) ** 2 if b > 0 else (0.0 if y == 0 else np.inf)) < 1.0 - 1e-12
    if inside:
        for j in range(5):
            out[j, k] = np.nan
        return
    z = complex(x, y)
    w = z / R
    root = np.sqrt(w * w - 4.0 * m)
    if w.real * root.real + w.imag * root.imag < 0:
        root = -root
    zeta = 0.5 * (w + root)
    inv = 1.0 / zeta
    inv2 = inv * inv
    dphi = R * (gamma - A * inv2)
    ddphi = 2.0 * R * A * inv2 * inv
    q = 1.0 - m * inv2
    dom = R * q
    ddom = 2.0 * R * m * inv2 * inv
    g, dg = inv + m * zeta, m - inv2
    h = dphi / dom
    dh = 2.0 * (A - gamma * m) * inv2 * inv / (q * q)
    Ac = A.conjugate()
    dpsi = -p * R * dg - R * (Ac - gamma * inv2) - R * (dg * h + g * dh)
    dPhi = (ddphi * dom - dphi * ddom) / (dom * dom * dom)
    X = 2.0 * (z.conjugate() * dPhi + dpsi / dom)
    trace = 4.0 * h.real
    out[0, k] = 0.5 * (trace - X.real)
    out[1, k] = 0.5 * (trace + X.real)
    out[2, k] = 0.5 * X.imag
    if want_u:
        phi = R * (gamma * zeta + A * inv)
        psi = -p * R * g - R * (gamma * inv + Ac * zeta) - R * g * h
        omega = R * (zeta + m * inv)
        U = (kappa * phi - omega / dom.conjugate() * dphi.conjugate() - psi.conjugate()) / (2.0 * mu)
        out[3, k] = U.real
        out[4, k] = U.imag


try:  # numba is a core dependency; the guard only keeps the NumPy path usable without it
    import numba

    _point = numba.njit(cache=True, inline="always")(_ellipse_point)

    @numba.njit(cache=True)
    def _ellipse_kernel(x, y, a, b, R, m, gamma, A, p, want_u, mu, kappa, out):
        for k in range(x.size):
            _point(x[k], y[k], a, b, R, m, gamma, A, p, want_u, mu, kappa, out, k)
except ImportError:  # pragma: no cover
    _ellipse_kernel = None


# --------------------------------------------------------------------------------------------
# §2.2 Pressurised slot (crack limit)
# --------------------------------------------------------------------------------------------


def _plane_constants(E, nu, plane):
    """(E, ν) of the plane-stress formulas: plane strain uses E/(1−ν²), ν/(1−ν)."""
    _elastic(E, nu, plane)
    if plane == "strain":
        return E / (1.0 - nu**2), nu / (1.0 - nu)
    return E, nu


def slot_opening_axis(y, a, p, E, nu, plane="stress"):
    """Vertical displacement ``u_y(0, y)`` (mm) on the axis of a pressurised slot, ``y ≥ 0``.

    Slot ``|x| < a, y = 0`` with pressure ``p`` (MPa) on its faces in an infinite plate
    (Jaeger–Cook pin-displacement formula [4]_), η = y/a:

    .. math:: u_y = \\frac{p a}{E}\\Big((1−ν)(\\sqrt{1+η^2} − η) + \\frac{1+ν}{\\sqrt{1+η^2}}\\Big)

    Gauge pins at ``(0, ±y)`` move apart by ``2 u_y`` (:func:`slot_pin_change`).
    """
    E, nu = _plane_constants(E, nu, plane)
    y = np.asarray(y, float)
    if np.any(y < 0):
        raise ValueError("slot_opening_axis needs y >= 0 mm (the field is antisymmetric in y)")
    r = np.sqrt(1.0 + (y / a) ** 2)
    return p * a / E * ((1.0 - nu) * (r - y / a) + (1.0 + nu) / r)


def slot_pin_change(y, a, p, E, nu, plane="stress"):
    """Change of distance (mm, > 0 apart) between pins at ``(0, ±y)`` across a pressurised slot."""
    return 2.0 * slot_opening_axis(y, a, p, E, nu, plane)


def slot_cod(x, a, p, E, nu=0.0, plane="stress"):
    """Crack opening displacement ``4 p √(a² − x²) / E`` (mm) for ``|x| ≤ a`` (Sneddon); 0 outside."""
    E, _ = _plane_constants(E, nu, plane)
    x = np.asarray(x, float)
    return 4.0 * p * np.sqrt(np.clip(a * a - x * x, 0.0, None)) / E


def slot_stress_axis(y, a, p):
    """``(σxx, σyy)`` (MPa) on the slot axis ``x = 0`` at distance ``y ≥ 0`` (mm).

    σyy = p(y³/(y²+a²)^{3/2} − 1), σxx = p(y(y²+2a²)/(y²+a²)^{3/2} − 1); τ = 0.
    """
    y = np.abs(np.asarray(y, float))
    d = (y * y + a * a) ** 1.5
    return p * (y * (y * y + 2.0 * a * a) / d - 1.0), p * (y**3 / d - 1.0)


def slot_stress_ahead(x, a, p):
    """σxx = σyy (MPa) on the slot line ahead of the tips, ``|x| > a``: ``p(|x|/√(x²−a²) − 1)``."""
    x = np.abs(np.asarray(x, float))
    if np.any(x <= a):
        raise ValueError("slot_stress_ahead needs |x| > a (ahead of the tips)")
    return p * (x / np.sqrt(x * x - a * a) - 1.0)


def slot_stress_intensity(a, p):
    """Mode-I stress intensity ``K_I = p √(π a)`` (MPa·√mm) of a pressurised slot of half-length a."""
    return p * np.sqrt(np.pi * np.asarray(a, float))


# --------------------------------------------------------------------------------------------
# §2.3 Several slots: constant-element displacement-discontinuity method
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Slot:
    """A straight pressurised slot: centre (mm), length (mm), angle (rad from +x) and pressure (MPa)."""

    centre: tuple
    length: float
    angle: float = 0.0
    pressure: float = 1.0

    def __post_init__(self):
        if not self.length > 0:
            raise ValueError(f"slot length must be > 0 mm; got {self.length}")


def _ddm_kernels(x, y, a, nu):
    """Displacement and stress influence of a constant DD element (local axes, half-length a).

    Returns ``(ux, uy, sxx, syy, sxy)`` each of shape ``(..., 2)``: per unit shear (Ds, index 0)
    and normal (Dn, index 1) discontinuity, for ``2G = 1`` in the stresses. Crouch & Starfield's
    convention: ``D = u(y=0⁻) − u(y=0⁺)`` (an opening has Dn < 0).
    """
    c = 1.0 / (4.0 * np.pi * (1.0 - nu))
    xm, xp = x - a, x + a
    r1, r2 = xm * xm + y * y, xp * xp + y * y
    fx = 0.5 * c * (np.log(r1) - np.log(r2))
    fy = -c * (np.arctan2(y, xm) - np.arctan2(y, xp))
    fxy = c * (y / r1 - y / r2)
    fxx = c * (xm / r1 - xp / r2)
    fyy = -fxx
    fxyy = c * ((xm * xm - y * y) / r1**2 - (xp * xp - y * y) / r2**2)
    fyyy = c * (2.0 * y * xm / r1**2 - 2.0 * y * xp / r2**2)
    ux = np.stack([2 * (1 - nu) * fy - y * fxx, -(1 - 2 * nu) * fx - y * fxy], axis=-1)
    uy = np.stack([(1 - 2 * nu) * fx - y * fxy, 2 * (1 - nu) * fy - y * fyy], axis=-1)
    sxx = np.stack([2 * fxy + y * fxyy, fyy + y * fyyy], axis=-1)
    syy = np.stack([-y * fxyy, fyy - y * fyyy], axis=-1)
    sxy = np.stack([fyy + y * fyyy, -y * fxyy], axis=-1)
    return ux, uy, sxx, syy, sxy


@dataclass(frozen=True, eq=False, repr=False)
class DDMSolution(Displayed):
    """Displacement discontinuities of constant elements along slots in an infinite plate.

    Attributes
    ----------
    centres : ndarray of shape (n, 2)
        Element mid-points, mm.
    half_lengths : ndarray of shape (n,)
        mm.
    angles : ndarray of shape (n,)
        Element direction, rad from +x.
    slot : ndarray of shape (n,)
        Index of the slot each element belongs to.
    ds, dn : ndarray of shape (n,)
        Shear and normal discontinuities ``u⁻ − u⁺`` in element axes, mm (opening: dn < 0).
    shear_modulus : float
        MPa.
    nu_kernel : float
        Poisson's ratio in the plane-strain kernels (ν/(1+ν) for plane stress).
    """

    centres: np.ndarray
    half_lengths: np.ndarray
    angles: np.ndarray
    slot: np.ndarray
    ds: np.ndarray
    dn: np.ndarray
    shear_modulus: float
    nu_kernel: float

    def opening(self):
        """Opening of each element (mm, > 0 when the faces move apart), ``(n,)``."""
        return -self.dn

    def to_dict(self):
        """JSON-able, units in the keys as :meth:`PlaneField.to_dict`: per element (``n`` each)
        ``centres_mm`` (``[x, y]`` pairs), ``half_lengths_mm``, ``angles_rad``, ``slot``, ``ds_mm``,
        ``dn_mm``; ``shear_modulus_MPa`` and ``nu_kernel``."""
        return {"centres_mm": self.centres.tolist(), "half_lengths_mm": self.half_lengths.tolist(),
                "angles_rad": self.angles.tolist(), "slot": [int(i) for i in self.slot],
                "ds_mm": self.ds.tolist(), "dn_mm": self.dn.tolist(),
                "shear_modulus_MPa": float(self.shear_modulus), "nu_kernel": float(self.nu_kernel)}

    def field(self, x, y, chunk=4096):
        """Stresses (MPa) and displacements (mm) at points ``(x, y)`` (mm) as a :class:`PlaneField`.

        Points exactly on an element give the average of the two faces' stresses; avoid them.
        """
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        shape = x.shape
        px, py = x.ravel(), y.ravel()
        out = np.zeros((5, px.size))
        cb, sb = np.cos(self.angles), np.sin(self.angles)
        D = np.stack([self.ds, self.dn], axis=-1)  # (n, 2)
        for start in range(0, px.size, chunk):
            sl = slice(start, start + chunk)
            dx = px[sl, None] - self.centres[:, 0]
            dy = py[sl, None] - self.centres[:, 1]
            xl, yl = dx * cb + dy * sb, -dx * sb + dy * cb
            ux, uy, sxx, syy, sxy = (np.einsum("pek,ek->pe", k, D) for k in _ddm_kernels(xl, yl, self.half_lengths, self.nu_kernel))
            g2 = 2.0 * self.shear_modulus
            sxx, syy, sxy = g2 * sxx, g2 * syy, g2 * sxy
            out[0, sl] = np.sum(ux * cb - uy * sb, axis=1)
            out[1, sl] = np.sum(ux * sb + uy * cb, axis=1)
            out[2, sl] = np.sum(sxx * cb**2 + syy * sb**2 - 2 * sxy * sb * cb, axis=1)
            out[3, sl] = np.sum(sxx * sb**2 + syy * cb**2 + 2 * sxy * sb * cb, axis=1)
            out[4, sl] = np.sum((sxx - syy) * sb * cb + sxy * (cb**2 - sb**2), axis=1)
        ux, uy, sxx, syy, sxy = (v.reshape(shape) for v in out)
        return PlaneField(sxx, syy, sxy, ux, uy)


def solve_slots(slots, E, nu, n_elements=80, plane="stress", spacing="cosine"):
    """Pressurised slots in an infinite homogeneous plate by the displacement-discontinuity method.

    Each slot is divided into ``n_elements`` constant elements (``spacing="cosine"`` refines
    towards the tips, ``"uniform"``); the mid-point of each element is collocated with normal
    traction ``−p`` (the jack pushes the faces apart) and zero shear. Plane stress uses the
    plane-strain kernels with ν' = ν/(1+ν) and the same shear modulus (Crouch & Starfield [5]_).

    Parameters
    ----------
    slots : sequence of Slot
    E, nu : float
        MPa, -.
    n_elements : int
        Elements per slot.

    Returns
    -------
    DDMSolution
    """
    mu, _ = _elastic(E, nu, plane)
    nu_k = nu / (1.0 + nu) if plane == "stress" else nu
    if spacing not in ("cosine", "uniform"):
        raise ValueError(f"spacing must be 'cosine' or 'uniform'; got {spacing!r}")
    if int(n_elements) != n_elements or n_elements < 1:
        raise ValueError(f"n_elements must be an integer >= 1; got {n_elements}")
    t = np.linspace(0.0, 1.0, int(n_elements) + 1)
    s = -np.cos(np.pi * t) if spacing == "cosine" else 2.0 * t - 1.0  # in [-1, 1]
    centres, halves, angles, owner, pressure = [], [], [], [], []
    for k, sl in enumerate(slots):
        ends = 0.5 * sl.length * s
        mid, half = 0.5 * (ends[1:] + ends[:-1]), 0.5 * np.diff(ends)
        c, d = np.cos(sl.angle), np.sin(sl.angle)
        centres.append(np.column_stack([sl.centre[0] + mid * c, sl.centre[1] + mid * d]))
        halves.append(half)
        angles.append(np.full(len(mid), sl.angle))
        owner.append(np.full(len(mid), k))
        pressure.append(np.full(len(mid), sl.pressure))
    centres, halves = np.vstack(centres), np.concatenate(halves)
    angles, owner, pressure = np.concatenate(angles), np.concatenate(owner), np.concatenate(pressure)
    n = len(halves)
    cb, sb = np.cos(angles), np.sin(angles)
    # influence at collocation point i of element j, in j's local axes
    dx = centres[:, None, 0] - centres[None, :, 0]
    dy = centres[:, None, 1] - centres[None, :, 1]
    xl = dx * cb[None] + dy * sb[None]
    yl = -dx * sb[None] + dy * cb[None]
    _, _, sxx, syy, sxy = _ddm_kernels(xl, yl, halves[None], nu_k)  # (i, j, 2)
    cj, sj = cb[None, :, None], sb[None, :, None]
    gxx = sxx * cj**2 + syy * sj**2 - 2 * sxy * sj * cj
    gyy = sxx * sj**2 + syy * cj**2 + 2 * sxy * sj * cj
    gxy = (sxx - syy) * sj * cj + sxy * (cj**2 - sj**2)
    ci, si = cb[:, None, None], sb[:, None, None]  # receiver normal (−s, c), tangent (c, s)
    sn = gxx * si**2 + gyy * ci**2 - 2 * gxy * si * ci
    tau = (gyy - gxx) * si * ci + gxy * (ci**2 - si**2)
    M = 2.0 * mu * np.block([[tau[:, :, 0], tau[:, :, 1]], [sn[:, :, 0], sn[:, :, 1]]])
    rhs = np.concatenate([np.zeros(n), -pressure])
    D = np.linalg.solve(M, rhs)
    return DDMSolution(centres, halves, angles, owner, D[:n], D[n:], mu, nu_k)


# --------------------------------------------------------------------------------------------
# Classical evaluations (ASTM C1196/C1197, RILEM MDT.D.4/D.5)
# --------------------------------------------------------------------------------------------


def insitu_stress(p_cancel, Km, Ka=1.0):
    """In-situ normal stress (MPa, compression positive) of a single flat-jack test.

    ``σ = Km · Ka · p`` (ASTM C1196 §3 [6]_; the symbols Km, Ka are the usual ones, INFERRED, see ``docs/references.md`` "INFERRED choices"): ``p_cancel`` the
    jack pressure (MPa) that restores the pre-cut gauge distances, ``Km`` the jack efficiency
    (calibration, ≤ 1), ``Ka = A_jack / A_slot`` (≤ 1).
    """
    for name, v in (("Km", Km), ("Ka", Ka)):
        if not 0 < v <= 1.5:
            raise ValueError(f"{name} must be in (0, 1.5]; got {v}")
    return Km * Ka * np.asarray(p_cancel, float)


def cancellation_pressure(pressure, readings):
    """Jack pressure (MPa) at which the mean gauge reading returns to its pre-cut value (zero).

    Parameters
    ----------
    pressure : array_like of shape (n_steps,)
        Jack pressures, MPa, increasing.
    readings : array_like of shape (n_steps,) or (n_steps, n_gauges)
        Gauge readings relative to the pre-cut state (the gauges are zeroed before the cut), mm;
        the cut closes the gauges (negative readings) and the jack reopens them.

    Returns
    -------
    float
        Linear interpolation between the two steps bracketing the first sign change of the mean
        reading.
    """
    p = np.asarray(pressure, float)
    r = np.asarray(readings, float)
    mean = r if r.ndim == 1 else r.mean(axis=1)
    if p.ndim != 1 or len(mean) != len(p) or len(p) < 2:
        raise ValueError(f"need pressure (n,) and readings (n,) or (n, g) with n >= 2; got {p.shape}, {r.shape}")
    if np.any(np.diff(p) <= 0):
        raise ValueError("pressures must increase step by step")
    hit = np.flatnonzero(np.sign(mean[:-1]) * np.sign(mean[1:]) <= 0)
    if len(hit) == 0:
        raise ValueError(
            f"the mean reading never returns to the pre-cut value between {p[0]:g} and {p[-1]:g} MPa "
            f"(from {mean[0]:.4g} to {mean[-1]:.4g} mm); raise the pressure further"
        )
    i = hit[0]
    if mean[i + 1] == mean[i]:
        return float(p[i])
    return float(p[i] - mean[i] * (p[i + 1] - p[i]) / (mean[i + 1] - mean[i]))


def jack_efficiency(force, pressure, jack_area):
    """Jack efficiency Km (-) from a calibration in a testing machine (ASTM C1196 §7.4).

    ``Km`` is the least-squares slope through the origin of the machine stress ``F/A_jack``
    against the jack pressure: ``force`` (N) and ``pressure`` (MPa) at each step, ``jack_area`` mm².
    """
    F, p = np.asarray(force, float), np.asarray(pressure, float)
    if F.shape != p.shape or F.size < 1 or not jack_area > 0:
        raise ValueError("need force and pressure of the same shape and jack_area > 0 mm²")
    return float(np.dot(F / jack_area, p) / np.dot(p, p))


def chord_modulus(stress, strain, levels=None):
    """Chord modulus (MPa) between two stress levels of a double flat-jack test.

    ``stress`` (MPa, compression positive, e.g. Km·Ka·p) and ``strain`` (compression positive,
    ΔL/L of a gauge between the jacks) at each step; ``levels = (σ1, σ2)`` (MPa) interpolates
    both ends, by default the first and last step: ``E = (σ2 − σ1)/(ε2 − ε1)``.
    """
    s, e = np.asarray(stress, float), np.asarray(strain, float)
    if s.shape != e.shape or s.ndim != 1 or len(s) < 2:
        raise ValueError("need stress and strain of equal shape (n,), n >= 2")
    if levels is None:
        s1, s2, e1, e2 = s[0], s[-1], e[0], e[-1]
    else:
        if np.any(np.diff(s) <= 0):
            raise ValueError("stresses must increase to interpolate at given levels")
        s1, s2 = levels
        e1, e2 = np.interp([s1, s2], s, e)
    if e2 == e1:
        raise ValueError("no strain change between the two levels")
    return float((s2 - s1) / (e2 - e1))


def apparent_poisson(strain_transverse, strain_axial):
    """Apparent Poisson's ratio ``−ε_h/ε_v`` from transverse and axial gauge strains (same sign convention)."""
    return -np.asarray(strain_transverse, float) / np.asarray(strain_axial, float)


# --------------------------------------------------------------------------------------------
# Simplified masonry models (INFERRED) and the phase-3 statics of the flat-jack scenario
# --------------------------------------------------------------------------------------------


def homogenised_moduli(E_b, nu_b, kN, kV, r_hj, unit_height, unit_length):
    """Homogenised moduli ``(E_x, E_y, G_xy)`` (MPa) of a brick wall (INFERRED, see ``docs/references.md`` "INFERRED choices").

    ``1/E_y = 1/E_b + 1/(h kN)`` (series across bed joints; exact for stack bond),
    ``1/E_x ≈ 1/E_b + 1/(l r kN)`` (a lower bound for running bond),
    ``1/G ≈ 1/G_b + 1/(h kV)`` with ``G_b = E_b/(2(1+ν_b))``; h, l in mm, kN, kV in N/mm³.
    """
    Gb = E_b / (2.0 * (1.0 + nu_b))
    Ey = 1.0 / (1.0 / E_b + 1.0 / (unit_height * kN))
    Ex = 1.0 / (1.0 / E_b + 1.0 / (unit_length * r_hj * kN)) if r_hj > 0 else 0.0
    G = 1.0 / (1.0 / Gb + 1.0 / (unit_height * kV))
    return Ex, Ey, G


def shear_lag_opening(p, E_b, kV, strip_height):
    """Face displacement ``u0 = p/√(2 kV E_b / h_j)`` (mm) of the shear-lag strip pushed by a
    vertical jack (INFERRED, see ``docs/references.md`` "INFERRED choices"); p MPa, E_b MPa, kV N/mm³, h_j mm."""
    return p / np.sqrt(2.0 * kV * E_b / strip_height)


def sliding_pressure_difference(c, tan_phi, p_H, slot_length, jack_height):
    """Phase-3 estimate of the critical ``Δp_V = p_V1 − p_V2`` (MPa) to slide the block's top bed joint.

    Statics with frictionless jack faces: the top bed joint carries the normal
    stress ``p_H`` and the average shear ``Δp_V h_V / L_H``, so sliding starts at
    ``Δp_V = (L_H / h_V)(c + p_H tanφ)``; c and p_H in MPa, lengths in mm.
    """
    return slot_length / jack_height * (c + p_H * tan_phi)
