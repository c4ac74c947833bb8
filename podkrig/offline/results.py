"""The result of the offline stage: a snapshot store's numbers after a run.

:class:`OfflineResult` is what ``podkrig snapshots run`` reports and what a study's offline stages
(``offline``, ``held_out``) record in their manifests (:meth:`OfflineResult.to_dict`); the study
report reads it back with :meth:`OfflineResult.from_dict` and both render it through
:mod:`podkrig.reports.offline`.

Examples
--------
>>> r = OfflineResult(total=16, done=15, failed=1, pending=0, executor="serial", n_dofs=120,
...                   fe_ms_per_run=12.5, fe_seconds_total=0.19, failures=("row 3: no convergence",))
>>> OfflineResult.from_dict(r.to_dict()) == r
True
"""

from dataclasses import dataclass

import numpy as np

from podkrig.display import Displayed
from podkrig.offline.failures import FailureReport, failure_report
from podkrig.offline.store import SnapshotStore

__all__ = ["OfflineResult"]

#: failed rows whose error text a result keeps (the store keeps every one)
SHOWN_FAILURES = 5


@dataclass(frozen=True, repr=False)
class OfflineResult(Displayed):
    """A snapshot store after an offline run.

    Attributes
    ----------
    total, done, failed, pending : int
        Rows of the store (FE runs): all, finished, failed, not run yet.
    executor : str
        Where the rows ran (:attr:`podkrig.offline.runner.RunSummary.executor`).
    n_dofs : int
        Degrees of freedom of the FE model.
    fe_ms_per_run : float or None
        Mean wall time of a stored row's FE run, ms (None: no row ran).
    fe_seconds_total : float
        Wall time of every stored row's FE run, s.
    failures : tuple of str
        ``"row I: error"`` of the first :data:`SHOWN_FAILURES` failed rows.
    notes : tuple of str
        What else a user should know (a store kept aside and rebuilt, a serial run of a small job).
    failure : FailureReport or None
        With failed rows: their share, reasons and the classifier of where they fail
        (:func:`~podkrig.offline.failures.failure_report`).
    """

    total: int
    done: int
    failed: int
    pending: int
    executor: str
    n_dofs: int
    fe_ms_per_run: float | None
    fe_seconds_total: float
    failures: tuple = ()
    notes: tuple = ()
    failure: FailureReport | None = None

    @classmethod
    def from_store(cls, path, summary, notes=()):
        """The result of a run (``summary``: its :class:`~podkrig.offline.runner.RunSummary`) from
        the store at ``path`` (its per-row FE times and errors)."""
        with SnapshotStore.open(path) as store:
            wall = store.wall_times()
            failures = [f"row {i}: {e}" for i, e in store.errors().items()][:SHOWN_FAILURES] if summary.failed else []
            n_dofs = store.n_dofs
            failure = failure_report(store) if summary.failed else None
        ran = wall[np.isfinite(wall)]
        return cls(total=summary.total, done=summary.done, failed=summary.failed, pending=summary.pending,
                   executor=summary.executor, n_dofs=n_dofs,
                   fe_ms_per_run=float(1000 * ran.mean()) if len(ran) else None,
                   fe_seconds_total=float(ran.sum()), failures=tuple(failures), notes=tuple(notes), failure=failure)

    def to_dict(self):
        """JSON-able dict (a study's offline manifest); :meth:`from_dict` reads it back."""
        return {"total": self.total, "done": self.done, "failed": self.failed, "pending": self.pending,
                "executor": self.executor, "n_dofs": self.n_dofs, "fe_ms_per_run": self.fe_ms_per_run,
                "fe_seconds_total": self.fe_seconds_total, "failures": list(self.failures), "notes": list(self.notes),
                "failure": None if self.failure is None else self.failure.to_dict()}

    @classmethod
    def from_dict(cls, d):
        return cls(total=int(d["total"]), done=int(d["done"]), failed=int(d["failed"]), pending=int(d["pending"]),
                   executor=d["executor"], n_dofs=int(d["n_dofs"]),
                   fe_ms_per_run=None if d["fe_ms_per_run"] is None else float(d["fe_ms_per_run"]),
                   fe_seconds_total=float(d["fe_seconds_total"]), failures=tuple(d.get("failures", ())),
                   notes=tuple(d.get("notes", ())),
                   failure=None if d.get("failure") is None else FailureReport.from_dict(d["failure"]))
