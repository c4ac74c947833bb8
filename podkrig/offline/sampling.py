"""Sampling designs in the unit hypercube: scrambled Sobol', Latin hypercube, uniform random.

Every design returns ``U`` of shape ``(n_samples, n_params)`` in :math:`[0, 1)^d`, reproducible
from an integer ``seed`` (recorded by the snapshot store); map it to physical values with
:meth:`podkrig.parameters.ParameterSpace.from_unit`. The design's ``seed`` is an integer, not an
``rng`` as elsewhere in podkrig: it is the design's identity, stored in the snapshot file.

- ``"sobol"``: scrambled Sobol' points [1]_ with the Joe & Kuo direction numbers [2]_, through
  :class:`scipy.stats.qmc.Sobol`. Its balance properties need ``n`` to be a power of two (a
  warning says so otherwise). ``sobol(k, d, seed, skip=n)`` returns points ``n .. n+k-1`` of the
  same scrambled sequence, bitwise identical to the tail of ``sobol(n + k, d, seed)``; this is how
  a store grows.
- ``"lhs"``: Latin hypercube, :class:`scipy.stats.qmc.LatinHypercube`; a design of ``n`` points
  cannot be extended.
- ``"lhs-ese"``: Latin hypercube optimised for space filling by SMT's enhanced stochastic
  evolutionary algorithm (``smt.sampling_methods.LHS(criterion="ese")``) [3]_; better spread
  than ``"lhs"`` for held-out and enrichment designs, but costly beyond a few hundred points
  (each ESE iteration updates an ``n × n`` distance criterion); cannot be extended.
- ``"random"``: independent uniform points from :func:`numpy.random.default_rng`; for held-out
  test sets.

Example
-------
>>> from podkrig.offline.sampling import sobol
>>> U = sobol(8, 3, seed=1)
>>> U.shape
(8, 3)
>>> bool(((U >= 0) & (U < 1)).all())
True

References
----------
.. [1] I. M. Sobol', "On the distribution of points in a cube and the approximate evaluation of
   integrals", USSR Comput. Math. Math. Phys. 7(4), 86–112, 1967.
.. [2] S. Joe and F. Y. Kuo, "Constructing Sobol sequences with better two-dimensional
   projections", SIAM J. Sci. Comput. 30(5), 2635–2654, 2008.
.. [3] R. Jin, W. Chen, A. Sudjianto, "An efficient algorithm for constructing optimal design of
   computer experiments", Journal of Statistical Planning and Inference 134(1), 268–287, 2005.
"""

import logging
import warnings

import numpy as np
from scipy.stats import qmc

from podkrig._qmc import engine_options, scrambled_sobol

logger = logging.getLogger(__name__)

METHODS = ("sobol", "lhs", "lhs-ese", "random")


def _check(n, d, seed, skip=0):
    for name, value, least in (("n", n, 1), ("d", d, 1), ("seed", seed, 0), ("skip", skip, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name} must be an integer; got {value!r}")
        if value < least:
            raise ValueError(f"{name} must be >= {least}; got {value}")


def is_power_of_two(n):
    """True when ``n`` is 1, 2, 4, 8, ..."""
    return n > 0 and n & (n - 1) == 0


def sobol(n, d, seed, *, skip=0):
    """Scrambled Sobol' points ``skip .. skip+n-1`` of the sequence fixed by ``seed``.

    Parameters
    ----------
    n : int
        Number of points, >= 1.
    d : int
        Dimension (number of free parameters), >= 1.
    seed : int
        Seed of the scrambling, >= 0.
    skip : int, optional
        Points of the sequence to skip first (the engine is fast-forwarded), >= 0.

    Returns
    -------
    U : ndarray of shape (n, d)
        Points in the unit hypercube.

    Warns
    -----
    UserWarning
        When ``skip + n`` is not a power of two (the design loses Sobol' balance properties).
    """
    _check(n, d, seed, skip)
    _warn_power_of_two(skip + n)
    return _sobol(n, d, seed, skip)


def _warn_power_of_two(total):
    if not is_power_of_two(total):
        warnings.warn(
            f"Sobol' design of {total} points: balance properties need a power of two "
            f"(e.g. {1 << (total - 1).bit_length()}); the points are still valid but less uniform",
            UserWarning,
            stacklevel=3,  # the caller of sobol() / sample()
        )


def _sobol(n, d, seed, skip):
    # the seed goes through numpy.random.default_rng: the sequence of every store written so far
    return scrambled_sobol(n, d, np.random.default_rng(seed), skip=skip)


def latin_hypercube(n, d, seed):
    """Latin hypercube design of ``n`` points.

    Parameters
    ----------
    n, d : int
        Number of points and dimension, >= 1.
    seed : int
        Seed, >= 0.

    Returns
    -------
    U : ndarray of shape (n, d)
        Points in the unit hypercube, one per row and column stratum.
    """
    _check(n, d, seed)
    return qmc.LatinHypercube(d, **engine_options(np.random.default_rng(seed))).random(n)


def latin_hypercube_ese(n, d, seed):
    """Latin hypercube of ``n`` points optimised by SMT's enhanced stochastic evolutionary (ESE)
    algorithm (maximin-type :math:`\\phi_p` criterion, Jin et al. 2005).

    Parameters
    ----------
    n, d : int
        Number of points and dimension, >= 1.
    seed : int
        Seed, >= 0 (SMT's ``seed``).

    Returns
    -------
    U : ndarray of shape (n, d)
        Points in the unit hypercube, one per row and column stratum.

    Notes
    -----
    Cost grows about as :math:`n^2 d` per ESE iteration: about a second for 64 points in 4
    dimensions, minutes for a few thousand (use ``"sobol"`` for large designs).
    """
    _check(n, d, seed)
    # SMT's sampling module imports in ~1-2 s (7 s measured under load 14): only when used
    from smt.sampling_methods import LHS

    lhs = LHS(xlimits=np.array([[0.0, 1.0]] * d), criterion="ese", seed=int(seed))
    # SMT may return 1.0 exactly (a stratum's upper edge); the designs here live in [0, 1)
    return np.minimum(lhs(n), np.nextafter(1.0, 0.0))


def uniform(n, d, seed):
    """Independent uniform points (e.g. a held-out test set).

    Parameters
    ----------
    n, d : int
        Number of points and dimension, >= 1.
    seed : int
        Seed of :func:`numpy.random.default_rng`, >= 0.

    Returns
    -------
    U : ndarray of shape (n, d)
        Points in the unit hypercube.
    """
    _check(n, d, seed)
    return np.random.default_rng(seed).random((n, d))


def sample(method, n, d, seed, *, skip=0):
    """Points ``skip .. skip+n-1`` of a seeded design.

    Parameters
    ----------
    method : {"sobol", "lhs", "lhs-ese", "random"}
    n, d : int
        Number of points and dimension, >= 1.
    seed : int
        Seed, >= 0.
    skip : int, optional
        Points already drawn; only ``"sobol"`` can continue its sequence.

    Returns
    -------
    U : ndarray of shape (n, d)

    Raises
    ------
    ValueError
        Unknown method, or ``skip > 0`` for a design that cannot be extended.
    """
    if method not in METHODS:
        raise ValueError(f"sampling method must be one of {METHODS}; got {method!r}")
    _check(n, d, seed, skip)
    if method == "sobol":
        _warn_power_of_two(skip + n)
        return _sobol(n, d, seed, skip)
    if skip:
        raise ValueError(
            f"a {method!r} design of {skip} points cannot be extended; only 'sobol' continues its sequence"
        )
    if method == "lhs":
        return latin_hypercube(n, d, seed)
    return latin_hypercube_ese(n, d, seed) if method == "lhs-ese" else uniform(n, d, seed)
