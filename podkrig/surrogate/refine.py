"""Adaptive enrichment of a POD-kriging surrogate: add FE runs where it is least certain.

Each round fits the surrogate on the finished rows of the training store, measures the held-out
median relative error, and, unless the target or the budget is reached, appends the ``batch``
candidates of largest predictive variance (summed over the outputs, mm²) from a scrambled Sobol'
candidate set to the store (:meth:`~podkrig.offline.store.SnapshotStore.extend`) and runs them with the
offline runner (:func:`~podkrig.offline.runner.run_pending`), so that every new snapshot is saved and an
interrupted refinement resumes from the store. Selected points keep a minimum distance from each
other (half the mean nearest-neighbour distance of the training design) so that a batch does not
cluster around one variance peak.
"""

import logging
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from podkrig._qmc import rng_seed
from podkrig.offline.runner import run_pending
from podkrig.config import make_settings
from podkrig.offline.sampling import sample
from podkrig.offline.store import SnapshotStore
from podkrig.surrogate.podkriging import fit_from_store, training_data
from podkrig.surrogate.settings import RefineSettings
from podkrig.surrogate.validation import held_out_errors

logger = logging.getLogger(__name__)


def select_batch(U_candidates, score, U_train, k):
    """Greedy choice of ``k`` high-score candidates kept apart from each other.

    Parameters
    ----------
    U_candidates : ndarray of shape (m, d)
        Candidate points, unit cube.
    score : ndarray of shape (m,)
        Larger is more wanted (e.g. predictive variance, mm²).
    U_train : ndarray of shape (n, d)
        Current design, unit cube.
    k : int

    Returns
    -------
    ndarray of int, shape (<= k,)
        Indices into ``U_candidates``.
    """
    nn = cKDTree(U_train).query(U_train, k=2)[0][:, 1]
    radius = 0.5 * float(np.mean(nn))
    order = np.argsort(score)[::-1]
    chosen = []
    for i in order:
        if len(chosen) == k:
            break
        if chosen and np.min(np.linalg.norm(U_candidates[chosen] - U_candidates[i], axis=1)) < radius:
            continue
        chosen.append(int(i))
    return np.array(chosen, dtype=int)


def refine_surrogate(surrogate, store, held_out, *, target_error=None, budget=None, batch=None, n_candidates=None,
                     rng=None, workers=None, sampling=None):
    """Enrich the training store until the held-out median error or the FE budget is reached.

    Parameters
    ----------
    surrogate : PODKriging
        The surrogate to refine: its settings (POD, regressor, output) are reused; it is left
        unchanged.
    store : str or Path
        Training snapshot store (appended to).
    held_out : str or Path
        Held-out snapshot store (read only).
    target_error : float
        Held-out median relative error to reach (-). Every setting is checked against the ranges
        of :class:`~podkrig.surrogate.settings.RefineSettings`, and one left None takes its default
        there (the one definition of the defaults).
    budget : int
        Maximum number of new FE runs.
    batch : int
        FE runs per round.
    n_candidates : int
        Size of the candidate set (a power of two for Sobol').
    rng : int or numpy.random.Generator
        Source of the candidate sets: round ``r`` (1, 2, ...) draws its set with seed ``rng + r``
        (a Generator gives the base seed by one draw).
    workers : int
        FE workers of the runner (1: in this process).
    sampling : {"sobol", "lhs", "lhs-ese", "random"}
        Design of the candidate set (:func:`podkrig.offline.sampling.sample`); ``"lhs-ese"`` is
        slow for thousands of candidates (reduce ``n_candidates``).

    Returns
    -------
    PODKriging
        Fitted on the final store, with ``provenance_["refinement"]``: ``added`` (FE runs),
        ``history`` (per round: ``n_train``, ``median``, ``p95``), ``stop_reason``.
    """
    r = make_settings(RefineSettings, {  # the ranges and defaults of RefineSettings, each refused value named
        "target_error": target_error, "budget": budget, "batch": batch, "n_candidates": n_candidates,
        "seed": None if isinstance(rng, np.random.Generator) else rng, "workers": workers, "sampling": sampling},
        {"seed": "rng"})
    target_error, budget, batch, n_candidates = r.target_error, r.budget, r.batch, r.n_candidates
    workers, sampling = r.workers, r.sampling
    store, held_out = Path(store), Path(held_out)
    seed = rng_seed(rng) if isinstance(rng, np.random.Generator) else r.seed
    template = surrogate
    output = template.provenance_.get("output", "readings")
    with SnapshotStore.open(held_out) as h:
        Xh, Yh = training_data(h, output)
    added, history = 0, []
    while True:
        with SnapshotStore.open(store) as s:
            sur = fit_from_store(s, pod=template.pod, kriging=template.kriging, output=output,
                                 layout=template.layout, scaling=template.scaling)
            U_train = s.parameters(physical=False, only_done=True)
            space = s.space
        summary = held_out_errors(sur, Xh, Yh, with_loo=False).summary()
        history.append({"n_train": len(U_train), "median": summary["rel_error"]["median"],
                        "p95": summary["rel_error"]["p95"]})
        logger.info("refine: %d snapshots, held-out median %.3g", len(U_train), history[-1]["median"])
        if history[-1]["median"] <= target_error:
            reason = f"target {target_error:g} reached"
            break
        if added >= budget:
            reason = f"budget of {budget} FE runs used"
            break
        k = min(batch, budget - added)
        U_cand = sample(sampling, n_candidates, space.n_params, seed + len(history))
        _, std = sur.predict_unit(U_cand, return_std=True)
        pick = select_batch(U_cand, np.sum(std**2, axis=1), U_train, k)
        SnapshotStore.extend(store, U_cand[pick])
        summary_run = run_pending(store, workers=workers)
        added += len(pick)
        if summary_run.failed_now:
            logger.warning("refine: %d of %d new FE runs failed (kept as failed rows)", summary_run.failed_now,
                           len(pick))
    sur.provenance_["refinement"] = {"added": added, "history": history, "stop_reason": reason}
    return sur
