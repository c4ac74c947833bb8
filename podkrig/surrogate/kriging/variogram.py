"""Semivariogram models of the thesis (ch. 4): the exponential family and the power model.

Inputs live in the unit cube; a *range* :math:`a_k > 0` per input dimension makes the models
anisotropic. Both models are written through the same *reduced distance*

.. math::

    s(x, x') = \\sum_{k=1}^{d} \\left( \\frac{|x_k - x'_k|}{a_k} \\right)^{\\beta},

i.e. the anisotropy is applied per dimension inside the sum (a product of one-dimensional
correlations), **not** as :math:`\\|(x - x')/a\\|^\\beta`. For :math:`\\beta = 2` the two forms agree
(Gaussian / RBF); for :math:`\\beta = 1` the per-dimension form is the product of 1-D exponential
correlations, which coincides with scikit-learn's ``Matern(nu=0.5)`` in one dimension.

- ``"exponential"`` (exponential family, Sacks et al. 1989 "power-exponential"):
  :math:`\\gamma(x, x') = \\sigma^2 (1 - e^{-s})`, correlation :math:`R = e^{-s}`,
  :math:`0 < \\beta \\le 2` (:math:`\\beta = 1` exponential, :math:`\\beta = 2` Gaussian).
- ``"power"`` (intrinsic, no sill): :math:`\\gamma(x, x') = \\sigma^2 s`, :math:`0 < \\beta < 2`.
  A sum of one-dimensional power variograms, each conditionally negative definite for
  :math:`\\beta < 2`, so the sum is a valid intrinsic model. Its *generalised covariance* is
  :math:`K = -\\gamma`; ordinary kriging uses it in the variogram form of the kriging system.

A nugget :math:`\\eta` (relative to :math:`\\sigma^2`) adds :math:`\\eta` to the diagonal of the
(generalised) covariance matrix of the training points, i.e. a jump :math:`\\gamma(0^+) = \\sigma^2 \\eta`.

References
----------
.. [1] J. Sacks, W. J. Welch, T. J. Mitchell, H. P. Wynn, "Design and analysis of computer
   experiments", Statistical Science 4(4), 409–423, 1989.
.. [2] The thesis, ch. 4 (semivariograms with exponent 1.2, 1.5, 1.8); see ``docs/references.md``.
"""

import numpy as np

from podkrig.surrogate.kriging._kernels import EXPONENTIAL, POWER, abs_power

VARIOGRAMS = {"exponential": EXPONENTIAL, "power": POWER}
BETA_FIT_BOUNDS = {"exponential": (0.2, 2.0), "power": (0.2, 1.95)}


def check_variogram(variogram):
    """The kernel code of ``variogram``; ``ValueError`` naming the choices otherwise."""
    if variogram not in VARIOGRAMS:
        raise ValueError(f"variogram must be one of {sorted(VARIOGRAMS)}; got {variogram!r}")
    return VARIOGRAMS[variogram]


def check_beta(beta, variogram):
    """Validate a fixed exponent for ``variogram``; returns it as float.

    Raises
    ------
    ValueError
        ``beta`` outside (0, 2] (exponential family) or (0, 2) (power model).
    """
    try:
        b = float(beta)
    except (TypeError, ValueError):
        raise ValueError(f"beta must be a number in (0, 2] or 'fit'; got {beta!r}") from None
    if variogram == "exponential" and not 0.0 < b <= 2.0:
        raise ValueError(f"beta of the exponential family must satisfy 0 < beta <= 2; got {b:g}")
    if variogram == "power" and not 0.0 < b < 2.0:
        raise ValueError(
            f"beta of the power model must satisfy 0 < beta < 2 (beta = 2 is not a valid intrinsic "
            f"model); got {b:g}"
        )
    return b


def reduced_distance(X1, X2, ranges, beta):
    """:math:`s(x, x')` for all pairs, ``(n1, n2)``.

    Parameters
    ----------
    X1 : ndarray of shape (n1, d)
    X2 : ndarray of shape (n2, d)
        Points in the unit cube.
    ranges : ndarray of shape (d,)
        Ranges :math:`a_k` in unit-cube units.
    beta : float
    """
    X1, X2 = np.atleast_2d(X1), np.atleast_2d(X2)
    theta = np.asarray(ranges, dtype=float) ** (-beta)
    return abs_power(X1[:, None, :] - X2[None, :, :], beta) @ theta


def covariance(X1, X2, ranges, beta, variogram="exponential"):
    """(Generalised) covariance per unit sill, ``(n1, n2)``: :math:`e^{-s}` or :math:`-s`.

    Parameters
    ----------
    X1, X2 : ndarray of shape (n1, d), (n2, d)
    ranges : ndarray of shape (d,)
    beta : float
    variogram : {"exponential", "power"}
    """
    S = reduced_distance(X1, X2, ranges, beta)
    return np.exp(-S) if check_variogram(variogram) == EXPONENTIAL else -S


def semivariogram(h, variogram="exponential", beta=1.5, sill=1.0, range_=1.0, nugget=0.0):
    """Isotropic semivariogram :math:`\\gamma(h)` for plots and documentation.

    Parameters
    ----------
    h : array_like
        Lag, in the units of ``range_``.
    variogram : {"exponential", "power"}
    beta : float
    sill : float
        :math:`\\sigma^2` (exponential family) or the scale :math:`s` (power model), in output units².
    range_ : float
        Range :math:`a`.
    nugget : float
        Nugget relative to ``sill``; :math:`\\gamma(0) = 0` always.

    Returns
    -------
    gamma : ndarray, same shape as ``h``
    """
    h = np.abs(np.asarray(h, dtype=float))
    t = (h / range_) ** check_beta(beta, variogram)
    g = 1.0 - np.exp(-t) if check_variogram(variogram) == EXPONENTIAL else t
    return np.where(h > 0, sill * (g + nugget), 0.0)
