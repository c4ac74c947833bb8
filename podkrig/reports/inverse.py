"""Figures of an inversion: fit, region of equivalence, RVC, posterior (matplotlib, imported lazily).

Every function takes result objects, draws on a new figure, saves it to ``path`` (PNG) and returns
the path. Units on every axis.
"""

from pathlib import Path

import numpy as np

from podkrig.online.findings import RESIDUAL_CONVENTION, chi2_basis
from podkrig.reports.findings import fe_difference, words
from podkrig.reports.figures import pyplot, save
from podkrig.reports.flat_jack import jack_pressures
from podkrig.reports.ga import plot_history, plot_parameters, plot_statistics
from podkrig.reports.html import Page, fmt, num, pct, unit_cell


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


def plot_fit(result, path, *, load_unit="kN", steps=None):
    """Measured and fitted readings per sensor, load on the vertical axis (the convention of test
    reports: reading (mm) across, load up), measured with ±2σ noise bars, the calibrated surrogate
    as a line with its ±2σ band.

    ``steps`` (a flat-jack test's ``scenario.steps``, its load levels being step numbers): the
    vertical axis is the jack pressure (MPa) that drives each step's phase instead
    (:func:`~podkrig.reports.flat_jack.jack_pressures`), one colour and one line per phase."""
    plt = pyplot()
    meas = result.problem.measurement
    pred, std = result.predicted()
    sd = meas.grid(result.problem.misfit.noise_std)  # NaN where a reading is missing
    n = len(meas.sensor_names)
    cols = min(n, 3)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), squeeze=False)
    if steps is None:
        load = np.asarray(meas.load_levels, float)
        groups = [(np.ones(len(load), bool), "k", "tab:red", "")]
        ylabel = f"load ({load_unit})"
    else:
        load, phases, labels = jack_pressures(steps, meas.load_levels)
        groups = [(phases == ph, f"C{k}", f"C{k}", labels[ph]) for k, ph in enumerate(labels) if (phases == ph).any()]
        ylabel = "jack pressure (MPa)"
    for j, name in enumerate(meas.sensor_names):
        ax = axes.flat[j]
        for sel, colour, line_colour, label in groups:  # with steps: the phase names the points, by colour
            ax.errorbar(meas.values[sel, j], load[sel], xerr=2 * sd[sel, j], fmt="o", color=colour, ms=4, capsize=3,
                        label=label or "measured ±2σ noise")
            ax.plot(pred[sel, j], load[sel], "-", color=line_colour,
                    label=None if label else "calibrated model (surrogate)")
            if std is not None:
                ax.fill_betweenx(load[sel], pred[sel, j] - 2 * std[sel, j], pred[sel, j] + 2 * std[sel, j],
                                 color=line_colour, alpha=0.2, label=None if label else "surrogate ±2σ")
        ax.set_title(name)
        ax.set_xlabel(f"{name} reading (mm)")
        ax.set_ylabel(ylabel)
        ax.locator_params(axis="x", nbins=4)  # µm-size readings: few, readable ticks
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4))
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    if steps is not None:  # what the marks are, once: points measured (±2σ), lines the surrogate (±2σ band)
        axes.flat[0].plot([], [], "o", color="0.4", label="measured ±2σ noise")
        axes.flat[0].plot([], [], "-", color="0.4", label="calibrated model (surrogate)" + ("" if std is None else " ±2σ"))
    axes.flat[0].legend(fontsize=7)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def plot_residuals(result, path, *, load_unit="kN", steps=None):
    """Standardised residuals (measured − model)/σ (:data:`RESIDUAL_CONVENTION`) per sensor and load
    level, as a heat map with its colour bar; with a flat-jack test's ``steps``, each row named by
    its step, phase and driving jack pressure (MPa)."""
    plt = pyplot()
    meas = result.problem.measurement
    pred, _ = result.predicted()
    sd = meas.grid(result.problem.misfit.noise_std)  # NaN where a reading is missing
    z = (meas.values - pred) / sd
    fig, ax = plt.subplots(figsize=(1.2 + 0.9 * len(meas.sensor_names), 1.2 + 0.5 * len(meas.load_levels)))
    lim = max(3.0, float(np.abs(z).max()))
    im = ax.imshow(z, cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="auto")
    ax.set_xticks(range(len(meas.sensor_names)), meas.sensor_names, rotation=45)
    if steps is not None:
        pressure, phases, _ = jack_pressures(steps, meas.load_levels)
        names = [f"step {v:g} (phase {ph}, {p:g} MPa)" for v, ph, p in zip(meas.load_levels, phases, pressure)]
    else:
        names = [f"step {v:g}" if load_unit == "step" else f"{v:g} {load_unit}" for v in meas.load_levels]
    ax.set_yticks(range(len(meas.load_levels)), names)
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


#: most outputs of one validation model drawn as distributions (the table lists them all)
MAX_DISTRIBUTION_PANELS = 8


def is_validation(model_name):
    """Whether an RVC result of a calibration is a validation model's (not ``calibration``/``calibration.TEST``)."""
    return model_name != "calibration" and not model_name.startswith("calibration.")


def distribution_file(model_name):
    """The file name of a validation model's distribution figure (:func:`plot_rvc_distributions`)."""
    return f"rvc_{model_name}.png"


def plot_rvc_distribution(res, path, title):
    """The distribution of each output of one RVC (a validation model's capacity: ``F_peak`` in kN,
    ``d_peak`` in mm) over the region of equivalence: one panel per output (the first
    :data:`MAX_DISTRIBUTION_PANELS`), a density histogram of the values at the members with a
    Gaussian kernel density estimate, the mean and the quantiles (:attr:`RVCResult.quantiles`) as
    vertical lines, and the FE validation runs at region members that did not fail as ticks
    along the axis."""
    from scipy.stats import gaussian_kde

    plt = pyplot()
    n = min(len(res.outputs), MAX_DISTRIBUTION_PANELS)
    fig, axes = plt.subplots(1, n, figsize=(4.4 * n, 4.6), squeeze=False)
    runs = res.runs
    for k, ax in enumerate(axes[0]):
        v = res.values[:, k]
        unit = res.units[k]
        ax.hist(v, bins=min(40, max(10, len(v) // 50)), density=True, color="0.8", edgecolor="0.6", lw=0.5,
                label=f"{res.n_samples} region members")
        if np.ptp(v) > 1e-12 * max(abs(float(res.mean[k])), 1e-300):
            grid = np.linspace(v.min(), v.max(), 200)
            ax.plot(grid, gaussian_kde(v)(grid), color="C0", lw=1.2, label="kernel density")
        ax.axvline(res.mean[k], color="k", lw=1.2, label=f"mean {res.mean[k]:.4g} {unit}, CV {100 * res.cv[k]:.2g} %")
        for j, q in enumerate(res.quantile_levels):
            ax.axvline(res.quantiles[j, k], color="C3", ls="--", lw=1,
                       label=f"{100 * q:g} % quantile {res.quantiles[j, k]:.4g} {unit}")
        if runs is not None and runs.n_runs:
            ok = ~runs.failed
            ax.plot(runs.fe[ok, k], np.zeros(int(ok.sum())), "|", color="C2", ms=14, mew=1.5,
                    label=f"FE runs at members ({int(ok.sum())} of {runs.n_runs} did not fail)")
        ax.set_xlabel(_label(res.outputs[k], unit))
        ax.set_ylabel(f"density (1/{unit})" if unit and unit != "-" else "density (-)")
        ax.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2, frameon=False)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def plot_rvc_distributions(rvc_results, folder):
    """:func:`plot_rvc_distribution` of each validation model of a calibration's RVC results into
    ``folder``; returns ``{model name: file name}`` (:func:`distribution_file`)."""
    drawn = {}
    for name, res in rvc_results.items():
        if is_validation(name) and res.values is not None:
            plot_rvc_distribution(res, Path(folder) / distribution_file(name),
                                  f"validation model {name}: distribution over the region of equivalence")
            drawn[name] = distribution_file(name)
    return drawn


# --------------------------------------------------------------------------------------------
# the renderers of a calibration (CalibrationResult), shared by the inversion report of the CLI
# and the study report: each writes one part on a Page, from the result objects alone


def render_parameters(page, calibration, caption="Identified parameters"):
    """The identified parameters: best fit, region of equivalence, identified or not, share of the
    search range, and the MCMC credible interval when there is a posterior."""
    inv, region, posterior = calibration.inversion, calibration.region, calibration.posterior
    units = dict(zip(inv.free, inv.units))
    rows = []
    for j, name in enumerate(inv.free):
        lo, hi = region.intervals[name]
        ident = region.identifiability[name]
        row = [name, unit_cell(units[name]), num(float(inv.x[j])), f"[{num(lo)}, {num(hi)}]",
               "yes" if ident["identifiable"] else "NO", f"{100 * ident['share']:.0f}"]
        if posterior is not None:
            row.append(f"[{num(posterior.intervals[name][0])}, {num(posterior.intervals[name][1])}]")
        rows.append(row)
    page.table(["parameter", "unit", "best fit", f"region of equivalence ({100 * region.confidence:.0f} %)",
                "identified", "share of search range (%)"]
               + (["MCMC credible interval"] if posterior is not None else []), rows, caption=caption)


def render_joint(page, inv):
    """A joint calibration's fit: the shared and per-test parameters, and each test's share of the
    misfit."""
    units = dict(zip(inv.free, inv.units))
    page.paragraph("One set of parameters fitted to every test at once: the misfit is the sum of the tests' "
                   "misfits (thesis eq. 2.13 per test, independent noise between tests).")
    page.table(["parameter", "unit", "best fit", "tests that depend on it"],
               [[n, unit_cell(units[n]), num(v), ", ".join(t for t, one in inv.tests.items() if n in one.free)]
                for n, v in inv.free_parameters.items()])
    page.table(["test", "readings", "χ² (-)", "dof", "χ²/dof (-)", "χ² includes"],
               [[name, one.measurement["n_obs"], num(one.chi2), one.dof, num(one.chi2_dof, 3), one.chi2_basis]
                for name, one in inv.tests.items()]
               + [["all tests", inv.measurement["n_obs"], num(inv.chi2), inv.dof, num(inv.chi2_dof, 3),
                   inv.chi2_basis]],
               caption="Each test's share of the joint fit")


def render_fit(page, inv, folder="", deformed=False):
    """One test's fit: its data, its parameters, misfit and χ² (with what C_D includes), the FE
    check at the optimum, and the fit and residual figures (``folder``: where they are, relative
    to the page), with the deformed specimen when ``deformed``."""
    m = inv.measurement
    page.paragraph(
        f"Data: {m['file']} ({m['n_obs']} readings: gauges {', '.join(m['sensors'])} at "
        f"{', '.join(f'{v:g}' for v in m['load_levels'])} {m['load_unit']})."
    )
    units = dict(zip(inv.free, inv.units))
    page.table(["parameter", "unit", "best fit"], [[n, unit_cell(units[n]), num(v)] for n, v in inv.free_parameters.items()])
    page.table(["misfit ω (-)", "χ² (-)", "degrees of freedom", "χ²/dof (-)", "χ² includes", "surrogate evaluations",
                "time (s)"],
               [[num(inv.misfit), num(inv.chi2), inv.dof, num(inv.chi2_dof, 3), inv.chi2_basis, inv.n_evaluations,
                 num(inv.seconds, 3)]])
    fe = inv.fe_check
    if fe is not None:
        page.table(["max |FE − surrogate|", "max |FE − surrogate| / σ (-)", "relative difference (-)",
                    "χ²/dof of the FE model (-)", "χ² includes"],
                   [[fe_difference(fe.max_abs_diff_by_unit, fe.max_abs_diff), num(fe.max_diff_over_noise, 3), num(fe.rel_diff, 3),
                     num(fe.chi2_dof_fe, 3), chi2_basis("fe_check")]],
                   caption="FE check at the best fit")
        if fe.ok:
            page.success("At the best fit the surrogate agrees with the FE model within the measurement noise.")
    up = ("the jack pressure driving each phase (MPa) up, one colour per phase" if m["load_unit"] == "step"
          else "load up")
    page.figure(f"{folder}fit.png", "Measured readings (±2σ noise) and the calibrated surrogate with its ±2σ band: "
                                    f"reading (mm) across, {up}, one panel per gauge.")
    page.figure(f"{folder}residuals.png", f"Standardised residuals {RESIDUAL_CONVENTION} of the surrogate at the best "
                                          "fit, per gauge and load level, with their colour scale (-).")
    if deformed:
        page.figure(f"{folder}deformed.png", "FE model at the best fit, last load level: left the deformed mesh "
                                             "(magnified, with a length and a displacement scale bar), right the "
                                             "displacement magnitude |u| (mm).")


def render_ga(page):
    """The GA's figures (``ga_history.png``, ``ga_parameters.png``)."""
    page.figure("ga_history.png", "Genetic algorithm: every evaluated misfit by generation with the reported "
                                  "optimum's misfit (dashed), and population statistics (thesis Fig. 3.17).")
    page.figure("ga_parameters.png", "Genetic algorithm: parameter values of the evaluated individuals against misfit, "
                                     "coloured by generation, with the reported optimum (star on a dashed line; dotted: "
                                     "the GA's own best before the least-squares polish, where it differs) (log axes "
                                     "for log-sampled parameters; thesis Fig. 3.23).")


def render_region(page, region, posterior=None):
    """The region of equivalence: how it was built, its per-parameter intervals and identifiability,
    its figure (``region.png``), and the posterior's convergence when there is one."""
    page.paragraph(
        f"Parameter vectors whose misfit is statistically indistinguishable from the best fit "
        f"({region.method}, confidence {100 * region.confidence:.0f} %; {len(region.samples)} members of "
        f"{region.n_evaluated} surrogate evaluations, {region.seconds:.2f} s)."
    )
    rows = []
    for j, name in enumerate(region.names):
        lo, hi = region.intervals[name]
        ident = region.identifiability[name]
        rows.append([name, unit_cell(region.units[j]), num(lo), num(hi), f"{100 * ident['share']:.0f}",
                     "yes" if ident["identifiable"] else "NO"])
    page.table(["parameter", "unit", "low", "high", "share of search range (%)", "identified"], rows)
    page.figure("region.png", "2-D projections of the region of equivalence, with the best fit (star)"
                + (" and MCMC posterior samples." if posterior is not None else "."))
    if posterior is not None:
        page.table(["MCMC steps", "acceptance (-)", "max autocorrelation time (steps)", "effective samples",
                    "max R̂ (-)", "converged"],
                   [[posterior.n_steps, fmt(posterior.acceptance), fmt(float(np.max(posterior.autocorr_time))),
                     fmt(posterior.effective_samples), fmt(float(np.max(posterior.r_hat))),
                     "yes" if posterior.converged else "NO"]])
        if not posterior.converged:
            page.warning("the MCMC chains have not converged (chain shorter than 50 autocorrelation times or R̂ ≥ "
                         "1.05).", "sample longer before reading the credible intervals.")


def _failure_reasons(runs):
    """The failed runs of a :class:`~podkrig.online.propagation.ValidationRuns` by reason — the
    solver status with its budget limit, the FE error's type, or no load maximum — as
    ``{reason: (count, one message)}``, in order of first occurrence."""
    out = {}
    for status, no_peak, message in zip(runs.status, runs.no_peak, runs.messages):
        if no_peak:
            reason = "no load maximum"
        elif status == "error":
            reason = f"FE error {message.split(':')[0]}"
        elif status != "converged":
            reason = message.split(",")[0]  # "budget_exhausted: steps"
        else:
            continue
        n, example = out.get(reason, (0, message))
        out[reason] = (n + 1, example)
    return out


def render_rvc(page, rvc_results, intro="", figures=None):
    """The response variability of each model over the region: per output its unit, mean, CV,
    quantiles, range and (max − min)/mean, the figure (``rvc.png``), and for each validation model
    its FE runs at region members (the share that failed, FE against the distribution) and its
    distribution figure (``figures``: model name → file, :func:`plot_rvc_distributions`)."""
    page.paragraph(
        "How much the predictions of the calibration model and of the validation models vary over the region of "
        "equivalence: a small coefficient of variation (CV) means the calibration pins down what these tests show. "
        "Each distribution is the surrogate of its model evaluated at the region's members; the quantiles bound "
        "the band the calibration predicts." + intro)
    levels = next(iter(rvc_results.values())).quantile_levels if rvc_results else ()
    rows = []
    for model, x in rvc_results.items():
        for k, out in enumerate(x.outputs):
            rows.append([model, out, unit_cell(x.units[k]), num(float(x.mean[k])), pct(x.cv[k]),
                         *(num(float(x.quantiles[j, k])) if x.quantile_levels == levels else "—"
                           for j in range(len(levels))),
                         num(float(x.min[k])), num(float(x.max[k])), pct(x.range_ratio[k])])
    page.table(["model", "output (sensor@load)", "unit", "mean", "CV (%)", *(f"{100 * q:g} % quantile" for q in levels),
                "min", "max", "(max − min)/mean (%)"], rows)
    page.figure("rvc.png", "Spread of each output over the region of equivalence, relative to its mean.")
    runs = [(model, x) for model, x in rvc_results.items() if x.runs is not None]
    if runs:
        page.paragraph(
            "FE runs of the validation models at a seeded subsample of the region's members. A run failed when it "
            "stopped early (a step, iteration or CPU budget exhausted, no convergence, an FE error) or when its load "
            "had no maximum within the control range (its peak in the last control interval: no capacity): the failed "
            "share is the "
            "share of the validation model's runs over the region that give no capacity. The runs that did not fail "
            "check the surrogate's distribution: about the band's share of them should fall inside it.")
        rows = []
        for model, x in runs:
            r = x.runs
            ok = ~r.failed
            inside = (r.fe[ok] >= x.quantiles[0]) & (r.fe[ok] <= x.quantiles[-1])  # (n_ok, n_outputs)
            diff = r.relative_difference()
            rows.append([model, r.n_runs, int(r.stopped.sum()), int(r.no_peak.sum()), pct(r.failed_share),
                         ", ".join(f"{o}: {int(n)} of {int(ok.sum())}" for o, n in zip(x.outputs, inside.sum(axis=0))),
                         pct(float(diff.max())) if diff.size else "—"])
        page.table(["model", "FE runs", "stopped early", "no load maximum", "failed share (%)",
                    "FE runs inside the band of the lowest and highest quantile",
                    "max |FE − surrogate| / |FE| (%)"], rows, caption="Validation runs at region members")
        for model, x in runs:
            why = _failure_reasons(x.runs)
            if why:
                page.paragraph(f"{model}: why runs failed: " + "; ".join(
                    f"{n} × {reason} (e.g. {example})" for reason, (n, example) in why.items()) + ".", "meta")
    for model, filename in (figures or {}).items():
        page.figure(filename, f"Validation model {model}: distribution of each output over the region of "
                              "equivalence (histogram and kernel density; mean and quantiles as lines; FE runs "
                              "at members as ticks).")


def write_inversion_report(out_dir, calibration, *, load_unit="kN", noise_text="", rvc=True):
    """Write ``out_dir/index.html`` with the figures of a calibration; returns the page path.

    Parameters
    ----------
    out_dir : Path
    calibration : podkrig.online.calibrate.CalibrationResult
        As :func:`~podkrig.online.calibrate.calibrate` returned it (its inversion with its
        problem, the region with its members, the RVC results with their values).
    load_unit : str
    noise_text : str
        The noise model in words.
    rvc : bool
        Show the RVC section.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    result, region, posterior = calibration.inversion, calibration.region, calibration.posterior
    problem = result.problem
    page = Page("podkrig inversion report")
    page.paragraph(
        f"Noise: {noise_text}. Free parameters: {', '.join(problem.free)}; fixed: "
        + (", ".join(f"{k} = {v:g}" for k, v in problem.fixed.items()) or "none") + ".",
        "meta",
    )
    for f in words(calibration.findings, "cli"):
        page.warning(f.message, f.remedy)
    page.heading("Identified parameters")
    render_parameters(page, calibration)
    page.heading("Fit to the measurements")
    # a flat-jack test: readings against the jack pressure of each phase (its steps, from the spec)
    steps = getattr(problem.model.scenario(), "steps", None) if load_unit == "step" else None
    plot_fit(result, out / "fit.png", load_unit=load_unit, steps=steps)
    plot_residuals(result, out / "residuals.png", load_unit=load_unit, steps=steps)
    render_fit(page, result)
    page.heading("Region of equivalence")
    plot_region(region, out / "region.png", best=result.x, posterior=posterior, space=problem.free_space)
    render_region(page, region, posterior)
    if rvc:
        page.heading("Response variability (RVC)")
        plot_rvc(calibration.rvc, out / "rvc.png")
        render_rvc(page, calibration.rvc, figures=plot_rvc_distributions(calibration.rvc, out))
    page.heading("Genetic algorithm")
    plot_ga_history(result, out / "ga_history.png")
    plot_ga_parameters(result, out / "ga_parameters.png")
    render_ga(page)
    return page.write(out / "index.html")


def plot_ga_history(inversion, path):
    """The GA of an inversion (:class:`~podkrig.online.invert.InverseResult`): every evaluated
    misfit by generation with the reported optimum's misfit, and population statistics."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    plot_history(inversion.ga, ax=axes[0], optimum=inversion.misfit)
    plot_statistics(inversion.ga, ax=axes[1])
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def plot_ga_parameters(inversion, path):
    """Parameter values of the GA's evaluated individuals against their misfit, coloured by
    generation, with the inversion's reported optimum (after its least-squares polishes: ``x``,
    ``misfit``) marked and the GA's own best where it differs; a log axis for each parameter the
    search space samples on a log scale."""
    pyplot()
    space = inversion.problem.free_space
    axes = plot_parameters(inversion.ga, xscale=list(space.scales), optimum=(inversion.x, inversion.misfit))
    save(axes[0].figure, path, dpi=110)
    return path
