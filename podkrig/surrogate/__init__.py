"""Surrogate stage: POD of the snapshots plus ordinary kriging of the POD coefficients.

- :mod:`~podkrig.surrogate.pod` — proper orthogonal decomposition (thesis ch. 4);
- :mod:`~podkrig.surrogate.kriging` — ordinary kriging with exponential-family semivariograms;
- :mod:`~podkrig.surrogate.podkriging` — the POD-kriging surrogate and its training from a store
  (its file: :mod:`podkrig.io.surrogate_file`);
- :mod:`~podkrig.surrogate.backends` — selectable regressors of the POD coefficients: ours,
  SMT's KRG/KPLS, scikit-learn's GPR;
- :mod:`~podkrig.surrogate.validation` — held-out and leave-one-out errors;
- :mod:`~podkrig.surrogate.refine` — adaptive enrichment of the training design;
- :mod:`~podkrig.surrogate.settings` — POD truncation, kriging and backend settings
  (``[surrogate]``), and the fit from a store with them;
- :mod:`~podkrig.surrogate.results` — the fit and the held-out check in numbers.
"""

from podkrig.surrogate.backends import BACKENDS, make_backend
from podkrig.surrogate.podkriging import PODKriging, fit_from_store, training_data

__all__ = ["BACKENDS", "PODKriging", "fit_from_store", "make_backend", "training_data"]
