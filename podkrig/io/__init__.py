"""File formats at the edge of the numerics: what is read from or written to disk, and nothing else.

- :mod:`~podkrig.io.measurement_log` — laboratory measurement logs (CSV, Excel ``.xlsx``, units
  by pint) read into a :class:`~podkrig.online.measurement.Measurement`;
- :mod:`~podkrig.io.surrogate_file` — the HDF5 file of a fitted
  :class:`~podkrig.surrogate.PODKriging` (``save_surrogate`` / ``load_surrogate``, schema versions).

The numerical stages (``offline``, ``surrogate``, ``online``, ``diagnosis``, ``sensors``, ...) take
and return objects and arrays; they never import this package, nor h5py, openpyxl or pint (the
import contract in ``pyproject.toml``). The front ends (``cli``, ``study``, ``reports``) read and
write files through it. The snapshot store (:mod:`podkrig.offline.store`) stays in the offline
stage: the runner appends to it row by row while FE runs finish.
"""
