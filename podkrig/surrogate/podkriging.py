"""The POD-kriging surrogate: a POD basis of the snapshots plus one kriging interpolant per mode.

Conventions: parameter vectors ``X`` of shape ``(n_samples, n_params)`` in physical units (scaled
to the unit cube inside, by a :class:`~podkrig.parameters.ParameterSpace` or by the training
bounds); snapshots ``Y`` of shape ``(n_samples, ...)``, e.g. readings ``(n, n_loads, n_sensors)``
or fields ``(n, n_loads, n_nodes, 2)`` in mm, flattened in C order to ``(n, n_outputs)`` for the POD.

Example
-------
>>> import numpy as np
>>> from podkrig.surrogate import PODKriging
>>> from podkrig.surrogate.pod import POD
>>> from podkrig.surrogate.kriging import OrdinaryKriging
>>> rng = np.random.default_rng(0)
>>> X = rng.uniform([10, 4], [1000, 400], size=(40, 2))
>>> Y = np.stack([np.outer([1, 2, 3], [1 / x[0], 1 / x[1], 1 / x[0] + 1 / x[1]]) for x in X])
>>> sur = PODKriging(pod=POD(energy=1 - 1e-10), kriging=OrdinaryKriging(beta=1.8)).fit(X, Y)
>>> sur.predict(X[:2], reshape=True).shape
(2, 3, 3)

References
----------
.. [1] The thesis, ch. 4 (POD and ordinary kriging; sources of error of the approximation).
.. [2] L. Sirovich, "Turbulence and the dynamics of coherent structures", Q. Appl. Math. 45(3),
   561–571, 1987.
.. [3] J. Sacks, W. J. Welch, T. J. Mitchell, H. P. Wynn, "Design and analysis of computer
   experiments", Statistical Science 4(4), 409–423, 1989.
"""

import datetime
import logging
import warnings
from pathlib import Path

import numpy as np

from podkrig import __version__
from podkrig.parallel import one_blas_thread
from podkrig.exceptions import NotFittedError
from podkrig.parameters import ParameterSpace
from podkrig.surrogate.backends import backend_from_arrays, backend_name, backend_version
from podkrig.surrogate.kriging import OrdinaryKriging
from podkrig.surrogate.pod import POD

logger = logging.getLogger(__name__)

DEFAULT_ENERGY = 1 - 1e-8
#: one POD over the outputs of all control levels, or a POD (+ kriging of its coefficients) per level
LAYOUTS = ("stacked", "per_level")
#: scaling of the outputs before the POD: one scale per unit, one per sensor, or none
SCALINGS = ("unit", "sensor", "none")


def _clone(estimator):
    return type(estimator)(**estimator.get_params())


class PODKriging:
    """POD of the snapshots, ordinary kriging of each retained POD coefficient.

    Parameters
    ----------
    pod : POD, optional
        Template of the POD (copied at ``fit``); default ``POD(energy=1 - 1e-8)``.
    kriging : OrdinaryKriging or another backend, optional
        Template of the regressor of the POD coefficients (copied at ``fit``; its hyperparameters
        are fitted per mode); default ``OrdinaryKriging()``, which above
        :data:`~podkrig.surrogate.kriging.ordinary.EXACT_FIT_MAX_SAMPLES` snapshots fits the
        hyperparameters on a random subset and factorises the system of all snapshots once per
        mode (``fit_subset="auto"``; the choice is kept in the file and shown by the held-out
        report). Any estimator of
        :mod:`podkrig.surrogate.backends` (SMT's KRG/KPLS, scikit-learn's GPR) may serve instead;
        the surrogate then predicts, validates, saves and inverts the same way.
    space : ParameterSpace, optional
        Maps parameters to the unit cube (linear or log per parameter) and defines the trained
        box. Without it the training samples' bounding box is mapped linearly to the unit cube.
    layout : {"stacked", "per_level"}, default "stacked"
        One POD over the snapshot flattened across all control levels (the first axis of a
        snapshot), or a separate POD per level (thesis §4.3.3; ``POD(blocks=n_levels)``) whose
        coefficients are kriged one by one like all POD coefficients; predictions and standard
        deviations come back in the same layout either way.
    scaling : {"unit", "sensor", "none"}, default "none"
        Divide each output by a scale before the POD and multiply back after: ``"unit"``, the
        standard deviation over the snapshots pooled over every output of the same unit (the
        ``units`` given to :meth:`fit`: forces in kN and displacements in mm then weigh alike in
        the POD energy, while gauges of one unit keep their relative weights); ``"sensor"``, the
        same per sensor; ``"none"``, raw values (the unit that is numerically larger dominates the
        energy). Scales are relative to the first group's (whose outputs keep their numbers: a
        surrogate of one unit is not scaled) and computed from the training snapshots, so
        multiplying a sensor's readings by a constant changes nothing but its predictions' unit.

    Attributes
    ----------
    pod_ : POD
    kriging_ : OrdinaryKriging or another backend
    backend_ : str
        Name of the backend (``"podkrig"``, ``"smt-krg"``, ``"smt-kpls"``, ``"sklearn-gpr"``).
    X_ : ndarray of shape (n_samples, n_params)
        Training parameters, physical units.
    lower_, upper_ : ndarray of shape (n_params,)
        The trained box, physical units.
    output_shape_ : tuple
        Shape of one snapshot, e.g. ``(n_loads, n_sensors)``.
    residual_variance_ : ndarray of shape (n_outputs,)
        POD truncation part of the predictive variance, output units².
    scale_ : ndarray of shape (n_outputs,)
        The scale of each output (-: relative to the first group's; ones without scaling).
    units_ : tuple of str
        The unit of each output of one control level (all ``""`` when none were given).
    train_norm_, train_residual_norm_ : ndarray of shape (n_samples,)
        :math:`\\|y_i\\|` and the POD truncation residual :math:`\\|y_i - P y_i\\|` of the training
        snapshots, in scaled outputs (for the leave-one-out errors).
    provenance_ : dict
        Source store, its content hash, sensor names, load levels, ... (filled by
        :func:`fit_from_store`; ``package_version`` and ``created`` always).

    Notes
    -----
    Prediction :math:`\\hat y(x) = \\bar y + \\sum_k \\hat a_k(x) \\varphi_k`; predictive variance
    per output :math:`o`

    .. math::

        \\sigma^2_o(x) = \\sum_k \\sigma^2_{K,k}(x) \\, \\varphi_{k,o}^2 + r_o,

    with the kriging variance :math:`\\sigma^2_{K,k}` of mode :math:`k` (modes independent) and the
    mean squared residual :math:`r_o` of the training snapshots off the retained basis (POD
    truncation error).
    """

    def __init__(self, pod=None, kriging=None, space=None, layout="stacked", scaling="none"):
        self.pod = pod
        self.kriging = kriging
        self.space = space
        self.layout = layout
        self.scaling = scaling

    def get_params(self, deep=True):
        """Hyperparameters as a dict (scikit-learn convention)."""
        return {"pod": self.pod, "kriging": self.kriging, "space": self.space, "layout": self.layout,
                "scaling": self.scaling}

    def _scales(self, Yf, units):
        """Scale of each flattened output: the RMS over a group's outputs of their standard
        deviations over the snapshots (a group: one unit, one sensor, or none: ones), divided by
        the first group's."""
        n_levels, width = self._levels()
        if self.scaling == "none":
            return np.ones(Yf.shape[1])
        sd = Yf.std(axis=0).reshape(n_levels, width)
        keys = units if self.scaling == "unit" else tuple(range(width))
        scale = np.ones(width)
        for key in dict.fromkeys(keys):
            cols = [j for j in range(width) if keys[j] == key]
            rms = float(np.sqrt(np.mean(sd[:, cols] ** 2)))
            scale[cols] = rms if rms > 0 else 1.0
        # relative to the first group's: its outputs keep their numbers, and a surrogate of one
        # unit is not scaled at all (the kriging fit does not depend on a common factor of its
        # data, but a factor other than a power of two changes the numbers by rounding)
        return np.tile(scale / scale[0], n_levels)

    def _levels(self):
        """``(n_levels, outputs per level)``: the first axis of a snapshot is the control level
        (a one-dimensional snapshot is one level)."""
        shape = self.output_shape_
        if len(shape) < 2:
            return 1, int(np.prod(shape))
        return int(shape[0]), int(np.prod(shape[1:]))

    # ------------------------------------------------------------------ scaling
    def _to_unit(self, X):
        if self.space is not None:
            return self.space.to_unit(X)
        return (X - self.lower_) / (self.upper_ - self.lower_)

    def _unit_inside(self, X):
        """Unit coordinates of samples inside the box (physical units, checked exactly by the
        caller): the map is monotone, so only a rounding of the log scale can leave [0, 1] by an ulp,
        and the clip removes exactly that."""
        return np.clip(self._to_unit(X), 0.0, 1.0)

    @property
    def parameter_names(self):
        """Names of the parameters (from the space, else ``x0, x1, ...``)."""
        if self.space is not None:
            return self.space.names
        return tuple(f"x{k}" for k in range(self.X_.shape[1]))

    # ------------------------------------------------------------------ fit / predict
    def fit(self, X, Y, units=None):
        """Fit the POD basis and one kriging interpolant per retained mode.

        Parameters
        ----------
        X : array_like of shape (n_samples, n_params)
            Parameter vectors, physical units (inside ``space`` when one is given).
        Y : array_like of shape (n_samples, ...)
            Snapshots, e.g. readings ``(n, n_loads, n_sensors)`` in mm (a force in kN).
        units : sequence of str, optional
            The unit of each output of one control level (e.g. of each sensor: ``["mm", "mm",
            "kN"]``); default: one unit for all. Scaling ``"unit"`` groups the outputs by it and the
            held-out report gives errors per unit.

        Returns
        -------
        self : PODKriging

        Raises
        ------
        ValueError
            Mismatched shapes, samples outside the space, or a parameter that does not vary.
        """
        X = np.array(X, dtype=float, copy=True)
        Y = np.asarray(Y, dtype=float)
        if X.ndim != 2:
            raise ValueError(f"X must have shape (n_samples, n_params); got {X.shape}")
        if Y.ndim < 2 or Y.shape[0] != X.shape[0]:
            raise ValueError(f"Y must have shape ({X.shape[0]}, ...) (one snapshot per row of X); got {Y.shape}")
        if self.layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}; got {self.layout!r}")
        if self.scaling not in SCALINGS:
            raise ValueError(f"scaling must be one of {SCALINGS}; got {self.scaling!r}")
        if self.space is not None:
            if X.shape[1] != self.space.n_params:
                raise ValueError(f"X has {X.shape[1]} columns but the space has parameters {list(self.space.names)}")
            lower, upper = self.space.lower, self.space.upper
            out = (X < lower) | (X > upper)
            if out.any():
                k = int(np.argmax(out.any(axis=0)))
                raise ValueError(
                    f"training samples of {self.space.names[k]!r} lie outside its bounds "
                    f"[{lower[k]:g}, {upper[k]:g}] {self.space.units[k]}; widen the space"
                )
            U = self._unit_inside(X)
        else:
            lower, upper = X.min(axis=0), X.max(axis=0)
            flat = np.flatnonzero(upper <= lower)
            if len(flat):
                raise ValueError(
                    f"parameter column {int(flat[0])} is constant ({lower[flat[0]]:g}) in the training "
                    "samples; remove it or give a ParameterSpace"
                )
            self.lower_, self.upper_ = lower, upper  # _to_unit reads them
            U = self._to_unit(X)
        self.lower_, self.upper_ = np.asarray(lower, float), np.asarray(upper, float)
        self.output_shape_ = tuple(Y.shape[1:])
        n_levels, width = self._levels()
        units = tuple(str(u) for u in units) if units is not None else ("",) * width
        if len(units) != width:
            raise ValueError(f"units must name the unit of each of the {width} outputs of one control level; "
                             f"got {len(units)}: {list(units)}")
        self.units_ = units
        Yf = Y.reshape(len(Y), -1)
        self.scale_ = self._scales(Yf, units)
        Yf = Yf / self.scale_
        params = (self.pod if self.pod is not None else POD(energy=DEFAULT_ENERGY)).get_params()
        params["blocks"] = n_levels if self.layout == "per_level" else None
        self.pod_ = POD(**params).fit(Yf)
        A = self.pod_.transform(Yf)
        self.train_norm_ = np.linalg.norm(Yf, axis=1)
        self.train_residual_norm_ = np.linalg.norm(Yf - self.pod_.inverse_transform(A), axis=1)
        self.kriging_ = _clone(self.kriging if self.kriging is not None else OrdinaryKriging()).fit(U, A)
        self.backend_ = backend_name(self.kriging_)
        self.X_ = X
        self.U_ = U
        self.residual_variance_ = self.pod_.residual_variance_ * self.scale_**2
        self.n_features_in_ = X.shape[1]
        self.provenance_ = {"package_version": __version__, "created": _now()}
        logger.info("POD-kriging fitted: %d samples, %d outputs, %d modes", len(X), Yf.shape[1],
                    self.pod_.n_modes_)
        return self

    def _check_fitted(self):
        if not hasattr(self, "kriging_"):
            raise NotFittedError("this PODKriging instance is not fitted yet; call fit(X, Y) first")

    @property
    def n_modes_(self):
        """Number of retained POD modes."""
        self._check_fitted()
        return self.pod_.n_modes_

    def check_box(self, X, extrapolate=False):
        """Unit-cube coordinates of ``X``; refuse (or warn about) samples outside the trained box.

        Parameters
        ----------
        X : array_like of shape (n, n_params)
            Physical units.
        extrapolate : bool
            Warn instead of raising.

        Returns
        -------
        U : ndarray of shape (n, n_params)
        """
        self._check_fitted()
        X = np.asarray(X, dtype=float)
        if X.ndim == 1:
            X = X[None, :]
        if X.ndim != 2 or X.shape[1] != self.n_features_in_:
            raise ValueError(
                f"X must have shape (n, {self.n_features_in_}) for parameters {list(self.parameter_names)}; "
                f"got {X.shape}"
            )
        if not np.all(np.isfinite(X)):
            raise ValueError("X must be finite; found NaN or inf")
        out = (X < self.lower_) | (X > self.upper_)  # physical units, exact: the trained box
        if not out.any():
            return self._unit_inside(X)
        i, k = (int(v[0]) for v in np.nonzero(out))
        unit = self.space.units[k] if self.space is not None else ""
        msg = (
            f"{int(out.any(axis=1).sum())} of {len(X)} samples lie outside the trained box, e.g. sample "
            f"{i}: {self.parameter_names[k]} = {X[i, k]:g} {unit} not in "
            f"[{self.lower_[k]:g}, {self.upper_[k]:g}]".replace("  ", " ")
        )
        if not extrapolate:
            raise ValueError(msg + "; the surrogate does not extrapolate: pass extrapolate=True "
                                   "to predict anyway (accuracy unknown) or train on a wider space")
        warnings.warn(msg + "; extrapolating, accuracy unknown", UserWarning, stacklevel=3)
        return self._to_unit(X)

    def predict(self, X, return_std=False, *, extrapolate=False, reshape=False):
        """Predicted snapshots (and standard deviations) for a batch of parameter vectors.

        Parameters
        ----------
        X : array_like of shape (n, n_params)
            Physical units, inside the trained box.
        return_std : bool, default False
            Also return the predictive standard deviation (kriging variance of every mode plus the
            POD truncation variance).
        extrapolate : bool, default False
            Allow samples outside the trained box (with a warning).
        reshape : bool, default False
            Return ``(n, *output_shape_)`` (e.g. ``(n, n_loads, n_sensors)``) instead of
            ``(n, n_outputs)``.

        Returns
        -------
        Y : ndarray of shape (n, n_outputs) or (n, *output_shape_)
            Output units (mm for readings and fields).
        std : ndarray, same shape
            Only with ``return_std``.

        Raises
        ------
        ValueError
            Samples outside the trained box without ``extrapolate=True``.
        """
        return self._predict_unit(self.check_box(X, extrapolate), return_std, reshape)

    def predict_unit(self, U, return_std=False, *, reshape=False):
        """:meth:`predict` at unit-cube coordinates of the parameters (the scaling of ``space``).

        The entry point of algorithms that work in the unit cube (the GA, least squares, region
        sampling): the coordinates go straight to the kriging, with no round trip through
        physical units.

        Parameters
        ----------
        U : array_like of shape (n, n_params)
            Coordinates in [0, 1] (exactly: the surrogate does not extrapolate here).
        return_std, reshape : bool
            As in :meth:`predict`.

        Raises
        ------
        ValueError
            Wrong shape, non-finite values, or a coordinate outside [0, 1].
        """
        self._check_fitted()
        U = np.asarray(U, dtype=float)
        if U.ndim == 1:
            U = U[None, :]
        if U.ndim != 2 or U.shape[1] != self.n_features_in_:
            raise ValueError(f"U must have shape (n, {self.n_features_in_}) for parameters "
                             f"{list(self.parameter_names)}; got {U.shape}")
        if not np.all(np.isfinite(U)):
            raise ValueError("U must be finite; found NaN or inf")
        out = (U < 0.0) | (U > 1.0)
        if out.any():
            i, k = (int(v[0]) for v in np.nonzero(out))
            raise ValueError(f"unit coordinates must lie in [0, 1]; sample {i}: {self.parameter_names[k]} has "
                             f"{U[i, k]:g}; use predict() with physical values and extrapolate=True to extrapolate")
        return self._predict_unit(U, return_std, reshape)

    def _predict_unit(self, U, return_std, reshape):
        if return_std:
            A, S = self.kriging_.predict(U, return_std=True)
        else:
            A = self.kriging_.predict(U)
        # the reconstruction is a skinny product (n_modes is small): a multi-threaded BLAS only
        # adds wake-ups, and waits for a descheduled thread on a shared machine (8 ms instead of
        # 0.1 ms for 10 000 x 6 x 24 while another process held one of two cores)
        with one_blas_thread():
            Y = self.pod_.inverse_transform(A.reshape(len(U), -1)) * self.scale_
            shape = (len(U), *self.output_shape_) if reshape else Y.shape
            if not return_std:
                return Y.reshape(shape)
            var = ((S.reshape(len(U), -1) ** 2) @ (self.pod_.modes_**2)) * self.scale_**2 + self.residual_variance_
        return Y.reshape(shape), np.sqrt(var).reshape(shape)

    def project(self, Y):
        """Best approximation of snapshots in the surrogate's POD space (the scaled outputs
        projected, then unscaled): the truncation part of the error.

        Parameters
        ----------
        Y : array_like of shape (n, n_outputs) or (n, *output_shape_)
            Output units.

        Returns
        -------
        ndarray of shape (n, n_outputs)
        """
        self._check_fitted()
        Yf = np.asarray(Y, dtype=float).reshape(len(Y), -1)
        return self.pod_.project(Yf / self.scale_) * self.scale_

    # ------------------------------------------------------------------ state exchange
    def to_arrays(self):
        """The fitted state as named arrays and plain metadata, for a file format (no pickle).

        :func:`podkrig.io.surrogate_file.save_surrogate` writes it to HDF5; :meth:`from_arrays`
        rebuilds the surrogate from it, with bitwise identical predictions.

        Returns
        -------
        arrays : dict
            ``X`` ``(n_samples, n_params)`` physical units, ``U`` its unit-cube coordinates,
            ``lower``, ``upper`` ``(n_params,)``, ``train_norm``, ``train_residual_norm``
            ``(n_samples,)``; ``pod`` and ``kriging``: the arrays of :meth:`POD.to_arrays` and of
            the backend's ``to_arrays``.
        attrs : dict
            ``settings`` (``{"pod": ..., "kriging": ...}``, the templates' settings, JSON-able),
            ``provenance`` (dict), ``parameter_space`` (:meth:`ParameterSpace.to_dict` or None),
            ``output_shape`` (list), ``backend``, ``backend_version`` (str); ``pod`` and
            ``kriging``: the attributes of those parts.
        """
        self._check_fitted()
        kr = self.kriging_
        settings = {
            "layout": self.layout, "scaling": self.scaling, "units": list(self.units_),
            "pod": self.pod_.get_params(),
            "kriging": {k: (np.asarray(v).tolist() if isinstance(v, (np.ndarray, tuple))
                            else f"callable {getattr(v, '__qualname__', type(v).__name__)}" if callable(v) else v)
                        for k, v in kr.get_params().items()},  # a callable optimizer: its name only
        }
        pod_arrays, pod_attrs = self.pod_.to_arrays()
        kr_arrays, kr_attrs = kr.to_arrays()
        arrays = {"X": self.X_, "U": self.U_, "lower": self.lower_, "upper": self.upper_,
                  "train_norm": self.train_norm_, "train_residual_norm": self.train_residual_norm_,
                  "scale": self.scale_, "pod": pod_arrays, "kriging": kr_arrays}
        attrs = {"settings": settings, "provenance": self.provenance_,
                 "parameter_space": self.space.to_dict() if self.space is not None else None,
                 "output_shape": list(self.output_shape_), "backend": self.backend_,
                 "backend_version": backend_version(kr), "pod": pod_attrs, "kriging": kr_attrs}
        return arrays, attrs

    @classmethod
    def from_arrays(cls, arrays, attrs):
        """A fitted surrogate from :meth:`to_arrays` output; predictions are bitwise identical.

        Parameters
        ----------
        arrays, attrs : mapping
            As :meth:`to_arrays` returns them (array values may be any array_like). ``backend``
            may be missing (then ``"podkrig"``), and the kriging part may lack what older
            surrogates did not record (the backend's ``from_arrays`` says what).

        Raises
        ------
        KeyError, ValueError, TypeError
            A missing or inconsistent entry.
        """
        settings, space = attrs["settings"], attrs["parameter_space"]
        kr_settings = dict(settings["kriging"])
        if isinstance(kr_settings.get("range_bounds"), list):
            kr_settings["range_bounds"] = tuple(kr_settings["range_bounds"])
        backend = str(attrs.get("backend", "podkrig"))
        kr = backend_from_arrays(backend, arrays["kriging"], attrs["kriging"], kr_settings)
        sur = cls(pod=POD(**settings["pod"]), kriging=_clone(kr),
                  space=ParameterSpace.from_dict(space) if space is not None else None,
                  layout=settings.get("layout", "stacked"), scaling=settings.get("scaling", "none"))
        sur.pod_ = POD.from_arrays(arrays["pod"], attrs["pod"], sur.pod.get_params())
        sur.kriging_, sur.backend_ = kr, backend
        sur.X_, sur.U_ = np.asarray(arrays["X"]), np.asarray(arrays["U"])
        sur.lower_, sur.upper_ = np.asarray(arrays["lower"]), np.asarray(arrays["upper"])
        sur.train_norm_ = np.asarray(arrays["train_norm"])
        sur.train_residual_norm_ = np.asarray(arrays["train_residual_norm"])
        sur.output_shape_ = tuple(attrs["output_shape"])
        # written before outputs were scaled: raw outputs of one unseen unit
        sur.scale_ = np.asarray(arrays["scale"]) if "scale" in arrays else np.ones(sur.pod_.n_outputs_)
        sur.units_ = tuple(settings.get("units", ("",) * sur._levels()[1]))
        sur.residual_variance_ = sur.pod_.residual_variance_ * sur.scale_**2
        sur.n_features_in_ = sur.X_.shape[1]
        sur.provenance_ = dict(attrs["provenance"])
        return sur


def _now():
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


def training_data(store, output="readings", exclude=()):
    """Parameters and snapshots of the finished rows of a snapshot store.

    Parameters
    ----------
    store : podkrig.offline.store.SnapshotStore
        An open store.
    output : {"readings", "field"}
        Sensor readings ``(n, n_loads, n_sensors)`` or displacement fields
        ``(n, n_loads, n_nodes, 2)``, mm.
    exclude : sequence of int
        Finished store rows left out as well (e.g. runs without a load maximum for a surrogate
        of capacity).

    Returns
    -------
    X : ndarray of shape (n_done, n_params)
        Physical parameters.
    Y : ndarray of shape (n_done, ...)
        Snapshots, mm.
    """
    if output not in ("readings", "field"):
        raise ValueError(f"output must be 'readings' or 'field'; got {output!r}")
    X = store.parameters(physical=True, only_done=True)
    Y = store.readings(only_done=True) if output == "readings" else store.fields(only_done=True)
    if len(exclude):
        keep = ~np.isin(np.flatnonzero(store.done_mask()), list(exclude))
        X, Y = X[keep], Y[keep]
    if len(X) < 3:
        raise ValueError(f"{store.path} has {len(X)} finished snapshots; the surrogate needs at least 3 "
                         "(run 'podkrig snapshots run' first)")
    return X, Y


def fit_from_store(store, pod=None, kriging=None, output="readings", layout="stacked", scaling="none", exclude=()):
    """Fit a :class:`PODKriging` on a snapshot store and record where it came from.

    Parameters
    ----------
    store : podkrig.offline.store.SnapshotStore
        An open store; its parameter space scales the inputs.
    pod, kriging : optional
        Templates, as in :class:`PODKriging`.
    output : {"readings", "field"}
    layout, scaling : str
        As in :class:`PODKriging`; the readings' units are the store's sensor units (a load
        reading's own — the force and the peak readings ``F_peak``, ``d_peak`` — else mm; a
        field is all mm).
    exclude : sequence of int
        Finished store rows left out of the fit (:func:`training_data`).

    Returns
    -------
    PODKriging
        With ``provenance_`` holding the store path and content hash, scenario spec, sensor names,
        load levels and unit, the output kind and the number of nodes.
    """
    X, Y = training_data(store, output, exclude)
    # the unit of each sensor: mm, a load reading's own (sensor_definitions kind "force" or "peak")
    sensor_units = [store.sensor_definitions.get(n, {}).get("unit", "mm")
                    if store.sensor_definitions.get(n, {}).get("kind") in ("force", "peak") else "mm"
                    for n in store.sensor_names]
    units = sensor_units if output == "readings" else None
    sur = PODKriging(pod=pod, kriging=kriging, space=store.space, layout=layout, scaling=scaling).fit(X, Y, units)
    sur.provenance_.update({
        "source_store": str(Path(store.path).resolve()),
        "source_content_hash": store.content_hash(),
        "scenario_spec": store.spec.to_dict(),
        "sensor_names": list(store.sensor_names),
        "load_levels": np.asarray(store.load_levels).tolist(),
        "load_unit": store.load_unit,
        "reading_unit": store.reading_unit,
        "sensor_units": sensor_units,
        "output": output,
        "n_nodes": int(store.n_nodes),
        "n_train": len(X),
    })
    return sur
