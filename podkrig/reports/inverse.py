"""Figures of an inversion: fit, region of equivalence, RVC, posterior (matplotlib, imported lazily).

Every function takes result objects, draws on a new figure, saves it to ``path`` (PNG) and returns
the path. Units on every axis.
"""

from pathlib import Path

import numpy as np

from podkrig.online.findings import RESIDUAL_CONVENTION, chi2_basis, inversion_findings
from podkrig.reports.findings import identifiability_text, words
from podkrig.reports.figures import pyplot, save
from podkrig.reports.ga import plot_history, plot_parameters, plot_statistics
from podkrig.reports.html import Page, fmt


def _label(name, unit):
    return f"{name} ({unit})" if unit and unit != "-" else f"{name} (-)"


def log_axis(ax, which, lo, hi):
    """Put the ``which`` ("x" or "y") axis of ``ax``, a log-sampled parameter spanning
    [``lo``, ``hi``], on a log scale;
    over less than a decade, with 4 plain-number ticks (the default labels every minor tick in
    ``a × 10^b`` form, which overlap)."""
    from matplotlib import ticker  # matplotlib is imported by the figure being drawn

    getattr(ax, f"set_{which}scale")("log")
    axis = getattr(ax, f"{which}axis")
    if hi < 10 * lo:
        axis.set_major_locator(ticker.MaxNLocator(4))
        axis.set_minor_locator(ticker.NullLocator())
        axis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:.4g}"))


def plot_fit(result, path, *, load_unit="kN"):
    """Measured and fitted readings per sensor, load on the vertical axis (the convention of test
    reports: reading (mm) across, load up), measured with ±2σ noise bars, the calibrated surrogate
    as a line with its ±2σ band."""
    plt = pyplot()
    meas = result.problem.measurement
    pred, std = result.predicted()
    sd = meas.grid(result.problem.misfit.noise_std)  # NaN where a reading is missing
    n = len(meas.sensor_names)
    cols = min(n, 3)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), squeeze=False)
    load = np.asarray(meas.load_levels, float)
    for j, name in enumerate(meas.sensor_names):
        ax = axes.flat[j]
        ax.errorbar(meas.values[:, j], load, xerr=2 * sd[:, j], fmt="o", color="k", ms=4, capsize=3,
                    label="measured ±2σ noise")
        ax.plot(pred[:, j], load, "-", color="tab:red", label="calibrated model (surrogate)")
        if std is not None:
            ax.fill_betweenx(load, pred[:, j] - 2 * std[:, j], pred[:, j] + 2 * std[:, j], color="tab:red",
                             alpha=0.2, label="surrogate ±2σ")
        ax.set_title(name)
        ax.set_xlabel(f"{name} reading (mm)")
        ax.set_ylabel(f"load ({load_unit})")
        ax.locator_params(axis="x", nbins=4)  # µm-size readings: few, readable ticks
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4))
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def plot_residuals(result, path, *, load_unit="kN"):
    """Standardised residuals (measured − model)/σ (:data:`RESIDUAL_CONVENTION`) per sensor and load
    level, as a heat map with its colour bar."""
    plt = pyplot()
    meas = result.problem.measurement
    pred, _ = result.predicted()
    sd = meas.grid(result.problem.misfit.noise_std)  # NaN where a reading is missing
    z = (meas.values - pred) / sd
    fig, ax = plt.subplots(figsize=(1.2 + 0.9 * len(meas.sensor_names), 1.2 + 0.5 * len(meas.load_levels)))
    lim = max(3.0, float(np.abs(z).max()))
    im = ax.imshow(z, cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="auto")
    ax.set_xticks(range(len(meas.sensor_names)), meas.sensor_names, rotation=45)
    ax.set_yticks(range(len(meas.load_levels)),
                  [f"step {v:g}" if load_unit == "step" else f"{v:g} {load_unit}" for v in meas.load_levels])
    for (i, j), v in np.ndenumerate(z):  # white on the dark ends of the scale
        ax.text(j, i, f"{v:+.1f}", ha="center", va="center", fontsize=7, color="w" if abs(v) > 0.6 * lim else "k")
    fig.colorbar(im, ax=ax, label=f"{RESIDUAL_CONVENTION} (-)")
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def plot_region(region, path, *, best=None, truth=None, posterior=None, space=None):
    """2-D projections of the region of equivalence on every pair of parameters (thesis
    Figs. 5.17–5.21), with the best fit, the truth (when known) and posterior samples."""
    plt = pyplot()
    p = len(region.names)
    X = region.samples
    if len(X) > 20000:
        X = X[np.random.default_rng(0).choice(len(X), 20000, replace=False)]
    pairs = [(i, j) for i in range(p) for j in range(i + 1, p)] or [(0, 0)]
    cols = min(len(pairs), 3)
    rows = int(np.ceil(len(pairs) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.6 * rows), squeeze=False)
    # a log axis for every parameter sampled on a log scale (the axis the search and the region live on)
    scales = space.scales if space is not None else ["linear"] * p
    log = [sc == "log" and X[:, k].min() > 0 for k, sc in enumerate(scales)]
    for ax, (i, j) in zip(axes.flat, pairs):
        if i == j:
            ax.hist(X[:, i], bins=40, color="0.6")
        else:
            ax.scatter(X[:, i], X[:, j], s=2, color="0.65", alpha=0.4, label=f"region ({100 * region.confidence:.0f} %)", rasterized=True)
            if posterior is not None:
                P = posterior.samples[:: max(1, len(posterior.samples) // 3000)]
                ax.scatter(P[:, i], P[:, j], s=2, color="tab:blue", alpha=0.3, label="MCMC posterior", rasterized=True)
            if best is not None:
                ax.plot(best[i], best[j], "r*", ms=11, label="best fit")
            if truth is not None:
                ax.plot(truth[i], truth[j], "kx", ms=9, mew=2, label="truth")
            ax.set_ylabel(_label(region.names[j], region.units[j]))
            if log[j]:
                log_axis(ax, "y", X[:, j].min(), X[:, j].max())
        ax.set_xlabel(_label(region.names[i], region.units[i]))
        if log[i]:
            log_axis(ax, "x", X[:, i].min(), X[:, i].max())
    for ax in list(axes.flat)[len(pairs):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7, markerscale=2)
    fig.suptitle(f"region of equivalence ({region.method}, {len(region.samples)} members of {region.n_evaluated} evaluated)", fontsize=9)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def plot_rvc(rvc_results, path):
    """Spread of model outputs over the region (thesis Figs. 5.16 / 7.27): per model and output,
    the normalised distribution (value / mean) as box plots, annotated with the CV."""
    plt = pyplot()
    labels, data, cvs = [], [], []
    for model_name, res in rvc_results.items():
        for k, out in enumerate(res.outputs):
            labels.append(f"{model_name}\n{out}")
            data.append(res.values[:, k] / res.mean[k])
            cvs.append(res.cv[k])
    fig, ax = plt.subplots(figsize=(max(5, 0.9 * len(labels) + 1), 4))
    ax.boxplot(data, whis=(0, 100))
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=60, fontsize=7)
    for k, cv in enumerate(cvs, start=1):
        ax.annotate(f"CV {100 * cv:.2f} %", (k, 1), xytext=(0, 8), textcoords="offset points", ha="center", fontsize=7)
    ax.axhline(1.0, color="0.5", lw=0.8)
    ax.set_ylabel("output / mean over the region (-)")
    ax.set_title("response variability over the region of equivalence (RVC)")
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def write_inversion_report(out_dir, result, region, *, posterior=None, rvc_results=None, load_unit="kN", noise_text="",
                           findings=None):
    """Write ``out_dir/index.html`` with the figures of an inversion; returns the page path.

    Parameters
    ----------
    out_dir : Path
    result : podkrig.online.invert.InverseResult
        With its problem (and its FE check when one was run).
    region : podkrig.online.region.Region
    posterior : podkrig.online.posterior.Posterior, optional
    rvc_results : dict of str to RVCResult, optional
        Model name → :func:`podkrig.online.propagation.rvc` result (with its values).
    findings : list of FindingText, optional
        Default: :func:`podkrig.online.findings.inversion_findings` of ``result`` and ``region``,
        worded for the command line (:func:`podkrig.reports.findings.words`).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    problem = result.problem
    if findings is None:
        findings = words(inversion_findings(result, region), "cli")
    page = Page("podkrig inversion report")
    page.paragraph(
        f"Data: {problem.measurement.source} ({problem.n_obs} readings: sensors {', '.join(problem.measurement.sensor_names)}"
        f" at {', '.join(f'{v:g}' for v in problem.measurement.load_levels)} {load_unit}); noise: {noise_text}. "
        f"Free parameters: {', '.join(problem.free)}; fixed: "
        + (", ".join(f"{k} = {v:g}" for k, v in problem.fixed.items()) or "none") + ".",
        "meta",
    )
    for f in findings:
        page.warning(f.message, f.remedy)

    page.heading("Identified parameters")
    units = dict(zip(problem.free_space.names, problem.free_space.units))
    rows = []
    for j, name in enumerate(problem.free):
        lo, hi = region.intervals[name]
        verdict = identifiability_text(name, (lo, hi), units[name], region.identifiability[name])
        post = f"[{fmt(posterior.intervals[name][0])}, {fmt(posterior.intervals[name][1])}]" if posterior else "—"
        rows.append([f"{name} ({units[name]})", fmt(result.x[j]), f"[{fmt(lo)}, {fmt(hi)}]", post, verdict])
    page.table(["parameter (unit)", "best fit", f"region of equivalence ({100 * region.confidence:.0f} %)",
                "MCMC credible interval", "verdict"], rows)
    page.table(["misfit ω (-)", "χ² (-)", "degrees of freedom", "χ²/dof (-)", "χ² includes", "evaluations", "seconds (s)"],
               [[fmt(result.misfit), fmt(result.chi2), result.dof, fmt(result.chi2_dof), result.chi2_basis,
                 result.n_evaluations, fmt(result.seconds, 3)]])

    page.heading("Fit to the measurements")
    page.figure(Path(plot_fit(result, out / "fit.png", load_unit=load_unit)).name,
                "Measured readings (±2σ noise) and the calibrated surrogate with its ±2σ band: reading (mm) "
                "across, load up, one panel per sensor.")
    page.figure(Path(plot_residuals(result, out / "residuals.png", load_unit=load_unit)).name,
                f"Standardised residuals {RESIDUAL_CONVENTION} of the surrogate at the best fit, per sensor and load "
                "level, with their colour scale.")

    fe = result.fe_check
    if fe is not None:
        page.heading("FE check at the optimum")
        page.table(["max |FE − surrogate| (mm)", "max |FE − surrogate| / σ (-)", "relative difference (-)",
                    "χ²/dof of the FE model (-)", "χ² includes"],
                   [[fmt(fe.max_abs_diff), fmt(fe.max_diff_over_noise), fmt(fe.rel_diff), fmt(fe.chi2_dof_fe),
                     chi2_basis("fe_check")]])
        if fe.ok:
            page.success("The surrogate agrees with the FE model at the optimum within the measurement noise.")

    page.heading("Region of equivalence")
    page.paragraph(
        f"Parameter vectors whose misfit is statistically indistinguishable from the best fit "
        f"(ω − ω* ≤ ½ χ²_{len(problem.free)}({region.confidence:.2f}); {region.n_evaluated} surrogate evaluations, "
        f"{len(region.samples)} members, {region.seconds:.2f} s)."
    )
    page.figure(Path(plot_region(region, out / "region.png", best=result.x, posterior=posterior, space=problem.free_space)).name,
                "2-D projections of the region of equivalence" + (" with MCMC posterior samples" if posterior else "") + ".")
    if posterior is not None:
        page.table(["MCMC steps", "acceptance (-)", "max autocorrelation time (steps)", "effective samples", "max R̂ (-)", "converged"],
                   [[posterior.n_steps, fmt(posterior.acceptance), fmt(float(np.max(posterior.autocorr_time))),
                     fmt(posterior.effective_samples), fmt(float(np.max(posterior.r_hat))), "yes" if posterior.converged else "NO"]])
        if not posterior.converged:
            page.warning("the MCMC chains have not converged (chain shorter than 50 autocorrelation times or R̂ ≥ 1.05).",
                         "run longer (--mcmc-steps) before reading the credible intervals.")

    if rvc_results:
        page.heading("Response variability (RVC)")
        rows = []
        for model_name, res in rvc_results.items():
            for k, o in enumerate(res.outputs):
                rows.append([model_name, o, fmt(res.mean[k]), fmt(100 * res.cv[k], 3), fmt(100 * res.range_ratio[k], 3)])
        page.table(["model", "output", "mean (mm)", "CV (%)", "(max − min)/mean (%)"], rows)
        page.figure(Path(plot_rvc(rvc_results, out / "rvc.png")).name, "Spread of the outputs over the region of equivalence.")

    page.heading("Genetic algorithm")
    page.figure(Path(plot_ga_history(result.ga, out / "ga_history.png")).name,
                "Every evaluated individual's misfit by generation, and population statistics (thesis Fig. 3.17).")
    page.figure(Path(plot_ga_parameters(result.ga, out / "ga_parameters.png", problem.free_space)).name,
                "Parameter values of evaluated individuals against misfit (thesis Fig. 3.23).")
    return page.write(out / "index.html")


def plot_ga_history(ga, path):
    """The GA's history: every evaluated misfit by generation, and population statistics."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    plot_history(ga, ax=axes[0])
    plot_statistics(ga, ax=axes[1])
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def plot_ga_parameters(ga, path, space=None):
    """Parameter values of the GA's evaluated individuals against their misfit, coloured by
    generation; a log axis for each parameter the search space samples on a log scale."""
    pyplot()
    fig = np.ravel(plot_parameters(ga, xscale=None if space is None else list(space.scales)))[0].figure
    save(fig, path, dpi=110)
    return path
