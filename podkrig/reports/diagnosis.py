"""Figures and the HTML page of a model diagnosis (:func:`podkrig.diagnosis.diagnose`).

The residuals are drawn on the specimen: the wall's joints, the supports, every sensor coloured
(gauges, point sensors) or drawn as an arrow (pairs of x/y displacement channels, e.g. DIC) by its
standardised residual (measured − model)/σ at the highest load level, before and after the
extension; the named cause's location is marked.
"""

import json
from pathlib import Path

import numpy as np

from fe.mesh.mesh import INTERFACE_KINDS
from podkrig.diagnosis.results import CHI2_ALPHA_SHARE
from podkrig.online.findings import RESIDUAL_CONVENTION
from podkrig.reports.figures import colourbar, load_label, pyplot, save
from podkrig.reports.flat_jack import shade_phases
from podkrig.reports.html import Page, fmt


def _channel_geometry(scenario):
    """Channel name → ("gauge", p1, p2) or ("point", xy, component)."""
    geometry = {}
    for s in scenario.sensors:
        kind = getattr(s, "kind", None)
        if kind == "gauge":
            geometry[s.name] = ("gauge", np.asarray(s.p1, float), np.asarray(s.p2, float))
        elif kind == "point":
            geometry[s.name] = ("point", np.asarray(s.point, float), s.component)
        else:  # a grid of points, channels ".ux", ".uy" per point
            points = s.points
            for k, name in enumerate(s.channel_names):
                geometry[name] = ("point", points[k // 2], name[-1])
    return geometry


def _draw_wall(ax, scenario):
    mesh = scenario.mesh
    for kind, colour, width in (("bed", "#999", 0.6), ("head", "#999", 0.6)):
        conn = mesh.interfaces[mesh.interface_kind == INTERFACE_KINDS.index(kind)]
        for e in conn:
            p, q = mesh.nodes[e[0]], mesh.nodes[e[1]]
            ax.plot([p[0], q[0]], [p[1], q[1]], color=colour, lw=width, zorder=1)
    ax.plot([0, mesh.width, mesh.width, 0, 0], [0, 0, mesh.height, mesh.height, 0], color="#444", lw=1.0, zorder=1)
    sup = mesh.nodes[np.asarray(getattr(scenario, "supported_nodes", []), dtype=int)]
    if len(sup):
        ax.plot(sup[:, 0], sup[:, 1], "^", color="#555", ms=3, zorder=2, label="supported nodes")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")


def _mark_causes(ax, diagnosis):
    for cause in diagnosis.causes:
        _mark_cause(ax, diagnosis, cause)


def unnamed_significant(d):
    """Of a diagnosis's JSON ``d`` with no cause named: its candidates whose corrected
    likelihood-ratio test is significant, as text ("gauge_fault at sensor D2, gain (corrected p =
    0.003)"), "" when none is."""
    level = d["adequacy"]["alpha"]  # the adequacy gate's level, that of its χ² test
    found = [c for c in d["candidates"] if c["applicable"] and c["p_corrected"] < level]
    return "; ".join(f"{c['name']} at {c['location']} (corrected p = {c['p_corrected']:.2g})" for c in found)


def _mark_cause(ax, diagnosis, cause):
    d = cause.location.detail
    if cause.name == "weak_joint":
        ax.plot(d["x"], d["y"], color="red", lw=4, alpha=0.8, zorder=5, label=f"weak joint (f = {cause.value:.3g})")
    elif cause.name == "weak_joint_strength":
        ax.plot(d["x"], d["y"], color="red", lw=4, alpha=0.8, zorder=5, label=f"weaker joint (s = {cause.value:.3g})")
    elif cause.name in ("gauge_fault", "gauge_slip"):
        geom = _channel_geometry(diagnosis.scenario).get(d["sensor"])
        if geom is not None:
            xy = 0.5 * (geom[1] + geom[2]) if geom[0] == "gauge" else geom[1]
            what = "faulty" if cause.name == "gauge_fault" else "slipped"
            ax.plot(*xy, "o", ms=16, mfc="none", mec="red", mew=2, zorder=6, label=f"{what} sensor {d['sensor']}")
    elif cause.name == "nonlinearity_onset":
        xy = np.array([[j["x"], j["y"]] for j in d["joints"]])
        ax.plot(xy[:, 0], xy[:, 1], "x", color="red", ms=12, mew=3, zorder=6,
                label=f"first cracking/sliding joints (from {d['load']:g} {d['unit']})")
    elif cause.name == "support_compliance":
        sup = diagnosis.scenario.mesh.nodes[np.asarray(diagnosis.scenario.supported_nodes, dtype=int)]
        ax.plot(sup[:, 0], sup[:, 1], "s", color="red", ms=5, zorder=6, label="compliant supports")


def plot_residuals_on_specimen(diagnosis, path):
    """Standardised residuals at the highest load level drawn on the specimen, before and after:
    gauges coloured by their residual, x/y displacement pairs (point sensors, DIC) as arrows of the
    residual vector (same scale in both panels)."""
    plt = pyplot()
    fits = [("base model", diagnosis.base)]
    if diagnosis.extended is not None:
        fits.append((f"extended: {' + '.join(c.name for c in diagnosis.causes)}", diagnosis.extended))
    fig, axes = plt.subplots(1, len(fits), figsize=(6.2 * len(fits), 6.0), squeeze=False)
    geometry = _channel_geometry(diagnosis.scenario)
    m = diagnosis.measurement
    top = int(np.argmax(m.load_levels))
    residuals = [diagnosis.residuals(f)[top] for _, f in fits]
    vmax = max(3.0, float(np.max(np.abs(residuals[0]))))
    norm = plt.Normalize(-vmax, vmax)
    cmap = plt.get_cmap("coolwarm")
    size = max(diagnosis.scenario.mesh.width, diagnosis.scenario.mesh.height)
    pairs = [abs(r) for name, r in zip(m.sensor_names, residuals[0]) if geometry.get(name, ("",))[0] == "point"]
    largest = max(pairs, default=1.0)
    arrow_scale = 0.1 * size / max(largest, 1e-12)  # mm of drawing per σ: the largest arrow is 10 % of the wall
    key_sigma = float(f"{largest / 2:.1g}") or 1.0
    for ax, (title, _), res in zip(axes[0], fits, residuals):
        _draw_wall(ax, diagnosis.scenario)
        values = dict(zip(m.sensor_names, res))
        arrows, short = {}, []
        for name, r in values.items():
            geom = geometry.get(name)
            if geom is None:
                continue
            if geom[0] == "gauge":
                ax.plot([geom[1][0], geom[2][0]], [geom[1][1], geom[2][1]], color=cmap(norm(r)), lw=4, zorder=4)
                if np.linalg.norm(geom[2] - geom[1]) >= 0.15 * size:
                    ax.annotate(f"{name} {r:+.1f}", geom[2], fontsize=7, zorder=7, xytext=(3, 3), textcoords="offset points")
                else:  # short gauges crowd each other: listed in a box
                    short.append(f"{name} {r:+.1f}")
            else:
                arrows.setdefault(tuple(np.round(geom[1], 6)), {})[geom[2]] = r
        if arrows:
            xy = np.array(list(arrows))
            ux = np.array([a.get("x", 0.0) for a in arrows.values()])
            uy = np.array([a.get("y", 0.0) for a in arrows.values()])
            q = ax.quiver(xy[:, 0], xy[:, 1], ux * arrow_scale, uy * arrow_scale, color="k", angles="xy",
                          scale_units="xy", scale=1.0, width=0.004, zorder=4)
            ax.quiverkey(q, 0.82, 1.02, key_sigma * arrow_scale, f"{key_sigma:g}σ", labelpos="E", coordinates="axes",
                         fontproperties={"size": 8})
            ax.plot(xy[:, 0], xy[:, 1], ".", color="#555", ms=2, zorder=3)
        if short:
            ax.text(0.98, 0.02, "short gauges (σ):\n" + "\n".join(short), transform=ax.transAxes, fontsize=7,
                    ha="right", va="bottom", bbox={"fc": "white", "ec": "#999"}, zorder=8)
        if title != "base model":
            _mark_causes(ax, diagnosis)
        chi = np.sum(res**2)
        ax.set_title(f"{title}\nresiduals at {m.load_levels[top]:g} {diagnosis.scenario.load_unit} (Σr² = {chi:.1f})", fontsize=10, pad=16)
        handles, _ = ax.get_legend_handles_labels()
        if handles:
            ax.legend(fontsize=7, loc="upper left")
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    colourbar(fig, sm, axes[0].tolist(), shrink=0.7, label=f"gauge residual {RESIDUAL_CONVENTION} (-)")
    save(fig, path, dpi=110)
    return path


def plot_residuals_vs_load(diagnosis, path, max_channels=12):
    """Standardised residuals against load for the channels with the largest base residuals."""
    plt = pyplot()
    m = diagnosis.measurement
    rb = diagnosis.residuals(diagnosis.base)
    re = None if diagnosis.extended is None else diagnosis.residuals(diagnosis.extended)
    order = np.argsort(-np.sum(rb**2, axis=0))[:max_channels]
    n = len(order)
    cols = min(4, n)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.5 * rows), squeeze=False, sharex=True)
    for ax, j in zip(axes.ravel(), order):
        ax.axhspan(-2, 2, color="#eee")
        ax.plot(m.load_levels, rb[:, j], "o-", color="C3", label="base")
        if re is not None:
            ax.plot(m.load_levels, re[:, j], "s--", color="C0", label="extended")
        ax.axhline(0, color="k", lw=0.6)
        ax.set_title(m.sensor_names[j], fontsize=9)
        if getattr(diagnosis.scenario, "steps", None):  # a flat-jack test: steps, its phases shaded
            shade_phases(ax, diagnosis.scenario, labels=False)
        ax.set_xlabel(load_label(diagnosis.scenario.load_unit))
        ax.set_ylabel(f"{RESIDUAL_CONVENTION} (-)")
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def candidate_evidence(diagnosis):
    """(name, evidence) of each applicable candidate with some evidence: −log10 of its
    multiplicity-corrected p-value, capped at 50; empty when no candidate improves the fit at all."""
    cands = [c for c in diagnosis.candidates if c.applicable]
    scores = [(c.name, min(-c.log10_p_corrected, 50.0)) for c in cands]
    return scores if any(v > 1e-9 for _, v in scores) else []


def plot_candidate_scores(diagnosis, path):
    """Evidence of each candidate: −log10 of its multiplicity-corrected p-value, with the α line.
    Returns None (and draws nothing) when no candidate has any evidence
    (:func:`candidate_evidence` is empty): the page says so in words instead of an empty chart."""
    scores = candidate_evidence(diagnosis)
    if not scores:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 0.5 * len(scores) + 1.2))
    colours = ["C3" if (diagnosis.cause == name) else "C0" for name, _ in scores]
    ax.barh([n for n, _ in scores][::-1], [v for _, v in scores][::-1], color=colours[::-1])
    ax.axvline(-np.log10(diagnosis.alpha), color="k", ls="--", label=f"α = {diagnosis.alpha:g}")
    ax.set_xlabel("evidence −log10(corrected p) (-), capped at 50")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save(fig, path, dpi=110)
    return path


def chi2_level_text():
    """The level of the χ² test in terms of the one significance level α of the settings
    (``[diagnosis] alpha``): a share of α, never a second α."""
    return f"χ² test at α × {CHI2_ALPHA_SHARE:g}"


def fitted_parameter_text(candidate, alpha):
    """``"f = 0.066 -"`` for a candidate's fitted parameter, with a caveat when the candidate is not
    significant (its fitted value then only says where the fit went, not that the effect exists)."""
    par = candidate["parameter"]
    text = f"{par['name']} = {fmt(par['value'])} {par['unit']}".rstrip(" -")
    if candidate["p_corrected"] >= alpha:
        text += " (not significant: not evidence of the effect)"
    return text


def write_diagnosis_report(diagnosis, out_dir, *, noise_text=""):
    """Write ``out_dir/index.html`` and its figures; returns the page path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    d = diagnosis.to_dict()
    m, sc = diagnosis.measurement, diagnosis.scenario
    page = Page("podkrig model diagnosis")
    page.paragraph(
        f"Scenario {sc.name}; data {m.source} ({m.n_obs} readings, {len(m.sensor_names)} sensors at "
        f"{', '.join(f'{v:g}' for v in m.load_levels)} {sc.load_unit}); noise: {noise_text or 'as given'}. "
        f"Base model's free parameters: {', '.join(d['base']['parameters'])}. "
        f"{d['n_fe_runs']} FE runs, {d['seconds']:.1f} s.", "meta")

    page.heading("Verdict")
    page.paragraph(f"χ² here: {d['adequacy']['basis']}. The inversion's χ²/dof (surrogate, with its variance C_T) "
                   "and the FE check's (data noise only) differ from it by what their C_D holds and by the fit.",
                   "meta")
    if d["verdict"] == "adequate":
        page.success(
            f"The calibrated base model explains the data within the noise: χ²/dof = {d['adequacy']['chi2_dof']:.2f} "
            f"(p = {d['adequacy']['p_value']:.3g}) and no candidate cause improves the fit significantly at α = {d['adequacy']['alpha']:g} (the χ² test's level) "
            "after correcting for the number of candidates and locations tried.")
    elif d["cause"] is None and unnamed_significant(d):
        page.warning(
            f"The base model misses something (χ²/dof = {d['adequacy']['chi2_dof']:.2f}, p = {d['adequacy']['p_value']:.2g}): "
            f"a candidate cause improves the fit significantly ({unnamed_significant(d)}) "
            f"at α = {d['adequacy']['alpha']:g} (the χ² test's level) after correcting for the number of candidates and locations tried, "
            "but what is left of the effect after refitting the base parameters is too small or too diffuse to name "
            "as a cause: no candidate explains the data.",
            "look at the residual pattern below; a longer load range, more load levels or a sensor near the "
            "candidate's location would tell whether the effect is real.")
    elif d["cause"] is None:
        page.warning(
            f"The base model does not explain the data (χ²/dof = {d['adequacy']['chi2_dof']:.2f}, p = {d['adequacy']['p_value']:.2g}), "
            "and no candidate cause in the library explains the residual.",
            "check the noise level and the measurement file; look at the residual pattern below for an effect outside the library "
            "(nonlinearity, a different test set-up), and extend the model accordingly.")
    else:
        det = d["detail"]
        named = "; ".join(f"{c['cause']} at {c['location']} ({c['parameter']} = {fmt(c['value'])} {c['unit']}, "
                          f"neutral {fmt(c['neutral'])})" for c in d["causes"])
        page.warning(
            f"The base model does not explain the data. {'Cause' if len(d['causes']) == 1 else 'Causes, in the order found'}: "
            f"{named}.",
            "check the named effects on the specimen or the set-up; if confirmed, calibrate with the extended model "
            "(its parameters are below) or repair the causes and test again.")
        if not d["extended"]["fully_explained"]:
            page.warning(
                f"The extended model still does not explain the data (χ²/dof = {d['extended']['chi2_dof']:.2f}): "
                "an effect outside the candidate library (or more causes than the search allows) may be missing.",
                "look at the residual pattern of the extended model below for what remains.")
        if det["alternatives"]:
            page.warning(
                "The data cannot tell this cause apart from: " + "; ".join(f"{a['cause']} at {a['location']}" for a in det["alternatives"]) + ".",
                "add a sensor that separates them (e.g. near the named location) or inspect both on the specimen.")

    page.heading("Residuals on the specimen")
    panels = ("left the calibrated base model, right the extended model with the named cause marked"
              if diagnosis.extended is not None else "the calibrated base model (no cause named, so no extended model)")
    page.figure(Path(plot_residuals_on_specimen(diagnosis, out / "residuals_specimen.png")).name,
                f"Standardised residuals {RESIDUAL_CONVENTION} at the highest load: gauges coloured, displacement pairs "
                f"as arrows; {panels}.")
    page.figure(Path(plot_residuals_vs_load(diagnosis, out / "residuals_load.png")).name,
                "Standardised residuals against load for the channels with the largest base residuals (grey band: ±2σ).")
    st = d["residual_structure"]
    rows = sorted(st["per_sensor"].items(), key=lambda kv: -kv[1]["chi2_share"])[:15]
    page.table(["sensor", "share of χ² (%)", "growth with load (corr., -)", "residuals at each load (σ)"],
               [[s, fmt(100 * v["chi2_share"]), "—" if v["growth_with_load"] is None else fmt(v["growth_with_load"]),
                 ", ".join(f"{x:+.1f}" for x in v["standardised"])] for s, v in rows],
               caption="Where the base model's residual sits (largest shares first).")

    page.heading("Candidate causes")
    scores = plot_candidate_scores(diagnosis, out / "candidates.png")
    if scores is None:
        (out / "candidates.png").unlink(missing_ok=True)  # a chart of an earlier run must not stay beside the page
        page.paragraph("Nothing significant: no candidate cause improves the fit at all (every Δχ² is 0), so there "
                       "is no evidence to chart.")
    else:
        page.figure(Path(scores).name,
                    "Evidence for each candidate at its best location; bars beyond the dashed line are significant.")
        if d["cause"] is None:
            page.paragraph(f"Nothing significant: no bar reaches the dashed line (α = {diagnosis.alpha:g}).")
    crow = []
    for c in d["candidates"]:
        if not c["applicable"]:
            crow.append([c["name"], "not applicable: " + c["reason"], "", "", "", "", ""])
            continue
        crow.append([c["name"], c["location"], fitted_parameter_text(c, diagnosis.alpha), c["n_locations"],
                     fmt(c["delta_chi2"]), f"{c['p_corrected']:.2g}",
                     "yes" if c["visible"] else "no: these sensors cannot see it"])
    page.table(["candidate", "best location", "fitted parameter", "locations tried", "Δχ² (-)", "corrected p (-)",
                "visible"], crow)
    for c in d["candidates"]:
        if c["applicable"]:
            page.paragraph(f"{c['name']}: {c['description']} Signature: {c['signature']}")

    if d["gain"] is not None and d["gain"]["steps"]:
        page.heading("Causes found in turn")
        page.table(["step", "cause added", "location", "fitted parameter", "χ² before → after (-)", "corrected p (-)",
                    "effect left after refitting (σ)", "dropped"],
                   [[k, st["cause"], st["location"], f"{st['parameter']} = {fmt(st['value'])} {st['unit']}",
                     f"{fmt(st['chi2_before'])} → {fmt(st['chi2_after'])}", f"{st['p_corrected']:.2g}",
                     fmt(st["effect_left"]), st["dropped"] or ""] for k, st in enumerate(d["gain"]["steps"], 1)],
                   caption="Forward selection: each step refits the base parameters with every cause found so far and "
                           "adds the most significant candidate; a cause no longer significant once later ones are in "
                           "is dropped.")

    page.heading("Base and extended fits")
    rows = [["base", ", ".join(f"{k} = {fmt(v)}" for k, v in d["base"]["parameters"].items()), fmt(d["base"]["chi2"]),
             fmt(d["base"]["chi2_dof"]), fmt(d["base"]["aic"]), fmt(d["base"]["bic"])]]
    if d["extended"] is not None:
        e = d["extended"]
        effects = ", ".join(f"{k} {fmt(v)}" for k, v in e["effects"].items())
        rows.append(["extended", ", ".join(f"{k} = {fmt(v)}" for k, v in e["parameters"].items()) + f"; effects: {effects}",
                     fmt(e["chi2"]), fmt(e["chi2_dof"]), fmt(e["aic"]), fmt(e["bic"])])
    page.table(["model", "parameters (N/mm³, MPa, -)", "χ² (-)", "χ²/dof (-)", "AIC (-)", "BIC (-)"], rows,
               caption=f"FE fits of the diagnosis; χ² includes: {d['adequacy']['basis']}")
    g = d["gain"]
    if g is not None and "held_out" in g:
        h = g["held_out"]
        page.table(["held out", "RMS residual before (σ)", "RMS residual after (σ)", "max |error| before (mm)", "max |error| after (mm)"],
                   [[h["held_out"], fmt(h["rms_before"]), fmt(h["rms_after"]), fmt(h["max_abs_mm_before"]), fmt(h["max_abs_mm_after"])]],
                   caption="Both models fitted without the highest load level, then compared with it.")
    page.details("JSON", json.dumps(d, indent=1))
    return page.write(out / "index.html")
