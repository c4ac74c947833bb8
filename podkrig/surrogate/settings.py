"""Settings of the surrogate stage: POD truncation, the kriging of the POD coefficients and the
backend that regresses them.

Each field states its default and allowed values once (:mod:`podkrig.config`): the study file's
``[surrogate]`` table validates into :class:`SurrogateSettings`, ``podkrig surrogate build`` builds
one from its options and takes its ``--variogram``, ``--criterion`` and ``--backend`` choices from
it, and both fit through :func:`fit_surrogate` (templates from :meth:`SurrogateSettings.templates`).
A study's surrogate stage is cached by ``dataclasses.asdict`` of these settings.

Examples
--------
>>> s = SurrogateSettings(modes=3, beta=1.5)
>>> pod, kriging = s.templates()
>>> pod.n_modes, kriging.beta, kriging.variogram
(3, 1.5, 'exponential')
>>> SurrogateSettings(backend="sklearn-gpr").templates()[1].backend
'sklearn-gpr'
"""

import logging
import time
from typing import Annotated, Any

from pydantic import AfterValidator, StrictFloat, StrictInt

from podkrig import limits
from podkrig.config import Seed, allowed, choice, finite, settings, settings_error, type_name
from podkrig.exceptions import StoreError
from podkrig.offline.failures import failure_report
from podkrig.offline.settings import SAMPLING_METHODS
from podkrig.surrogate.backends import BACKENDS as _BACKEND_REGISTRY
from podkrig.surrogate.backends import make_backend
from podkrig.surrogate.kriging import DEFAULT_BETA, VARIOGRAMS as _VARIOGRAM_REGISTRY, OrdinaryKriging
from podkrig.surrogate.kriging.ordinary import CRITERIA
from podkrig.surrogate.pod import POD
from podkrig.surrogate.podkriging import DEFAULT_ENERGY, LAYOUTS, SCALINGS, fit_from_store

__all__ = ["BACKENDS", "BETA_MODES", "CRITERIA", "FAILED_ROWS", "VARIOGRAMS", "RefineSettings", "SurrogateSettings", "fit_surrogate"]

#: semivariogram models of the kriging (:mod:`podkrig.surrogate.kriging.variogram`)
VARIOGRAMS = tuple(_VARIOGRAM_REGISTRY)
#: fitted exponents: per mode, or on the first mode and shared by all
BETA_MODES = ("fit", "fit-shared")
#: surrogate backends behind the one surrogate interface (:mod:`podkrig.surrogate.backends`)
BACKENDS = tuple(_BACKEND_REGISTRY)

logger = logging.getLogger(__name__)

#: what a fit does with a store's failed rows (:func:`fit_surrogate`)
FAILED_ROWS = ("drop", "refuse")

BETA_ALLOWED = "a number in (0, 2] (below 2 for the power variogram), \"fit\" or \"fit-shared\""


@settings
class SurrogateSettings:
    """POD truncation (``energy`` or ``modes``; neither: energy 1 − 10⁻⁸), the kriging of the POD
    coefficients (semivariogram, exponent β, hyperparameter criterion, nugget relative to the sill)
    and the surrogate ``backend`` (another backend than ``"podkrig"`` fits its own hyperparameters:
    the kriging settings do not apply to it); ``pod``: one POD over the responses stacked at all
    control levels or a POD + kriging per level (thesis §4.3.3), and the ``scaling`` of mixed outputs
    (kN and mm) before the POD (:class:`~podkrig.surrogate.PODKriging`); ``failed_rows``: whether a
    store with failed rows trains on its finished rows (``"drop"``, stating how many and which) or is
    refused."""

    energy: Annotated[StrictFloat, allowed("a number in (0, 1], e.g. 0.99999999", unit="-", gt=0, le=1)] | None = None
    modes: Annotated[StrictInt, allowed("an integer >= 1", ge=1)] | None = None
    variogram: choice(VARIOGRAMS) = "exponential"
    beta: Annotated[Any, allowed(BETA_ALLOWED, unit="-")] = DEFAULT_BETA
    criterion: choice(CRITERIA) = "ml"
    nugget: Annotated[StrictFloat, AfterValidator(finite),
                      allowed("a number in [0, 1] (relative to the sill: 1 is as much noise as signal)", unit="-",
                              ge=0, le=1)] = 0.0
    backend: choice(BACKENDS) = "podkrig"
    pod: choice(LAYOUTS, "stacked (one POD over the responses at all control levels) or per_level (a POD + "
                         "kriging per control level)") = "stacked"
    scaling: choice(SCALINGS, "unit, sensor or none (each output divided before the POD by the standard "
                              "deviation over the snapshots pooled per unit or per sensor: kN and mm weigh "
                              "alike)") = "unit"
    failed_rows: choice(FAILED_ROWS) = "drop"

    def __post_init__(self):
        if self.energy is not None and self.modes is not None:
            raise settings_error("give either energy or modes, not both", "modes")
        beta = self.beta
        if isinstance(beta, str):
            if beta not in BETA_MODES:
                raise settings_error(f"{beta!r} is not a known exponent setting", "beta", BETA_ALLOWED)
            return
        if isinstance(beta, bool) or not isinstance(beta, int | float):
            raise settings_error(f"must be a number; got {type_name(beta)} {beta!r}", "beta", BETA_ALLOWED)
        if not (0 < beta <= 2 and (self.variogram != "power" or beta < 2)):
            raise settings_error(f"{beta!r} is out of range", "beta", BETA_ALLOWED)
        object.__setattr__(self, "beta", float(beta))

    def templates(self):
        """Unfitted POD and regression templates of these settings, as
        :class:`~podkrig.surrogate.PODKriging` takes them: ``(POD, regressor)`` — our
        :class:`~podkrig.surrogate.kriging.OrdinaryKriging` with the kriging settings, or the
        ``backend``'s regressor with its own defaults."""
        pod = POD(n_modes=self.modes) if self.modes is not None else POD(energy=self.energy or DEFAULT_ENERGY)
        # the layout (``pod``) and ``scaling`` are the surrogate's own: fit_surrogate passes them
        if self.backend != "podkrig":
            return pod, make_backend(self.backend)
        return pod, OrdinaryKriging(variogram=self.variogram, beta=self.beta, criterion=self.criterion,
                                    nugget=self.nugget)


_WORKERS_ALLOWED = f"an integer in [1, {limits.MAX_WORKERS}] (FE processes; 1 runs them in this process)"


@settings
class RefineSettings:
    """Adaptive refinement of a surrogate (:func:`~podkrig.surrogate.refine.refine_surrogate`): add
    ``batch`` FE runs per round where the surrogate is least certain among ``n_candidates`` points
    of a ``sampling`` design (seeded by ``seed``), until the held-out median relative error is at
    most ``target_error`` or ``budget`` FE runs were added; ``workers`` FE processes."""

    target_error: Annotated[StrictFloat, allowed("a number in (0, 1] (held-out median relative error)", unit="-",
                                                 gt=0, le=1)] = 0.005
    budget: Annotated[StrictInt, allowed(f"an integer in [0, {limits.MAX_ROWS}] (new FE runs)", ge=0,
                                         le=limits.MAX_ROWS)] = 64
    batch: Annotated[StrictInt, allowed("an integer >= 1 (FE runs per round)", ge=1)] = 8
    n_candidates: Annotated[StrictInt, allowed(f"an integer in [1, {limits.MAX_ROWS}] (candidate points)", ge=1,
                                               le=limits.MAX_ROWS)] = 4096
    seed: Seed = 1
    workers: Annotated[StrictInt, allowed(_WORKERS_ALLOWED, ge=1, le=limits.MAX_WORKERS)] = 1
    sampling: choice(SAMPLING_METHODS) = "sobol"


def fit_surrogate(store, settings, output="readings", exclude=(), why=""):
    """Fit a surrogate of these settings on a snapshot store, timed.

    Only finished rows train it. Failed rows — FE runs that raised, and nonlinear runs that
    stopped early (partial rows: their readings end where the run stopped) — are never used
    silently: with ``settings.failed_rows == "refuse"`` a store holding any is refused; with
    ``"drop"`` they are left out with a warning naming how many and which, and recorded in the
    surrogate's provenance (``dropped_rows``, ``failed_share``) with the classifier of where runs
    fail (``failure_region``, :class:`~podkrig.offline.failures.FailureRegion`), which the
    inversion uses to warn when its best fit lies in that region.

    Parameters
    ----------
    store : podkrig.offline.store.SnapshotStore
        An open store.
    settings : SurrogateSettings
    output : {"readings", "field"}
    exclude : sequence of int
        Finished rows left out as well, recorded with ``why`` (words) in the provenance
        (``excluded_rows``, ``excluded_why``): e.g. the runs without a load maximum
        (:func:`~podkrig.offline.failures.no_peak_rows`) of a surrogate of capacity.
    why : str

    Returns
    -------
    PODKriging
        Fitted, with ``provenance_["training_seconds"]`` (s, wall time of the fit) beside the
        store's provenance (:func:`~podkrig.surrogate.podkriging.fit_from_store`).

    Raises
    ------
    StoreError
        ``failed_rows="refuse"`` and the store has failed rows (the message names them).
    """
    failures = failure_report(store) if store.counts()["failed"] else None
    if failures is not None:
        rows = _rows_text(failures.rows)
        why = ", ".join(f"{n} {reason}" for reason, n in sorted(failures.reasons.items()))
        if settings.failed_rows == "refuse":
            raise StoreError(
                f"{store.path}: {failures.n_failed} of {failures.n_run} FE runs failed or stopped early ({why}; "
                f"rows {rows}); failed_rows='refuse' does not fit a surrogate on such a store: rerun them with other "
                "solver settings, or set failed_rows='drop' to train on the finished rows only")
        logger.warning("%s: %d of %d FE runs failed or stopped early (%s; rows %s) and are left out of the surrogate "
                       "(failed_rows='drop')", store.path, failures.n_failed, failures.n_run, why, rows)
    pod, regressor = settings.templates()
    t0 = time.perf_counter()
    sur = fit_from_store(store, pod=pod, kriging=regressor, output=output, layout=settings.pod,
                         scaling=settings.scaling, exclude=exclude)
    sur.provenance_["training_seconds"] = time.perf_counter() - t0
    if len(exclude):
        logger.warning("%s: %d finished rows are left out of the surrogate (%s; rows %s)", store.path, len(exclude),
                       why, _rows_text(list(exclude)))
        sur.provenance_.update({"excluded_rows": [int(i) for i in exclude], "excluded_why": why})
    if failures is not None:
        sur.provenance_.update({
            "dropped_rows": list(failures.rows), "failed_share": failures.share, "failed_reasons": failures.reasons,
            "failure_region": None if failures.region is None else failures.region.to_dict()})
    return sur


def _rows_text(rows, limit=20):
    more = f" and {len(rows) - limit} more" if len(rows) > limit else ""
    return ", ".join(map(str, rows[:limit])) + more
