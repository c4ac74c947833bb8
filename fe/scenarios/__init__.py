"""Scenario registry: name → scenario class; :func:`build_scenario` rebuilds one from its spec."""

from ..exceptions import SpecError
from .base import ParameterInfo, Scenario
from .diagonal_compression import DiagonalCompression
from .flat_jack import FlatJack
from .flat_jack_nl import FlatJackElasticNonlinear, FlatJackShearNonlinear
from .shear_compression import ShearCompression
from .spec import ScenarioSpec
from .specimens import CoupletTension, PrismCompression, TripletShear
from .wall_opening import WallOpeningNonlinear
from .walls_nonlinear import DiagonalCompressionNonlinear, ShearCompressionNonlinear

SCENARIOS = {
    cls.name: cls
    for cls in (DiagonalCompression, ShearCompression, FlatJack, CoupletTension, TripletShear, PrismCompression,
                ShearCompressionNonlinear, DiagonalCompressionNonlinear, FlatJackShearNonlinear, FlatJackElasticNonlinear,
                WallOpeningNonlinear)
}


def build_scenario(spec, solver="auto"):
    """Build a scenario from a :class:`ScenarioSpec`, a plain dict, or a registered name."""
    if isinstance(spec, str):
        spec = ScenarioSpec(spec)
    elif isinstance(spec, dict):
        spec = ScenarioSpec.from_dict(spec)
    if spec.scenario not in SCENARIOS:
        raise SpecError(f"unknown scenario {spec.scenario!r}; available: {sorted(SCENARIOS)}")
    return SCENARIOS[spec.scenario](spec, solver=solver)


__all__ = ["SCENARIOS", "ParameterInfo", "Scenario", "ScenarioSpec", "build_scenario"]
