"""Overparameterisation: nested analyses with growing sets of free parameters (thesis ch. 5).

Each analysis frees a set of parameters, identifies them, samples their region of equivalence and
(optionally) propagates it to validation models. Misfit alone always improves when a parameter is
freed; the information criteria (AIC, BIC), the identifiability verdicts and the validation RVC
tell whether the extra parameter is supported by the data.
"""

from dataclasses import dataclass

import numpy as np

from podkrig.online.invert import invert
from podkrig.online.propagation import rvc
from podkrig.online.region import likelihood_ratio_region


def information_criteria(result):
    """AIC and BIC of an inversion with Gaussian noise of known covariance.

    −2 log L = χ² + const, so AIC = χ² + 2k and BIC = χ² + k ln n (k free parameters, n
    observations); differences between nested analyses are what matter.
    """
    k, n = result.problem.n_free, result.problem.n_obs
    return {"aic": result.chi2 + 2 * k, "bic": result.chi2 + k * np.log(n)}


@dataclass(frozen=True)
class NestedAnalysis:
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


@dataclass(frozen=True)
class OverparamResult:
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


def nested_analyses(make_problem, free_sets, *, confidence=0.95, rng=0, validation=None, n_samples=2**16):
    """Compare nested sets of free parameters (thesis ch. 5, analyses 0–5).

    Parameters
    ----------
    make_problem : callable
        ``make_problem(free) -> InverseProblem`` for a tuple of free names.
    free_sets : sequence of sequence of str
    validation : dict of str to (model, fixed), optional
        Validation models for RVC; a validation model's parameters that an analysis does not
        free take the calibration's values.

    Returns
    -------
    OverparamResult
    """
    analyses = []
    for free in free_sets:
        problem = make_problem(tuple(free))
        result = invert(problem, rng=rng)
        region = likelihood_ratio_region(problem, result.x, confidence=confidence, rng=rng, n_samples=n_samples)
        ic = information_criteria(result)
        spread = None
        if validation:
            spread = {}
            for name, (model, fixed) in validation.items():
                fx = {**fixed, **{k: v for k, v in result.parameters.items() if k not in free and k in model.space.names}}
                spread[name] = float(np.max(rvc(region, model, fixed=fx, rng=rng).cv))
        analyses.append(NestedAnalysis(
            tuple(free), {n: result.parameters[n] for n in free}, result.misfit, result.chi2_dof, ic["aic"], ic["bic"],
            region.intervals, region.identifiability, spread))
    return OverparamResult(tuple(analyses))


__all__ = ["NestedAnalysis", "OverparamResult", "information_criteria", "nested_analyses"]
