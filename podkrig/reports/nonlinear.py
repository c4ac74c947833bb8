"""Figures and HTML page of one nonlinear virtual test: load–displacement curve with its peak, the
deformed mesh with interface opening and slip drawn on the joints, and a step slider through the
stored steps (:mod:`podkrig.reports.step_slider`)."""

from pathlib import Path

import numpy as np

from podkrig.reports.figures import pyplot, save
from podkrig.reports.html import Page, fmt, num
from podkrig.reports.step_slider import build_step_slider, step_slider_html

#: each limit of a run's budget (``response.limit``, :data:`fe.solvers.nonlinear.LIMITS`): its name in
#: words and the scenario option that sets it
LIMITS = {"steps": ("step", "max_steps"), "iterations": ("iteration", "max_total_iterations"),
          "cpu": ("CPU-time", "max_cpu_seconds"), "wall": ("wall-clock (hang guard)", "max_seconds")}
#: the options of a run's budget
BUDGET_OPTIONS = "max_steps, max_total_iterations, max_cpu_seconds"

#: the unit of each path-following setting (:class:`fe.solvers.nonlinear.PathSettings`, the
#: report's solver table): what a count counts, s, "-" for a ratio (with what it is relative to),
#: "on/off" for a switch, "choice" for one of a set of words
SETTING_UNITS = {
    "max_steps": "increments", "max_iterations": "iterations per increment",
    "max_total_iterations": "iterations", "max_cpu_seconds": "s (CPU)", "max_seconds": "s (wall clock)",
    "tolerance": "- (force residual / force)", "line_search": "on/off", "growth": "- (increment factor)",
    "cutback": "- (increment factor)", "easy_iterations": "iterations",
    "min_increment_fraction": "- (of the initial increment)", "max_increment_fraction": "- (of the initial increment)",
    "record_states": "on/off", "elastic_fallback": "on/off", "stagnation_iterations": "iterations",
    "elastic_iterations": "iterations", "arc_length_fallback": "on/off", "max_detour_steps": "increments",
    "detour_after_failures": "failed increments", "relaxed_factor": "- (× tolerance)", "predictor": "choice",
    "step_rule": "choice", "peak_tolerance": "- (load change / load)", "max_peak_steps": "increments",
    "max_peak_levels": "bracket halvings", "peak_newton_tolerance": "- (force residual / force)",
    "divergence_factor": "- (× distance of the first iterate)",
}


def plot_load_displacement(scenario, response, path):
    """Load against the control displacement over every converged step; the peak and the
    response levels marked."""
    plt = pyplot()
    res = response.path
    mask = res.of_phase(res.phase[-1]) if len(res.phase) else np.zeros(0, bool)
    disp = scenario.control_sign * res.path[mask]
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.plot(disp, res.load[mask], "-", color="C0", lw=1.5, label="converged steps")
    ok = np.isfinite(response.loads)
    ax.plot(response.load_levels[ok], response.loads[ok], "o", color="C0", ms=4, label="response levels")
    if np.isfinite(response.peak_load):
        ax.plot([response.peak_displacement], [response.peak_load], "*", color="C3", ms=12,
                label=f"peak {response.peak_load:.3g} {response.force_unit} at {response.peak_displacement:.3g} mm")
    ax.set_xlabel(f"control displacement ({response.load_unit})")
    ax.set_ylabel(f"load ({response.force_unit})")
    ax.set_title(f"{scenario.name}: {response.status}")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    save(fig, path, dpi=120)
    return path


def plot_deformed_mesh(scenario, response, path, level=-1, magnification=None):
    """The deformed specimen at one response level (default: the last reached): unit outlines
    displaced by ``magnification`` × u, joints coloured by opening (mm) and slip drawn as line width."""
    plt = pyplot()
    res = response.path
    if res.displacements is None or not len(res.displacements):
        raise ValueError("the run kept no states: run with field=True (podkrig simulate --report does)")
    step = len(res.displacements) - 1 if level == -1 else int(level)
    u = np.asarray(res.displacements[step], float)
    st = res.states[step]
    mesh = scenario.mesh
    span = max(mesh.width, mesh.height)
    if magnification is None:
        umax = np.abs(u).max()
        magnification = 0.05 * span / umax if umax > 0 else 1.0
    xy = mesh.nodes + magnification * u
    fig, ax = plt.subplots(figsize=(6.4, 6.4 * mesh.height / mesh.width + 0.6))
    corners = mesh.quads[:, :4]
    for quad in xy[corners]:
        ax.fill(quad[:, 0], quad[:, 1], facecolor="0.92", edgecolor="0.7", lw=0.3)
    nodes = scenario.model.point_nodes()
    pts_def = xy[nodes]  # the joint points on their (deformed) face-A nodes
    opening = np.asarray(st["opening"], float)
    slip = np.abs(np.asarray(st["slip"], float))
    vmax = max(float(np.percentile(np.abs(opening), 99.5)), 1e-6)
    sc = ax.scatter(pts_def[:, 0], pts_def[:, 1], c=opening, cmap="RdBu_r",
                    vmin=-vmax, vmax=vmax, s=4 + 40 * slip / max(slip.max(), 1e-12), zorder=3)
    fig.colorbar(sc, ax=ax, label="joint opening (mm); marker size ∝ slip", shrink=0.8)
    ax.set_aspect("equal")
    ax.set_title(f"deformed ×{magnification:.3g} at control {scenario.control_sign * res.path[step]:.3g} mm "
                 f"(max slip {slip.max():.3g} mm)")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    fig.tight_layout()
    save(fig, path, dpi=120)
    return path


def _early_stop_remedy(response):
    """What to do about a run that stopped early, naming the limit that ended it if one did."""
    if response.limit in LIMITS:
        words, option = LIMITS[response.limit]
        remedy = f"The {words} limit ended the run: raise {option} (the budget: {BUDGET_OPTIONS})"
    else:
        remedy = f"Raise the budget ({BUDGET_OPTIONS})"
    return remedy + ", lower the increment, or check the parameters; the converged part of the path is shown."


def stop_line(response):
    """One line on a nonlinear run that did not reach its control range: the status, the limit
    that ended it (and the option setting it) or that Newton did not converge, and the control
    value reached against the target (the last response level); None for a run that reached it.
    The first line of the run's HTML page and of ``podkrig simulate``'s table output."""
    if response.converged:
        return None
    if response.limit in LIMITS:
        words, option = LIMITS[response.limit]
        why = f"the {words} limit ({option}) ended it"
    else:
        why = "Newton did not converge at the smallest increment"
    return (f"stopped early, status {response.status}: {why}; control reached {response.reached:.4g} of "
            f"{response.load_levels[-1]:.4g} {response.load_unit}")


def _cell(value):
    """A solver setting or count for the table: numbers as numbers, switches as on/off."""
    if isinstance(value, bool):
        return "on" if value else "off"
    return str(value) if isinstance(value, int) else num(value)


def _solver_tables(page, response):
    """The run's path-following record in tables with units: what it did, its peaks, its settings."""
    d = response.path.to_dict()
    rows = [["status", d["status"], "-"], ["limit that ended it", d["limit"] or "—", "-"],
            ["converged steps", d["steps"], "steps"], ["attempted increments", d["attempted_steps"], "increments"],
            ["failed increments (cut back)", d["failed_steps"], "increments"],
            ["peak refinement increments", d["peak_steps"], "increments"],
            ["Newton iterations", d["total_iterations"], "iterations"],
            ["steps accepted at a relaxed tolerance", len(d["relaxed_steps"]), "steps"],
            ["wall time", d["seconds"], "s"], ["CPU time", d["cpu_seconds"], "s"]]
    page.table(["quantity", "value", "unit"], [[k, _cell(v), u] for k, v, u in rows], caption="Path following")
    if d["peaks"]:
        page.table(["phase", f"control at the peak ({response.load_unit})", f"peak load ({response.force_unit})",
                    "load change across the final bracket (-)", "tolerance (-)", "resolved"],
                   [[ph, fmt(pk["path"]), fmt(pk["load"]), fmt(pk["change"]), fmt(pk["tolerance"]),
                     "yes" if pk["resolved"] else "no"] for ph, pk in d["peaks"].items()], caption="Load maxima")
    page.table(["setting", "value", "unit"],
               [[k, _cell(v), SETTING_UNITS.get(k, "")] for k, v in d["settings"].items()],
               caption="Solver settings (scenario options of the same names)")


def write_nonlinear_report(scenario, response, values, out_dir):
    """Figures plus an HTML page in ``out_dir``; returns the page path. The page's first line says
    whether the run reached its control range (:func:`stop_line` when it did not)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plot_load_displacement(scenario, response, out / "load_displacement.png")
    page = Page(f"{scenario.name}: nonlinear virtual test")
    if response.converged:
        page.success(f"Reached {response.reached:g} {response.load_unit}: peak {response.peak_load:.4g} "
                     f"{response.force_unit} at {response.peak_displacement:.4g} mm.")
    else:
        page.warning(f"{stop_line(response)}. {response.message}".rstrip(" ."), _early_stop_remedy(response))
    page.figure("load_displacement.png", "Load against the control displacement (every converged step).")
    if response.path.displacements:
        plot_deformed_mesh(scenario, response, out / "deformed.png")
        page.figure("deformed.png", "Deformed specimen at the last converged step, joints coloured by opening.")
        page.heading("Step by step")
        page.fragment(step_slider_html(build_step_slider(scenario, response)))
    header = [f"level ({response.load_unit})", f"load ({response.force_unit})"] + [f"{n} (mm)" for n in response.sensor_names]
    rows = [[fmt(lv), num(ld)] + [num(v) for v in row]  # "—" at the levels a stopped run did not reach
            for lv, ld, row in zip(response.load_levels, response.loads, response.readings)]
    page.table(header, rows, caption="Readings at the response levels")
    page.table(["parameter", "value", "unit"], [[k, fmt(v), scenario.parameters[k].unit] for k, v in values.items()],
               caption="Parameters")
    _solver_tables(page, response)
    return page.write(out / "index.html")
