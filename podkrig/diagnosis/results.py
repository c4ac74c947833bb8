"""Results of a model diagnosis: the fits (base and extended model), the score of each candidate
cause, and the :class:`DiagnosisResult` with its verdict, gain and JSON form; computed by
:func:`podkrig.diagnosis.engine.diagnose`."""

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from fe.scenarios import build_scenario
from fe.sensors import absolute_displacements
from podkrig.diagnosis.candidates import EffectParameter, Location
from podkrig.display import Displayed
from podkrig.online.model_error import ModelError
from podkrig.online.findings import RESIDUAL_CONVENTION, chi2_basis
from podkrig.online.measurement import Measurement
from podkrig.online.rigid_body import rigid_body_modes

#: the omnibus χ² test runs at this share of α: it guards against gross misfit, while the targeted
#: candidate tests carry the detection (with hundreds of readings, χ² alone flags the last per
#: cent of discretisation error of an independent FE model as a missing effect)
CHI2_ALPHA_SHARE = 0.1


@dataclass(frozen=True)
class Alternative:
    """A candidate (at a location) whose extended fit is within a likelihood ratio of
    ``EQUIVALENCE_RATIO`` of the best: the data cannot tell them apart."""

    name: str
    location: object
    delta_chi2: float


@dataclass(frozen=True, eq=False)
class Fit:
    """A least-squares fit of the FE model (base or extended) to (part of) the data.

    Attributes
    ----------
    values : dict of str to float
        Every parameter of the scenario at the optimum.
    free : dict of str to float
        The base model's free parameters at the optimum.
    effects : tuple of float
        The causes' parameters at the optimum, in the order the causes were found (empty for the
        base model).
    chi2 : float
        ``‖L⁻¹(d − g)‖²`` over the fitted entries.
    n_obs, n_params : int
    readings : ndarray of shape (n_loads, n_sensors)
        FE readings at the optimum (every sensor and load level of the scenario), mm.
    jacobian : ndarray of shape (n_obs, n_params)
        Whitened Jacobian w.r.t. the fit coordinates (unit cube) at the optimum.
    n_removed : int
        Degrees of freedom taken by the rigid-body motions removed from the fitted entries
        (:mod:`podkrig.online.rigid_body`: 3 per DIC grid and load level); ``dof = n_obs − n_removed − n_params``.
    """

    values: dict
    free: dict
    effects: tuple
    chi2: float
    n_obs: int
    n_params: int
    readings: np.ndarray
    jacobian: np.ndarray
    n_removed: int = 0

    @property
    def effect(self):
        """The parameter of the cause found last, or None for the base model."""
        return self.effects[-1] if self.effects else None

    @property
    def dof(self):
        return max(self.n_obs - self.n_removed - self.n_params, 1)

    @property
    def chi2_dof(self):
        return self.chi2 / self.dof

    @property
    def aic(self):
        """χ² + 2k (Akaike, Gaussian noise of known covariance, constants dropped)."""
        return self.chi2 + 2 * self.n_params

    @property
    def bic(self):
        """χ² + k ln n (Schwarz; n the entries left after removing rigid-body motions)."""
        return self.chi2 + self.n_params * np.log(self.n_obs - self.n_removed)

    def to_dict(self):
        """Every field, arrays as nested lists (JSON-able; :meth:`from_dict` reads it back)."""
        return {"values": {k: float(v) for k, v in self.values.items()},
                "free": {k: float(v) for k, v in self.free.items()},
                "effects": [float(c) for c in self.effects], "chi2": float(self.chi2),
                "n_obs": int(self.n_obs), "n_params": int(self.n_params), "readings": self.readings.tolist(),
                "jacobian": self.jacobian.tolist(), "n_removed": int(self.n_removed)}

    @classmethod
    def from_dict(cls, d):
        effects = d["effects"] if "effects" in d else ([] if d.get("effect") is None else [d["effect"]])
        return cls(dict(d["values"]), dict(d["free"]), tuple(float(c) for c in effects), float(d["chi2"]), int(d["n_obs"]),
                   int(d["n_params"]), np.asarray(d["readings"], dtype=float),
                   np.asarray(d["jacobian"], dtype=float).reshape(int(d["n_obs"]), -1), int(d.get("n_removed", 0)))

    def summary(self):
        return {
            "parameters": {k: float(v) for k, v in self.free.items()},
            "chi2": float(self.chi2), "dof": int(self.dof), "chi2_dof": float(self.chi2_dof),
            "misfit": float(0.5 * self.chi2), "aic": float(self.aic), "bic": float(self.bic),
        }


@dataclass
class CandidateScore:
    """A candidate cause's evidence at its best location."""

    name: str
    description: str
    signature: str
    n_locations: int
    applicable: bool
    reason: str | None = None
    location: object = None
    parameter: object = None
    screening_delta_chi2: float = 0.0
    delta_chi2: float = 0.0
    p_value: float = 1.0
    p_corrected: float = 1.0
    log10_p_corrected: float = 0.0
    visible: bool = True
    max_delta_chi2: float = 0.0
    effect_size: float = 0.0
    #: the largest change of a reading (σ) left after refitting the current model's parameters
    effect_left: float = 0.0
    #: log of the Bonferroni factor (candidates × locations) of its test
    log_correction: float = 0.0
    fit: Fit | None = None
    #: (location, parameter, screening Δχ², extended fit, Δχ²) of each location refitted with the FE model
    refitted: list = field(default_factory=list)

    def state(self):
        """Every field (JSON-able), for :meth:`from_state`; :meth:`to_dict` is the report form."""
        d = {k: v.item() if isinstance(v, np.generic) else v for k, v in dataclasses.asdict(self).items()}
        d["location"] = None if self.location is None else dataclasses.asdict(self.location)
        d["parameter"] = None if self.parameter is None else dataclasses.asdict(self.parameter)
        d["fit"] = None if self.fit is None else self.fit.to_dict()
        d["refitted"] = [{"location": dataclasses.asdict(loc), "parameter": dataclasses.asdict(par),
                          "screening_delta_chi2": float(lin), "fit": fit.to_dict(), "delta_chi2": float(delta)}
                         for loc, par, lin, fit, delta in self.refitted]
        return d

    @classmethod
    def from_state(cls, d):
        d = dict(d)
        d["location"] = None if d["location"] is None else Location(**d["location"])
        d["parameter"] = None if d["parameter"] is None else EffectParameter(**d["parameter"])
        d["fit"] = None if d["fit"] is None else Fit.from_dict(d["fit"])
        d["refitted"] = [(Location(**r["location"]), EffectParameter(**r["parameter"]), r["screening_delta_chi2"],
                          Fit.from_dict(r["fit"]), r["delta_chi2"]) for r in d["refitted"]]
        return cls(**d)

    def to_dict(self):
        d = {
            "name": self.name, "applicable": self.applicable, "n_locations": self.n_locations,
            "description": self.description, "signature": self.signature,
        }
        if not self.applicable:
            d["reason"] = self.reason
            return d
        d.update({
            "location": None if self.location is None else self.location.label,
            "detail": None if self.location is None else self.location.detail,
            "parameter": None if self.parameter is None else {
                "name": self.parameter.name, "unit": self.parameter.unit, "neutral": self.parameter.neutral,
                "value": None if self.fit is None else self.fit.effect},
            "screening_delta_chi2": float(self.screening_delta_chi2),
            "delta_chi2": float(self.delta_chi2),
            "p_value": float(self.p_value),
            "p_corrected": float(self.p_corrected),
            "score": float(-self.log10_p_corrected),
            "visible": bool(self.visible),
            "max_delta_chi2": float(self.max_delta_chi2),
            "effect_size": float(self.effect_size),
            "effect_left": float(self.effect_left),
        })
        return d


@dataclass(frozen=True)
class Cause:
    """A cause in the final extended model: candidate name, location, parameter and fitted value."""

    name: str
    location: Location
    parameter: EffectParameter
    value: float

    def to_dict(self):
        return {"cause": self.name, "location": self.location.label, "detail": self.location.detail,
                "key": self.location.key, "parameter": self.parameter.name, "unit": self.parameter.unit,
                "value": float(self.value), "neutral": self.parameter.neutral}

    def state(self):
        return {"name": self.name, "location": dataclasses.asdict(self.location),
                "parameter": dataclasses.asdict(self.parameter), "value": float(self.value)}

    @classmethod
    def from_state(cls, d):
        return cls(d["name"], Location(**d["location"]), EffectParameter(**d["parameter"]), float(d["value"]))


@dataclass(frozen=True, eq=False)
class Step:
    """One round of the forward selection: the cause added, and the model's χ² before and after
    (with the base parameters and every cause refitted).

    Attributes
    ----------
    score : CandidateScore
        The added candidate's score in its round (location, corrected p, effect left).
    chi2_before, chi2_after : float
    p_value_after : float
        χ² test of the model after this step.
    dropped : str or None
        An earlier cause dropped by the backward check in this step (no longer significant).
    """

    score: CandidateScore
    chi2_before: float
    chi2_after: float
    p_value_after: float
    dropped: str | None = None

    def to_dict(self):
        s = self.score
        return {"cause": s.name, "location": s.location.label, "parameter": s.parameter.name,
                "unit": s.parameter.unit, "value": s.fit.effect, "p_corrected": float(s.p_corrected),
                "effect_left": float(s.effect_left), "chi2_before": float(self.chi2_before),
                "chi2_after": float(self.chi2_after), "chi2_drop": float(self.chi2_before - self.chi2_after),
                "p_value_after": float(self.p_value_after), "dropped": self.dropped}

    def state(self):
        return {"score": self.score.state(), "chi2_before": self.chi2_before, "chi2_after": self.chi2_after,
                "p_value_after": self.p_value_after, "dropped": self.dropped}

    @classmethod
    def from_state(cls, d):
        return cls(CandidateScore.from_state(d["score"]), float(d["chi2_before"]), float(d["chi2_after"]),
                   float(d["p_value_after"]), d["dropped"])


@dataclass(frozen=True, eq=False, repr=False)
class DiagnosisResult(Displayed):
    """Outcome of :func:`diagnose`; :meth:`to_dict` is the JSON of ``podkrig diagnose``."""

    scenario: object
    measurement: Measurement
    noise_std: np.ndarray
    alpha: float
    base: Fit
    extended: Fit | None
    chi2_p_value: float
    verdict: str
    cause: str | None
    best: CandidateScore | None
    alternatives: list
    candidates: list
    structure: dict
    held_out: dict | None
    seconds: float
    n_fe_runs: int
    surrogate_fit: dict
    extended_p_value: float | None = None
    model_error: ModelError | None = None
    #: the forward selection's rounds, in order (:class:`Step`)
    steps: list = field(default_factory=list)
    #: the causes of the final extended model, in the order found (:class:`Cause`)
    causes: list = field(default_factory=list)
    #: rigid-body motions removed (:mod:`podkrig.online.rigid_body`): the option and the point groups
    rigid_body: str = "keep"
    rigid_groups: dict | None = None

    @property
    def fully_explained(self):
        """Whether the extended model passes the χ² test (None without a named cause). When it does
        not, an effect outside the library (or beyond ``max_causes``) may be missing."""
        if self.extended_p_value is None:
            return None
        return self.extended_p_value >= self.alpha * CHI2_ALPHA_SHARE

    def residuals(self, fit):
        """Standardised residuals ``(d − g)/σ`` of a fit, ``(n_loads_obs, n_sensors_obs)``; with
        rigid-body removal (:attr:`rigid_body`) ``P (d − g)/σ``, the rigid motion of each DIC grid
        (and point group) and load level fitted and removed (:mod:`podkrig.online.rigid_body`)."""
        idx = self.measurement.output_indices(self.scenario.sensor_names, self.scenario.load_levels)
        r = self.measurement.data - fit.readings.ravel()[idx]
        modes = rigid_body_modes(self.measurement, absolute_displacements(self.scenario.sensors), self.rigid_body,
                                 self.rigid_groups)
        if modes is not None:
            r = modes.remove(r)
        return (r / self.noise_std).reshape(self.measurement.values.shape)

    def detail(self):
        if self.best is None or self.cause is None:
            return None
        d = {"location": self.best.location.label, **self.best.location.detail,
             "parameter": self.best.parameter.name, "unit": self.best.parameter.unit,
             "value": self.best.fit.effect, "neutral": self.best.parameter.neutral}
        d["alternatives"] = [{"cause": a.name, "location": a.location.label, "delta_chi2": float(a.delta_chi2)}
                             for a in self.alternatives]
        return d

    def gain(self):
        if self.extended is None:
            return None
        b, e = self.base, self.extended
        g = {
            "chi2_drop": float(b.chi2 - e.chi2),
            "chi2_dof_before": float(b.chi2_dof), "chi2_dof_after": float(e.chi2_dof),
            "misfit_drop": float(0.5 * (b.chi2 - e.chi2)),
            "aic_drop": float(b.aic - e.aic), "bic_drop": float(b.bic - e.bic),
            "steps": [st.to_dict() for st in self.steps],
        }
        if self.held_out is not None:
            g["held_out"] = self.held_out
            g["held_out_rms_before"] = self.held_out["rms_before"]
            g["held_out_rms_after"] = self.held_out["rms_after"]
        return g

    def to_dict(self, *, state=False):
        """The JSON of ``podkrig diagnose``; with ``state=True`` also ``"state"``, everything
        :meth:`from_dict` needs to rebuild this object (fits with their readings and Jacobians, every
        candidate's score, the measurement and the scenario spec)."""
        d = self._report_dict()
        if state:
            index = {id(c): i for i, c in enumerate(self.candidates)}
            m = self.measurement
            d["state"] = {
                "scenario_spec": self.scenario.spec.to_dict(),
                "measurement": {"values": m.values.tolist(), "sensor_names": list(m.sensor_names),
                                "load_levels": m.load_levels.tolist(), "source": m.source},
                "noise_std": np.asarray(self.noise_std).tolist(), "alpha": float(self.alpha),
                "base": self.base.to_dict(), "extended": None if self.extended is None else self.extended.to_dict(),
                "chi2_p_value": float(self.chi2_p_value), "extended_p_value": self.extended_p_value,
                "candidates": [c.state() for c in self.candidates],
                "best": None if self.best is None else index[id(self.best)],
                "alternatives": [{"name": a.name, "location": dataclasses.asdict(a.location),
                                  "delta_chi2": float(a.delta_chi2)} for a in self.alternatives],
                "structure": self.structure, "held_out": self.held_out, "surrogate_fit": self.surrogate_fit,
                "model_error": None if self.model_error is None else self.model_error.to_dict(),
                "steps": [st.state() for st in self.steps], "causes": [c.state() for c in self.causes],
                "rigid_body": self.rigid_body,
                "rigid_groups": None if self.rigid_groups is None else {k: list(v) for k, v in self.rigid_groups.items()},
            }
        return d

    @classmethod
    def from_dict(cls, d, *, scenario=None):
        """Rebuild a diagnosis from :meth:`to_dict` with ``state=True``.

        Parameters
        ----------
        d : dict
        scenario : fe.Scenario, optional
            The diagnosed scenario; default: built again from the recorded spec.
        """
        if "state" not in d:
            raise ValueError("this diagnosis dict has no 'state': write it with to_dict(state=True) to read it back")
        s = d["state"]
        m = s["measurement"]
        candidates = [CandidateScore.from_state(c) for c in s["candidates"]]
        return cls(
            scenario=scenario if scenario is not None else build_scenario(s["scenario_spec"]),
            measurement=Measurement(np.asarray(m["values"], dtype=float), m["sensor_names"], m["load_levels"], m["source"]),
            noise_std=np.asarray(s["noise_std"], dtype=float), alpha=s["alpha"], base=Fit.from_dict(s["base"]),
            extended=None if s["extended"] is None else Fit.from_dict(s["extended"]),
            chi2_p_value=s["chi2_p_value"], verdict=d["verdict"], cause=d["cause"],
            best=None if s["best"] is None else candidates[s["best"]],
            alternatives=[Alternative(a["name"], Location(**a["location"]), a["delta_chi2"]) for a in s["alternatives"]],
            candidates=candidates, structure=s["structure"], held_out=s["held_out"], seconds=d["seconds"],
            n_fe_runs=d["n_fe_runs"], surrogate_fit=s["surrogate_fit"], extended_p_value=s["extended_p_value"],
            model_error=None if s.get("model_error") is None else ModelError.from_dict(s["model_error"]),
            steps=[Step.from_state(st) for st in s.get("steps", [])],
            causes=[Cause.from_state(c) for c in s.get("causes", [])],
            rigid_body=s.get("rigid_body", "keep"), rigid_groups=s.get("rigid_groups"),
        )

    def _report_dict(self):
        return {
            "verdict": self.verdict,
            "cause": self.cause,
            "causes": [c.to_dict() for c in self.causes],
            "alpha": float(self.alpha),
            "detail": self.detail(),
            "candidates": [c.to_dict() for c in self.candidates],
            "base": self.base.summary(),
            "extended": None if self.extended is None else {
                **self.extended.summary(), "effect": self.best.fit.effect,
                "effects": {c.name: float(c.value) for c in self.causes},
                "p_value": self.extended_p_value, "fully_explained": self.fully_explained},
            "gain": self.gain(),
            "adequacy": {
                "chi2": float(self.base.chi2), "dof": int(self.base.dof), "chi2_dof": float(self.base.chi2_dof),
                "p_value": float(self.chi2_p_value), "alpha": self.alpha * CHI2_ALPHA_SHARE,
                "model_error": None if self.model_error is None else self.model_error.to_dict(self.measurement),
                "basis": chi2_basis("diagnosis", None if self.model_error is None else self.model_error.describe()),
                "rigid_body": self.rigid_body, "dof_removed": int(self.base.n_removed),
            },
            "residual_convention": RESIDUAL_CONVENTION,
            "residual_structure": self.structure,
            "scenario": self.scenario.name,
            "sensors": list(self.measurement.sensor_names),
            "load_levels": self.measurement.load_levels.tolist(),
            "seconds": float(self.seconds),
            "n_fe_runs": int(self.n_fe_runs),
            "surrogate": self.surrogate_fit,
        }


__all__ = ["CHI2_ALPHA_SHARE", "Alternative", "CandidateScore", "Cause", "DiagnosisResult", "Fit", "Step"]
