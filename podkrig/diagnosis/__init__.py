"""Model diagnosis: find what a calibrated FE model gets wrong, name the cause among candidate
physical effects, fit the extended model and measure the gain (see :mod:`.engine`)."""

from podkrig.diagnosis.candidates import (
    CANDIDATES,
    DEFAULT_CANDIDATES,
    Candidate,
    EffectParameter,
    FEContext,
    Location,
)
from podkrig.diagnosis.engine import build_base_surrogate, diagnose
from podkrig.diagnosis.results import DiagnosisResult
from podkrig.diagnosis.settings import DiagnosisSettings

__all__ = [
           "CANDIDATES",
           "DEFAULT_CANDIDATES",
           "Candidate",
           "DiagnosisResult",
           "DiagnosisSettings",
           "EffectParameter",
           "FEContext",
           "Location",
           "build_base_surrogate",
           "diagnose",
]
