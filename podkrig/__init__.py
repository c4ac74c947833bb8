"""podkrig — surrogate-first inverse analysis of mesoscale FE models of brick masonry.

Stages: offline snapshots of the bundled FE solver (:mod:`fe`) → POD + ordinary kriging
surrogate → online genetic-algorithm inversion, region of equivalence, RVC → model diagnosis.

The public API, by stage (each name also lives in its stage's module)::

    from podkrig import ParameterSpace                                  # shared
    from podkrig import SnapshotStore, run_snapshots, sample            # offline
    from podkrig import PODKriging, fit_from_store, make_backend        # surrogate
    from podkrig import read_measurement, load_surrogate, save_surrogate  # files (podkrig.io)
    from podkrig import (Measurement, NoiseModel,                       # online
                         InverseProblem, JointProblem, SurrogateModel, FEModel, invert, fe_check,
                         calibrate, CalibrationResult, CalibrationSettings, InversionSettings,
                         RegionSettings, NoiseSettings, likelihood_ratio_region, rvc, nested_analyses, sample_posterior,
                         reading_sensitivity, misfit_sensitivity)
    from podkrig import diagnose, DiagnosisResult, DiagnosisSettings    # diagnosis
    from podkrig import place_sensors                                   # test design
    from podkrig import load_study, run_study                           # studies
    from podkrig import minimize, GeneticAlgorithm, GAOptions           # the GA

Names are resolved on first use (PEP 562): ``import podkrig`` stays cheap (the CLI imports it for
its version; the stages pull numba, scipy, h5py and Dask, several seconds on a cold start).
"""

import importlib
import sys
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("podkrig")
except PackageNotFoundError:  # pragma: no cover - running from a source tree without install
    __version__ = "0.0.0+unknown"

#: public name → module that defines it
_PUBLIC = {
    "ParameterSpace": "podkrig.parameters",
    "PodkrigError": "podkrig.exceptions",
    "StoreError": "podkrig.exceptions",
    "SnapshotStore": "podkrig.offline.store",
    "run_snapshots": "podkrig.offline.runner",
    "sample": "podkrig.offline.sampling",
    "PODKriging": "podkrig.surrogate.podkriging",
    "fit_from_store": "podkrig.surrogate.podkriging",
    "make_backend": "podkrig.surrogate.backends",
    "OrdinaryKriging": "podkrig.surrogate.kriging",
    "POD": "podkrig.surrogate.pod",
    "held_out_errors": "podkrig.surrogate.validation",
    "Measurement": "podkrig.online.measurement",
    "NoiseModel": "podkrig.online.measurement",
    "read_measurement_csv": "podkrig.io.measurement_log",
    "write_measurement_csv": "podkrig.io.measurement_log",
    "load_surrogate": "podkrig.io.surrogate_file",
    "save_surrogate": "podkrig.io.surrogate_file",
    "read_measurement": "podkrig.io.measurement_log",
    "ImportSettings": "podkrig.io.measurement_log",
    "instrument_noise": "podkrig.online.measurement",
    "InverseProblem": "podkrig.online.problem",
    "JointProblem": "podkrig.online.joint",
    "SurrogateModel": "podkrig.online.problem",
    "FEModel": "podkrig.online.problem",
    "fix_from_scenario": "podkrig.online.problem",
    "invert": "podkrig.online.invert",
    "fe_check": "podkrig.online.invert",
    "calibrate": "podkrig.online.calibrate",
    "CalibrationResult": "podkrig.online.calibrate",
    "CalibrationSettings": "podkrig.online.settings",
    "InversionSettings": "podkrig.online.settings",
    "RegionSettings": "podkrig.online.settings",
    "NoiseSettings": "podkrig.online.settings",
    "DiagnosisResult": "podkrig.diagnosis.results",
    "DiagnosisSettings": "podkrig.diagnosis.settings",
    "likelihood_ratio_region": "podkrig.online.region",
    "noise_monte_carlo_region": "podkrig.online.region",
    "rvc": "podkrig.online.propagation",
    "nested_analyses": "podkrig.online.nested",
    "sample_posterior": "podkrig.online.posterior",
    "reading_sensitivity": "podkrig.online.sensitivity",
    "misfit_sensitivity": "podkrig.online.sensitivity",
    "diagnose": "podkrig.diagnosis",
    "place_sensors": "podkrig.sensors.placement",
    "load_study": "podkrig.study",
    "run_study": "podkrig.study",
    "minimize": "podkrig.ga",
    "GeneticAlgorithm": "podkrig.ga",
    "GAOptions": "podkrig.ga",
}

__all__ = ["__version__", *sorted(_PUBLIC)]


def __getattr__(name):
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'podkrig' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__


def _show_results_in_jupyter():
    """In a running IPython (a notebook), register the HTML of the results
    (:mod:`podkrig.reports.jupyter`, imported for that); elsewhere nothing is imported."""
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None and hasattr(ipython, "get_ipython") else None
    if shell is not None:
        importlib.import_module("podkrig.reports.jupyter").register()


_show_results_in_jupyter()
