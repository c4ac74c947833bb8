"""Figures of a genetic-algorithm run, drawn from a :class:`~podkrig.ga.GAResult`.

Presentation only: these functions read a result and never compute one. matplotlib is imported
when a figure is drawn (:func:`_pyplot`), with the backend the user chose.

- :func:`plot_history` — every evaluated individual's objective against its generation
  (the "individual history chart" of the thesis, Fig. 3.17);
- :func:`plot_statistics` — best, mean and standard deviation of the population per generation
  (thesis Fig. 3.17);
- :func:`plot_parameters` — objective against each parameter's value, one panel per parameter
  (thesis Fig. 3.23), labelled with the parameter names and units, with the optimum the caller
  reports (e.g. an inversion's, after its least-squares polishes) marked.
"""

from __future__ import annotations

import numpy as np

from podkrig.reports.figures import colourbar

__all__ = ["plot_history", "plot_parameters", "plot_statistics"]


def _pyplot():
    """``matplotlib.pyplot``, imported on the first figure: it costs ~1.3 s on top of numpy and
    scipy (``python -X importtime``, loaded 2-core machine), which a GA run on a surrogate (well
    under a second) should not pay."""
    import matplotlib.pyplot as plt  # local on purpose: see the docstring

    return plt


def _axes(ax):
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6.0, 4.0), layout="constrained")
    return ax


def _use_log(values, log):
    finite = values[np.isfinite(values)]
    if log is None:
        return finite.size > 0 and finite.min() > 0 and finite.max() / finite.min() > 100
    return log


def plot_history(result, ax=None, *, log=None, optimum=None):
    """Individual history chart: objective of every evaluated individual vs generation.

    Parameters
    ----------
    result : GAResult
    ax : matplotlib.axes.Axes or None
        Axes to draw on; a new figure if None.
    log : bool or None
        Logarithmic objective axis; None chooses it when all values are positive and span
        more than two decades.
    optimum : float or None
        The objective of the optimum the caller reports (e.g. an inversion's misfit after its
        least-squares polishes), drawn as a dashed horizontal line (label ``"reported optimum"``).

    Returns
    -------
    ax : matplotlib.axes.Axes
    """
    ax = _axes(ax)
    feasible = (result.violation_history <= 0.0) & ~result.polish_mask
    gen, f = result.generation_history, result.f_history
    ax.scatter(gen[feasible], f[feasible], s=6, alpha=0.5, label="individual")
    infeasible = (result.violation_history > 0.0) & ~result.polish_mask
    if infeasible.any():
        ax.scatter(gen[infeasible], f[infeasible], s=6, marker="x", alpha=0.4,
                   label="infeasible individual")
    if result.polish_mask.any():
        ax.scatter(gen[result.polish_mask], f[result.polish_mask], s=10, marker="^",
                   alpha=0.6, label="local polish")
    ax.plot(np.arange(result.ngen + 1), result.generation_best, color="k", lw=1.2,
            label="best in population")
    if optimum is not None:
        ax.axhline(optimum, color="tab:red", lw=1.0, ls="--", label="reported optimum")
    if _use_log(f, log):
        ax.set_yscale("log")
    ax.set_xlabel("generation")
    ax.set_ylabel("objective f")
    ax.set_title("Individual history")
    ax.legend(loc="upper right", fontsize="small")
    return ax


def plot_statistics(result, ax=None, *, log=None):
    """Population statistics per generation: best, mean and mean ± one standard deviation.

    Parameters
    ----------
    result : GAResult
    ax : matplotlib.axes.Axes or None
    log : bool or None
        Logarithmic objective axis (None: automatic, as in :func:`plot_history`).

    Returns
    -------
    ax : matplotlib.axes.Axes
    """
    ax = _axes(ax)
    g = np.arange(result.ngen + 1)
    mean, std = result.generation_mean, result.generation_std
    ax.plot(g, result.generation_best, label="best")
    ax.plot(g, mean, label="mean")
    ax.plot(g, std, ls=":", label="standard deviation")
    ax.fill_between(g, mean - std, mean + std, alpha=0.2, label="mean ± std")
    if _use_log(np.concatenate([result.generation_best, mean]), log):
        ax.set_yscale("log")
    ax.set_xlabel("generation")
    ax.set_ylabel("objective f in population")
    ax.set_title("Population statistics")
    ax.legend(loc="upper right", fontsize="small")
    return ax


def plot_parameters(result, axes=None, *, log=None, xscale=None, optimum=None):
    """Objective of every evaluated individual against each parameter (one panel each).

    Parameters
    ----------
    result : GAResult
    axes : sequence of matplotlib.axes.Axes or None
        ``n_params`` axes; a new figure with a row of panels if None.
    log : bool or None
        Logarithmic objective axis (None: automatic).
    xscale : sequence of {"linear", "log"} or None
        Scale of each parameter axis (e.g. the parameter space's scales).
    optimum : tuple (x, f) or None
        The optimum the caller reports: ``x`` of shape (n_params,) in physical units and its
        objective ``f`` — e.g. an inversion's ``(result.x, result.misfit)``, which its
        least-squares polishes may have moved away from the GA's best. Drawn on every panel as a
        star at ``(x[i], f)`` on a dashed line (label ``"reported optimum"``); the GA's own best,
        where it differs, as a dotted grey line (label ``"GA best before the polish"``). None:
        the GA's best is the optimum.

    Returns
    -------
    axes : list of matplotlib.axes.Axes
    """
    n_params = len(result.parameter_names)
    if axes is None:
        _, axes = _pyplot().subplots(1, n_params, figsize=(3.2 * n_params, 3.2), sharey=True,
                               layout="constrained", squeeze=False)
        axes = list(axes[0])
    elif len(axes) != n_params:
        raise ValueError(f"axes must hold {n_params} axes, one per parameter; got {len(axes)}")
    x_opt, f_opt = (result.x, result.fun) if optimum is None else optimum
    x_opt = np.asarray(x_opt, dtype=float)
    if x_opt.shape != (n_params,):
        raise ValueError(f"optimum x must hold {n_params} values, one per parameter; got shape {x_opt.shape}")
    f = result.f_history
    use_log = _use_log(f, log)
    units = result.parameter_units
    for i, ax in enumerate(axes):
        points = ax.scatter(result.X_history[:, i], f, s=5, alpha=0.4, c=result.generation_history,
                            cmap="viridis")
        if optimum is not None and result.x[i] != x_opt[i]:
            ax.axvline(result.x[i], color="0.5", lw=0.8, ls=":", label="GA best before the polish")
        ax.axvline(x_opt[i], color="k", lw=0.8, ls="--")
        ax.plot([x_opt[i]], [f_opt], "*", color="tab:red", mec="k", mew=0.5, ms=11, zorder=5,
                label="reported optimum")
        unit = f" ({units[i]})" if units is not None and units[i] else ""  # "(unit)" as on every report axis
        ax.set_xlabel(f"{result.parameter_names[i]}{unit}")
        ax.set_ylabel("objective f")
        if use_log:
            ax.set_yscale("log")
        if xscale is not None:
            ax.set_xscale(xscale[i])
    axes[0].legend(loc="upper right", fontsize="small")
    colourbar(axes[0].figure, points, list(axes), label="generation", shrink=0.9)  # one scale for every panel
    return axes
