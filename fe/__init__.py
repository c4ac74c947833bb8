"""fe — the bundled 2D plane-stress mesoscale masonry finite-element solver.

Units are expanded continuum elements (Q8 serendipity by default, or Q4); bed joints, head joints
and unit mid-planes are zero-thickness line interfaces (thesis ch. 2). A *scenario* is a complete
virtual test built from a plain spec; ``run`` maps model parameters to a :class:`Response`
(readings ``(n_loads, n_sensors)`` in mm). Units: N, mm, MPa; interface stiffness N/mm³.

Nonlinear scenarios (``couplet_tension``, ``triplet_shear``, ``prism_compression``,
``shear_compression_nl``, ``diagonal_compression_nl``) run the joints with a softening interface
law (:mod:`fe.interfaces`) through the path-following solver (:mod:`fe.solvers.nonlinear`) and
return a :class:`~fe.response.NonlinearResponse` (readings at levels of the control displacement,
loads, peak, status).

Example
-------
>>> from fe import build_scenario
>>> scenario = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
>>> response = scenario.run({"kN_bj": 80.0})
>>> response.readings.shape
(4, 6)
>>> bool(response.reading("D1")[-1] < 0)   # the compressed diagonal shortens
True

This package knows nothing of surrogates and never imports ``podkrig``.
"""

from .exceptions import FEError, MeshError, SensorError, SolverError, SpecError
from .response import Response
from .scenarios import SCENARIOS, ParameterInfo, Scenario, ScenarioSpec, build_scenario

__all__ = [
    "build_scenario", "SCENARIOS", "Scenario", "ScenarioSpec", "ParameterInfo", "Response",
    "FEError", "MeshError", "SensorError", "SolverError", "SpecError",
]
