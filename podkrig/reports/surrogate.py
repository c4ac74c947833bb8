"""Figures, tables and a one-page HTML report of a POD-kriging surrogate and its held-out errors.

Presentation only: every function takes fitted objects or result dataclasses
(:class:`~podkrig.surrogate.validation.HeldOutReport`,
:class:`~podkrig.surrogate.results.SurrogateFitResult`,
:class:`~podkrig.surrogate.results.HeldOutResult`) and writes PNG files or page sections; nothing
is computed here beyond reshaping for display. :func:`fit_tables` and :func:`held_out_tables` are
the one rendering of those results, on the study report and on ``podkrig surrogate validate
--report`` alike. matplotlib is imported lazily with the non-interactive Agg backend.
"""

import json
import logging
from pathlib import Path

import numpy as np

from podkrig.reports.figures import load_label, pyplot, save
from podkrig.reports.html import Page, num, pct

logger = logging.getLogger(__name__)


def plot_energy(pod, path):
    """Energy decay of the POD: singular values² share and the unretained energy, log scale."""
    plt = pyplot()
    s2 = pod.singular_values_**2
    k = np.arange(1, len(s2) + 1)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.semilogy(k, s2 / s2.sum(), "o-", label=r"energy share $\lambda_k / \sum \lambda$")
    rest = np.clip(1.0 - pod.energy_, 1e-18, None)
    ax.semilogy(k, rest, "s--", label=r"unretained energy $1 - \sum_{j \leq k} \lambda_j / \sum \lambda$")
    ax.axvline(pod.n_modes_, color="k", lw=0.8, ls=":", label=f"retained: {pod.n_modes_} modes")
    ax.set_xlabel("mode number k (-)")
    ax.set_ylabel("energy share (-)")
    ax.set_title("POD energy decay")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return Path(path)


def plot_reading_modes(pod, sensor_names, load_levels, load_unit, path, n_show=4):
    """First POD modes of readings: one panel per mode, one line per sensor over the load levels."""
    plt = pyplot()
    n_loads, n_sensors = len(load_levels), len(sensor_names)
    n_show = min(n_show, pod.n_modes_)
    fig, axes = plt.subplots(1, n_show, figsize=(3.2 * n_show, 3.4), squeeze=False)
    for k in range(n_show):
        ax = axes[0, k]
        mode = pod.modes_[k].reshape(n_loads, n_sensors)
        for j, name in enumerate(sensor_names):
            ax.plot(load_levels, mode[:, j], "o-", ms=3, label=name)
        ax.set_title(f"mode {k + 1}")
        ax.set_xlabel(load_label(load_unit))
        ax.set_ylabel("mode component (mm per unit coefficient)" if k == 0 else "")
        ax.axhline(0, color="k", lw=0.5)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return Path(path)


def plot_field_modes(pod, nodes, path, n_show=3, load_index=-1):
    """First POD modes of displacement fields on the mesh (magnitude at one load level, coloured)."""
    plt = pyplot()
    n_nodes = len(nodes)
    n_show = min(n_show, pod.n_modes_)
    fig, axes = plt.subplots(1, n_show, figsize=(4 * n_show, 3.8), squeeze=False)
    for k in range(n_show):
        ax = axes[0, k]
        mode = pod.modes_[k].reshape(-1, n_nodes, 2)[load_index]
        mag = np.hypot(mode[:, 0], mode[:, 1])
        sc = ax.scatter(nodes[:, 0], nodes[:, 1], c=mag, s=2, cmap="viridis")
        ax.set_aspect("equal")
        ax.set_title(f"mode {k + 1} (last load level)")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        fig.colorbar(sc, ax=ax, label="|mode| (mm per unit coefficient)", shrink=0.8)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return Path(path)


def plot_error_histograms(errors_by_label, path):
    """Histograms of held-out relative errors per semivariogram and exponent (cf. thesis Fig. 4.4)."""
    plt = pyplot()
    labels = list(errors_by_label)
    fig, axes = plt.subplots(len(labels), 1, figsize=(6, 1.8 * len(labels) + 0.6), sharex=True, squeeze=False)
    allv = np.concatenate([np.asarray(v, float) for v in errors_by_label.values()])
    allv = allv[allv > 0]
    lo, hi = (allv.min(), allv.max()) if len(allv) else (1e-6, 1.0)
    bins = np.logspace(np.log10(lo), np.log10(hi) + 1e-9, 30)
    for ax, label in zip(axes[:, 0], labels):
        e = np.asarray(errors_by_label[label], float)
        ax.hist(np.clip(e, lo, hi), bins=bins, color="C0", alpha=0.8)
        ax.axvline(np.median(e), color="C3", lw=1, label=f"median {np.median(e):.2e}")
        ax.set_xscale("log")
        ax.set_ylabel("samples (-)")
        ax.set_title(label, fontsize=9)
        ax.legend(fontsize=7)
    axes[-1, 0].set_xlabel(r"held-out relative error $\|\hat y - y\| / \|y\|$ (-)")
    fig.tight_layout()
    save(fig, path, dpi=110)
    return Path(path)


def plot_predicted_vs_fe(report, path, unit="mm"):
    """Surrogate prediction against the FE value for every held-out output, with ±2σ bars."""
    plt = pyplot()
    y, p, s = report.Y_true.ravel(), report.Y_pred.ravel(), report.Y_std.ravel()
    if len(y) > 20000:  # keep the figure light for full fields
        idx = np.random.default_rng(0).choice(len(y), 20000, replace=False)
        y, p, s = y[idx], p[idx], s[idx]
    fig, ax = plt.subplots(figsize=(5, 5))
    ax.errorbar(y, p, yerr=2 * s, fmt=".", ms=2, lw=0.3, alpha=0.5, label=r"prediction $\pm 2\sigma$")
    lim = [min(y.min(), p.min()), max(y.max(), p.max())]
    ax.plot(lim, lim, "k-", lw=0.8, label="prediction = FE")
    ax.set_xlabel(f"FE value ({unit})")
    ax.set_ylabel(f"surrogate prediction ({unit})")
    ax.set_title("held-out outputs")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return Path(path)


def fit_tables(page, result):
    """A surrogate fit (:class:`~podkrig.surrogate.results.SurrogateFitResult`) as a table on ``page``:
    training snapshots, POD modes, retained energy, the exponents per mode (our kriging) or the
    backend's description, training time."""
    regression = (", ".join(f"{b:.3g}" for b in result.beta) if result.beta is not None
                  else result.description or result.backend)
    page.table(["training snapshots", "POD modes", "retained energy (-)",
                "β per mode (-)" if result.beta is not None else "backend", "training time (s)"],
               [[result.n_train, result.n_modes, f"{result.retained_energy:.10f}", regression,
                 num(result.training_seconds, 3)]])
    if result.dropped_rows:
        page.paragraph(dropped_text(result.dropped_rows))


def dropped_text(rows, limit=20):
    """The failed training rows a fit left out, in words (``rows``: their indices)."""
    more = f" and {len(rows) - limit} more" if len(rows) > limit else ""
    return (f"{len(rows)} failed training runs (rows {', '.join(map(str, rows[:limit]))}{more}) were left out of "
            "the fit (failed_rows = 'drop').")


def held_out_tables(page, result):
    """A held-out check (:class:`~podkrig.surrogate.results.HeldOutResult`) on ``page``: what the
    errors mean, the relative errors (total, POD truncation, interpolation, leave-one-out) in %, the
    absolute errors in mm and the ±2σ coverage, and how the kriging was trained."""
    page.paragraph(
        "The surrogate against FE runs it was not trained on. Relative error per run: ‖ŷ − y‖ / ‖y‖ over all "
        "readings; POD part: what the retained modes cannot represent; interpolation part: the kriging error."
    )
    errors = (("total", result.rel_error), ("POD truncation", result.pod_error),
              ("interpolation", result.interp_error), ("leave-one-out (training)", result.loo_error))
    page.table(["error (%)", "median", "95th percentile", "max"],
               [[label] + [pct(e[q]) for q in ("median", "p95", "max")] for label, e in errors if e is not None])
    page.table(["held-out runs", "RMS error (mm)", "max error (mm)", "readings within ±2σ (%)"],
               [[result.n_held_out, num(result.rms_abs_error_mm, 3), num(result.max_abs_error_mm, 3),
                 pct(result.coverage_2sigma)]])
    if result.fit_description is not None:
        page.paragraph(f"Kriging: {result.fit_description}.")


def write_html(directory, title, fit, held, figures, notes=(), extra=None):
    """Write ``directory/index.html`` of a surrogate's held-out check: its fit and its errors
    (:func:`fit_tables`, :func:`held_out_tables`), the figures beside it, and the numbers as JSON.

    Parameters
    ----------
    directory : str or Path
        Created if missing; figures are referenced by file name.
    title : str
    fit : SurrogateFitResult
    held : HeldOutResult
    figures : sequence of (caption, Path)
    notes : sequence of str
        Extra lines (e.g. settings, the source stores).
    extra : dict, optional
        More numbers for the JSON block (e.g. the median errors of other kriging settings).

    Returns
    -------
    Path of ``index.html``.
    """
    page = Page(title)
    fit_tables(page, fit)
    held_out_tables(page, held)
    for note in notes:
        page.paragraph(note, "meta")
    for caption, path in figures:
        page.figure(Path(path).name, caption)
    data = {"surrogate": fit.to_dict(), "held_out": held.to_dict(), **(extra or {})}
    page.details("numbers (JSON)", json.dumps(data, indent=2, default=str))
    return page.write(Path(directory) / "index.html")
