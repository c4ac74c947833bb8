"""Monte-Carlo check of a layout: the actual inversion (:mod:`podkrig.online`) repeated under noise.

For each truth ``m*`` (interior points of the box) and each noise realisation ``r``, pseudo-data
``d_r = g_S(m*) + σ ξ_r`` (ξ standard normal, σ per sensor kind) are inverted with
:func:`podkrig.online.invert` (GA + least-squares polish) on the layout's readings; the spread of
the identified parameters is the layout's real identification uncertainty, nonlinearity and box
bounds included. The 95 % interval width of parameter ``j`` is the 2.5–97.5 % inter-percentile
range of the identified values, in unit coordinates of the box (log10 for log-scaled parameters)
and in the parameter's unit, averaged over the truths.

The forward model is a POD-kriging surrogate of *all* candidates' readings fitted on the
sensitivity points (:func:`candidate_surrogate`); a :class:`LayoutModel` selects a layout's
channels, so every layout is checked with the same surrogate. Pseudo-data come from the same
surrogate (the check isolates the effect of noise and layout), and the inversion leaves out the
kriging variance (``model_error=False``) for the same reason.

Public names used from the online stage (their import paths may move when it is split):
``InverseProblem``, ``invert``, ``Measurement``, ``NoiseModel``.
"""

import logging
import time
from dataclasses import dataclass

import numpy as np

from podkrig._qmc import rng_seed
from podkrig.display import Displayed
from podkrig.offline.sampling import sobol
from podkrig.online.invert import invert
from podkrig.online.problem import InverseProblem
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.surrogate.kriging import OrdinaryKriging
from podkrig.surrogate.pod import POD
from podkrig.surrogate.podkriging import PODKriging

logger = logging.getLogger(__name__)


def candidate_surrogate(sens, energy=1 - 1e-10, beta=1.8):
    """A POD-kriging surrogate of every candidate channel's readings over the free space, fitted on
    the points of :class:`Sensitivities` ``sens`` (outputs ``(n_loads, n_channels)``, mm)."""
    return PODKriging(pod=POD(energy=energy), kriging=OrdinaryKriging(beta=beta), space=sens.space).fit(
        sens.X, sens.readings)


class LayoutModel:
    """The readings of one layout, as an inversion model (see :mod:`podkrig.online.problem`).

    Parameters
    ----------
    surrogate : PODKriging or model
        From :func:`candidate_surrogate`, or any model with ``predict(X) -> (n, n_loads *
        n_channels)`` over all candidate channels.
    sens : Sensitivities
        Gives the channel names and which candidate owns each channel.
    layout : sequence of int
        Candidate indices.
    """

    def __init__(self, surrogate, sens, layout):
        self.surrogate = surrogate
        self.space = sens.space
        channels = sens.channels_of(layout)
        n_ch = len(sens.channel_names)
        self.sensor_names = tuple(sens.channel_names[c] for c in channels)
        self.load_levels = sens.load_levels
        self._columns = (np.arange(len(sens.load_levels))[:, None] * n_ch + channels[None, :]).ravel()
        kinds = sens.candidates.kinds
        self.kinds = tuple(kinds[sens.channel_sensor[c]] for c in channels)

    def predict(self, X, return_std=False):
        """Readings of the layout ``(n, n_loads * n_channels)`` mm (load-major); with ``return_std``
        the std is None: the check leaves the kriging variance out (see the module docstring)."""
        mean = self.surrogate.predict(X)[:, self._columns]
        return (mean, None) if return_std else mean


@dataclass(frozen=True, eq=False, repr=False)
class MonteCarloResult(Displayed):
    """Identified parameters under noise for one layout.

    Attributes
    ----------
    truths : ndarray of shape (n_truths, n_params)
        True parameters, physical units.
    identified : ndarray of shape (n_truths, n_realisations, n_params)
        Identified parameters, physical units.
    width_unit : ndarray of shape (n_params,)
        Mean over truths of the 95 % inter-percentile width, unit coordinates (fraction of the box;
        log10 for log-scaled parameters).
    width : ndarray of shape (n_params,)
        The same in the parameters' units (log-scaled: the width of the interval in the unit).
    names, units : tuple of str
    seconds : float
    """

    truths: np.ndarray
    identified: np.ndarray
    width_unit: np.ndarray
    width: np.ndarray
    names: tuple
    units: tuple
    seconds: float

    @property
    def mean_width_unit(self):
        """Mean over parameters of :attr:`width_unit`."""
        return float(self.width_unit.mean())

    def to_dict(self):
        return {"names": list(self.names), "units": list(self.units), "truths": self.truths.tolist(),
                "width_unit": self.width_unit.tolist(), "width": self.width.tolist(),
                "mean_width_unit": self.mean_width_unit, "n_realisations": int(self.identified.shape[1]),
                "seconds": self.seconds}


def interior_truths(space, n, rng=0, margin=0.2):
    """``n`` Sobol' points of the box shrunk by ``margin`` on each side (unit coordinates), physical.
    ``rng`` (int or Generator) scrambles the Sobol' set: an integer is the design's seed."""
    return space.from_unit(margin + (1 - 2 * margin) * sobol(n, space.n_params, rng_seed(rng)))


def monte_carlo(surrogate, sens, layout, noise, truths, *, n_realisations=50, rng=0, population_size=40,
                generations=30, n_starts=3, progress=None):
    """Invert noisy pseudo-data on ``layout`` many times; see the module docstring.

    Parameters
    ----------
    surrogate : PODKriging
        From :func:`candidate_surrogate`.
    sens : Sensitivities
    layout : sequence of int
    noise : SensorNoise
        Absolute σ per kind is used (a relative model uses σ = δ |g(m*)| at each truth).
    truths : ndarray of shape (n_truths, n_params)
    n_realisations : int
    rng : int
        Seed of the noise and of the inversions.
    population_size, generations, n_starts : int
        Inversion budget (:func:`podkrig.online.invert`); the polish from several starts finishes it.
    progress : callable, optional
        ``progress(done, total)`` after each inversion.

    Returns
    -------
    MonteCarloResult
    """
    t0 = time.perf_counter()
    model = LayoutModel(surrogate, sens, layout)
    truths = np.atleast_2d(truths)
    gen = np.random.default_rng(rng)
    n_l, n_s = len(model.load_levels), len(model.sensor_names)
    p = sens.n_params
    out = np.empty((len(truths), n_realisations, p))
    total, done = len(truths) * n_realisations, 0
    for t, truth in enumerate(truths):
        clean = model.predict(truth[None])[0].reshape(n_l, n_s)
        if noise.relative is None:
            sigma = np.array([noise.sigma(k) for k in model.kinds])
            noise_model = NoiseModel(sigma=dict(zip(model.sensor_names, sigma.tolist())))
            std = np.broadcast_to(sigma, clean.shape)
        else:
            std = np.maximum(noise.relative * np.abs(clean), noise.floor)
            noise_model = NoiseModel(covariance=np.diag(std.ravel() ** 2))
        for r in range(n_realisations):
            data = clean + std * gen.standard_normal(clean.shape)
            problem = InverseProblem(model, Measurement(data, model.sensor_names, model.load_levels, "monte carlo"),
                                     noise_model, model_error=False)
            out[t, r] = invert(problem, rng=int(gen.integers(2**31)), population_size=population_size,
                               generations=generations, n_starts=n_starts).x
            done += 1
            if progress is not None:
                progress(done, total)
    space = sens.space
    U = space.to_unit(out.reshape(-1, p)).reshape(out.shape)
    width_unit = np.mean(np.percentile(U, 97.5, axis=1) - np.percentile(U, 2.5, axis=1), axis=0)
    width = np.mean(np.percentile(out, 97.5, axis=1) - np.percentile(out, 2.5, axis=1), axis=0)
    return MonteCarloResult(truths, out, width_unit, width, space.names, space.units, time.perf_counter() - t0)
