"""One calibration over several tests: the misfits of the tests summed over shared parameters.

Laboratories calibrate a wall from several tests at once — triplets, a flat-jack test and a wall
test — never from one curve. A :class:`JointProblem` holds one
:class:`~podkrig.online.problem.InverseProblem` per test (its model, measurement and noise) and
searches the union of their free parameters: a parameter named in several tests is *shared* (one
value for all of them), a parameter of one test only is that test's own (a *nuisance* parameter
such as a flat jack's efficiency ``Km``). Its misfit is thesis eq. (2.13) summed over the tests,

.. math::

    \\omega(m) = \\sum_t \\omega_t(m_t), \\qquad m_t = \\text{the entries of } m \\text{ test } t
    \\text{ depends on},

which is the misfit of the stacked data vector when the tests' noises are independent (their
C_D block-diagonal). A joint problem offers what :func:`~podkrig.online.invert.invert`, the
regions of :mod:`~podkrig.online.region`, :func:`~podkrig.online.posterior.sample_posterior`
and :func:`~podkrig.online.propagation.rvc` use, so one GA inversion and one region of
equivalence serve the tests together; :meth:`JointProblem.parts` gives each test's view for its
residuals, χ²/dof and FE check.
"""

import functools
from dataclasses import dataclass

import numpy as np

from podkrig.online.problem import UnitCubeLeastSquares
from podkrig.parameters import ParameterSpace


@dataclass(frozen=True, eq=False)
class JointProblem(UnitCubeLeastSquares):
    """Several calibration problems sharing named parameters.

    Parameters
    ----------
    problems : dict of str to InverseProblem
        One per test, in report order. A parameter free in several tests must have the same bounds,
        scale and unit in each (it is one search range); the joint free parameters are the union,
        in order of first appearance. Priors, fixed values and noise stay per test.

    Attributes
    ----------
    free : tuple of str
    free_space : ParameterSpace
        The joint search box.
    columns : dict of str to ndarray
        For each test, the positions of its free parameters in :attr:`free`.
    """

    problems: dict

    def __post_init__(self):
        if not self.problems:
            raise ValueError("a joint calibration needs at least one test")
        object.__setattr__(self, "problems", dict(self.problems))  # a copy: the tests are fixed
        self._parameters  # a shared parameter with two search ranges is refused here

    @functools.cached_property
    def _parameters(self):
        """The joint free parameters, name → :class:`~podkrig.parameters.Parameter`, in order of
        first appearance; a shared parameter must have one search range."""
        params, origin = {}, {}
        for test, problem in self.problems.items():
            for p in problem.free_space.parameters:
                if p.name not in params:
                    params[p.name], origin[p.name] = p, test
                    continue
                q = params[p.name]
                if (q.lower, q.upper, q.scale, q.unit) != (p.lower, p.upper, p.scale, p.unit):
                    raise ValueError(
                        f"shared parameter {p.name} has the search range [{q.lower:g}, {q.upper:g}] {q.unit} "
                        f"({q.scale}) in test {origin[p.name]!r} but [{p.lower:g}, {p.upper:g}] {p.unit} ({p.scale}) in "
                        f"test {test!r}: a shared parameter has one range; give the same bounds and scale")
        return params

    @functools.cached_property
    def free(self):
        return tuple(self._parameters)

    @functools.cached_property
    def free_space(self):
        return ParameterSpace(tuple(self._parameters.values()))

    @functools.cached_property
    def columns(self):
        return {t: np.array([self.free.index(n) for n in p.free]) for t, p in self.problems.items()}

    @property
    def n_free(self):
        return len(self.free)

    @property
    def n_obs(self):
        """Readings of all tests together."""
        return sum(p.n_obs for p in self.problems.values())

    @property
    def n_removed(self):
        """Degrees of freedom taken by removed rigid-body motions, all tests together."""
        return sum(p.n_removed for p in self.problems.values())

    @property
    def model_error(self):
        """Whether any test adds its model's predictive variance C_T to C_D (thesis eq. 2.10)."""
        return any(p.model_error for p in self.problems.values())

    @property
    def frozen_model_std(self):
        """The frozen predictive std of every test, concatenated; None unless all are frozen
        (:meth:`freeze_model_error`)."""
        stds = [p.frozen_model_std for p in self.problems.values()]
        return None if any(s is None for s in stds) else np.concatenate(stds)

    def _split(self, X):
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return [(p, X[:, self.columns[t]]) for t, p in self.problems.items()]

    def omega(self, X):
        """ω at joint free vectors ``(n, n_free)`` (physical): Σ_t ω_t, ``(n,)``."""
        return sum(p.omega(Xt) for p, Xt in self._split(X))

    def omega_unit(self, U):
        """ω at unit-cube coordinates of the joint box, ``(n,)`` (the tests' boxes are its faces)."""
        return sum(p.omega_unit(Ut) for p, Ut in self._split(U))

    def chi2(self, X):
        """Data term of all tests, Σ_t (g_t − d_t)ᵀ C_D,t⁻¹ (g_t − d_t), ``(n,)``."""
        return sum(p.chi2(Xt) for p, Xt in self._split(X))

    def _residuals_batch(self, U):
        """Every test's whitened (and prior) residuals side by side, ``(n, Σ_t n_residuals,t)``."""
        return np.hstack([p._residuals_batch(Ut) for p, Ut in self._split(U)])

    def freeze_model_error(self, x):
        """The same joint problem with each test's predictive std frozen at ``x`` (see
        :meth:`InverseProblem.freeze_model_error`)."""
        x = np.asarray(x, dtype=float)
        return JointProblem({t: p.freeze_model_error(x[self.columns[t]]) for t, p in self.problems.items()})

    def with_noisy_data(self, x, rng):
        """Every test's data replaced by g_t(x) + e_t, e_t ~ N(0, C_d,t), independent across tests."""
        x = np.asarray(x, dtype=float)
        return JointProblem({t: p.with_noisy_data(x[self.columns[t]], rng) for t, p in self.problems.items()})

    def parts(self, x):
        """Each test's problem and its free values at joint free values ``x`` ``(n_free,)``:
        ``{test: (InverseProblem, x_t)}``."""
        x = np.asarray(x, dtype=float)
        return {t: (p, x[self.columns[t]]) for t, p in self.problems.items()}

    def parameters_at(self, x):
        """The joint free parameters at ``x`` and the fixed values every test agrees on,
        ``{name: value}`` (each test's full set: :meth:`parts`)."""
        out = dict(zip(self.free, np.asarray(x, dtype=float).tolist()))
        fixed = [p.fixed for p in self.problems.values()]
        for name, value in fixed[0].items():
            if name not in out and all(f.get(name) == value for f in fixed[1:]):
                out[name] = float(value)
        return out

    def measurement_summary(self):
        """``n_obs`` of all tests and each test's data summary under ``tests`` (JSON-able)."""
        tests = {t: p.measurement_summary() for t, p in self.problems.items()}
        return {"file": "; ".join(s["file"] for s in tests.values()), "n_obs": self.n_obs, "tests": tests}


__all__ = ["JointProblem"]
