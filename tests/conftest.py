"""Shared pytest fixtures and helpers."""

import contextlib
import importlib.util
import logging
from pathlib import Path

import h5py
import pytest

from fe.scenarios import Scenario, build_scenario
from fe.scenarios.diagonal_compression import DEFAULT_SENSORS
from podkrig.parameters import ParameterSpace

#: the 9 × 9 displacement grid over the diagonal test's panel that the diagnosis tests add to its
#: six gauges (mm)
DIC_9X9 = {"kind": "dic", "x0": 65.0, "y0": 32.5, "x1": 1105.0, "y1": 1072.5, "nx": 9, "ny": 9}
#: the joint stiffnesses the diagnosis tests leave free (N/mm³, log-uniform)
JOINT_BOUNDS = {"kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log")}


def load_file(path):
    """Import the Python file ``path`` (a script of ``scripts/`` or ``examples/``, which are not
    packages) as a module named by its stem, without running its ``main``."""
    path = Path(path)
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def done_rows(path):
    """Finished rows of a snapshot store another process is writing (read without the HDF5 lock;
    0 while the file is absent or not yet a store)."""
    try:
        with h5py.File(path, "r", locking=False) as f:
            return int((f["status"][...] == 1).sum())
    except (OSError, KeyError):
        return 0


@pytest.fixture(scope="session")
def coarse_diagonal():
    """The diagonal compression test on a coarse mesh (2 × 1 Q8 per unit): fast, same physics."""
    return build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})


@pytest.fixture(scope="session")
def default_diagonal():
    """The diagonal compression test with its default (converged) mesh."""
    return build_scenario("diagonal_compression")


@pytest.fixture(scope="session")
def dic_diagonal():
    """The diagonal test on the coarse mesh (2 × 1 Q8 per unit) with its six gauges and
    :data:`DIC_9X9`."""
    sensors = {g.name: g.to_dict() for g in DEFAULT_SENSORS}
    sensors["DIC"] = dict(DIC_9X9)
    return build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1, "sensors": sensors})


@pytest.fixture(scope="session")
def dic_diagonal_space(dic_diagonal):
    """:data:`JOINT_BOUNDS` over :func:`dic_diagonal`; the other parameters at their defaults."""
    return ParameterSpace.from_scenario(dic_diagonal, JOINT_BOUNDS)


@pytest.fixture(scope="session")
def dic_diagonal_surrogate(dic_diagonal, dic_diagonal_space):
    """The diagnosis base surrogate of :func:`dic_diagonal` over :func:`dic_diagonal_space`: 64
    Sobol' FE runs (seed 0), as ``diagnose`` builds it. Built once per session (per xdist worker)
    and shared: read-only — a test that refits or changes it works on a ``copy.deepcopy``."""
    from podkrig.diagnosis import build_base_surrogate

    return build_base_surrogate(dic_diagonal, dic_diagonal_space, dic_diagonal.resolve(), 64, 0)


class FECounter:
    """Counts FE runs (``run`` calls of :class:`Scenario` and of every subclass that overrides it,
    e.g. the nonlinear scenarios) in this process while a test runs."""

    def __init__(self, monkeypatch):
        self.calls = 0
        classes, todo = [], [Scenario]
        while todo:
            cls = todo.pop()
            todo.extend(cls.__subclasses__())
            if "run" in vars(cls):
                classes.append(cls)
        for cls in classes:
            monkeypatch.setattr(cls, "run", self._counted(vars(cls)["run"]))

    def _counted(self, original):
        def counted(scenario, *args, **kwargs):
            self.calls += 1
            return original(scenario, *args, **kwargs)

        return counted


@pytest.fixture
def fe_counter(monkeypatch):
    """Start counting FE runs at any point of a test: ``counter = fe_counter()``, then
    ``counter.calls``."""
    return lambda: FECounter(monkeypatch)


@contextlib.contextmanager
def _counting_fe_runs():
    with pytest.MonkeyPatch.context() as monkeypatch:
        yield FECounter(monkeypatch)


@pytest.fixture(scope="session")
def count_fe_runs():
    """Count FE runs inside a block, in a fixture shared by several tests (a module-scoped run
    that tests check in turn): ``with count_fe_runs() as counter: ...``, then ``counter.calls``."""
    return _counting_fe_runs


@pytest.fixture(autouse=True)
def _project_loggers_enabled():
    """Importing ``distributed`` (a Dask test earlier in the same worker) runs
    ``logging.config.dictConfig``, which disables every logger that exists then; a later test that
    checks a podkrig warning with ``caplog`` would see nothing. The product repairs this after its
    own import (:func:`podkrig.offline.runner.import_distributed`); a test that imports
    ``distributed`` directly bypasses that, so ours are re-enabled before each test too."""
    for name, logger in list(logging.root.manager.loggerDict.items()):
        if isinstance(logger, logging.Logger) and name.split(".")[0] in ("podkrig", "fe"):
            logger.disabled = False
    yield
