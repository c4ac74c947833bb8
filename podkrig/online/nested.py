"""Overparameterisation: nested analyses with growing sets of free parameters (thesis ch. 5).

Each analysis frees a set of parameters and calibrates them
(:func:`~podkrig.online.calibrate.calibrate`: identify, sample the region of equivalence and,
optionally, propagate it to validation models; no FE check). Misfit alone always improves when a parameter is
freed; the information criteria (AIC, BIC), the identifiability verdicts and the validation RVC
tell whether the extra parameter is supported by the data.
"""

from dataclasses import dataclass

import numpy as np

from podkrig.display import Displayed
from podkrig.online.calibrate import calibrate
from podkrig.online.settings import CONFIDENCE, CalibrationSettings, InversionSettings, RegionSettings


def information_criteria(result):
    """AIC and BIC of an inversion with Gaussian noise of known covariance.

    −2 log L = χ² + const, so AIC = χ² + 2k and BIC = χ² + k ln n (k free parameters, n
    observations); differences between nested analyses are what matter.
    """
    k, n = result.problem.n_free, result.problem.n_obs
    return {"aic": result.chi2 + 2 * k, "bic": result.chi2 + k * np.log(n)}


@dataclass(frozen=True, repr=False)
class NestedAnalysis(Displayed):
    """One analysis of :func:`nested_analyses`.

    Attributes
    ----------
    free : tuple of str
    parameters : dict of str to float
        Best fit of the free parameters, physical units.
    misfit, chi2_dof, aic, bic : float
    intervals : dict of str to (float, float)
        Equivalence intervals, physical units.
    identifiability : dict of str to dict
        :func:`podkrig.online.region.identifiability` verdicts.
    rvc : dict of str to float or None
        Per validation model: the largest CV of its outputs over the region (-).
    """

    free: tuple
    parameters: dict
    misfit: float
    chi2_dof: float
    aic: float
    bic: float
    intervals: dict
    identifiability: dict
    rvc: dict | None = None

    @property
    def unidentified(self):
        """Free parameters the data do not pin down."""
        return [n for n, v in self.identifiability.items() if not v["identifiable"]]

    def to_dict(self):
        d = {"free": list(self.free), "parameters": dict(self.parameters), "misfit": float(self.misfit),
             "chi2_dof": float(self.chi2_dof), "aic": float(self.aic), "bic": float(self.bic),
             "intervals": {k: [float(v[0]), float(v[1])] for k, v in self.intervals.items()},
             "identifiability": self.identifiability}
        if self.rvc is not None:
            d["rvc"] = {k: float(v) for k, v in self.rvc.items()}
        return d

    @classmethod
    def from_dict(cls, d):
        return cls(tuple(d["free"]), dict(d["parameters"]), float(d["misfit"]), float(d["chi2_dof"]), float(d["aic"]),
                   float(d["bic"]), {k: (float(v[0]), float(v[1])) for k, v in d["intervals"].items()},
                   {k: dict(v) for k, v in d["identifiability"].items()},
                   None if d.get("rvc") is None else dict(d["rvc"]))


@dataclass(frozen=True, repr=False)
class OverparamResult(Displayed):
    """Outcome of :func:`nested_analyses`: the analyses in the order given (iterable)."""

    analyses: tuple

    def __iter__(self):
        return iter(self.analyses)

    def __len__(self):
        return len(self.analyses)

    def __getitem__(self, i):
        return self.analyses[i]

    def to_dict(self):
        """``{"analyses": [NestedAnalysis.to_dict(), ...]}``."""
        return {"analyses": [a.to_dict() for a in self.analyses]}

    @classmethod
    def from_dict(cls, d):
        return cls(tuple(NestedAnalysis.from_dict(a) for a in d["analyses"]))


def nested_analyses(make_problem, free_sets, *, confidence=CONFIDENCE, rng=0, validation=None, n_samples=2**16):
    """Compare nested sets of free parameters (thesis ch. 5, analyses 0–5).

    Parameters
    ----------
    make_problem : callable
        ``make_problem(free) -> InverseProblem`` for a tuple of free names.
    free_sets : sequence of sequence of str
    confidence, rng, n_samples
        The region's confidence, the seed of every analysis and the region's samples per round
        (:class:`~podkrig.online.settings.CalibrationSettings`).
    validation : dict of str to (model, fixed), optional
        Validation models for RVC; a validation model's parameters that an analysis does not
        free take the calibration's values (then ``fixed``).

    Returns
    -------
    OverparamResult
    """
    settings = CalibrationSettings(inversion=InversionSettings(seed=rng), region=RegionSettings(samples=n_samples),
                                   confidence=confidence, fe_check=False)
    models = {name: (model, None, fixed) for name, (model, fixed) in (validation or {}).items()}
    analyses = []
    for free in free_sets:
        one = calibrate(make_problem(tuple(free)), settings, validation=models, check_measurement=False,
                        calibration_rvc=False)
        result, region = one.inversion, one.region
        ic = information_criteria(result)
        spread = {name: float(np.max(r.cv)) for name, r in one.rvc.items()} if validation else None
        analyses.append(NestedAnalysis(
            tuple(free), {n: result.parameters[n] for n in free}, result.misfit, result.chi2_dof, ic["aic"], ic["bic"],
            region.intervals, region.identifiability, spread))
    return OverparamResult(tuple(analyses))


__all__ = ["NestedAnalysis", "OverparamResult", "information_criteria", "nested_analyses"]
