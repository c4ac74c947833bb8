"""Calibration runs of ``podkrig serve``: the calibration stage in a worker thread, and its history.

A run calls :func:`podkrig.online.calibrate.calibrate` — the one calibration stage every front door
calls — on the session's problem with the parameters frozen on the page fixed at their values, the
noise model and GA settings of the page validated by the library's own settings classes
(:class:`~podkrig.online.settings.NoiseSettings`, :class:`~podkrig.online.settings.InversionSettings`).
:func:`result_view` turns a :class:`~podkrig.online.calibrate.CalibrationResult` into what the page
shows: the parameters with their intervals and identifiability in words, the region of equivalence
(at most :data:`MAX_REGION_MEMBERS` members for the pair plot), the FE check and the findings.
"""

import numpy as np

from podkrig.reports.findings import identifiability_text, words

#: members of the region of equivalence sent to the page (a deterministic subset of a larger region)
MAX_REGION_MEMBERS = 2000


def region_members(region, limit=MAX_REGION_MEMBERS):
    """``(samples, omega)`` of a region, at most ``limit`` members (a seeded subset, in order)."""
    samples, omega = region.samples, region.omega
    if samples is None:
        return np.empty((0, len(region.names))), np.empty(0)
    if len(samples) > limit:
        keep = np.sort(np.random.default_rng(0).choice(len(samples), limit, replace=False))
        samples, omega = samples[keep], omega[keep]
    return samples, omega


def result_view(result, diagnosis=None):
    """The page's view of a :class:`~podkrig.online.calibrate.CalibrationResult`: ``parameters``
    (value, interval, identified, the verdict in words), ``chi2_dof``, ``dof``, ``seconds``,
    ``n_fe_runs``, ``region`` (names, units, members, their ω and the best fit), ``fe_check`` (one
    entry per test checked), ``findings`` (code, level and message with its remedy) and
    ``diagnosis`` (a diagnosis result's dict, or None)."""
    inv, region = result.inversion, result.region
    verdicts = region.identifiability
    parameters = []
    for name, unit, value in zip(inv.free, inv.units, inv.x):
        interval = region.intervals.get(name)
        verdict = verdicts.get(name)
        parameters.append({
            "name": name, "unit": unit, "value": float(value),
            "interval": None if interval is None else [float(v) for v in interval],
            "identified": None if verdict is None else bool(verdict["identifiable"]),
            "words": "" if verdict is None or interval is None else identifiability_text(name, interval, unit, verdict),
        })
    samples, omega = region_members(region)
    checks = []
    for test, one in result.tests.items():
        fe = one.fe_check
        if fe is None:
            continue
        d = fe.to_dict()
        units = list((d.get("max_abs_diff_by_unit") or {"mm": None}))
        checks.append({"test": test, "max_diff": d["max_abs_diff"], "unit": units[0] if len(units) == 1 else "mm",
                       **d})
    return {
        "parameters": parameters, "chi2": float(inv.chi2), "chi2_dof": float(inv.chi2_dof), "dof": int(inv.dof),
        "seconds": float(result.seconds), "n_fe_runs": int(result.n_fe_runs),
        "region": {"names": list(region.names), "units": list(region.units), "samples": samples.tolist(),
                   "omega": omega.tolist(), "n_members": int(len(region.samples) if region.samples is not None else 0),
                   "confidence": float(region.confidence), "best": [float(v) for v in inv.x]},
        "fe_check": checks,
        "findings": [{"code": f.code, "level": f.level, "message": f"{f.message} {f.remedy}".strip()}
                     for f in words(result.findings, "study")],
        "diagnosis": diagnosis,
    }


__all__ = ["MAX_REGION_MEMBERS", "region_members", "result_view"]
