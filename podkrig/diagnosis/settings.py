"""Settings of the model diagnosis, declared once (:mod:`podkrig.config`): the study file's
``[diagnosis]`` table validates into :class:`DiagnosisSettings`, ``podkrig diagnose`` builds one
from its options, and :func:`~podkrig.diagnosis.diagnose` consumes it.

Examples
--------
>>> s = DiagnosisSettings(max_causes=2)
>>> s.alpha, s.model_tolerance
(0.01, None)
"""

from typing import Annotated

from pydantic import StrictBool, StrictFloat, StrictInt

from podkrig.config import Seed, allowed, settings

__all__ = ["DiagnosisSettings"]


@settings
class DiagnosisSettings:
    """The model diagnosis: on or off (in a study), its seed (surrogate design and GA), the most
    causes it names in turn, the significance level of its tests, the FE runs of its base surrogate,
    and an optional fixed relative model-form tolerance (by default each reading's discretisation
    error is estimated from the scenario on a mesh refined twice: :mod:`podkrig.online.model_error`)."""

    enabled: StrictBool = False
    seed: Seed = 0
    max_causes: Annotated[StrictInt, allowed("an integer in [1, 10]", ge=1, le=10)] = 3
    model_tolerance: Annotated[StrictFloat | StrictInt | None,
                               allowed("a number in [0, 0.5), e.g. 0.01 for 1 % of each reading", unit="-", ge=0,
                                       lt=0.5)] = None
    alpha: Annotated[StrictFloat, allowed("a number in (0, 0.5) (multiplicity-corrected significance level)", unit="-",
                                          gt=0, lt=0.5)] = 0.01
    n_train: Annotated[StrictInt, allowed("an integer >= 4 (FE runs of the base surrogate)", ge=4)] = 64
