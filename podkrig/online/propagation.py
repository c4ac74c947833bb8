"""Propagation of an identification: response variability over the region of equivalence (RVC).

RVC (response variability of calibration/validation models, thesis ch. 5 and 7) is the spread of
a model's predictions over the members of a region of equivalence: per output, the coefficient
of variation std/|mean| and (max − min)/|mean|. A small CV for a validation model means the
calibration pins down what that other test would show.
"""

from dataclasses import dataclass

import numpy as np

from podkrig.display import Displayed


@dataclass(frozen=True, eq=False, repr=False)
class RVCResult(Displayed):
    """Spread of a model's outputs over a region of equivalence.

    Attributes
    ----------
    outputs : tuple of str
        Output names ``"SENSOR@LOAD"``.
    mean, std, min, max : ndarray of shape (n_outputs,)
        Over the region members, mm.
    cv : ndarray of shape (n_outputs,)
        std / |mean| (-).
    range_ratio : ndarray of shape (n_outputs,)
        (max − min) / |mean| (-).
    n_samples : int
        Region members used.
    values : ndarray of shape (n_samples, n_outputs) or None
        The outputs at each member, mm (for figures; not part of :meth:`to_dict`).
    """

    outputs: tuple
    mean: np.ndarray
    std: np.ndarray
    cv: np.ndarray
    range_ratio: np.ndarray
    min: np.ndarray
    max: np.ndarray
    n_samples: int
    values: np.ndarray | None = None

    def to_dict(self):
        """``outputs``, ``mean``, ``std``, ``cv``, ``range_ratio``, ``min``, ``max`` (lists aligned with
        ``outputs``) and ``n_samples``."""
        return {"outputs": list(self.outputs), "mean": self.mean.tolist(), "std": self.std.tolist(),
                "cv": self.cv.tolist(), "range_ratio": self.range_ratio.tolist(), "min": self.min.tolist(),
                "max": self.max.tolist(), "n_samples": self.n_samples}

    @classmethod
    def from_dict(cls, d, *, values=None):
        arrays = [np.asarray(d[k], dtype=float) for k in ("mean", "std", "cv", "range_ratio", "min", "max")]
        return cls(tuple(d["outputs"]), *arrays, int(d["n_samples"]), None if values is None else np.asarray(values))


def rvc(region, model, *, fixed=None, outputs=None, max_samples=20000, rng=0):
    """Response variability of a (calibration or validation) model over a region of equivalence.

    Parameters
    ----------
    region : Region
    model : object
        A batched model (``space``, ``sensor_names``, ``load_levels``, ``predict``) whose space
        contains the region's parameters; its other parameters take the values in ``fixed``.
    fixed : dict of str to float, optional
    outputs : sequence of str, optional
        Output names ``"SENSOR@LOAD"`` to report (default: every sensor at the last load level).
    max_samples : int
        Region members used (a seeded random subset when there are more).

    Returns
    -------
    RVCResult
    """
    fixed = dict(fixed or {})
    names = list(model.space.names)
    missing = [n for n in names if n not in region.names and n not in fixed]
    if missing:
        raise ValueError(f"RVC model needs values for {missing} (not calibrated): pass them as fixed")
    X = region.samples
    if len(X) > max_samples:
        X = X[np.random.default_rng(rng).choice(len(X), max_samples, replace=False)]
    full = np.empty((len(X), len(names)))
    for j, n in enumerate(names):
        full[:, j] = X[:, region.names.index(n)] if n in region.names else fixed[n]
    levels = np.asarray(model.load_levels, dtype=float)
    all_names = [f"{s}@{level:g}" for level in levels for s in model.sensor_names]
    if outputs is None:
        outputs = [f"{s}@{levels[-1]:g}" for s in model.sensor_names]
    unknown = [o for o in outputs if o not in all_names]
    if unknown:
        raise ValueError(f"unknown RVC output(s) {unknown}; outputs are SENSOR@LOAD, e.g. {all_names[:3]}")
    idx = [all_names.index(o) for o in outputs]
    Y, _ = model.predict(full, return_std=True)
    Y = Y[:, idx]
    mean = Y.mean(axis=0)
    std = Y.std(axis=0, ddof=1) if len(Y) > 1 else np.zeros_like(mean)
    scale = np.maximum(np.abs(mean), 1e-300)
    return RVCResult(tuple(outputs), mean, std, std / scale, (Y.max(axis=0) - Y.min(axis=0)) / scale, Y.min(axis=0),
                     Y.max(axis=0), int(len(Y)), Y)


__all__ = ["RVCResult", "rvc"]
