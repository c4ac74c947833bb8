"""Ordinary kriging with the semivariograms of the thesis (ch. 4): exponential family and power.

- :mod:`~podkrig.surrogate.kriging.variogram`: the models, :math:`\\gamma(h) = \\sigma^2 (1 - e^{-(h/a)^\\beta})`
  and :math:`\\gamma(h) = s h^\\beta`, with a range per input dimension;
- :mod:`~podkrig.surrogate.kriging.ordinary`: :class:`OrdinaryKriging`, one interpolant per output column,
  hyperparameters by concentrated likelihood or closed-form leave-one-out error.
"""

from podkrig.surrogate.kriging.ordinary import (
    DEFAULT_BETA,
    FitMethod,
    KrigingHyperparameters,
    OrdinaryKriging,
    l_bfgs_b,
)
from podkrig.surrogate.kriging.variogram import VARIOGRAMS, covariance, semivariogram

__all__ = ["DEFAULT_BETA", "VARIOGRAMS", "FitMethod", "KrigingHyperparameters", "OrdinaryKriging", "covariance", "l_bfgs_b", "semivariogram"]
