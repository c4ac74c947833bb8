"""Settings of the offline stage: the sampling designs of FE runs and where the runs go.

Each field states its default, unit and allowed values once (:mod:`podkrig.config`); the study
file's ``[sampling]`` table validates into :class:`SamplingSettings`, ``podkrig snapshots run``
builds a :class:`Design` from its options and takes its ``--sampling`` choices from
:data:`SAMPLING_METHODS`, and a study's offline stage is cached by ``dataclasses.asdict`` of the
design it ran.

Examples
--------
>>> design = Design(n=16, seed=3)
>>> design.method, design.run_arguments()
('sobol', {'n': 16, 'seed': 3, 'sampling': 'sobol'})
"""

from typing import Annotated

from pydantic import AfterValidator, StrictInt, StrictStr

from podkrig import limits
from podkrig.config import Seed, allowed, choice, limit, settings, settings_error

__all__ = ["SAMPLING_METHODS", "Design", "SamplingSettings", "TrainingDesign"]

#: sampling designs (:func:`podkrig.offline.sampling.sample`); "lhs-ese" is SMT's optimised Latin
#: hypercube (enhanced stochastic evolution)
SAMPLING_METHODS = ("sobol", "lhs", "random", "lhs-ese")

#: FE runs of a design: at most limits.MAX_ROWS (the estimate at ~1 KiB per stored row)
ROWS_ALLOWED = f"an integer in [{{}}, {limits.MAX_ROWS}] (FE runs)"
#: the row limit of a design (first: of any design; second: of one that trains a surrogate)
rows = limit(lambda n: limits.check_rows(n, 1024, "n"), ROWS_ALLOWED.format(1))
training_rows = limit(lambda n: limits.check_rows(n, 1024, "n"), ROWS_ALLOWED.format(4))


def _refuse(value):
    raise ValueError("out of range")


@settings
class Design:
    """A seeded sampling design: ``n`` points by ``method`` with ``seed``."""

    n: Annotated[StrictInt, allowed(ROWS_ALLOWED.format(1), ge=1), rows]
    seed: Seed
    method: choice(SAMPLING_METHODS) = "sobol"

    def run_arguments(self):
        """The design as keyword arguments of :func:`podkrig.offline.runner.run_snapshots` and
        :func:`~podkrig.offline.runner.prepare_store` (``n``, ``seed``, ``sampling``)."""
        return {"n": self.n, "seed": self.seed, "sampling": self.method}


@settings
class TrainingDesign(Design):
    """A design that trains a surrogate (training set, validation models): at least 4 points."""

    n: Annotated[StrictInt, allowed(ROWS_ALLOWED.format(4), ge=4), training_rows]


@settings
class SamplingSettings:
    """Training and held-out designs and where the FE runs go: ``workers`` local processes (1: in
    this process; the default when no ``scheduler`` is given) or a Dask ``scheduler``."""

    train: TrainingDesign
    held_out: Design
    workers: Annotated[StrictInt, allowed(f"an integer in [1, {limits.MAX_WORKERS}] (FE processes; 1 runs them in "
                                          "this process)", ge=1),
                       limit(limits.check_workers, f"an integer in [1, {limits.MAX_WORKERS}]")] | None = None
    scheduler: Annotated[StrictStr, AfterValidator(lambda v: v if "://" in v else _refuse(v)),
                         allowed("a Dask scheduler address such as 'tcp://10.0.0.5:8786'")] | None = None

    def __post_init__(self):
        if self.scheduler is not None and self.workers is not None:
            raise settings_error("give either workers (local processes) or scheduler (a Dask cluster), not both",
                                 "workers")
        if self.scheduler is None and self.workers is None:
            object.__setattr__(self, "workers", 1)
