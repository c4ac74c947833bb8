"""Shared pytest fixtures and helpers."""

import contextlib
import fcntl
import importlib.util
import json
import logging
import os
import shutil
from pathlib import Path

import h5py
import pytest

from fe.scenarios import Scenario, build_scenario
from fe.scenarios.diagonal_compression import DEFAULT_SENSORS
from podkrig.parameters import ParameterSpace

ROOT = Path(__file__).resolve().parents[1]

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


def shared_cli_run(tmp_path_factory, name, args):
    """``podkrig ARGS`` run once per test session in the folder ``name`` (a scratch folder with
    ``examples/`` beside it, the command's working directory) and shared by every test and every
    xdist worker of the session that asks for it: ``(folder, exit_code, output)``.

    The first caller runs it under an exclusive lock on ``NAME.lock`` in the session's temporary
    folder (the parent of a worker's own, which all workers of one session share); the others wait
    on the lock and read the result. Read-only for the tests: one that writes into the run's
    folder works on a copy (its stages are cached by their inputs' contents, so a copy resumes as
    the original would: every finished stage skipped)."""
    from typer.testing import CliRunner

    from podkrig.cli import app

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent
    folder, result = root / name, root / f"{name}.json"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes (or the process dies)
        if not result.is_file():
            shutil.rmtree(folder, ignore_errors=True)  # what a caller that raised left
            folder.mkdir()
            (folder / "examples").symlink_to(ROOT / "examples")
            with pytest.MonkeyPatch.context() as monkeypatch:
                monkeypatch.chdir(folder)
                run = CliRunner().invoke(app, args)
            result.write_text(json.dumps({"exit_code": run.exit_code, "output": run.output}))
    done = json.loads(result.read_text())
    return folder, done["exit_code"], done["output"]


@pytest.fixture(scope="session")
def demo_run(tmp_path_factory):
    """``podkrig demo --skip-diagnosis`` (the README's first command, about 350 FE runs) run once
    per session, see :func:`shared_cli_run`; its study folder is ``FOLDER/out/demo``."""
    return shared_cli_run(tmp_path_factory, "demo_skip_diagnosis", ["demo", "--skip-diagnosis"])


@pytest.fixture(scope="session")
def triplet_series_run(tmp_path_factory):
    """``podkrig run examples/triplet_series.toml --out out/triplet_series`` (docs/strength.md's
    command, 518 FE runs) run once per session, see :func:`shared_cli_run`; its study folder is
    ``FOLDER/out/triplet_series``."""
    return shared_cli_run(tmp_path_factory, "triplet_series",
                          ["run", "examples/triplet_series.toml", "--out", "out/triplet_series"])


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


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread_per_xdist_worker():
    """Under ``pytest -n N`` the N worker processes already use the cores: each worker's MKL (the
    PARDISO sparse solver) and OpenBLAS get one thread, as :func:`podkrig.parallel.one_blas_thread`
    gives the online stage. With their default (one thread per core) the workers' pools compete
    for the same cores: the linear FE solves of the diagnosis tests took 20 % more CPU with two
    MKL threads than with one even in a single process (tests/test_diagnosis.py's negative
    control, 4 trials: 10.9 s against 8.7 s), and its two negative controls under ``-n 2`` 123 s
    against 90 s (the nonlinear strength trials: no difference). A limit at run time, in this process only: subprocesses a test starts
    (tests/test_fe_verification.py switches MKL's threads in one) keep their defaults. Without
    xdist (``-p no:xdist``, one process) the libraries keep theirs."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        yield
        return
    from threadpoolctl import threadpool_limits

    with contextlib.suppress(ImportError):
        import pypardiso  # noqa: F401  (loads MKL, so that the limit reaches it)
    with threadpool_limits(limits=1, user_api="blas"):
        yield


@pytest.fixture
def memo_nonlinear_runs(monkeypatch):
    """Serve a nonlinear scenario's repeated runs from memory while a test runs: a second
    ``run(params)`` of a scenario with the same spec and bitwise the same resolved values returns
    a copy of the first run's response instead of following the load path again (runs with
    ``field`` or ``settings`` are not kept). The path following is a deterministic function of
    those inputs in one process (tests/test_diagnosis_strength.py compares two runs bitwise), so
    what a test computes is unchanged (a weak-joint and a dilatancy trial: the same diagnosis to
    every number but its time); only the FE runs it repeats are saved — a diagnosis on a curve
    repeats about a quarter of its runs (572 and 561 runs, 416 and 422 distinct: a refit's final
    point, the start of the next one), since its FE context keeps only its last run. Returns the memo (key → response)."""
    import copy

    from fe.scenarios.nonlinear import NonlinearScenario

    original, memo = NonlinearScenario.run, {}

    def run(scenario, params=None, *, field=False, settings=None):
        if field or settings is not None:
            return original(scenario, params, field=field, settings=settings)
        key = (json.dumps(scenario.spec.to_dict(), sort_keys=True, default=repr),
               tuple(sorted(scenario.resolve(params).items())))
        if key not in memo:
            memo[key] = original(scenario, params)
        return copy.deepcopy(memo[key])

    monkeypatch.setattr(NonlinearScenario, "run", run)
    return memo


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
