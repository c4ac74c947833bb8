"""The one scrambled Sobol' sequence of podkrig, on every scipy version ``pyproject.toml`` allows.

:class:`scipy.stats.qmc.Sobol` takes a ``numpy.random.Generator`` as ``rng=`` from scipy 1.15
and as ``seed=`` before (the same points on both); an integer given as ``seed=`` is scipy's own
integer seeding, also the same on every version (and not the sequence of
``numpy.random.default_rng(seed)``). Every Sobol' design of the package (offline designs, the GA's
initial population, the inversion's screen, the region sampling) comes from
:func:`scrambled_sobol`. It sits at the bottom of the package (like ``parallel``) so that the GA
can use it; :func:`podkrig.offline.sampling.sobol` is the checked public form for designs.
"""

import inspect
import warnings

import numpy as np
from scipy.stats import qmc

# scipy >= 1.15 takes ``rng=``; older versions ``seed=`` (same integer -> same Generator)
_RNG_KEYWORD = "rng" if "rng" in inspect.signature(qmc.Sobol).parameters else "seed"


def engine_options(rng):
    """Keyword argument giving ``rng`` to a :mod:`scipy.stats.qmc` engine on any scipy version.

    ``rng``: a ``numpy.random.Generator`` (drawn from), an integer (scipy's integer seeding), or
    None (fresh entropy, not reproducible).
    """
    if rng is None or isinstance(rng, np.random.Generator):
        return {_RNG_KEYWORD: rng}
    if isinstance(rng, bool) or not isinstance(rng, (int, np.integer)):
        raise TypeError(f"rng must be an integer, a numpy.random.Generator or None; got {rng!r}")
    return {"seed": int(rng)}  # accepted without warning from scipy 1.12 to 1.17


def scrambled_sobol(n, d, rng, *, skip=0):
    """Points ``skip .. skip+n-1`` of a scrambled Sobol' sequence (Joe & Kuo directions).

    Parameters
    ----------
    n, d : int
        Number of points and dimension, >= 1 (checked by scipy; see
        :func:`podkrig.offline.sampling.sobol` for the checked design).
    rng : int, numpy.random.Generator or None
        Source of the scrambling (see :func:`engine_options`); a Generator is drawn from.
    skip : int
        Points skipped first (the engine is fast-forwarded).

    Returns
    -------
    U : ndarray of shape (n, d)
        Points in [0, 1); the first ``2**m`` are those of ``random_base2(m)``. No warning about
        powers of two (the callers decide).
    """
    engine = qmc.Sobol(d, scramble=True, **engine_options(rng))
    if skip:
        engine.fast_forward(skip)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # scipy's power-of-two note
        return engine.random(n)


def rng_seed(rng):
    """An integer seed derived from ``rng`` (int or Generator) for a seeded design: an integer is
    returned as it is (the same points as before), a Generator gives one draw from it."""
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(2**31))
    return rng
