"""Shared pytest fixtures."""

import contextlib
import logging

import pytest

from fe.scenarios import Scenario, build_scenario


@pytest.fixture(scope="session")
def coarse_diagonal():
    """The diagonal compression test on a coarse mesh (2 × 1 Q8 per unit): fast, same physics."""
    return build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})


@pytest.fixture(scope="session")
def default_diagonal():
    """The diagonal compression test with its default (converged) mesh."""
    return build_scenario("diagonal_compression")


class FECounter:
    """Counts FE runs (``Scenario.run`` calls) in this process while a test runs."""

    def __init__(self, monkeypatch):
        self.calls = 0
        original = Scenario.run

        def counted(scenario, *args, **kwargs):
            self.calls += 1
            return original(scenario, *args, **kwargs)

        monkeypatch.setattr(Scenario, "run", counted)


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
