"""Offline stage: FE snapshots over a sampled parameter design into a resumable HDF5 store.

- :mod:`~podkrig.offline.sampling` — Sobol', Latin hypercube and random designs in the unit cube;
- :mod:`~podkrig.offline.store` — the self-describing, crash-safe snapshot store;
- :mod:`~podkrig.offline.runner` — runs a scenario over a design, serially or on Dask;
- :mod:`~podkrig.offline.settings` — the designs and where the runs go (``[sampling]``);
- :mod:`~podkrig.offline.results` — a store's numbers after a run (:class:`OfflineResult`).
"""

from podkrig.offline.runner import run_snapshots
from podkrig.offline.sampling import sample
from podkrig.offline.store import SnapshotStore

__all__ = ["SnapshotStore", "run_snapshots", "sample"]
